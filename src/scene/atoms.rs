//! What selections and colour schemes read about each atom: chain, residue
//! name and number, atom name, element, HETATM flag and B-factor, kept
//! beside `Scene::spheres` (one row per sphere record: for an instanced
//! scene, per stored molecule atom). Strings are interned: a row is 22
//! bytes.

use std::collections::HashMap;

use super::elements::Element;

/// Which columns a file gave (an `.xyz` names elements only; a `.gro`
/// has no chains, HETATM flags or B-factors).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Known {
    pub chain: bool,
    pub residue: bool,
    pub name: bool,
    pub element: bool,
    pub hetatm: bool,
    pub bfactor: bool,
}

impl Known {
    /// Everything a PDB or mmCIF file gives.
    pub const MOLECULAR: Known = Known {
        chain: true,
        residue: true,
        name: true,
        element: true,
        hetatm: true,
        bfactor: true,
    };
}

/// One atom's fields as a reader sees them (bytes as written, trimmed).
#[derive(Clone, Copy, Debug, Default)]
pub struct AtomInfo<'a> {
    pub chain: &'a [u8],
    pub resname: &'a [u8],
    pub resid: i32,
    pub name: &'a [u8],
    pub hetatm: bool,
    pub bfactor: f32,
}

/// Interned strings: an id per distinct byte string.
#[derive(Clone, Debug, Default)]
pub struct Strings {
    list: Vec<String>,
    map: HashMap<Vec<u8>, u32>,
}

impl Strings {
    pub fn intern(&mut self, s: &[u8]) -> u32 {
        if let Some(&i) = self.map.get(s) {
            return i;
        }
        let i = self.list.len() as u32;
        self.list.push(String::from_utf8_lossy(s).into_owned());
        self.map.insert(s.to_vec(), i);
        i
    }

    pub fn get(&self, id: u32) -> &str {
        self.list.get(id as usize).map_or("", String::as_str)
    }

    pub fn len(&self) -> usize {
        self.list.len()
    }

    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// Every string with its id.
    pub fn iter(&self) -> impl Iterator<Item = (u32, &str)> {
        self.list
            .iter()
            .enumerate()
            .map(|(i, s)| (i as u32, s.as_str()))
    }
}

/// The atom table: column vectors, one row per sphere record.
#[derive(Clone, Debug, Default)]
pub struct Atoms {
    pub known: Known,
    /// Chain, residue and atom names share one interner.
    pub strings: Strings,
    pub chain: Vec<u32>,
    pub resname: Vec<u32>,
    pub resid: Vec<i32>,
    pub name: Vec<u32>,
    pub element: Vec<Element>,
    pub hetatm: Vec<bool>,
    pub bfactor: Vec<f32>,
    /// (interning cache: consecutive atoms share chain and residue)
    last: [(Vec<u8>, u32); 2],
}

impl Atoms {
    pub fn new(known: Known) -> Self {
        Atoms {
            known,
            ..Default::default()
        }
    }

    pub fn len(&self) -> usize {
        self.element.len()
    }

    pub fn is_empty(&self) -> bool {
        self.element.is_empty()
    }

    fn cached(&mut self, k: usize, s: &[u8]) -> u32 {
        if self.last[k].0 == s && !self.strings.is_empty() {
            return self.last[k].1;
        }
        let id = self.strings.intern(s);
        self.last[k] = (s.to_vec(), id);
        id
    }

    pub fn push(&mut self, element: Element, info: &AtomInfo) {
        let chain = self.cached(0, info.chain);
        let resname = self.cached(1, info.resname);
        let name = self.strings.intern(info.name);
        self.chain.push(chain);
        self.resname.push(resname);
        self.resid.push(info.resid);
        self.name.push(name);
        self.element.push(element);
        self.hetatm.push(info.hetatm);
        self.bfactor.push(info.bfactor);
    }

    /// The rows `index` names, in that order (assembly copies, molecule
    /// regrouping, subsets).
    pub fn pick(&self, index: impl Iterator<Item = usize>) -> Atoms {
        let mut a = Atoms {
            known: self.known,
            strings: self.strings.clone(),
            ..Default::default()
        };
        for i in index {
            a.chain.push(self.chain[i]);
            a.resname.push(self.resname[i]);
            a.resid.push(self.resid[i]);
            a.name.push(self.name[i]);
            a.element.push(self.element[i]);
            a.hetatm.push(self.hetatm[i]);
            a.bfactor.push(self.bfactor[i]);
        }
        a
    }

    /// Row `i`'s residue name.
    pub fn resname_of(&self, i: usize) -> &str {
        self.strings.get(self.resname[i])
    }
}
