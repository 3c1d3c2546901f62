//! The air grid alone, heated by a hot inflow (1600 K above ambient) over a burner of
//! diameter D: prints the dominant frequencies of the axial velocity on the axis one
//! diameter up, for several D, against the puffing law f = 1.5/√D.
//!
//!     cargo run --release -p phenomena-flame --example air_puff [D ...]
//!
//! Environment overrides: CPD (cells per diameter, default 24), UIN (inflow, m/s,
//! default 0.1).
use phenomena_flame::air::AirGrid;

#[allow(clippy::print_stdout, reason = "the spectrum peaks are the output")]
fn main() {
    let ds: Vec<f32> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let ds = if ds.is_empty() { vec![0.1, 0.2, 0.4, 0.6] } else { ds };
    let cpd = std::env::var("CPD").ok().and_then(|v| v.parse().ok()).unwrap_or(24usize);
    let u_in: f32 = std::env::var("UIN").ok().and_then(|v| v.parse().ok()).unwrap_or(0.1);
    for d in ds {
        let (nr, nz) = (2 * cpd, 8 * cpd);
        let dx = d / cpd as f32;
        let mut a = AirGrid::new(nr, nz, dx, 300.0);
        let dt = 1.0 / 60.0;
        let mut signal = Vec::new();
        let t0 = std::time::Instant::now();
        let mut subs = 0;
        for _frame in 0..(10.0 / dt) as usize {
            let n = a.substeps(dt, 1.0);
            subs += n;
            for _ in 0..n {
                for i in 0..cpd / 2 {
                    a.set_inflow(i, u_in);
                    a.set_theta(i, 0, 1600.0);
                }
                a.step(dt / n as f32, None, 2000.0, 1.0);
            }
            signal.push(a.velocity(0.0, d).1);
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3 / signal.len() as f64;
        let s = &signal[(3.0 / dt) as usize..];
        let mean = s.iter().sum::<f32>() / s.len() as f32;
        let (mut best, mut best_p) = (0.0, 0.0);
        let mut spectrum = Vec::new();
        let mut f = 0.3f64;
        while f < 15.0 {
            let (mut re, mut im) = (0.0f64, 0.0f64);
            for (k, v) in s.iter().enumerate() {
                let ph = 2.0 * std::f64::consts::PI * f * k as f64 * dt as f64;
                re += f64::from(v - mean) * ph.cos();
                im += f64::from(v - mean) * ph.sin();
            }
            let p = re * re + im * im;
            spectrum.push((f, p));
            if p > best_p {
                best_p = p;
                best = f;
            }
            f += 0.05;
        }
        let total: f64 = spectrum.iter().map(|x| x.1).sum();
        let mut peaks: Vec<(f64, f64)> = (1..spectrum.len() - 1)
            .filter(|&k| spectrum[k].1 >= spectrum[k - 1].1 && spectrum[k].1 >= spectrum[k + 1].1)
            .map(|k| (spectrum[k].0, spectrum[k].1 / total))
            .collect();
        peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
        let top: Vec<String> =
            peaks.iter().take(4).map(|(f, p)| format!("{f:.2}Hz {:.0}%", p * 100.0)).collect();
        println!("  peaks: {}", top.join(", "));
        let law = 1.5 / f64::from(d).sqrt();
        println!(
            "D {d:.2} m: peak {best:.2} Hz, law {law:.2} Hz, ratio {:.2}; mean w {mean:.2} m/s, max {:.2}; {ms:.1} ms/frame, {:.1} substeps",
            best / law,
            a.max_speed(),
            subs as f64 / signal.len() as f64
        );
    }
}
