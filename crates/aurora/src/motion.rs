//! Charged-particle motion in the x-z plane (thesis §2.3): the Lorentz force from the
//! shape's electric field and the y-directed magnetic field (eq 2.10), a pseudo-Coulomb
//! repulsion computed as an SPH pressure force (eq 2.11-2.18), and the position and
//! velocity updates of eq (2.19)-(2.20) followed by a speed limit.

use glam::Vec2;
use phenomena_core::grid::{GridError, NeighborGrid};
use phenomena_core::kernel::{Dim, Kernel, KernelKind};
use phenomena_core::neighbors::{NeighborLists, TooManyNeighbors};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::config::{CoulombKernels, MotionParams};
use crate::field::Grid;

/// Particles per parallel work item (fixed, so results do not depend on thread count).
const CHUNK: usize = 1024;
/// Most neighbours a particle may have within the support radius; more means particles
/// piled on each other and a step quadratic in their number.
pub const MAX_NEIGHBORS: usize = 4096;

/// Why a motion step failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MotionError {
    /// The neighbour grid could not be built.
    #[error("neighbour search failed")]
    Grid(#[from] GridError),
    /// Too many particles within one support radius.
    #[error("particles are packed too densely")]
    TooDense(#[source] TooManyNeighbors),
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

/// Reusable buffers of the motion step.
#[derive(Clone, Debug)]
pub struct MotionScratch {
    grid: NeighborGrid,
    lists: NeighborLists,
    density: Vec<f32>,
    inv_2density: Vec<f32>,
    pressure: Vec<f32>,
    accel: Vec<Vec2>,
    tmp2: Vec<Vec2>,
    tmp_id: Vec<u64>,
}

impl Default for MotionScratch {
    fn default() -> Self {
        Self {
            grid: NeighborGrid::default(),
            lists: NeighborLists::new(CHUNK),
            density: Vec::new(),
            inv_2density: Vec::new(),
            pressure: Vec::new(),
            accel: Vec::new(),
            tmp2: Vec::new(),
            tmp_id: Vec::new(),
        }
    }
}

impl MotionScratch {
    /// SPH density of each particle from the last step (particles per km², unit mass).
    pub fn density(&self) -> &[f32] {
        &self.density
    }
}

/// One motion step: sort particles by cell, SPH density δ (eq 2.11) and pressure
/// p = k(δ - δ0) (eq 2.13), the pseudo-Coulomb force (eq 2.14), the Lorentz force with E
/// interpolated bilinearly (eq 2.10), then eq (2.19)-(2.20) with the weights w_L, w_P,
/// and the velocity normalisation (damping, then the speed limit). Particles leaving the
/// plane are removed; returns how many.
pub fn step(
    p: &mut Particles,
    model: &ForceModel,
    field_grid: &Grid,
    e_field: &[Vec2],
    rest_density: f32,
    s: &mut MotionScratch,
) -> Result<usize, MotionError> {
    let h = model.support_km();
    s.grid.build(&p.position_km, h / 2.0)?;
    // Reorder into cell order: runs of cells become contiguous index ranges.
    s.grid.gather(&p.position_km, &mut s.tmp2);
    std::mem::swap(&mut p.position_km, &mut s.tmp2);
    s.grid.gather(&p.velocity_km_s, &mut s.tmp2);
    std::mem::swap(&mut p.velocity_km_s, &mut s.tmp2);
    s.grid.gather(&p.id, &mut s.tmp_id);
    std::mem::swap(&mut p.id, &mut s.tmp_id);
    s.grid.mark_points_sorted();

    let n = p.len();
    s.lists.build(&p.position_km, &s.grid, 2, h, MAX_NEIGHBORS).map_err(MotionError::TooDense)?;
    let (pos, lists) = (&p.position_km, &s.lists);
    s.density.resize(n, 0.0);
    s.pressure.resize(n, 0.0);
    let (kd, k, rho0) = (model.density, model.gas_constant, rest_density);
    s.density
        .par_chunks_mut(CHUNK)
        .zip(s.pressure.par_chunks_mut(CHUNK))
        .zip(lists.chunks().par_iter())
        .for_each(|((d, pr), list)| {
            for o in 0..d.len() {
                // eq (2.11): δ_i = Σ_j m_j W(x_j - x_i), unit mass.
                let (_, dist) = list.neighbors(o);
                let sum: f32 = dist.iter().map(|&r| kd.value(r)).sum();
                d[o] = sum;
                pr[o] = k * (sum - rho0); // eq (2.13)
            }
        });

    // 1/(2δ_j) once per particle rather than a division per pair.
    s.inv_2density.clear();
    s.inv_2density.extend(s.density.iter().map(|&d| 0.5 / d));
    let (inv2d, pres, vel) = (&s.inv_2density, &s.pressure, &p.velocity_km_s);
    let kg = model.gradient;
    s.accel.resize(n, Vec2::ZERO);
    s.accel.par_chunks_mut(CHUNK).zip(lists.chunks().par_iter()).enumerate().for_each(|(c, (out, list))| {
        for (o, a) in out.iter_mut().enumerate() {
            let i = c * CHUNK + o;
            let xi = pos[i];
            let pi = pres[i];
            let (idx, dist) = list.neighbors(o);
            let mut f = Vec2::ZERO;
            for (&j, &r) in idx.iter().zip(dist) {
                let j = j as usize;
                // eq (2.14): F_P = Σ m_j (p_i + p_j)/(2 δ_j) ∇W(x_j - x_i); ∇W points from
                // j to i (g < 0), so positive pressure repels. The self-pair has g = 0.
                f += (pos[j] - xi) * ((pi + pres[j]) * inv2d[j] * kg.gradient_factor(r));
            }
            let lorentz = model.lorentz(field_grid.interpolate(e_field, xi), vel[i]);
            *a = lorentz * model.weight_lorentz + f * model.weight_coulomb;
        }
    });

    // eq (2.19)-(2.20), then damping and the speed limit.
    let (dt, vmax, damping) = (model.dt, model.max_speed, model.damping);
    let accel = &s.accel;
    p.position_km.par_chunks_mut(CHUNK).zip(p.velocity_km_s.par_chunks_mut(CHUNK)).enumerate().for_each(
        |(c, (x, v))| {
            for o in 0..x.len() {
                let a = accel[c * CHUNK + o];
                x[o] += v[o] * dt + a * (0.5 * dt * dt);
                v[o] = (v[o] + a * dt) * damping;
                let speed = v[o].length();
                if speed > vmax {
                    v[o] *= vmax / speed;
                }
            }
        },
    );
    // Particles that left the plane (or became non-finite) are removed.
    let extent = field_grid.extent_km();
    let origin = field_grid.origin_km;
    let keep: Vec<bool> = p
        .position_km
        .iter()
        .map(|&x| x.is_finite() && x.cmpge(origin).all() && x.cmplt(origin + extent).all())
        .collect();
    let removed = keep.iter().filter(|k| !**k).count();
    if removed > 0 {
        p.retain(&keep);
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane() -> (Grid, Vec<Vec2>) {
        let g = Grid { nx: 16, nz: 16, origin_km: Vec2::ZERO, cell_km: 1.0 };
        (g, vec![Vec2::ZERO; 256])
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
