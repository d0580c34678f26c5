//! mmCIF/BinaryCIF models that load instanced: PetWorld files (each model
//! a molecule type), cellPACK exports and `--assembly` (each generator
//! row's chains a molecule type, its operators the instances).

use super::assembly::{self, assemblies};
use super::{AtomReader, Category};
use crate::scene::molecule::{InstancedFrom, MolBuilder, find_assembly};
use crate::scene::{LoadOptions, ModelSelect, Scene, SceneError};
use std::collections::HashMap;

/// How a file's atoms make an instanced scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum InstancedKind {
    /// PetWorld: `_pdbx_model` names molecule types, generator rows
    /// instantiate models (`PDB_model_num`).
    PetWorld,
    /// An assembly's generator rows (cellPACK exports: assembly 1 unless
    /// `--assembly` says otherwise).
    Assembly(u32),
}

/// The data block name of cellPACK exports.
pub(crate) const CELLPACK_BLOCK: &str = "CELLPACK_MODEL";

pub(super) fn instanced_kind(
    opts: &LoadOptions,
    kept: &HashMap<&'static str, Category>,
    header: Option<&str>,
) -> Option<InstancedKind> {
    let petworld = kept.contains_key("_pdbx_model")
        && kept
            .get("_pdbx_struct_assembly_gen")
            .is_some_and(|g| g.col("_pdbx_struct_assembly_gen.PDB_model_num").is_some());
    if petworld {
        return Some(InstancedKind::PetWorld);
    }
    match (opts.assembly, header) {
        (Some(a), _) => Some(InstancedKind::Assembly(a)),
        (None, Some(h)) if h.eq_ignore_ascii_case(CELLPACK_BLOCK) => {
            Some(InstancedKind::Assembly(1))
        }
        _ => None,
    }
}

/// The models an `_atom_site` reader keeps: PetWorld files need them all
/// (each is a molecule type), so `--model` does not apply there.
pub(super) fn atom_model(
    name: &str,
    opts: &LoadOptions,
    kind: Option<InstancedKind>,
) -> Result<ModelSelect, SceneError> {
    if kind != Some(InstancedKind::PetWorld) {
        return Ok(opts.model);
    }
    if opts.model != ModelSelect::First {
        return Err(SceneError::Invalid(format!(
            "{name}: --model does not apply to a PetWorld model (each model is a molecule type)"
        )));
    }
    Ok(ModelSelect::All)
}

pub(super) fn finish_instanced(
    builder: MolBuilder,
    name: &str,
    opts: &LoadOptions,
    atoms: Option<AtomReader>,
    kept: &HashMap<&'static str, Category>,
    kind: InstancedKind,
) -> Result<Scene, SceneError> {
    let bad = |m: String| SceneError::Invalid(format!("{name}: {m}"));
    match kind {
        InstancedKind::PetWorld => {
            let generators = kept
                .get("_pdbx_struct_assembly_gen")
                .ok_or_else(|| bad("no _pdbx_struct_assembly_gen".into()))?;
            let ops_cat = kept
                .get("_pdbx_struct_oper_list")
                .ok_or_else(|| bad("no _pdbx_struct_oper_list".into()))?;
            let ops = assembly::operators(name, ops_cat)?;
            let col = |c: &str| {
                generators
                    .col(&format!("_pdbx_struct_assembly_gen.{c}"))
                    .ok_or_else(|| bad(format!("_pdbx_struct_assembly_gen lacks {c}")))
            };
            let (model_col, expr_col) = (col("PDB_model_num")?, col("oper_expression")?);
            // model numbers -> the index the reader gave them (file order)
            let models: Vec<i64> = atoms.as_ref().map(|a| a.models.clone()).unwrap_or_default();
            let mut rows = Vec::new();
            for r in &generators.rows {
                let num: i64 = r[model_col]
                    .trim()
                    .parse()
                    .map_err(|_| bad(format!("bad PDB_model_num '{}'", r[model_col])))?;
                let Some(index) = models.iter().position(|&m| m == num) else {
                    // a model without atoms adds nothing
                    continue;
                };
                let list = assembly::oper_expression(&r[expr_col], &ops)
                    .map_err(|m| bad(format!("model {num}: {m}")))?;
                rows.push((index as u32, list));
            }
            // `_pdbx_model` row k names model number k + 1
            let labels: Vec<String> = kept
                .get("_pdbx_model")
                .and_then(|c| c.col("_pdbx_model.name").map(|i| (c, i)))
                .map(|(c, i)| c.rows.iter().map(|r| r[i].clone()).collect())
                .unwrap_or_default();
            let names = models
                .iter()
                .map(|&num| {
                    usize::try_from(num - 1)
                        .ok()
                        .and_then(|k| labels.get(k))
                        .cloned()
                        .unwrap_or_else(|| format!("model {num}"))
                })
                .collect();
            builder.finish_instanced(name, opts.color_by, InstancedFrom::Models { rows, names })
        }
        InstancedKind::Assembly(want) => {
            let list = assemblies(name, kept, want)?;
            let asm = find_assembly(name, &list, want)?;
            // cellPACK: `root.compartment.surface.group.name` per entity
            let mut paths = HashMap::new();
            let mut depth = 0;
            if let Some(e) = kept.get("_entity")
                && let (Some(id), Some(desc)) =
                    (e.col("_entity.id"), e.col("_entity.pdbx_description"))
            {
                for r in &e.rows {
                    let parts: Vec<String> = r[desc].split('.').map(str::to_string).collect();
                    if parts.len() > 1 && parts[0] == "root" {
                        depth = depth.max(parts.len() - 1);
                        paths.insert(r[id].as_bytes().to_vec(), parts[1..].to_vec());
                    }
                }
            }
            let depth_names = if depth == 4 {
                ["compartment", "location", "group", "ingredient"]
                    .map(String::from)
                    .to_vec()
            } else {
                Vec::new()
            };
            builder.finish_instanced(
                name,
                opts.color_by,
                InstancedFrom::Assembly {
                    asm,
                    paths,
                    depth_names,
                },
            )
        }
    }
}
