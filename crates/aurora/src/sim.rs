//! The aurora simulation of part 1: every K frames the intermediate target shape is
//! renewed (particles redistributed against the old shape, §2.3.4; a new field computed,
//! §2.2.3); every frame the particles move (§2.3).

use crate::noise::NoiseSampler;
use glam::Vec2;
use phenomena_core::clock::SharedClock;
use phenomena_core::rng::{Purpose, Stream};
use phenomena_core::validate::InvalidConfig;
use serde::{Deserialize, Serialize};

use crate::config::{AuroraConfig, FieldParams, RedistributionRule};
use crate::field::{
    Grid, Nearness, add_noise, count_per_cell, electric_field, sample_near_shape, solve_potential,
};
use crate::motion::{ForceModel, MotionError, MotionScratch, Particles, step};
use crate::shape::{Animation, Shape, ShapeError};

const REDISTRIBUTE: Purpose = Purpose::named("aurora.redistribute");
/// Stream numbers of the charge samples: the initial particles use stream 0, each
/// renewal r its own stream 1 + r.
const INITIAL_STREAM: u64 = 0;

/// Why an aurora simulation could not be created or stepped.
#[derive(Debug, thiserror::Error)]
pub enum AuroraError {
    /// Invalid parameters; every problem listed.
    #[error(transparent)]
    Invalid(#[from] InvalidConfig),
    /// The shapes could not be built.
    #[error("invalid aurora shapes: {0}")]
    Shape(#[from] ShapeError),
    /// A motion step failed.
    #[error("particle motion failed")]
    Motion(#[from] MotionError),
    /// A saved state does not fit this simulation.
    #[error("the saved state does not fit this simulation: {0}")]
    State(String),
}

/// The field of the current intermediate target shape.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FieldState {
    /// The intermediate target shape the field was made for.
    pub shape: Shape,
    /// Charges per cell, N(i, j).
    pub counts: Vec<u32>,
    /// Potential before noise, units of q0/ε0 (eq 2.6).
    pub potential: Vec<f64>,
    /// Potential with noise (what E comes from).
    pub potential_noisy: Vec<f64>,
    /// Electric field, (q0/ε0)/km, per cell (eq 2.8-2.9).
    pub e: Vec<Vec2>,
    /// The reference density δ0 of eq (2.13): the particles spread evenly over the
    /// cells near the shape, per km².
    pub rest_density: f32,
    /// Renewals so far (this field is number `renewal`).
    pub renewal: u64,
}

/// What, besides the shape, a field is built from.
#[derive(Clone, Copy, Debug)]
pub struct FieldInputs<'a> {
    /// The plane's grid.
    pub grid: &'a Grid,
    /// Field parameters.
    pub params: &'a FieldParams,
    /// The potential's noise.
    pub noise: &'a NoiseSampler,
    /// The simulation's seed.
    pub seed: u64,
    /// Renewal number (picks the charge samples' random stream).
    pub renewal: u64,
    /// Simulation time, seconds (the noise's time coordinate follows it).
    pub time_s: f64,
    /// Particles in the simulation (for the reference density δ0).
    pub particles: usize,
}

impl FieldState {
    /// One renewal's field (§2.2.3): sample charges near `shape`, count them per cell,
    /// solve the Poisson equation, add the noise, take E by central differences. Records
    /// the times of sampling and of the rest in `stats`, read from `clock`.
    pub fn build(shape: Shape, inputs: &FieldInputs<'_>, stats: &mut StepStats, clock: &SharedClock) -> Self {
        let (grid, f) = (inputs.grid, inputs.params);
        let t = clock.stopwatch();
        let stream = 1 + inputs.renewal;
        let charges =
            sample_near_shape(&shape, f.reach_km, f.charges as usize, f.sampler, inputs.seed, stream);
        let counts = count_per_cell(grid, &charges);
        stats.sampling_ms = t.ms();
        let t = clock.stopwatch();
        let source: Vec<f64> = counts.iter().map(|&n| f64::from(n)).collect();
        let (potential, _) = solve_potential(grid, &source, f.poisson);
        let mut noisy = potential.clone();
        add_noise(
            grid,
            &mut noisy,
            inputs.noise,
            inputs.time_s * f.noise_time_frequency_hz,
            f.noise.amplitude,
        );
        let e = electric_field(grid, &noisy);
        stats.poisson_ms = t.ms();
        let near_cells = counts.iter().filter(|&&n| n > 0).count().max(1);
        let cell_area = grid.cell_km * grid.cell_km;
        let rest_density = inputs.particles as f32 / (near_cells as f32 * cell_area);
        Self { shape, counts, potential, potential_noisy: noisy, e, rest_density, renewal: inputs.renewal }
    }
}

/// What one frame did, with timings of its parts (milliseconds, 0 unless the simulation
/// was given a clock by [`AuroraSim::set_clock`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StepStats {
    /// Particles after the frame.
    pub particles: usize,
    /// Whether the shape was renewed this frame.
    pub renewed: bool,
    /// Particles removed for leaving the plane.
    pub left_plane: usize,
    /// Particles removed by redistribution (not near the shape, or crowded cells).
    pub redistributed_removed: usize,
    /// Particles added by redistribution (sparse cells).
    pub redistributed_added: usize,
    /// Cells still over the upper threshold after redistribution (its per-cell removal
    /// cap was not enough).
    pub crowded_cells: usize,
    /// Particles in the fullest cell right after this frame's redistribution (0 when the
    /// frame did not redistribute): every particle left is in a near cell of the old
    /// shape, so this is the largest near-cell count the renewal left (Table 3.3's upper
    /// threshold bounds it under rule `"reach"`). A frame ends with its renewal, so
    /// `max_near_cell` of a renewal frame counts the same particles (over the new
    /// shape's near cells).
    pub redistributed_max_cell: u32,
    /// Time spent placing charges, ms.
    pub sampling_ms: f64,
    /// Time spent solving the Poisson equation, adding noise and differentiating, ms.
    pub poisson_ms: f64,
    /// Time spent redistributing, ms.
    pub redistribution_ms: f64,
    /// Time spent on forces and integration, ms.
    pub forces_ms: f64,
    /// Particles in the fullest near cell of the current field after the frame (cells
    /// near the intermediate target shape as §2.3.4 judges them; Table 3.3 deletes
    /// above 500 at each renewal).
    pub max_near_cell: u32,
    /// Share of the particles within L_thr of the current intermediate target shape
    /// after the frame.
    pub near_share: f64,
}

/// The aurora simulation (part 1): shapes, field, particles.
///
/// ```
/// use phenomena_aurora::{AuroraConfig, AuroraSim};
/// let mut config = AuroraConfig::default();
/// config.motion.particles = 2000;
/// config.field.charges = 5000;
/// let mut sim = AuroraSim::new(config, 1).unwrap();
/// for _ in 0..10 {
///     sim.step().unwrap();
/// }
/// assert!(sim.particles().len() > 1000);
/// ```
#[derive(Clone, Debug)]
pub struct AuroraSim {
    config: AuroraConfig,
    seed: u64,
    frame: u64,
    next_id: u64,
    animation: Animation,
    grid: Grid,
    model: ForceModel,
    noise: NoiseSampler,
    particles: Particles,
    field: FieldState,
    /// Derived from `field` at each renewal: the near cells of §2.3.4 and the L_thr test.
    near: Near,
    scratch: MotionScratch,
    clock: SharedClock,
}

/// What §2.3.4 judges near the current intermediate target shape, made with its field.
#[derive(Clone, Debug)]
struct Near {
    /// Per cell: near the shape (charge count and potential tests of Table 3.3).
    cells: Vec<bool>,
    /// Points within L_thr of the shape.
    within: Nearness,
}

impl Near {
    fn of(field: &FieldState, r: &crate::config::Redistribution, reach_km: f32) -> Self {
        Self { cells: near_cells(field, r), within: Nearness::new(&field.shape, reach_km) }
    }
}

/// The near cells of §2.3.4 with Table 3.3's thresholds: at least `near_count_ratio` ×
/// the mean charge count and at most `near_potential_ratio` × the mean potential (and
/// some charge).
fn near_cells(field: &FieldState, r: &crate::config::Redistribution) -> Vec<bool> {
    let cells = field.counts.len().max(1);
    let mean_n = field.counts.iter().map(|&n| f64::from(n)).sum::<f64>() / cells as f64;
    let mean_phi = field.potential.iter().sum::<f64>() / cells as f64;
    (0..field.counts.len())
        .map(|c| {
            f64::from(field.counts[c]) >= f64::from(r.near_count_ratio) * mean_n
                && field.potential[c] <= f64::from(r.near_potential_ratio) * mean_phi
                && field.counts[c] > 0
        })
        .collect()
}

impl AuroraSim {
    /// Build the shapes, place the particles near the source shape and compute its field.
    pub fn new(config: AuroraConfig, seed: u64) -> Result<Self, AuroraError> {
        config.validate().map_err(InvalidConfig::from)?;
        let animation = config.animation()?;
        let grid = config.grid();
        let model = ForceModel::new(&config.motion);
        let noise = config.field.noise.sampler();
        let source = animation.shape_at(animation.keyframe_frames()[0]);
        let positions = sample_near_shape(
            &source,
            config.field.reach_km,
            config.motion.particles as usize,
            config.field.sampler,
            seed,
            INITIAL_STREAM,
        );
        let n = positions.len();
        let particles = Particles {
            id: (0..n as u64).collect(),
            position_km: positions,
            velocity_km_s: vec![Vec2::ZERO; n],
        };
        let mut sim = Self {
            config,
            seed,
            frame: 0,
            next_id: n as u64,
            animation,
            grid,
            model,
            noise,
            particles,
            field: FieldState::default(),
            near: Near { cells: Vec::new(), within: Nearness::new(&Shape::default(), 1.0) },
            scratch: MotionScratch::default(),
            clock: SharedClock::default(),
        };
        let mut stats = StepStats::default();
        sim.renew(&mut stats, false);
        Ok(sim)
    }

    /// Time the parts of each step with `clock` (the library reads no clock itself;
    /// without one the timings in [`StepStats`] are 0).
    pub fn set_clock(&mut self, clock: SharedClock) {
        self.clock = clock;
    }

    /// The configuration.
    pub fn config(&self) -> &AuroraConfig {
        &self.config
    }

    /// The seed the simulation was made with.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Frames completed.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// The plane's grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// The particles.
    pub fn particles(&self) -> &Particles {
        &self.particles
    }

    /// The current field and the shape it was made for.
    pub fn field(&self) -> &FieldState {
        &self.field
    }

    /// The shapes over time.
    pub fn animation(&self) -> &Animation {
        &self.animation
    }

    /// Advance one frame: move the particles, then, every K frames, renew the shape
    /// (redistributing against the old one first). §2.3.4 redistributes "after the
    /// position update", at the renewal; a frame ends with it, so the frame's particles
    /// (and its stats: `max_near_cell` at most `remove_above` under rule `"reach"`) are
    /// those right after redistribution.
    pub fn step(&mut self) -> Result<StepStats, AuroraError> {
        let mut stats = StepStats::default();
        let t = self.clock.stopwatch();
        stats.left_plane = step(
            &mut self.particles,
            &self.model,
            &self.grid,
            &self.field.e,
            self.field.rest_density,
            &mut self.scratch,
        )?;
        stats.forces_ms = t.ms();
        self.frame += 1;
        let k = u64::from(self.config.shape.renew_every_frames);
        if self.frame.is_multiple_of(k) {
            self.renew(&mut stats, self.config.redistribution.enabled);
        }
        stats.particles = self.particles.len();
        stats.max_near_cell = self.max_near_cell();
        stats.near_share = self.near.within.share(&self.particles.position_km);
        Ok(stats)
    }

    /// Particles in the fullest near cell of the current field.
    fn max_near_cell(&self) -> u32 {
        let mut counts = vec![0u32; self.grid.len()];
        for &x in &self.particles.position_km {
            if let Some((i, j)) = self.grid.cell_of(x) {
                counts[self.grid.index(i, j)] += 1;
            }
        }
        counts.iter().zip(&self.near.cells).filter(|(_, near)| **near).map(|(&n, _)| n).max().unwrap_or(0)
    }

    /// Renew the intermediate target shape: redistribute against the old field, then
    /// sample charges near the new shape and compute its potential and field.
    fn renew(&mut self, stats: &mut StepStats, redistribute: bool) {
        stats.renewed = true;
        if redistribute && !self.field.counts.is_empty() {
            let clock = self.clock.clone();
            let t = clock.stopwatch();
            (
                stats.redistributed_removed,
                stats.redistributed_added,
                stats.crowded_cells,
                stats.redistributed_max_cell,
            ) = self.redistribute();
            stats.redistribution_ms = t.ms();
        }
        let renewal = if self.field.counts.is_empty() { 0 } else { self.field.renewal + 1 };
        let target_frame = self.frame as f32 + self.config.shape.lookahead_frames as f32;
        let shape = self.animation.shape_at(target_frame);
        let time_s = self.frame as f64 * f64::from(self.config.motion.time_step_s);
        let inputs = FieldInputs {
            grid: &self.grid,
            params: &self.config.field,
            noise: &self.noise,
            seed: self.seed,
            renewal,
            time_s,
            particles: self.particles.len(),
        };
        self.field = FieldState::build(shape, &inputs, stats, &self.clock);
        self.near = Near::of(&self.field, &self.config.redistribution, self.config.field.reach_km);
    }

    /// §2.3.4 with Table 3.3's thresholds: remove particles in cells that are not near
    /// the (old) shape, thin crowded near cells from the particle farthest from the shape
    /// on, and top up sparse near cells with particles at random positions moving with
    /// their neighbours' mean velocity; rule `"reach"` also removes particles beyond
    /// L_thr, removes a crowded cell's whole excess and adds only within L_thr
    /// ([`RedistributionRule`]). Returns (removed, added, cells still crowded, particles
    /// in the fullest cell afterwards).
    fn redistribute(&mut self) -> (usize, usize, usize, u32) {
        let r = &self.config.redistribution;
        let reach_rule = r.rule == RedistributionRule::Reach;
        let (grid, field) = (&self.grid, &self.field);
        let cells = grid.len();
        let near = &self.near.cells;
        let within = &self.near.within;
        let p = &self.particles;
        let (by_cell, mut keep, beyond) = particles_by_cell(p, grid, &self.near, reach_rule);
        let mut removed = beyond;
        let mut crowded = 0usize;
        let mut fullest = 0u32;
        let mut additions: Vec<(u64, Vec2, Vec2)> = Vec::new();
        for c in 0..cells {
            let members = &by_cell[c];
            if !near[c] {
                for &i in members {
                    keep[i as usize] = false;
                }
                removed += members.len();
                continue;
            }
            let count = members.len() as u32;
            let (ci, cj) = (c % grid.nx, c / grid.nx);
            let corner = grid.origin_km + Vec2::new(ci as f32, cj as f32) * grid.cell_km;
            // Rule "reach": the part of `add_below` the cell's share within L_thr asks for.
            let add_below = if reach_rule && count < r.add_below {
                let covered = covered_share(within, corner, grid.cell_km);
                (f64::from(r.add_below) * covered).round() as u32
            } else {
                r.add_below
            };
            if count > r.remove_above {
                let cap = if reach_rule { u32::MAX } else { r.remove_max };
                let excess = ((count - r.remove_above).min(cap)) as usize;
                crowded += usize::from(count - excess as u32 > r.remove_above);
                fullest = fullest.max(count - excess as u32);
                remove_farthest(members, excess, &field.shape, &p.position_km, &mut keep);
                removed += excess;
            } else if count < add_below {
                let add = (add_below - count).min(r.add_max);
                let mean_v = neighbourhood_mean_velocity(&by_cell, p, grid, (ci, cj));
                let mut rng = Stream::new(self.seed, REDISTRIBUTE, field.renewal * cells as u64 + c as u64);
                let cell = (corner, grid.cell_km);
                let placed = place_additions(
                    &mut rng,
                    cell,
                    add,
                    reach_rule.then_some(within),
                    mean_v,
                    &mut additions,
                );
                fullest = fullest.max(count + placed);
            } else {
                fullest = fullest.max(count);
            }
        }
        let added = additions.len();
        self.particles.retain(&keep);
        for (_, x, v) in additions {
            self.particles.push(self.next_id, x, v);
            self.next_id += 1;
        }
        (removed, added, crowded, fullest)
    }
}

/// The particles of every cell of `grid`, in particle order; which particles stay (not
/// those outside the grid, nor under rule `"reach"` those in near cells beyond L_thr);
/// and how many of the latter went.
fn particles_by_cell(
    p: &Particles,
    grid: &Grid,
    near: &Near,
    reach_rule: bool,
) -> (Vec<Vec<u32>>, Vec<bool>, usize) {
    let mut by_cell: Vec<Vec<u32>> = vec![Vec::new(); grid.len()];
    let mut keep = vec![true; p.len()];
    let mut beyond = 0usize;
    for (i, &x) in p.position_km.iter().enumerate() {
        match grid.cell_of(x) {
            Some((ci, cj)) => {
                let c = grid.index(ci, cj);
                if reach_rule && near.cells[c] && !near.within.covers(x) {
                    keep[i] = false;
                    beyond += 1;
                } else {
                    by_cell[c].push(i as u32);
                }
            }
            None => keep[i] = false,
        }
    }
    (by_cell, keep, beyond)
}

/// Thin a crowded cell (§2.3.4): the `excess` particles of `members` farthest from the
/// shape go (`keep` cleared); ties broken by index for determinism.
fn remove_farthest(members: &[u32], excess: usize, shape: &Shape, position_km: &[Vec2], keep: &mut [bool]) {
    let mut by_distance: Vec<(f32, u32)> =
        members.iter().map(|&i| (shape.distance(position_km[i as usize]), i)).collect();
    // Farthest first; ties broken by index for determinism.
    by_distance.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    for &(_, i) in &by_distance[..excess] {
        keep[i as usize] = false;
    }
}

/// Mean velocity (km/s) of the particles in cell `(ci, cj)` and its neighbours (zero
/// when there are none): what particles added to a sparse cell move with (§2.3.4).
fn neighbourhood_mean_velocity(
    by_cell: &[Vec<u32>],
    p: &Particles,
    grid: &Grid,
    (ci, cj): (usize, usize),
) -> Vec2 {
    let mut mean_v = Vec2::ZERO;
    let mut neighbours = 0usize;
    for nj in cj.saturating_sub(1)..=(cj + 1).min(grid.nz - 1) {
        for ni in ci.saturating_sub(1)..=(ci + 1).min(grid.nx - 1) {
            for &i in &by_cell[grid.index(ni, nj)] {
                mean_v += p.velocity_km_s[i as usize];
                neighbours += 1;
            }
        }
    }
    if neighbours > 0 {
        mean_v /= neighbours as f32;
    }
    mean_v
}

/// Top up a sparse cell (§2.3.4): `add` particles at uniform random positions in the
/// cell (`corner`, edge `cell_km`), moving at `mean_v`, into `additions`. With `within`
/// (rule `"reach"`) a position is drawn up to [`ADD_DRAWS`] times to lie within L_thr,
/// and the particle is left out if none does. Returns how many were placed.
fn place_additions(
    rng: &mut Stream,
    (corner, cell_km): (Vec2, f32),
    add: u32,
    within: Option<&Nearness>,
    mean_v: Vec2,
    additions: &mut Vec<(u64, Vec2, Vec2)>,
) -> u32 {
    let mut placed = 0u32;
    for _ in 0..add {
        let mut x = corner + Vec2::new(rng.next_f32(), rng.next_f32()) * cell_km;
        if let Some(within) = within {
            let mut draws = 1;
            while !within.covers(x) && draws < ADD_DRAWS {
                x = corner + Vec2::new(rng.next_f32(), rng.next_f32()) * cell_km;
                draws += 1;
            }
            if !within.covers(x) {
                continue;
            }
        }
        additions.push((0, x, mean_v));
        placed += 1;
    }
    placed
}

/// Draws per added particle to find a position within L_thr (rule `"reach"`).
const ADD_DRAWS: u32 = 16;

/// The share of the cell at `corner` (side `cell_km`) within reach, from an 8 × 8
/// lattice of its points.
fn covered_share(within: &Nearness, corner: Vec2, cell_km: f32) -> f64 {
    const N: u32 = 8;
    let inside = (0..N * N)
        .filter(|k| {
            let q = Vec2::new((k % N) as f32 + 0.5, (k / N) as f32 + 0.5) / N as f32;
            within.covers(corner + q * cell_km)
        })
        .count();
    inside as f64 / f64::from(N * N)
}

/// A checkpoint: everything an [`AuroraSim`] built from the same configuration and
/// seed needs to continue bit-identically (the shapes, grid and noise are rebuilt from
/// the configuration; every random number is keyed by seed, purpose and frame or
/// renewal, so no stream position is kept).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AuroraState {
    /// Frames completed.
    pub frame: u64,
    /// Id of the next particle to be added.
    pub next_id: u64,
    /// The particles.
    pub particles: Particles,
    /// The field of the current intermediate target shape.
    pub field: FieldState,
}

impl AuroraSim {
    /// A checkpoint of the current state.
    pub fn state(&self) -> AuroraState {
        AuroraState {
            frame: self.frame,
            next_id: self.next_id,
            particles: self.particles.clone(),
            field: self.field.clone(),
        }
    }

    /// Continue from a checkpoint taken with [`AuroraSim::state`] of a simulation with
    /// the same configuration and seed. Refused, leaving `self` as it was, when its
    /// arrays do not fit this simulation's grid or a particle is not finite.
    pub fn restore(&mut self, state: AuroraState) -> Result<(), AuroraError> {
        let bad = |what: String| Err(AuroraError::State(what));
        let p = &state.particles;
        if p.position_km.len() != p.len() || p.velocity_km_s.len() != p.len() {
            return bad(format!(
                "{} ids, {} positions, {} velocities",
                p.len(),
                p.position_km.len(),
                p.velocity_km_s.len()
            ));
        }
        if let Some(i) =
            (0..p.len()).find(|&i| !p.position_km[i].is_finite() || !p.velocity_km_s[i].is_finite())
        {
            return bad(format!("particle {i} has a position or velocity that is not finite"));
        }
        let f = &state.field;
        let cells = self.grid.len();
        let lens = [f.counts.len(), f.potential.len(), f.potential_noisy.len(), f.e.len()];
        if lens.iter().any(|&l| l != cells) {
            return bad(format!("field arrays of {lens:?} cells for a grid of {cells}"));
        }
        if !f.rest_density.is_finite() || f.e.iter().any(|e| !e.is_finite()) {
            return bad("the field is not finite".into());
        }
        if f.shape.next.len() != f.shape.points.len()
            || f.shape.next.iter().flatten().any(|&j| j as usize >= f.shape.points.len())
        {
            return bad("the field's shape links points it does not have".into());
        }
        self.frame = state.frame;
        self.next_id = state.next_id;
        self.particles = state.particles;
        self.field = state.field;
        self.near = Near::of(&self.field, &self.config.redistribution, self.config.field.reach_km);
        Ok(())
    }
}

impl phenomena_core::phenomenon::Simulation for AuroraSim {
    type StepStats = StepStats;
    type Error = AuroraError;

    fn step(&mut self) -> Result<StepStats, AuroraError> {
        AuroraSim::step(self)
    }

    fn frames_done(&self) -> u64 {
        self.frame()
    }

    type State = AuroraState;

    fn state(&self) -> AuroraState {
        AuroraSim::state(self)
    }

    fn restore(&mut self, state: AuroraState) -> Result<(), AuroraError> {
        AuroraSim::restore(self, state)
    }
}
