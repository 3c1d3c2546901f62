//! The stochastic model (§2) against brute force, N = 10⁶ facets, over many seeds: the
//! generated count's mean and variance, where the glints fall on screen, the mean image
//! and how long glints last. Each scene moves the eye's H with position (a perspective
//! camera and a street lamp, or a moving sun), so a model that used one global H fails.
//!
//! Nine p-value tests are run in this file (tile chi-square at frames 0 and 3 of the
//! lamp scene, the lifetimes' KS test and the return-gap chi-square, tile chi-square for
//! plates of two tilts, for leaves and for the two-sided dust under a moving sun, and its
//! gap chi-square); Bonferroni's correction makes each one's threshold 0.01 / 9. The mean
//! checks (3σ and 4σ bounds) are separate fixed bounds on top of that.

mod common;

use common::{chi2_two_sample, ks_two_sample};
use glam::Vec3;
use phenomena_core::camera::{Camera, Projection};
use phenomena_sparkle::{
    Background, Dust, GlareShape, Leaves, Light, Method, Normals, Phong, Population, RenderSettings,
    SparkleConfig, SparkleRenderer, SparkleSim,
};

/// Each p-value must reach 0.01 after a Bonferroni correction for the 9 tests.
const P_MIN: f64 = 0.01 / 9.0;
/// Frames a stochastic glint is remembered after it stops being seen.
const MEMORY: u32 = 4;
const TILES: (usize, usize) = (32, 18);

/// The lamp scene's 600 m³ box of 10⁶ crystals, turning up to `rotation_deg` a frame.
fn lamp_dust(rotation_deg: f32) -> Dust {
    Dust {
        box_min_m: Vec3::new(-5.0, 0.0, -15.0),
        box_max_m: Vec3::new(5.0, 6.0, -5.0),
        density_per_m3: 1e6 / 600.0,
        fall_speed_m_per_s: 0.3,
        wind_m_per_s: Vec3::new(0.5, 0.0, 0.0),
        gust_m_per_s: 0.3,
        turbulence_m_per_s: 0.2,
        rotation_deg_per_frame: rotation_deg,
        normals: Normals::Uniform,
    }
}

/// A street lamp inside a 600 m³ box of 10⁶ crystals, seen by a perspective camera.
fn lamp_scene(method: Method, exponent_n: f32, cos_theta: f32, rotation_deg: f32) -> SparkleConfig {
    SparkleConfig {
        method,
        fps: 30.0,
        phong: Phong {
            specular_k_s: 1.0,
            light_intensity: 1.0,
            threshold_i_e: cos_theta.powf(exponent_n),
            exponent_n,
            two_sided: false,
        },
        light: Light::Point { position_m: Vec3::new(2.0, 5.0, -8.0) },
        camera: Camera {
            position: Vec3::new(0.0, 2.0, 2.0),
            look_at: Vec3::new(0.0, 3.0, -10.0),
            up: Vec3::Y,
            projection: Projection::Perspective { fov_y_deg: 60.0 },
        },
        population: Population::DiamondDust(lamp_dust(rotation_deg)),
        memory_frames: MEMORY,
    }
}

/// Glint counts per screen tile, plus one bin for glints off screen.
fn tiles(config: &SparkleConfig, sim: &SparkleSim, into: &mut [u64]) {
    let view = config.camera.view(TILES.0, TILES.1).unwrap();
    for x in &sim.glints().position_m {
        let bin = match view.project(*x) {
            Some(p)
                if p.x_px >= 0.0 && p.y_px >= 0.0 && p.x_px < TILES.0 as f32 && p.y_px < TILES.1 as f32 =>
            {
                p.y_px as usize * TILES.0 + p.x_px as usize
            }
            _ => TILES.0 * TILES.1,
        };
        into[bin] += 1;
    }
}

/// What one method produced over the seeds at the frames looked at.
struct Tally {
    counts: Vec<Vec<f64>>,
    tiles: Vec<Vec<u64>>,
    image: Vec<Vec<f64>>,
    lifetimes: Vec<f64>,
    /// Births by how many frames they had been unseen (1..=MEMORY, then MEMORY + 1 for
    /// longer or never).
    gaps: Vec<u64>,
}

/// Run `seeds` seeds for `frames` frames; tally at each frame in `at`.
fn run(config: SparkleConfig, seeds: std::ops::Range<u64>, frames: u32, at: &[u32], image: bool) -> Tally {
    let (iw, ih) = (16, 9);
    let mut t = Tally {
        counts: vec![Vec::new(); at.len()],
        tiles: vec![vec![0; TILES.0 * TILES.1 + 1]; at.len()],
        image: vec![vec![0.0; iw * ih]; at.len()],
        lifetimes: Vec::new(),
        gaps: vec![0; MEMORY as usize + 2],
    };
    let settings = RenderSettings {
        background: Background::Black,
        glare: GlareShape::None,
        glint_gain: 1.0,
        ..Default::default()
    };
    let mut renderer = SparkleRenderer::new(settings, iw, ih, None).unwrap();
    for seed in seeds {
        let mut sim = SparkleSim::new(config, seed).unwrap();
        for frame in 0..=frames {
            if frame > 0 {
                sim.step().unwrap();
                t.lifetimes.extend(sim.finished_lifetimes().iter().map(|&l| f64::from(l)));
                for &g in sim.birth_gaps() {
                    t.gaps[g as usize] += 1;
                }
            }
            if let Some(k) = at.iter().position(|&a| a == frame) {
                t.counts[k].push(sim.glints().len() as f64);
                tiles(&config, &sim, &mut t.tiles[k]);
                if image {
                    let f = renderer.render(&sim);
                    for (acc, v) in t.image[k].iter_mut().zip(f.c1.data()) {
                        *acc += f64::from(*v);
                    }
                }
            }
        }
    }
    t
}

fn mean_var(xs: &[f64]) -> (f64, f64) {
    let m = xs.iter().sum::<f64>() / xs.len() as f64;
    (m, xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (xs.len() - 1) as f64)
}

/// Means of two samples agree within 4 standard errors of their difference.
fn assert_same_mean(what: &str, a: &[f64], b: &[f64]) {
    let ((ma, va), (mb, vb)) = (mean_var(a), mean_var(b));
    let se = (va / a.len() as f64 + vb / b.len() as f64).sqrt();
    assert!((ma - mb).abs() < 4.0 * se, "{what}: means {ma} vs {mb} (se {se})");
}

#[test]
#[ignore = "slow tier: cargo test -- --include-ignored"]
fn lamp_scene_frames_match_brute_force() {
    // A wide cone (n = 20, cos θ = 0.9: p = 0.05, 50,000 glints a frame) so the mean
    // image converges: 150 seeds put ~5e4 glints in each of the 16×9 pixels, a relative
    // standard error of 0.5 % per method (weights (N·H)^20 add 16 %) and an expected
    // relative L1 difference of about 0.5 % between two correct methods.
    let seeds = 150;
    let at = [0, 3];
    let stochastic = run(lamp_scene(Method::Stochastic, 20.0, 0.9, 2.0), 0..seeds, 3, &at, true);
    let brute = run(lamp_scene(Method::BruteForce, 20.0, 0.9, 2.0), 1000..1000 + seeds, 3, &at, true);
    let p = 0.5 * (1.0 - 0.9);
    for (k, frame) in at.iter().enumerate() {
        // Counts: each method's mean within 3σ of N p (σ of a mean of `seeds` binomials).
        for (name, t) in [("stochastic", &stochastic), ("brute force", &brute)] {
            let (m, _) = mean_var(&t.counts[k]);
            let sigma = (1e6 * p * (1.0 - p) / seeds as f64).sqrt();
            assert!(
                (m - 1e6 * p).abs() < 3.0 * sigma,
                "{name} frame {}: mean count {m} vs {}",
                at[k],
                1e6 * p
            );
        }
        let (chi, df, pv) = chi2_two_sample(&stochastic.tiles[k], &brute.tiles[k]);
        assert!(pv >= P_MIN, "frame {frame}: tiles chi² {chi:.1} on {df} df, p = {pv:.2e}");
        let (a, b) = (&stochastic.image[k], &brute.image[k]);
        let l1 = a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f64>() / b.iter().sum::<f64>();
        assert!(l1 < 0.01, "frame {frame}: mean image relative L1 {l1:.4}");
    }
}

#[test]
#[ignore = "slow tier: cargo test -- --include-ignored"]
fn glint_lifetimes_match_brute_force() {
    // A narrow cone (cos θ = 0.99, θ = 8.1°) and 4° of rotation a frame: glints last a
    // few frames. Lifetimes of glints born in frames 1-15 that die by frame 16.
    let seeds = 40;
    let stochastic = run(lamp_scene(Method::Stochastic, 200.0, 0.99, 4.0), 0..seeds, 16, &[], false);
    let brute = run(lamp_scene(Method::BruteForce, 200.0, 0.99, 4.0), 1000..1000 + seeds, 16, &[], false);
    assert!(stochastic.lifetimes.len() > 10_000 && brute.lifetimes.len() > 10_000);
    let (d, pv) = ks_two_sample(&stochastic.lifetimes, &brute.lifetimes);
    assert!(pv >= P_MIN, "lifetimes: KS D = {d:.4}, p = {pv:.2e}");
    assert_same_mean("lifetime", &stochastic.lifetimes, &brute.lifetimes);
    // Glints that turn back into the cone soon after leaving it: in the full system they
    // return where they were; the remembered ghosts must reproduce how often, after how
    // many unseen frames (a model that draws every newcomer afresh fails this).
    assert!(brute.gaps[1] > 1000, "{:?}", brute.gaps);
    let (chi, df, pv) = chi2_two_sample(&stochastic.gaps[1..], &brute.gaps[1..]);
    assert!(
        pv >= P_MIN,
        "return gaps {:?} vs {:?}: chi² {chi:.1} on {df} df, p = {pv:.2e}",
        stochastic.gaps,
        brute.gaps
    );
}

#[test]
#[ignore = "slow tier: cargo test -- --include-ignored"]
fn count_is_binomial_before_and_after_births() {
    // 20,000 seeds of the stochastic model alone (p = 5.0e-4, 500 glints): the sample
    // variance's relative standard error is √(2/20000) = 1 %, so "within 5 %" is a 5σ
    // bound; the mean is held to 3σ as asked.
    let seeds = 20_000u64;
    let config = lamp_scene(Method::Stochastic, 2000.0, 0.999, 1.0);
    let p = config.phong.uniform_fraction();
    let (n, expect_var) = (1e6, 1e6 * p * (1.0 - p));
    let mut counts = [Vec::new(), Vec::new()];
    for seed in 0..seeds {
        let mut sim = SparkleSim::new(config, seed).unwrap();
        counts[0].push(sim.glints().len() as f64);
        for _ in 0..4 {
            sim.step().unwrap();
        }
        counts[1].push(sim.glints().len() as f64);
    }
    for (frame, c) in [0, 4].iter().zip(&counts) {
        let (m, v) = mean_var(c);
        assert!(
            (m - n * p).abs() < 3.0 * (expect_var / seeds as f64).sqrt(),
            "frame {frame}: mean {m} vs {}",
            n * p
        );
        assert!((v / expect_var - 1.0).abs() < 0.05, "frame {frame}: variance {v} vs {expect_var}");
    }
}

#[test]
#[ignore = "slow tier: cargo test -- --include-ignored"]
fn plates_match_brute_force() {
    // Horizontal plates (two-sided) under a low sun: glints gather around the subsun and
    // a pillar. Both tilts mix the two ways the box's split cells draw candidates
    // (`CellTable::split`): normals uniform in the cap thinned by the lobe (cells whose
    // cap holds the lobe's axis), and normals from the lobe restricted to a window of
    // polar and azimuth angles, kept when in the cap (cells out in the lobe's tail).
    // This test found a lost batch of candidates (a 1.3 % deficit at tilt 1°, 11
    // standard errors) while that path was written.
    for tilt_deg in [10.0, 1.0] {
        let config = |method| SparkleConfig {
            method,
            phong: Phong {
                threshold_i_e: 0.99f32.powf(200.0),
                exponent_n: 200.0,
                two_sided: true,
                ..Phong::default()
            },
            light: Light::Sun {
                azimuth_deg: 0.0,
                elevation_deg: 15.0,
                azimuth_rate_deg_per_s: 0.0,
                elevation_rate_deg_per_s: 0.0,
            },
            population: Population::DiamondDust(Dust {
                normals: Normals::Plates { tilt_deg },
                ..lamp_dust(3.0)
            }),
            ..lamp_scene(method, 200.0, 0.99, 3.0)
        };
        let seeds = 60;
        let stochastic = run(config(Method::Stochastic), 0..seeds, 2, &[0, 2], false);
        let brute = run(config(Method::BruteForce), 1000..1000 + seeds, 2, &[0, 2], false);
        assert!(mean_var(&brute.counts[1]).0 > 300.0, "tilt {tilt_deg}: {}", mean_var(&brute.counts[1]).0);
        for k in 0..2 {
            assert_same_mean(
                &format!("tilt {tilt_deg}: plate count"),
                &stochastic.counts[k],
                &brute.counts[k],
            );
        }
        let (chi, df, pv) = chi2_two_sample(&stochastic.tiles[1], &brute.tiles[1]);
        assert!(pv >= P_MIN, "plates tilt {tilt_deg}: tiles chi² {chi:.1} on {df} df, p = {pv:.2e}");
    }
}

#[test]
#[ignore = "slow tier: cargo test -- --include-ignored"]
fn leaves_under_a_moving_sun_match_brute_force() {
    // 10⁶ leaves on a crown, a 25° normal lobe, the sun sweeping 1° a frame: every
    // glint change comes from H moving, none from the leaves.
    let config = |method| SparkleConfig {
        method,
        phong: Phong {
            threshold_i_e: 0.99f32.powf(200.0),
            exponent_n: 200.0,
            two_sided: false,
            ..Phong::default()
        },
        light: Light::Sun {
            azimuth_deg: -30.0,
            elevation_deg: 35.0,
            azimuth_rate_deg_per_s: 30.0,
            elevation_rate_deg_per_s: 0.0,
        },
        camera: Camera {
            position: Vec3::new(0.0, 3.0, 6.0),
            look_at: Vec3::new(0.0, 2.0, -12.0),
            up: Vec3::Y,
            projection: Projection::Perspective { fov_y_deg: 50.0 },
        },
        population: Population::LeafGlitter(Leaves { count: 1_000_000, ..Leaves::default() }),
        ..SparkleConfig::default()
    };
    let seeds = 60;
    let stochastic = run(config(Method::Stochastic), 0..seeds, 3, &[0, 3], false);
    let brute = run(config(Method::BruteForce), 1000..1000 + seeds, 3, &[0, 3], false);
    assert!(mean_var(&brute.counts[1]).0 > 500.0, "{}", mean_var(&brute.counts[1]).0);
    for k in 0..2 {
        assert_same_mean("leaf count", &stochastic.counts[k], &brute.counts[k]);
    }
    let (chi, df, pv) = chi2_two_sample(&stochastic.tiles[1], &brute.tiles[1]);
    assert!(pv >= P_MIN, "leaves: tiles chi² {chi:.1} on {df} df, p = {pv:.2e}");
}

#[test]
#[ignore = "slow tier: cargo test -- --include-ignored"]
fn two_sided_dust_under_a_moving_sun_seen_orthographically_matches_brute_force() {
    // Two-sided facets (both caps), a sun climbing 1° a frame (H changes with time, the
    // regions' sun term) and an orthographic camera (V the same everywhere).
    let config = |method| SparkleConfig {
        phong: Phong {
            threshold_i_e: 0.99f32.powf(200.0),
            exponent_n: 200.0,
            two_sided: true,
            ..Phong::default()
        },
        light: Light::Sun {
            azimuth_deg: 150.0,
            elevation_deg: 10.0,
            azimuth_rate_deg_per_s: 0.0,
            elevation_rate_deg_per_s: 30.0,
        },
        camera: Camera {
            position: Vec3::new(0.0, 3.0, 5.0),
            look_at: Vec3::new(0.0, 3.0, -10.0),
            up: Vec3::Y,
            projection: Projection::Orthographic { height_m: 8.0 },
        },
        ..lamp_scene(method, 200.0, 0.99, 3.0)
    };
    let seeds = 40;
    let stochastic = run(config(Method::Stochastic), 0..seeds, 8, &[8], false);
    let brute = run(config(Method::BruteForce), 1000..1000 + seeds, 8, &[8], false);
    let p = 1.0 - 0.99;
    for (name, t) in [("stochastic", &stochastic), ("brute force", &brute)] {
        let (m, _) = mean_var(&t.counts[0]);
        let sigma = (1e6 * p * (1.0 - p) / seeds as f64).sqrt();
        assert!((m - 1e6 * p).abs() < 3.0 * sigma, "{name}: mean count {m} vs {}", 1e6 * p);
    }
    let (chi, df, pv) = chi2_two_sample(&stochastic.tiles[0], &brute.tiles[0]);
    assert!(pv >= P_MIN, "tiles chi² {chi:.1} on {df} df, p = {pv:.2e}");
    let (chi, df, pv) = chi2_two_sample(&stochastic.gaps[1..], &brute.gaps[1..]);
    assert!(
        pv >= P_MIN,
        "return gaps {:?} vs {:?}: chi² {chi:.1} on {df} df, p = {pv:.2e}",
        stochastic.gaps,
        brute.gaps
    );
}
