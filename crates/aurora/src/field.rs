//! The electric field of an intermediate target shape (thesis §2.2.3): charges sampled
//! near the shape's segments give a count per cell N(i, j) and a charge density
//! ρ = q0·N/ΔS (eq 2.2); the potential solves the Poisson equation with φ = 0 on the
//! border (eq 2.3-2.6), Perlin noise over (x, z, t) is added, and E = -∇φ by central
//! differences (eq 2.7-2.9).
//!
//! Potentials are kept in units of q0/ε0 (so a cell holding one charge has source 1);
//! physical volts are that times q0/ε0 = 1.81e-8 V. Lengths are km.

use std::sync::Arc;

use crate::noise::NoiseSampler;
use glam::Vec2;
use phenomena_core::rng::{Purpose, Stream};
use rayon::prelude::*;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlannerScalar};
use serde::{Deserialize, Serialize};

use crate::shape::Shape;

const SAMPLE: Purpose = Purpose::named("aurora.field.sample");
/// Samples per parallel work item; fixed so results do not depend on the thread count.
const SAMPLE_CHUNK: usize = 4096;

/// The simulation plane's grid: `nx × nz` square cells of `cell_km`, from `origin_km`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// Cells along x.
    pub nx: usize,
    /// Cells along z.
    pub nz: usize,
    /// Lower corner of the plane, km.
    pub origin_km: Vec2,
    /// Cell edge Δd, km.
    pub cell_km: f32,
}

impl Grid {
    /// Number of cells.
    pub fn len(&self) -> usize {
        self.nx * self.nz
    }

    /// Whether the grid has no cells.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row-major index of cell (i, j) (i along x).
    #[inline]
    pub fn index(&self, i: usize, j: usize) -> usize {
        j * self.nx + i
    }

    /// The cell containing `p`, if inside the plane.
    #[inline]
    pub fn cell_of(&self, p: Vec2) -> Option<(usize, usize)> {
        let c = (p - self.origin_km) / self.cell_km;
        if c.x >= 0.0 && c.y >= 0.0 && (c.x as usize) < self.nx && (c.y as usize) < self.nz {
            Some((c.x as usize, c.y as usize))
        } else {
            None
        }
    }

    /// Centre of cell (i, j), km.
    #[inline]
    pub fn center(&self, i: usize, j: usize) -> Vec2 {
        self.origin_km + (Vec2::new(i as f32, j as f32) + 0.5) * self.cell_km
    }

    /// Size of the plane, km.
    pub fn extent_km(&self) -> Vec2 {
        Vec2::new(self.nx as f32, self.nz as f32) * self.cell_km
    }

    /// Bilinear interpolation of a cell-centred field at `p` (clamped at the border).
    #[inline]
    pub fn interpolate<T>(&self, values: &[T], p: Vec2) -> T
    where
        T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
    {
        let c = (p - self.origin_km) / self.cell_km - 0.5;
        let fx = c.x.clamp(0.0, (self.nx - 1) as f32);
        let fz = c.y.clamp(0.0, (self.nz - 1) as f32);
        let (i0, j0) = (fx as usize, fz as usize);
        let (i1, j1) = ((i0 + 1).min(self.nx - 1), (j0 + 1).min(self.nz - 1));
        let (tx, tz) = (fx - i0 as f32, fz - j0 as f32);
        let a = values[self.index(i0, j0)] * (1.0 - tx) + values[self.index(i1, j0)] * tx;
        let b = values[self.index(i0, j1)] * (1.0 - tx) + values[self.index(i1, j1)] * tx;
        a * (1.0 - tz) + b * tz
    }
}

/// How charges are placed near the shape.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sampler {
    /// The thesis (Fig 2.8): uniform points in the shape's bounding box grown by L_thr,
    /// kept when within L_thr of a segment. §3.3 names it the bottleneck: most points are
    /// rejected for long thin shapes.
    Paper,
    /// Uniform points drawn from the region within L_thr of the segments directly: the
    /// plane is cut into cells a quarter of L_thr wide, classified once per shape as
    /// outside, wholly inside or partly inside the region; a point is drawn uniformly in
    /// a cell chosen uniformly among the last two kinds and kept if it is inside. The
    /// same distribution as the thesis's rejection from the bounding box (tested by
    /// chi-square over cells), with few rejections and most distance tests skipped.
    #[default]
    Direct,
}

/// Which points lie within L_thr of a shape: its segments bucketed for distance queries.
#[derive(Clone, Debug)]
pub struct Nearness {
    index: SegmentIndex,
    reach: f32,
}

impl Nearness {
    /// The test of distance `reach_km` from `shape`'s segments.
    pub fn new(shape: &Shape, reach_km: f32) -> Self {
        Self { index: SegmentIndex::new(shape, reach_km), reach: reach_km }
    }

    /// Whether `p` lies within the reach of a segment.
    pub fn covers(&self, p: Vec2) -> bool {
        self.index.covers(p, self.reach)
    }

    /// The share of `points` within reach (0 for none), in parallel; the count is exact,
    /// so any thread count gives the same share.
    pub fn share(&self, points: &[Vec2]) -> f64 {
        if points.is_empty() {
            return 0.0;
        }
        let near: usize =
            points.par_chunks(4096).map(|c| c.iter().filter(|&&p| self.covers(p)).count()).sum();
        near as f64 / points.len() as f64
    }
}

/// Segments' numbers bucketed into square cells: each segment is filed in every cell
/// its `reach`-neighbourhood's box overlaps, so the segments within `reach` of a point
/// are among its cell's. Shared by the field's distance tests ([`Nearness`]) and the
/// small-scale motion's nearest sheet ([`crate::small_scale`]).
#[derive(Clone, Debug)]
pub(crate) struct SegmentBuckets {
    origin: Vec2,
    cell: f32,
    nx: usize,
    nz: usize,
    start: Vec<u32>,
    items: Vec<u32>,
}

impl SegmentBuckets {
    /// `nx × nz` cells of `cell` km from `origin`; segment k is `segments[k]` (a, b).
    /// Boxes reaching past the grid are clamped to its edge cells.
    pub(crate) fn new(
        segments: impl Iterator<Item = (Vec2, Vec2)>,
        reach: f32,
        origin: Vec2,
        cell: f32,
        (nx, nz): (usize, usize),
    ) -> Self {
        let clamp_cell = |p: Vec2| {
            let c = ((p - origin) / cell).max(Vec2::ZERO);
            ((c.x as usize).min(nx - 1), (c.y as usize).min(nz - 1))
        };
        let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); nx * nz];
        for (k, (a, b)) in segments.enumerate() {
            let (i0, j0) = clamp_cell(a.min(b) - Vec2::splat(reach));
            let (i1, j1) = clamp_cell(a.max(b) + Vec2::splat(reach));
            for j in j0..=j1 {
                for i in i0..=i1 {
                    buckets[j * nx + i].push(k as u32);
                }
            }
        }
        let mut start = Vec::with_capacity(nx * nz + 1);
        let mut items = Vec::new();
        for b in &buckets {
            start.push(items.len() as u32);
            items.extend_from_slice(b);
        }
        start.push(items.len() as u32);
        Self { origin, cell, nx, nz, start, items }
    }

    /// Segments whose neighbourhood may contain `p` (none outside the grid).
    pub(crate) fn near(&self, p: Vec2) -> &[u32] {
        &self.items[self.near_range(p)]
    }

    /// Where [`SegmentBuckets::near`]'s segments lie in [`SegmentBuckets::items`].
    pub(crate) fn near_range(&self, p: Vec2) -> std::ops::Range<usize> {
        let c = (p - self.origin) / self.cell;
        if !(c.x >= 0.0 && c.y >= 0.0) || c.x as usize >= self.nx || c.y as usize >= self.nz {
            return 0..0;
        }
        let k = c.y as usize * self.nx + c.x as usize;
        self.start[k] as usize..self.start[k + 1] as usize
    }

    /// Every cell's segment numbers, cell after cell.
    pub(crate) fn items(&self) -> &[u32] {
        &self.items
    }
}

/// Segments bucketed into square cells for distance queries.
#[derive(Clone, Debug)]
struct SegmentIndex {
    /// Per segment: start a, direction b - a, and 1/|b - a|² (0 for a point).
    lines: Vec<(Vec2, Vec2, f32)>,
    buckets: SegmentBuckets,
}

impl SegmentIndex {
    /// Bucket every segment into the cells its L_thr-neighbourhood overlaps.
    fn new(shape: &Shape, reach: f32) -> Self {
        let segments: Vec<(Vec2, Vec2)> = shape.segments().collect();
        let (lo, hi) = segments.iter().fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), &(a, b)| {
            (lo.min(a).min(b), hi.max(a).max(b))
        });
        let origin = lo - Vec2::splat(reach);
        let cell = (reach * 2.0).max(1e-6);
        let span = (hi + Vec2::splat(reach) - origin) / cell;
        let cells = if segments.is_empty() {
            (1, 1)
        } else {
            ((span.x as usize + 1).min(4096), (span.y as usize + 1).min(4096))
        };
        let buckets = SegmentBuckets::new(segments.iter().copied(), reach, origin, cell, cells);
        let lines = segments
            .iter()
            .map(|&(a, b)| {
                let len2 = (b - a).length_squared();
                (a, b - a, if len2 > 0.0 { 1.0 / len2 } else { 0.0 })
            })
            .collect();
        Self { lines, buckets }
    }

    /// Segments whose neighbourhood may contain `p`.
    fn near(&self, p: Vec2) -> &[u32] {
        self.buckets.near(p)
    }

    /// Whether some segment lies within `reach` of `p` (squared distances: no root, no
    /// division).
    fn covers(&self, p: Vec2, reach: f32) -> bool {
        let reach_sq = reach * reach;
        self.near(p).iter().any(|&s| self.distance_squared(p, s as usize) < reach_sq)
    }

    /// Distance from `p` to the nearest segment listed near it (∞ if none).
    fn nearest(&self, p: Vec2) -> f32 {
        self.near(p)
            .iter()
            .map(|&s| self.distance_squared(p, s as usize))
            .fold(f32::INFINITY, f32::min)
            .sqrt()
    }

    /// Squared distance from `p` to segment `s`.
    #[inline]
    fn distance_squared(&self, p: Vec2, s: usize) -> f32 {
        let (a, ab, inv_len2) = self.lines[s];
        let t = ((p - a).dot(ab) * inv_len2).clamp(0.0, 1.0);
        (a + ab * t).distance_squared(p)
    }
}

/// The cells of a fine square grid that meet the neighbourhood of the segments, each
/// marked when it lies wholly inside it.
struct CellCover {
    origin: Vec2,
    size: f32,
    nx: usize,
    /// (cell index, wholly inside).
    cells: Vec<(u32, bool)>,
}

/// Fine cells per L_thr for [`CellCover`]: a quarter of L_thr wide, most cells that meet
/// the neighbourhood lie wholly inside it.
const COVER_CELLS_PER_REACH: f32 = 4.0;
/// Most cells a [`CellCover`] may have (coarser cells beyond).
const MAX_COVER_CELLS: f32 = 4.0e6;

impl CellCover {
    /// Classify the cells by the distance d from their centre to the nearest segment:
    /// with h the half-diagonal, d ≥ reach + h means no point of the cell is near
    /// (dropped), d + h < reach means every point is (kept, inside), else some may be
    /// (kept, to test). `index` must list every segment within reach + h of a point.
    fn new(index: &SegmentIndex, lo: Vec2, hi: Vec2, reach: f32, size: f32) -> Self {
        let nx = ((hi.x - lo.x) / size).ceil().max(1.0) as usize;
        let nz = ((hi.y - lo.y) / size).ceil().max(1.0) as usize;
        let half_diagonal = size * std::f32::consts::FRAC_1_SQRT_2;
        let cells = (0..nz)
            .into_par_iter()
            .flat_map_iter(|j| {
                (0..nx).filter_map(move |i| {
                    let centre = lo + (Vec2::new(i as f32, j as f32) + 0.5) * size;
                    let d = index.nearest(centre);
                    (d < reach + half_diagonal).then_some(((j * nx + i) as u32, d + half_diagonal < reach))
                })
            })
            .collect();
        Self { origin: lo, size, nx, cells }
    }
}

/// `count` points uniformly distributed within `reach_km` (L_thr) of the shape's
/// segments. Deterministic for `(seed, stream)`, whatever the thread count.
pub fn sample_near_shape(
    shape: &Shape,
    reach_km: f32,
    count: usize,
    sampler: Sampler,
    seed: u64,
    stream: u64,
) -> Vec<Vec2> {
    let r = reach_km;
    if shape.segments().next().is_none() || count == 0 || !(r > 0.0) {
        return Vec::new();
    }
    let (lo, hi) = shape
        .segments()
        .fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), (a, b)| (lo.min(a).min(b), hi.max(a).max(b)));
    let (box_lo, box_hi) = (lo - Vec2::splat(r), hi + Vec2::splat(r));
    let span = box_hi - box_lo;
    let size = (r / COVER_CELLS_PER_REACH).max((span.x * span.y / MAX_COVER_CELLS).sqrt());
    // The index lists segments within reach + the cover cells' half-diagonal of a point.
    let index = SegmentIndex::new(shape, r + size * std::f32::consts::FRAC_1_SQRT_2);
    let cover = match sampler {
        Sampler::Paper => None,
        Sampler::Direct => Some(CellCover::new(&index, box_lo, box_hi, r, size)),
    };
    let chunks = count.div_ceil(SAMPLE_CHUNK);
    let parts: Vec<Vec<Vec2>> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let want = SAMPLE_CHUNK.min(count - c * SAMPLE_CHUNK);
            let mut rng = Stream::new(seed, SAMPLE, stream.wrapping_mul(1 << 20).wrapping_add(c as u64));
            let mut out = Vec::with_capacity(want);
            while out.len() < want {
                match &cover {
                    None => {
                        let p = Vec2::new(rng.uniform(box_lo.x, box_hi.x), rng.uniform(box_lo.y, box_hi.y));
                        if index.covers(p, r) {
                            out.push(p);
                        }
                    }
                    Some(cover) => {
                        // A cell uniformly among those that meet the neighbourhood (all of
                        // equal area), a uniform point in it, kept if near a segment.
                        let (k, inside) = cover.cells[rng.below(cover.cells.len() as u32) as usize];
                        let (i, j) = (k as usize % cover.nx, k as usize / cover.nx);
                        let corner = cover.origin + Vec2::new(i as f32, j as f32) * cover.size;
                        let p = corner + Vec2::new(rng.next_f32(), rng.next_f32()) * cover.size;
                        if inside || index.covers(p, r) {
                            out.push(p);
                        }
                    }
                }
            }
            out
        })
        .collect();
    parts.concat()
}

/// Count points per grid cell (points outside the plane are not counted).
pub fn count_per_cell(grid: &Grid, points: &[Vec2]) -> Vec<u32> {
    let mut n = vec![0u32; grid.len()];
    for &p in points {
        if let Some((i, j)) = grid.cell_of(p) {
            n[grid.index(i, j)] += 1;
        }
    }
    n
}

/// How the Poisson equation is solved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "method", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Poisson {
    /// The thesis's Gauss-Seidel iteration of eq (2.6), cell by cell in row order, until
    /// `max_iterations` or until no cell changes by more than `tolerance` × max |φ|.
    GaussSeidel {
        /// Iteration cap.
        max_iterations: u32,
        /// Relative change at which to stop.
        tolerance: f64,
    },
    /// The exact solution of the same discrete equations by the discrete sine transform
    /// (which diagonalises the 5-point Laplacian with φ = 0 on the border), in
    /// O(N² log N): the limit Gauss-Seidel converges to, in milliseconds.
    #[default]
    Direct,
}

/// Solve eq (2.6) for the potential: on interior cells φ = (γ - s)/4 where γ is the sum
/// of the four neighbours and s the source (here s = N, the charges in the cell, so φ is
/// in units of q0/ε0; the thesis's minus sign makes the potential low near the shape);
/// φ = 0 on the border cells. Returns φ and the iterations used (0 for `Direct`).
pub fn solve_potential(grid: &Grid, source: &[f64], method: Poisson) -> (Vec<f64>, u32) {
    match method {
        Poisson::GaussSeidel { max_iterations, tolerance } => {
            gauss_seidel(grid, source, max_iterations, tolerance)
        }
        Poisson::Direct => (dst_solve(grid, source), 0),
    }
}

fn gauss_seidel(grid: &Grid, s: &[f64], max_iterations: u32, tolerance: f64) -> (Vec<f64>, u32) {
    let (nx, nz) = (grid.nx, grid.nz);
    let mut phi = vec![0.0f64; nx * nz];
    if nx < 3 || nz < 3 {
        return (phi, 0);
    }
    for it in 1..=max_iterations {
        let mut max_change = 0.0f64;
        let mut max_abs = 0.0f64;
        for j in 1..nz - 1 {
            for i in 1..nx - 1 {
                let k = j * nx + i;
                let gamma = phi[k - 1] + phi[k + 1] + phi[k - nx] + phi[k + nx];
                let new = 0.25 * (gamma - s[k]);
                max_change = max_change.max((new - phi[k]).abs());
                max_abs = max_abs.max(new.abs());
                phi[k] = new;
            }
        }
        if max_change <= tolerance * max_abs {
            return (phi, it);
        }
    }
    (phi, max_iterations)
}

/// DST-I of every row of length `n` in `data` (rows of stride `n`), in place, by an FFT
/// of the odd extension of length 2(n + 1). Rows go two at a time through one complex
/// FFT: the transform of a real odd sequence is purely imaginary, so with z = a + i·b,
/// Im Z carries a's transform and -Re Z carries b's.
fn dst_rows(data: &mut [f64], n: usize, fft: &Arc<dyn Fft<f64>>) {
    data.par_chunks_mut(2 * n).for_each(|pair| {
        let m = 2 * (n + 1);
        let mut buf = vec![Complex::new(0.0, 0.0); m];
        let (a, b) = pair.split_at_mut(n);
        for k in 0..n {
            let v = Complex::new(a[k], b.get(k).copied().unwrap_or(0.0));
            buf[k + 1] = v;
            buf[m - 1 - k] = -v;
        }
        fft.process(&mut buf);
        for k in 0..n {
            a[k] = -0.5 * buf[k + 1].im;
        }
        for (k, out) in b.iter_mut().enumerate() {
            *out = 0.5 * buf[k + 1].re;
        }
    });
}

fn transpose(src: &[f64], w: usize, h: usize) -> Vec<f64> {
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            out[x * h + y] = src[y * w + x];
        }
    }
    out
}

fn dst_solve(grid: &Grid, s: &[f64]) -> Vec<f64> {
    let (nx, nz) = (grid.nx, grid.nz);
    let mut phi = vec![0.0f64; nx * nz];
    if nx < 3 || nz < 3 {
        return phi;
    }
    let (n, m) = (nx - 2, nz - 2); // interior unknowns along x and z
    let mut planner = FftPlannerScalar::new();
    let (fx, fz) = (planner.plan_fft_forward(2 * (n + 1)), planner.plan_fft_forward(2 * (m + 1)));
    // Interior source, rows along x.
    let mut a: Vec<f64> =
        (0..m).flat_map(|j| (0..n).map(move |i| (i, j))).map(|(i, j)| s[(j + 1) * nx + i + 1]).collect();
    dst_rows(&mut a, n, &fx);
    let mut b = transpose(&a, n, m); // rows along z
    dst_rows(&mut b, m, &fz);
    // Divide by the eigenvalues of the 5-point operator (γ - 4φ).
    let (pn, pm) = (std::f64::consts::PI / (n + 1) as f64, std::f64::consts::PI / (m + 1) as f64);
    for k in 0..n {
        let lx = 2.0 * ((k + 1) as f64 * pn).cos();
        for l in 0..m {
            let lz = 2.0 * ((l + 1) as f64 * pm).cos();
            b[k * m + l] /= lx + lz - 4.0;
        }
    }
    dst_rows(&mut b, m, &fz);
    let mut c = transpose(&b, m, n);
    dst_rows(&mut c, n, &fx);
    // DST-I is its own inverse up to 2/(n + 1) per axis.
    let scale = 4.0 / ((n + 1) as f64 * (m + 1) as f64);
    for j in 0..m {
        for i in 0..n {
            phi[(j + 1) * nx + i + 1] = c[j * n + i] * scale;
        }
    }
    phi
}

/// The largest |residual| of eq (2.6) over the interior, γ - 4φ - s.
pub fn residual_max(grid: &Grid, phi: &[f64], s: &[f64]) -> f64 {
    let nx = grid.nx;
    let mut worst = 0.0f64;
    for j in 1..grid.nz.saturating_sub(1) {
        for i in 1..nx.saturating_sub(1) {
            let k = j * nx + i;
            let r = phi[k - 1] + phi[k + 1] + phi[k - nx] + phi[k + nx] - 4.0 * phi[k] - s[k];
            worst = worst.max(r.abs());
        }
    }
    worst
}

/// Add noise over (x, z, t) to the potential (§2.2.3, Fig 2.11): amplitude relative to
/// the largest |φ|, so the same setting works at any charge count.
pub fn add_noise(grid: &Grid, phi: &mut [f64], noise: &NoiseSampler, time_s: f64, relative_amplitude: f64) {
    if relative_amplitude == 0.0 {
        return;
    }
    let max_abs = phi.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let scale = relative_amplitude * max_abs;
    let nx = grid.nx;
    phi.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
        for (i, v) in row.iter_mut().enumerate() {
            let c = grid.center(i, j);
            *v += scale * noise.sample3(f64::from(c.x), f64::from(c.y), time_s);
        }
    });
}

/// E = -∇φ by central differences (eq 2.8, 2.9), one-sided at the border, in units of
/// (q0/ε0) per km.
pub fn electric_field(grid: &Grid, phi: &[f64]) -> Vec<Vec2> {
    let (nx, nz) = (grid.nx, grid.nz);
    let inv = 1.0 / f64::from(grid.cell_km);
    let mut e = vec![Vec2::ZERO; nx * nz];
    e.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
        for (i, out) in row.iter_mut().enumerate() {
            let (il, ir) = (i.saturating_sub(1), (i + 1).min(nx - 1));
            let (jl, jr) = (j.saturating_sub(1), (j + 1).min(nz - 1));
            let ex = -(phi[j * nx + ir] - phi[j * nx + il]) * inv / (ir - il).max(1) as f64;
            let ez = -(phi[jr * nx + i] - phi[jl * nx + i]) * inv / (jr - jl).max(1) as f64;
            *out = Vec2::new(ex as f32, ez as f32);
        }
    });
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize) -> Grid {
        Grid { nx: n, nz: n, origin_km: Vec2::ZERO, cell_km: 1.0 }
    }

    #[test]
    fn direct_solver_satisfies_the_discrete_equations() {
        let g = Grid { nx: 37, nz: 23, origin_km: Vec2::ZERO, cell_km: 2.0 };
        let mut s = vec![0.0; g.len()];
        for (k, v) in s.iter_mut().enumerate() {
            *v = ((k * 7919) % 13) as f64 - 3.0;
        }
        let (phi, _) = solve_potential(&g, &s, Poisson::Direct);
        // Rounding of O(N² log N) f64 operations on values of order 10-100.
        assert!(residual_max(&g, &phi, &s) < 1e-9, "{}", residual_max(&g, &phi, &s));
        for i in 0..g.nx {
            assert_eq!(phi[g.index(i, 0)], 0.0);
            assert_eq!(phi[g.index(i, g.nz - 1)], 0.0);
        }
    }

    #[test]
    fn a_point_charge_makes_a_well() {
        let g = grid(33);
        let mut s = vec![0.0; g.len()];
        s[g.index(16, 16)] = 100.0;
        let (phi, _) = solve_potential(&g, &s, Poisson::Direct);
        // The thesis's sign: the potential is lowest at the charge, so E points to it.
        let centre = phi[g.index(16, 16)];
        assert!(centre < 0.0 && phi.iter().all(|&v| v >= centre));
        let e = electric_field(&g, &phi);
        assert!(e[g.index(10, 16)].x > 0.0 && e[g.index(22, 16)].x < 0.0);
        assert!(e[g.index(16, 10)].y > 0.0 && e[g.index(16, 22)].y < 0.0);
    }

    #[test]
    fn samples_stay_within_reach_and_are_deterministic() {
        let shape = Shape {
            points: vec![Vec2::new(10.0, 10.0), Vec2::new(50.0, 20.0), Vec2::new(60.0, 60.0)],
            next: vec![Some(1), Some(2), None],
            sheet: vec![0; 3],
            index_in_sheet: vec![0, 1, 2],
        };
        for sampler in [Sampler::Paper, Sampler::Direct] {
            let a = sample_near_shape(&shape, 3.0, 10_000, sampler, 7, 0);
            assert_eq!(a.len(), 10_000);
            assert!(a.iter().all(|&p| shape.distance(p) < 3.0));
            let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
            let b = pool.install(|| sample_near_shape(&shape, 3.0, 10_000, sampler, 7, 0));
            assert_eq!(a, b);
        }
    }

    #[test]
    fn the_cell_cover_keeps_every_cell_that_meets_the_region_and_marks_inside_ones_truly() {
        let shape = Shape {
            points: vec![
                Vec2::new(10.0, 10.0),
                Vec2::new(50.0, 20.0),
                Vec2::new(52.0, 21.0),
                Vec2::new(30.0, 60.0),
            ],
            next: vec![Some(1), Some(2), Some(3), None],
            sheet: vec![0; 4],
            index_in_sheet: vec![0, 1, 2, 3],
        };
        let (r, size) = (6.0, 1.5);
        let index = SegmentIndex::new(&shape, r + size * std::f32::consts::FRAC_1_SQRT_2);
        let (lo, hi) = (Vec2::splat(4.0), Vec2::new(58.0, 66.0));
        let cover = CellCover::new(&index, lo, hi, r, size);
        let kept: std::collections::HashMap<u32, bool> = cover.cells.iter().copied().collect();
        let (mut inside, mut partial) = (0, 0);
        // A dense lattice of test points (8 per cell side), checked against the plain
        // distance to the shape.
        let step = size / 8.0;
        for j in 0..((hi.y - lo.y) / step) as usize {
            for i in 0..((hi.x - lo.x) / step) as usize {
                let p = lo + (Vec2::new(i as f32, j as f32) + 0.5) * step;
                let c = ((p - lo) / size).floor();
                let k = (c.y as usize * cover.nx + c.x as usize) as u32;
                let near = shape.distance(p) < r;
                match kept.get(&k) {
                    None => assert!(!near, "{p} is near the shape but its cell was dropped"),
                    Some(true) => {
                        assert!(near, "{p} is not near the shape but its cell is marked inside");
                        inside += 1;
                    }
                    Some(false) => partial += 1,
                }
            }
        }
        assert!(inside > 2 * partial, "most kept cells are wholly inside: {inside} vs {partial}");
    }
}
