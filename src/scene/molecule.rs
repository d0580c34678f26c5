//! Shared machinery for molecular formats: region-id assignment
//! (model / chain / residue / atom), colouring, and biological assemblies.

use std::collections::HashMap;

use super::atoms::{AtomInfo, Atoms, Known};
use super::elements::Element;
use super::{ColorBy, MAX_LEVELS, MAX_SPHERES, Scene, SceneError, Sphere};

pub(crate) const LEVEL_NAMES: [&str; MAX_LEVELS] = ["model", "chain", "residue", "atom"];

/// A fixed palette for chain colouring: distinct, medium-light hues that
/// read well under shading (roughly Tableau 20 / PyMOL chain colours).
pub(crate) const PALETTE: [[u8; 3]; 20] = [
    [0x4E, 0x9A, 0xE8],
    [0xF2, 0x8E, 0x2B],
    [0x59, 0xC1, 0x5A],
    [0xE1, 0x57, 0x59],
    [0x9B, 0x7B, 0xD4],
    [0x76, 0xD7, 0xD0],
    [0xED, 0xC9, 0x48],
    [0xFF, 0x9D, 0xA7],
    [0xA0, 0x7E, 0x6B],
    [0xB0, 0xE0, 0x7A],
    [0x8C, 0xB4, 0xF0],
    [0xD6, 0x8F, 0xD6],
    [0xF7, 0xB6, 0x7C],
    [0x3F, 0xB8, 0x9A],
    [0xC9, 0xC9, 0x5A],
    [0x6F, 0x8F, 0xC7],
    [0xE6, 0x7E, 0x9E],
    [0x9E, 0xD9, 0xA5],
    [0xC4, 0x9C, 0x6E],
    [0xA8, 0xA8, 0xE8],
];

pub(crate) fn palette_color(i: u32) -> [u8; 4] {
    let [r, g, b] = PALETTE[i as usize % PALETTE.len()];
    [r, g, b, 0xFF]
}

/// Packs up to 7 bytes exactly (with the length), or hashes longer input
/// (FNV-1a with the top bit set, so the two kinds never collide). Used for
/// chain and residue keys without allocating.
pub(crate) fn key64(parts: &[&[u8]]) -> u64 {
    let len: usize = parts.iter().map(|p| p.len() + 1).sum();
    if len <= 8 {
        // Separator byte 0xFF keeps ("A","") and ("","A") apart.
        let mut buf = [0u8; 8];
        let mut i = 0;
        for p in parts {
            buf[i..i + p.len()].copy_from_slice(p);
            buf[i + p.len()] = 0xFF;
            i += p.len() + 1;
        }
        return u64::from_le_bytes(buf) & !(1 << 63);
    }
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in parts {
        for &b in p.iter().chain(std::iter::once(&0xFF)) {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h | (1 << 63)
}

/// One `BIOMOLECULE` / `assembly_id`: groups of chains with the operators
/// applied to them.
#[derive(Clone, Debug, Default)]
pub(crate) struct Assembly {
    pub id: u32,
    pub groups: Vec<AsmGroup>,
}

#[derive(Clone, Debug, Default)]
pub(crate) struct AsmGroup {
    /// Chain names the operators apply to (empty = every chain).
    pub chains: Vec<Vec<u8>>,
    /// Rows of a 3x4 matrix: rotation | translation.
    pub ops: Vec<[[f32; 4]; 3]>,
}

/// Picks assembly `id` or explains which ones exist.
pub(crate) fn find_assembly<'a>(
    name: &str,
    list: &'a [Assembly],
    id: u32,
) -> Result<&'a Assembly, SceneError> {
    list.iter().find(|a| a.id == id).ok_or_else(|| {
        let have: Vec<String> = list.iter().map(|a| a.id.to_string()).collect();
        SceneError::Invalid(if have.is_empty() {
            format!("{name}: assembly {id} not found (the file defines no assemblies)")
        } else {
            format!(
                "{name}: assembly {id} not found (the file defines {})",
                have.join(", ")
            )
        })
    })
}

/// Accumulates atoms and assigns dense region ids: level 1 per
/// (level 0, chain), level 2 by change detection of the residue key, level 3
/// the atom's index.
pub(crate) struct MolBuilder {
    spheres: Vec<Sphere>,
    chain_ids: HashMap<(u32, u64), u32>,
    last_chain: Option<(u32, u64, u32)>,
    residues: u32,
    last_res: Option<(u32, u128)>,
    /// When building an assembly: per atom, the interned name its chain has
    /// in the assembly chain lists.
    asm_chain: Option<Vec<u32>>,
    asm_names: Vec<Vec<u8>>,
    last_asm: Option<u32>,
    /// Per assembly chain name (by index): the entity its first atom named.
    asm_entity: Vec<Vec<u8>>,
    /// What selections read, one row per atom.
    atoms: Atoms,
}

impl MolBuilder {
    pub(crate) fn new(capacity: usize, track_assembly: bool) -> Self {
        MolBuilder {
            spheres: Vec::with_capacity(capacity),
            chain_ids: HashMap::new(),
            last_chain: None,
            residues: 0,
            last_res: None,
            asm_chain: track_assembly.then(Vec::new),
            asm_names: Vec::new(),
            last_asm: None,
            asm_entity: Vec::new(),
            atoms: Atoms::new(Known::MOLECULAR),
        }
    }

    /// The atom fields the format gives (default: all of PDB/mmCIF's).
    pub(crate) fn set_known(&mut self, known: Known) {
        self.atoms.known = known;
    }

    /// Starts recording each atom's assembly chain name (instanced
    /// scenes: molecule types are made of chains), if not yet.
    pub(crate) fn track_assembly(&mut self) {
        if self.asm_chain.is_none() && self.spheres.is_empty() {
            self.asm_chain = Some(Vec::new());
        }
    }

    /// Atoms added so far.
    pub(crate) fn len(&self) -> usize {
        self.spheres.len()
    }

    /// Adds one atom.
    #[inline]
    pub(crate) fn push(&mut self, center: [f32; 3], element: Element, keys: AtomKeys) {
        let AtomKeys {
            level0,
            chain,
            residue,
            asm_chain,
            entity,
            info,
        } = keys;
        self.atoms.push(element, &info);
        let chain_id = match self.last_chain {
            Some((l0, key, id)) if l0 == level0 && key == chain => id,
            _ => {
                let next = self.chain_ids.len() as u32;
                let id = *self.chain_ids.entry((level0, chain)).or_insert(next);
                self.last_chain = Some((level0, chain, id));
                id
            }
        };
        let res_id = match self.last_res {
            Some((c, key)) if c == chain_id && key == residue => self.residues - 1,
            _ => {
                self.residues += 1;
                self.last_res = Some((chain_id, residue));
                self.residues - 1
            }
        };
        if let Some(per_atom) = self.asm_chain.as_mut() {
            let cached = self
                .last_asm
                .filter(|&i| self.asm_names[i as usize] == asm_chain);
            let id = cached.unwrap_or_else(|| {
                match self.asm_names.iter().position(|n| n == asm_chain) {
                    Some(i) => i as u32,
                    None => {
                        self.asm_names.push(asm_chain.to_vec());
                        self.asm_entity.push(entity.to_vec());
                        self.asm_names.len() as u32 - 1
                    }
                }
            });
            self.last_asm = Some(id);
            per_atom.push(id);
        }
        self.spheres.push(Sphere {
            center,
            radius: element.radius(),
            color: element.color(),
            region: [level0, chain_id, res_id, 0],
        });
    }

    /// Applies the assembly (if any), colours and numbers atoms. An
    /// assembly whose copies would exceed [`MAX_SPHERES`] is refused before
    /// anything is allocated.
    pub(crate) fn finish(
        self,
        source: &str,
        color_by: ColorBy,
        assembly: Option<&Assembly>,
    ) -> Result<Scene, SceneError> {
        let mut picked = None;
        let mut spheres = match (assembly, &self.asm_chain) {
            (Some(asm), Some(per_atom)) => {
                let total = expanded_count(per_atom, &self.asm_names, asm);
                if total > MAX_SPHERES as u128 {
                    return Err(SceneError::Invalid(format!(
                        "{source}: assembly {} makes {total} spheres ({} operators over {} atoms), \
                         more than {MAX_SPHERES}, the most sphereshade renders",
                        asm.id,
                        asm.groups.iter().map(|g| g.ops.len()).sum::<usize>(),
                        self.spheres.len()
                    )));
                }
                let (out, from) = expand(&self.spheres, per_atom, &self.asm_names, asm);
                picked = Some(from);
                out
            }
            _ => self.spheres,
        };
        let atoms = match picked {
            Some(from) => self.atoms.pick(from.into_iter()),
            None => self.atoms,
        };
        for (i, s) in spheres.iter_mut().enumerate() {
            s.region[3] = i as u32;
            if color_by == ColorBy::Chain {
                s.color = palette_color(s.region[1]);
            }
        }
        Ok(Scene {
            spheres,
            level_names: LEVEL_NAMES.iter().map(|s| s.to_string()).collect(),
            source: source.to_string(),
            instancing: None,
            expanded: false,
            atoms: Some(atoms),
            origin: None,
        })
    }
}

/// What places an atom in the hierarchy: `chain` and `residue` are opaque
/// keys; `asm_chain` is the chain name assembly lists refer to and `entity`
/// its entity id (both ignored unless tracking assemblies); `info` what
/// selections read.
pub(crate) struct AtomKeys<'a> {
    pub level0: u32,
    pub chain: u64,
    pub residue: u128,
    pub asm_chain: &'a [u8],
    pub entity: &'a [u8],
    pub info: AtomInfo<'a>,
}

/// How an instanced scene's molecule types and instances come out of the
/// atoms read.
pub(crate) enum InstancedFrom<'a> {
    /// PetWorld: each model is a molecule type; each generator row
    /// instantiates one model (by index among the models read) with its
    /// operators. `names[i]`: the label of model index i.
    Models {
        rows: Vec<(u32, Vec<[[f32; 4]; 3]>)>,
        names: Vec<String>,
    },
    /// An assembly: each generator row's chains are a molecule type, its
    /// operators the instances. `paths`: the hierarchy path of an entity
    /// (cellPACK's dot-separated `pdbx_description`), by entity id.
    Assembly {
        asm: &'a Assembly,
        paths: HashMap<Vec<u8>, Vec<String>>,
        depth_names: Vec<String>,
    },
}

impl MolBuilder {
    /// The atoms read as an instanced scene (molecule types, instances, the
    /// hierarchy); the builder must have tracked assembly chains.
    pub(crate) fn finish_instanced(
        mut self,
        source: &str,
        color_by: ColorBy,
        from: InstancedFrom,
    ) -> Result<Scene, SceneError> {
        use super::instanced::InstancedBuilder;
        let per_atom = self.asm_chain.take().unwrap_or_default();
        if color_by == ColorBy::Chain {
            for s in &mut self.spheres {
                s.color = palette_color(s.region[1]);
            }
        }
        // A molecule's atoms with chain indices dense within it; `order`
        // collects the atoms' rows as the scene stores them.
        let order = std::cell::RefCell::new(Vec::new());
        let molecule = |pick: &dyn Fn(usize) -> bool| -> Vec<Sphere> {
            let mut chains: Vec<u32> = Vec::new();
            self.spheres
                .iter()
                .enumerate()
                .filter(|&(i, _)| pick(i))
                .map(|(i, s)| {
                    order.borrow_mut().push(i);
                    let c = match chains.iter().position(|&c| c == s.region[1]) {
                        Some(c) => c,
                        None => {
                            chains.push(s.region[1]);
                            chains.len() - 1
                        }
                    };
                    Sphere {
                        region: [c as u32, 0, 0, 0],
                        ..*s
                    }
                })
                .collect()
        };
        let op64 = |m: &[[f32; 4]; 3]| m.map(|r| r.map(f64::from));
        let mut b = InstancedBuilder::default();
        match from {
            InstancedFrom::Models { rows, names } => {
                let models = self
                    .spheres
                    .iter()
                    .map(|s| s.region[0] + 1)
                    .max()
                    .unwrap_or(0);
                // PetWorld's membrane entities have label_asym_ids MEM...
                let membrane: Vec<bool> = (0..models)
                    .map(|m| {
                        let mut atoms = self
                            .spheres
                            .iter()
                            .zip(&per_atom)
                            .filter(|(s, _)| s.region[0] == m)
                            .peekable();
                        atoms.peek().is_some()
                            && atoms.all(|(_, &a)| self.asm_names[a as usize].starts_with(b"MEM"))
                    })
                    .collect();
                let grouped = membrane.iter().any(|&m| m);
                b.depth_names = if grouped {
                    vec!["group".into(), "type".into()]
                } else {
                    vec!["type".into()]
                };
                let mut types: HashMap<u32, u32> = HashMap::new();
                for (model, ops) in rows {
                    if model >= models {
                        continue;
                    }
                    let m = match types.get(&model) {
                        Some(&m) => m,
                        None => {
                            let label = names
                                .get(model as usize)
                                .cloned()
                                .unwrap_or_else(|| format!("model {}", model + 1));
                            let node = if membrane[model as usize] {
                                b.node(&["membrane", &label])
                            } else {
                                b.node(&[&label])
                            };
                            let atoms = molecule(&|i| self.spheres[i].region[0] == model);
                            let m = b.molecule(&label, node, atoms);
                            types.insert(model, m);
                            m
                        }
                    };
                    for op in &ops {
                        b.instance_matrix(source, m, op64(op))?;
                    }
                }
            }
            InstancedFrom::Assembly {
                asm,
                paths,
                depth_names,
            } => {
                b.depth_names = depth_names;
                let mut types: Vec<(Vec<Vec<u8>>, u32)> = Vec::new();
                for (g, group) in asm.groups.iter().enumerate() {
                    let m = match types.iter().find(|(c, _)| *c == group.chains) {
                        Some(&(_, m)) => m,
                        None => {
                            let wanted: Vec<bool> = self
                                .asm_names
                                .iter()
                                .map(|n| group.chains.is_empty() || group.chains.contains(n))
                                .collect();
                            // the hierarchy path of the group's first chain's entity
                            let path = self
                                .asm_names
                                .iter()
                                .enumerate()
                                .find(|(i, _)| wanted[*i])
                                .and_then(|(i, _)| paths.get(&self.asm_entity[i]))
                                .cloned()
                                .unwrap_or_default();
                            let label = path.last().cloned().unwrap_or_else(|| {
                                let chains: Vec<String> = group
                                    .chains
                                    .iter()
                                    .map(|c| String::from_utf8_lossy(c).into_owned())
                                    .collect();
                                if chains.is_empty() {
                                    format!("assembly {} group {}", asm.id, g + 1)
                                } else {
                                    chains.join(",")
                                }
                            });
                            let refs: Vec<&str> = path.iter().map(String::as_str).collect();
                            let node = b.node(&refs);
                            let atoms = molecule(&|i| wanted[per_atom[i] as usize]);
                            let m = b.molecule(&label, node, atoms);
                            types.push((group.chains.clone(), m));
                            m
                        }
                    };
                    for op in &group.ops {
                        b.instance_matrix(source, m, op64(op))?;
                    }
                }
            }
        }
        let mut scene = b.finish(source)?;
        scene.atoms = Some(self.atoms.pick(order.into_inner().into_iter()));
        Ok(scene)
    }
}

/// Spheres an assembly would make: per group, operators x the atoms of its
/// chains (exact, in u128: no product can overflow).
fn expanded_count(per_atom: &[u32], names: &[Vec<u8>], asm: &Assembly) -> u128 {
    let mut per_name = vec![0u128; names.len()];
    for &a in per_atom {
        per_name[a as usize] += 1;
    }
    asm.groups
        .iter()
        .map(|g| {
            let atoms: u128 = names
                .iter()
                .zip(&per_name)
                .filter(|(n, _)| g.chains.is_empty() || g.chains.iter().any(|c| c == *n))
                .map(|(_, k)| *k)
                .sum();
            atoms * g.ops.len() as u128
        })
        .sum()
}

/// Builds the copies of an assembly. Level 0 becomes the copy index
/// (combined with the model when several models are loaded); chains and
/// residues are renumbered so each copy's are distinct regions.
/// Returns the copies and, per copy, the atom it copies.
fn expand(
    spheres: &[Sphere],
    per_atom: &[u32],
    names: &[Vec<u8>],
    asm: &Assembly,
) -> (Vec<Sphere>, Vec<usize>) {
    let models = spheres.iter().map(|s| s.region[0] + 1).max().unwrap_or(1);
    let mut out = Vec::new();
    let mut from = Vec::new();
    let mut copy = 0u32;
    for group in &asm.groups {
        let wanted: Vec<bool> = names
            .iter()
            .map(|n| group.chains.is_empty() || group.chains.iter().any(|c| c == n))
            .collect();
        for m in &group.ops {
            for (i, (s, &a)) in spheres.iter().zip(per_atom).enumerate() {
                if !wanted[a as usize] {
                    continue;
                }
                from.push(i);
                let [x, y, z] = s.center;
                let t = |r: &[f32; 4]| r[0] * x + r[1] * y + r[2] * z + r[3];
                let mut c = *s;
                c.center = [t(&m[0]), t(&m[1]), t(&m[2])];
                c.region[0] = copy.wrapping_mul(models).wrapping_add(s.region[0]);
                out.push(c);
            }
            copy += 1;
        }
    }
    // Renumber chains per (copy, old chain) and residues per (chain, old
    // residue) run, keeping ids dense.
    let mut chains: HashMap<(u32, u32), u32> = HashMap::new();
    let mut last: Option<(u32, u32, u32)> = None;
    let mut residues = 0u32;
    let mut last_res: Option<(u32, u32)> = None;
    for s in &mut out {
        let key = (s.region[0], s.region[1]);
        let chain = match last {
            Some((a, b, id)) if (a, b) == key => id,
            _ => {
                let next = chains.len() as u32;
                let id = *chains.entry(key).or_insert(next);
                last = Some((key.0, key.1, id));
                id
            }
        };
        if last_res != Some((chain, s.region[2])) {
            residues += 1;
            last_res = Some((chain, s.region[2]));
        }
        s.region[1] = chain;
        s.region[2] = residues - 1;
    }
    (out, from)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_exact_when_short() {
        assert_ne!(key64(&[b"A", b""]), key64(&[b"", b"A"]));
        assert_ne!(key64(&[b"A"]), key64(&[b"B"]));
        assert_eq!(key64(&[b"AB", b"CD"]), key64(&[b"AB", b"CD"]));
        assert_ne!(key64(&[b"LONGCHAINNAME"]), key64(&[b"LONGCHAINNAMF"]));
    }

    fn keys(level0: u32, chain: u64, residue: u128, asm_chain: &[u8]) -> AtomKeys<'_> {
        AtomKeys {
            level0,
            chain,
            residue,
            asm_chain,
            entity: b"",
            info: Default::default(),
        }
    }

    #[test]
    fn builder_regions() {
        let mut b = MolBuilder::new(0, true);
        let p = [0.0; 3];
        b.push(p, Element::C, keys(0, 1, 10, b"A"));
        b.push(p, Element::C, keys(0, 1, 10, b"A"));
        b.push(p, Element::C, keys(0, 1, 11, b"A"));
        b.push(p, Element::O, keys(0, 2, 11, b"B"));
        b.push(p, Element::O, keys(0, 1, 10, b"A")); // chain A again: same chain id
        let s = b.finish("t", ColorBy::Element, None).unwrap();
        let r: Vec<_> = s.spheres.iter().map(|s| s.region).collect();
        assert_eq!(
            r,
            vec![
                [0, 0, 0, 0],
                [0, 0, 0, 1],
                [0, 0, 1, 2],
                [0, 1, 2, 3],
                [0, 0, 3, 4]
            ]
        );
        assert_eq!(s.spheres[3].radius, Element::O.radius());
    }

    #[test]
    fn assembly_copies() {
        let mut b = MolBuilder::new(0, true);
        b.push([1.0, 0.0, 0.0], Element::C, keys(0, 1, 1, b"A"));
        b.push([2.0, 0.0, 0.0], Element::C, keys(0, 2, 2, b"B"));
        b.push([3.0, 0.0, 0.0], Element::C, keys(0, 3, 3, b"C"));
        let ident = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ];
        let shift = [
            [1.0, 0.0, 0.0, 10.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ];
        let asm = Assembly {
            id: 1,
            groups: vec![AsmGroup {
                chains: vec![b"A".to_vec(), b"C".to_vec()],
                ops: vec![ident, shift],
            }],
        };
        let s = b.finish("t", ColorBy::Chain, Some(&asm)).unwrap();
        let c: Vec<_> = s.spheres.iter().map(|s| s.center[0]).collect();
        assert_eq!(c, vec![1.0, 3.0, 11.0, 13.0]);
        let l0: Vec<_> = s.spheres.iter().map(|s| s.region[0]).collect();
        assert_eq!(l0, vec![0, 0, 1, 1]);
        let l1: Vec<_> = s.spheres.iter().map(|s| s.region[1]).collect();
        assert_eq!(l1, vec![0, 1, 2, 3]);
        assert_eq!(s.spheres[2].color, palette_color(2));
    }
}
