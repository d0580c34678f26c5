//! Instanced scenes from JSON: cellPACK packing results (the legacy
//! `results: [[t], [w, x, y, z]]` per ingredient, bead spheres from
//! `positions`/`radii`) and the mesoscale manifest of DESIGN.md (a strict
//! subset of Mol*'s Mesoscale Explorer `manifest.json`). Object keys are
//! read in file order: the expanded order follows it.

use super::instanced::InstancedBuilder;
use super::molecule::palette_color;
use super::{LoadOptions, Scene, SceneError, Sphere};
use glam::{DQuat, Vec3};
use serde::Deserialize;
use serde::de::{Deserializer, MapAccess, Visitor};
use std::path::Path;

/// A JSON object with its keys in file order.
struct Ordered<T>(Vec<(String, T)>);

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Ordered<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>> Visitor<'de> for V<T> {
            type Value = Ordered<T>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("an object")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<Ordered<T>, A::Error> {
                let mut v = Vec::new();
                while let Some((k, x)) = m.next_entry()? {
                    v.push((k, x));
                }
                Ok(Ordered(v))
            }
        }
        d.deserialize_map(V(std::marker::PhantomData))
    }
}

/// What kind of JSON document it is, by its top-level keys.
#[derive(Deserialize)]
struct Probe {
    compartments: Option<serde::de::IgnoredAny>,
    cytoplasme: Option<serde::de::IgnoredAny>,
    roots: Option<serde::de::IgnoredAny>,
    entities: Option<serde::de::IgnoredAny>,
}

pub(crate) fn parse(
    data: &[u8],
    name: &str,
    dir: &Path,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    let bad = |m: String| SceneError::Invalid(format!("{name}: {m}"));
    let json = |e: serde_json::Error| bad(format!("JSON: {e}"));
    let probe: Probe = serde_json::from_slice(data).map_err(json)?;
    if probe.compartments.is_some() || probe.cytoplasme.is_some() {
        let r: Results = serde_json::from_slice(data).map_err(json)?;
        cellpack(r, name)
    } else if probe.roots.is_some() || probe.entities.is_some() {
        let m: Manifest = serde_json::from_slice(data).map_err(json)?;
        manifest(m, name, dir, opts)
    } else {
        Err(bad(
            "not a cellPACK packing result (no compartments or cytoplasme) nor a manifest \
             (no roots or entities)"
                .into(),
        ))
    }
}

#[derive(Deserialize)]
struct Results {
    compartments: Option<Ordered<Compartment>>,
    cytoplasme: Option<Location>,
}

#[derive(Deserialize)]
struct Compartment {
    surface: Option<Location>,
    interior: Option<Location>,
}

#[derive(Deserialize)]
struct Location {
    ingredients: Ordered<Ingredient>,
}

#[derive(Deserialize)]
struct Ingredient {
    #[serde(default)]
    results: Vec<(Vec<f64>, Vec<f64>)>,
    /// Bead centres per level of detail.
    #[serde(default)]
    positions: Vec<Vec<[f64; 3]>>,
    #[serde(default)]
    radii: Vec<Vec<f64>>,
}

/// A cellPACK packing result: each ingredient a molecule type of bead
/// spheres (its finest level), each result an instance x' = R(q) x + t
/// with q given (w, x, y, z).
fn cellpack(r: Results, name: &str) -> Result<Scene, SceneError> {
    let bad = |m: String| SceneError::Invalid(format!("{name}: {m}"));
    let mut b = InstancedBuilder::default();
    b.depth_names = ["compartment", "location", "ingredient"]
        .map(String::from)
        .to_vec();
    // Ingredients in the expanded order: cytoplasme, then per compartment
    // its surface, then its interior.
    let mut all: Vec<(Vec<String>, String, Ingredient)> = Vec::new();
    if let Some(c) = r.cytoplasme {
        for (ing, x) in c.ingredients.0 {
            all.push((vec!["cytoplasme".into(), ing.clone()], ing, x));
        }
    }
    for (comp, c) in r.compartments.map(|c| c.0).unwrap_or_default() {
        for (loc, l) in [("surface", c.surface), ("interior", c.interior)] {
            for (ing, x) in l.map(|l| l.ingredients.0).unwrap_or_default() {
                all.push((vec![comp.clone(), loc.into(), ing.clone()], ing, x));
            }
        }
    }
    for (k, (path, label, ing)) in all.into_iter().enumerate() {
        let what = format!("ingredient {label}");
        let (Some(pos), Some(rad)) = (ing.positions.last(), ing.radii.last()) else {
            if ing.results.is_empty() {
                continue;
            }
            return Err(bad(format!(
                "{what} has instances but no bead positions/radii"
            )));
        };
        if pos.len() != rad.len() {
            return Err(bad(format!(
                "{what}: {} bead positions, {} radii",
                pos.len(),
                rad.len()
            )));
        }
        let color = palette_color(k as u32);
        let mut atoms = Vec::with_capacity(pos.len());
        for (p, &r) in pos.iter().zip(rad) {
            let c = p.map(|v| v as f32);
            if !(c.iter().all(|v| v.is_finite()) && r.is_finite() && r >= 0.0) {
                return Err(bad(format!(
                    "{what}: a bead at {p:?} radius {r} is not finite"
                )));
            }
            atoms.push(Sphere {
                center: c,
                radius: r as f32,
                color,
                region: [0; super::MAX_LEVELS],
            });
        }
        let refs: Vec<&str> = path.iter().map(String::as_str).collect();
        let node = b.node(&refs);
        let m = b.molecule(&label, node, atoms);
        for (i, (t, q)) in ing.results.iter().enumerate() {
            let (&[tx, ty, tz], &[w, x, y, z]) = (t.as_slice(), q.as_slice()) else {
                return Err(bad(format!(
                    "{what}: result {i} is not [[x, y, z], [w, x, y, z]]"
                )));
            };
            b.instance_quat(name, m, DQuat::from_xyzw(x, y, z, w), [tx, ty, tz])?;
        }
    }
    b.finish(name)
}

#[derive(Deserialize)]
struct Manifest {
    #[serde(default)]
    roots: Vec<TreeNode>,
    entities: Vec<Entity>,
}

#[derive(Deserialize)]
struct TreeNode {
    id: String,
    label: Option<String>,
    #[serde(default)]
    children: Vec<TreeNode>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Entity {
    label: String,
    file: String,
    color: Option<serde_json::Value>,
    size_factor: Option<f64>,
    #[serde(default)]
    groups: Vec<String>,
    instances: Instances,
    /// sphereshade's extension: `none` (default) or `bbox` (the entity's
    /// atoms centred on their bounding box first).
    center: Option<String>,
}

#[derive(Deserialize)]
struct Instances {
    positions: Array,
    rotations: Rotations,
}

#[derive(Deserialize)]
struct Rotations {
    variant: String,
    data: Array,
}

/// Numbers inline or a view of a little-endian f32 binary file.
#[derive(Deserialize)]
#[serde(untagged)]
enum Array {
    Inline(Vec<f64>),
    File { file: String, view: View },
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct View {
    byte_offset: u64,
    byte_length: u64,
}

impl Array {
    fn values(&self, dir: &Path, what: &str) -> Result<Vec<f64>, String> {
        match self {
            Array::Inline(v) => Ok(v.clone()),
            Array::File { file, view } => {
                let path = dir.join(file);
                let bytes =
                    std::fs::read(&path).map_err(|e| format!("{what}: {}: {e}", path.display()))?;
                let end = view.byte_offset.checked_add(view.byte_length);
                let slice = end
                    .filter(|&e| e <= bytes.len() as u64 && view.byte_length % 4 == 0)
                    .map(|e| &bytes[view.byte_offset as usize..e as usize])
                    .ok_or_else(|| {
                        format!(
                            "{what}: the view {}+{} is outside {} ({} bytes) or not whole f32 values",
                            view.byte_offset,
                            view.byte_length,
                            path.display(),
                            bytes.len()
                        )
                    })?;
                Ok(slice
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64)
                    .collect())
            }
        }
    }
}

/// Paths from a root to every node of the tree, by node id.
fn tree_paths(nodes: &[TreeNode], above: &mut Vec<String>, out: &mut Vec<(String, Vec<String>)>) {
    for n in nodes {
        above.push(n.label.clone().unwrap_or_else(|| n.id.clone()));
        out.push((n.id.clone(), above.clone()));
        tree_paths(&n.children, above, out);
        above.pop();
    }
}

fn parse_color(v: &serde_json::Value) -> Option<[u8; 4]> {
    match v {
        serde_json::Value::String(s) => {
            let h = s.strip_prefix('#').unwrap_or(s);
            let n = u32::from_str_radix(h, 16).ok().filter(|_| h.len() == 6)?;
            Some([(n >> 16) as u8, (n >> 8) as u8, n as u8, 255])
        }
        serde_json::Value::Number(n) => {
            let n = n.as_u64().filter(|&n| n <= 0xFF_FFFF)?;
            Some([(n >> 16) as u8, (n >> 8) as u8, n as u8, 255])
        }
        serde_json::Value::Array(a) if a.len() == 3 => {
            let c: Option<Vec<u8>> = a
                .iter()
                .map(|x| x.as_u64().filter(|&x| x <= 255).map(|x| x as u8))
                .collect();
            c.map(|c| [c[0], c[1], c[2], 255])
        }
        _ => None,
    }
}

/// A manifest: each entity a molecule type (its file's spheres), each
/// instance k at x' = R(q_k) x + p_k with q_k = data[4k..4k+4] (x, y, z, w).
fn manifest(m: Manifest, name: &str, dir: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
    let bad = |m: String| SceneError::Invalid(format!("{name}: {m}"));
    let mut paths = Vec::new();
    tree_paths(&m.roots, &mut Vec::new(), &mut paths);
    let mut b = InstancedBuilder::default();
    for (e_index, e) in m.entities.iter().enumerate() {
        let what = format!("entity {} ({})", e_index, e.label);
        let file = dir.join(&e.file);
        let sub = super::load(
            &file,
            &LoadOptions {
                assembly: None,
                ..opts.clone()
            },
            &mut |_, _| {},
        )
        .map_err(|err| bad(format!("{what}: {err}")))?;
        if sub.instancing.is_some() {
            return Err(bad(format!(
                "{what}: {} is itself instanced (nested instancing is not supported)",
                e.file
            )));
        }
        let factor = e.size_factor.unwrap_or(1.0);
        if !(factor > 0.0 && factor.is_finite()) {
            return Err(bad(format!("{what}: sizeFactor {factor} must be positive")));
        }
        let color = match &e.color {
            None => None,
            Some(c) => Some(parse_color(c).ok_or_else(|| {
                bad(format!(
                    "{what}: color {c} is not \"#RRGGBB\", 0xRRGGBB or [r, g, b]"
                ))
            })?),
        };
        let shift = match e.center.as_deref() {
            None | Some("none") => Vec3::ZERO,
            Some("bbox") => sub
                .center_bounds()
                .map_or(Vec3::ZERO, |(lo, hi)| (lo + hi) * 0.5),
            Some(other) => {
                return Err(bad(format!(
                    "{what}: center '{other}' (expected none or bbox)"
                )));
            }
        };
        // the file's chain level gives chains (an .xyzr's single region
        // column, as `write_manifest` writes them)
        let chain_level = sub
            .level_names
            .iter()
            .position(|l| l == "chain")
            .or_else(|| (sub.level_names == ["level0"]).then_some(0));
        let mut chains: Vec<u32> = Vec::new();
        let atoms = sub
            .spheres
            .iter()
            .map(|s| {
                let key = chain_level.map_or(0, |l| s.region[l]);
                let c = chains.iter().position(|&k| k == key).unwrap_or_else(|| {
                    chains.push(key);
                    chains.len() - 1
                });
                Sphere {
                    center: (Vec3::from(s.center) - shift).to_array(),
                    radius: (s.radius as f64 * factor) as f32,
                    color: color.unwrap_or(s.color),
                    region: [c as u32, 0, 0, 0],
                }
            })
            .collect();
        let path: Vec<&str> = match e.groups.first() {
            Some(g) => paths
                .iter()
                .find(|(id, _)| id == g)
                .map(|(_, p)| p.iter().map(String::as_str).collect())
                .ok_or_else(|| bad(format!("{what}: group '{g}' is not a node of the roots")))?,
            None => Vec::new(),
        };
        let node = b.node(&path);
        let mol = b.molecule(&e.label, node, atoms);
        let pos = e.instances.positions.values(dir, &what).map_err(bad)?;
        if e.instances.rotations.variant != "quaternion" {
            return Err(bad(format!(
                "{what}: rotations variant '{}' (only quaternion)",
                e.instances.rotations.variant
            )));
        }
        let rot = e.instances.rotations.data.values(dir, &what).map_err(bad)?;
        if pos.len() % 3 != 0 || rot.len() % 4 != 0 || pos.len() / 3 != rot.len() / 4 {
            return Err(bad(format!(
                "{what}: {} position values and {} rotation values (expected 3 and 4 per instance)",
                pos.len(),
                rot.len()
            )));
        }
        for (p, q) in pos.chunks_exact(3).zip(rot.chunks_exact(4)) {
            b.instance_quat(
                name,
                mol,
                DQuat::from_xyzw(q[0], q[1], q[2], q[3]),
                [p[0], p[1], p[2]],
            )?;
        }
    }
    b.finish(name)
}

/// Writes an instanced scene as a manifest in `dir` (`manifest.json`, one
/// `.xyzr` per molecule type with its chain as a region column, binary
/// instance arrays): the inverse of loading one. Rigid transforms only.
pub fn write_manifest(scene: &Scene, dir: &Path) -> Result<(), String> {
    use super::instanced::Transforms;
    use std::fmt::Write as _;
    let inst = scene
        .instancing
        .as_ref()
        .ok_or("the scene is not instanced")?;
    let Transforms::Rigid(rigid) = &inst.transforms else {
        return Err("a manifest holds rigid transforms only".into());
    };
    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    let mut entities = Vec::new();
    let mut pos_bytes: Vec<u8> = Vec::new();
    let mut rot_bytes: Vec<u8> = Vec::new();
    for (m, mol) in inst.molecules.iter().enumerate() {
        let file = format!("molecule_{m}.xyzr");
        let mut text = String::new();
        let atoms = &scene.spheres[mol.first as usize..(mol.first + mol.atoms) as usize];
        for a in atoms {
            let _ = writeln!(
                text,
                "{} {} {} {} {}",
                a.center[0], a.center[1], a.center[2], a.radius, a.region[0]
            );
        }
        std::fs::write(dir.join(&file), text).map_err(|e| e.to_string())?;
        let (p0, r0) = (pos_bytes.len(), rot_bytes.len());
        for (k, _) in inst
            .instance_molecule
            .iter()
            .enumerate()
            .filter(|&(_, &im)| im as usize == m)
        {
            let r = &rigid[k];
            for v in &r.t[..3] {
                pos_bytes.extend_from_slice(&v.to_le_bytes());
            }
            for v in &r.q {
                rot_bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        entities.push(serde_json::json!({
            "label": mol.label,
            "file": file,
            "groups": if mol.node == 0 { vec![] } else { vec![format!("n{}", mol.node)] },
            "instances": {
                "positions": {"file": "positions.bin", "view": {"byteOffset": p0, "byteLength": pos_bytes.len() - p0}},
                "rotations": {"variant": "quaternion", "data": {"file": "rotations.bin", "view": {"byteOffset": r0, "byteLength": rot_bytes.len() - r0}}},
            },
        }));
    }
    std::fs::write(dir.join("positions.bin"), pos_bytes).map_err(|e| e.to_string())?;
    std::fs::write(dir.join("rotations.bin"), rot_bytes).map_err(|e| e.to_string())?;
    fn node_json(inst: &super::instanced::Instancing, n: usize) -> serde_json::Value {
        let children: Vec<serde_json::Value> = (0..inst.nodes.len())
            .filter(|&c| inst.nodes[c].parent == Some(n as u32))
            .map(|c| node_json(inst, c))
            .collect();
        serde_json::json!({"id": format!("n{n}"), "label": inst.nodes[n].label, "children": children})
    }
    let roots: Vec<serde_json::Value> = (0..inst.nodes.len())
        .filter(|&c| inst.nodes[c].parent == Some(0))
        .map(|c| node_json(inst, c))
        .collect();
    let doc = serde_json::json!({"roots": roots, "entities": entities});
    let text = serde_json::to_string_pretty(&doc).map_err(|e| e.to_string())?;
    std::fs::write(dir.join("manifest.json"), text).map_err(|e| e.to_string())
}
