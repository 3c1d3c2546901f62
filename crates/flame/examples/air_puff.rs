//! The air grid alone, heated by a hot inflow (1600 K above ambient) over a burner of
//! diameter D: prints the peak of the Welch spectrum of the axial velocity on the axis
//! one diameter up, for several D, against the puffing law f = 1.5/√D.
//!
//!     cargo run --release -p phenomena-flame --example air_puff [D ...]
//!
//! Environment overrides: CPD (cells per diameter, default 20), UIN (inflow, m/s,
//! default 0.05), SECONDS (default 20).
use phenomena_flame::air::{AirGrid, Burner, dominant_frequency};

#[allow(clippy::print_stdout, reason = "the spectrum peaks are the output")]
fn main() {
    let ds: Vec<f32> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let ds = if ds.is_empty() { vec![0.1, 0.3, 0.6] } else { ds };
    let env = |k: &str, d: f32| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
    let cpd = env("CPD", 20.0) as usize;
    let u_in = env("UIN", 0.05);
    let seconds = env("SECONDS", 20.0);
    for d in ds {
        let mut a = AirGrid::new(2 * cpd, 8 * cpd, d / cpd as f32, 300.0);
        let burner = Burner { cells: cpd / 2, inflow_m_s: u_in, theta: 1600.0 };
        let dt = 1.0 / 60.0;
        let mut signal = Vec::new();
        let t0 = std::time::Instant::now();
        for _ in 0..(seconds / dt) as usize {
            let n = a.substeps(dt, 1.0);
            for _ in 0..n {
                a.step(dt / n as f32, &burner);
            }
            signal.push(a.velocity(0.0, d).1);
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3 / signal.len() as f64;
        let skip = (2.0 / dt) as usize;
        let (f, share) =
            dominant_frequency(&signal[skip..], f64::from(dt), (4.0 / dt) as usize, 15.0).unwrap_or_default();
        let law = 1.5 / f64::from(d).sqrt();
        println!(
            "D {d:.2} m: peak {f:.2} Hz = {:.2} of the law ({law:.2} Hz), {:.0} % of the power; {ms:.1} ms/frame",
            f / law,
            share * 100.0
        );
    }
}
