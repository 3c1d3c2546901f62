//! Snow glitter: the sparkle model (Hwang and Noma, §2) on the snow's surface. Sunlit snow
//! is full of ice grains whose flat faces mirror the sun; a grain glints when its face
//! normal N lies within the Phong cone around the half vector H between the sun and the
//! eye, (|N·H|)^n ≥ I_e (two-sided faces, k_s I_l = 1), and shines (|N·H|)^n.
//!
//! **The full system.** Grains lie on the snow's triangles as a Poisson process of
//! `grains_per_m2`, positions uniform over each triangle, face normals uniform over the
//! sphere. The grains stay where they are: the same snow seen from elsewhere, or under a
//! moved sun, glints elsewhere, as real snow does (no per-frame noise).
//!
//! **Only the grains that can glint are made.** The sphere of normals is cut into
//! [`CELLS`] cells of equal solid angle (bands of equal height in z, equal sectors in
//! azimuth). The grains of a triangle whose normals fall in one cell are a Poisson count
//! of mean ρ A / [`CELLS`] with positions and normals uniform in the triangle and the
//! cell, drawn from random numbers keyed by the triangle's place and the cell (read by
//! counter, so a grain whose normal cannot glint costs one number): so each
//! cell's grains are fixed, frame after frame, and only the cells that meet the cone
//! around ±H (widened by how much H can turn across the triangle) are ever drawn, a few of
//! the 2,048. A Poisson process restricted to disjoint cells is independent Poisson
//! processes on them, so the glints have exactly the full system's distribution;
//! `tests/glitter_matches_brute_force.rs` checks it against [`brute_force`], which draws
//! every grain of every triangle.

use glam::Vec3;
use phenomena_core::rng::{Counter, Purpose, Stream};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use phenomena_core::validate::Issues;

/// Bands of equal height in z of the sphere of normals.
const Z_BANDS: usize = 32;
/// Azimuth sectors per band.
const SECTORS: usize = 64;
/// Cells of equal solid angle, 4π / 2,048 sr each (about 4.5° across on average). With
/// 2,048 the village's glitter took 15.2 ms against 16.5 with 512 (8 % less), and with
/// 8,192 (64 × 128) no less (15.4 ms): medians of three runs, docs/performance.md,
/// 2026-12-07.
pub const CELLS: usize = Z_BANDS * SECTORS;

const GRAINS: Purpose = Purpose::named("snow.glitter.grains");
/// A cell's count where its mean is too large for inversion (a stream of another purpose
/// than [`GRAINS`]: a stream's state is the first numbers of the counter of its key).
const GRAIN_COUNTS: Purpose = Purpose::named("snow.glitter.grain-counts");
const BRUTE: Purpose = Purpose::named("snow.glitter.brute-force");

/// Snow glitter settings (`[render.glitter]`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Glitter {
    /// Ice grains per square metre of snow surface (0: no glitter).
    pub grains_per_m2: f32,
    /// Phong exponent n of a grain's face.
    pub exponent_n: f32,
    /// Visibility threshold I_e (relative to k_s I_l = 1).
    pub threshold_i_e: f32,
    /// Radiance of a grain's face mirroring the sun, relative to sunlit white snow's
    /// (2,000: ice reflects 2-5 % of the sun's radiance, some 10⁵ times a white
    /// surface's under the same sun, before the sun's disc outgrows the cone).
    pub mirror_radiance: f32,
    /// Size of a grain's face, mm: a glint lights a pixel by its face's share of the
    /// pixel's footprint, so near grains sparkle and far ones fade into the snow.
    pub grain_mm: f32,
}

impl Default for Glitter {
    fn default() -> Self {
        // n = 10,000 and I_e = 0.0025: a cone of 1.98° (the sparkle default), so
        // 1 - cos θ = 6·10⁻⁴ of two-sided grains glint: ~60 per m² of sunlit snow.
        Self {
            grains_per_m2: 1.0e5,
            exponent_n: 10_000.0,
            threshold_i_e: 0.0025,
            mirror_radiance: 2000.0,
            grain_mm: 1.0,
        }
    }
}

impl Glitter {
    /// The settings' problems, fields under `prefix`.
    pub(crate) fn validate(&self, i: &mut Issues, prefix: &str) {
        // Up to 10x the default: every visible face draws its grains in the cells near
        // the cone each frame (a few of the 2,048), so 10⁸ per m² on the village's ~10³ m²
        // would draw some 10⁸ to 10⁹ grains a frame.
        i.range(&format!("{prefix}.grains_per_m2"), self.grains_per_m2, 0.0..=1e6);
        i.range(&format!("{prefix}.exponent_n"), self.exponent_n, 1.0..=1e7);
        i.range_open_low(&format!("{prefix}.threshold_i_e"), self.threshold_i_e, 0.0, 0.999);
        i.range(&format!("{prefix}.mirror_radiance"), self.mirror_radiance, 0.0..=1e9);
        i.range_open_low(&format!("{prefix}.grain_mm"), self.grain_mm, 0.0, 1000.0);
    }

    /// Half-angle of the cone of normals that glint, radians.
    fn cone_rad(&self) -> f32 {
        self.threshold_i_e.powf(1.0 / self.exponent_n).clamp(-1.0, 1.0).acos()
    }

    /// The brightness of a grain of face normal `n` under half vector `h`, if it glints.
    fn intensity(&self, n: Vec3, h: Vec3) -> Option<f32> {
        let i = n.dot(h).abs().powf(self.exponent_n);
        (i >= self.threshold_i_e).then_some(i)
    }
}

/// A glinting grain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Glint {
    /// Where, metres.
    pub position: Vec3,
    /// Brightness (|N·H|)^n, in [I_e, 1].
    pub intensity: f32,
}

/// The light's geometry: the eye, and the unit direction towards the sun.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Viewing {
    /// The eye, metres.
    pub eye: Vec3,
    /// Unit direction towards the sun.
    pub sun: Vec3,
}

impl Viewing {
    /// The half vector at `p`.
    fn half(&self, p: Vec3) -> Vec3 {
        (self.sun + (self.eye - p).normalize_or_zero()).normalize_or_zero()
    }
}

/// A triangle's key for its grains' streams: its place (centroid to the millimetre, and
/// which tenth of a metre of height), so its grains stay while the snow beneath it
/// deepens by less than that and the mesh is rebuilt; snow on two maps at one place
/// (a bench over the ground) differs in height by more, so its grains differ. A
/// triangle's grains are drawn anew when its snow crosses a tenth of a metre (about
/// every two hours at 5 cm/h) or its edge moves.
fn key(tri: &[Vec3; 3]) -> u64 {
    let c = (tri[0] + tri[1] + tri[2]) / 3.0;
    let q = |v: f32, step: f32| (v / step).floor() as i64 as u64;
    q(c.x, 1e-3).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ q(c.z, 1e-3).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ q(c.y, 0.1).wrapping_mul(0x1656_67B1_9E37_79F9)
}

/// A cell's ranges: z in [z0, z1), azimuth in [φ0, φ1).
fn cell_bounds(cell: usize) -> (f32, f32, f32, f32) {
    let (band, sector) = (cell / SECTORS, cell % SECTORS);
    let dz = 2.0 / Z_BANDS as f32;
    let dphi = std::f32::consts::TAU / SECTORS as f32;
    let z0 = -1.0 + band as f32 * dz;
    (z0, z0 + dz, sector as f32 * dphi, (sector + 1) as f32 * dphi)
}

/// Pushes onto `out` the cells that may hold a normal within `alpha` of unit `axis`;
/// returns the heights z such a normal can have (lowest, highest).
fn cells_near(axis: Vec3, alpha: f32, out: &mut Vec<usize>) -> (f32, f32) {
    let theta = axis.z.clamp(-1.0, 1.0).acos();
    let (lo, hi) = ((theta + alpha).min(std::f32::consts::PI).cos(), (theta - alpha).max(0.0).cos());
    let dz = 2.0 / Z_BANDS as f32;
    let band_of = |z: f32| (((z + 1.0) / dz).floor() as i64).clamp(0, Z_BANDS as i64 - 1) as usize;
    // The cap's azimuth half-width; all azimuths when it holds a pole.
    let s = theta.sin();
    let all = theta <= alpha || theta + alpha >= std::f32::consts::PI || alpha.sin() >= s;
    let dphi = std::f32::consts::TAU / SECTORS as f32;
    // The sectors the cap spans (the same in every band); unused when it holds a pole.
    let (first, last) = if all {
        (0, 0)
    } else {
        let half = (alpha.sin() / s).asin();
        let phi = axis.y.atan2(axis.x).rem_euclid(std::f32::consts::TAU);
        (((phi - half) / dphi).floor() as i64, ((phi + half) / dphi).floor() as i64)
    };
    for band in band_of(lo)..=band_of(hi) {
        if all {
            out.extend((0..SECTORS).map(|k| band * SECTORS + k));
            continue;
        }
        for k in first..=last {
            out.push(band * SECTORS + k.rem_euclid(SECTORS as i64) as usize);
        }
    }
    (lo, hi)
}

/// A point uniform over the triangle.
fn in_triangle(tri: &[Vec3; 3], s: &mut Stream) -> Vec3 {
    let (u, v) = (s.next_f32(), s.next_f32());
    in_triangle_at(tri, u, v)
}

/// The point of the triangle that two uniforms in [0, 1) pick, uniform over it when they
/// are (the square folded along its diagonal onto the triangle's half).
#[inline]
fn in_triangle_at(tri: &[Vec3; 3], mut u: f32, mut v: f32) -> Vec3 {
    if u + v > 1.0 {
        (u, v) = (1.0 - u, 1.0 - v);
    }
    tri[0] + (tri[1] - tri[0]) * u + (tri[2] - tri[0]) * v
}

/// Means from which [`poisson`] leaves inversion for `rand_distr`.
const INVERSION_BELOW: f64 = 30.0;

/// A Poisson count of mean `mean`, with `e` = exp(−mean) given (a triangle's cells share
/// it): by inversion of the distribution function below a mean of 30 (about mean + 1
/// uniforms' worth of steps, one uniform), by `rand_distr` above.
fn poisson(s: &mut Stream, mean: f64, e: f64) -> u64 {
    if mean < INVERSION_BELOW {
        return poisson_inverted(s.next_f64(), mean, e);
    }
    match rand_distr::Poisson::new(mean) {
        Ok(d) => s.sample::<f64, _>(&d) as u64,
        Err(_) => 0,
    }
}

/// The Poisson count of mean `mean` (`e` = exp(−mean)) whose distribution function first
/// exceeds the uniform `u`.
#[inline]
fn poisson_inverted(u: f64, mean: f64, e: f64) -> u64 {
    let (mut k, mut p, mut cdf) = (0u64, e, e);
    while u >= cdf && p > 0.0 {
        k += 1;
        p *= mean / k as f64;
        cdf += p;
    }
    k
}

/// The glints of the grains on `tris` (the snow's surface) seen under `viewing`, made
/// only in the cells of normals that can glint. In triangle order, the same for any
/// thread count.
pub fn glints(tris: &[[Vec3; 3]], viewing: Viewing, g: &Glitter, seed: u64) -> Vec<Glint> {
    if !(g.grains_per_m2 > 0.0) {
        return Vec::new();
    }
    let cone = g.cone_rad();
    // A cheap first test (a little wider than the threshold, for rounding).
    let cos_cone = (cone + 1e-4).cos();
    // Chunks of triangles in parallel, each with its own buffers, joined in order.
    tris.par_chunks(1024)
        .flat_map_iter(|chunk| {
            let (mut out, mut cells) = (Vec::new(), Vec::new());
            for tri in chunk {
                triangle_glints(tri, viewing, g, seed, (cone, cos_cone), &mut cells, &mut out);
            }
            out
        })
        .collect()
}

/// The glints of one triangle's grains, onto `out` (`cells`: a scratch buffer).
fn triangle_glints(
    tri: &[Vec3; 3],
    viewing: Viewing,
    g: &Glitter,
    seed: u64,
    (cone, cos_cone): (f32, f32),
    cells: &mut Vec<usize>,
    out: &mut Vec<Glint>,
) {
    let centre = (tri[0] + tri[1] + tri[2]) / 3.0;
    let h = viewing.half(centre);
    if h == Vec3::ZERO {
        return;
    }
    let alpha = cone + half_vector_turn(tri, centre, viewing) + 1e-4;
    cells.clear();
    // A glinting normal is within the cone of H at its grain, and that H within the turn
    // of H at the centre: within α of ±H there. The cells and the heights z a normal
    // within α of H can have (those near −H: the negated), and the cap, take 1e-3 more
    // for rounding (`cells_near`'s arccosine of H's height is off by up to about 4e-4
    // next to the poles).
    let z = cells_near(h, alpha + 1e-3, cells);
    antipodes(cells);
    let cap = Cap { axis: h, cos_alpha: (alpha + 1e-3).min(std::f32::consts::PI).cos(), z };
    grains_in(tri, (viewing, g, seed), cos_cone, cells, cap, out);
}

/// `cells` joined by their antipodal cells (those of the cone around −H: the partition is
/// symmetric), in ascending order without repeats.
fn antipodes(cells: &mut Vec<usize>) {
    let n = cells.len();
    for k in 0..n {
        let (band, sector) = (cells[k] / SECTORS, cells[k] % SECTORS);
        cells.push((Z_BANDS - 1 - band) * SECTORS + (sector + SECTORS / 2) % SECTORS);
    }
    cells.sort_unstable();
    cells.dedup();
}

/// How far H may turn over the triangle from its value at the centre, radians: the eye's
/// direction V turns by at most δ = asin(reach / distance) (the triangle's angular
/// radius), and H = (L + V)/|L + V| turns by at most δ / |L + V| (most when the eye
/// looks towards the sun and |L + V| is small), with |L + V| ≥ |L + V_c| − δ; all the
/// sphere (π) when that bound fails. `centre`: the triangle's centroid.
fn half_vector_turn(tri: &[Vec3; 3], centre: Vec3, viewing: Viewing) -> f32 {
    let reach = tri.iter().map(|p| (*p - centre).length()).fold(0.0, f32::max);
    let to_eye = viewing.eye - centre;
    let distance = to_eye.length();
    if !(distance > reach) {
        return std::f32::consts::PI;
    }
    let delta = (reach / distance).asin();
    let sum = (viewing.sun + to_eye / distance).length() - delta;
    if sum > 1e-3 { (delta / sum).min(std::f32::consts::PI) } else { std::f32::consts::PI }
}

/// Where a triangle's glinting normals can be: within the angle of cosine `cos_alpha`
/// of ±`axis`, so at heights z in `z` or its negation.
#[derive(Clone, Copy)]
struct Cap {
    axis: Vec3,
    cos_alpha: f32,
    z: (f32, f32),
}

impl Cap {
    /// The whole sphere.
    #[cfg(test)]
    const ALL: Cap = Cap { axis: Vec3::Z, cos_alpha: -1.0, z: (-1.0, 1.0) };
}

/// The glints of the grains of `tri` whose normals lie in `cells` (normals outside `cap`
/// cannot glint and are not looked at: outside its heights before their azimuth is
/// drawn, outside its angle before the grain is placed), onto `out`.
fn grains_in(
    tri: &[Vec3; 3],
    (viewing, g, seed): (Viewing, &Glitter, u64),
    cos_cone: f32,
    cells: &[usize],
    cap: Cap,
    out: &mut Vec<Glint>,
) {
    let area = 0.5 * (tri[1] - tri[0]).cross(tri[2] - tri[0]).length();
    if !(area > 0.0) {
        return;
    }
    let mean = f64::from(g.grains_per_m2) * f64::from(area) / CELLS as f64;
    let e = (-mean).exp();
    let k = key(tri);
    for &cell in cells {
        let numbers = cell_numbers(seed, k, cell);
        let count = if mean < INVERSION_BELOW {
            poisson_inverted(numbers.f64_at(0), mean, e)
        } else {
            poisson(&mut Stream::new(seed, GRAIN_COUNTS, cell_index(k, cell)), mean, e)
        };
        cell_grains(&numbers, cell, count, cap, |_, n, (u, v)| {
            if let Some(glint) = glint_of(tri, viewing, g, cos_cone, n, (u, v)) {
                out.push(glint);
            }
        });
    }
}

/// The index of a cell's random numbers: a triangle's key (see [`key`]) and the cell.
#[inline]
fn cell_index(key: u64, cell: usize) -> u64 {
    key.wrapping_mul(CELLS as u64).wrapping_add(cell as u64)
}

/// A cell's numbers by counter: its count is number 0, grain j's normal (height,
/// azimuth) number 2j + 1 and its place number 2j + 2, so a grain whose normal cannot
/// glint costs one number, and every grain has its own numbers whatever the view.
#[inline]
fn cell_numbers(seed: u64, key: u64, cell: usize) -> Counter {
    Counter::new(seed, GRAINS, cell_index(key, cell))
}

/// The first `count` grains of `cell` (its `numbers`) whose normals lie in `cap`, in
/// order: `keep(j, normal, (u, v))`, (u, v) picking the grain's place in its triangle
/// ([`in_triangle_at`]).
#[inline]
fn cell_grains(
    numbers: &Counter,
    cell: usize,
    count: u64,
    cap: Cap,
    mut keep: impl FnMut(u64, Vec3, (f32, f32)),
) {
    let (z0, z1, p0, p1) = cell_bounds(cell);
    for j in 0..count {
        let (a, b) = numbers.f32_pair_at(2 * j + 1);
        let z = z0 + (z1 - z0) * a;
        // Outside both caps' heights: cannot glint (no trigonometry spent).
        let near = (cap.z.0..=cap.z.1).contains(&z) || (-cap.z.1..=-cap.z.0).contains(&z);
        if !near {
            continue;
        }
        let phi = p0 + (p1 - p0) * b;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (sin, cos) = phi.sin_cos();
        let n = Vec3::new(r * cos, r * sin, z);
        if n.dot(cap.axis).abs() < cap.cos_alpha {
            continue;
        }
        keep(j, n, numbers.f32_pair_at(2 * j + 2));
    }
}

/// The glint of a grain of face normal `n` at the place (u, v) picks in `tri`, if it
/// glints.
#[inline]
fn glint_of(
    tri: &[Vec3; 3],
    viewing: Viewing,
    g: &Glitter,
    cos_cone: f32,
    n: Vec3,
    (u, v): (f32, f32),
) -> Option<Glint> {
    let x = in_triangle_at(tri, u, v);
    let h = viewing.half(x);
    if n.dot(h).abs() >= cos_cone {
        return g.intensity(n, h).map(|intensity| Glint { position: x, intensity });
    }
    None
}

/// How much wider than a face's cone of glinting normals a kept face's grains reach,
/// radians (0.1°): the face's H may turn this far (as the snow beneath it deepens), less
/// any growth of its cone's own half-angle, before its grains are drawn anew. The cone
/// is about 2.2° at the defaults, so a kept face holds about a tenth more grains than
/// it needs; in the village and the yard (frames 24..34) fewer than one face in 10,000
/// a frame turned past 0.25°.
const KEPT_ROOM_RAD: f32 = 0.1 * std::f32::consts::PI / 180.0;
/// How much a kept face may grow, a share of its area, before its grains are drawn anew
/// (with 1 %, 3.5 % of the village's faces a frame grew past it).
const KEPT_AREA_ROOM: f32 = 0.05;
/// Slots of the table of kept faces a key may take.
const WAYS: usize = 8;

/// The grains that may glint on each face, kept from frame to frame: an exact shortcut
/// for [`glints`] on snow that changes little between frames. Each face's grains are
/// fixed by its key (its place) and the cells of normals; a face that is drawn keeps
/// the grains of its cells near ±H whose normals lie within 0.1° more than its cone, up
/// to the counts of a face 5 % larger. While a face of the same key has its H that
/// close to the kept one and its area no larger, its glints are those of the kept
/// grains that pass the glint test now (the counts worked out for its area now, from
/// the same numbers; a count by inversion does not grow as the mean falls, which
/// rounding could break only for a uniform within about 10⁻¹⁶ of a step of the
/// distribution function): so [`GlintCache::glints`] returns exactly what [`glints`]
/// returns, frame after frame (tests `kept_grains_glint_as_drawn_ones`, with snow
/// deepening under a moving sun, and `kept_grains_follow_faces_that_grow`). A change of
/// seed, settings, eye or sun empties it.
///
/// The village's glitter at 640x360 (frames 24..48) took 13.4-13.7 ms against
/// 18.2-19.4 without it, the yard's 10.5-11.8 against 14.1-16.1 (docs/performance.md,
/// 2026-12-07); the call after a change costs about twice [`glints`], as it keeps
/// every face.
#[derive(Clone, Default)]
pub struct GlintCache {
    under: Option<Under>,
    /// The kept faces' keys, [`WAYS`] to a bucket (a bucket per place: see
    /// [`GlintCache::bucket_of`]), and the faces in the same order.
    keys: Vec<u64>,
    slots: Vec<Slot>,
    /// Calls so far (each slot's `used` is the last call that used it).
    calls: u32,
    /// The side of the cells of the grid of places that picks a face's bucket, m.
    grid_m: f32,
    cells: Vec<KeptCell>,
    grains: Vec<KeptGrain>,
    /// The kept cells and grains after the last compaction.
    live: usize,
    /// Faces found kept and faces drawn anew in the last call.
    hits: usize,
    misses: usize,
    /// Compactions so far.
    compactions: usize,
}

impl std::fmt::Debug for GlintCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GlintCache")
            .field("slots", &self.slots.len())
            .field("cells", &self.cells.len())
            .field("grains", &self.grains.len())
            .field("last_call", &self.last_call())
            .finish_non_exhaustive()
    }
}

/// What a cache's faces were kept under.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Under {
    seed: u64,
    glitter: Glitter,
    eye: Vec3,
    sun: Vec3,
}

/// A kept face (its key beside it in [`GlintCache::keys`]): the H and cone half-angle its
/// grains were kept for, the largest area they serve, and its cells (`cells..cells +
/// n_cells` of the cache's).
#[derive(Clone, Copy, Debug, Default)]
struct Slot {
    filled: bool,
    used: u32,
    axis: Vec3,
    alpha: f32,
    area: f32,
    cells: u32,
    n_cells: u32,
}

/// A kept cell: its count's uniform and its kept grains (`grains..end` of the cache's).
#[derive(Clone, Copy, Debug)]
struct KeptCell {
    u0: f64,
    grains: u32,
    end: u32,
}

/// A kept grain: its number j in its cell, its normal and its place's uniforms.
#[derive(Clone, Copy, Debug)]
struct KeptGrain {
    j: u64,
    n: Vec3,
    uv: (f32, f32),
}

/// Faces kept anew by one chunk of a call, (bucket, key, face), the faces' cells and
/// grains indexed in the chunk's own lists.
#[derive(Default)]
struct Kept {
    faces: Vec<(usize, u64, Slot)>,
    cells: Vec<KeptCell>,
    grains: Vec<KeptGrain>,
    /// The slots whose faces served.
    used: Vec<usize>,
}

impl GlintCache {
    /// Faces whose kept grains served the last call, and faces drawn anew and kept in it
    /// (none in the first call after a change: see [`GlintCache::glints`]).
    pub fn last_call(&self) -> (usize, usize) {
        (self.hits, self.misses)
    }

    /// The glints of the grains on `tris`, exactly as [`glints`] gives them, keeping
    /// each face's grains for the next call. The first call after a change of seed,
    /// settings, eye or sun (or the first of all) is [`glints`] itself and keeps nothing;
    /// the next keeps every face it can (not those past the inversion of the counts or
    /// with too wide a cone, which are always drawn afresh).
    pub fn glints(&mut self, tris: &[[Vec3; 3]], viewing: Viewing, g: &Glitter, seed: u64) -> Vec<Glint> {
        if !(g.grains_per_m2 > 0.0) {
            return Vec::new();
        }
        let under = Under { seed, glitter: *g, eye: viewing.eye, sun: viewing.sun };
        let size = (4 * tris.len()).next_power_of_two().max(1024);
        if self.under != Some(under) {
            // The first call after a change draws as `glints` does and keeps nothing: a
            // still frame, or a view that changes every frame, pays nothing for keeping.
            *self = Self { under: Some(under), ..Self::default() };
            return glints(tris, viewing, g, seed);
        }
        if self.slots.len() < size {
            (self.keys, self.slots) = (vec![0; size], vec![Slot::default(); size]);
            (self.cells, self.grains, self.live) = (Vec::new(), Vec::new(), 0);
            // The side of a square of twice the faces' mean area: a texel's for the
            // halves of texels.
            let area: f64 = tris.iter().map(|t| f64::from((t[1] - t[0]).cross(t[2] - t[0]).length())).sum();
            self.grid_m = ((area / tris.len() as f64).sqrt() as f32).max(1e-4);
        }
        let cone = g.cone_rad();
        let cos_cone = (cone + 1e-4).cos();
        self.calls += 1;
        let this = &*self;
        let parts: Vec<(Vec<Glint>, Kept)> = tris
            .par_chunks(1024)
            .map(|chunk| {
                let (mut out, mut kept, mut cells) = (Vec::new(), Kept::default(), Vec::new());
                for tri in chunk {
                    this.face(tri, (viewing, g, seed), (cone, cos_cone), &mut cells, &mut kept, &mut out);
                }
                (out, kept)
            })
            .collect();
        let mut out = Vec::new();
        (self.hits, self.misses) = (0, 0);
        // Every slot that served marked before any is replaced.
        for slot in parts.iter().flat_map(|(_, kept)| &kept.used) {
            self.slots[*slot].used = self.calls;
        }
        for (glints, kept) in parts {
            out.extend(glints);
            self.hits += kept.used.len();
            self.misses += kept.faces.len();
            self.keep(kept);
        }
        out
    }

    /// The first slot of the bucket of a face of centroid `c`: by its place on a grid in
    /// x and z of about the faces' size (`grid_m`: a texel's two faces and the snow of
    /// another map over or under them share a bucket's [`WAYS`]), each row of the grid
    /// on consecutive buckets from a place its z hashes to, so that faces next to each
    /// other (as the mesh lists them) look in buckets next to each other.
    #[inline]
    fn bucket_of(&self, c: Vec3) -> usize {
        let q = |v: f32| (v / self.grid_m).floor() as i64 as u64;
        let bucket = (q(c.z).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 32).wrapping_add(q(c.x));
        (bucket as usize).wrapping_mul(WAYS) & (self.slots.len() - 1)
    }

    /// The glints of one face onto `out`, from its kept grains (the slot noted in
    /// `kept.used`) or drawn anew and kept in `kept` (unless it cannot be: a mean count
    /// past inversion, or a cone too wide).
    fn face(
        &self,
        tri: &[Vec3; 3],
        (viewing, g, seed): (Viewing, &Glitter, u64),
        (cone, cos_cone): (f32, f32),
        cells: &mut Vec<usize>,
        kept: &mut Kept,
        out: &mut Vec<Glint>,
    ) {
        let centre = (tri[0] + tri[1] + tri[2]) / 3.0;
        let h = viewing.half(centre);
        let area = 0.5 * (tri[1] - tri[0]).cross(tri[2] - tri[0]).length();
        if h == Vec3::ZERO || !(area > 0.0) {
            return;
        }
        let alpha = cone + half_vector_turn(tri, centre, viewing) + 1e-4;
        let room = area * (1.0 + KEPT_AREA_ROOM);
        let k = key(tri);
        let bucket = self.bucket_of(centre);
        let serves = |i: usize| {
            let s = &self.slots[i];
            self.keys[i] == k
                && s.filled
                && area <= s.area
                && h.cross(s.axis).length().atan2(h.dot(s.axis)) + alpha <= s.alpha
        };
        if let Some(slot) = (bucket..bucket + WAYS).find(|&i| serves(i)) {
            let s = &self.slots[slot];
            let range = s.cells as usize..(s.cells + s.n_cells) as usize;
            glints_of_kept(tri, (viewing, g, cos_cone), area, &self.cells[range], &self.grains, out);
            kept.used.push(slot);
            return;
        }
        let mean_room = f64::from(g.grains_per_m2) * f64::from(room) / CELLS as f64;
        if !(mean_room < INVERSION_BELOW) || !(alpha + KEPT_ROOM_RAD < 0.5) {
            // Past inversion, or too wide a cone to keep: drawn as `glints` draws it.
            triangle_glints(tri, viewing, g, seed, (cone, cos_cone), cells, out);
            return;
        }
        let wide = alpha + KEPT_ROOM_RAD;
        cells.clear();
        let z = cells_near(h, wide + 1e-3, cells);
        antipodes(cells);
        let cap = Cap { axis: h, cos_alpha: (wide + 1e-3).min(std::f32::consts::PI).cos(), z };
        let e = (-mean_room).exp();
        let first = kept.cells.len();
        for &cell in cells.iter() {
            let numbers = cell_numbers(seed, k, cell);
            let u0 = numbers.f64_at(0);
            let start = kept.grains.len();
            cell_grains(&numbers, cell, poisson_inverted(u0, mean_room, e), cap, |j, n, uv| {
                kept.grains.push(KeptGrain { j, n, uv });
            });
            if kept.grains.len() > start {
                kept.cells.push(KeptCell { u0, grains: start as u32, end: kept.grains.len() as u32 });
            }
        }
        glints_of_kept(tri, (viewing, g, cos_cone), area, &kept.cells[first..], &kept.grains, out);
        let face = Slot {
            filled: true,
            used: 0,
            axis: h,
            alpha: wide,
            area: room,
            cells: first as u32,
            n_cells: (kept.cells.len() - first) as u32,
        };
        kept.faces.push((bucket, k, face));
    }

    /// One chunk's faces kept anew into the table (each into its bucket's slot of the
    /// same key, or else an empty one, or else the one used longest ago), and the lists
    /// compacted when mostly dead.
    fn keep(&mut self, kept: Kept) {
        let (cells0, grains0) = (self.cells.len() as u32, self.grains.len() as u32);
        self.grains.extend(kept.grains);
        self.cells.extend(kept.cells.into_iter().map(|c| KeptCell {
            u0: c.u0,
            grains: c.grains + grains0,
            end: c.end + grains0,
        }));
        for (bucket, key, mut face) in kept.faces {
            face.cells += cells0;
            face.used = self.calls;
            let ways = &mut self.slots[bucket..bucket + WAYS];
            let keys = &mut self.keys[bucket..bucket + WAYS];
            let slot = match (0..WAYS).find(|&i| ways[i].filled && keys[i] == key) {
                Some(same) => same,
                None => (0..WAYS).min_by_key(|&i| (ways[i].filled, ways[i].used)).unwrap_or(0),
            };
            (ways[slot], keys[slot]) = (face, key);
        }
        if self.cells.len() + self.grains.len() > 4 * self.live.max(1 << 16) {
            self.compact();
        }
    }

    /// The lists rebuilt with only what the table's faces used in this call hold (the
    /// others let go).
    fn compact(&mut self) {
        let (mut cells, mut grains) = (Vec::new(), Vec::new());
        self.compactions += 1;
        for s in &mut self.slots {
            s.filled &= s.used == self.calls;
        }
        for s in self.slots.iter_mut().filter(|s| s.filled) {
            let first = cells.len() as u32;
            for c in &self.cells[s.cells as usize..(s.cells + s.n_cells) as usize] {
                let start = grains.len() as u32;
                grains.extend_from_slice(&self.grains[c.grains as usize..c.end as usize]);
                cells.push(KeptCell { u0: c.u0, grains: start, end: grains.len() as u32 });
            }
            s.cells = first;
        }
        (self.cells, self.grains) = (cells, grains);
        self.live = self.cells.len() + self.grains.len();
    }
}

/// The glints of a face of `area` from its kept `cells` (grains in `grains`): each
/// cell's count for this area from its uniform, and of its first that many grains
/// those that glint, in order.
fn glints_of_kept(
    tri: &[Vec3; 3],
    (viewing, g, cos_cone): (Viewing, &Glitter, f32),
    area: f32,
    cells: &[KeptCell],
    grains: &[KeptGrain],
    out: &mut Vec<Glint>,
) {
    if cells.is_empty() {
        return;
    }
    let mean = f64::from(g.grains_per_m2) * f64::from(area) / CELLS as f64;
    let e = (-mean).exp();
    for c in cells {
        let count = poisson_inverted(c.u0, mean, e);
        for grain in grains[c.grains as usize..c.end as usize].iter().take_while(|k| k.j < count) {
            out.extend(glint_of(tri, viewing, g, cos_cone, grain.n, grain.uv));
        }
    }
}

/// The reference: every grain of every triangle (a Poisson count of mean ρ A, positions
/// uniform, normals uniform on the sphere), kept when it glints. Slow; for tests.
pub fn brute_force(tris: &[[Vec3; 3]], viewing: Viewing, g: &Glitter, seed: u64) -> Vec<Glint> {
    let mut out = Vec::new();
    for (t, tri) in tris.iter().enumerate() {
        let area = 0.5 * (tri[1] - tri[0]).cross(tri[2] - tri[0]).length();
        let mut s = Stream::new(seed, BRUTE, t as u64);
        let mean = f64::from(g.grains_per_m2) * f64::from(area);
        for _ in 0..poisson(&mut s, mean, (-mean).exp()) {
            let x = in_triangle(tri, &mut s);
            let n = s.on_unit_sphere();
            if let Some(intensity) = g.intensity(n, viewing.half(x)) {
                out.push(Glint { position: x, intensity });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cells_drawn_hold_every_glint_of_all_the_cells() {
        // The default narrow cone, the sun low and ahead (the eye looks towards it, where
        // H turns most over a triangle): the cells chosen give exactly the glints that
        // drawing every cell gives, triangle by triangle, for near and far, small and
        // large triangles.
        let g = Glitter { grains_per_m2: 2.0e6, ..Glitter::default() };
        let cone = g.cone_rad();
        let cos_cone = (cone + 1e-4).cos();
        let all: Vec<usize> = (0..CELLS).collect();
        let mut s = Stream::new(3, Purpose::named("test"), 0);
        let (mut found, mut cells) = (0, Vec::new());
        for t in 0..400 {
            let sun = Vec3::new(0.0, (2.0 + 10.0 * s.next_f32()).to_radians().sin(), -1.0).normalize();
            let viewing = Viewing { eye: Vec3::new(0.0, 1.6, 0.0), sun };
            let size = 0.02 + 0.5 * s.next_f32();
            let c = Vec3::new(4.0 * s.next_f32() - 2.0, 0.0, -1.0 - 12.0 * s.next_f32());
            let tri = [c, c + Vec3::new(size, 0.0, 0.0), c + Vec3::new(0.0, 0.02 * size, -size)];
            let (mut chosen, mut every) = (Vec::new(), Vec::new());
            triangle_glints(&tri, viewing, &g, t, (cone, cos_cone), &mut cells, &mut chosen);
            grains_in(&tri, (viewing, &g, t), cos_cone, &all, Cap::ALL, &mut every);
            assert_eq!(chosen, every, "triangle {t}: {tri:?}");
            found += every.len();
        }
        assert!(found > 1000, "{found} glints: too few to tell");
    }

    /// A 60 × 60 heightfield of 5 cm texels as triangles, its height at (i, j) given.
    fn field(height: impl Fn(f32, f32) -> f32) -> Vec<[Vec3; 3]> {
        let at = |i: usize, j: usize| {
            let (x, z) = (i as f32 * 0.05 - 1.5, j as f32 * 0.05 - 1.5);
            Vec3::new(x, height(x, z), z)
        };
        let mut tris = Vec::new();
        for j in 0..60 {
            for i in 0..60 {
                let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
                tris.extend([[a, b, c], [a, c, d]]);
            }
        }
        tris
    }

    #[test]
    fn kept_grains_glint_as_drawn_ones() {
        // Snow deepening by 5 mm a frame (the village's rate) with a mound growing on it
        // (faces that tilt, grow and cross tenths of a metre: their keys and H change),
        // seen from 4 m with the sun low ahead; then the sun moved (the cache starts
        // again). Every frame's glints are exactly those drawn afresh, and both kept and
        // new faces served.
        let g = Glitter { grains_per_m2: 4.0e6, ..Glitter::default() };
        let eye = Vec3::new(0.0, 1.6, 4.0);
        let mut cache = GlintCache::default();
        // Faces served by kept grains and drawn anew, in each sun's frames.
        let (mut hits, mut misses, mut found) = ([0; 2], [0; 2], 0);
        for (phase, (sun_deg, frames)) in [(20.0f32, 0..40), (25.0, 40..50)].into_iter().enumerate() {
            let sun = Vec3::new(0.0, sun_deg.to_radians().sin(), -sun_deg.to_radians().cos());
            let viewing = Viewing { eye, sun };
            for f in frames {
                let depth = 0.005 * f as f32;
                let mound = 0.01 * f as f32;
                let tris =
                    field(|x, z| depth + mound * (-(x * x + z * z) / 0.3).exp() + 0.02 * (7.0 * x).sin());
                let fresh = glints(&tris, viewing, &g, 5);
                assert_eq!(cache.glints(&tris, viewing, &g, 5), fresh, "frame {f}");
                let (h, m) = cache.last_call();
                (hits[phase], misses[phase], found) =
                    (hits[phase] + h, misses[phase] + m, found + fresh.len());
            }
        }
        assert!(found > 5_000, "{found} glints: too few to tell");
        // (At 4 m the faces' H turns past the room every few frames: more are drawn anew
        // than in a scene seen from tens of metres.)
        for phase in 0..2 {
            let (h, m) = (hits[phase], misses[phase]);
            assert!(h > m && m > 1_000, "sun {phase}: {h} faces served by kept grains, {m} drawn anew");
        }
        assert!(cache.compactions > 0, "the lists were never compacted");
    }

    #[test]
    fn kept_grains_follow_faces_that_grow() {
        // Faces of 1 cm growing in place by 3 % of their area a call (the same keys; H and the cone's
        // turn over the face change by less than the room): served by kept grains until
        // they have grown past the room, then drawn anew.
        let g = Glitter { grains_per_m2: 1.0e8, ..Glitter::default() };
        let viewing = Viewing { eye: Vec3::new(0.0, 1.6, 4.0), sun: Vec3::new(0.0, 0.34, -0.94).normalize() };
        let base: Vec<[Vec3; 3]> = (0..4000)
            .map(|k| {
                let c = Vec3::new((k % 80) as f32 * 0.0137 - 0.55, 0.0, (k / 80) as f32 * 0.0137 - 0.35);
                [
                    c + Vec3::new(-0.005, 0.0, -0.003),
                    c + Vec3::new(0.0, 0.0, 0.006),
                    c + Vec3::new(0.005, 0.0, -0.003),
                ]
            })
            .collect();
        let mut cache = GlintCache::default();
        let (mut hits, mut misses, mut found) = (0, 0, 0);
        for step in 0..10 {
            let s = 1.015f32.powi(step);
            let tris: Vec<[Vec3; 3]> = base
                .iter()
                .map(|t| {
                    let c = (t[0] + t[1] + t[2]) / 3.0;
                    t.map(|p| c + (p - c) * s)
                })
                .collect();
            let fresh = glints(&tris, viewing, &g, 9);
            assert_eq!(cache.glints(&tris, viewing, &g, 9), fresh, "step {step}");
            let (h, m) = cache.last_call();
            (hits, misses, found) = (hits + h, misses + m, found + fresh.len());
        }
        assert!(
            found > 2_000 && hits > 1_000 && misses > 1_000,
            "{found} glints, {hits} faces served by kept grains, {misses} drawn anew"
        );
    }

    #[test]
    fn the_cells_near_an_axis_hold_every_normal_within_the_angle() {
        // Normals drawn near many axes: each lies in a listed cell.
        let mut s = Stream::new(1, Purpose::named("test"), 0);
        for _ in 0..2000 {
            let axis = s.on_unit_sphere();
            let alpha = 0.2 * s.next_f32();
            let mut cells = Vec::new();
            cells_near(axis, alpha, &mut cells);
            for _ in 0..20 {
                let n = s.on_unit_sphere();
                if n.dot(axis) < alpha.cos() {
                    continue;
                }
                let band = (((n.z + 1.0) / (2.0 / Z_BANDS as f32)).floor() as usize).min(Z_BANDS - 1);
                let sector = ((n.y.atan2(n.x).rem_euclid(std::f32::consts::TAU))
                    / (std::f32::consts::TAU / SECTORS as f32))
                    .floor() as usize
                    % SECTORS;
                assert!(cells.contains(&(band * SECTORS + sector)), "axis {axis:?} α {alpha}: {n:?} missed");
            }
            assert!(cells.len() < CELLS / 4 || alpha > 0.1, "{} cells for α {alpha}", cells.len());
        }
    }
}
