//! A lattice block whose interior sits exactly at the rest density has zero pressure
//! there, and the symmetric lattice makes every interior force cancel: deep inside the
//! block nothing moves, while the surface (below rest density) does.

use glam::Vec3;
use phenomena_flame::{FlameConfig, FlameSim, Mode};

#[test]
fn interior_of_a_block_at_rest_density_does_not_move() {
    let mut config = FlameConfig { mode: Mode::Paper, ..Default::default() };
    config.sph.gas_constant_m2_s2 = 1.0;
    config.emitter.rate_per_s = 0.0; // only the block
    let d = config.sph.support_radius_m;
    let h = d / 1.5; // lattice spacing: about 14 neighbours within d
    let n = 26usize;
    let half = (n as f32 - 1.0) * h / 2.0;
    let mut positions = Vec::new();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                positions.push(Vec3::new(i as f32, j as f32, k as f32) * h - Vec3::splat(half) + Vec3::Y);
            }
        }
    }
    let count = positions.len();
    let centre = (n / 2 * n + n / 2) * n + n / 2; // the middle of the block
    // Measure the lattice's own interior density with the simulation's kernel sum, and
    // make it the rest density: p = 0 inside.
    let mut probe =
        FlameSim::with_particles(config.clone(), 1, positions.clone(), vec![Vec3::ZERO; count]).unwrap();
    probe.evaluate_at(0.0).unwrap();
    let pp = probe.particles();
    let at = pp.id.iter().position(|&id| id == centre as u64).unwrap();
    config.sph.rest_density_kg_m3 = pp.density_kg_m3[at];

    let mut sim = FlameSim::with_particles(config, 1, positions.clone(), vec![Vec3::ZERO; count]).unwrap();
    let steps = 2;
    for _ in 0..steps {
        sim.step().unwrap();
    }
    // A disturbance travels at most 2d per step (density reads neighbours within d, the
    // force reads their pressures within d), so particles farther than 2·d·steps from
    // the surface have seen only an exactly symmetric, zero-pressure neighbourhood.
    let depth_needed = 2.0 * d * steps as f32 + h;
    let p = sim.particles();
    let (mut interior, mut surface_moved) = (0, 0);
    for (idx, &id) in p.id.iter().enumerate() {
        let start = positions[id as usize];
        let depth = (half - (start - Vec3::Y).abs().max_element()).max(0.0);
        let moved = p.position_m[idx].distance(start);
        if depth > depth_needed {
            interior += 1;
            // f32 rounding of the pair sums gives accelerations of ~1e-6 m/s²; over two
            // frames that is ~1e-9 m. 1e-6 m is a thousand times that and 40,000 times
            // below the support radius.
            assert!(moved < 1e-6, "interior particle {id} at depth {depth} moved {moved} m");
        } else if depth == 0.0 && moved > 1e-5 {
            surface_moved += 1;
        }
    }
    assert!(interior > 500, "the interior must be non-trivial: {interior}");
    assert!(surface_moved > 100, "the surface, below rest density, must move: {surface_moved}");
}
