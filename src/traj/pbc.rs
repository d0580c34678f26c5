//! Periodic boundaries (`--pbc keep|wrap|whole`) for triclinic cells given
//! as rows a, b, c (positions r = fa a + fb b + fc c in fractional terms).
//! - `wrap`: every atom into the cell, 0 <= f < 1 along each vector.
//! - `whole`: every residue whole: each atom moved by a lattice vector to
//!   the image nearest the residue's first atom (searched over the 27
//!   neighbouring images after rounding, so it is exact for any reduced
//!   triclinic cell, e.g. GROMACS's rhombic dodecahedron), as long as a
//!   residue is smaller than half the cell.
//!
//! Frames without a cell are left as they are.

/// What to do with atoms across the periodic boundary.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Pbc {
    #[default]
    Keep,
    Wrap,
    Whole,
}

type M3 = [[f64; 3]; 3];

/// Inverse of the matrix whose columns are the cell vectors (maps r to f).
fn frac_matrix(cell: &M3) -> Option<M3> {
    // columns = vectors: m[i][j] = cell[j][i]
    let m = [
        [cell[0][0], cell[1][0], cell[2][0]],
        [cell[0][1], cell[1][1], cell[2][1]],
        [cell[0][2], cell[1][2], cell[2][2]],
    ];
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if !(det.abs() > 1e-12) || !det.is_finite() {
        return None;
    }
    let inv = |a: usize, b: usize, c: usize, d: usize| m[a][b] * m[c][d];
    Some([
        [
            (inv(1, 1, 2, 2) - inv(1, 2, 2, 1)) / det,
            (inv(0, 2, 2, 1) - inv(0, 1, 2, 2)) / det,
            (inv(0, 1, 1, 2) - inv(0, 2, 1, 1)) / det,
        ],
        [
            (inv(1, 2, 2, 0) - inv(1, 0, 2, 2)) / det,
            (inv(0, 0, 2, 2) - inv(0, 2, 2, 0)) / det,
            (inv(0, 2, 1, 0) - inv(0, 0, 1, 2)) / det,
        ],
        [
            (inv(1, 0, 2, 1) - inv(1, 1, 2, 0)) / det,
            (inv(0, 1, 2, 0) - inv(0, 0, 2, 1)) / det,
            (inv(0, 0, 1, 1) - inv(0, 1, 1, 0)) / det,
        ],
    ])
}

fn mul(m: &M3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

/// f -> r: f_a a + f_b b + f_c c.
fn to_cart(cell: &M3, f: [f64; 3]) -> [f64; 3] {
    let mut r = [0.0; 3];
    for (k, fk) in f.iter().enumerate() {
        for (i, ri) in r.iter_mut().enumerate() {
            *ri += fk * cell[k][i];
        }
    }
    r
}

/// Applies `mode` to one frame. `residues[i]` is atom i's residue id
/// (atoms of a residue need not be contiguous); empty = each atom alone.
pub fn apply_pbc(mode: Pbc, positions: &mut [[f32; 3]], cell: Option<&M3>, residues: &[u32]) {
    let Some(cell) = cell else { return };
    let Some(inv) = frac_matrix(cell) else { return };
    let p64 = |p: &[f32; 3]| [p[0] as f64, p[1] as f64, p[2] as f64];
    match mode {
        Pbc::Keep => {}
        Pbc::Wrap => {
            for p in positions.iter_mut() {
                let f = mul(&inv, p64(p)).map(|x| x - x.floor());
                let r = to_cart(cell, f);
                *p = [r[0] as f32, r[1] as f32, r[2] as f32];
            }
        }
        Pbc::Whole => {
            if residues.len() != positions.len() {
                return;
            }
            let mut first: std::collections::HashMap<u32, [f64; 3]> = Default::default();
            for (p, &res) in positions.iter_mut().zip(residues) {
                let here = p64(p);
                let r0 = *first.entry(res).or_insert(here);
                let d = [here[0] - r0[0], here[1] - r0[1], here[2] - r0[2]];
                let f = mul(&inv, d).map(|x| x - x.round());
                let mut best = to_cart(cell, f);
                let mut best2 = best.iter().map(|x| x * x).sum::<f64>();
                for i in -1..=1 {
                    for j in -1..=1 {
                        for k in -1..=1 {
                            let g = [f[0] + i as f64, f[1] + j as f64, f[2] + k as f64];
                            let c = to_cart(cell, g);
                            let c2 = c.iter().map(|x| x * x).sum::<f64>();
                            if c2 < best2 {
                                best = c;
                                best2 = c2;
                            }
                        }
                    }
                }
                *p = [
                    (r0[0] + best[0]) as f32,
                    (r0[1] + best[1]) as f32,
                    (r0[2] + best[2]) as f32,
                ];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// GROMACS's rhombic dodecahedron (xy-square), edge 10.
    fn dodecahedron() -> M3 {
        let d = 10.0;
        [
            [d, 0.0, 0.0],
            [0.0, d, 0.0],
            [0.5 * d, 0.5 * d, d * 0.5f64.sqrt()],
        ]
    }

    #[test]
    fn wrap_puts_atoms_inside_and_whole_joins_split_residues() {
        let cell = dodecahedron();
        let inv = frac_matrix(&cell).unwrap();
        // frac(to_cart(f)) = f
        let f = [0.3, -1.2, 2.7];
        let back = mul(&inv, to_cart(&cell, f));
        for k in 0..3 {
            assert!((back[k] - f[k]).abs() < 1e-12);
        }
        let mut p = vec![[23.0f32, -7.5, 4.0], [-3.0, 14.0, -9.0]];
        apply_pbc(Pbc::Wrap, &mut p, Some(&cell), &[]);
        for q in &p {
            let f = mul(&inv, [q[0] as f64, q[1] as f64, q[2] as f64]);
            assert!(f.iter().all(|&x| (-1e-6..1.0 + 1e-6).contains(&x)), "{f:?}");
        }
        // A residue of two atoms 1 Å apart, the second shifted by a + c.
        let a = [1.0f32, 1.0, 1.0];
        let mut p = vec![
            a,
            [
                a[0] + 1.0 + (cell[0][0] + cell[2][0]) as f32,
                a[1] + (cell[2][1]) as f32,
                a[2] + cell[2][2] as f32,
            ],
        ];
        apply_pbc(Pbc::Whole, &mut p, Some(&cell), &[7, 7]);
        let d: f32 = (0..3)
            .map(|k| (p[1][k] - p[0][k]).powi(2))
            .sum::<f32>()
            .sqrt();
        assert!((d - 1.0).abs() < 1e-4, "{p:?}");
        // keep, and frames without a cell, change nothing
        let before = p.clone();
        apply_pbc(Pbc::Keep, &mut p, Some(&cell), &[7, 7]);
        apply_pbc(Pbc::Wrap, &mut p, None, &[]);
        assert_eq!(p, before);
    }
}
