//! Charged-particle motion in the x-z plane (thesis §2.3): the Lorentz force from the
//! shape's electric field and the y-directed magnetic field (eq 2.10), a pseudo-Coulomb
//! repulsion computed as an SPH pressure force (eq 2.11-2.18), and the position and
//! velocity updates of eq (2.19)-(2.20) followed by a speed limit.

use crate::pairs::{CellRows, for_each_half_pair_run, for_each_half_pair_run2};
use glam::Vec2;
use phenomena_core::grid::GridError;
use phenomena_core::kernel::{Dim, Kernel, KernelKind};
use phenomena_core::lanes::{LANES, add, in_run, load};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wide::f32x8;

use crate::config::{CoulombKernels, MotionParams};
use crate::field::Grid;

/// Particles per parallel work item (fixed, so results do not depend on thread count).
const CHUNK: usize = 1024;
/// Neighbour cells per support radius. Cells of h/2 searched two rings out would test
/// fewer candidates (6.25 h² instead of 9 h² per particle), but in shorter runs that
/// fill fewer SIMD lanes; on the default scene the two measured alike, and one ring is
/// simpler.
const RINGS: usize = 1;
/// Most particles one neighbour cell (h wide) may hold; more means particles piled on
/// each other and a step quadratic in their number.
pub const MAX_PER_CELL: usize = 4096;

/// Why a motion step failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MotionError {
    /// The neighbour grid could not be built.
    #[error("neighbour search failed")]
    Grid(#[from] GridError),
    /// Too many particles in one neighbour cell.
    #[error(
        "particles are packed too densely: {count} in one cell of the neighbour grid, more than {MAX_PER_CELL}"
    )]
    TooDense {
        /// Particles in the fullest cell.
        count: usize,
    },
}

/// Charged particles, structure-of-arrays.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Particles {
    /// Identity, unique over a simulation's life.
    pub id: Vec<u64>,
    /// Position (x, z), km.
    pub position_km: Vec<Vec2>,
    /// Velocity (x, z), km/s.
    pub velocity_km_s: Vec<Vec2>,
}

impl Particles {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.id.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.id.is_empty()
    }

    /// Keep particle i where `keep[i]`, in order.
    pub fn retain(&mut self, keep: &[bool]) {
        let mut k = 0;
        for (i, &kept) in keep.iter().enumerate().take(self.len()) {
            if kept {
                self.id[k] = self.id[i];
                self.position_km[k] = self.position_km[i];
                self.velocity_km_s[k] = self.velocity_km_s[i];
                k += 1;
            }
        }
        self.id.truncate(k);
        self.position_km.truncate(k);
        self.velocity_km_s.truncate(k);
    }

    /// Append a particle.
    pub fn push(&mut self, id: u64, position_km: Vec2, velocity_km_s: Vec2) {
        self.id.push(id);
        self.position_km.push(position_km);
        self.velocity_km_s.push(velocity_km_s);
    }
}

/// The forces' constant factors, derived once from the parameters.
#[derive(Clone, Copy, Debug)]
pub struct ForceModel {
    /// Acceleration per unit of E, km/s² per ((q0/ε0)/km): q0²/(m ε0) × 1e-6.
    pub lorentz_e: f32,
    /// Gyro-frequency q0·B/m, rad/s.
    pub gyro_rad_s: f32,
    density: Kernel,
    gradient: Kernel,
    gas_constant: f32,
    weight_lorentz: f32,
    weight_coulomb: f32,
    max_speed: f32,
    damping: f32,
    dt: f32,
}

impl ForceModel {
    /// Derive the factors from the motion parameters.
    pub fn new(m: &MotionParams) -> Self {
        let (dk, gk) = match m.kernels {
            CoulombKernels::Poly6Spiky => (KernelKind::Poly6, KernelKind::Spiky),
            CoulombKernels::Spline => (KernelKind::CubicSpline, KernelKind::CubicSpline),
        };
        // E in units of (q0/ε0)/km -> V/m: × (q0/ε0)/1000; a = q0 E/m in m/s²; /1000 -> km/s².
        let lorentz_e = m.charge_c * m.charge_c / (m.particle_mass_kg * m.permittivity_f_m) * 1e-6;
        Self {
            lorentz_e: lorentz_e as f32,
            gyro_rad_s: (m.charge_c * m.magnetic_field_t / m.particle_mass_kg) as f32,
            density: Kernel::new(dk, Dim::Two, m.support_km),
            gradient: Kernel::new(gk, Dim::Two, m.support_km),
            gas_constant: m.gas_constant,
            weight_lorentz: m.weight_lorentz,
            weight_coulomb: m.weight_coulomb,
            max_speed: m.max_speed_km_s,
            damping: (-m.damping_per_s * m.time_step_s).exp(),
            dt: m.time_step_s,
        }
    }

    /// The kernel support radius, km.
    pub fn support_km(&self) -> f32 {
        self.density.support()
    }

    /// The Lorentz acceleration q0(E + v × B)/m (eq 2.10) with B along +y: in the x-z
    /// plane v × B = (-v_z B, v_x B).
    #[inline]
    pub fn lorentz(&self, e: Vec2, v: Vec2) -> Vec2 {
        e * self.lorentz_e + Vec2::new(-v.y, v.x) * self.gyro_rad_s
    }
}

/// Replace `v` by `values` followed by one group of zero lanes.
fn fill_padded(v: &mut Vec<f32>, values: impl IndexedParallelIterator<Item = f32>) {
    v.clear();
    v.par_extend(values.with_min_len(4096));
    v.extend([0.0; LANES]);
}

/// Sum of the lanes in a fixed order (not the target-dependent horizontal add).
#[inline]
fn reduce(v: f32x8) -> f32 {
    v.to_array().iter().sum()
}

/// Reusable buffers of the motion step.
#[derive(Clone, Debug, Default)]
pub struct MotionScratch {
    rows: CellRows,
    density: Vec<f32>,
    inv_2density: Vec<f32>,
    pressure: Vec<f32>,
    keep: Vec<bool>,
    tmp2: Vec<Vec2>,
    tmp_id: Vec<u64>,
    xs: Vec<f32>,
    zs: Vec<f32>,
    fx: Vec<f32>,
    fz: Vec<f32>,
}

impl MotionScratch {
    /// SPH density of each particle from the last step (particles per km², unit mass).
    pub fn density(&self) -> &[f32] {
        &self.density
    }

    /// The pseudo-Coulomb force per unit mass of each particle from the last step
    /// (x and z components), before the weight w_P.
    pub fn coulomb_force(&self) -> (&[f32], &[f32]) {
        (&self.fx, &self.fz)
    }
}

/// One motion step: sort particles by cell, SPH density δ (eq 2.11) and pressure
/// p = k(δ - δ0) (eq 2.13), the pseudo-Coulomb force (eq 2.14), the Lorentz force with E
/// interpolated bilinearly (eq 2.10), then eq (2.19)-(2.20) with the weights w_L, w_P,
/// and the velocity normalisation (damping, then the speed limit). Particles leaving the
/// plane are removed; returns how many.
///
/// Each close pair is visited once per pass ([`for_each_half_pair_run`]) and its terms are
/// added to both particles: the density term W is symmetric, and eq (2.14)'s pair term
/// differs between the two sides only by the factor 1/(2δ) of the other particle.
pub fn step(
    p: &mut Particles,
    model: &ForceModel,
    field_grid: &Grid,
    e_field: &[Vec2],
    rest_density: f32,
    s: &mut MotionScratch,
) -> Result<usize, MotionError> {
    coulomb(p, model, rest_density, s)?;
    let n = p.len();

    // Lorentz force, eq (2.19)-(2.20) with the weights w_L and w_P, then damping and the
    // speed limit; particles that leave the plane (or became non-finite) are marked.
    let (dt, vmax, damping) = (model.dt, model.max_speed, model.damping);
    let (fx, fz) = (&s.fx, &s.fz);
    let (lo, hi) = (field_grid.origin_km, field_grid.origin_km + field_grid.extent_km());
    s.keep.clear();
    s.keep.resize(n, true);
    p.position_km
        .par_chunks_mut(CHUNK)
        .zip(p.velocity_km_s.par_chunks_mut(CHUNK))
        .zip(s.keep.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(c, ((x, v), keep))| {
            for o in 0..x.len() {
                let i = c * CHUNK + o;
                let lorentz = model.lorentz(field_grid.interpolate(e_field, x[o]), v[o]);
                let a = lorentz * model.weight_lorentz + Vec2::new(fx[i], fz[i]) * model.weight_coulomb;
                x[o] += v[o] * dt + a * (0.5 * dt * dt);
                v[o] = (v[o] + a * dt) * damping;
                let speed = v[o].length();
                if speed > vmax {
                    v[o] *= vmax / speed;
                }
                keep[o] = x[o].is_finite() && x[o].cmpge(lo).all() && x[o].cmplt(hi).all();
            }
        });
    let keep = &s.keep;
    let removed = keep.iter().filter(|k| !**k).count();
    if removed > 0 {
        p.retain(keep);
    }
    Ok(removed)
}

/// Sort the particles into cell order (reordering `p`), then the SPH density δ
/// (eq 2.11) and the pseudo-Coulomb force per unit mass (eq 2.13-2.14), left in `s`
/// ([`MotionScratch::density`], [`MotionScratch::coulomb_force`]).
pub fn coulomb(
    p: &mut Particles,
    model: &ForceModel,
    rest_density: f32,
    s: &mut MotionScratch,
) -> Result<(), MotionError> {
    sort_into_cells(p, model, s)?;
    let pos = &p.position_km;
    // Coordinates as separate arrays, padded by one group of lanes so that the last group
    // of a run can be read whole (the lanes past the run are masked out).
    fill_padded(&mut s.xs, pos.par_iter().map(|x| x.x));
    fill_padded(&mut s.zs, pos.par_iter().map(|x| x.y));
    sph_density(s, model.density, p.len());
    // eq (2.13) p = k(δ - δ0), and 1/(2δ) once per particle rather than a division per pair.
    let (k, rho0) = (model.gas_constant, rest_density);
    fill_padded(&mut s.pressure, s.density.par_iter().map(|&d| k * (d - rho0)));
    fill_padded(&mut s.inv_2density, s.density.par_iter().map(|&d| 0.5 / d));
    pressure_force(s, model.gradient, p.len());
    Ok(())
}

/// Bin the particles into the cells of `s.rows` (of size h / RINGS) and reorder `p` into
/// cell order, so that runs of cells become contiguous index ranges; refuse a cell of
/// more than [`MAX_PER_CELL`] particles.
fn sort_into_cells(p: &mut Particles, model: &ForceModel, s: &mut MotionScratch) -> Result<(), MotionError> {
    let h = model.support_km();
    s.rows.build(&p.position_km, h / RINGS as f32)?;
    if s.rows.max_cell_count() > MAX_PER_CELL {
        return Err(MotionError::TooDense { count: s.rows.max_cell_count() });
    }
    s.rows.gather(&p.position_km, &mut s.tmp2);
    std::mem::swap(&mut p.position_km, &mut s.tmp2);
    s.rows.gather(&p.velocity_km_s, &mut s.tmp2);
    std::mem::swap(&mut p.velocity_km_s, &mut s.tmp2);
    s.rows.gather(&p.id, &mut s.tmp_id);
    std::mem::swap(&mut p.id, &mut s.tmp_id);
    Ok(())
}

/// eq (2.11): δ_i = Σ_j m_j W(x_j - x_i) with unit mass and kernel `kd`, the self term
/// included, for the `n` particles into `s.density` (each close pair visited once).
fn sph_density(s: &mut MotionScratch, kd: Kernel, n: usize) {
    let (xs, zs) = (&s.xs, &s.zs);
    s.density.clear();
    s.density.resize(n, kd.value(0.0));
    for_each_half_pair_run(&s.rows, RINGS, &mut s.density, |acc, base, i, runs| {
        let (xi, zi) = (f32x8::splat(xs[i]), f32x8::splat(zs[i]));
        let mut sum = f32x8::ZERO;
        for run in runs {
            // From the run's start to the window's end: the last group's lanes past
            // the run add +0.0 in one vector add (no density is −0.0: each starts at
            // W(0) ≥ 0 and adds terms ≥ 0, so +0.0 leaves its bits).
            let out = &mut acc[run.start - base..];
            for k in (0..run.len()).step_by(LANES) {
                let j = run.start + k;
                let (dx, dz) = (load(&xs[j..]) - xi, load(&zs[j..]) - zi);
                let w = in_run(run.len() - k).select(kd.value_sq_x8(dx * dx + dz * dz), f32x8::ZERO);
                add(&mut out[k..], w);
                sum += w;
            }
        }
        acc[i - base] += reduce(sum);
    });
}

/// eq (2.14): F_i = Σ_j m_j (p_i + p_j)/(2 δ_j) ∇W(x_i - x_j) for the `n` particles into
/// `s.fx` and `s.fz`, from the pressures and 1/(2δ) in `s`. With ∇W = g·(x_i - x_j)
/// (g from kernel `kg`) and g < 0, F_i = Σ_j (p_i + p_j) g /(2 δ_j) · (x_j - x_i) repels
/// for positive pressure, and the pair adds the mirror term with 1/(2 δ_i) to j.
fn pressure_force(s: &mut MotionScratch, kg: Kernel, n: usize) {
    let (xs, zs) = (&s.xs, &s.zs);
    let (inv2d, pres) = (&s.inv_2density, &s.pressure);
    s.fx.clear();
    s.fx.resize(n, 0.0);
    s.fz.clear();
    s.fz.resize(n, 0.0);
    for_each_half_pair_run2(&s.rows, RINGS, &mut s.fx, &mut s.fz, |acc_x, acc_z, base, i, runs| {
        let (xi, zi) = (f32x8::splat(xs[i]), f32x8::splat(zs[i]));
        let (pi, inv_i) = (f32x8::splat(pres[i]), f32x8::splat(inv2d[i]));
        let (mut fx, mut fz) = (f32x8::ZERO, f32x8::ZERO);
        for run in runs {
            for k in (0..run.len()).step_by(LANES) {
                let j = run.start + k;
                let (dx, dz) = (load(&xs[j..]) - xi, load(&zs[j..]) - zi);
                let g = kg.gradient_factor_sq_x8(dx * dx + dz * dz);
                let c = in_run(run.len() - k).select((pi + load(&pres[j..])) * g, f32x8::ZERO);
                let ci = c * load(&inv2d[j..]);
                fx += dx * ci;
                fz += dz * ci;
                let cj = c * inv_i;
                // To the window's end, as in `sph_density`: lanes past the run add ±0.0
                // (c is +0.0 there, every coordinate finite: `CellRows::build` refuses
                // others, and 1/(2δ_i) finite: δ_i ≥ W(0) > 0), which leaves every sum's
                // bits (a sum that starts at +0.0 is never −0.0).
                add(&mut acc_x[j - base..], -(dx * cj));
                add(&mut acc_z[j - base..], -(dz * cj));
            }
        }
        acc_x[i - base] += reduce(fx);
        acc_z[i - base] += reduce(fz);
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane() -> (Grid, Vec<Vec2>) {
        let g = Grid { nx: 16, nz: 16, origin_km: Vec2::ZERO, cell_km: 1.0 };
        (g, vec![Vec2::ZERO; 256])
    }

    /// Eq (2.11)-(2.14) as printed, every pair in both directions, with the scalar kernels.
    fn reference(pos: &[Vec2], model: &ForceModel, rest_density: f32) -> (Vec<f32>, Vec<Vec2>) {
        let density: Vec<f32> =
            pos.iter().map(|&xi| pos.iter().map(|&xj| model.density.value(xi.distance(xj))).sum()).collect();
        let pressure: Vec<f32> = density.iter().map(|&d| model.gas_constant * (d - rest_density)).collect();
        let force = (0..pos.len())
            .map(|i| {
                (0..pos.len())
                    .map(|j| {
                        let g = model.gradient.gradient_factor(pos[i].distance(pos[j]));
                        (pos[j] - pos[i]) * ((pressure[i] + pressure[j]) / (2.0 * density[j]) * g)
                    })
                    .sum()
            })
            .collect();
        (density, force)
    }

    #[test]
    fn the_pair_sweep_matches_the_equations_summed_over_all_pairs() {
        // A cloud with a dense core and a sparse halo (runs of every length, full and
        // partial SIMD groups, both stripe phases), and a strip two cells wide, where the
        // lanes read past the end of a run hold close particles of the next row.
        let mut rng =
            phenomena_core::rng::Stream::new(7, phenomena_core::rng::Purpose::named("test.motion"), 0);
        let mut cloud = Particles::default();
        let mut strip = Particles::default();
        for id in 0..1500 {
            let spread = if id % 3 == 0 { 3.0 } else { 0.8 };
            cloud.push(id, Vec2::new(rng.uniform(-spread, spread), rng.uniform(-spread, spread)), Vec2::ZERO);
            strip.push(id, Vec2::new(rng.uniform(0.0, 0.6), rng.uniform(-10.0, 10.0)), Vec2::ZERO);
        }
        for (mut p, kernels) in [
            (cloud.clone(), CoulombKernels::Poly6Spiky),
            (cloud, CoulombKernels::Spline),
            (strip.clone(), CoulombKernels::Poly6Spiky),
            (strip, CoulombKernels::Spline),
        ] {
            let model = ForceModel::new(&MotionParams { kernels, support_km: 0.35, ..Default::default() });
            let rest_density = 30.0;
            let mut s = MotionScratch::default();
            coulomb(&mut p, &model, rest_density, &mut s).unwrap();
            let (density, force) = reference(&p.position_km, &model, rest_density);
            let (fx, fz) = s.coulomb_force();
            // f32 sums of up to ~100 terms in a different order: rounding is a few 1e-7
            // of the largest value per term, so 1e-4 of it is a wide margin, yet a missing
            // or doubled pair anywhere but at the edge of the support (where W → 0) moves
            // a sum by more (as does reading one lane past a run in the strip).
            let dmax = density.iter().fold(0f32, |m, &d| m.max(d));
            let fmax = force.iter().fold(0f32, |m, f| m.max(f.length()));
            for i in 0..p.len() {
                assert!((s.density()[i] - density[i]).abs() <= 1e-4 * dmax, "{kernels:?} δ[{i}]");
                let f = Vec2::new(fx[i], fz[i]);
                assert!((f - force[i]).length() <= 1e-4 * fmax, "{kernels:?} F[{i}]: {f} vs {}", force[i]);
            }
        }
    }

    #[test]
    fn two_close_particles_repel() {
        for kernels in [CoulombKernels::Poly6Spiky, CoulombKernels::Spline] {
            let params = MotionParams { kernels, support_km: 1.0, ..Default::default() };
            let model = ForceModel::new(&params);
            let (g, e) = plane();
            let mut p = Particles::default();
            p.push(0, Vec2::new(8.0, 8.0), Vec2::ZERO);
            p.push(1, Vec2::new(8.3, 8.1), Vec2::ZERO);
            step(&mut p, &model, &g, &e, 0.0, &mut MotionScratch::default()).unwrap();
            let (a, b) = if p.id[0] == 0 { (0, 1) } else { (1, 0) };
            let apart = (p.position_km[b] - p.position_km[a]).length();
            assert!(apart > Vec2::new(0.3, 0.1).length(), "{kernels:?}: they moved apart ({apart})");
            // Newton's third law: equal and opposite velocities.
            assert!((p.velocity_km_s[a] + p.velocity_km_s[b]).length() < 1e-5);
        }
    }

    #[test]
    fn the_electric_force_pulls_along_e_and_b_turns_velocity() {
        let model = ForceModel::new(&MotionParams::default());
        assert!(model.lorentz(Vec2::X, Vec2::ZERO).x > 0.0);
        // v × B with B along +y: v = +x gives (x, z) = (-v_z, v_x)·ω = (0, ω).
        let turn = model.lorentz(Vec2::ZERO, Vec2::X);
        assert!(turn.y > 0.0);
        assert!((turn.y - 0.5).abs() < 1e-3, "default gyro-frequency 0.5 rad/s: {turn:?}");
        assert!(turn.x.abs() < 1e-6);
    }

    #[test]
    fn speed_is_limited() {
        let params = MotionParams { max_speed_km_s: 3.0, ..Default::default() };
        assert!(ForceModel::new(&params).lorentz_e * 1e3 * params.time_step_s > 3.0);
        let model = ForceModel::new(&params);
        let (g, _) = plane();
        let e = vec![Vec2::new(1e3, 0.0); 256]; // ~1000 km/s²: 33 km/s after one step
        let mut p = Particles::default();
        p.push(0, Vec2::new(2.0, 8.0), Vec2::ZERO);
        let mut s = MotionScratch::default();
        step(&mut p, &model, &g, &e, 0.0, &mut s).unwrap();
        assert!((p.velocity_km_s[0].length() - 3.0).abs() < 1e-5);
    }
}
