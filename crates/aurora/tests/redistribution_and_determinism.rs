//! Redistribution (§2.3.4, Fig 2.14) keeps the particles spread along the shape, and a
//! simulation is bit-identical for any thread count.

mod common;

use phenomena_aurora::field::count_per_cell;
use phenomena_aurora::{AuroraConfig, AuroraSim};

/// Scene 1 run to its end. Returns the most cells holding more than Table 3.3's upper
/// threshold at any renewal after the transition (without redistribution: counted
/// after the frame; with it: what redistribution left), and the cells the final
/// shape's charges reach that hold no particle at the end.
fn crowded_and_empty(redistribute: bool) -> (usize, usize) {
    let (mut config, frames, seed) = common::load("aurora-scene1.toml");
    config.redistribution.enabled = redistribute;
    let upper = config.redistribution.remove_above;
    let mut sim = AuroraSim::new(config, seed).expect("valid aurora");
    let last = *sim.animation().keyframe_frames().last().expect("keyframes");
    let mut crowded = 0;
    for frame in 1..=frames {
        let stats = sim.step().expect("step");
        if frame as f32 >= last && stats.renewed && redistribute {
            crowded = crowded.max(stats.crowded_cells);
        } else if frame as f32 >= last && stats.renewed {
            let counts = count_per_cell(sim.grid(), &sim.particles().position_km);
            crowded = crowded.max(counts.iter().filter(|&&n| n > upper).count());
        }
    }
    let counts = count_per_cell(sim.grid(), &sim.particles().position_km);
    let charges = &sim.field().counts;
    let empty = counts.iter().zip(charges).filter(|&(&n, &q)| q > 0 && n == 0).count();
    (crowded, empty)
}

#[test]
fn redistribution_reduces_crowding_and_holes() {
    let (crowded_off, empty_off) = crowded_and_empty(false);
    let (crowded_on, empty_on) = crowded_and_empty(true);
    // Fig 2.14: without redistribution particles pile up in some cells and leave others
    // near the shape empty; with it fewer cells are over the upper threshold and fewer
    // near the shape are empty. Not every crowded cell is cleared: the sheet's centre
    // attracts particles faster than Table 3.3's cap of 100 removals per cell and renewal
    // takes them away at the default gas constant (3 cells stay over 500 at one renewal
    // of scene 1; the issue 3 note has the numbers).
    assert!(crowded_off > 0, "without redistribution some cell exceeds the upper threshold");
    assert!(
        crowded_on < crowded_off,
        "cells over the upper threshold: {crowded_on} with vs {crowded_off} without"
    );
    assert!(empty_on < empty_off, "empty cells near the shape: {empty_on} with vs {empty_off} without");
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
