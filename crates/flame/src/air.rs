//! The air around the flame (extended mode only; an extension beyond the paper, whose
//! particles only push each other).
//!
//! A fire puffs because of the air around it: the hot gas accelerates upwards, draws
//! the ambient air in at its base (the flame necks), the shear layer between them rolls
//! up into a toroidal vortex, and the vortex sheds the flame's tip as a tongue. The
//! puffing is the flame's axisymmetric (varicose) mode, so the air is solved in the
//! meridional plane of the burner's axis: an incompressible flow in cylindrical
//! coordinates (r, z) without swirl, with buoyancy from the density deficit of hot gas
//! (ρ ∝ 1/T at constant pressure, so the upward acceleration is g·(T - T_a)/T), on a
//! staggered (MAC) grid whose cell is a fixed fraction of the burner's diameter.
//!
//! The burner is where the flame's hot gas enters: at the emitter's temperature (the
//! particles are born burning, §4.3) and slowly (`inflow_m_s`), as the gas of a pool
//! fire leaves its surface; its own buoyancy accelerates it. The particles are carried
//! by the air and are no hotter than it ([`Air`]).
//!
//! Each substep: the velocity and the temperature excess are carried by the flow
//! (semi-Lagrangian with a MacCormack correction, clamped to the values it interpolated
//! between, after Selle et al. 2008, so the roll-up is not smeared away), the burner's
//! gas enters, the buoyancy is added, and the velocity is projected to zero
//! divergence. The projection is exact, not iterated: the pressure Poisson equation is
//! diagonalised along z by the cosine modes of its boundary conditions (a wall at the
//! ground, open air at the top) and each mode is a tridiagonal system along r (the axis,
//! and open air at the outer radius, where the entrained air comes in).

use crate::obstacles::Solids;
pub use crate::obstacles::{MAX_BOUNDARY_CELLS, MAX_CAPACITANCE_VALUES, MAX_OBSTACLES, Obstacle};
use phenomena_core::validate::Issues;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Standard gravity, m/s².
const G: f32 = 9.81;

/// The air's parameters, the `[flame.extended.air]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AirParams {
    /// Solve the air around the flame (extended mode only). With the defaults below
    /// the flame puffs at 0.91-0.95 of the pool-fire law f = 1.5/√D for D = 0.1-0.6 m
    /// (`tests/flame_puffs_like_a_pool_fire.rs`). Off by default because it is not yet
    /// live: 45-160 ms a frame for those burners (docs/performance.md), against the
    /// 2-3 ms of the flame scenes without it.
    pub enabled: bool,
    /// Grid cells across the burner's diameter. The puffing frequency depends on it
    /// through the scheme's numerical viscosity (the air has no other): measured with
    /// `examples/air_puff.rs` (2026-12-06), 16 cells give 0.73-0.78 of the law, 20 give
    /// 0.91-0.95, over D = 0.1-0.6 m; the ratio does not change with D at a given
    /// count, because the grid scales with D.
    pub cells_per_diameter: u32,
    /// Radius of the air's cylinder, in burner diameters.
    pub radius_diameters: f32,
    /// Height of the air's cylinder above the burner, in burner diameters.
    pub height_diameters: f32,
    /// Time over which a particle takes up the air's velocity, seconds (Stokes drag).
    pub drag_time_s: f32,
    /// Speed at which the burner's hot gas enters the air, m/s. A pool or gas-burner
    /// fire's gas leaves its surface at centimetres a second and is accelerated by its
    /// own buoyancy; the particles' launch speed (`emitter.velocity_m_s`) decays into
    /// the air's within `drag_time_s`.
    pub inflow_m_s: f32,
    /// Largest Courant number of one air substep (cells crossed in one substep), kept
    /// with up to 16 air substeps a simulation substep; faster air than that crosses
    /// more cells a substep (the transport stays stable, less accurate).
    pub max_courant: f32,
    /// Solids of revolution about the burner's axis that the air flows around and the
    /// particles cannot enter ([`Obstacle`]); at most [`MAX_OBSTACLES`]. (Not written
    /// when empty, so the scenes without obstacles keep their checkpoints' identity.)
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub obstacles: Vec<Obstacle>,
}

impl Default for AirParams {
    fn default() -> Self {
        Self {
            enabled: false,
            cells_per_diameter: 20,
            radius_diameters: 2.0,
            height_diameters: 8.0,
            drag_time_s: 0.02,
            inflow_m_s: 0.05,
            max_courant: 1.0,
            obstacles: Vec::new(),
        }
    }
}

impl AirParams {
    /// This table's problems, into `i`, fields prefixed by `prefix`.
    pub(crate) fn validate(&self, prefix: &str, i: &mut Issues) {
        i.count(&format!("{prefix}cells_per_diameter"), u64::from(self.cells_per_diameter), 4..=128);
        i.range(&format!("{prefix}radius_diameters"), self.radius_diameters, 0.75..=8.0);
        i.range(&format!("{prefix}height_diameters"), self.height_diameters, 1.0..=32.0);
        i.range_open_low(&format!("{prefix}drag_time_s"), self.drag_time_s, 0.0, 100.0);
        i.range(&format!("{prefix}inflow_m_s"), self.inflow_m_s, 0.0..=100.0);
        i.range(&format!("{prefix}max_courant"), self.max_courant, 0.1..=4.0);
        // The projection's cost grows as nz² · nr: bound the grid's rows and columns.
        let (nr, nz) = self.cells();
        if nz > MAX_ROWS {
            i.push(
                format!("{prefix}height_diameters"),
                self.height_diameters,
                format!("at most {MAX_ROWS} rows of cells: cells_per_diameter × height_diameters is {nz}"),
            );
        }
        if nr > MAX_COLUMNS {
            i.push(
                format!("{prefix}radius_diameters"),
                self.radius_diameters,
                format!(
                    "at most {MAX_COLUMNS} rings of cells: cells_per_diameter × radius_diameters is {nr}"
                ),
            );
        }
    }

    /// The obstacles' problems around a burner of `burner_radius_m` (≥ 0), into `i`
    /// ([`crate::obstacles`]).
    pub(crate) fn validate_obstacles(&self, prefix: &str, burner_radius_m: f32, i: &mut Issues) {
        let (nr, nz) = self.cells();
        let cell_m = 2.0 * burner_radius_m / self.cells_per_diameter.max(1) as f32;
        crate::obstacles::validate(&self.obstacles, prefix, burner_radius_m, (nr, nz, cell_m), i);
    }

    /// Cells along r and z.
    fn cells(&self) -> (usize, usize) {
        let cpd = self.cells_per_diameter as f32;
        let nr = ((self.radius_diameters * cpd).round() as usize).max(2);
        let nz = ((self.height_diameters * cpd).round() as usize).max(2);
        (nr, nz)
    }
}

/// Most rows of air cells (the projection's transform is nz² · nr multiply-adds: at
/// 512 × 128, 3.4·10⁷ per air substep).
const MAX_ROWS: usize = 512;
/// Most rings of air cells.
const MAX_COLUMNS: usize = 128;

/// The air on its grid: velocity on the faces, temperature excess in the cells.
///
/// Cell (i, j) spans r ∈ [i, i+1)·dx and z ∈ [j, j+1)·dx above the burner. `ur` lives
/// on the faces r = i·dx (i = 0..=nr, the axis at i = 0), `uz` on the faces z = j·dx
/// (j = 0..=nz, the ground at j = 0).
#[derive(Clone, Debug)]
pub struct AirGrid {
    nr: usize,
    nz: usize,
    dx: f32,
    ambient_k: f32,
    /// Radial velocity, m/s, `[j * (nr + 1) + i]`.
    ur: Vec<f32>,
    /// Axial velocity, m/s, `[j * nr + i]`, j = 0..=nz.
    uz: Vec<f32>,
    /// Temperature above ambient, kelvin, `[j * nr + i]`.
    theta: Vec<f32>,
    /// Cosine modes of the z Laplacian, `[k * nz + j]`, and their eigenvalues (per dx²).
    modes: Vec<f32>,
    eigen: Vec<f32>,
    scratch: [Vec<f32>; 4],
    /// What the transport's forward step keeps for its backward step, a sample a
    /// field ([`mac_cormack`]).
    kept: Vec<[f32; 4]>,
    /// Solid cells ([`AirGrid::set_solid`]); `None` without obstacles.
    solids: Option<Box<Solids>>,
}

/// The burner as the air sees it: hot gas entering through the ground.
#[derive(Clone, Copy, Debug)]
pub struct Burner {
    /// Cells from the axis whose ground face is the burner.
    pub cells: usize,
    /// The gas's speed through the ground face, m/s.
    pub inflow_m_s: f32,
    /// The gas's temperature above ambient, kelvin.
    pub theta: f32,
}

impl AirGrid {
    /// Air at rest and at ambient temperature, `nr` × `nz` cells of `dx` metres.
    pub fn new(nr: usize, nz: usize, dx: f32, ambient_k: f32) -> Self {
        let mut modes = vec![0.0; nz * nz];
        let mut eigen = vec![0.0; nz];
        for k in 0..nz {
            let theta = (k as f64 + 0.5) * std::f64::consts::PI / nz as f64;
            eigen[k] = (2.0 * theta.cos() - 2.0) as f32;
            for j in 0..nz {
                modes[k * nz + j] = (theta * (j as f64 + 0.5)).cos() as f32;
            }
        }
        Self {
            nr,
            nz,
            dx,
            ambient_k,
            ur: vec![0.0; (nr + 1) * nz],
            uz: vec![0.0; nr * (nz + 1)],
            theta: vec![0.0; nr * nz],
            modes,
            eigen,
            scratch: Default::default(),
            kept: Vec::new(),
            solids: None,
        }
    }

    /// Makes `cell` (`[j * nr + i]`) the solid cells: the faces beside them carry no
    /// flow ([`crate::obstacles`]). No solid cell leaves the grid as it was (and its
    /// projection the open grid's).
    pub(crate) fn set_solid(&mut self, cell: Vec<bool>) {
        let (nr, nz) = (self.nr, self.nz);
        self.solids = None;
        let solids = Solids::new(cell, nr, nz, |rhs| self.open_solve(rhs));
        self.solids = solids.map(Box::new);
    }

    /// Whether cell (i, j) is solid.
    pub fn is_solid(&self, i: usize, j: usize) -> bool {
        self.solids.as_ref().is_some_and(|s| s.cell[j * self.nr + i])
    }

    /// Cells along r and z, and the cell size in metres.
    pub fn shape(&self) -> (usize, usize, f32) {
        (self.nr, self.nz, self.dx)
    }

    /// Ambient temperature, kelvin.
    pub fn ambient_k(&self) -> f32 {
        self.ambient_k
    }

    /// The air's velocity (radial, axial) at distance `r` from the axis and height `z`
    /// above the ground, m/s (held at the grid's edge values outside it).
    pub fn velocity(&self, r: f32, z: f32) -> (f32, f32) {
        self.sampler().velocity(r / self.dx, z / self.dx)
    }

    /// The air's temperature above ambient at (r, z), kelvin.
    pub fn theta_at(&self, r: f32, z: f32) -> f32 {
        self.theta_layout().value(&self.theta, r / self.dx, z / self.dx)
    }

    fn ur_layout(&self) -> Layout {
        Layout { w: self.nr + 1, h: self.nz, r_off: 0.0, z_off: 0.5, odd: true, ambient_outside: false }
    }

    fn uz_layout(&self) -> Layout {
        Layout { w: self.nr, h: self.nz + 1, r_off: 0.5, z_off: 0.0, odd: false, ambient_outside: false }
    }

    fn theta_layout(&self) -> Layout {
        Layout { w: self.nr, h: self.nz, r_off: 0.5, z_off: 0.5, odd: false, ambient_outside: true }
    }

    /// Largest speed on the grid, m/s.
    pub fn max_speed(&self) -> f32 {
        self.ur.iter().chain(&self.uz).fold(0.0f32, |m, v| m.max(v.abs()))
    }

    /// Substeps that keep `dt` within `max_courant` cells of travel.
    pub fn substeps(&self, dt: f32, max_courant: f32) -> u32 {
        let travel = self.max_speed() * dt / (max_courant * self.dx);
        (travel.ceil() as u32).clamp(1, 16)
    }

    fn sampler(&self) -> Sampler<'_> {
        Sampler { ur_layout: self.ur_layout(), uz_layout: self.uz_layout(), ur: &self.ur, uz: &self.uz }
    }

    /// One substep of `dt` seconds: transport, the `burner`'s hot gas entering,
    /// buoyancy, projection.
    pub fn step(&mut self, dt: f32, burner: &Burner) {
        self.advect(dt);
        for i in 0..burner.cells.min(self.nr) {
            self.uz[i] = burner.inflow_m_s;
            self.theta[i] = burner.theta;
        }
        self.buoyancy(dt);
        // The axis carries no radial flow.
        for j in 0..self.nz {
            self.ur[j * (self.nr + 1)] = 0.0;
        }
        self.close_solids();
        self.project(dt);
    }

    /// No flow through the faces beside solid cells, and solid cells at the ambient
    /// temperature.
    fn close_solids(&mut self) {
        let Some(s) = &self.solids else { return };
        for (u, &open) in self.ur.iter_mut().zip(&s.ur_open) {
            if !open {
                *u = 0.0;
            }
        }
        for (u, &open) in self.uz.iter_mut().zip(&s.uz_open) {
            if !open {
                *u = 0.0;
            }
        }
        for (t, &solid) in self.theta.iter_mut().zip(&s.cell) {
            if solid {
                *t = 0.0;
            }
        }
    }

    /// Carries ur, uz and θ along the flow for `dt` (MacCormack, clamped).
    fn advect(&mut self, dt: f32) {
        let nr = self.nr;
        let dt_cells = dt / self.dx;
        let [mut forward, mut ur, mut uz, mut theta] = std::mem::take(&mut self.scratch);
        let mut kept = std::mem::take(&mut self.kept);
        {
            let s = self.sampler();
            let mut scratch = (&mut forward, &mut kept);
            mac_cormack(&s, dt_cells, self.ur_layout(), &self.ur, &mut scratch, &mut ur);
            mac_cormack(&s, dt_cells, self.uz_layout(), &self.uz, &mut scratch, &mut uz);
            mac_cormack(&s, dt_cells, self.theta_layout(), &self.theta, &mut scratch, &mut theta);
        }
        self.kept = kept;
        // The ground's faces keep their boundary values.
        uz[..nr].copy_from_slice(&self.uz[..nr]);
        std::mem::swap(&mut self.ur, &mut ur);
        std::mem::swap(&mut self.uz, &mut uz);
        std::mem::swap(&mut self.theta, &mut theta);
        self.scratch = [forward, ur, uz, theta];
    }

    /// Upward acceleration g·(T - T_a)/T on the axial faces above the ground.
    fn buoyancy(&mut self, dt: f32) {
        let (nr, nz) = (self.nr, self.nz);
        let ta = self.ambient_k;
        for j in 1..=nz {
            for i in 0..nr {
                let below = self.theta[(j - 1) * nr + i];
                let above = if j < nz { self.theta[j * nr + i] } else { below };
                let th = 0.5 * (below + above);
                self.uz[j * nr + i] += dt * G * th / (th + ta);
            }
        }
    }

    /// Removes the divergence: solves ∇²p = ∇·u / dt exactly and subtracts dt ∇p.
    fn project(&mut self, dt: f32) {
        let (nr, nz) = (self.nr, self.nz);
        let inv_dx = 1.0 / self.dx;
        // Divergence × dx² / dt, so that the Laplacian below is in units of dx⁻².
        let scale = self.dx / dt;
        let mut rhs = std::mem::take(&mut self.scratch[0]);
        rhs.clear();
        rhs.resize(nr * nz, 0.0);
        for j in 0..nz {
            for i in 0..nr {
                rhs[j * nr + i] = self.divergence(i, j) * scale;
            }
        }
        let p = if self.solids.is_some() { self.solve_with_solids(&rhs) } else { self.solve_poisson(&rhs) };
        // u -= dt ∇p, with p in units where ∇ is a plain difference: p·dt/dx² scaled.
        self.subtract_gradient(&p, dt * inv_dx);
        self.scratch[0] = rhs;
        self.scratch[3] = p;
    }

    /// u -= g ∇p through every face the solids leave open (the closed ones stay at
    /// rest); the outer and top faces take the ghost −p of p = 0 there.
    fn subtract_gradient(&mut self, p: &[f32], g: f32) {
        let (nr, nz) = (self.nr, self.nz);
        let solids = self.solids.as_deref();
        let ur_open = |f: usize| solids.is_none_or(|s| s.ur_open[f]);
        let uz_open = |f: usize| solids.is_none_or(|s| s.uz_open[f]);
        for j in 0..nz {
            for i in 1..=nr {
                if ur_open(j * (nr + 1) + i) {
                    let outer = if i < nr { p[j * nr + i] } else { -p[j * nr + nr - 1] };
                    self.ur[j * (nr + 1) + i] -= g * (outer - p[j * nr + i - 1]);
                }
            }
        }
        for j in 1..=nz {
            for i in 0..nr {
                if uz_open(j * nr + i) {
                    let above = if j < nz { p[j * nr + i] } else { -p[(nz - 1) * nr + i] };
                    self.uz[j * nr + i] -= g * (above - p[(j - 1) * nr + i]);
                }
            }
        }
    }

    /// p with L p = rhs in the air's cells and no flux through the faces beside solid
    /// cells, p = 0 in them: exact, by the capacitance matrix of [`crate::obstacles`].
    fn solve_with_solids(&mut self, rhs: &[f32]) -> Vec<f32> {
        let Some(s) = self.solids.take() else { return self.solve_poisson(rhs) };
        let p = s.solve(rhs, |b| self.solve_poisson(b));
        self.solids = Some(s);
        p
    }

    /// [`AirGrid::solve_poisson`] as a fresh vector (for the obstacles' set-up and tests).
    pub(crate) fn open_solve(&mut self, rhs: &[f32]) -> Vec<f32> {
        let p = self.solve_poisson(rhs);
        let out = p.clone();
        self.scratch[3] = p;
        out
    }

    /// p with L p = rhs, L the 5-point cylindrical Laplacian times dx² (axis: no flux;
    /// outer radius and top: p = 0 on the boundary face; ground: no flux).
    fn solve_poisson(&mut self, rhs: &[f32]) -> Vec<f32> {
        let (nr, nz) = (self.nr, self.nz);
        // Into the z modes: rhs_k(i) = (2/nz) Σ_j C[k][j] rhs(j, i).
        let mut hat = std::mem::take(&mut self.scratch[1]);
        hat.clear();
        hat.resize(nz * nr, 0.0);
        let modes = &self.modes;
        let norm = 2.0 / nz as f32;
        hat.par_chunks_mut(nr).enumerate().for_each(|(k, row)| {
            for j in 0..nz {
                let c = modes[k * nz + j] * norm;
                for (h, r) in row.iter_mut().zip(&rhs[j * nr..(j + 1) * nr]) {
                    *h += c * r;
                }
            }
        });
        // Each mode along r: a_i p_{i-1} + (λ_k - a_i - c_i) p_i + c_i p_{i+1} = rhs.
        let eigen = &self.eigen;
        hat.par_chunks_mut(nr).enumerate().for_each(|(k, row)| thomas_radial(row, eigen[k]));
        // Back: p(j, i) = Σ_k C[k][j] p_k(i).
        let mut p = std::mem::take(&mut self.scratch[3]);
        p.clear();
        p.resize(nr * nz, 0.0);
        p.par_chunks_mut(nr).enumerate().for_each(|(j, row)| {
            for k in 0..nz {
                let c = modes[k * nz + j];
                for (o, h) in row.iter_mut().zip(&hat[k * nr..(k + 1) * nr]) {
                    *o += c * h;
                }
            }
        });
        self.scratch[1] = hat;
        p
    }

    /// ∇·u × dx of cell (i, j), m/s: the cylindrical divergence (r·u_r through the
    /// faces at radii i and i + 1 over the cell's centre radius, plus u_z's difference).
    fn divergence(&self, i: usize, j: usize) -> f32 {
        let nr = self.nr;
        let (ri, ro, rc) = (i as f32, (i + 1) as f32, i as f32 + 0.5);
        let div_r = (ro * self.ur[j * (nr + 1) + i + 1] - ri * self.ur[j * (nr + 1) + i]) / rc;
        let div_z = self.uz[(j + 1) * nr + i] - self.uz[j * nr + i];
        div_r + div_z
    }

    /// Largest |∇·u|·dx over the cells, m/s: zero up to rounding after a projection.
    pub fn max_divergence(&self) -> f32 {
        let mut worst = 0.0f32;
        for j in 0..self.nz {
            for i in 0..self.nr {
                worst = worst.max(self.divergence(i, j).abs());
            }
        }
        worst
    }
}

/// The air coupled to a flame: the grid on the burner's axis and the wind's drift of
/// the air column.
///
/// The particles are the burner's gas, and that gas's mass, momentum and heat already
/// enter the air through the burner ([`Burner`]). So the air carries the particles
/// (Stokes drag towards its velocity) and sets how hot they can be (a particle is no
/// hotter than the air around it: where the flame's gas has mixed with entrained air it
/// dims), but their own momentum is not given back to the air, which would count the
/// burner's gas twice. (Measured: with that reaction added, the particles piling up
/// over the slow burner pushed the air into a slow breathing at 0.75 Hz that hid the
/// puffing, `examples/flame_puff.rs`, 2026-12-06.)
///
/// The grid is axisymmetric, so the wind cannot blow across it; instead each row of the
/// grid carries a horizontal drift velocity, pushed by the wind's force density (as the
/// air's, ρ = 1.2 kg/m³) and carried up with the air rising in the flame's core, and the
/// row's axis is displaced by the drift it has accumulated. Air enters the lowest row
/// from the ground without drift, so the column leans with the time its air has spent
/// in the wind, as a plume in a crossflow does; the grid's own flow (the necking, the
/// vortex rings) is solved about the leaning axis. The drift forgets the wind over a
/// second, so rows whose core does not rise (above the flame's
/// tip, above an obstacle) reach a steady drift instead of gaining it without end, and
/// no row's axis moves further than the cylinder's radius from the burner. Rows that
/// hold an obstacle stay on the burner's axis (the obstacle is fixed to the ground),
/// and the rows above lean from there. The particles
/// also still feel the wind's force directly, as in the paper; dragged to the air within
/// `drag_time_s`, that adds a slip of F·τ/ρ, millimetres a second.
///
/// Outside the air's cylinder (beyond `radius_diameters` or above `height_diameters`)
/// the air is ambient: a particle there is cooled to the ambient temperature, and moves
/// with the air at the cylinder's edge.
#[derive(Clone, Debug)]
pub struct Air {
    grid: AirGrid,
    /// The burner's centre: the axis's foot and the ground's height.
    origin: glam::Vec3,
    /// Per row: the air's horizontal drift velocity (x, z), m/s.
    drift: Vec<glam::Vec2>,
    /// Per row: the axis's horizontal displacement from the burner's centre (x, z), m.
    offset: Vec<glam::Vec2>,
    /// Cells within the burner's radius (the flame's core, whose rise carries the drift).
    core: usize,
    /// Per row: it holds an obstacle (or lies just under one), so it does not drift.
    anchored: Vec<bool>,
    burner: Burner,
    params: AirParams,
}

impl Air {
    /// The air around `burner` in air at `ambient_k`: the burner's gas enters the air at
    /// `params.inflow_m_s` and at the emitter's temperature (the particles are born
    /// burning, at that temperature: the paper's §4.3).
    pub fn new(params: &AirParams, burner: &crate::config::Emitter, ambient_k: f32) -> Self {
        let (origin, radius_m, flame_k) = (burner.position_m, burner.radius_m, burner.temperature_k);
        let cpd = params.cells_per_diameter as usize;
        let dx = 2.0 * radius_m / cpd as f32;
        let (nr, nz) = params.cells();
        let mut grid = AirGrid::new(nr, nz, dx, ambient_k);
        grid.set_solid(crate::obstacles::solid_cells(&params.obstacles, nr, nz, dx));
        // Rows whose span meets an obstacle's heights, or lies within a cell under it.
        let anchored = (0..nz)
            .map(|j| {
                let (lo, hi) = (j as f32 * dx, (j + 1) as f32 * dx);
                params.obstacles.iter().any(|o| hi >= o.bottom_m - dx && lo <= o.top_m)
            })
            .collect();
        let cells = (0..nr).take_while(|&i| (i as f32 + 0.5) * dx < radius_m).count().max(1);
        Self {
            grid,
            origin,
            drift: vec![glam::Vec2::ZERO; nz],
            offset: vec![glam::Vec2::ZERO; nz],
            core: (cpd / 2).max(1),
            anchored,
            burner: Burner { cells, inflow_m_s: params.inflow_m_s, theta: (flame_k - ambient_k).max(0.0) },
            params: params.clone(),
        }
    }

    /// The grid.
    pub fn grid(&self) -> &AirGrid {
        &self.grid
    }

    /// Row of height `z` above the ground (clamped).
    fn row(&self, z: f32) -> usize {
        let (_, nz, dx) = self.grid.shape();
        ((z / dx).max(0.0) as usize).min(nz - 1)
    }

    /// A point's distance from the (displaced) axis, height, and unit radial direction
    /// in the horizontal plane.
    fn local(&self, p: glam::Vec3) -> (f32, f32, glam::Vec2) {
        let z = p.y - self.origin.y;
        let axis = glam::Vec2::new(self.origin.x, self.origin.z) + self.offset[self.row(z)];
        let d = glam::Vec2::new(p.x, p.z) - axis;
        let r = d.length();
        let dir = if r > 0.0 { d / r } else { glam::Vec2::ZERO };
        (r, z, dir)
    }

    /// Whether `p` (world space) lies inside the air's cylinder: within its radius of
    /// the (displaced) axis at its height, and between the ground and its top.
    pub fn contains(&self, p: glam::Vec3) -> bool {
        let (nr, nz, dx) = self.grid.shape();
        let (r, z, _) = self.local(p);
        r <= nr as f32 * dx && (0.0..=nz as f32 * dx).contains(&z)
    }

    /// Height of the ground (the burner's centre), world space, m.
    pub fn ground_m(&self) -> f32 {
        self.origin.y
    }

    /// Where the air's axis stands at `height_m` above the ground (world x, z, m): the
    /// burner's centre displaced by that row's drift.
    pub fn axis_at(&self, height_m: f32) -> glam::Vec2 {
        glam::Vec2::new(self.origin.x, self.origin.z) + self.offset[self.row(height_m)]
    }

    /// Whether `p` (world space) lies inside one of the obstacles.
    pub fn in_obstacle(&self, p: glam::Vec3) -> bool {
        let r = glam::Vec2::new(p.x - self.origin.x, p.z - self.origin.z).length();
        self.params.obstacles.iter().any(|o| o.contains(r, p.y - self.origin.y))
    }

    /// The box (lowest and highest corner, world space, m) that holds the air's cylinder
    /// with every row's axis where the wind has displaced it.
    pub fn bounds(&self) -> (glam::Vec3, glam::Vec3) {
        let (nr, nz, dx) = self.grid.shape();
        let radius = nr as f32 * dx;
        let (lo, hi) = self
            .offset
            .iter()
            .fold((glam::Vec2::MAX, glam::Vec2::MIN), |(lo, hi), &o| (lo.min(o), hi.max(o)));
        let foot = glam::Vec2::new(self.origin.x, self.origin.z);
        let (lo, hi) = (foot + lo - glam::Vec2::splat(radius), foot + hi + glam::Vec2::splat(radius));
        (
            glam::Vec3::new(lo.x, self.origin.y, lo.y),
            glam::Vec3::new(hi.x, self.origin.y + nz as f32 * dx, hi.y),
        )
    }

    /// The air's velocity at `p` (world space), m/s.
    pub fn velocity_at(&self, p: glam::Vec3) -> glam::Vec3 {
        let (r, z, dir) = self.local(p);
        let (ur, uz) = self.grid.velocity(r, z);
        let drift = self.drift[self.row(z)];
        glam::Vec3::new(dir.x * ur + drift.x, uz, dir.y * ur + drift.y)
    }

    /// The air's temperature at `p`, kelvin.
    pub fn temperature_at(&self, p: glam::Vec3) -> f32 {
        let (r, z, _) = self.local(p);
        self.grid.ambient_k + self.grid.theta_at(r, z)
    }

    /// Drags the particles' velocities `v` towards the air's over `h` seconds (Stokes
    /// drag with the configured time).
    pub fn drag(&self, h: f32, pos: &[glam::Vec3], v: &mut [glam::Vec3]) {
        let keep = (-h / self.params.drag_time_s).exp();
        v.par_chunks_mut(512).zip(pos.par_chunks(512)).for_each(|(v, pos)| {
            for (v, &p) in v.iter_mut().zip(pos) {
                let air = self.velocity_at(p);
                *v = air + (*v - air) * keep;
            }
        });
    }

    /// Keeps the particles out of the obstacles (see [`Obstacle`]): each
    /// moved by its velocity `vel` over the last `h` seconds to `pos`. The obstacles
    /// stand on the burner's axis; the rows of the air that hold them do not drift
    /// with the wind ([`Air::step`]), so the air has them there too.
    pub fn collide(&self, h: f32, pos: &mut [glam::Vec3], vel: &mut [glam::Vec3]) {
        let obstacles = &self.params.obstacles;
        if obstacles.is_empty() {
            return;
        }
        let axis = self.origin;
        pos.par_chunks_mut(512).zip(vel.par_chunks_mut(512)).for_each(|(pos, vel)| {
            for (x, v) in pos.iter_mut().zip(vel.iter_mut()) {
                // Out of one obstacle may be into another (a pot on stones): again,
                // a few times.
                for _ in 0..4 {
                    let mut moved = false;
                    for o in obstacles {
                        moved |= crate::obstacles::push_out(o, axis, x, v, h);
                    }
                    if !moved {
                        break;
                    }
                }
            }
        });
    }

    /// Advances the air by `h` seconds under the wind's force density `wind` (N/m³).
    pub fn step(&mut self, h: f32, wind: glam::Vec3) {
        let (nr, nz, dx) = self.grid.shape();
        // The drift and the axis's displacement: carried up at the core's mean rise
        // (first-order upwind; air enters at the ground without either), pushed by the
        // wind.
        let push = glam::Vec2::new(wind.x, wind.z) / AIR_DENSITY * h;
        // The drift forgets over DRIFT_MEMORY_S: a steady wind's force gives the air a
        // steady speed (F τ / ρ) instead of accelerating air the flame does not renew
        // (above its tip, above an obstacle) without end.
        let keep = (-h / DRIFT_MEMORY_S).exp();
        let core = self.core.min(nr);
        let rise = |j: usize| {
            let w: f32 = (0..core).map(|i| self.grid.uz[(j + 1) * nr + i]).sum::<f32>() / core as f32;
            (w.max(0.0) * h / dx).min(1.0)
        };
        let rises: Vec<f32> = (0..nz).map(rise).collect();
        for j in (0..nz).rev() {
            let (below_drift, below_offset) = if j > 0 {
                (self.drift[j - 1], self.offset[j - 1])
            } else {
                (glam::Vec2::ZERO, glam::Vec2::ZERO)
            };
            let c = rises[j];
            let (drift, offset) = (self.drift[j], self.offset[j]);
            self.drift[j] = (drift + (below_drift - drift) * c) * keep + push;
            self.offset[j] = offset + (below_offset - offset) * c;
        }
        let reach = nr as f32 * dx;
        for j in 0..nz {
            self.offset[j] = (self.offset[j] + self.drift[j] * h).clamp_length_max(reach);
        }
        // The obstacles are fixed to the ground: their rows (and the row under each,
        // whose rise they close off) stay on the burner's axis, and the rows above
        // lean from there.
        for (j, _) in self.anchored.iter().enumerate().filter(|(_, a)| **a) {
            (self.drift[j], self.offset[j]) = (glam::Vec2::ZERO, glam::Vec2::ZERO);
        }
        let n = self.grid.substeps(h, self.params.max_courant);
        for _ in 0..n {
            self.grid.step(h / n as f32, &self.burner);
        }
    }

    /// The state a checkpoint keeps.
    pub fn state(&self) -> AirState {
        AirState {
            ur: self.grid.ur.clone(),
            uz: self.grid.uz.clone(),
            theta: self.grid.theta.clone(),
            drift: self.drift.iter().map(|d| d.to_array()).collect(),
            offset: self.offset.iter().map(|d| d.to_array()).collect(),
        }
    }

    /// Continues from `state`; refused (`Err` naming the field) when its shape is not
    /// this grid's.
    pub fn restore(&mut self, state: &AirState) -> Result<(), String> {
        let g = &self.grid;
        let expect = [
            ("ur", state.ur.len(), g.ur.len()),
            ("uz", state.uz.len(), g.uz.len()),
            ("theta", state.theta.len(), g.theta.len()),
            ("drift", state.drift.len(), self.drift.len()),
            ("offset", state.offset.len(), self.offset.len()),
        ];
        if let Some((name, got, want)) = expect.iter().find(|(_, a, b)| a != b) {
            return Err(format!("air.{name} has {got} values, the grid {want}"));
        }
        let finite = state.ur.iter().chain(&state.uz).chain(&state.theta).all(|v| v.is_finite())
            && state.drift.iter().chain(&state.offset).flatten().all(|v| v.is_finite());
        if !finite {
            return Err("air has a value that is not finite".into());
        }
        // The transport only interpolates and the burner only heats: the air is never
        // colder than ambient.
        if let Some(t) = state.theta.iter().find(|&&t| t < 0.0) {
            return Err(format!("air.theta has {t} K, below ambient"));
        }
        self.grid.ur.clone_from(&state.ur);
        self.grid.uz.clone_from(&state.uz);
        self.grid.theta.clone_from(&state.theta);
        self.drift = state.drift.iter().map(|&d| glam::Vec2::from_array(d)).collect();
        self.offset = state.offset.iter().map(|&d| glam::Vec2::from_array(d)).collect();
        Ok(())
    }
}

/// The strongest frequency of `signal` (sampled every `dt` seconds) below `max_hz`,
/// and its share of the spectrum's power below `max_hz`: Welch's estimate, Hann
/// windows of `segment` samples overlapping by half, each window's mean removed. For
/// measuring a flame's puffing from the simulation (`examples/flame_puff.rs` and the
/// puffing test).
pub fn dominant_frequency(signal: &[f32], dt: f64, segment: usize, max_hz: f64) -> Option<(f64, f64)> {
    use std::f64::consts::PI;
    if segment < 4 || signal.len() < segment {
        return None;
    }
    let bins = ((max_hz * segment as f64 * dt) as usize).clamp(1, segment / 2);
    let mut power = vec![0.0f64; bins];
    let mut start = 0;
    while start + segment <= signal.len() {
        let x = &signal[start..start + segment];
        let mean = x.iter().map(|&v| f64::from(v)).sum::<f64>() / segment as f64;
        for (k, p) in power.iter_mut().enumerate() {
            let (mut re, mut im) = (0.0, 0.0);
            for (n, &v) in x.iter().enumerate() {
                let w = 0.5 - 0.5 * (2.0 * PI * n as f64 / segment as f64).cos();
                let phase = 2.0 * PI * ((k + 1) * n) as f64 / segment as f64;
                re += w * (f64::from(v) - mean) * phase.cos();
                im += w * (f64::from(v) - mean) * phase.sin();
            }
            *p += re * re + im * im;
        }
        start += segment / 2;
    }
    let total: f64 = power.iter().sum();
    let (k, best) = power.iter().enumerate().fold((0, 0.0), |b, (k, &p)| if p > b.1 { (k, p) } else { b });
    (total > 0.0).then(|| ((k + 1) as f64 / (segment as f64 * dt), best / total))
}

/// The air's part of a flame checkpoint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AirState {
    /// Radial face velocities, m/s.
    pub ur: Vec<f32>,
    /// Axial face velocities, m/s.
    pub uz: Vec<f32>,
    /// Cell temperatures above ambient, kelvin.
    pub theta: Vec<f32>,
    /// Per row: the drift velocity (x, z), m/s.
    pub drift: Vec<[f32; 2]>,
    /// Per row: the axis's displacement (x, z), m.
    pub offset: Vec<[f32; 2]>,
}

/// Ambient air density, kg/m³.
const AIR_DENSITY: f32 = 1.2;

/// Time over which the air's drift forgets the wind, seconds: a steady wind of force
/// density F moves the air no faster than F · 1 s / ρ (0.17 m/s for 0.2 N/m³).
const DRIFT_MEMORY_S: f32 = 1.0;

/// Lower index and weight of a clamped linear interpolation at `f` over `n` samples.
fn split(f: f32, n: usize) -> (usize, f32) {
    let f = f.clamp(0.0, (n - 1) as f32);
    let i = (f.floor() as usize).min(n.saturating_sub(2));
    (i, f - i as f32)
}

/// One z mode's radial system, solved in place (Thomas algorithm; the system is
/// diagonally dominant since λ < 0).
fn thomas_radial(row: &mut [f32], lambda: f32) {
    let nr = row.len();
    // The grids a configuration can ask for fit on the stack; larger ones (only through
    // `AirGrid::new`) take the heap.
    let mut stack = [0.0f32; MAX_COLUMNS];
    let mut heap = Vec::new();
    let c_prime: &mut [f32] = if nr <= MAX_COLUMNS {
        &mut stack[..nr]
    } else {
        heap.resize(nr, 0.0);
        &mut heap
    };
    let mut prev_c = 0.0f32;
    let mut prev_d = 0.0f32;
    for i in 0..nr {
        let rc = i as f32 + 0.5;
        let a = i as f32 / rc;
        let c = (i + 1) as f32 / rc;
        let mut b = lambda - a - c;
        if i == nr - 1 {
            // Ghost p_nr = -p_{nr-1}: p = 0 on the outer face.
            b -= c;
        }
        let c_here = if i + 1 < nr { c } else { 0.0 };
        let denom = b - a * prev_c;
        prev_c = c_here / denom;
        prev_d = (row[i] - a * prev_d) / denom;
        c_prime[i] = prev_c;
        row[i] = prev_d;
    }
    for i in (0..nr - 1).rev() {
        row[i] -= c_prime[i] * row[i + 1];
    }
}

/// Where a field's samples sit: `w` × `h` of them, sample (i, j) at
/// ((i + r_off)·dx, (j + z_off)·dx); `odd` fields change sign across the axis.
#[derive(Clone, Copy)]
struct Layout {
    w: usize,
    h: usize,
    r_off: f32,
    z_off: f32,
    odd: bool,
    /// Beyond the grid's outer radius and top the field is 0 (ambient air comes in),
    /// instead of the edge's value.
    ambient_outside: bool,
}

impl Layout {
    /// Position of sample n, in cells.
    fn position(&self, n: usize) -> (f32, f32) {
        ((n % self.w) as f32 + self.r_off, (n / self.w) as f32 + self.z_off)
    }

    /// The four samples around (r, z) in cells, mirrored across the axis and clamped at
    /// the grid's edges, and the weights of the second along r and z; `None` where the
    /// field is ambient (0) outside the grid.
    #[inline(always)]
    fn corners(&self, v: &[f32], r: f32, z: f32) -> Option<([f32; 4], f32, f32)> {
        let (w, h) = (self.w, self.h);
        if self.ambient_outside && (r.abs() >= w as f32 || z >= h as f32) {
            return None;
        }
        let (i, a) = split(r.abs() - self.r_off, w);
        let (j, b) = split(z - self.z_off, h);
        let i1 = (i + 1).min(w - 1);
        let j1 = (j + 1).min(h - 1);
        Some(([v[j * w + i], v[j * w + i1], v[j1 * w + i], v[j1 * w + i1]], a, b))
    }

    /// Bilinear value at (r, z) in cells ([`Layout::corners`]).
    #[inline(always)]
    fn value(&self, v: &[f32], r: f32, z: f32) -> f32 {
        let Some((c, a, b)) = self.corners(v, r, z) else { return 0.0 };
        let value = bilinear(c, a, b);
        if self.odd && r < 0.0 { -value } else { value }
    }

    /// Bilinear value, min and max of the four samples around (r, z) in cells
    /// ([`Layout::corners`]).
    fn sample(&self, v: &[f32], r: f32, z: f32) -> (f32, f32, f32) {
        let Some((c @ [v00, v10, v01, v11], a, b)) = self.corners(v, r, z) else { return (0.0, 0.0, 0.0) };
        let value = bilinear(c, a, b);
        let (lo, hi) = (v00.min(v10).min(v01).min(v11), v00.max(v10).max(v01).max(v11));
        if self.odd && r < 0.0 { (-value, -hi, -lo) } else { (value, lo, hi) }
    }
}

/// The bilinear interpolation of the corners (v00, v10, v01, v11) at weights `a` along r
/// and `b` along z.
#[inline(always)]
fn bilinear([v00, v10, v01, v11]: [f32; 4], a: f32, b: f32) -> f32 {
    (v00 * (1.0 - a) + v10 * a) * (1.0 - b) + (v01 * (1.0 - a) + v11 * a) * b
}

/// Interpolates the grid's velocity at a point given in cells.
struct Sampler<'a> {
    ur_layout: Layout,
    uz_layout: Layout,
    ur: &'a [f32],
    uz: &'a [f32],
}

impl Sampler<'_> {
    /// The velocity at (r, z), cells per second... in the fields' unit (m/s).
    #[inline]
    fn velocity(&self, r: f32, z: f32) -> (f32, f32) {
        (self.ur_layout.value(self.ur, r, z), self.uz_layout.value(self.uz, r, z))
    }

    /// Where the air at (r, z) (in cells) was `dt_cells` ago, `dt_cells` = dt/dx
    /// (midpoint rule; negative traces forward), given the velocity (u, w) there.
    #[inline]
    fn trace_from(&self, (r, z): (f32, f32), (u, w): (f32, f32), dt_cells: f32) -> (f32, f32) {
        let (rm, zm) = (r - 0.5 * dt_cells * u, z - 0.5 * dt_cells * w);
        let (u, w) = self.velocity(rm, zm);
        (r - dt_cells * u, z - dt_cells * w)
    }
}

/// MacCormack transport of the field `old` laid out as `layout` into `out` (after Selle
/// et al. 2008): a forward semi-Lagrangian step, the same step backwards from its
/// result, half the round trip's error added back, clamped to the four values the
/// forward step interpolated between. The forward step keeps, a sample, the velocity at
/// the sample (both traces start from it) and those bounds in `scratch` beside its
/// values: the backward step works them out once less.
fn mac_cormack(
    s: &Sampler<'_>,
    dt_cells: f32,
    layout: Layout,
    old: &[f32],
    (forward, kept): &mut (&mut Vec<f32>, &mut Vec<[f32; 4]>),
    out: &mut Vec<f32>,
) {
    const CH: usize = 256;
    forward.resize(old.len(), 0.0);
    kept.resize(old.len(), [0.0; 4]);
    forward.par_chunks_mut(CH).zip(kept.par_chunks_mut(CH)).enumerate().for_each(|(c, (chunk, kept))| {
        for (o, (v, k)) in chunk.iter_mut().zip(kept).enumerate() {
            let at = layout.position(c * CH + o);
            let (u, w) = s.velocity(at.0, at.1);
            let (rb, zb) = s.trace_from(at, (u, w), dt_cells);
            let (value, lo, hi) = layout.sample(old, rb, zb);
            (*v, *k) = (value, [u, w, lo, hi]);
        }
    });
    let (forward, kept) = (&**forward, &**kept);
    out.resize(old.len(), 0.0);
    out.par_chunks_mut(CH).enumerate().for_each(|(c, chunk)| {
        for (o, v) in chunk.iter_mut().enumerate() {
            let n = c * CH + o;
            let [u, w, lo, hi] = kept[n];
            let (rf, zf) = s.trace_from(layout.position(n), (u, w), -dt_cells);
            let back = layout.value(forward, rf, zf);
            *v = (forward[n] + 0.5 * (old[n] - back)).clamp(lo, hi);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hot inflow over a burner of 12 cells' diameter: after a second the hot gas rises
    /// on the axis, the air beside the burner flows in towards it (entrainment: the
    /// flame necks), and the air well outside the plume stays at ambient temperature.
    #[test]
    fn hot_gas_rises_and_draws_the_air_in_at_its_base() {
        let (cpd, d) = (12usize, 0.2f32);
        let mut a = AirGrid::new(2 * cpd, 6 * cpd, d / cpd as f32, 300.0);
        let dt = 1.0 / 60.0;
        for _ in 0..60 {
            let n = a.substeps(dt, 1.0);
            for _ in 0..n {
                let burner = Burner { cells: cpd / 2, inflow_m_s: 0.1, theta: 1600.0 };
                a.step(dt / n as f32, &burner);
            }
        }
        // Free fall over one diameter with the hot gas's buoyancy g·θ/T ≈ 0.84 g would
        // reach √(2·0.84·g·D) ≈ 1.8 m/s; friction with the air around only slows it.
        let (_, w) = a.velocity(0.0, d);
        assert!(w > 0.3 && w < 3.0, "axial velocity one diameter up {w} m/s");
        let (u, _) = a.velocity(0.75 * d, 0.25 * d);
        assert!(u < 0.0, "radial velocity beside the base {u} m/s: the air should flow in");
        assert!(
            a.theta_at(1.5 * d, 0.5 * d) < 50.0,
            "ambient air heated to {} K above ambient",
            a.theta_at(1.5 * d, 0.5 * d)
        );
    }

    /// MacCormack as Selle et al. (2008) write it, every sample worked out where it is
    /// used: each trace from scratch (two velocity samples each), the forward step's
    /// bounds sampled again in the backward step.
    fn mac_cormack_as_written(s: &Sampler<'_>, dt_cells: f32, layout: Layout, old: &[f32]) -> Vec<f32> {
        let trace = |(r, z): (f32, f32), dt: f32| {
            let (u, w) = s.velocity(r, z);
            let (rm, zm) = (r - 0.5 * dt * u, z - 0.5 * dt * w);
            let (u, w) = s.velocity(rm, zm);
            (r - dt * u, z - dt * w)
        };
        let forward: Vec<f32> = (0..old.len())
            .map(|n| {
                let (rb, zb) = trace(layout.position(n), dt_cells);
                layout.sample(old, rb, zb).0
            })
            .collect();
        (0..old.len())
            .map(|n| {
                let (rb, zb) = trace(layout.position(n), dt_cells);
                let (_, lo, hi) = layout.sample(old, rb, zb);
                let (rf, zf) = trace(layout.position(n), -dt_cells);
                let back = layout.sample(&forward, rf, zf).0;
                (forward[n] + 0.5 * (old[n] - back)).clamp(lo, hi)
            })
            .collect()
    }

    #[test]
    fn the_transport_keeps_the_bits_of_the_scheme_as_written() {
        // A rising plume's air (half a second over a burner of 12 cells): each field
        // carried by `mac_cormack` (which keeps the forward step's velocities and
        // bounds for the backward step) has the same bits as carried by the scheme
        // worked out sample by sample.
        let cpd = 12usize;
        let mut a = AirGrid::new(2 * cpd, 6 * cpd, 0.2 / cpd as f32, 300.0);
        let burner = Burner { cells: cpd / 2, inflow_m_s: 0.1, theta: 1600.0 };
        for _ in 0..60 {
            a.step(1.0 / 120.0, &burner);
        }
        let s = a.sampler();
        assert!(a.max_speed() > 0.3, "the plume moves ({} m/s)", a.max_speed());
        // The substep's own time, and one in which the fastest air crosses 30 cells:
        // then traces cross the axis (the odd field's mirror) and leave the grid (its
        // edges, the ambient air outside): 42 and 4 of theta's 3,456 when written.
        for dt_cells in [1.0 / 120.0 / a.dx, 30.0 / a.max_speed()] {
            let fields = [(a.ur_layout(), &a.ur), (a.uz_layout(), &a.uz), (a.theta_layout(), &a.theta)];
            // Where the traces from theta's samples end, both ways.
            let ends: Vec<(f32, f32)> = (0..a.theta.len())
                .flat_map(|n| {
                    let at = a.theta_layout().position(n);
                    let v = s.velocity(at.0, at.1);
                    [s.trace_from(at, v, dt_cells), s.trace_from(at, v, -dt_cells)]
                })
                .collect();
            let across = ends.iter().filter(|e| e.0 < 0.0).count();
            let outside = ends.iter().filter(|e| e.0 >= a.nr as f32 || e.1 >= a.nz as f32).count();
            if dt_cells > 1.0 / 120.0 / a.dx {
                assert!(
                    across > 0 && outside > 0,
                    "{across} traces across the axis, {outside} out of the grid"
                );
            }
            for (layout, field) in fields {
                let (mut forward, mut kept, mut out) = (Vec::new(), Vec::new(), Vec::new());
                mac_cormack(&s, dt_cells, layout, field, &mut (&mut forward, &mut kept), &mut out);
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&out), bits(&mac_cormack_as_written(&s, dt_cells, layout, field)));
            }
        }
    }

    #[test]
    fn the_grid_is_bounded_and_its_problems_are_named() {
        let mut i = Issues::default();
        AirParams::default().validate("air.", &mut i);
        assert!(i.is_empty());
        let p = AirParams {
            cells_per_diameter: 128,
            height_diameters: 32.0,
            radius_diameters: 4.0,
            ..Default::default()
        };
        let mut i = Issues::default();
        p.validate("air.", &mut i);
        let fields: Vec<String> = i.into_result().unwrap_err().into_iter().map(|e| e.field).collect();
        assert_eq!(fields, ["air.height_diameters", "air.radius_diameters"]);
    }

    #[test]
    fn projection_leaves_no_divergence() {
        let mut a = AirGrid::new(16, 40, 0.01, 300.0);
        // A hot blob and an arbitrary swirl of velocity.
        for j in 0..40 {
            for i in 0..16 {
                let c = j * 16 + i;
                a.theta[c] = if (i as i32 - 3).pow(2) + (j as i32 - 10).pow(2) < 16 { 900.0 } else { 0.0 };
                a.uz[c] = ((i * 7 + j * 3) % 11) as f32 * 0.1;
            }
        }
        for j in 0..40 {
            for i in 1..=16 {
                a.ur[j * 17 + i] = ((i * 5 + j) % 7) as f32 * 0.1 - 0.3;
            }
        }
        assert!(a.max_divergence() > 0.1);
        a.step(1.0 / 120.0, &Burner { cells: 0, inflow_m_s: 0.0, theta: 0.0 });
        // Rounding of f32 sums over 40 modes of order-1 values: well under 1e-4 m/s.
        assert!(a.max_divergence() < 1e-4, "divergence {}", a.max_divergence());
    }

    /// A grid of `nr` × `nz` cells with a hot blob and an arbitrary swirl.
    fn stirred(nr: usize, nz: usize) -> AirGrid {
        let mut a = AirGrid::new(nr, nz, 0.01, 300.0);
        for j in 0..nz {
            for i in 0..nr {
                let c = j * nr + i;
                a.theta[c] = if (i as i32 - 3).pow(2) + (j as i32 - 10).pow(2) < 16 { 900.0 } else { 0.0 };
                a.uz[c] = ((i * 7 + j * 3) % 11) as f32 * 0.1;
            }
            for i in 1..=nr {
                a.ur[j * (nr + 1) + i] = ((i * 5 + j) % 7) as f32 * 0.1 - 0.3;
            }
        }
        a
    }

    /// Around a plate over the axis and a ring on the ground the projection leaves no
    /// divergence in the air's cells, and no air crosses a solid cell's faces.
    #[test]
    fn projection_around_solids_leaves_no_divergence() {
        let (nr, nz) = (16, 40);
        let mut a = stirred(nr, nz);
        let plate = Obstacle { inner_radius_m: 0.0, outer_radius_m: 0.06, bottom_m: 0.2, top_m: 0.22 };
        let ring = Obstacle { inner_radius_m: 0.1, outer_radius_m: 0.12, bottom_m: 0.0, top_m: 0.05 };
        a.set_solid(crate::obstacles::solid_cells(&[plate, ring], nr, nz, 0.01));
        let solid = (0..nr * nz).filter(|&c| a.is_solid(c % nr, c / nr)).count();
        assert_eq!(solid, 6 * 2 + 2 * 5, "the plate's and the ring's cells");
        a.step(1.0 / 120.0, &Burner { cells: 0, inflow_m_s: 0.0, theta: 0.0 });
        let s = a.solids.as_ref().unwrap();
        let mut worst = 0.0f32;
        for j in 0..nz {
            for i in 0..nr {
                if !s.cell[j * nr + i] {
                    worst = worst.max(a.divergence(i, j).abs());
                }
            }
        }
        // Rounding of f32 sums, as for the open grid: well under 1e-4 m/s.
        assert!(worst < 1e-4, "divergence {worst}");
        let shut = |open: &[bool], u: &[f32]| open.iter().zip(u).all(|(&o, &u)| o || u == 0.0);
        assert!(shut(&s.ur_open, &a.ur) && shut(&s.uz_open, &a.uz), "air through a solid face");
    }
}
