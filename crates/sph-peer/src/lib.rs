//! The shared setup of the SPH peer benchmark: one particle block, two solvers.
//!
//! Both solvers get the same 3-D block of particles (a jittered lattice with spacing
//! d/2, where d is the kernel support radius), zero gravity and one step of 1/60 s per
//! call. What differs, and why a ratio of step times is only indicative:
//! - phenomena's flame is weakly compressible SPH (equation of state p = k(ρ - ρ0), one
//!   density pass and one force pass per step, paper eq 3, 11, 12);
//! - salva3d 0.11 offers only incompressible solvers; we use DFSPH, which iterates a
//!   divergence solve and a density solve until their error tolerances are met (at
//!   least one iteration each), with the cubic-spline kernel.

use glam::Vec3;
use nalgebra::Vector3;
use phenomena_core::rng::{Purpose, Stream};
use phenomena_flame::{FlameConfig, FlameSim, Mode};
use salva3d::LiquidWorld;
use salva3d::object::{Fluid, interaction_groups::InteractionGroups};
use salva3d::solver::DFSPHSolver;

/// Support radius shared by both solvers, metres.
pub const SUPPORT_M: f32 = 0.04;
/// Rest density shared by both solvers, kg/m³.
pub const REST_DENSITY: f32 = 1.0;

/// A jittered lattice of about `n` particles with spacing d/2.
pub fn block(n: usize) -> Vec<Vec3> {
    let side = (n as f32).cbrt().round() as usize;
    let spacing = SUPPORT_M / 2.0;
    let mut rng = Stream::new(1, Purpose::named("peer.block"), 0);
    let mut out = Vec::with_capacity(side * side * side);
    for i in 0..side {
        for j in 0..side {
            for k in 0..side {
                let jitter =
                    Vec3::new(rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05));
                out.push((Vec3::new(i as f32, j as f32, k as f32) + jitter) * spacing);
            }
        }
    }
    out
}

/// phenomena's flame SPH over the block: paper mode, no emission, no wind.
pub fn ours(points: &[Vec3]) -> FlameSim {
    let mut config = FlameConfig { mode: Mode::Paper, ..Default::default() };
    config.emitter.rate_per_s = 0.0;
    config.sph.support_radius_m = SUPPORT_M;
    config.sph.rest_density_kg_m3 = REST_DENSITY;
    // Lattice mass: the block starts near the rest density.
    config.sph.particle_mass_kg = REST_DENSITY * (SUPPORT_M / 2.0).powi(3);
    config.domain.min_m = Vec3::splat(-1.0);
    config.domain.max_m = Vec3::splat(3.0);
    let n = points.len();
    FlameSim::with_particles(config, 1, points.to_vec(), vec![Vec3::ZERO; n]).expect("valid peer config")
}

/// salva3d's DFSPH over the same block with the same support radius
/// (salva: support = 2 × particle radius × smoothing factor).
pub fn peer(points: &[Vec3]) -> LiquidWorld {
    let smoothing_factor = 2.0f32;
    let particle_radius = SUPPORT_M / (2.0 * smoothing_factor);
    let solver: DFSPHSolver = DFSPHSolver::new();
    let mut world = LiquidWorld::new(solver, particle_radius, smoothing_factor, 1.0);
    let positions: Vec<Vector3<f32>> = points.iter().map(|p| Vector3::new(p.x, p.y, p.z)).collect();
    world.add_fluid(Fluid::new(positions, particle_radius, REST_DENSITY, InteractionGroups::all()));
    world
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_solvers_see_the_same_block_and_support() {
        let points = block(1000);
        assert_eq!(points.len(), 1000);
        let world = peer(&points);
        assert!((world.h() - SUPPORT_M).abs() < 1e-7);
        let mut sim = ours(&points);
        sim.step().expect("step");
        assert_eq!(sim.particles().len(), 1000);
    }
}
