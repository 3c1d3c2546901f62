//! The SPH gas of the flame paper §4: particles with mass, velocity, position and
//! temperature (§4.1), advanced by the per-frame loop of §4.3.

use glam::Vec3;
use phenomena_core::grid::{GridError, NeighborGrid};
use phenomena_core::kernel::{Dim, Kernel, KernelKind};
use phenomena_core::lanes::{LANES, in_run, load};
use phenomena_core::rng::{Purpose, Stream};
use phenomena_core::validate::InvalidConfig;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wide::f32x8;

use crate::air::{Air, AirState};
use crate::config::{FlameConfig, Mode};

const EMIT: Purpose = Purpose::named("flame.emit");
/// Particles per parallel work item: large enough to amortise scheduling, fixed so the
/// split never depends on the thread count (each particle's sum is independent anyway).
const CHUNK: usize = 512;
/// Most neighbours a particle may have (within the support radius, itself included).
/// A flame has a few dozen; thousands mean particles piled on each other, which would
/// make the step quadratic in their number.
pub const MAX_NEIGHBORS: usize = 2048;
/// Grid cells per support radius. Cells of d/2 searched two rings deep test 42 % fewer
/// candidates (15.6 d³ of volume instead of 27 d³), but a dispersing flame fills few of
/// the 8× more cells and the grid's per-cell work then dominates: cells of d measured
/// faster (6.9 vs 8.6 ms per step at 10,000 particles on 2 cores). Cutting each row of
/// cells to the support sphere's chord (cells of d/4 along x: 14.5 d³ of candidates in
/// the same nine runs) measured slower too, 2026-12-03: the chord's arithmetic per row
/// cost more than the eight-wide scan of the candidates it saved (7.2 against 6.0 s for
/// 300 steps at 30,000 particles on one thread, `examples/flame_cycles`, warm-up included).
const GRID_RINGS: usize = 1;
/// Candidate runs per particle: one per row of cells, (2 rings + 1)² of them.
const RUNS: usize = (2 * GRID_RINGS + 1) * (2 * GRID_RINGS + 1);

/// Why a simulation could not be created or stepped.
#[derive(Debug, thiserror::Error)]
pub enum FlameError {
    /// The configuration is invalid; every problem is listed.
    #[error(transparent)]
    Invalid(#[from] InvalidConfig),
    /// The neighbour grid could not be built (e.g. a particle became non-finite).
    #[error("neighbour search failed")]
    Grid(#[from] GridError),
    /// A particle has more neighbours than the SPH step can afford.
    #[error(
        "a particle has more than {limit} neighbours within the support radius: the gas is too dense \
         (emit fewer particles per frame, widen the burner, or use a smaller support radius)"
    )]
    TooDense {
        /// The neighbour limit.
        limit: usize,
    },
    /// Supplied particle arrays have different lengths.
    #[error("particle arrays differ in length: {0}")]
    Shape(String),
}

/// Particle state, structure-of-arrays (one `Vec` per attribute, index = particle).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Particles {
    /// Identity, unique over a simulation's life (the emission order).
    pub id: Vec<u64>,
    /// Position x, metres.
    pub position_m: Vec<Vec3>,
    /// Velocity u, m/s.
    pub velocity_m_s: Vec<Vec3>,
    /// Mass m, kg.
    pub mass_kg: Vec<f32>,
    /// Current temperature T, kelvin.
    pub temperature_k: Vec<f32>,
    /// Temperature at birth, kelvin.
    pub birth_temperature_k: Vec<f32>,
    /// Age, seconds.
    pub age_s: Vec<f32>,
    /// Age at which the particle is removed, seconds.
    pub lifetime_s: Vec<f32>,
    /// SPH density ρ of eq (3) from the last step, kg/m³.
    pub density_kg_m3: Vec<f32>,
    /// Pressure p of eq (11) from the last step, Pa.
    pub pressure_pa: Vec<f32>,
    /// Acceleration a of eq (8) from the last step, m/s².
    pub acceleration_m_s2: Vec<Vec3>,
}

impl Particles {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.position_m.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.position_m.is_empty()
    }

    fn check_shape(&self) -> Result<(), FlameError> {
        let n = self.len();
        let lens = [
            self.id.len(),
            self.velocity_m_s.len(),
            self.mass_kg.len(),
            self.temperature_k.len(),
            self.birth_temperature_k.len(),
            self.age_s.len(),
            self.lifetime_s.len(),
            self.density_kg_m3.len(),
            self.pressure_pa.len(),
            self.acceleration_m_s2.len(),
        ];
        if lens.iter().all(|&l| l == n) {
            Ok(())
        } else {
            Err(FlameError::Shape(format!("{n} positions but attribute lengths {lens:?}")))
        }
    }

    /// Keep particle i where `keep[i]`, preserving order.
    fn retain(&mut self, keep: &[bool]) {
        fn f<T: Copy>(v: &mut Vec<T>, keep: &[bool]) {
            let mut k = 0;
            for i in 0..v.len() {
                if keep[i] {
                    v[k] = v[i];
                    k += 1;
                }
            }
            v.truncate(k);
        }
        f(&mut self.id, keep);
        f(&mut self.position_m, keep);
        f(&mut self.velocity_m_s, keep);
        f(&mut self.mass_kg, keep);
        f(&mut self.temperature_k, keep);
        f(&mut self.birth_temperature_k, keep);
        f(&mut self.age_s, keep);
        f(&mut self.lifetime_s, keep);
        f(&mut self.density_kg_m3, keep);
        f(&mut self.pressure_pa, keep);
        f(&mut self.acceleration_m_s2, keep);
    }

    /// Reorder every attribute into the grid's cell order.
    fn gather(&mut self, grid: &NeighborGrid, s: &mut Scratch) {
        fn g<T: Copy>(v: &mut Vec<T>, grid: &NeighborGrid, tmp: &mut Vec<T>) {
            grid.gather(v, tmp);
            std::mem::swap(v, tmp);
        }
        g(&mut self.id, grid, &mut s.u64);
        g(&mut self.position_m, grid, &mut s.vec3);
        g(&mut self.velocity_m_s, grid, &mut s.vec3);
        g(&mut self.acceleration_m_s2, grid, &mut s.vec3);
        g(&mut self.mass_kg, grid, &mut s.f32);
        g(&mut self.temperature_k, grid, &mut s.f32);
        g(&mut self.birth_temperature_k, grid, &mut s.f32);
        g(&mut self.age_s, grid, &mut s.f32);
        g(&mut self.lifetime_s, grid, &mut s.f32);
        g(&mut self.density_kg_m3, grid, &mut s.f32);
        g(&mut self.pressure_pa, grid, &mut s.f32);
    }
}

#[derive(Clone, Debug, Default)]
struct Scratch {
    u64: Vec<u64>,
    vec3: Vec<Vec3>,
    f32: Vec<f32>,
    keep: Vec<bool>,
    /// Positions x, y, z and masses in separate arrays, each padded by [`LANES`] zeros.
    lanes: [Vec<f32>; 4],
    /// Neighbour lists per chunk of [`CHUNK`] particles (the pairs of §4.3 step 2).
    neighbors: Vec<NeighborChunk>,
}

/// Neighbour lists of one chunk of particles in compressed-row form: the neighbours of
/// the chunk's particle `o` (itself included) are `index[start[o]..start[o + 1]]`.
#[derive(Clone, Debug, Default)]
struct NeighborChunk {
    start: Vec<u32>,
    index: Vec<u32>,
}

/// What happened during one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StepStats {
    /// Particles alive after the frame.
    pub particles: usize,
    /// Particles added at the burner.
    pub emitted: usize,
    /// Particles removed because they reached their lifetime.
    pub expired: usize,
    /// Particles removed because they left the domain (or became non-finite).
    pub left_domain: usize,
    /// Particles not emitted because `max_particles` was reached.
    pub capped: usize,
    /// Neighbour pairs within the support radius in the last substep (each pair counted
    /// from both sides, self-pairs included): the SPH work done.
    pub neighbor_pairs: usize,
}

/// A checkpoint: everything needed to continue a simulation bit-identically.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FlameState {
    /// Frames completed.
    pub frame: u64,
    /// Id of the next particle to be born.
    pub next_id: u64,
    /// The particles.
    pub particles: Particles,
    /// The air around the flame, when it is solved (extended mode).
    #[serde(default)]
    pub air: Option<AirState>,
}

/// The flame simulation, created from a configuration and a seed and advanced by
/// [`FlameSim::step`], one frame at a time.
///
/// ```
/// use phenomena_flame::{FlameConfig, FlameSim};
/// let mut sim = FlameSim::new(FlameConfig::default(), 7).unwrap();
/// for _ in 0..30 {
///     sim.step().unwrap();
/// }
/// let p = sim.particles();
/// assert!(p.len() > 1000);
/// // The gas rises from the burner.
/// let mean_y = p.position_m.iter().map(|x| x.y).sum::<f32>() / p.len() as f32;
/// assert!(mean_y > 0.05);
/// ```
#[derive(Clone, Debug)]
pub struct FlameSim {
    config: FlameConfig,
    seed: u64,
    frame: u64,
    next_id: u64,
    particles: Particles,
    grid: NeighborGrid,
    density_kernel: Kernel,
    pressure_kernel: Kernel,
    scratch: Scratch,
    /// The air around the flame (extended mode with `extended.air.enabled`).
    air: Option<Air>,
}

impl FlameSim {
    /// A simulation with no particles yet; the burner adds them from the first step.
    pub fn new(config: FlameConfig, seed: u64) -> Result<Self, FlameError> {
        config.validate().map_err(InvalidConfig::from)?;
        let d = config.sph.support_radius_m;
        let x = &config.extended;
        let air = (config.mode == Mode::Extended && x.air.enabled)
            .then(|| Air::new(&x.air, &config.emitter, x.ambient_temperature_k));
        Ok(Self {
            air,
            density_kernel: Kernel::new(KernelKind::Poly6, Dim::Three, d),
            pressure_kernel: Kernel::new(config.sph.pressure_kernel, Dim::Three, d),
            config,
            seed,
            frame: 0,
            next_id: 0,
            particles: Particles::default(),
            grid: NeighborGrid::default(),
            scratch: Scratch::default(),
        })
    }

    /// Continue from a checkpoint taken with [`FlameSim::state`].
    pub fn from_state(config: FlameConfig, seed: u64, state: FlameState) -> Result<Self, FlameError> {
        let mut sim = Self::new(config, seed)?;
        sim.restore(state)?;
        Ok(sim)
    }

    /// Continue from a checkpoint taken with [`FlameSim::state`] of a simulation with
    /// the same configuration and seed. Refused, leaving `self` as it was, when the
    /// arrays differ in length or a position or velocity is not finite.
    pub fn restore(&mut self, state: FlameState) -> Result<(), FlameError> {
        let p = &state.particles;
        p.check_shape()?;
        if let Some(i) =
            (0..p.len()).find(|&i| !p.position_m[i].is_finite() || !p.velocity_m_s[i].is_finite())
        {
            return Err(FlameError::Shape(format!(
                "particle {i} has a position or velocity that is not finite"
            )));
        }
        match (&mut self.air, &state.air) {
            (Some(air), Some(a)) => air.restore(a).map_err(FlameError::Shape)?,
            (None, None) => {}
            (Some(_), None) => {
                return Err(FlameError::Shape("the checkpoint has no air, the simulation does".into()));
            }
            (None, Some(_)) => {
                return Err(FlameError::Shape("the checkpoint has air, the simulation none".into()));
            }
        }
        self.frame = state.frame;
        self.next_id = state.next_id;
        self.particles = state.particles;
        Ok(())
    }

    /// Place particles directly (no emission history): positions and velocities, with
    /// the configured particle mass and birth temperature, age 0 and unbounded lifetime.
    /// For tests and for seeding a simulation with a shape.
    pub fn with_particles(
        config: FlameConfig,
        seed: u64,
        positions_m: Vec<Vec3>,
        velocities_m_s: Vec<Vec3>,
    ) -> Result<Self, FlameError> {
        let n = positions_m.len();
        if velocities_m_s.len() != n {
            return Err(FlameError::Shape(format!("{n} positions, {} velocities", velocities_m_s.len())));
        }
        let m = config.sph.particle_mass_kg;
        let t = config.emitter.temperature_k;
        let particles = Particles {
            id: (0..n as u64).collect(),
            position_m: positions_m,
            velocity_m_s: velocities_m_s,
            mass_kg: vec![m; n],
            temperature_k: vec![t; n],
            birth_temperature_k: vec![t; n],
            age_s: vec![0.0; n],
            lifetime_s: vec![f32::INFINITY; n],
            density_kg_m3: vec![0.0; n],
            pressure_pa: vec![0.0; n],
            acceleration_m_s2: vec![Vec3::ZERO; n],
        };
        let mut sim = Self::new(config, seed)?;
        let air = sim.air.as_ref().map(Air::state);
        sim.restore(FlameState { frame: 0, next_id: n as u64, particles, air })?;
        Ok(sim)
    }

    /// A checkpoint of the current state.
    pub fn state(&self) -> FlameState {
        FlameState {
            frame: self.frame,
            next_id: self.next_id,
            particles: self.particles.clone(),
            air: self.air.as_ref().map(Air::state),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &FlameConfig {
        &self.config
    }

    /// Replace the wind from the next step on (the paper's §6 mouse drag: the drag
    /// vector becomes the wind force). Rejects a wind that
    /// [`FlameConfig::validate`](crate::FlameConfig::validate) would reject, naming it.
    pub fn set_wind(&mut self, wind: crate::config::Wind) -> Result<(), FlameError> {
        let mut config = self.config.clone();
        config.wind = wind;
        config.validate().map_err(InvalidConfig::from)?;
        self.config = config;
        Ok(())
    }

    /// Frames completed.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// Simulated time, seconds.
    pub fn time_s(&self) -> f64 {
        self.frame as f64 * f64::from(self.config.frame_time_s)
    }

    /// The particles (read-only).
    pub fn particles(&self) -> &Particles {
        &self.particles
    }

    /// The air around the flame, when it is solved.
    pub fn air(&self) -> Option<&Air> {
        self.air.as_ref()
    }

    /// Advance one frame by the loop of §4.3: (1) add particles at the burner, then per
    /// substep (2) neighbour search, (3) density (eq 3), (4) pressure (eq 11) and the
    /// symmetric pressure force (eq 12) plus the external force, (5) acceleration (eq 8)
    /// and semi-implicit Euler integration; finally remove expired particles and those
    /// outside the domain.
    pub fn step(&mut self) -> Result<StepStats, FlameError> {
        let mut stats = StepStats { emitted: 0, ..Default::default() };
        (stats.emitted, stats.capped) = self.emit();
        let h = self.config.frame_time_s / self.config.substeps as f32;
        for sub in 0..self.config.substeps {
            let t = self.time_s() as f32 + sub as f32 * h;
            self.evaluate_at(t)?;
            self.integrate(h, t);
            stats.neighbor_pairs = self.scratch.neighbors.iter().map(|c| c.index.len()).sum();
            // Remove after every substep, so the next neighbour search only sees
            // particles inside the (validated) domain.
            let (expired, outside) = self.remove_dead();
            stats.expired += expired;
            stats.left_domain += outside;
        }
        self.frame += 1;
        stats.particles = self.particles.len();
        Ok(stats)
    }

    /// Steps (2)-(4) of §4.3 for the current positions at time `time_s`: neighbour
    /// search (reordering particles by cell), density, pressure and acceleration. The
    /// results are in [`Particles`]; positions are not advanced.
    pub fn evaluate_at(&mut self, time_s: f32) -> Result<(), FlameError> {
        let d = self.config.sph.support_radius_m;
        self.grid.build(&self.particles.position_m, d / GRID_RINGS as f32)?;
        self.particles.gather(&self.grid, &mut self.scratch);
        self.grid.mark_points_sorted();
        self.compute_density_pressure()?;
        self.compute_accelerations(time_s);
        Ok(())
    }

    /// Step (1): add this frame's particles at the burner.
    fn emit(&mut self) -> (usize, usize) {
        let e = &self.config.emitter;
        let dt = f64::from(self.config.frame_time_s);
        let rate = f64::from(e.rate_per_s);
        // Particles due by the end of this frame minus those due by its start, so that
        // fractional rates average out exactly over time.
        let due = ((self.frame + 1) as f64 * dt * rate).floor() - (self.frame as f64 * dt * rate).floor();
        let due = due.max(0.0) as usize;
        let room = (self.config.max_particles as usize).saturating_sub(self.particles.len());
        let n = due.min(room);
        let extended = self.config.mode == Mode::Extended;
        let mut rng = Stream::new(self.seed, EMIT, self.frame);
        let p = &mut self.particles;
        for _ in 0..n {
            let (u, v) = rng.in_unit_disk();
            p.id.push(self.next_id);
            self.next_id += 1;
            p.position_m.push(e.position_m + Vec3::new(u * e.radius_m, 0.0, v * e.radius_m));
            let jitter = Vec3::new(rng.normal() as f32, rng.normal() as f32, rng.normal() as f32);
            p.velocity_m_s.push(e.velocity_m_s + jitter * e.velocity_jitter_m_s);
            let mut t = e.temperature_k;
            let tj = rng.normal() as f32;
            if extended {
                t = (t + tj * self.config.extended.temperature_jitter_k).max(1.0);
            }
            p.temperature_k.push(t);
            p.birth_temperature_k.push(t);
            p.mass_kg.push(self.config.sph.particle_mass_kg);
            p.age_s.push(0.0);
            p.lifetime_s.push(e.lifetime_s * (1.0 + e.lifetime_jitter * (2.0 * rng.next_f32() - 1.0)));
            p.density_kg_m3.push(0.0);
            p.pressure_pa.push(0.0);
            p.acceleration_m_s2.push(Vec3::ZERO);
        }
        (n, due - n)
    }

    /// Steps (2)-(3): find and store every pair closer than d (§4.3: "the combinations
    /// of particles are remembered"), and with them ρ_i = Σ_j m_j W_poly6(|x_i - x_j|)
    /// (eq 2, 3) and p_i = k(ρ_i - ρ0) (eq 11).
    fn compute_density_pressure(&mut self) -> Result<(), FlameError> {
        let d = self.config.sph.support_radius_m;
        let d2 = d * d;
        let clamp = self.config.mode == Mode::Extended && self.config.extended.clamp_negative_pressure;
        let n = self.particles.len();
        let chunks = n.div_ceil(CHUNK);
        self.scratch.neighbors.resize_with(chunks, NeighborChunk::default);
        self.fill_lanes();
        let [xs, ys, zs, ms] = &self.scratch.lanes;
        let too_dense = std::sync::atomic::AtomicBool::new(false);
        let pass = DensityPass {
            xs,
            ys,
            zs,
            ms,
            pos: &self.particles.position_m,
            grid: &self.grid,
            d2: f32x8::splat(d2),
            inv_d2: f32x8::splat(1.0 / d2),
            scale: self.density_kernel.value_sq(0.0),
            gas_constant_m2_s2: self.config.sph.gas_constant_m2_s2,
            rest_density_kg_m3: self.config.sph.rest_density_kg_m3,
            clamp,
            too_dense: &too_dense,
        };
        self.particles
            .density_kg_m3
            .par_chunks_mut(CHUNK)
            .zip(self.particles.pressure_pa.par_chunks_mut(CHUNK))
            .zip(self.scratch.neighbors.par_iter_mut())
            .enumerate()
            .for_each(|(c, ((rho, p), nb))| pass.chunk(c, rho, p, nb));
        if too_dense.load(std::sync::atomic::Ordering::Relaxed) {
            return Err(FlameError::TooDense { limit: MAX_NEIGHBORS });
        }
        Ok(())
    }

    /// The particles' coordinates and masses as separate arrays, padded by one vector,
    /// so that eight candidates load as three coordinate vectors and one of masses.
    fn fill_lanes(&mut self) {
        let p = &self.particles;
        for (a, v) in self.scratch.lanes.iter_mut().enumerate() {
            v.clear();
            if a < 3 {
                v.extend(p.position_m.iter().map(|x| x[a]));
            } else {
                v.extend_from_slice(&p.mass_kg);
            }
            v.extend([0.0; LANES]);
        }
    }

    /// Step (4)-(5a): the symmetrised pressure force of eq (12),
    /// f_i = -Σ_j m_j (p_i + p_j) / (2ρ_j) ∇W(x_i - x_j), plus the wind force density,
    /// divided by ρ_i (eq 8); in extended mode plus buoyancy.
    fn compute_accelerations(&mut self, time_s: f32) {
        let wind = self.config.wind.force_at(time_s);
        let (buoyancy, ambient) = match self.config.mode {
            Mode::Paper => (0.0, 0.0),
            // The air is buoyant and carries the particles.
            Mode::Extended if self.air.is_some() => (0.0, 0.0),
            Mode::Extended => {
                (self.config.extended.buoyancy_m_s2_per_k, self.config.extended.ambient_temperature_k)
            }
        };
        let kernel = self.pressure_kernel;
        let p = &self.particles;
        let (pos, mass, rho, pres, temp) =
            (&p.position_m, &p.mass_kg, &p.density_kg_m3, &p.pressure_pa, &p.temperature_k);
        let mut acc = std::mem::take(&mut self.scratch.vec3);
        acc.clear();
        acc.resize(pos.len(), Vec3::ZERO);
        acc.par_chunks_mut(CHUNK).zip(self.scratch.neighbors.par_iter()).enumerate().for_each(
            |(c, (out, nb))| {
                for (o, a) in out.iter_mut().enumerate() {
                    let i = c * CHUNK + o;
                    let xi = pos[i];
                    let pi = pres[i];
                    let mut f = Vec3::ZERO;
                    for &j in &nb.index[nb.start[o] as usize..nb.start[o + 1] as usize] {
                        let j = j as usize;
                        if j != i {
                            let r = xi - pos[j];
                            let g = kernel.gradient_factor(r.length());
                            f -= r * (mass[j] * (pi + pres[j]) / (2.0 * rho[j]) * g);
                        }
                    }
                    *a = (f + wind) / rho[i] + Vec3::Y * (buoyancy * (temp[i] - ambient));
                }
            },
        );
        let old = std::mem::replace(&mut self.particles.acceleration_m_s2, acc);
        self.scratch.vec3 = old;
    }

    /// Step (5b): v += a·h, x += v·h (semi-implicit Euler); age and, in extended mode,
    /// Newtonian cooling T = T_amb + (T_0 - T_amb)·exp(-age/τ). With the air, the
    /// velocity is dragged towards the air's between the two, and the air is advanced.
    fn integrate(&mut self, h: f32, time_s: f32) {
        if let Some(air) = &mut self.air {
            let p = &mut self.particles;
            for (v, a) in p.velocity_m_s.iter_mut().zip(&p.acceleration_m_s2) {
                *v += *a * h;
            }
            air.drag(h, &p.position_m, &mut p.velocity_m_s);
            air.step(h, self.config.wind.force_at(time_s));
        }
        // With the air, the velocity has already taken its step.
        let kick = if self.air.is_some() { 0.0 } else { h };
        let p = &mut self.particles;
        let cooling = match self.config.mode {
            Mode::Extended => {
                Some((self.config.extended.ambient_temperature_k, self.config.extended.cooling_time_s))
            }
            Mode::Paper => None,
        };
        p.position_m
            .par_chunks_mut(CHUNK)
            .zip(p.velocity_m_s.par_chunks_mut(CHUNK))
            .zip(p.acceleration_m_s2.par_chunks(CHUNK))
            .zip(p.age_s.par_chunks_mut(CHUNK))
            .zip(p.temperature_k.par_chunks_mut(CHUNK))
            .zip(p.birth_temperature_k.par_chunks(CHUNK))
            .for_each(|(((((x, v), a), age), temp), birth)| {
                for i in 0..x.len() {
                    v[i] += a[i] * kick;
                    x[i] += v[i] * h;
                    age[i] += h;
                    if let Some((ambient, tau)) = cooling {
                        temp[i] = ambient + (birth[i] - ambient) * (-age[i] / tau).exp();
                    }
                }
            });
        // With the air, a particle is no hotter than the air around it: where the
        // flame's gas has mixed with entrained air, it dims. And it cannot enter the
        // air's obstacles.
        if let Some(air) = &self.air {
            let p = &mut self.particles;
            air.collide(h, &mut p.position_m, &mut p.velocity_m_s);
            p.temperature_k.par_chunks_mut(CHUNK).zip(p.position_m.par_chunks(CHUNK)).for_each(
                |(temp, x)| {
                    for (t, x) in temp.iter_mut().zip(x) {
                        *t = t.min(air.temperature_at(*x));
                    }
                },
            );
        }
    }

    /// Remove particles past their lifetime or outside the domain. The paper does not
    /// say how particles leave; a finite lifetime stands for the fuel burning out.
    fn remove_dead(&mut self) -> (usize, usize) {
        let (lo, hi) = (self.config.domain.min_m, self.config.domain.max_m);
        let p = &self.particles;
        let keep = &mut self.scratch.keep;
        keep.clear();
        let (mut expired, mut outside) = (0, 0);
        for i in 0..p.len() {
            let x = p.position_m[i];
            let inside = x.is_finite() && x.cmpge(lo).all() && x.cmple(hi).all();
            let alive = p.age_s[i] < p.lifetime_s[i];
            if !alive {
                expired += 1;
            } else if !inside {
                outside += 1;
            }
            keep.push(alive && inside);
        }
        if expired + outside > 0 {
            let keep = std::mem::take(&mut self.scratch.keep);
            self.particles.retain(&keep);
            self.scratch.keep = keep;
        }
        (expired, outside)
    }
}

/// One density pass (steps (2)-(3)): the particles as lanes, the grid, the poly6 kernel
/// and the equation of state.
struct DensityPass<'a> {
    /// Coordinates and masses, padded by one vector ([`FlameSim::fill_lanes`]).
    xs: &'a [f32],
    ys: &'a [f32],
    zs: &'a [f32],
    ms: &'a [f32],
    pos: &'a [Vec3],
    grid: &'a NeighborGrid,
    /// d² and 1/d² in every lane, m² and m⁻².
    d2: f32x8,
    inv_d2: f32x8,
    /// σ/d³: W_poly6 at r = 0.
    scale: f32,
    /// k and ρ0 of eq (11).
    gas_constant_m2_s2: f32,
    rest_density_kg_m3: f32,
    /// Negative pressures clamped to 0 (extended mode).
    clamp: bool,
    /// Set when a particle has more than [`MAX_NEIGHBORS`] neighbours.
    too_dense: &'a std::sync::atomic::AtomicBool,
}

impl DensityPass<'_> {
    /// ρ_i and p_i (eq 2, 3, 11) of chunk `c`'s particles into `rho` and `p`, and their
    /// neighbour lists into `nb`.
    #[inline]
    fn chunk(&self, c: usize, rho: &mut [f32], p: &mut [f32], nb: &mut NeighborChunk) {
        nb.start.clear();
        nb.index.clear();
        // Each particle's cell (the particles are in cell order, `evaluate_at`).
        let cells = self.grid.point_cells();
        let (mut runs, mut count, mut run_cell) = ([(0usize, 0usize); RUNS], 0, u32::MAX);
        for o in 0..rho.len() {
            nb.start.push(nb.index.len() as u32);
            let i = c * CHUNK + o;
            let xi = self.pos[i];
            // The runs are collected first so that the sums stay in registers
            // (accumulated inside the callback they lived on the stack: 30 % slower).
            // They depend only on the particle's cell, so consecutive particles of one
            // cell share them.
            if cells[i] != run_cell {
                run_cell = cells[i];
                count = 0;
                self.grid.for_each_candidate_run(xi, GRID_RINGS, |run| {
                    runs[count] = (run.start, run.end);
                    count += 1;
                });
            }
            let sum = self.density_at(xi, &runs[..count], nb);
            rho[o] = sum;
            let pi = self.gas_constant_m2_s2 * (sum - self.rest_density_kg_m3);
            p[o] = if self.clamp { pi.max(0.0) } else { pi };
        }
        nb.start.push(nb.index.len() as u32);
    }

    /// ρ at `xi` (eq 2, 3), kg/m³, from the candidates in `runs` (ranges of particle
    /// indices), appending those inside the support to `nb`'s list. Particles are in
    /// cell order, so each run of cells is a contiguous range of particle indices, scanned
    /// eight at a time. W is exactly 0 outside the support, so only the lanes past the
    /// run's end are masked.
    #[inline(always)]
    fn density_at(&self, xi: Vec3, runs: &[(usize, usize)], nb: &mut NeighborChunk) -> f32 {
        let (xs, ys, zs, ms) = (self.xs, self.ys, self.zs, self.ms);
        let own = nb.index.len();
        let (qx, qy, qz) = (f32x8::splat(xi.x), f32x8::splat(xi.y), f32x8::splat(xi.z));
        let one = f32x8::splat(1.0);
        let mut sum = f32x8::ZERO;
        'runs: for &(start, end) in runs {
            // Room for the run's candidates in the list, trimmed after it (no allocation,
            // which is a call that spills the vectors, inside the scan). The neighbour
            // limit is checked after every eight, so a pile-up stops early and a run never
            // needs more than the limit plus one vector of room.
            let mut kept = nb.index.len();
            nb.index.resize(kept + (end - start).min(MAX_NEIGHBORS + LANES), 0);
            let mut k = start;
            while k < end {
                let (dx, dy, dz) = (load(&xs[k..]) - qx, load(&ys[k..]) - qy, load(&zs[k..]) - qz);
                let r2 = dx * dx + dy * dy + dz * dz;
                let live = in_run(end - k);
                // Poly6, eq (2): σ/d³ (1 - r²/d²)³, clamped at 0 outside d.
                let t = (one - r2 * self.inv_d2).fast_max(f32x8::ZERO);
                sum += live.select(load(&ms[k..]) * (t * t * t), f32x8::ZERO);
                let mut inside = (live & r2.simd_lt(self.d2)).to_bitmask();
                while inside != 0 {
                    nb.index[kept] = (k + inside.trailing_zeros() as usize) as u32;
                    kept += 1;
                    inside &= inside - 1;
                }
                if kept - own > MAX_NEIGHBORS {
                    self.too_dense.store(true, std::sync::atomic::Ordering::Relaxed);
                    nb.index.truncate(kept);
                    break 'runs;
                }
                k += LANES;
            }
            nb.index.truncate(kept);
        }
        // The lanes summed in a fixed order (not the target's reduce_add, which differs
        // between SSE2 and AVX builds).
        self.scale * sum.to_array().iter().fold(0.0f32, |a, &b| a + b)
    }
}

impl phenomena_core::phenomenon::Simulation for FlameSim {
    type StepStats = StepStats;
    type Error = FlameError;

    fn step(&mut self) -> Result<StepStats, FlameError> {
        FlameSim::step(self)
    }

    fn frames_done(&self) -> u64 {
        self.frame()
    }

    type State = FlameState;

    fn state(&self) -> FlameState {
        FlameSim::state(self)
    }

    fn restore(&mut self, state: FlameState) -> Result<(), FlameError> {
        FlameSim::restore(self, state)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn emission_rate_is_exact_on_average() {
        let mut c = FlameConfig::default();
        c.emitter.rate_per_s = 1000.0 / 7.0;
        c.emitter.lifetime_s = 1e3;
        let mut sim = FlameSim::new(c, 1).unwrap();
        let mut total = 0;
        for _ in 0..420 {
            total += sim.step().unwrap().emitted;
        }
        // 420 frames at 60 fps = 7 s -> exactly 1000 particles due.
        assert_eq!(total, 1000);
    }

    #[test]
    fn set_wind_acts_from_the_next_step_and_rejects_bad_values() {
        use crate::config::Wind;
        let mean_x = |sim: &FlameSim| {
            let p = sim.particles();
            p.position_m.iter().map(|x| f64::from(x.x)).sum::<f64>() / p.len() as f64
        };
        let mut calm = FlameSim::new(FlameConfig::default(), 3).unwrap();
        let mut windy = FlameSim::new(FlameConfig::default(), 3).unwrap();
        for _ in 0..10 {
            calm.step().unwrap();
            windy.step().unwrap();
        }
        assert_eq!(mean_x(&calm), mean_x(&windy));
        let gust = Wind { force_n_m3: glam::Vec3::new(2.0, 0.0, 0.0), keys: Vec::new() };
        windy.set_wind(gust.clone()).unwrap();
        assert_eq!(windy.config().wind, gust);
        for _ in 0..20 {
            calm.step().unwrap();
            windy.step().unwrap();
        }
        assert!(mean_x(&windy) > mean_x(&calm) + 0.01, "{} vs {}", mean_x(&windy), mean_x(&calm));
        let bad = Wind { force_n_m3: glam::Vec3::new(f32::NAN, 0.0, 0.0), keys: Vec::new() };
        let e = windy.set_wind(bad).unwrap_err().to_string();
        assert!(e.contains("wind.force_n_m3"), "{e}");
        assert_eq!(windy.config().wind, gust, "a rejected wind leaves the old one");
    }

    #[test]
    fn the_cap_holds_and_is_counted() {
        let c = FlameConfig { max_particles: 100, ..Default::default() };
        let mut sim = FlameSim::new(c, 1).unwrap();
        let s = sim.step().unwrap();
        assert_eq!(s.particles, 50);
        let s = sim.step().unwrap();
        assert_eq!((s.particles, s.emitted, s.capped), (100, 50, 0));
        let s = sim.step().unwrap();
        assert_eq!((s.particles, s.emitted, s.capped), (100, 0, 50));
    }

    #[test]
    fn checkpoint_continues_bit_identically() {
        let mut a = FlameSim::new(FlameConfig::default(), 5).unwrap();
        for _ in 0..20 {
            a.step().unwrap();
        }
        let mut b = FlameSim::from_state(a.config().clone(), 5, a.state()).unwrap();
        for _ in 0..10 {
            a.step().unwrap();
            b.step().unwrap();
        }
        assert_eq!(a.state(), b.state());
    }

    #[test]
    fn the_eight_wide_density_pass_equals_a_direct_sum() {
        // A dense clump (runs far longer than eight lanes) inside a sparse cloud (runs of
        // one or two), against ρ_i = Σ_j m_j W(|x_i - x_j|) over every pair in f64 and
        // the neighbour lists against every pair closer than d.
        let config = FlameConfig::default();
        let d = config.sph.support_radius_m;
        let mut rng = Stream::new(4, Purpose::named("test"), 0);
        let mut u = || rng.next_f32() - 0.5;
        let mut x: Vec<Vec3> = (0..600).map(|_| Vec3::new(u(), u(), u()) * 0.03).collect();
        x.extend((0..900).map(|_| Vec3::new(u(), u() + 0.5, u()) * 0.4));
        let v = vec![Vec3::ZERO; x.len()];
        let mut sim = FlameSim::with_particles(config.clone(), 1, x, v).unwrap();
        sim.evaluate_at(0.0).unwrap();
        let kernel = Kernel::new(KernelKind::Poly6, Dim::Three, d);
        let p = sim.particles();
        let mut longest_run = 0;
        for i in 0..p.len() {
            let xi = p.position_m[i];
            let mut direct = 0.0f64;
            let mut near = Vec::new();
            for j in 0..p.len() {
                let r2 = (p.position_m[j] - xi).length_squared();
                direct += f64::from(p.mass_kg[j] * kernel.value_sq(r2));
                if r2 < d * d {
                    near.push(j as u32);
                }
            }
            // All terms are positive: f32 summation of n terms errs by at most about
            // n·ε of the sum (n ≤ a few hundred here, ε = 6e-8).
            let rho = f64::from(p.density_kg_m3[i]);
            assert!((rho - direct).abs() <= 3e-5 * direct, "particle {i}: {rho} vs {direct}");
            let nb = &sim.scratch.neighbors[i / CHUNK];
            let o = i % CHUNK;
            let mut list = nb.index[nb.start[o] as usize..nb.start[o + 1] as usize].to_vec();
            list.sort_unstable();
            assert_eq!(list, near, "particle {i}");
            sim.grid.for_each_candidate_run(xi, GRID_RINGS, |r| longest_run = longest_run.max(r.len()));
        }
        assert!(longest_run > 4 * LANES, "the clump makes long runs ({longest_run})");
    }

    #[test]
    fn a_pile_up_is_refused_quickly() {
        // 40,000 particles within one support radius: every particle has them all as
        // neighbours. The pass stops each particle after MAX_NEIGHBORS + 8 of them
        // instead of keeping all 40,000 (1.6e9 pairs, 6.4 GB of lists), and says why.
        let config = FlameConfig::default();
        let mut rng = Stream::new(2, Purpose::named("test"), 0);
        let x: Vec<Vec3> =
            (0..40_000).map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.01).collect();
        let v = vec![Vec3::ZERO; x.len()];
        let mut sim = FlameSim::with_particles(config, 1, x, v).unwrap();
        let e = sim.evaluate_at(0.0).unwrap_err();
        assert!(matches!(e, FlameError::TooDense { limit: MAX_NEIGHBORS }), "{e}");
        let nb: usize = sim.scratch.neighbors.iter().map(|c| c.index.len()).sum();
        assert!(nb <= 40_000 * (MAX_NEIGHBORS + LANES), "{nb} pairs kept");
    }

    #[test]
    fn invalid_config_is_refused() {
        let c = FlameConfig { substeps: 0, ..Default::default() };
        assert!(
            matches!(FlameSim::new(c, 0), Err(FlameError::Invalid(v)) if v.issues[0].field == "substeps")
        );
    }
}
