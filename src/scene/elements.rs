//! Chemical elements: van der Waals radii, CPK-style colours and element
//! guessing from atom names (for files without element columns).
//!
//! Radii follow Bondi (1964) where Bondi gives a value, Mantina et al. (2009)
//! for the remaining main-group elements, and 2.00 Å for transition metals
//! that neither defines (a common visualisation default). Hydrogen uses
//! Rowland & Taylor's 1.10 Å. Unknown elements get [`UNKNOWN_RADIUS`].
//! Colours are the Jmol CPK palette.

/// Radius used for atoms whose element is unknown (carbon-sized).
pub const UNKNOWN_RADIUS: f32 = 1.70;
/// Colour used for atoms whose element is unknown (Jmol's "other" pink).
pub const UNKNOWN_COLOR: [u8; 4] = [0xFF, 0x14, 0x93, 0xFF];

struct Info {
    symbol: &'static str,
    radius: f32,
    rgb: u32,
}

const fn e(symbol: &'static str, radius: f32, rgb: u32) -> Info {
    Info {
        symbol,
        radius,
        rgb,
    }
}

/// Indexed by atomic number - 1.
static TABLE: [Info; 92] = [
    e("H", 1.10, 0xFFFFFF),
    e("He", 1.40, 0xD9FFFF),
    e("Li", 1.82, 0xCC80FF),
    e("Be", 1.53, 0xC2FF00),
    e("B", 1.92, 0xFFB5B5),
    e("C", 1.70, 0x909090),
    e("N", 1.55, 0x3050F8),
    e("O", 1.52, 0xFF0D0D),
    e("F", 1.47, 0x90E050),
    e("Ne", 1.54, 0xB3E3F5),
    e("Na", 2.27, 0xAB5CF2),
    e("Mg", 1.73, 0x8AFF00),
    e("Al", 1.84, 0xBFA6A6),
    e("Si", 2.10, 0xF0C8A0),
    e("P", 1.80, 0xFF8000),
    e("S", 1.80, 0xFFFF30),
    e("Cl", 1.75, 0x1FF01F),
    e("Ar", 1.88, 0x80D1E3),
    e("K", 2.75, 0x8F40D4),
    e("Ca", 2.31, 0x3DFF00),
    e("Sc", 2.11, 0xE6E6E6),
    e("Ti", 2.00, 0xBFC2C7),
    e("V", 2.00, 0xA6A6AB),
    e("Cr", 2.00, 0x8A99C7),
    e("Mn", 2.00, 0x9C7AC7),
    e("Fe", 2.00, 0xE06633),
    e("Co", 2.00, 0xF090A0),
    e("Ni", 1.63, 0x50D050),
    e("Cu", 1.40, 0xC88033),
    e("Zn", 1.39, 0x7D80B0),
    e("Ga", 1.87, 0xC28F8F),
    e("Ge", 2.11, 0x668F8F),
    e("As", 1.85, 0xBD80E3),
    e("Se", 1.90, 0xFFA100),
    e("Br", 1.85, 0xA62929),
    e("Kr", 2.02, 0x5CB8D1),
    e("Rb", 3.03, 0x702EB0),
    e("Sr", 2.49, 0x00FF00),
    e("Y", 2.00, 0x94FFFF),
    e("Zr", 2.00, 0x94E0E0),
    e("Nb", 2.00, 0x73C2C9),
    e("Mo", 2.00, 0x54B5B5),
    e("Tc", 2.00, 0x3B9E9E),
    e("Ru", 2.00, 0x248F8F),
    e("Rh", 2.00, 0x0A7D8C),
    e("Pd", 1.63, 0x006985),
    e("Ag", 1.72, 0xC0C0C0),
    e("Cd", 1.58, 0xFFD98F),
    e("In", 1.93, 0xA67573),
    e("Sn", 2.17, 0x668080),
    e("Sb", 2.06, 0x9E63B5),
    e("Te", 2.06, 0xD47A00),
    e("I", 1.98, 0x940094),
    e("Xe", 2.16, 0x429EB0),
    e("Cs", 3.43, 0x57178F),
    e("Ba", 2.68, 0x00C900),
    e("La", 2.00, 0x70D4FF),
    e("Ce", 2.00, 0xFFFFC7),
    e("Pr", 2.00, 0xD9FFC7),
    e("Nd", 2.00, 0xC7FFC7),
    e("Pm", 2.00, 0xA3FFC7),
    e("Sm", 2.00, 0x8FFFC7),
    e("Eu", 2.00, 0x61FFC7),
    e("Gd", 2.00, 0x45FFC7),
    e("Tb", 2.00, 0x30FFC7),
    e("Dy", 2.00, 0x1FFFC7),
    e("Ho", 2.00, 0x00FF9C),
    e("Er", 2.00, 0x00E675),
    e("Tm", 2.00, 0x00D452),
    e("Yb", 2.00, 0x00BF38),
    e("Lu", 2.00, 0x00AB24),
    e("Hf", 2.00, 0x4DC2FF),
    e("Ta", 2.00, 0x4DA6FF),
    e("W", 2.00, 0x2194D6),
    e("Re", 2.00, 0x267DAB),
    e("Os", 2.00, 0x266696),
    e("Ir", 2.00, 0x175487),
    e("Pt", 1.75, 0xD0D0E0),
    e("Au", 1.66, 0xFFD123),
    e("Hg", 1.55, 0xB8B8D0),
    e("Tl", 1.96, 0xA6544D),
    e("Pb", 2.02, 0x575961),
    e("Bi", 2.07, 0x9E4FB5),
    e("Po", 1.97, 0xAB5C00),
    e("At", 2.02, 0x754F45),
    e("Rn", 2.20, 0x428296),
    e("Fr", 3.48, 0x420066),
    e("Ra", 2.83, 0x007D00),
    e("Ac", 2.00, 0x70ABFA),
    e("Th", 2.00, 0x00BAFF),
    e("Pa", 2.00, 0x00A1FF),
    e("U", 1.86, 0x008FFF),
];

/// An element, or "unknown". Cheap to copy; look-ups are table indexing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Element(u8); // atomic number, 0 = unknown

impl Element {
    pub const UNKNOWN: Element = Element(0);
    /// A water model's massless site (TIP4P `MW`, TIP5P `LP1`/`LP2`): kept,
    /// so atom counts match trajectories, but with a radius of 0.1 Å it sits
    /// unseen inside its oxygen instead of showing as a 1.7 Å unknown atom.
    pub const VIRTUAL: Element = Element(255);
    pub const H: Element = Element(1);
    pub const B: Element = Element(5);
    pub const C: Element = Element(6);
    pub const N: Element = Element(7);
    pub const O: Element = Element(8);
    pub const F: Element = Element(9);
    pub const NA: Element = Element(11);
    pub const MG: Element = Element(12);
    pub const P: Element = Element(15);
    pub const S: Element = Element(16);
    pub const CL: Element = Element(17);
    pub const K: Element = Element(19);
    pub const CA: Element = Element(20);
    pub const FE: Element = Element(26);
    pub const ZN: Element = Element(30);
    pub const BE: Element = Element(4);
    pub const CS: Element = Element(55);

    /// Atomic number (0 for unknown).
    pub fn number(self) -> u8 {
        self.0
    }

    /// Element with the given atomic number, if it is in the table.
    pub fn from_number(z: u32) -> Option<Element> {
        (1..=TABLE.len() as u32)
            .contains(&z)
            .then_some(Element(z as u8))
    }

    fn info(self) -> Option<&'static Info> {
        (self.0 as usize).checked_sub(1).and_then(|i| TABLE.get(i))
    }

    /// Symbol with conventional capitalisation ("C", "Cl"); "X" if unknown.
    pub fn symbol(self) -> &'static str {
        if self == Element::VIRTUAL {
            return "VS";
        }
        self.info().map_or("X", |i| i.symbol)
    }

    /// Van der Waals radius in Å.
    pub fn radius(self) -> f32 {
        if self == Element::VIRTUAL {
            return 0.1;
        }
        self.info().map_or(UNKNOWN_RADIUS, |i| i.radius)
    }

    /// CPK colour, RGBA with A = 255.
    pub fn color(self) -> [u8; 4] {
        if self == Element::VIRTUAL {
            return Element::O.color();
        }
        self.info().map_or(UNKNOWN_COLOR, |i| {
            [(i.rgb >> 16) as u8, (i.rgb >> 8) as u8, i.rgb as u8, 0xFF]
        })
    }

    /// Parses an element symbol, case-insensitively, ignoring surrounding
    /// blanks ("CL", " C", "Fe"). Deuterium and tritium map to hydrogen.
    pub fn from_symbol(s: &[u8]) -> Option<Element> {
        let s = trim(s);
        let (a, b) = match *s {
            [a] => (a.to_ascii_uppercase(), 0),
            [a, b] => (a.to_ascii_uppercase(), b.to_ascii_lowercase()),
            _ => return None,
        };
        // Fast path for the elements that make up almost every biomolecule.
        if b == 0 {
            match a {
                b'C' => return Some(Element::C),
                b'H' | b'D' | b'T' => return Some(Element::H),
                b'N' => return Some(Element::N),
                b'O' => return Some(Element::O),
                b'S' => return Some(Element::S),
                b'P' => return Some(Element::P),
                _ => {}
            }
        }
        TABLE
            .iter()
            .position(|i| {
                let sym = i.symbol.as_bytes();
                sym[0] == a && sym.get(1).copied().unwrap_or(0) == b
            })
            .map(|i| Element(i as u8 + 1))
    }

    /// Element from an element symbol or an atomic number ("6").
    pub fn from_symbol_or_number(s: &[u8]) -> Option<Element> {
        let t = trim(s);
        if !t.is_empty() && t.iter().all(u8::is_ascii_digit) {
            let z = std::str::from_utf8(t).ok()?.parse::<u32>().ok()?;
            return Element::from_number(z);
        }
        Element::from_symbol(t)
    }
}

/// Trims ASCII blanks (space, tab) at both ends.
pub(crate) fn trim(s: &[u8]) -> &[u8] {
    let start = s
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(s.len());
    let end = s
        .iter()
        .rposition(|b| !b.is_ascii_whitespace())
        .map_or(start, |e| e + 1);
    &s[start..end]
}

/// Force-field atom names whose first letters would give the wrong element
/// (CHARMM ions and water oxygen).
fn special_name(name: &[u8]) -> Option<Element> {
    Some(match name {
        b"CLA" => Element::CL,
        b"SOD" => Element::NA,
        b"POT" => Element::K,
        b"CAL" => Element::CA,
        b"CES" => Element::CS,
        b"ZN2" => Element::ZN,
        b"MG2" => Element::MG,
        b"OH2" | b"OW" => Element::O,
        b"MW" | b"MW1" | b"MW2" | b"LP" | b"LP1" | b"LP2" | b"EP" | b"EP1" | b"EP2" => {
            Element::VIRTUAL
        }
        _ => return None,
    })
}

/// Guesses the element of a PDB atom from its name field (columns 13-16,
/// exactly 4 bytes when the line is long enough) and residue name, for files
/// whose element columns 77-78 are blank.
///
/// PDB alignment rule: one-letter elements start in column 14, two-letter
/// elements in column 13, so " CA " is an alpha carbon and "CA  " calcium.
/// Four-character names start in column 13 too ("HG21" is a hydrogen, not
/// mercury), so those fall back to their first letter.
pub fn guess_pdb(name_field: &[u8], res_name: &[u8]) -> Element {
    let name = trim(name_field);
    if name.is_empty() {
        return Element::UNKNOWN;
    }
    if let Some(el) = special_name(name) {
        return el;
    }
    // A single-atom residue named like its atom is an ion: " MG " in "MG".
    if name.len() <= 2
        && name == trim(res_name)
        && let Some(el) = Element::from_symbol(name)
    {
        return el;
    }
    let first = name_field[0];
    if first.is_ascii_alphabetic() && name_field.len() >= 2 {
        let first_up = first.to_ascii_uppercase();
        // Long names are organic atoms with numbered suffixes, not metals.
        let long = (first_up == b'H' && name.len() >= 3)
            || (name.len() >= 4 && matches!(first_up, b'C' | b'N' | b'O'));
        if long {
            return Element::from_symbol(&[first_up]).unwrap_or(Element::UNKNOWN);
        }
        if name_field[1].is_ascii_alphabetic()
            && let Some(el) = Element::from_symbol(&name_field[..2])
        {
            return el;
        }
        return Element::from_symbol(&[first]).unwrap_or(Element::UNKNOWN);
    }
    // Column 13 blank or a digit ("1HB "): the element is column 14.
    guess_name(&name_field[1..], b"")
}

/// Guesses the element from a free-form atom name (GRO, mmCIF without
/// type_symbol): leading digits are skipped, then the first letter decides,
/// with two-letter symbols only for ions (name equals residue name).
pub fn guess_name(name: &[u8], res_name: &[u8]) -> Element {
    let name = trim(name);
    if let Some(el) = special_name(name) {
        return el;
    }
    if !res_name.is_empty()
        && name.len() <= 2
        && name.eq_ignore_ascii_case(trim(res_name))
        && let Some(el) = Element::from_symbol(name)
    {
        return el;
    }
    let letters = match name.iter().position(|b| b.is_ascii_alphabetic()) {
        Some(i) => &name[i..],
        None => return Element::UNKNOWN,
    };
    if let Some(el) = Element::from_symbol(&letters[..1]) {
        return el;
    }
    // No one-letter element ("MG", "ZN" written without a matching residue).
    if letters.len() >= 2
        && letters[1].is_ascii_alphabetic()
        && let Some(el) = Element::from_symbol(&letters[..2])
    {
        return el;
    }
    Element::UNKNOWN
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn symbols_and_radii() {
        assert_eq!(Element::from_symbol(b"C"), Some(Element::C));
        assert_eq!(Element::from_symbol(b" C"), Some(Element::C));
        assert_eq!(Element::from_symbol(b"CL"), Some(Element::CL));
        assert_eq!(Element::from_symbol(b"cl"), Some(Element::CL));
        assert_eq!(Element::from_symbol(b"Fe"), Some(Element::FE));
        assert_eq!(Element::from_symbol(b"BE"), Some(Element::BE));
        assert_eq!(Element::from_symbol(b"D"), Some(Element::H));
        assert_eq!(Element::from_symbol(b"XX"), None);
        assert_eq!(Element::from_symbol(b"  "), None);
        assert_eq!(Element::from_symbol(b"ABC"), None);
        assert_eq!(Element::from_symbol_or_number(b"8"), Some(Element::O));
        assert_eq!(Element::from_symbol_or_number(b"0"), None);
        assert_eq!(Element::from_symbol_or_number(b"999"), None);
        assert_eq!(Element::C.radius(), 1.70);
        assert_eq!(Element::N.radius(), 1.55);
        assert_eq!(Element::O.radius(), 1.52);
        assert_eq!(Element::S.radius(), 1.80);
        assert_eq!(Element::P.radius(), 1.80);
        assert_eq!(Element::H.radius(), 1.10);
        assert_eq!(Element::UNKNOWN.radius(), 1.70);
        assert_eq!(Element::CL.symbol(), "Cl");
        assert_eq!(Element::UNKNOWN.symbol(), "X");
        assert_eq!(Element::C.color(), [0x90, 0x90, 0x90, 0xFF]);
        // Every table entry round-trips through its symbol.
        for z in 1..=92 {
            let el = Element::from_number(z).unwrap();
            assert_eq!(
                Element::from_symbol(el.symbol().as_bytes()),
                Some(el),
                "{z}"
            );
            assert!(el.radius() > 0.5 && el.radius() < 4.0);
        }
    }

    #[test]
    fn pdb_name_guessing() {
        assert_eq!(guess_pdb(b" CA ", b"ALA"), Element::C);
        assert_eq!(guess_pdb(b"CA  ", b"CA "), Element::CA);
        assert_eq!(guess_pdb(b"CA  ", b"XYZ"), Element::CA);
        assert_eq!(guess_pdb(b" N  ", b"ALA"), Element::N);
        assert_eq!(guess_pdb(b" OH2", b"TIP"), Element::O);
        assert_eq!(guess_pdb(b" CLA", b"CLA"), Element::CL);
        assert_eq!(guess_pdb(b" SOD", b"SOD"), Element::NA);
        assert_eq!(guess_pdb(b" POT", b"POT"), Element::K);
        assert_eq!(guess_pdb(b"HG21", b"THR"), Element::H);
        assert_eq!(guess_pdb(b"HD11", b"LEU"), Element::H);
        assert_eq!(guess_pdb(b"HG1 ", b"THR"), Element::H);
        assert_eq!(
            guess_pdb(b"HG  ", b"HG "),
            Element::from_symbol(b"HG").unwrap()
        );
        assert_eq!(guess_pdb(b"1HB ", b"ALA"), Element::H);
        assert_eq!(guess_pdb(b" HN1", b"PRO"), Element::H);
        assert_eq!(guess_pdb(b"FE  ", b"HEM"), Element::FE);
        assert_eq!(guess_pdb(b"C210", b"POPC"), Element::C);
        // Column-14 alignment with an ion residue: read as the ion.
        assert_eq!(guess_pdb(b" MG ", b" MG"), Element::MG);
        // Column-14 alignment, not an ion residue: M is no element, so "MG".
        assert_eq!(guess_pdb(b" MG ", b"BEF"), Element::MG);
        assert_eq!(guess_pdb(b" BE ", b"BEF"), Element::B);
        assert_eq!(guess_pdb(b"    ", b"ALA"), Element::UNKNOWN);
    }

    #[test]
    fn free_name_guessing() {
        assert_eq!(guess_name(b"OW", b"SOL"), Element::O);
        assert_eq!(guess_name(b"HW1", b"SOL"), Element::H);
        assert_eq!(guess_name(b"CA", b"ALA"), Element::C);
        assert_eq!(guess_name(b"NA", b"NA"), Element::NA);
        assert_eq!(guess_name(b"CL", b"CL"), Element::CL);
        assert_eq!(guess_name(b"ZN", b"ZN2"), Element::ZN);
        assert_eq!(guess_name(b"1HB", b"ALA"), Element::H);
        assert_eq!(guess_name(b"MW", b"SOL"), Element::VIRTUAL);
        assert_eq!(guess_name(b"LP1", b"TIP5"), Element::VIRTUAL);
        assert_eq!(Element::VIRTUAL.radius(), 0.1);
        assert_eq!(guess_name(b"", b""), Element::UNKNOWN);
    }
}
