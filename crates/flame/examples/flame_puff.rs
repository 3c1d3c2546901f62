//! The extended flame with the air on (`extended.air.enabled`) on burners of several
//! diameters D (emission rate scaled with the burner's area): prints the strongest
//! peaks of three spectra against the puffing law f = 1.5/√D (Cetegen & Ahmed 1993):
//! the flame's luminous height (below which 90 % of the particles' T⁴ lies), the T⁴
//! above 1.5 D, and the air's axial velocity on the axis one diameter up. Each peak
//! shows its frequency, its ratio to the law and its share of the spectrum's power.
//!
//!     cargo run --release -p phenomena-flame --example flame_puff [D ...]
//!
//! Environment overrides: CPD (cells per diameter), BURN (burn time, s), DRAG (drag
//! time, s), HRR (kW/m²), VEL (emitter speed, m/s), COURANT.
use phenomena_flame::{FlameConfig, FlameSim};

fn peaks(s: &[f32], dt: f64) -> Vec<(f64, f64)> {
    let mean = s.iter().sum::<f32>() / s.len() as f32;
    let mut spectrum = Vec::new();
    let mut f = 0.3f64;
    while f < 15.0 {
        let (mut re, mut im) = (0.0f64, 0.0f64);
        for (k, v) in s.iter().enumerate() {
            let ph = 2.0 * std::f64::consts::PI * f * k as f64 * dt;
            re += f64::from(v - mean) * ph.cos();
            im += f64::from(v - mean) * ph.sin();
        }
        spectrum.push((f, re * re + im * im));
        f += 0.05;
    }
    let total: f64 = spectrum.iter().map(|x| x.1).sum();
    let mut p: Vec<(f64, f64)> = (1..spectrum.len() - 1)
        .filter(|&k| spectrum[k].1 >= spectrum[k - 1].1 && spectrum[k].1 >= spectrum[k + 1].1)
        .map(|k| (spectrum[k].0, spectrum[k].1 / total))
        .collect();
    p.sort_by(|a, b| b.1.total_cmp(&a.1));
    p.truncate(4);
    p
}

#[allow(clippy::print_stdout, reason = "the spectrum peaks are the output")]
fn main() {
    let ds: Vec<f32> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let ds = if ds.is_empty() { vec![0.1, 0.3, 0.6] } else { ds };
    for d in ds {
        let mut c = FlameConfig::default();
        c.extended.air.enabled = true;
        if let Some(cpd) = std::env::var("CPD").ok().and_then(|v| v.parse().ok()) {
            c.extended.air.cells_per_diameter = cpd;
        }
        let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<f32>().ok());
        if let Some(v) = env("BURN") {
            c.extended.air.burn_time_s = v;
        }
        if let Some(v) = env("DRAG") {
            c.extended.air.drag_time_s = v;
        }
        if let Some(v) = env("HRR") {
            c.extended.air.heat_release_kw_m2 = v;
        }
        if let Some(v) = env("VEL") {
            c.emitter.velocity_m_s.y = v;
        }
        if let Some(v) = env("COURANT") {
            c.extended.air.max_courant = v;
        }
        let r = d / 2.0;
        c.emitter.rate_per_s *= (r / 0.08).powi(2);
        c.emitter.radius_m = r;
        let mut sim = FlameSim::new(c, 1).expect("valid config");
        let dt = f64::from(sim.config().frame_time_s);
        let (mut height, mut upper, mut axis) = (Vec::new(), Vec::new(), Vec::new());
        let t0 = std::time::Instant::now();
        let frames = (8.0 / dt) as usize;
        for _ in 0..frames {
            sim.step().expect("step");
            let p = sim.particles();
            let mut w: Vec<(f32, f32)> =
                p.position_m.iter().zip(&p.temperature_k).map(|(x, t)| (x.y, (t / 1500.0).powi(4))).collect();
            w.sort_by(|a, b| a.0.total_cmp(&b.0));
            let total: f32 = w.iter().map(|x| x.1).sum();
            let mut acc = 0.0;
            let mut h90 = 0.0;
            for (y, e) in &w {
                acc += e;
                if acc >= 0.9 * total {
                    h90 = *y;
                    break;
                }
            }
            height.push(h90);
            if let Some(a) = sim.air() {
                axis.push(a.grid().velocity(0.0, d).1);
            }
            upper.push(w.iter().filter(|x| x.0 > 1.5 * d).map(|x| x.1).sum::<f32>());
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3 / frames as f64;
        let skip = (2.0 / dt) as usize;
        let law = 1.5 / f64::from(d).sqrt();
        let fmt = |p: Vec<(f64, f64)>| {
            p.iter()
                .map(|(f, w)| format!("{f:.2} Hz ({:.2}) {:.0}%", f / law, w * 100.0))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let mean_h = height[skip..].iter().sum::<f32>() / (frames - skip) as f32;
        println!(
            "D {d:.2} m, law {law:.2} Hz, {} particles, {ms:.1} ms/frame, mean height {mean_h:.2} m",
            sim.particles().len()
        );
        println!("  height: {}", fmt(peaks(&height[skip..], dt)));
        println!("  upper:  {}", fmt(peaks(&upper[skip..], dt)));
        if axis.len() > skip {
            println!("  axis w: {}", fmt(peaks(&axis[skip..], dt)));
        }
    }
}
