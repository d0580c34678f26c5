//! Biological assemblies of an mmCIF file: `_pdbx_struct_assembly_gen`
//! rows (chains and operator expressions) and `_pdbx_struct_oper_list`
//! (3x4 matrices), expanded for the assembly asked for.

use super::Category;
use crate::scene::molecule::{AsmGroup, Assembly};
use crate::scene::text::parse_f32;
use crate::scene::{MAX_SPHERES, SceneError};
use std::collections::HashMap;

pub(super) type Op = [[f32; 4]; 3];

/// Builds the assemblies from `_pdbx_struct_assembly_gen` and
/// `_pdbx_struct_oper_list` (chains are label_asym_ids). Only assembly
/// `want` gets its operators expanded; the others are listed by id (for
/// the "not found" message).
pub(super) fn assemblies(
    name: &str,
    kept: &HashMap<&'static str, Category>,
    want: u32,
) -> Result<Vec<Assembly>, SceneError> {
    let (Some(gen_cat), Some(ops_cat)) = (
        kept.get("_pdbx_struct_assembly_gen"),
        kept.get("_pdbx_struct_oper_list"),
    ) else {
        return Ok(Vec::new());
    };
    let bad = |msg: String| SceneError::Invalid(format!("{name}: {msg}"));
    let ops = operators(name, ops_cat)?;
    let cols = [
        "_pdbx_struct_assembly_gen.assembly_id",
        "_pdbx_struct_assembly_gen.oper_expression",
        "_pdbx_struct_assembly_gen.asym_id_list",
    ]
    .map(|c| gen_cat.col(c));
    let [Some(a_col), Some(e_col), Some(l_col)] = cols else {
        return Err(bad(
            "_pdbx_struct_assembly_gen lacks assembly_id, oper_expression or asym_id_list".into(),
        ));
    };
    let mut list: Vec<Assembly> = Vec::new();
    for r in &gen_cat.rows {
        // Non-numeric assembly ids cannot be selected by number.
        let Ok(id) = r[a_col].trim().parse::<u32>() else {
            continue;
        };
        let group = AsmGroup {
            chains: r[l_col]
                .split(',')
                .map(|c| c.trim().as_bytes().to_vec())
                .filter(|c| !c.is_empty())
                .collect(),
            ops: if id == want {
                oper_expression(&r[e_col], &ops).map_err(|m| bad(format!("assembly {id}: {m}")))?
            } else {
                Vec::new()
            },
        };
        match list.iter_mut().find(|a| a.id == id) {
            Some(a) => a.groups.push(group),
            None => list.push(Assembly {
                id,
                groups: vec![group],
            }),
        }
    }
    Ok(list)
}

/// `_pdbx_struct_oper_list`: the 3x4 operators by id.
pub(super) fn operators(name: &str, ops_cat: &Category) -> Result<HashMap<String, Op>, SceneError> {
    let bad = |msg: String| SceneError::Invalid(format!("{name}: {msg}"));
    let id_col = ops_cat
        .col("_pdbx_struct_oper_list.id")
        .ok_or_else(|| bad("_pdbx_struct_oper_list has no id".into()))?;
    // the 12 columns, found once (oper lists of cellPACK models have 10^4-10^5 rows)
    let mut cols = [[0usize; 4]; 3];
    for (i, row) in cols.iter_mut().enumerate() {
        for (j, slot) in row.iter_mut().enumerate() {
            let item = if j < 3 {
                format!("_pdbx_struct_oper_list.matrix[{}][{}]", i + 1, j + 1)
            } else {
                format!("_pdbx_struct_oper_list.vector[{}]", i + 1)
            };
            *slot = ops_cat
                .col(&item)
                .ok_or_else(|| bad(format!("bad or missing {item}")))?;
        }
    }
    let mut ops: HashMap<String, Op> = HashMap::with_capacity(ops_cat.rows.len());
    for r in &ops_cat.rows {
        let mut m = [[0.0f32; 4]; 3];
        for (i, mrow) in m.iter_mut().enumerate() {
            for (j, slot) in mrow.iter_mut().enumerate() {
                let c = cols[i][j];
                *slot = r
                    .get(c)
                    .and_then(|v| parse_f32(v.as_bytes()))
                    .ok_or_else(|| {
                        bad(format!(
                            "operator {}: bad {}",
                            r.get(id_col).map_or("?", |s| s.as_str()),
                            ops_cat.items[c]
                        ))
                    })?;
            }
        }
        ops.insert(r[id_col].clone(), m);
    }
    Ok(ops)
}

/// Expands `1`, `1,2`, `(1-60)`, `(1-5)(6,7)` (a product: the right factor
/// is applied first) into matrices. The product's size is checked against
/// [`MAX_SPHERES`] before it is built (every operator makes at least one
/// sphere): `(1-10)` ten times over would be 10^10 matrices.
pub(super) fn oper_expression(expr: &str, ops: &HashMap<String, Op>) -> Result<Vec<Op>, String> {
    let bad = || {
        format!(
            "bad oper_expression '{}'",
            crate::scene::text::show(expr.as_bytes())
        )
    };
    let expr = expr.trim();
    let factors: Vec<&str> = if expr.contains('(') {
        expr.split(['(', ')'])
            .map(str::trim)
            .filter(|f| !f.is_empty())
            .collect()
    } else {
        vec![expr]
    };
    let mut lists: Vec<Vec<Op>> = Vec::new();
    let mut total: u128 = 1;
    for factor in factors {
        let mut mats = Vec::new();
        for part in factor.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            match part.split_once('-') {
                Some((a, b)) => {
                    let (a, b) = (
                        a.trim().parse::<u32>().map_err(|_| bad())?,
                        b.trim().parse::<u32>().map_err(|_| bad())?,
                    );
                    if b < a || (b - a) as usize >= MAX_SPHERES {
                        return Err(bad());
                    }
                    for i in a..=b {
                        mats.push(*ops.get(&i.to_string()).ok_or_else(bad)?);
                    }
                }
                None => mats.push(*ops.get(part).ok_or_else(bad)?),
            }
        }
        if mats.is_empty() {
            return Err(bad());
        }
        total = total.saturating_mul(mats.len() as u128);
        if total > MAX_SPHERES as u128 {
            return Err(format!(
                "oper_expression '{}' makes more than {MAX_SPHERES} operators (each at least one \
                 sphere; the most sphereshade renders)",
                crate::scene::text::show(expr.as_bytes())
            ));
        }
        lists.push(mats);
    }
    let mut result: Vec<Op> = vec![IDENTITY];
    for mats in lists {
        result = result
            .iter()
            .flat_map(|l| mats.iter().map(move |r| compose(l, r)))
            .collect();
    }
    Ok(result)
}

pub(super) const IDENTITY: Op = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
];

/// `a ∘ b`: apply `b`, then `a`.
fn compose(a: &Op, b: &Op) -> Op {
    let mut m = [[0.0f32; 4]; 3];
    for i in 0..3 {
        for j in 0..4 {
            let mut v = if j == 3 { a[i][3] } else { 0.0 };
            for k in 0..3 {
                v += a[i][k] * b[k][j];
            }
            m[i][j] = v;
        }
    }
    m
}
