//! The snow's glitter (`glitter::glints`, only the cells of normals that can glint)
//! against brute force (`glitter::brute_force`, every grain), over many seeds, as the
//! sparkle tests compare the stochastic model with the full system: the glint count's
//! mean (and the exact value), where the glints lie on the snow, their brightness, and
//! how many stay when the sun moves a little (the grains stay put).
//!
//! Four p-value tests run here (tile chi-square, brightness KS, and the same two after
//! the sun moved); Bonferroni's correction makes each one's threshold 0.01 / 4. The mean
//! checks are separate 4σ bounds.

#[path = "../../sparkle/tests/common/mod.rs"]
mod common;

use common::{chi2_two_sample, ks_two_sample};
use glam::Vec3;
use phenomena_snow::glitter::{Glint, Glitter, Viewing, brute_force, glints};

const P_MIN: f64 = 0.01 / 4.0;
const SEEDS: u64 = 200;
const TILES: usize = 8;
const SIDE_M: f32 = 4.0;

/// A bumpy 4 m × 4 m snow surface of 20 × 20 quads (800 triangles).
fn surface() -> Vec<[Vec3; 3]> {
    let n = 20;
    let at = |i: usize, j: usize| {
        let (x, z) =
            (i as f32 / n as f32 * SIDE_M - 0.5 * SIDE_M, j as f32 / n as f32 * SIDE_M - 0.5 * SIDE_M);
        Vec3::new(x, 0.15 * (2.0 * x).sin() * (1.5 * z).cos(), z)
    };
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    tris
}

fn area(tris: &[[Vec3; 3]]) -> f64 {
    tris.iter().map(|t| f64::from(0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length())).sum()
}

/// A wide cone (n = 200, cos θ = 0.99) so each run has ~500 glints.
fn glitter() -> Glitter {
    Glitter {
        grains_per_m2: 3000.0,
        exponent_n: 200.0,
        threshold_i_e: 0.99f32.powf(200.0),
        ..Glitter::default()
    }
}

fn viewing(sun_turn_deg: f32) -> Viewing {
    let a = (25.0 + sun_turn_deg).to_radians();
    Viewing { eye: Vec3::new(0.0, 2.0, 4.0), sun: Vec3::new(0.0, a.sin(), -a.cos()) }
}

/// Per run: the glint count, the glints per tile of the surface, their brightnesses.
struct Runs {
    counts: Vec<f64>,
    tiles: Vec<u64>,
    intensity: Vec<f64>,
}

fn runs(make: &dyn Fn(u64) -> Vec<Glint>, seeds: std::ops::Range<u64>) -> Runs {
    let mut r = Runs { counts: Vec::new(), tiles: vec![0; TILES * TILES], intensity: Vec::new() };
    for seed in seeds {
        let g = make(seed);
        r.counts.push(g.len() as f64);
        for glint in &g {
            let tile = |v: f32| (((v / SIDE_M + 0.5) * TILES as f32) as usize).min(TILES - 1);
            r.tiles[tile(glint.position.z) * TILES + tile(glint.position.x)] += 1;
            r.intensity.push(f64::from(glint.intensity));
        }
    }
    r
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

fn compare(what: &str, ours: &Runs, brute: &Runs, expected: f64) {
    // Poisson counts: each mean within 4σ of the exact value, σ² = mean / seeds.
    for (name, r) in [("cells", ours), ("brute force", brute)] {
        let sigma = (expected / SEEDS as f64).sqrt();
        let m = mean(&r.counts);
        assert!((m - expected).abs() < 4.0 * sigma, "{what}, {name}: mean count {m} vs exactly {expected}");
    }
    let (chi, df, p) = chi2_two_sample(&ours.tiles, &brute.tiles);
    assert!(p >= P_MIN, "{what}: tiles chi² {chi:.1} on {df} df, p = {p:.2e}");
    let (d, p) = ks_two_sample(&ours.intensity, &brute.intensity);
    assert!(p >= P_MIN, "{what}: brightness KS D = {d:.4}, p = {p:.2e}");
}

#[test]
#[allow(clippy::print_stderr)] // the shares kept, for the notes (--nocapture)
fn glitter_matches_brute_force_and_stays_put_when_the_sun_moves() {
    let tris = surface();
    let g = glitter();
    // Uniform two-sided normals: a grain glints with probability 1 − cos θ wherever it
    // lies, so the mean count is exactly ρ A (1 − cos θ).
    let expected = f64::from(g.grains_per_m2) * area(&tris) * (1.0 - 0.99);
    for turn in [0.0, 0.5] {
        let ours = runs(&|s| glints(&tris, viewing(turn), &g, s), 0..SEEDS);
        let brute = runs(&|s| brute_force(&tris, viewing(turn), &g, s), 1000..1000 + SEEDS);
        compare(&format!("sun turned {turn}°"), &ours, &brute, expected);
    }
    // The grains stay: after the sun turns 0.5°, most glints are the same grains. The
    // share kept is what the two cones (8.1° half-angle, axes ~0.25° apart) share;
    // brute force keeps its grains by construction, so both keep the same share.
    let kept = |make: &dyn Fn(u64, f32) -> Vec<Glint>, seeds: std::ops::Range<u64>| -> f64 {
        let (mut both, mut total) = (0usize, 0usize);
        for seed in seeds {
            let (a, b) = (make(seed, 0.0), make(seed, 0.5));
            let at: std::collections::HashSet<[u32; 3]> =
                a.iter().map(|g| g.position.to_array().map(f32::to_bits)).collect();
            both += b.iter().filter(|g| at.contains(&g.position.to_array().map(f32::to_bits))).count();
            total += a.len();
        }
        both as f64 / total as f64
    };
    let ours = kept(&|s, t| glints(&tris, viewing(t), &g, s), 0..40);
    let brute = kept(&|s, t| brute_force(&tris, viewing(t), &g, s), 1000..1040);
    eprintln!("kept after the sun turned 0.5°: cells {ours:.4}, brute force {brute:.4}");
    // ~20,000 glints each: a share's standard error is under 0.3 %; 2 % is 7σ of the
    // difference.
    assert!(ours > 0.8 && (ours - brute).abs() < 0.02, "kept: cells {ours}, brute force {brute}");
}
