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
/// least one air cell (`cell_m`) thick, inside the air's cylinder of `nr` × `nz` cells,
/// leaving at least one cell of air above a burner of `burner_radius_m`; together they
/// seal no air off from the open boundaries (where the projection would have no
/// solution) and touch at most [`MAX_BOUNDARY_CELLS`] cells, and at most
/// [`MAX_CAPACITANCE_VALUES`] values of W.
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
    let before = i.len();
    for (k, o) in obstacles.iter().enumerate() {
        validate_one(o, &format!("{list}[{k}]."), burner_radius_m, (nr, nz, cell_m), i);
    }
    if obstacles.is_empty() || i.len() > before || !(cell_m > 0.0) || nr * nz > 1 << 20 {
        return;
    }
    let cell = solid_cells(obstacles, nr, nz, cell_m);
    let touched = boundary_cells(&cell, nr, nz).len();
    let named = format!("{} obstacles", obstacles.len());
    if touched > MAX_BOUNDARY_CELLS || touched * nr * nz > MAX_CAPACITANCE_VALUES {
        let text = format!(
            "obstacles that are solid in or beside at most {MAX_BOUNDARY_CELLS} air cells, and at most {MAX_CAPACITANCE_VALUES} for all of them times the grid's {} cells (these touch {touched}): smaller or fewer obstacles, or fewer cells_per_diameter",
            nr * nz
        );
        i.push(&list, &named, text);
    }
    if let Some((r, z)) = sealed_cell(&cell, nr, nz) {
        let (r, z) = ((r as f32 + 0.5) * cell_m, (z as f32 + 0.5) * cell_m);
        let text = format!(
            "obstacles that leave every pocket of air open to the air beyond: the air at r = {r} m, {z} m up is sealed in (leave a gap of at least one air cell, {cell_m} m)"
        );
        i.push(&list, &named, text);
    }
}

/// One obstacle's problems (see [`validate`]), fields under `at`.
fn validate_one(
    o: &Obstacle,
    at: &str,
    burner_radius_m: f32,
    (nr, nz, cell_m): (usize, usize, f32),
    i: &mut Issues,
) {
    let field = |name: &str| format!("{at}{name}");
    let before = i.len();
    i.range(&field("inner_radius_m"), o.inner_radius_m, 0.0..=1000.0);
    i.range_open_low(&field("outer_radius_m"), o.outer_radius_m, 0.0, 1000.0);
    i.range(&field("bottom_m"), o.bottom_m, 0.0..=1000.0);
    i.range_open_low(&field("top_m"), o.top_m, 0.0, 1000.0);
    if i.len() > before {
        return;
    }
    if !(o.outer_radius_m - o.inner_radius_m >= cell_m) {
        let text = format!(
            "at least one air cell ({cell_m} m: the burner's diameter / cells_per_diameter) beyond inner_radius_m = {}",
            o.inner_radius_m
        );
        i.push(field("outer_radius_m"), o.outer_radius_m, text);
    }
    if !(o.top_m - o.bottom_m >= cell_m) {
        let text = format!("at least one air cell ({cell_m} m) above bottom_m = {}", o.bottom_m);
        i.push(field("top_m"), o.top_m, text);
    }
    if o.inner_radius_m < burner_radius_m && !(o.bottom_m >= cell_m) {
        let text = format!(
            "at least one air cell ({cell_m} m) above the burner, which it covers (inner_radius_m below the burner's {burner_radius_m} m)"
        );
        i.push(field("bottom_m"), o.bottom_m, text);
    }
    let (radius, height) = (nr as f32 * cell_m, nz as f32 * cell_m);
    if o.inner_radius_m >= radius {
        let text = format!(
            "inside the air's cylinder ({radius:.3} m: radius_diameters burner diameters), where the air can flow round it"
        );
        i.push(field("inner_radius_m"), o.inner_radius_m, text);
    }
    if o.bottom_m >= height {
        let text =
            format!("inside the air's cylinder ({height:.3} m tall: height_diameters burner diameters)");
        i.push(field("bottom_m"), o.bottom_m, text);
    }
}

/// Most values of W (k boundary cells × n grid cells, f32): 64 MiB.
pub const MAX_CAPACITANCE_VALUES: usize = 1 << 24;

/// An air cell of `cell` (solid cells) that no path through open faces joins to the
/// open boundaries (the outer radius and the top), if any.
fn sealed_cell(cell: &[bool], nr: usize, nz: usize) -> Option<(usize, usize)> {
    let mut reached = vec![false; nr * nz];
    let mut stack: Vec<usize> = (0..nz)
        .map(|j| j * nr + nr - 1)
        .chain((0..nr).map(|i| (nz - 1) * nr + i))
        .filter(|&c| !cell[c])
        .collect();
    for &c in &stack {
        reached[c] = true;
    }
    while let Some(c) = stack.pop() {
        let (i, j) = (c % nr, c / nr);
        let neighbours = [
            (i > 0).then(|| c - 1),
            (i + 1 < nr).then(|| c + 1),
            (j > 0).then(|| c - nr),
            (j + 1 < nz).then(|| c + nr),
        ];
        for n in neighbours.into_iter().flatten() {
            if !cell[n] && !reached[n] {
                reached[n] = true;
                stack.push(n);
            }
        }
    }
    (0..nr * nz).find(|&c| !cell[c] && !reached[c]).map(|c| (c % nr, c / nr))
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
        // A zero pivot is a singular C, which `validate` refuses (air sealed in): no
        // infinities if one gets here.
        let pivot = lu[row * k + row];
        x[row] = if pivot != 0.0 { (x[row] - s) / pivot } else { 0.0 };
    }
    b.copy_from_slice(&x);
}

/// Keeps a particle out of `o`, a solid about the vertical axis through `axis`: the
/// particle moved this step from x − v·h to `x`; if that path enters `o` (sampled at
/// least twice per thickness of `o`, so no step passes through it), the particle is
/// put back outside the face it entered by, mirrored across it (as far outside as it
/// went in, at most half the thickness: particles arriving together keep their
/// spacing instead of landing on one sheet, where their SPH neighbours would pile up),
/// and its velocity into that face is removed (an inelastic wall). A particle that
/// was already inside leaves by the nearest face. Returns whether it moved the
/// particle. Never below the ground.
pub(crate) fn push_out(
    o: &Obstacle,
    axis: glam::Vec3,
    x: &mut glam::Vec3,
    v: &mut glam::Vec3,
    h: f32,
) -> bool {
    let prev = *x - *v * h;
    let (z_prev, z_now) = (prev.y - axis.y, x.y - axis.y);
    if (z_prev < o.bottom_m && z_now < o.bottom_m) || (z_prev > o.top_m && z_now > o.top_m) {
        return false;
    }
    let local = |p: glam::Vec3| (glam::Vec2::new(p.x - axis.x, p.z - axis.z).length(), p.y - axis.y);
    let (r, z) = local(prev);
    if o.contains(r, z) {
        return leave_by_nearest_face(o, axis, x, v);
    }
    let half = 0.5 * (o.outer_radius_m - o.inner_radius_m).min(o.top_m - o.bottom_m);
    let steps = ((*x - prev).length() / half).ceil();
    let steps = if steps.is_finite() { (steps as usize).clamp(1, 64) } else { 1 };
    let mut before = (r, z);
    for s in 1..=steps {
        let p = prev.lerp(*x, s as f32 / steps as f32);
        let (r, z) = local(p);
        if !o.contains(r, z) {
            before = (r, z);
            continue;
        }
        // The face it entered by: the one the last point outside lay beyond.
        let (rb, zb) = before;
        let face = if zb < o.bottom_m {
            Face::Bottom
        } else if zb > o.top_m {
            Face::Top
        } else if rb > o.outer_radius_m {
            Face::Outer
        } else {
            Face::Inner
        };
        *x = p;
        place_outside(o, axis, face, half, x, v);
        return true;
    }
    false
}

/// A face of an [`Obstacle`].
#[derive(Clone, Copy)]
enum Face {
    Bottom,
    Top,
    Inner,
    Outer,
}

/// Moves `x` (inside `o`) out through the nearest face (no inner face for a disc, no
/// underside for a solid on the ground).
fn leave_by_nearest_face(o: &Obstacle, axis: glam::Vec3, x: &mut glam::Vec3, v: &mut glam::Vec3) -> bool {
    let r = glam::Vec2::new(x.x - axis.x, x.z - axis.z).length();
    let z = x.y - axis.y;
    let faces = [
        (o.outer_radius_m - r, Face::Outer),
        (o.top_m - z, Face::Top),
        (if o.inner_radius_m > 0.0 { r - o.inner_radius_m } else { f32::INFINITY }, Face::Inner),
        (if o.bottom_m > 0.0 { z - o.bottom_m } else { f32::INFINITY }, Face::Bottom),
    ];
    let Some(&(_, face)) = faces.iter().min_by(|a, b| a.0.total_cmp(&b.0)) else { return false };
    let half = 0.5 * (o.outer_radius_m - o.inner_radius_m).min(o.top_m - o.bottom_m);
    place_outside(o, axis, face, half, x, v);
    true
}

/// Mirrors `x` (inside `o`) across `face`, at most `reach` outside it (and never below
/// the ground or across the axis), and removes `v`'s part into the face.
fn place_outside(
    o: &Obstacle,
    axis: glam::Vec3,
    face: Face,
    reach: f32,
    x: &mut glam::Vec3,
    v: &mut glam::Vec3,
) {
    // Just outside the face: f32 steps at the scale of the position.
    let gap = 1e-5 * (1.0 + x.abs().max_element());
    let d = glam::Vec2::new(x.x - axis.x, x.z - axis.z);
    let r = d.length();
    let radial = if r > 0.0 { d / r } else { glam::Vec2::X };
    let z = x.y - axis.y;
    let set_radius = |x: &mut glam::Vec3, radius: f32| {
        let p = glam::Vec2::new(axis.x, axis.z) + radial * radius;
        (x.x, x.z) = (p.x, p.y);
    };
    let normal = match face {
        Face::Bottom => {
            x.y = axis.y + (o.bottom_m - (z - o.bottom_m).min(reach) - gap).max(0.0);
            -glam::Vec3::Y
        }
        Face::Top => {
            x.y = axis.y + o.top_m + (o.top_m - z).min(reach) + gap;
            glam::Vec3::Y
        }
        Face::Outer => {
            set_radius(x, o.outer_radius_m + (o.outer_radius_m - r).min(reach) + gap);
            glam::Vec3::new(radial.x, 0.0, radial.y)
        }
        Face::Inner => {
            set_radius(x, (o.inner_radius_m - (r - o.inner_radius_m).min(reach) - gap).max(0.0));
            -glam::Vec3::new(radial.x, 0.0, radial.y)
        }
    };
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
        // A pot resting on a ring of stones seals the air around the burner in.
        let sealed = problems(&[o(0.2, 0.24, 0.0, 0.15), o(0.0, 0.24, 0.15, 0.17)]);
        assert!(sealed.contains("air.obstacles") && sealed.contains("sealed in"), "{sealed}");
        assert_eq!(problems(&[o(0.2, 0.24, 0.0, 0.12), o(0.0, 0.24, 0.15, 0.17)]), "", "a gap under the pot");
        // Beyond the air's cylinder (40 cells of 8 mm: 0.32 m; 160 cells: 1.28 m).
        let out = problems(&[o(0.33, 0.4, 0.0, 0.1)]);
        assert!(out.contains("air.obstacles[0].inner_radius_m") && out.contains("0.320 m"), "{out}");
        let high = problems(&[o(0.0, 0.1, 1.3, 1.4)]);
        assert!(high.contains("air.obstacles[0].bottom_m") && high.contains("1.280 m tall"), "{high}");
        // A value that is not a number is named once, not blamed on another field.
        let nan = problems(&[o(f32::NAN, 0.1, 0.3, 0.4)]);
        assert!(nan.contains("inner_radius_m") && !nan.contains("outer_radius_m"), "{nan}");
        let many = problems(&vec![o(0.0, 0.1, 0.3, 0.32); MAX_OBSTACLES + 1]);
        assert!(many.contains("at most 16 obstacles"), "{many}");
    }
}
