//! Redistribution (§2.3.4, Fig 2.14) keeps the particles spread along the shape, and a
//! simulation is bit-identical for any thread count.

mod common;

use phenomena_aurora::field::count_per_cell;
use phenomena_aurora::{AuroraConfig, AuroraSim};

/// Scene 1 run to its end, with or without redistribution. Returns the fraction of
/// particles farther than L_thr from the final target shape, and the cells that the final
/// shape's charges reach but that hold no particle.
fn strays_and_holes(redistribute: bool, damping_per_s: f32) -> (f64, usize) {
    let (mut config, frames, seed) = common::load("aurora-scene1.toml");
    config.redistribution.enabled = redistribute;
    config.motion.damping_per_s = damping_per_s;
    let reach = config.field.reach_km;
    let sim = common::run(config, seed, frames);
    let last = *sim.animation().keyframe_frames().last().expect("keyframes");
    let strays = 1.0 - common::fraction_near(&sim, &sim.animation().shape_at(last), reach);
    let counts = count_per_cell(sim.grid(), &sim.particles().position_km);
    let charges = &sim.field().counts;
    let holes = counts.iter().zip(charges).filter(|&(&n, &q)| q > 0 && n == 0).count();
    (strays, holes)
}

#[test]
#[ignore = "slow tier: cargo test -- --include-ignored"]
fn without_redistribution_particles_stray_and_leave_holes() {
    // Fig 2.14: without redistribution particles that left the shape stay away and cells
    // near it empty; with it (and with no cell over the upper threshold after any
    // renewal, which the scenario tests check on every scene) both shrink. Strays are
    // compared at a weak damping, 2/s, where particles leave the sheet: the default 6/s
    // holds them by itself (scene 1's final frame: 2.8 % of the particles outside L_thr
    // without redistribution, 2.6 % with), so redistribution's part shows at 2/s.
    let weak = 2.0;
    let (strays_off, _) = strays_and_holes(false, weak);
    let (strays_on, _) = strays_and_holes(true, weak);
    assert!(strays_off > 1.5 * strays_on, "strays at 2/s: {strays_on:.3} with vs {strays_off:.3} without");
    let damping = AuroraConfig::default().motion.damping_per_s;
    let (_, holes_off) = strays_and_holes(false, damping);
    let (_, holes_on) = strays_and_holes(true, damping);
    assert!(holes_on < holes_off, "empty cells near the shape: {holes_on} with vs {holes_off} without");
}

fn small() -> AuroraConfig {
    let mut config = AuroraConfig::default();
    config.motion.particles = 20_000;
    config.field.charges = 30_000;
    config
}

fn run_with_threads(threads: usize) -> AuroraSim {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    // 30 frames: four renewals with redistribution, neighbour lists over many chunks.
    pool.install(|| common::run(small(), 7, 30))
}

#[test]
fn the_same_seed_gives_the_same_particles_for_any_thread_count() {
    let one = run_with_threads(1);
    let three = run_with_threads(3);
    let p1 = one.particles();
    let p3 = three.particles();
    assert!(p1.len() > 10_000);
    assert_eq!(p1.id, p3.id);
    let bits = |v: &[glam::Vec2]| v.iter().flat_map(|x| [x.x.to_bits(), x.y.to_bits()]).collect::<Vec<_>>();
    assert_eq!(bits(&p1.position_km), bits(&p3.position_km));
    assert_eq!(bits(&p1.velocity_km_s), bits(&p3.velocity_km_s));
    assert_eq!(one.field().potential_noisy, three.field().potential_noisy);
}
