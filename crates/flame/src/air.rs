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
//! Each substep: the velocity and the temperature excess are carried by the flow
//! (semi-Lagrangian with a MacCormack correction, clamped to the values it interpolated
//! between, after Selle et al. 2008, so the roll-up is not smeared away), the buoyancy
//! and the particles' momentum and heat are added, and the velocity is projected to zero
//! divergence. The projection is exact, not iterated: the pressure Poisson equation is
//! diagonalised along z by the cosine modes of its boundary conditions (a wall at the
//! ground, open air at the top) and each mode is a tridiagonal system along r (the axis,
//! and open air at the outer radius, where the entrained air comes in).

use phenomena_core::validate::Issues;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Standard gravity, m/s².
const G: f32 = 9.81;

/// The air's parameters, the `[flame.extended.air]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AirParams {
    /// Solve the air around the flame (extended mode only). Off by default: the air
    /// rises, entrains and carries the particles, but with these defaults it does not
    /// yet puff at the frequency of real fires over the range of burner sizes issue 43
    /// asks for (see `examples/flame_puff.rs` and docs/phenomena.md); it costs 20-40 ms
    /// a frame.
    pub enabled: bool,
    /// Grid cells across the burner's diameter.
    pub cells_per_diameter: u32,
    /// Radius of the air's cylinder, in burner diameters.
    pub radius_diameters: f32,
    /// Height of the air's cylinder above the burner, in burner diameters.
    pub height_diameters: f32,
    /// Time over which a particle takes up the air's velocity, seconds (Stokes drag).
    pub drag_time_s: f32,
    /// Heat the fire releases per square metre of burner, kW/m² (pool fires of liquid
    /// fuels release about 500-3000 kW/m²). It is shared by the particles born each
    /// second, so each particle's heat falls as the emission rate rises.
    pub heat_release_kw_m2: f32,
    /// Mean time over which a particle releases its heat into the air (exponentially,
    /// from its birth), seconds.
    pub burn_time_s: f32,
    /// Largest Courant number of one air substep (cells crossed in one substep).
    pub max_courant: f32,
}

impl Default for AirParams {
    fn default() -> Self {
        Self {
            enabled: false,
            cells_per_diameter: 24,
            radius_diameters: 2.0,
            height_diameters: 8.0,
            drag_time_s: 0.02,
            heat_release_kw_m2: 1000.0,
            burn_time_s: 0.25,
            max_courant: 1.0,
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
        i.range(&format!("{prefix}heat_release_kw_m2"), self.heat_release_kw_m2, 0.0..=100_000.0);
        i.range_open_low(&format!("{prefix}burn_time_s"), self.burn_time_s, 0.0, 100.0);
        i.range(&format!("{prefix}max_courant"), self.max_courant, 0.1..=4.0);
    }
}

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
}

/// Where the particles put heat and momentum, per cell (`[j * nr + i]`), gathered by
/// [`AirGrid::deposit`].
#[derive(Clone, Debug, Default)]
pub struct Deposit {
    /// Σ weight·m of the particles, kg.
    pub mass: Vec<f32>,
    /// Σ weight·(heat the particle releases per second), W.
    pub heat: Vec<f32>,
    /// Σ weight·m·Δv of the particles' drag this substep, radial and axial, kg·m/s.
    pub impulse_r: Vec<f32>,
    /// Axial part of `impulse_r`'s sum.
    pub impulse_z: Vec<f32>,
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
        }
    }

    /// Cells along r and z, and the cell size in metres.
    pub fn shape(&self) -> (usize, usize, f32) {
        (self.nr, self.nz, self.dx)
    }

    /// Ambient temperature, kelvin.
    pub fn ambient_k(&self) -> f32 {
        self.ambient_k
    }

    /// Temperature above ambient of cell (i, j), kelvin.
    pub fn theta(&self, i: usize, j: usize) -> f32 {
        self.theta[j * self.nr + i]
    }

    /// Sets the temperature above ambient of cell (i, j), kelvin.
    pub fn set_theta(&mut self, i: usize, j: usize, kelvin: f32) {
        self.theta[j * self.nr + i] = kelvin;
    }

    /// Sets the axial velocity of the ground face under cell i (an inflow), m/s.
    pub fn set_inflow(&mut self, i: usize, m_s: f32) {
        self.uz[i] = m_s;
    }

    /// The air's velocity (radial, axial) at distance `r` from the axis and height `z`
    /// above the ground, m/s (held at the grid's edge values outside it).
    pub fn velocity(&self, r: f32, z: f32) -> (f32, f32) {
        self.sampler().velocity(r / self.dx, z / self.dx)
    }

    /// The air's temperature above ambient at (r, z), kelvin.
    pub fn theta_at(&self, r: f32, z: f32) -> f32 {
        self.theta_layout().sample(&self.theta, r / self.dx, z / self.dx).0
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

    /// One substep of `dt` seconds: transport, buoyancy, the particles' `deposit` (heat
    /// released, up to `theta_cap` kelvin above ambient; their drag's reaction), projection.
    /// `impulse_share` is the part of the deposit's impulse this substep takes (the
    /// particles' drag is gathered once for several air substeps).
    pub fn step(&mut self, dt: f32, deposit: Option<&Deposit>, theta_cap: f32, impulse_share: f32) {
        self.advect(dt);
        if let Some(d) = deposit {
            self.take(d, dt, theta_cap, impulse_share);
        }
        self.buoyancy(dt);
        // The axis carries no radial flow.
        for j in 0..self.nz {
            self.ur[j * (self.nr + 1)] = 0.0;
        }
        self.project(dt);
    }

    /// Carries ur, uz and θ along the flow for `dt` (MacCormack, clamped).
    fn advect(&mut self, dt: f32) {
        let nr = self.nr;
        let dt_cells = dt / self.dx;
        let [mut forward, mut ur, mut uz, mut theta] = std::mem::take(&mut self.scratch);
        {
            let s = self.sampler();
            mac_cormack(&s, dt_cells, self.ur_layout(), &self.ur, &mut forward, &mut ur);
            mac_cormack(&s, dt_cells, self.uz_layout(), &self.uz, &mut forward, &mut uz);
            mac_cormack(&s, dt_cells, self.theta_layout(), &self.theta, &mut forward, &mut theta);
        }
        // The ground's faces keep their boundary values.
        uz[..nr].copy_from_slice(&self.uz[..nr]);
        std::mem::swap(&mut self.ur, &mut ur);
        std::mem::swap(&mut self.uz, &mut uz);
        std::mem::swap(&mut self.theta, &mut theta);
        self.scratch = [forward, ur, uz, theta];
    }

    /// The particles' heat warms the air (ρ·c_p of ambient air per kelvin, up to the
    /// flame's temperature: where more heat would be released, there is no air left to
    /// burn it with), and their drag's reaction pushes the air.
    fn take(&mut self, d: &Deposit, dt: f32, theta_cap: f32, impulse_share: f32) {
        let (nr, nz, dx) = (self.nr, self.nz, self.dx);
        for j in 0..nz {
            for i in 0..nr {
                let c = j * nr + i;
                if d.heat[c] > 0.0 {
                    let warming = d.heat[c] * dt / (AIR_DENSITY * AIR_HEAT_CAPACITY * cell_volume(i, dx));
                    self.theta[c] = (self.theta[c] + warming).min(theta_cap.max(self.theta[c]));
                }
            }
        }
        // Impulses are in the cells; each face takes the mean of its two cells'. The
        // particles' mass joins the air's in the denominator: where they outweigh the
        // air, the air moves at most to their velocity instead of overshooting it (an
        // explicit exchange with heavier particles would be unstable).
        for j in 0..nz {
            for i in 1..nr {
                let (a, b) = (j * nr + i - 1, j * nr + i);
                let air = AIR_DENSITY * 0.5 * (cell_volume(i - 1, dx) + cell_volume(i, dx));
                let mass = (air + 0.5 * (d.mass[a] + d.mass[b])) / impulse_share;
                self.ur[j * (nr + 1) + i] -= 0.5 * (d.impulse_r[a] + d.impulse_r[b]) / mass;
            }
        }
        for j in 1..nz {
            for i in 0..nr {
                let (a, b) = ((j - 1) * nr + i, j * nr + i);
                let air = AIR_DENSITY * cell_volume(i, dx);
                let mass = (air + 0.5 * (d.mass[a] + d.mass[b])) / impulse_share;
                self.uz[j * nr + i] -= 0.5 * (d.impulse_z[a] + d.impulse_z[b]) / mass;
            }
        }
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
                let (ri, ro) = (i as f32, (i + 1) as f32);
                let rc = i as f32 + 0.5;
                let div_r = (ro * self.ur[j * (nr + 1) + i + 1] - ri * self.ur[j * (nr + 1) + i]) / rc;
                let div_z = self.uz[(j + 1) * nr + i] - self.uz[j * nr + i];
                rhs[j * nr + i] = (div_r + div_z) * scale;
            }
        }
        let p = self.solve_poisson(&rhs);
        // u -= dt ∇p, with p in units where ∇ is a plain difference: p·dt/dx² scaled.
        let g = dt * inv_dx;
        for j in 0..nz {
            for i in 1..=nr {
                let outer = if i < nr { p[j * nr + i] } else { -p[j * nr + nr - 1] };
                self.ur[j * (nr + 1) + i] -= g * (outer - p[j * nr + i - 1]);
            }
        }
        for j in 1..=nz {
            for i in 0..nr {
                let above = if j < nz { p[j * nr + i] } else { -p[(nz - 1) * nr + i] };
                self.uz[j * nr + i] -= g * (above - p[(j - 1) * nr + i]);
            }
        }
        self.scratch[0] = rhs;
        self.scratch[3] = p;
    }

    /// p with L p = rhs, L the 5-point cylindrical Laplacian times dx² (axis: no flux;
    /// outer radius and top: p = 0 on the boundary face; ground: no flux).
    fn solve_poisson(&mut self, rhs: &[f32]) -> Vec<f32> {
        let (nr, nz) = (self.nr, self.nz);
        // Into the z modes: rhs_k(i) = (2/nz) Σ_j C[k][j] rhs(j, i).
        let mut hat = vec![0.0f32; nz * nr];
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
        p
    }

    /// Largest |∇·u|·dx over the cells, m/s: zero up to rounding after a projection.
    pub fn max_divergence(&self) -> f32 {
        let nr = self.nr;
        let mut worst = 0.0f32;
        for j in 0..self.nz {
            for i in 0..nr {
                let (ri, ro, rc) = (i as f32, (i + 1) as f32, i as f32 + 0.5);
                let div_r = (ro * self.ur[j * (nr + 1) + i + 1] - ri * self.ur[j * (nr + 1) + i]) / rc;
                let div_z = self.uz[(j + 1) * nr + i] - self.uz[j * nr + i];
                worst = worst.max((div_r + div_z).abs());
            }
        }
        worst
    }

    /// Spreads one particle at (r, z) over the cells by bilinear weights: the heat it
    /// releases per second (W) and the impulse it took from the air this substep.
    pub fn deposit(&self, d: &mut Deposit, r: f32, z: f32, mass: f32, power_w: f32, impulse: (f32, f32)) {
        let (nr, nz) = (self.nr, self.nz);
        let fr = r / self.dx - 0.5;
        let fz = z / self.dx - 0.5;
        if !(fr < nr as f32 && fz < nz as f32 && fz > -1.0) {
            return;
        }
        let (i0, wr) = split(fr, nr);
        let (j0, wz) = split(fz, nz);
        for (dj, wj) in [(0, 1.0 - wz), (1, wz)] {
            for (di, wi) in [(0, 1.0 - wr), (1, wr)] {
                let (i, j) = ((i0 + di).min(nr - 1), (j0 + dj).min(nz - 1));
                let w = wi * wj;
                let c = j * nr + i;
                d.mass[c] += w * mass;
                d.heat[c] += w * power_w;
                d.impulse_r[c] += w * impulse.0;
                d.impulse_z[c] += w * impulse.1;
            }
        }
    }

    /// An empty deposit for this grid.
    pub fn clear_deposit(&self, d: &mut Deposit) {
        for v in [&mut d.mass, &mut d.heat, &mut d.impulse_r, &mut d.impulse_z] {
            v.clear();
            v.resize(self.nr * self.nz, 0.0);
        }
    }
}

/// The air coupled to a flame: the grid on the burner's axis, the particles' deposit,
/// and the wind's drift of the air column.
///
/// The grid is axisymmetric, so the wind cannot blow across it; instead each row of the
/// grid carries a horizontal drift velocity, pushed by the wind's force density (as the
/// air's, ρ = 1.2 kg/m³) and carried up with the air rising in the flame's core, and the
/// row's axis is displaced by the drift it has accumulated. Air entering at the ground
/// has no drift, so the column leans with the time its air has spent in the wind, as a
/// plume in a crossflow does; the grid's own flow (the necking, the vortex rings) is
/// solved about the leaning axis.
#[derive(Clone, Debug)]
pub struct Air {
    grid: AirGrid,
    deposit: Deposit,
    /// The burner's centre: the axis's foot and the ground's height.
    origin: glam::Vec3,
    /// Per row: the air's horizontal drift velocity (x, z), m/s.
    drift: Vec<glam::Vec2>,
    /// Per row: the axis's horizontal displacement from the burner's centre (x, z), m.
    offset: Vec<glam::Vec2>,
    /// Cells within the burner's radius (the flame's core, whose rise carries the drift).
    core: usize,
    /// Heat each particle releases over its life, J.
    particle_heat_j: f32,
    /// The flame's temperature above ambient: the most the air is heated to, kelvin.
    theta_cap: f32,
    params: AirParams,
}

impl Air {
    /// The air for a burner of `radius_m` at `origin` in air at `ambient_k`, emitting
    /// `rate_per_s` particles born at `flame_k`; the burner's gas enters the air at
    /// `inflow_m_s` upwards (the fuel's volume displaces air).
    pub fn new(params: &AirParams, burner: &crate::config::Emitter, ambient_k: f32) -> Self {
        let (origin, radius_m, rate_per_s, flame_k) =
            (burner.position_m, burner.radius_m, burner.rate_per_s, burner.temperature_k);
        let inflow_m_s = burner.velocity_m_s.y.max(0.0);
        let power_w = params.heat_release_kw_m2 * 1e3 * std::f32::consts::PI * radius_m * radius_m;
        let cpd = params.cells_per_diameter as usize;
        let dx = 2.0 * radius_m / cpd as f32;
        let nr = ((params.radius_diameters * cpd as f32).round() as usize).max(2);
        let nz = ((params.height_diameters * cpd as f32).round() as usize).max(2);
        let mut grid = AirGrid::new(nr, nz, dx, ambient_k);
        for i in 0..nr {
            if (i as f32 + 0.5) * dx < radius_m {
                grid.set_inflow(i, inflow_m_s);
            }
        }
        Self {
            grid,
            deposit: Deposit::default(),
            origin,
            drift: vec![glam::Vec2::ZERO; nz],
            offset: vec![glam::Vec2::ZERO; nz],
            core: (cpd / 2).max(1),
            particle_heat_j: if rate_per_s > 0.0 { power_w / rate_per_s } else { 0.0 },
            theta_cap: (flame_k - ambient_k).max(0.0),
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
    /// drag with the configured time), and gathers the heat they release at their `age`
    /// and the impulse the air gave them into this substep's deposit.
    pub fn drag(&mut self, h: f32, pos: &[glam::Vec3], v: &mut [glam::Vec3], mass: &[f32], age: &[f32]) {
        let keep = (-h / self.params.drag_time_s).exp();
        let mut deposit = std::mem::take(&mut self.deposit);
        self.grid.clear_deposit(&mut deposit);
        let tau = self.params.burn_time_s;
        let rate = self.particle_heat_j / tau;
        for i in 0..pos.len() {
            let (r, z, dir) = self.local(pos[i]);
            let (ur, uz) = self.grid.velocity(r, z);
            let drift = self.drift[self.row(z)];
            let air = glam::Vec3::new(dir.x * ur + drift.x, uz, dir.y * ur + drift.y);
            let new = air + (v[i] - air) * keep;
            let dv = new - v[i];
            v[i] = new;
            let radial = dv.x * dir.x + dv.z * dir.y;
            let power = rate * (-age[i] / tau).exp();
            self.grid.deposit(&mut deposit, r, z, mass[i], power, (mass[i] * radial, mass[i] * dv.y));
        }
        self.deposit = deposit;
    }

    /// Advances the air by `h` seconds under the wind's force density `wind` (N/m³),
    /// with this substep's deposit.
    pub fn step(&mut self, h: f32, wind: glam::Vec3) {
        let (nr, nz, dx) = self.grid.shape();
        // The drift and the axis's displacement: carried up at the core's mean rise
        // (first-order upwind; air enters at the ground without either), pushed by the
        // wind.
        let push = glam::Vec2::new(wind.x, wind.z) / AIR_DENSITY * h;
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
            self.drift[j] = drift + (below_drift - drift) * c + push;
            self.offset[j] = offset + (below_offset - offset) * c;
        }
        for j in 0..nz {
            self.offset[j] += self.drift[j] * h;
        }
        let n = self.grid.substeps(h, self.params.max_courant);
        for _ in 0..n {
            self.grid.step(h / n as f32, Some(&self.deposit), self.theta_cap, 1.0 / n as f32);
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
        let finite = state.ur.iter().chain(&state.uz).chain(&state.theta).all(|v| v.is_finite());
        if !finite {
            return Err("air has a value that is not finite".into());
        }
        self.grid.ur.clone_from(&state.ur);
        self.grid.uz.clone_from(&state.uz);
        self.grid.theta.clone_from(&state.theta);
        self.drift = state.drift.iter().map(|&d| glam::Vec2::from_array(d)).collect();
        self.offset = state.offset.iter().map(|&d| glam::Vec2::from_array(d)).collect();
        Ok(())
    }
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
/// Specific heat of air at constant pressure, J/(kg·K).
const AIR_HEAT_CAPACITY: f32 = 1005.0;

/// Volume of the ring of cells at radial index i, per dx³ times dx³.
fn cell_volume(i: usize, dx: f32) -> f32 {
    2.0 * std::f32::consts::PI * (i as f32 + 0.5) * dx * dx * dx
}

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
    let mut c_prime = vec![0.0f32; nr];
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

    /// Bilinear value, min and max of the four samples around (r, z) in cells,
    /// mirrored across the axis and clamped at the grid's edges.
    fn sample(&self, v: &[f32], r: f32, z: f32) -> (f32, f32, f32) {
        let (w, h) = (self.w, self.h);
        if self.ambient_outside && (r.abs() >= w as f32 || z >= h as f32) {
            return (0.0, 0.0, 0.0);
        }
        let (i, a) = split(r.abs() - self.r_off, w);
        let (j, b) = split(z - self.z_off, h);
        let i1 = (i + 1).min(w - 1);
        let j1 = (j + 1).min(h - 1);
        let (v00, v10, v01, v11) = (v[j * w + i], v[j * w + i1], v[j1 * w + i], v[j1 * w + i1]);
        let value = (v00 * (1.0 - a) + v10 * a) * (1.0 - b) + (v01 * (1.0 - a) + v11 * a) * b;
        let (lo, hi) = (v00.min(v10).min(v01).min(v11), v00.max(v10).max(v01).max(v11));
        if self.odd && r < 0.0 { (-value, -hi, -lo) } else { (value, lo, hi) }
    }
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
    fn velocity(&self, r: f32, z: f32) -> (f32, f32) {
        (self.ur_layout.sample(self.ur, r, z).0, self.uz_layout.sample(self.uz, r, z).0)
    }

    /// Where the air at (r, z) (in cells) was `dt_cells` ago, `dt_cells` = dt/dx
    /// (midpoint rule; negative traces forward).
    fn trace(&self, r: f32, z: f32, dt_cells: f32) -> (f32, f32) {
        let (u, w) = self.velocity(r, z);
        let (rm, zm) = (r - 0.5 * dt_cells * u, z - 0.5 * dt_cells * w);
        let (u, w) = self.velocity(rm, zm);
        (r - dt_cells * u, z - dt_cells * w)
    }
}

/// MacCormack transport of the field `old` laid out as `layout` into `out` (after Selle
/// et al. 2008): a forward semi-Lagrangian step, the same step backwards from its
/// result, half the round trip's error added back, clamped to the four values the
/// forward step interpolated between.
fn mac_cormack(
    s: &Sampler<'_>,
    dt_cells: f32,
    layout: Layout,
    old: &[f32],
    forward: &mut Vec<f32>,
    out: &mut Vec<f32>,
) {
    const CH: usize = 256;
    forward.resize(old.len(), 0.0);
    forward.par_chunks_mut(CH).enumerate().for_each(|(c, chunk)| {
        for (o, v) in chunk.iter_mut().enumerate() {
            let (r, z) = layout.position(c * CH + o);
            let (rb, zb) = s.trace(r, z, dt_cells);
            *v = layout.sample(old, rb, zb).0;
        }
    });
    let forward = &*forward;
    out.resize(old.len(), 0.0);
    out.par_chunks_mut(CH).enumerate().for_each(|(c, chunk)| {
        for (o, v) in chunk.iter_mut().enumerate() {
            let n = c * CH + o;
            let (r, z) = layout.position(n);
            let (rb, zb) = s.trace(r, z, dt_cells);
            let (_, lo, hi) = layout.sample(old, rb, zb);
            let (rf, zf) = s.trace(r, z, -dt_cells);
            let back = layout.sample(forward, rf, zf).0;
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
                for i in 0..cpd / 2 {
                    a.set_inflow(i, 0.1);
                    a.set_theta(i, 0, 1600.0);
                }
                a.step(dt / n as f32, None, 2000.0, 1.0);
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

    /// A particle's heat and impulse are spread with weights that sum to one.
    #[test]
    fn a_deposit_keeps_what_the_particle_gives() {
        let a = AirGrid::new(8, 8, 0.01, 300.0);
        let mut d = Deposit::default();
        a.clear_deposit(&mut d);
        for (r, z) in [(0.0, 0.0), (0.003, 0.02), (0.031, 0.047), (0.079, 0.079)] {
            a.deposit(&mut d, r, z, 1e-5, 2.0, (0.5, -0.25));
        }
        let sum = |v: &[f32]| v.iter().map(|&x| f64::from(x)).sum::<f64>();
        // Four particles; f32 weights that sum to one up to rounding.
        assert!((sum(&d.heat) - 8.0).abs() < 1e-5);
        assert!((sum(&d.mass) - 4e-5).abs() < 1e-10);
        assert!((sum(&d.impulse_r) - 2.0).abs() < 1e-5);
        assert!((sum(&d.impulse_z) + 1.0).abs() < 1e-5);
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
        a.step(1.0 / 120.0, None, 2000.0, 1.0);
        // Rounding of f32 sums over 40 modes of order-1 values: well under 1e-4 m/s.
        assert!(a.max_divergence() < 1e-4, "divergence {}", a.max_divergence());
    }
}
