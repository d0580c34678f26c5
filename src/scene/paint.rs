//! Colour schemes and the rules `--hide SEL`, `--paint SEL=COLOR`,
//! `--alpha SEL=A` (DESIGN.md "Colour, selections and translucency"),
//! applied to a loaded scene on the host: the scene that comes out is what
//! the GPU gets (hidden spheres are not in it, a sphere's alpha is its
//! colour's A byte).
//!
//! On instanced scenes `molecule`/`node` are decided per instance and the
//! rest per stored atom: instances whose per-instance answers agree share
//! one copy of their molecule with the rules applied, so nothing is
//! expanded (a molecule is copied once per distinct combination).

use std::collections::HashMap;

use super::atoms::Atoms;
use super::elements::Element;
use super::molecule::palette_color;
use super::select::{self, Sel, WATER, glob};
use super::{MAX_LEVELS, Origin, Scene, SceneError, Sphere};

/// `--color`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scheme {
    Element,
    Chain,
    Residue,
    Bfactor,
    Index,
    Hierarchy,
    Uniform([u8; 3]),
}

impl Scheme {
    pub const NAMES: &'static str = "element, chain, residue, bfactor, index, hierarchy or R,G,B";

    pub fn parse(s: &str) -> Result<Scheme, String> {
        Ok(match s {
            "element" => Scheme::Element,
            "chain" => Scheme::Chain,
            "residue" => Scheme::Residue,
            "bfactor" => Scheme::Bfactor,
            "index" => Scheme::Index,
            "hierarchy" => Scheme::Hierarchy,
            _ => Scheme::Uniform(
                parse_color(s)
                    .map_err(|_| format!("'{s}': expected {} (0-255 each)", Scheme::NAMES))?,
            ),
        })
    }
}

/// `--colormap`: the perceptual maps of `bfactor` and `index` (the
/// published tables, through the `colorous` crate).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Colormap {
    #[default]
    Viridis,
    Magma,
    Turbo,
}

impl Colormap {
    /// The map at t in [0, 1].
    pub fn at(self, t: f64) -> [u8; 3] {
        let g = match self {
            Colormap::Viridis => colorous::VIRIDIS,
            Colormap::Magma => colorous::MAGMA,
            Colormap::Turbo => colorous::TURBO,
        };
        let c = g.eval_continuous(t.clamp(0.0, 1.0));
        [c.r, c.g, c.b]
    }
}

/// A colour: `R,G,B` (0-255), `#RRGGBB` or a name (white, black, grey,
/// red, green, blue, yellow, orange, cyan, magenta).
pub fn parse_color(s: &str) -> Result<[u8; 3], String> {
    let named = match s.to_ascii_lowercase().as_str() {
        "white" => Some([255, 255, 255]),
        "black" => Some([0, 0, 0]),
        "grey" | "gray" => Some([128, 128, 128]),
        "red" => Some([230, 25, 25]),
        "green" => Some([30, 170, 50]),
        "blue" => Some([40, 80, 230]),
        "yellow" => Some([240, 220, 30]),
        "orange" => Some([250, 140, 20]),
        "cyan" => Some([0, 200, 220]),
        "magenta" => Some([210, 40, 190]),
        _ => None,
    };
    if let Some(c) = named {
        return Ok(c);
    }
    let bad = || format!("'{s}': expected R,G,B (0-255 each), #RRGGBB or a colour name");
    if let Some(hex) = s.strip_prefix('#') {
        let v = u32::from_str_radix(hex, 16).map_err(|_| bad())?;
        if hex.len() != 6 {
            return Err(bad());
        }
        return Ok([(v >> 16) as u8, (v >> 8) as u8, v as u8]);
    }
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(bad());
    }
    let mut c = [0u8; 3];
    for (o, p) in c.iter_mut().zip(parts) {
        *o = p.trim().parse().map_err(|_| bad())?;
    }
    Ok(c)
}

/// What a rule does to the spheres its selection picks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    Hide,
    Paint([u8; 3]),
    /// Alpha (0..1), stored as the colour's A byte.
    Alpha(f32),
}

/// One `--hide`, `--paint` or `--alpha`, as given and as parsed.
#[derive(Clone, Debug, PartialEq)]
pub struct Rule {
    /// The flag and its value as given (for messages).
    pub flag: &'static str,
    pub text: String,
    pub sel: Sel,
    pub action: Action,
}

impl Rule {
    /// `--hide SEL`.
    pub fn hide(text: &str) -> Result<Rule, String> {
        let sel = select::parse(text).map_err(|e| e.0)?;
        Ok(Rule {
            flag: "--hide",
            text: text.to_string(),
            sel,
            action: Action::Hide,
        })
    }

    /// `SEL=VALUE` split at the last `=`.
    fn split<'a>(flag: &'static str, text: &'a str) -> Result<(&'a str, &'a str), String> {
        text.rsplit_once('=')
            .ok_or_else(|| format!("{flag} takes SELECTION=VALUE"))
    }

    /// `--paint SEL=COLOR`.
    pub fn paint(text: &str) -> Result<Rule, String> {
        let (sel, c) = Rule::split("--paint", text)?;
        let color = parse_color(c.trim())?;
        Ok(Rule {
            flag: "--paint",
            text: text.to_string(),
            sel: select::parse(sel).map_err(|e| e.0)?,
            action: Action::Paint(color),
        })
    }

    /// `--alpha SEL=A`.
    pub fn alpha(text: &str) -> Result<Rule, String> {
        let (sel, a) = Rule::split("--alpha", text)?;
        let alpha = a
            .trim()
            .parse::<f32>()
            .ok()
            .filter(|a| (0.0..=1.0).contains(a))
            .ok_or_else(|| format!("'{a}': expected an alpha between 0 and 1"))?;
        Ok(Rule {
            flag: "--alpha",
            text: text.to_string(),
            sel: select::parse(sel).map_err(|e| e.0)?,
            action: Action::Alpha(alpha),
        })
    }

    fn apply(&self, s: &mut Sphere) -> bool {
        match self.action {
            Action::Hide => return false,
            Action::Paint([r, g, b]) => {
                s.color[0] = r;
                s.color[1] = g;
                s.color[2] = b;
            }
            Action::Alpha(a) => s.color[3] = alpha_byte(a),
        }
        true
    }
}

/// Alpha as the colour's A byte (255 = opaque).
pub fn alpha_byte(a: f32) -> u8 {
    (a.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// How the scene is coloured and which rules apply, in order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Paint {
    /// None: the loader's colours (element, or chain with ColorBy::Chain).
    pub scheme: Option<Scheme>,
    pub colormap: Colormap,
    pub rules: Vec<Rule>,
}

impl Paint {
    pub fn is_empty(&self) -> bool {
        self.scheme.is_none() && self.rules.is_empty()
    }
}

/// What the scene's source is, for messages ("scene:capsid", a path).
fn lacks(scene: &Scene, what: &str) -> String {
    format!("{} gives no {what}", scene.source)
}

/// Amino-acid colours of RasMol's `amino` scheme (RasMol 2.6 manual,
/// "Colour Schemes"); other residues take palette colours by name.
const AMINO: &[(&str, [u8; 3])] = &[
    ("ASP", [230, 10, 10]),
    ("GLU", [230, 10, 10]),
    ("CYS", [230, 230, 0]),
    ("MET", [230, 230, 0]),
    ("LYS", [20, 90, 255]),
    ("ARG", [20, 90, 255]),
    ("SER", [250, 150, 0]),
    ("THR", [250, 150, 0]),
    ("PHE", [50, 50, 170]),
    ("TYR", [50, 50, 170]),
    ("ASN", [0, 220, 220]),
    ("GLN", [0, 220, 220]),
    ("GLY", [235, 235, 235]),
    ("LEU", [15, 130, 15]),
    ("VAL", [15, 130, 15]),
    ("ILE", [15, 130, 15]),
    ("ALA", [200, 200, 200]),
    ("TRP", [180, 90, 180]),
    ("HIS", [130, 130, 210]),
    ("PRO", [220, 150, 130]),
];

/// Dense ranks of interned ids in order of first use (palette indices
/// that do not depend on what else was interned).
fn ranks() -> impl FnMut(u32) -> u32 {
    let mut seen: HashMap<u32, u32> = HashMap::new();
    move |id| {
        let n = seen.len() as u32;
        *seen.entry(id).or_insert(n)
    }
}

fn rgb(s: &mut Sphere, c: [u8; 3]) {
    s.color[..3].copy_from_slice(&c);
}

/// Each sphere record's group at the outermost level of the hierarchy
/// that tells them apart: the molecule type of an instanced scene's atoms,
/// else the region at the outermost level whose regions differ (the
/// chains of a protein); 0 where nothing differs. `--color hierarchy`
/// colours by it, the viewer's see-through presets pick by it.
pub fn hierarchy_groups(scene: &Scene) -> Vec<u32> {
    let mut g = vec![0; scene.spheres.len()];
    if let Some(inst) = &scene.instancing {
        for (m, mol) in inst.molecules.iter().enumerate() {
            let r = mol.first as usize..(mol.first + mol.atoms) as usize;
            g[r].iter_mut().for_each(|x| *x = m as u32);
        }
        return g;
    }
    let levels = scene.level_names.len().min(MAX_LEVELS);
    let level = (0..levels).find(|&l| {
        let first = scene.spheres.first().map(|s| s.region[l]);
        scene.spheres.iter().any(|s| Some(s.region[l]) != first)
    });
    if let Some(l) = level {
        for (x, s) in g.iter_mut().zip(&scene.spheres) {
            *x = s.region[l];
        }
    }
    g
}

/// Colours the scene's sphere records by `scheme` (alpha kept).
pub fn color_scheme(scene: &mut Scene, scheme: Scheme, map: Colormap) -> Result<(), String> {
    let n = scene.spheres.len();
    let atoms = scene.atoms.as_ref();
    let need = |ok: bool, what: &str| {
        if ok {
            Ok(atoms.expect("checked"))
        } else {
            Err(format!("--color: {}", lacks(scene, what)))
        }
    };
    let instanced = scene.instancing.is_some();
    match scheme {
        Scheme::Uniform(c) => scene.spheres.iter_mut().for_each(|s| rgb(s, c)),
        Scheme::Element => {
            let a = need(atoms.is_some_and(|a| a.known.element), "elements")?;
            let colors: Vec<[u8; 4]> = a.element.iter().map(|e| e.color()).collect();
            for (s, c) in scene.spheres.iter_mut().zip(colors) {
                rgb(s, [c[0], c[1], c[2]]);
            }
        }
        Scheme::Chain => {
            let plain_chains = !instanced && scene.level_names.get(1).is_some_and(|l| l == "chain");
            if plain_chains {
                // the chain region (a copy of an assembly has its own)
                for s in &mut scene.spheres {
                    let c = palette_color(s.region[1]);
                    rgb(s, [c[0], c[1], c[2]]);
                }
            } else if let Some(a) = atoms.filter(|a| a.known.chain) {
                let mut rank = ranks();
                let ids: Vec<u32> = a.chain.iter().map(|&c| rank(c)).collect();
                for (s, k) in scene.spheres.iter_mut().zip(ids) {
                    let c = palette_color(k);
                    rgb(s, [c[0], c[1], c[2]]);
                }
            } else if instanced {
                // beads: the chain index within the molecule
                for s in &mut scene.spheres {
                    let c = palette_color(s.region[0]);
                    rgb(s, [c[0], c[1], c[2]]);
                }
            } else {
                return Err(format!("--color chain: {}", lacks(scene, "chains")));
            }
        }
        Scheme::Residue => {
            let a = need(atoms.is_some_and(|a| a.known.residue), "residue names")?;
            let mut rank = ranks();
            let table: HashMap<&str, [u8; 3]> = AMINO.iter().copied().collect();
            let colors: Vec<[u8; 3]> = (0..n)
                .map(|i| {
                    table.get(a.resname_of(i)).copied().unwrap_or_else(|| {
                        let c = palette_color(rank(a.resname[i]));
                        [c[0], c[1], c[2]]
                    })
                })
                .collect();
            for (s, c) in scene.spheres.iter_mut().zip(colors) {
                rgb(s, c);
            }
        }
        Scheme::Bfactor => {
            let a = need(atoms.is_some_and(|a| a.known.bfactor), "B-factors")?;
            let (lo, hi) = a
                .bfactor
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &b| {
                    (l.min(b), h.max(b))
                });
            let span = (hi - lo).max(f32::MIN_POSITIVE) as f64;
            let colors: Vec<[u8; 3]> = a
                .bfactor
                .iter()
                .map(|&b| map.at((b - lo) as f64 / span))
                .collect();
            for (s, c) in scene.spheres.iter_mut().zip(colors) {
                rgb(s, c);
            }
        }
        Scheme::Index => {
            if instanced {
                return Err(
                    "--color index: an instanced scene colours by stored atom; use --expand".into(),
                );
            }
            let last = (n.max(2) - 1) as f64;
            for (i, s) in scene.spheres.iter_mut().enumerate() {
                rgb(s, map.at(i as f64 / last));
            }
        }
        Scheme::Hierarchy => {
            let groups = hierarchy_groups(scene);
            for (s, g) in scene.spheres.iter_mut().zip(groups) {
                let c = palette_color(g);
                rgb(s, [c[0], c[1], c[2]]);
            }
        }
    }
    Ok(())
}

/// A leaf of a selection made ready for one scene.
enum Pred {
    Const(bool),
    /// An interned string column and which ids match.
    Str(StrCol, Vec<bool>),
    Element(Vec<bool>),
    Resid(Vec<(i64, i64)>),
    Index(Vec<(u64, u64)>),
    Hetatm,
    Water(Vec<bool>),
    /// A per-instance leaf: its slot in an instance's answers.
    Instance(usize),
}

#[derive(Clone, Copy)]
enum StrCol {
    Chain,
    Resname,
    Name,
}

/// The compiled rules: a predicate per leaf (same order as `leaves`).
struct Compiled<'r> {
    rules: &'r [Rule],
    preds: Vec<Vec<Pred>>,
    /// Per-instance leaves: (rule, leaf) and what they ask.
    instance_leaves: Vec<&'r Sel>,
}

fn compile<'r>(scene: &Scene, rules: &'r [Rule]) -> Result<Compiled<'r>, String> {
    let atoms = scene.atoms.as_ref();
    let instanced = scene.instancing.is_some();
    let mut preds = Vec::new();
    let mut instance_leaves = Vec::new();
    for rule in rules {
        let err = |msg: String| format!("{} '{}': {msg}", rule.flag, rule.text);
        let mut leaves = Vec::new();
        rule.sel.leaves(&mut leaves);
        let mut ps = Vec::new();
        for leaf in leaves {
            let need = |ok: fn(&Atoms) -> bool, what: &str| -> Result<&Atoms, String> {
                atoms
                    .filter(|a| ok(a))
                    .ok_or_else(|| err(lacks(scene, what)))
            };
            let strs = |a: &Atoms, pats: &[String]| -> Vec<bool> {
                let mut m = vec![false; a.strings.len()];
                for (id, s) in a.strings.iter() {
                    m[id as usize] = pats.iter().any(|p| glob(p, s));
                }
                m
            };
            let p = match leaf {
                Sel::All => Pred::Const(true),
                Sel::Chain(p) => {
                    Pred::Str(StrCol::Chain, strs(need(|a| a.known.chain, "chains")?, p))
                }
                Sel::Resname(p) => Pred::Str(
                    StrCol::Resname,
                    strs(need(|a| a.known.residue, "residue names")?, p),
                ),
                Sel::Name(p) => {
                    Pred::Str(StrCol::Name, strs(need(|a| a.known.name, "atom names")?, p))
                }
                Sel::Element(p) => {
                    need(|a| a.known.element, "elements")?;
                    let upper: Vec<String> = p.iter().map(|s| s.to_ascii_uppercase()).collect();
                    Pred::Element(
                        (0..=255u8)
                            .map(|z| {
                                let sym = Element::from_number(z as u32)
                                    .map_or("X", |e| e.symbol())
                                    .to_ascii_uppercase();
                                upper.iter().any(|p| glob(p, &sym))
                            })
                            .collect(),
                    )
                }
                Sel::Resid(r) => {
                    need(|a| a.known.residue, "residue numbers")?;
                    Pred::Resid(r.clone())
                }
                Sel::Index(r) => {
                    if instanced {
                        return Err(err(
                            "index names expanded atoms; on an instanced scene select by molecule, node or atom fields, or add --expand".into(),
                        ));
                    }
                    Pred::Index(r.clone())
                }
                Sel::Hetatm => {
                    need(|a| a.known.hetatm, "HETATM records")?;
                    Pred::Hetatm
                }
                Sel::Water => {
                    let a = need(|a| a.known.residue, "residue names")?;
                    let mut m = vec![false; a.strings.len()];
                    for (id, s) in a.strings.iter() {
                        m[id as usize] = WATER.contains(&s);
                    }
                    Pred::Water(m)
                }
                Sel::Molecule(_) | Sel::Node(_) => {
                    if !instanced {
                        return Err(err(
                            "molecule and node select in instanced scenes (PetWorld, cellPACK, manifests, --assembly)".into(),
                        ));
                    }
                    instance_leaves.push(leaf);
                    Pred::Instance(instance_leaves.len() - 1)
                }
                Sel::Not(_) | Sel::And(..) | Sel::Or(..) => unreachable!("not a leaf"),
            };
            ps.push(p);
        }
        preds.push(ps);
    }
    Ok(Compiled {
        rules,
        preds,
        instance_leaves,
    })
}

impl Compiled<'_> {
    /// Whether rule `r` selects stored row `i` (input index `index`) given
    /// the per-instance answers `inst`.
    fn selects(
        &self,
        r: usize,
        atoms: Option<&Atoms>,
        i: usize,
        index: u64,
        inst: &[bool],
    ) -> bool {
        let mut k = 0;
        let preds = &self.preds[r];
        self.rules[r].sel.eval(&mut |_| {
            let p = &preds[k];
            k += 1;
            match p {
                Pred::Const(b) => *b,
                Pred::Str(col, m) => {
                    let a = atoms.expect("compiled with atoms");
                    let id = match col {
                        StrCol::Chain => a.chain[i],
                        StrCol::Resname => a.resname[i],
                        StrCol::Name => a.name[i],
                    };
                    m[id as usize]
                }
                Pred::Element(m) => m[atoms.expect("atoms").element[i].number() as usize],
                Pred::Resid(r) => {
                    let v = atoms.expect("atoms").resid[i] as i64;
                    r.iter().any(|&(a, b)| (a..=b).contains(&v))
                }
                Pred::Index(r) => r.iter().any(|&(a, b)| (a..=b).contains(&index)),
                Pred::Hetatm => atoms.expect("atoms").hetatm[i],
                Pred::Water(m) => m[atoms.expect("atoms").resname[i] as usize],
                Pred::Instance(j) => inst[*j],
            }
        })
    }

    /// Applies the rules in order to one sphere record; false: hidden.
    fn apply(
        &self,
        s: &mut Sphere,
        atoms: Option<&Atoms>,
        i: usize,
        index: u64,
        inst: &[bool],
    ) -> bool {
        for r in 0..self.rules.len() {
            if self.selects(r, atoms, i, index, inst) && !self.rules[r].apply(s) {
                return false;
            }
        }
        true
    }
}

/// What applying the rules did, for the one-line notes on stderr.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Applied {
    /// Per rule: represented spheres it selected.
    pub selected: Vec<u64>,
    pub hidden: u64,
    pub translucent: u64,
}

/// Colours the scene and applies the rules in order. A rule that selects
/// nothing is not an error (`Applied` counts them).
pub fn apply(mut scene: Scene, paint: &Paint) -> Result<(Scene, Applied), SceneError> {
    if let Some(scheme) = paint.scheme {
        color_scheme(&mut scene, scheme, paint.colormap).map_err(SceneError::Invalid)?;
    }
    let mut applied = Applied {
        selected: vec![0; paint.rules.len()],
        ..Default::default()
    };
    if paint.rules.is_empty() {
        return Ok((scene, applied));
    }
    if scene.origin.is_some() {
        return Err(SceneError::Invalid(
            "the scene was already subset (rules apply once)".into(),
        ));
    }
    if let Some(n) = scene.nesting() {
        // (a rule would have to tell one placement's copy from another's,
        // which the block's instances cannot)
        return Err(SceneError::Invalid(format!(
            "{}: --hide/--paint/--alpha rules on a nested scene ({} placements of one block) \
             are not supported; colour schemes are",
            scene.source,
            n.placements.len()
        )));
    }
    let c = compile(&scene, &paint.rules).map_err(SceneError::Invalid)?;
    if scene.instancing.is_some() {
        return apply_instanced(scene, &c, applied);
    }
    let atoms = scene.atoms.take();
    let mut kept = Vec::with_capacity(scene.spheres.len());
    let mut origin = Vec::new();
    for (i, s) in scene.spheres.iter().enumerate() {
        for (r, n) in applied.selected.iter_mut().enumerate() {
            *n += c.selects(r, atoms.as_ref(), i, i as u64, &[]) as u64;
        }
        let mut t = *s;
        if c.apply(&mut t, atoms.as_ref(), i, i as u64, &[]) {
            applied.translucent += (t.color[3] < 255) as u64;
            kept.push(t);
            origin.push(i as u32);
        }
    }
    applied.hidden = (scene.spheres.len() - kept.len()) as u64;
    if kept.is_empty() {
        return Err(SceneError::Invalid(format!(
            "{}: the rules hide every sphere",
            scene.source
        )));
    }
    let subset = applied.hidden > 0;
    scene.atoms = match (&atoms, subset) {
        (Some(a), true) => Some(a.pick(origin.iter().map(|&i| i as usize))),
        _ => atoms,
    };
    scene.spheres = kept;
    if subset {
        scene.origin = Some(Origin::Plain {
            index: origin,
            total: applied.hidden + scene.spheres.len() as u64,
        });
    }
    Ok((scene, applied))
}

/// A molecule type and an instance's answers to the per-instance leaves.
type Variant = (u32, Vec<bool>);

/// Instanced: instances grouped by their per-instance answers, a molecule
/// copy per (molecule, answers) with the rules applied to its atoms.
fn apply_instanced(
    mut scene: Scene,
    c: &Compiled,
    mut applied: Applied,
) -> Result<(Scene, Applied), SceneError> {
    let Some(mut inst) = scene.instancing.take() else {
        return Ok((scene, applied));
    };
    let represented = inst.represented();
    let atoms = scene.atoms.take();
    // per instance: its answers to the per-instance leaves
    let answers = |k: usize| -> Vec<bool> {
        let m = inst.instance_molecule[k] as usize;
        c.instance_leaves
            .iter()
            .map(|leaf| {
                let (pats, node_too) = match leaf {
                    Sel::Molecule(p) => (p, false),
                    Sel::Node(p) => (p, true),
                    _ => return false,
                };
                let mol = &inst.molecules[m];
                if !node_too {
                    return pats.iter().any(|p| glob(p, &mol.label));
                }
                let mut n = Some(mol.node);
                while let Some(i) = n {
                    let node = &inst.nodes[i as usize];
                    if pats.iter().any(|p| glob(p, &node.label)) {
                        return true;
                    }
                    n = node.parent;
                }
                false
            })
            .collect()
    };
    // (molecule, answers) -> its copy (None: every atom hidden) and what
    // each rule selects in one instance
    let mut variants: HashMap<Variant, (Option<u32>, Vec<u64>)> = HashMap::new();
    let mut molecules = Vec::new();
    let mut tree_regions = Vec::new();
    let mut spheres = Vec::new();
    let mut rows: Vec<usize> = Vec::new();
    let mut orig_atom: Vec<u32> = Vec::new();
    let mut instance_molecule = Vec::new();
    let mut keep = Vec::new();
    let mut first = vec![0u64];
    let mut orig_first = Vec::new();
    let mut orig_instance = Vec::new();
    for k in 0..inst.instances() {
        let m = inst.instance_molecule[k];
        let key = (m, answers(k));
        let mol = inst.molecules[m as usize].clone();
        let range = mol.first as usize..(mol.first + mol.atoms) as usize;
        let (variant, counts) = match variants.get(&key) {
            Some(v) => v.clone(),
            None => {
                let start = spheres.len();
                for (a, i) in range.clone().enumerate() {
                    let mut t = scene.spheres[i];
                    if c.apply(&mut t, atoms.as_ref(), i, 0, &key.1) {
                        spheres.push(t);
                        rows.push(i);
                        orig_atom.push(a as u32);
                    }
                }
                let n = (spheres.len() - start) as u32;
                let v = (n > 0).then(|| {
                    molecules.push(super::instanced::Molecule {
                        first: start as u32,
                        atoms: n,
                        ..mol.clone()
                    });
                    tree_regions.push(inst.tree_regions[m as usize]);
                    molecules.len() as u32 - 1
                });
                let counts: Vec<u64> = (0..c.rules.len())
                    .map(|r| {
                        range
                            .clone()
                            .filter(|&i| c.selects(r, atoms.as_ref(), i, 0, &key.1))
                            .count() as u64
                    })
                    .collect();
                variants.insert(key.clone(), (v, counts.clone()));
                (v, counts)
            }
        };
        for (n, k) in applied.selected.iter_mut().zip(&counts) {
            *n += k;
        }
        let shown = variant.map_or(0, |v| molecules[v as usize].atoms);
        applied.hidden += (mol.atoms - shown) as u64;
        if let Some(v) = variant {
            let vm = &molecules[v as usize];
            applied.translucent += spheres[vm.first as usize..(vm.first + vm.atoms) as usize]
                .iter()
                .filter(|s| s.color[3] < 255)
                .count() as u64;
            instance_molecule.push(v);
            keep.push(k);
            first.push(first.last().copied().unwrap_or(0) + vm.atoms as u64);
            orig_first.push(inst.first[k]);
            orig_instance.push(k as u32);
        }
    }
    if keep.is_empty() {
        return Err(SceneError::Invalid(format!(
            "{}: the rules hide every sphere",
            scene.source
        )));
    }
    inst.transforms = match &inst.transforms {
        super::instanced::Transforms::Rigid(v) => {
            super::instanced::Transforms::Rigid(keep.iter().map(|&k| v[k]).collect())
        }
        super::instanced::Transforms::Affine(v) => {
            super::instanced::Transforms::Affine(keep.iter().map(|&k| v[k]).collect())
        }
    };
    inst.molecules = molecules;
    inst.tree_regions = tree_regions;
    inst.instance_molecule = instance_molecule;
    inst.first = first;
    scene.spheres = spheres;
    scene.atoms = atoms.map(|a| a.pick(rows.into_iter()));
    if applied.hidden > 0 {
        scene.origin = Some(Origin::Instanced {
            instance: orig_instance,
            first: orig_first,
            atom: orig_atom,
            total: represented,
        });
    }
    scene.instancing = Some(inst);
    Ok((scene, applied))
}

/// Scene ids (what the GPU draws) to input-order indices (what the id
/// AOV names) after rules hid spheres.
#[derive(Clone, Debug, PartialEq)]
pub struct IdMap {
    origin: Origin,
    /// Instanced: per instance its first scene id and its molecule's first
    /// stored atom.
    scene_first: Vec<u64>,
    mol_first: Vec<u32>,
}

impl IdMap {
    /// Spheres as loaded.
    pub fn total(&self) -> Option<u64> {
        match &self.origin {
            Origin::Instanced { total, .. } | Origin::Plain { total, .. } => Some(*total),
        }
    }

    /// The input index of scene id `id`.
    pub fn input(&self, id: u64) -> u64 {
        self.locate(id).0
    }

    /// The input index of scene id `id`, and for an instanced scene the
    /// instance and atom (in its molecule) as loaded.
    pub fn locate(&self, id: u64) -> (u64, Option<(u32, u32)>) {
        match &self.origin {
            Origin::Plain { index, .. } => (index.get(id as usize).map_or(id, |&v| v as u64), None),
            Origin::Instanced {
                instance,
                first,
                atom,
                ..
            } => {
                let k = self.scene_first.partition_point(|&f| f <= id);
                let Some(k) = k.checked_sub(1).filter(|&k| k < instance.len()) else {
                    return (id, None);
                };
                let a = (id - self.scene_first[k]) as usize + self.mol_first[k] as usize;
                let orig = atom.get(a).copied().unwrap_or(0);
                (first[k] + orig as u64, Some((instance[k], orig)))
            }
        }
    }
}

impl Scene {
    /// The map from scene ids to input indices (None: nothing hidden, the
    /// two are the same).
    pub fn id_map(&self) -> Option<IdMap> {
        let origin = self.origin.clone()?;
        let (scene_first, mol_first) = match &self.instancing {
            Some(inst) => (
                inst.first.clone(),
                inst.instance_molecule
                    .iter()
                    .map(|&m| inst.molecules[m as usize].first)
                    .collect(),
            ),
            None => (Vec::new(), Vec::new()),
        };
        Some(IdMap {
            origin,
            scene_first,
            mol_first,
        })
    }

    /// Atoms as loaded (a trajectory frame's count): the spheres, or
    /// before rules hid some, their count then.
    pub fn input_count(&self) -> u64 {
        match &self.origin {
            Some(Origin::Plain { total, .. }) | Some(Origin::Instanced { total, .. }) => *total,
            None => self.represented(),
        }
    }

    /// Whether any sphere is see-through (alpha below 1).
    pub fn has_translucent(&self) -> bool {
        self.spheres.iter().any(|s| s.color[3] < 255)
    }
}
