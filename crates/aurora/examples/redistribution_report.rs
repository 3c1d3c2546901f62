//! Numbers: runs the thesis scenes 1-5 with the default motion and
//! redistribution parameters and prints, per scene, the fullest cell right after any
//! renewal's redistribution, the worst share of particles within L_thr over the last 40
//! frames, the particles at the end and the mean time per frame.
//!
//! ```sh
//! cargo run --release -p phenomena-aurora --example redistribution_report
//! cargo run --release -p phenomena-aurora --example redistribution_report -- --rule paper --damping 2 1 5
//! ```
//!
//! `--rule paper|reach` and `--damping RATE` change those two defaults; numbers pick
//! scenes (all five by default).

use std::io::Write;
use std::time::Instant;

use phenomena_aurora::{AuroraSim, MotionParams, Redistribution, RedistributionRule};

/// The scenario tests' scene loading.
#[path = "../tests/common/mod.rs"]
mod common;

fn main() {
    let mut args = std::env::args().skip(1);
    let (mut rule, mut damping, mut scenes) = (None, None, Vec::new());
    while let Some(a) = args.next() {
        match a.as_str() {
            "--rule" => {
                rule = Some(match args.next().as_deref() {
                    Some("paper") => RedistributionRule::Paper,
                    Some("reach") => RedistributionRule::Reach,
                    other => panic!("--rule paper|reach, not {other:?}"),
                })
            }
            "--damping" => {
                damping = Some(args.next().and_then(|v| v.parse::<f32>().ok()).expect("--damping RATE"))
            }
            n => scenes.push(n.parse::<u32>().expect("a scene number 1-5")),
        }
    }
    if scenes.is_empty() {
        scenes = (1..=5).collect();
    }
    for i in scenes {
        let (mut config, frames, seed) = common::load(&format!("aurora-scene{i}.toml"));
        config.motion = MotionParams::default();
        config.redistribution = Redistribution::default();
        if let Some(r) = rule {
            config.redistribution.rule = r;
        }
        if let Some(d) = damping {
            config.motion.damping_per_s = d;
        }
        let mut sim = AuroraSim::new(config, seed).expect("valid aurora");
        let (mut redistributed, mut after_step, mut crowded, mut worst) = (0u32, 0u32, 0usize, 1.0f64);
        let start = Instant::now();
        for frame in 1..=frames {
            let s = sim.step().expect("step");
            if s.renewed {
                redistributed = redistributed.max(s.redistributed_max_cell);
                after_step = after_step.max(s.max_near_cell);
                crowded += s.crowded_cells;
            }
            if frame + 40 > frames {
                worst = worst.min(s.near_share);
            }
        }
        let ms = start.elapsed().as_secs_f64() * 1e3 / f64::from(frames);
        writeln!(
            std::io::stdout(),
            "scene {i}: fullest cell after redistribution {redistributed} ({crowded} left crowded), \
             after the renewal frame's step {after_step}; min near_share over the last 40 frames \
             {worst:.3}; {} particles at the end; {ms:.0} ms per frame",
            sim.particles().len()
        )
        .expect("stdout");
    }
}
