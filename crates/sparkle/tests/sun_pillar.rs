//! The sun pillar's angular height, measured from the simulation's glints, against the
//! value the plates' tilt distribution gives by quadrature.
//!
//! **The observable.** A pillar is the light of nearly horizontal plates that mirror the
//! sun to the eye. Seen from inside a cloud of plates, it spreads in elevation around the
//! subsun (−e for a sun at elevation e): a plate tilted by t mirrors the sun at elevation
//! 2t − e, so tilts above e put light *above* the sun (the upper pillar, from the plates'
//! lower faces) and the rest below it. Its angular height here is the elevation span that
//! holds the central 80 % of its light (10th to 90th percentile): a percentile, unlike a
//! half maximum, needs no histogram of the noisy peak.
//!
//! **The analytic value.** For a view direction v, a glint needs its normal within the
//! Phong cone around H = (s − v)/|s − v| (s towards the sun), and shines k_s I_l (N·H)^n.
//! The light per unit of path and solid angle is then ρ G(H·y), with
//! G = ∫ (f(N·y) + f(−N·y)) (N·H)^n dN over the cone (two-sided plates, f the
//! von Mises-Fisher density), which depends on H only through its tilt. The light per
//! unit of elevation is cos α ∫ G dφ over the azimuth. Both are integrated numerically
//! (a midpoint rule far finer than the lobe's 1°), without the simulation.
//!
//! **The measure.** Each glint at distance r in direction v counts I / L(v)³, with L(v)
//! the ray's length in the box: crystals in a solid angle dΩ number ρ L³ dΩ / 3, so the
//! weighted sum estimates ρ E[I | v] whatever the box's shape (its faces cut rays at
//! different lengths above and below the eye).

use glam::Vec3;
use phenomena_core::camera::{Camera, Projection};
use phenomena_sparkle::{Dust, Light, Method, Normals, Phong, Population, SparkleConfig, SparkleSim};

const SUN_ELEVATION_DEG: f64 = 2.0;
const TILT_DEG: f32 = 4.0;
const EXPONENT: f32 = 3000.0;
const THRESHOLD: f32 = 0.0025;
const EYE: Vec3 = Vec3::new(0.0, 30.0, 0.0);
const BOX_MIN: Vec3 = Vec3::new(-60.0, 0.0, -120.0);
const BOX_MAX: Vec3 = Vec3::new(60.0, 60.0, 10.0);

fn config(density_per_m3: f64) -> SparkleConfig {
    SparkleConfig {
        method: Method::Stochastic,
        fps: 30.0,
        phong: Phong {
            specular_k_s: 1.0,
            light_intensity: 1.0,
            threshold_i_e: THRESHOLD,
            exponent_n: EXPONENT,
            two_sided: true,
        },
        light: Light::Sun {
            azimuth_deg: 0.0,
            elevation_deg: SUN_ELEVATION_DEG as f32,
            azimuth_rate_deg_per_s: 0.0,
            elevation_rate_deg_per_s: 0.0,
        },
        camera: Camera {
            position: EYE,
            look_at: EYE + Vec3::new(0.0, 0.0, -10.0),
            up: Vec3::Y,
            projection: Projection::Perspective { fov_y_deg: 60.0 },
        },
        population: Population::DiamondDust(Dust {
            box_min_m: BOX_MIN,
            box_max_m: BOX_MAX,
            density_per_m3,
            fall_speed_m_per_s: 0.3,
            wind_m_per_s: Vec3::new(0.5, 0.0, 0.0),
            gust_m_per_s: 0.3,
            turbulence_m_per_s: 0.1,
            rotation_deg_per_frame: 0.5,
            normals: Normals::Plates { tilt_deg: TILT_DEG },
        }),
        memory_frames: 4,
    }
}

/// The ray's length from the eye to the box's boundary along unit `v`.
fn path_in_box(v: [f64; 3]) -> f64 {
    let (eye, lo, hi) = (EYE.to_array(), BOX_MIN.to_array(), BOX_MAX.to_array());
    (0..3)
        .filter(|&k| v[k] != 0.0)
        .map(|k| {
            let bound = if v[k] > 0.0 { hi[k] } else { lo[k] };
            f64::from(bound - eye[k]) / v[k]
        })
        .fold(f64::INFINITY, f64::min)
}

/// The elevations (radians), azimuths from the sun's (radians) and weights I / L³ of
/// the glints of frames 0, 30 and 60 (a second apart: the crystals have turned and
/// drifted, so few glints are counted twice).
fn measured() -> Vec<(f64, f64, f64)> {
    let mut sim = SparkleSim::new(config(40.0), 7).unwrap();
    let mut out = Vec::new();
    for frame in 0..=60 {
        if frame > 0 {
            sim.step().unwrap();
        }
        if frame % 30 != 0 {
            continue;
        }
        let g = sim.glints();
        for (x, i) in g.position_m.iter().zip(&g.intensity) {
            let d = (*x - EYE).as_dvec3();
            let v = d / d.length();
            let l = path_in_box(v.to_array());
            out.push((v.y.asin(), v.x.atan2(-v.z), f64::from(*i) / (l * l * l)));
        }
    }
    out
}

/// G(c) for the tilt of H with cos = c: the two-sided lobe over the Phong cone, by a
/// midpoint rule in (δ, ψ) around H.
fn lobe_over_cone(h: [f64; 3]) -> f64 {
    let kappa = 1.0 / f64::from(TILT_DEG).to_radians().powi(2);
    let cos_max = f64::from(THRESHOLD).powf(1.0 / f64::from(EXPONENT));
    let delta_max = cos_max.acos();
    // An orthonormal pair around H.
    let e1 = {
        let a = if h[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
        let d = a[0] * h[0] + a[1] * h[1] + a[2] * h[2];
        let p = [a[0] - d * h[0], a[1] - d * h[1], a[2] - d * h[2]];
        let n = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        [p[0] / n, p[1] / n, p[2] / n]
    };
    let e2 = [h[1] * e1[2] - h[2] * e1[1], h[2] * e1[0] - h[0] * e1[2], h[0] * e1[1] - h[1] * e1[0]];
    let (nd, np) = (24, 32);
    let mut sum = 0.0;
    for a in 0..nd {
        let delta = (a as f64 + 0.5) / nd as f64 * delta_max;
        let weight = delta.cos().powf(f64::from(EXPONENT)) * delta.sin();
        for b in 0..np {
            let psi = (b as f64 + 0.5) / np as f64 * std::f64::consts::TAU;
            let ny = delta.cos() * h[1] + delta.sin() * (psi.cos() * e1[1] + psi.sin() * e2[1]);
            // exp(κ(N·y − 1)) for the lobe around +y and around −y (the other face).
            sum += weight * ((kappa * (ny - 1.0)).exp() + (kappa * (-ny - 1.0)).exp());
        }
    }
    sum
}

/// The light per unit of elevation at each of `alphas` (radians) within `band_deg` of the
/// sun's azimuth: cos α ∫ G(H) dφ.
fn analytic(alphas: &[f64], band_deg: f64) -> Vec<f64> {
    let e = SUN_ELEVATION_DEG.to_radians();
    let s = [0.0, e.sin(), -e.cos()];
    // G depends on H only through H·y: tabulate it over the tilt.
    let tilts: Vec<f64> = (0..=4000).map(|k| k as f64 * 0.01f64.to_radians()).collect();
    let table: Vec<f64> = tilts.iter().map(|t| lobe_over_cone([t.sin(), t.cos(), 0.0])).collect();
    let g = |hy: f64| {
        let t = hy.abs().min(1.0).acos().to_degrees() / 0.01;
        let k = t.floor() as usize;
        if k + 1 >= table.len() {
            return 0.0;
        }
        let f = t - k as f64;
        table[k] * (1.0 - f) + table[k + 1] * f
    };
    // A step of 0.005° or finer: far below the pillar's narrowest width near the subsun.
    let steps = (band_deg / 0.005).ceil().max(100.0) as usize;
    let step = 2.0 * band_deg / steps as f64;
    let phis: Vec<f64> = (0..steps).map(|k| (-band_deg + (k as f64 + 0.5) * step).to_radians()).collect();
    alphas
        .iter()
        .map(|&alpha| {
            let sum: f64 = phis
                .iter()
                .map(|&phi| {
                    let v = [alpha.cos() * phi.sin(), alpha.sin(), -alpha.cos() * phi.cos()];
                    let h = [s[0] - v[0], s[1] - v[1], s[2] - v[2]];
                    let n = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
                    g(h[1] / n)
                })
                .sum();
            alpha.cos() * sum
        })
        .collect()
}

/// The weighted `q`-quantile of `(value, weight)` pairs.
fn quantile(sorted: &[(f64, f64)], q: f64) -> f64 {
    let total: f64 = sorted.iter().map(|p| p.1).sum();
    let mut acc = 0.0;
    for &(x, w) in sorted {
        acc += w;
        if acc >= q * total {
            return x;
        }
    }
    sorted.last().map_or(0.0, |p| p.0)
}

/// The span from the 10th to the 90th percentile of the light within `band_deg` of the
/// sun's azimuth, degrees: (bottom, top) measured and (bottom, top) analytic.
#[allow(clippy::print_stdout)]
fn pillar(glints: &[(f64, f64, f64)], band_deg: f64) -> ((f64, f64), (f64, f64)) {
    let band = band_deg.to_radians();
    let mut seen: Vec<(f64, f64)> = glints.iter().filter(|g| g.1.abs() < band).map(|g| (g.0, g.2)).collect();
    seen.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert!(
        seen.len() > 10_000,
        "{} glints within {band_deg}°: too few to place the percentiles",
        seen.len()
    );
    let alphas: Vec<f64> = (0..6000).map(|k| (-30.0 + (k as f64 + 0.5) * 0.01).to_radians()).collect();
    let light = analytic(&alphas, band_deg);
    let expected: Vec<(f64, f64)> = alphas.iter().copied().zip(light).collect();
    let deg = |v: &[(f64, f64)]| (quantile(v, 0.1).to_degrees(), quantile(v, 0.9).to_degrees());
    let (m, e) = (deg(&seen), deg(&expected));
    println!(
        "within {band_deg}° of the sun's azimuth, {} glints: pillar {:.2}° to {:.2}°, analytic {:.2}° to {:.2}°",
        seen.len(),
        m.0,
        m.1,
        e.0,
        e.1
    );
    (m, e)
}

#[test]
fn the_pillar_rises_above_the_sun_as_high_as_the_tilts_allow() {
    let glints = measured();
    // The centre line (what the eye calls the pillar's height) and the whole pillar
    // (its light summed over azimuth, which sideways tilts spread more near the ends).
    for band_deg in [0.5, 60.0] {
        let ((lo, hi), (elo, ehi)) = pillar(&glints, band_deg);
        let (height, expected_height) = (hi - lo, ehi - elo);
        // 5 %: the bound. The sampling error of a 10 % percentile from N glints
        // is √(0.1·0.9/N) over the density (~0.03/°): 0.1° for N = 10⁴; the weights
        // I / L³ (brightness from 0.0025 to 1) shrink the effective N several times, so
        // some 0.2-0.3°, still a quarter of the bound's 1.2°.
        assert!(
            (height / expected_height - 1.0).abs() < 0.05,
            "within {band_deg}°: pillar {height:.2}° high, analytic {expected_height:.2}°"
        );
        // Around the subsun, and reaching above the sun: the upper pillar.
        assert!(hi > SUN_ELEVATION_DEG + 1.0, "the pillar's top {hi:.2}° is not above the sun");
        assert!(lo < -SUN_ELEVATION_DEG - 1.0, "the pillar's bottom {lo:.2}° is not below the subsun");
    }
}
