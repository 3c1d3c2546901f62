//! Obstacles in the air around the flame ([`crate::air`]): solids of revolution about
//! the burner's axis that the air flows around and the particles cannot enter.
//!
//! The air's pressure projection stays exact with them. The Laplacian of the grid with
//! its solid cells, T (no flux through a face beside a solid cell; p = 0 in a solid
//! cell), differs from the open grid's, L, only in the rows and columns of the k cells
//! that are solid or beside one (the set A): T = L + E D Eᵀ, with E the n × k selection
//! of A and D a sparse k × k matrix. So (the capacitance matrix method: Buzbee, Dorr,
//! George & Golub 1971; the Woodbury identity)
//!
//! T⁻¹ b = y − W C⁻¹ D Eᵀ y, with y = L⁻¹ b, W = L⁻¹ E and C = I + D Eᵀ W.
//!
//! L⁻¹ is the open grid's exact solve (cosine modes along z, tridiagonal along r), so W
//! takes k solves and C one k × k LU factorisation, both once, when the air is made;
//! each projection is then one exact solve, a k × k back-substitution and W's n × k
//! product. The obstacles are bounded so that k stays at most [`MAX_BOUNDARY_CELLS`].

use phenomena_core::validate::Issues;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Most obstacles in the air.
pub const MAX_OBSTACLES: usize = 16;

/// Most air cells that are solid or beside a solid cell (the capacitance matrix's
/// size: at most 1024² doubles, 8 MiB, factorised once in about 0.4 GFLOP).
pub const MAX_BOUNDARY_CELLS: usize = 1024;

/// A solid of revolution about the burner's axis, the `[[flame.extended.air.obstacles]]`
/// tables: a ring (the stones of a fire pit, a hearth's round wall, a chimney) or, with
/// `inner_radius_m = 0`, a disc or a cylinder (a pot or a plate over the fire). The air
/// is axisymmetric, so it can hold only shapes that are: a box or a log lying across
/// the fire would need a three-dimensional air. Heights are above the burner (the
/// ground); the solid is static and at the ambient temperature. In the air's grid a
/// cell is solid when its centre lies inside.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Obstacle {
    /// Inner radius, m (0: a disc).
    #[serde(default)]
    pub inner_radius_m: f32,
    /// Outer radius, m.
    pub outer_radius_m: f32,
    /// Height of its underside above the burner, m (0: it stands on the ground).
    #[serde(default)]
    pub bottom_m: f32,
    /// Height of its top above the burner, m.
    pub top_m: f32,
}

impl Obstacle {
    /// Whether the point at distance `r` from the axis and height `z` lies inside.
    pub fn contains(&self, r: f32, z: f32) -> bool {
        (self.inner_radius_m..=self.outer_radius_m).contains(&r) && (self.bottom_m..=self.top_m).contains(&z)
    }
}

/// Which cells of an `nr` × `nz` grid of `dx` m cells are solid: `[j * nr + i]`, the
/// cell whose centre lies in an obstacle.
pub(crate) fn solid_cells(obstacles: &[Obstacle], nr: usize, nz: usize, dx: f32) -> Vec<bool> {
    (0..nr * nz)
        .map(|c| {
            let (r, z) = (((c % nr) as f32 + 0.5) * dx, ((c / nr) as f32 + 0.5) * dx);
            obstacles.iter().any(|o| o.contains(r, z))
        })
        .collect()
}

/// The cells that are solid or beside a solid cell (the set A), ascending.
fn boundary_cells(cell: &[bool], nr: usize, nz: usize) -> Vec<usize> {
    (0..nr * nz)
        .filter(|&c| {
            let (i, j) = (c % nr, c / nr);
            cell[c]
                || (i > 0 && cell[c - 1])
                || (i + 1 < nr && cell[c + 1])
                || (j > 0 && cell[c - nr])
                || (j + 1 < nz && cell[c + nr])
        })
        .collect()
}

/// The obstacles' problems, into `i` (fields under `prefix`): each a finite solid at
/// least one air cell (`cell_m`) thick that leaves at least one cell of air above a
/// burner of `burner_radius_m`, and all of them touching at most
/// [`MAX_BOUNDARY_CELLS`] cells of the `nr` × `nz` grid.
pub(crate) fn validate(
    obstacles: &[Obstacle],
    prefix: &str,
    burner_radius_m: f32,
    (nr, nz, cell_m): (usize, usize, f32),
    i: &mut Issues,
) {
    let list = format!("{prefix}obstacles");
    if obstacles.len() > MAX_OBSTACLES {
        i.push(&list, obstacles.len(), format!("at most {MAX_OBSTACLES} obstacles"));
        return;
    }
    for (k, o) in obstacles.iter().enumerate() {
        let at = |field: &str| format!("{list}[{k}].{field}");
        i.range(&at("inner_radius_m"), o.inner_radius_m, 0.0..=1000.0);
        i.range_open_low(&at("outer_radius_m"), o.outer_radius_m, 0.0, 1000.0);
        i.range(&at("bottom_m"), o.bottom_m, 0.0..=1000.0);
        i.range_open_low(&at("top_m"), o.top_m, 0.0, 1000.0);
        let thin = |from: f32, to: f32| !(to - from >= cell_m);
        if thin(o.inner_radius_m, o.outer_radius_m) {
            let text = format!(
                "at least one air cell ({cell_m} m: the burner's diameter / cells_per_diameter) beyond inner_radius_m = {}",
                o.inner_radius_m
            );
            i.push(at("outer_radius_m"), o.outer_radius_m, text);
        }
        if thin(o.bottom_m, o.top_m) {
            let text = format!("at least one air cell ({cell_m} m) above bottom_m = {}", o.bottom_m);
            i.push(at("top_m"), o.top_m, text);
        }
        if o.inner_radius_m < burner_radius_m && !(o.bottom_m >= cell_m) {
            let text = format!(
                "at least one air cell ({cell_m} m) above the burner, which it covers (inner_radius_m below the burner's {burner_radius_m} m)"
            );
            i.push(at("bottom_m"), o.bottom_m, text);
        }
    }
    if obstacles.is_empty() || !(cell_m > 0.0) || nr * nz > 1 << 20 {
        return;
    }
    let cell = solid_cells(obstacles, nr, nz, cell_m);
    let touched = boundary_cells(&cell, nr, nz).len();
    if touched > MAX_BOUNDARY_CELLS {
        let text = format!(
            "obstacles that are solid in or beside at most {MAX_BOUNDARY_CELLS} air cells (these touch {touched}): smaller or fewer obstacles, or fewer cells_per_diameter"
        );
        i.push(&list, format!("{} obstacles", obstacles.len()), text);
    }
}

/// The grid's solid cells, the faces they close, and the capacitance solve of the
/// module's docs.
#[derive(Clone, Debug)]
pub(crate) struct Solids {
    /// `[j * nr + i]`: the cell is solid.
    pub(crate) cell: Vec<bool>,
    /// `[j * (nr + 1) + i]`: the radial face is open (no solid cell beside it).
    pub(crate) ur_open: Vec<bool>,
    /// `[j * nr + i]`, j = 0..=nz: the axial face is open.
    pub(crate) uz_open: Vec<bool>,
    /// The set A, ascending.
    boundary: Vec<usize>,
    /// D's entries: (row, column) in A's indices, value.
    d: Vec<(u32, u32, f64)>,
    /// W = L⁻¹ E, column a at `[a * n..(a + 1) * n]`.
    w: Vec<f32>,
    /// C's LU factors (row-major, unit lower triangle implied) and row permutation.
    lu: Vec<f64>,
    perm: Vec<usize>,
}

impl Solids {
    /// The solids of `cell` (an `nr` × `nz` grid), with `solve` the open grid's exact
    /// L⁻¹; `None` when no cell is solid.
    pub(crate) fn new(
        cell: Vec<bool>,
        nr: usize,
        nz: usize,
        mut solve: impl FnMut(&[f32]) -> Vec<f32>,
    ) -> Option<Self> {
        if !cell.contains(&true) {
            return None;
        }
        let n = nr * nz;
        let at = |i: usize, j: usize| cell[j * nr + i];
        let ur_open = (0..(nr + 1) * nz)
            .map(|f| {
                let (i, j) = (f % (nr + 1), f / (nr + 1));
                (i == 0 || !at(i - 1, j)) && (i == nr || !at(i, j))
            })
            .collect();
        let uz_open = (0..nr * (nz + 1))
            .map(|f| {
                let (i, j) = (f % nr, f / nr);
                (j == 0 || !at(i, j - 1)) && (j == nz || !at(i, j))
            })
            .collect();
        let boundary = boundary_cells(&cell, nr, nz);
        let k = boundary.len();
        let index = |c: usize| boundary.binary_search(&c).ok();
        // D = T − L on A × A, row by row.
        let mut d = Vec::new();
        for (b, &row) in boundary.iter().enumerate() {
            let mut diff = row_entries(row, nr, nz, None);
            for e in &mut diff {
                e.1 = -e.1;
            }
            diff.extend(row_entries(row, nr, nz, Some(&cell)));
            diff.sort_by_key(|e| e.0);
            for group in diff.chunk_by(|x, y| x.0 == y.0) {
                let v: f64 = group.iter().map(|e| e.1).sum();
                if v != 0.0 {
                    // T and L differ only on A × A (the module's docs).
                    let a = index(group[0].0).expect("a changed entry outside the boundary set");
                    d.push((b as u32, a as u32, v));
                }
            }
        }
        let mut w = vec![0.0f32; k * n];
        let mut unit = vec![0.0f32; n];
        for (a, &c) in boundary.iter().enumerate() {
            unit[c] = 1.0;
            w[a * n..(a + 1) * n].copy_from_slice(&solve(&unit));
            unit[c] = 0.0;
        }
        // C = I + D G with G = Eᵀ W.
        let mut cap = vec![0.0f64; k * k];
        for a in 0..k {
            cap[a * k + a] = 1.0;
        }
        for &(row, col, v) in &d {
            // (D G)[row][a] += D[row][col] · G[col][a], with G[col][a] = W_a at A's col-th cell.
            let at = boundary[col as usize];
            for a in 0..k {
                cap[row as usize * k + a] += v * f64::from(w[a * n + at]);
            }
        }
        let perm = lu_factor(&mut cap, k);
        Some(Self { cell, ur_open, uz_open, boundary, d, w, lu: cap, perm })
    }

    /// p with T p = `rhs` (the air's cells; the solid cells' `rhs` is ignored and
    /// their p is 0), `solve` the open grid's exact L⁻¹.
    pub(crate) fn solve(&self, rhs: &[f32], solve: impl FnOnce(&[f32]) -> Vec<f32>) -> Vec<f32> {
        let n = rhs.len();
        let k = self.boundary.len();
        let open: Vec<f32> = rhs.iter().zip(&self.cell).map(|(&r, &s)| if s { 0.0 } else { r }).collect();
        let mut y = solve(&open);
        let mut t = vec![0.0f64; k];
        for &(row, col, v) in &self.d {
            t[row as usize] += v * f64::from(y[self.boundary[col as usize]]);
        }
        lu_solve(&self.lu, &self.perm, k, &mut t);
        // y −= W s, in slices of cells in parallel, each summing the columns in order.
        const SLICE: usize = 1024;
        y.par_chunks_mut(SLICE).enumerate().for_each(|(part, y)| {
            let (from, len) = (part * SLICE, y.len());
            for (a, &s) in t.iter().enumerate() {
                let s = s as f32;
                for (p, w) in y.iter_mut().zip(&self.w[a * n + from..a * n + from + len]) {
                    *p -= w * s;
                }
            }
        });
        y
    }
}

/// The entries (column, value) of row `c` of the air's Laplacian times dx²
/// ([`crate::air::AirGrid`]'s L: axis and ground without flux, p = 0 on the outer and
/// top faces) on an `nr` × `nz` grid; with `solid`, T's row: no flux through a face
/// beside a solid cell, and a solid cell's row the identity.
fn row_entries(c: usize, nr: usize, nz: usize, solid: Option<&[bool]>) -> Vec<(usize, f64)> {
    let is_solid = |c: usize| solid.is_some_and(|s| s[c]);
    if is_solid(c) {
        return vec![(c, 1.0)];
    }
    let (i, j) = (c % nr, c / nr);
    let rc = i as f64 + 0.5;
    let mut out = Vec::with_capacity(5);
    let mut centre = 0.0;
    let mut link = |neighbour: Option<usize>, coef: f64, out: &mut Vec<(usize, f64)>| match neighbour {
        Some(nb) if is_solid(nb) => {}
        Some(nb) => {
            out.push((nb, coef));
            centre -= coef;
        }
        // The ghost beyond an open boundary: −p, p = 0 on the face.
        None => centre -= 2.0 * coef,
    };
    if i > 0 {
        link(Some(c - 1), i as f64 / rc, &mut out);
    }
    link((i + 1 < nr).then_some(c + 1), (i + 1) as f64 / rc, &mut out);
    if j > 0 {
        link(Some(c - nr), 1.0, &mut out);
    }
    link((j + 1 < nz).then_some(c + nr), 1.0, &mut out);
    out.push((c, centre));
    out
}

/// LU factorisation with partial pivoting of the `k` × `k` row-major `m`, in place;
/// returns the row permutation.
fn lu_factor(m: &mut [f64], k: usize) -> Vec<usize> {
    let mut perm: Vec<usize> = (0..k).collect();
    for col in 0..k {
        let pivot =
            (col..k).max_by(|&a, &b| m[a * k + col].abs().total_cmp(&m[b * k + col].abs())).unwrap_or(col);
        if pivot != col {
            for x in 0..k {
                m.swap(col * k + x, pivot * k + x);
            }
            perm.swap(col, pivot);
        }
        let p = m[col * k + col];
        if p == 0.0 {
            continue;
        }
        for row in col + 1..k {
            let f = m[row * k + col] / p;
            m[row * k + col] = f;
            if f != 0.0 {
                for x in col + 1..k {
                    m[row * k + x] -= f * m[col * k + x];
                }
            }
        }
    }
    perm
}

/// Solves (LU) x = P b in place in `b` with [`lu_factor`]'s factors.
fn lu_solve(lu: &[f64], perm: &[usize], k: usize, b: &mut [f64]) {
    let mut x: Vec<f64> = perm.iter().map(|&p| b[p]).collect();
    for row in 0..k {
        let s: f64 = (0..row).map(|c| lu[row * k + c] * x[c]).sum();
        x[row] -= s;
    }
    for row in (0..k).rev() {
        let s: f64 = (row + 1..k).map(|c| lu[row * k + c] * x[c]).sum();
        x[row] = (x[row] - s) / lu[row * k + row];
    }
    b.copy_from_slice(&x);
}

/// Moves `x` (world space), if inside `o` about the vertical axis through `origin`,
/// out through the nearest of `o`'s faces (mirrored across it), and removes the part
/// of `v` that points into `o` there (an inelastic wall).
pub(crate) fn push_out(o: &Obstacle, origin: glam::Vec3, x: &mut glam::Vec3, v: &mut glam::Vec3) {
    let d = glam::Vec2::new(x.x - origin.x, x.z - origin.z);
    let (r, z) = (d.length(), x.y - origin.y);
    if !o.contains(r, z) {
        return;
    }
    let radial = if r > 0.0 { d / r } else { glam::Vec2::X };
    let radial = glam::Vec3::new(radial.x, 0.0, radial.y);
    // Depth to each face and the outward normal there (no inner face for a disc, no
    // underside for a solid on the ground).
    let faces = [
        (o.outer_radius_m - r, radial),
        (o.top_m - z, glam::Vec3::Y),
        (if o.inner_radius_m > 0.0 { r - o.inner_radius_m } else { f32::INFINITY }, -radial),
        (if o.bottom_m > 0.0 { z - o.bottom_m } else { f32::INFINITY }, -glam::Vec3::Y),
    ];
    let Some(&(depth, normal)) = faces.iter().min_by(|a, b| a.0.total_cmp(&b.0)) else { return };
    // Mirrored across the face, as far outside as it was inside: particles that hit
    // the face together keep their spacing instead of landing on one sheet (where
    // their SPH neighbours would pile up).
    *x += normal * (2.0 * depth + 1e-5);
    let into = v.dot(normal);
    if into < 0.0 {
        *v -= normal * into;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::air::AirGrid;

    /// The capacitance solve is exact: its pressure satisfies T p = rhs in every air
    /// cell (T built row by row, independently of the solve) and is 0 in the solid
    /// cells, for a plate over the axis, a ring on the ground and a post at the edge.
    #[test]
    fn the_capacitance_solve_satisfies_the_obstructed_laplacian() {
        let (nr, nz, dx) = (12, 30, 0.01);
        let obstacles = [
            Obstacle { inner_radius_m: 0.0, outer_radius_m: 0.05, bottom_m: 0.15, top_m: 0.17 },
            Obstacle { inner_radius_m: 0.07, outer_radius_m: 0.09, bottom_m: 0.0, top_m: 0.04 },
            Obstacle { inner_radius_m: 0.1, outer_radius_m: 0.12, bottom_m: 0.2, top_m: 0.3 },
        ];
        let cell = solid_cells(&obstacles, nr, nz, dx);
        let mut grid = AirGrid::new(nr, nz, dx, 300.0);
        let solids = Solids::new(cell.clone(), nr, nz, |b| grid.open_solve(b)).expect("solid cells");
        let rhs: Vec<f32> = (0..nr * nz).map(|c| ((c * 37 % 101) as f32 - 50.0) / 50.0).collect();
        let p = solids.solve(&rhs, |b| grid.open_solve(b));
        let scale = p.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        for c in 0..nr * nz {
            if cell[c] {
                // The correction cancels y there up to f32 rounding of W's product.
                assert!(p[c].abs() <= 1e-5 * scale, "solid cell {c}: p = {}", p[c]);
                continue;
            }
            let tp: f64 =
                row_entries(c, nr, nz, Some(&cell)).iter().map(|&(col, v)| v * f64::from(p[col])).sum();
            // f32 rounding of the exact solve and of W's product over k columns: the
            // open grid's solve alone leaves residuals of 1e-5 of the right-hand side.
            assert!((tp - f64::from(rhs[c])).abs() < 1e-4, "cell {c}: T p = {tp}, rhs {}", rhs[c]);
        }
    }

    /// Row entries of the open grid are the fast solve's operator: L (L⁻¹ b) = b.
    #[test]
    fn the_rows_are_the_open_grids_laplacian() {
        let (nr, nz) = (10, 20);
        let mut grid = AirGrid::new(nr, nz, 0.01, 300.0);
        let b: Vec<f32> = (0..nr * nz).map(|c| ((c * 13 % 29) as f32 - 14.0) / 14.0).collect();
        let p = grid.open_solve(&b);
        for (c, &bc) in b.iter().enumerate() {
            let lp: f64 = row_entries(c, nr, nz, None).iter().map(|&(col, v)| v * f64::from(p[col])).sum();
            assert!((lp - f64::from(bc)).abs() < 1e-4, "cell {c}: L p = {lp}, b {bc}");
        }
    }

    #[test]
    fn obstacles_are_refused_by_name() {
        let o = |inner, outer, bottom, top| Obstacle {
            inner_radius_m: inner,
            outer_radius_m: outer,
            bottom_m: bottom,
            top_m: top,
        };
        let problems = |list: &[Obstacle]| {
            let mut i = Issues::default();
            validate(list, "air.", 0.08, (40, 160, 0.008), &mut i);
            i.into_result()
                .err()
                .unwrap_or_default()
                .iter()
                .map(|e| e.to_string())
                .collect::<Vec<_>>()
                .join("\n")
        };
        assert_eq!(problems(&[o(0.0, 0.1, 0.3, 0.32)]), "");
        let thin = problems(&[o(0.1, 0.104, 0.0, 0.1)]);
        assert!(thin.contains("air.obstacles[0].outer_radius_m") && thin.contains("0.008 m"), "{thin}");
        let flat = problems(&[o(0.0, 0.1, 0.3, 0.301)]);
        assert!(flat.contains("air.obstacles[0].top_m"), "{flat}");
        let lid = problems(&[o(0.0, 0.1, 0.0, 0.1)]);
        assert!(lid.contains("air.obstacles[0].bottom_m") && lid.contains("covers"), "{lid}");
        let nan = problems(&[o(0.0, f32::NAN, 0.3, 0.4)]);
        assert!(nan.contains("air.obstacles[0].outer_radius_m"), "{nan}");
        let big = problems(&[o(0.0, 0.3, 0.1, 1.0)]);
        assert!(big.contains("air.obstacles") && big.contains("at most 1024"), "{big}");
        let many = problems(&vec![o(0.0, 0.1, 0.3, 0.32); MAX_OBSTACLES + 1]);
        assert!(many.contains("at most 16 obstacles"), "{many}");
    }
}
