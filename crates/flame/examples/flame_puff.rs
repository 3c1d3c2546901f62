//! The extended flame with the air on (`extended.air.enabled`) on burners of several
//! diameters D (emission rate scaled with the burner's area): prints the peak of the
//! Welch spectrum of three signals against the puffing law f = 1.5/√D (Cetegen &
//! Ahmed 1993): the flame's luminous height (below which 90 % of the particles' T⁴
//! lies), the particles' T⁴ above one diameter, and the air's axial velocity on the
//! axis one diameter up.
//!
//!     cargo run --release -p phenomena-flame --example flame_puff [D ...]
//!
//! Environment overrides: CPD (cells per diameter), UIN (the air's inflow, m/s), DRAG
//! (drag time, s), SECONDS (default 20).
use phenomena_flame::air::dominant_frequency;
use phenomena_flame::{FlameConfig, FlameSim};

#[allow(clippy::print_stdout, reason = "the spectrum peaks are the output")]
fn main() {
    let ds: Vec<f32> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let ds = if ds.is_empty() { vec![0.1, 0.3, 0.6] } else { ds };
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<f32>().ok());
    let seconds = env("SECONDS").unwrap_or(20.0);
    for d in ds {
        let mut c = FlameConfig::default();
        c.extended.air.enabled = true;
        if let Some(v) = env("CPD") {
            c.extended.air.cells_per_diameter = v as u32;
        }
        if let Some(v) = env("UIN") {
            c.extended.air.inflow_m_s = v;
        }
        if let Some(v) = env("DRAG") {
            c.extended.air.drag_time_s = v;
        }
        let r = d / 2.0;
        c.emitter.rate_per_s *= (r / 0.08).powi(2);
        c.emitter.radius_m = r;
        let mut sim = FlameSim::new(c, 1).expect("valid config");
        let dt = f64::from(sim.config().frame_time_s);
        let (mut height, mut upper, mut axis) = (Vec::new(), Vec::new(), Vec::new());
        let t0 = std::time::Instant::now();
        let frames = (f64::from(seconds) / dt) as usize;
        for _ in 0..frames {
            sim.step().expect("step");
            let p = sim.particles();
            let mut w: Vec<(f32, f32)> =
                p.position_m.iter().zip(&p.temperature_k).map(|(x, t)| (x.y, (t / 1500.0).powi(4))).collect();
            w.sort_by(|a, b| a.0.total_cmp(&b.0));
            let total: f32 = w.iter().map(|x| x.1).sum();
            let mut acc = 0.0;
            let h90 = w.iter().find(|(_, e)| {
                acc += e;
                acc >= 0.9 * total
            });
            height.push(h90.map_or(0.0, |x| x.0));
            upper.push(w.iter().filter(|x| x.0 > d && x.0 < 3.0 * d).map(|x| x.1).sum::<f32>());
            axis.push(sim.air().map_or(0.0, |a| a.grid().velocity(0.0, d).1));
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3 / frames as f64;
        let skip = (2.0 / dt) as usize;
        let law = 1.5 / f64::from(d).sqrt();
        let peak = |s: &[f32]| {
            let (f, share) =
                dominant_frequency(&s[skip..], dt, (4.0 / dt) as usize, 15.0).unwrap_or_default();
            format!("{f:.2} Hz ({:.2} of the law) {:.0} %", f / law, share * 100.0)
        };
        let mean_h = height[skip..].iter().sum::<f32>() / (frames - skip) as f32;
        println!(
            "D {d:.2} m, law {law:.2} Hz, {} particles, {ms:.1} ms/frame, mean height {mean_h:.2} m",
            sim.particles().len()
        );
        println!("  height {} | upper {} | axis w {}", peak(&height), peak(&upper), peak(&axis));
    }
}
