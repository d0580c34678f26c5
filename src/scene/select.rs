//! Selections (DESIGN.md "Colour, selections and translucency"): a small
//! expression language parsed by recursive descent into an AST.
//!
//! ```text
//! expr    := and ("or" and)*
//! and     := unary ("and" unary)*
//! unary   := "not" unary | "(" expr ")" | keyword
//! keyword := chain NAME... | resname NAME... | name NAME... | element SYM...
//!          | resid RANGE... | index RANGE... | molecule NAME... | node NAME...
//!          | hetatm | water | all
//! ```
//! Names may use `*` and `?` globs; a RANGE is `N` or `A-B` (inclusive).
//! A value list ends at `and`, `or`, `)` or the end. Errors name the token
//! and its 1-based column.

/// A parsed selection.
#[derive(Clone, Debug, PartialEq)]
pub enum Sel {
    All,
    Chain(Vec<String>),
    Resname(Vec<String>),
    Name(Vec<String>),
    /// Element symbols (compared case-insensitively).
    Element(Vec<String>),
    Resid(Vec<(i64, i64)>),
    Index(Vec<(u64, u64)>),
    Hetatm,
    Water,
    /// Instanced scenes: molecule type labels.
    Molecule(Vec<String>),
    /// Instanced scenes: a hierarchy node and everything below it.
    Node(Vec<String>),
    Not(Box<Sel>),
    And(Box<Sel>, Box<Sel>),
    Or(Box<Sel>, Box<Sel>),
}

/// A parse error: the message, naming the token and its column.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SelError(pub String);

impl std::fmt::Display for SelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// Residue names that `water` selects (PDB, AMBER, GROMACS, CHARMM and
/// deuterated water).
pub const WATER: &[&str] = &[
    "HOH", "WAT", "H2O", "SOL", "TIP", "TIP3", "TIP4", "TIP5", "T3P", "T4P", "T5P", "SPC", "DOD",
    "D2O",
];

const KEYWORDS: &str =
    "chain, resname, resid, name, element, index, hetatm, water, all, molecule, node, not, '('";

#[derive(Clone, Copy, Debug)]
struct Token<'a> {
    text: &'a str,
    /// 1-based column (in characters).
    col: usize,
}

fn tokens(s: &str) -> Vec<Token<'_>> {
    let mut out = Vec::new();
    let mut start: Option<(usize, usize)> = None; // byte, column
    let mut col = 0;
    for (b, c) in s.char_indices() {
        col += 1;
        let paren = c == '(' || c == ')';
        if c.is_whitespace() || paren {
            if let Some((sb, sc)) = start.take() {
                out.push(Token {
                    text: &s[sb..b],
                    col: sc,
                });
            }
            if paren {
                out.push(Token {
                    text: &s[b..b + 1],
                    col,
                });
            }
        } else if start.is_none() {
            start = Some((b, col));
        }
    }
    if let Some((sb, sc)) = start {
        out.push(Token {
            text: &s[sb..],
            col: sc,
        });
    }
    out
}

struct Parser<'a> {
    toks: Vec<Token<'a>>,
    at: usize,
    /// Column just past the text (for errors at the end).
    end: usize,
}

impl<'a> Parser<'a> {
    fn peek(&self) -> Option<Token<'a>> {
        self.toks.get(self.at).copied()
    }

    fn is_word(&self, w: &str) -> bool {
        self.peek().is_some_and(|t| t.text == w)
    }

    fn err_at(t: Token, msg: &str) -> SelError {
        SelError(format!("'{}' at column {}: {msg}", t.text, t.col))
    }

    fn expr(&mut self) -> Result<Sel, SelError> {
        let mut l = self.and()?;
        while self.is_word("or") {
            self.at += 1;
            let r = self.operand("or", Self::and)?;
            l = Sel::Or(Box::new(l), Box::new(r));
        }
        Ok(l)
    }

    fn and(&mut self) -> Result<Sel, SelError> {
        let mut l = self.unary()?;
        while self.is_word("and") {
            self.at += 1;
            let r = self.operand("and", Self::unary)?;
            l = Sel::And(Box::new(l), Box::new(r));
        }
        Ok(l)
    }

    /// The operand after `op` (an error naming `op` at the end).
    fn operand(
        &mut self,
        op: &str,
        f: fn(&mut Self) -> Result<Sel, SelError>,
    ) -> Result<Sel, SelError> {
        if self.peek().is_none() {
            let t = self.toks[self.at - 1];
            return Err(Self::err_at(
                t,
                &format!("expected a selection after '{op}'"),
            ));
        }
        f(self)
    }

    fn unary(&mut self) -> Result<Sel, SelError> {
        let Some(t) = self.peek() else {
            return Err(SelError(format!(
                "expected a selection at column {} (the end)",
                self.end
            )));
        };
        self.at += 1;
        match t.text {
            "not" => {
                let inner = self.operand("not", Self::unary)?;
                Ok(Sel::Not(Box::new(inner)))
            }
            "(" => {
                let inner = self.expr()?;
                match self.peek() {
                    Some(c) if c.text == ")" => {
                        self.at += 1;
                        Ok(inner)
                    }
                    Some(o) => Err(Self::err_at(o, "expected 'and', 'or' or ')'")),
                    None => Err(Self::err_at(t, "is never closed")),
                }
            }
            "all" => Ok(Sel::All),
            "hetatm" => Ok(Sel::Hetatm),
            "water" => Ok(Sel::Water),
            "chain" => Ok(Sel::Chain(self.names(t)?)),
            "resname" => Ok(Sel::Resname(self.names(t)?)),
            "name" => Ok(Sel::Name(self.names(t)?)),
            "element" => Ok(Sel::Element(self.names(t)?)),
            "molecule" => Ok(Sel::Molecule(self.names(t)?)),
            "node" => Ok(Sel::Node(self.names(t)?)),
            "resid" => Ok(Sel::Resid(self.ranges(t, true)?)),
            "index" => {
                let r = self.ranges(t, false)?;
                Ok(Sel::Index(
                    r.into_iter().map(|(a, b)| (a as u64, b as u64)).collect(),
                ))
            }
            ")" => Err(Self::err_at(t, "expected a selection")),
            "and" | "or" => Err(Self::err_at(t, "expected a selection before it")),
            _ => Err(Self::err_at(
                t,
                &format!("unknown keyword (expected {KEYWORDS})"),
            )),
        }
    }

    /// The values after keyword `k`: tokens up to `and`, `or`, `)` or the
    /// end; at least one.
    fn values(&mut self, k: Token<'a>) -> Result<Vec<Token<'a>>, SelError> {
        let mut v = Vec::new();
        while let Some(t) = self.peek() {
            if matches!(t.text, "and" | "or" | ")" | "(") {
                break;
            }
            v.push(t);
            self.at += 1;
        }
        if v.is_empty() {
            return Err(Self::err_at(k, "needs at least one value"));
        }
        Ok(v)
    }

    fn names(&mut self, k: Token<'a>) -> Result<Vec<String>, SelError> {
        Ok(self
            .values(k)?
            .into_iter()
            .map(|t| t.text.to_string())
            .collect())
    }

    /// `N` or `A-B` values; negative numbers only when `signed` (resid:
    /// `-5`, `-5--1`, `-5-3`).
    fn ranges(&mut self, k: Token<'a>, signed: bool) -> Result<Vec<(i64, i64)>, SelError> {
        let mut out = Vec::new();
        for t in self.values(k)? {
            let bad = || {
                Self::err_at(
                    t,
                    if signed {
                        "expected a number or a range A-B"
                    } else {
                        "expected a number or a range A-B (0 or more)"
                    },
                )
            };
            let num = |s: &str| -> Option<i64> {
                let v: i64 = s.parse().ok()?;
                (signed || v >= 0).then_some(v)
            };
            // the dash separating A and B: the first one after position 0
            let (a, b) = match t.text[1.min(t.text.len())..].find('-') {
                Some(i) => {
                    let (a, b) = t.text.split_at(i + 1);
                    (num(a).ok_or_else(bad)?, num(&b[1..]).ok_or_else(bad)?)
                }
                None => {
                    let v = num(t.text).ok_or_else(bad)?;
                    (v, v)
                }
            };
            if a > b {
                return Err(Self::err_at(t, "the range runs backwards"));
            }
            out.push((a, b));
        }
        Ok(out)
    }
}

/// Parses a selection.
pub fn parse(s: &str) -> Result<Sel, SelError> {
    let mut p = Parser {
        toks: tokens(s),
        at: 0,
        end: s.chars().count() + 1,
    };
    if p.toks.is_empty() {
        return Err(SelError("the selection is empty".into()));
    }
    let sel = p.expr()?;
    if let Some(t) = p.peek() {
        return Err(Parser::err_at(
            t,
            if t.text == ")" {
                "no '(' to close"
            } else {
                "expected 'and', 'or' or the end"
            },
        ));
    }
    Ok(sel)
}

/// `*` (any run) and `?` (one character) globs; otherwise exact.
pub fn glob(pattern: &str, s: &str) -> bool {
    let (p, t): (Vec<char>, Vec<char>) = (pattern.chars().collect(), s.chars().collect());
    let (mut pi, mut ti) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while ti < t.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == t[ti]) {
            pi += 1;
            ti += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some((pi, ti));
            pi += 1;
        } else if let Some((sp, st)) = star {
            pi = sp + 1;
            ti = st + 1;
            star = Some((sp, st + 1));
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

impl Sel {
    /// Whether any leaf is a per-instance one (`molecule`, `node`).
    pub fn per_instance(&self) -> bool {
        match self {
            Sel::Molecule(_) | Sel::Node(_) => true,
            Sel::Not(a) => a.per_instance(),
            Sel::And(a, b) | Sel::Or(a, b) => a.per_instance() || b.per_instance(),
            _ => false,
        }
    }

    /// Every leaf, depth first.
    pub fn leaves<'s>(&'s self, out: &mut Vec<&'s Sel>) {
        match self {
            Sel::Not(a) => a.leaves(out),
            Sel::And(a, b) | Sel::Or(a, b) => {
                a.leaves(out);
                b.leaves(out);
            }
            leaf => out.push(leaf),
        }
    }

    /// Evaluates with `leaf` deciding each leaf.
    pub fn eval(&self, leaf: &mut dyn FnMut(&Sel) -> bool) -> bool {
        match self {
            Sel::Not(a) => !a.eval(leaf),
            Sel::And(a, b) => a.eval(leaf) && b.eval(leaf),
            Sel::Or(a, b) => a.eval(leaf) || b.eval(leaf),
            l => leaf(l),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(s: &str) -> String {
        parse(s).unwrap_err().0
    }

    #[test]
    fn precedence_and_grouping() {
        use Sel::*;
        let c = |v: &str| Chain(vec![v.into()]);
        assert_eq!(
            parse("chain A or chain B and not water").unwrap(),
            Or(
                Box::new(c("A")),
                Box::new(And(Box::new(c("B")), Box::new(Not(Box::new(Water)))))
            )
        );
        assert_eq!(
            parse("(chain A or chain B)and hetatm").unwrap(),
            And(
                Box::new(Or(Box::new(c("A")), Box::new(c("B")))),
                Box::new(Hetatm)
            )
        );
        assert_eq!(
            parse("resid 10-20 -5 -3--1 7").unwrap(),
            Resid(vec![(10, 20), (-5, -5), (-3, -1), (7, 7)])
        );
        assert_eq!(parse("index 0-99").unwrap(), Index(vec![(0, 99)]));
        assert_eq!(
            parse("not not all").unwrap(),
            Not(Box::new(Not(Box::new(All))))
        );
        assert_eq!(
            parse("resname HOH WAT").unwrap(),
            Resname(vec!["HOH".into(), "WAT".into()])
        );
        assert_eq!(
            parse("molecule Spike* and node membrane").unwrap(),
            And(
                Box::new(Molecule(vec!["Spike*".into()])),
                Box::new(Node(vec!["membrane".into()]))
            )
        );
    }

    #[test]
    fn every_error_names_the_token_and_column() {
        assert_eq!(err(""), "the selection is empty");
        assert_eq!(err("   "), "the selection is empty");
        assert_eq!(
            err("chian A"),
            format!("'chian' at column 1: unknown keyword (expected {KEYWORDS})")
        );
        assert_eq!(
            err("chain"),
            "'chain' at column 1: needs at least one value"
        );
        assert_eq!(
            err("water and chain"),
            "'chain' at column 11: needs at least one value"
        );
        assert_eq!(
            err("chain A and"),
            "'and' at column 9: expected a selection after 'and'"
        );
        assert_eq!(
            err("not"),
            "'not' at column 1: expected a selection after 'not'"
        );
        assert_eq!(
            err("or water"),
            "'or' at column 1: expected a selection before it"
        );
        assert_eq!(err("(water"), "'(' at column 1: is never closed");
        assert_eq!(err("water)"), "')' at column 6: no '(' to close");
        assert_eq!(err(")"), "')' at column 1: expected a selection");
        assert_eq!(
            err("(water hetatm)"),
            "'hetatm' at column 8: expected 'and', 'or' or ')'"
        );
        assert_eq!(
            err("water hetatm"),
            "'hetatm' at column 7: expected 'and', 'or' or the end"
        );
        assert_eq!(
            err("resid 10-x"),
            "'10-x' at column 7: expected a number or a range A-B"
        );
        assert_eq!(
            err("index -1"),
            "'-1' at column 7: expected a number or a range A-B (0 or more)"
        );
        assert_eq!(
            err("index 20-10"),
            "'20-10' at column 7: the range runs backwards"
        );
        assert_eq!(
            err("chain A and ()"),
            "')' at column 14: expected a selection"
        );
        assert_eq!(err("()"), "')' at column 2: expected a selection");
        // columns count characters, not bytes
        assert_eq!(
            err("name Å and resid x"),
            "'x' at column 18: expected a number or a range A-B"
        );
    }

    #[test]
    fn globs() {
        assert!(glob("Spike*", "Spike glycoprotein"));
        assert!(glob("*", ""));
        assert!(glob("C?", "CA"));
        assert!(!glob("C?", "C"));
        assert!(glob("*ase", "polymerase"));
        assert!(!glob("*ase", "polymerases"));
        assert!(glob("a*b*c", "axxbyyc"));
        assert!(!glob("a*b*c", "axxbyy"));
        assert!(glob("HOH", "HOH"));
        assert!(!glob("HOH", "HOHX"));
    }
}
