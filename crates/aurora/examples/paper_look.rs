//! Numbers: renders a thesis scene in `paper` mode (default: scene 2, frame
//! 200, 640x360) and prints the curtain's colour by height (the image criteria), each
//! line's paper-mode emission peak beside the physical mode's, and the frame as a PPM.
//!
//! ```sh
//! cargo run --release -p phenomena-aurora --example paper_look
//! cargo run --release -p phenomena-aurora --example paper_look -- --sky sky.toml --frame 150 --scene 1 --out look.ppm
//! ```
//!
//! `--sky FILE` reads `[render.sky]` settings (the table's contents, no header) to try
//! other constants; `mode` is set to `paper` unless the file sets it.

use phenomena_aurora::atmosphere::Atmosphere;
use phenomena_aurora::deposition::ColumnModel;
use phenomena_aurora::emission::Line;
use phenomena_aurora::fall::{PaperEmission, paper_peak_km, paper_profile};
use phenomena_aurora::{ColourMode, SkySettings};
use phenomena_core::color::srgb_encode_u8;
use phenomena_core::image::Frame;

/// The scenario tests' scene loading and the curtain measurement.
#[path = "../tests/common/mod.rs"]
mod common;

/// The command line: scene number, frame, image size, `[render.sky]` file and PPM path.
struct Args {
    scene: u32,
    frame: u32,
    size: (usize, usize),
    sky: Option<String>,
    out: Option<String>,
}

/// Read the command line (see the module docs).
fn parse_args() -> Args {
    let mut args = std::env::args().skip(1);
    let (mut scene, mut frame, mut size, mut sky, mut out) = (2u32, 200u32, (640usize, 360usize), None, None);
    while let Some(a) = args.next() {
        let mut value = || args.next().unwrap_or_else(|| panic!("{a} needs a value"));
        match a.as_str() {
            "--scene" => scene = value().parse().expect("--scene 1-5"),
            "--frame" => frame = value().parse().expect("--frame N"),
            "--size" => {
                let v = value();
                let (w, h) = v.split_once('x').expect("--size WxH");
                size = (w.parse().expect("width"), h.parse().expect("height"));
            }
            "--sky" => sky = Some(value()),
            "--out" => out = Some(value()),
            other => panic!("unknown argument {other}"),
        }
    }
    Args { scene, frame, size, sky, out }
}

/// The `[render.sky]` settings of the file at `path` (in `paper` mode unless it sets a
/// mode), or the defaults in `paper` mode.
fn sky_settings(path: Option<&str>) -> SkySettings {
    match path {
        Some(path) => {
            let text = std::fs::read_to_string(path).expect("--sky file");
            let mut s: SkySettings = toml::from_str(&text).expect("valid [render.sky] settings");
            if !text.lines().any(|l| l.trim_start().starts_with("mode")) {
                s.mode = ColourMode::Paper;
            }
            s
        }
        None => SkySettings { mode: ColourMode::Paper, ..SkySettings::thesis() },
    }
}

#[allow(clippy::print_stdout, reason = "a report")]
fn main() {
    let Args { scene, frame, size, sky, out } = parse_args();
    let settings = sky_settings(sky.as_deref());
    let (config, _, seed) = common::load(&format!("aurora-scene{scene}.toml"));
    let sim = common::run(config, seed, frame);
    let image = common::sky_frame(&sim, settings.clone(), size.0, size.1);
    let look = common::curtain_look(&image, 0.02);
    let [top, middle, bottom] = look.thirds;
    let norm = |c: [f64; 3]| {
        let m = c.iter().cloned().fold(0.0, f64::max).max(1e-30);
        c.map(|v| (v / m * 100.0).round() / 100.0)
    };
    println!(
        "scene {scene}, frame {frame}, {}x{}: R/G top {:.3}, middle {:.3}, ratio {:.2}; RGB top {:?} middle {:?} bottom {:?}",
        size.0,
        size.1,
        look.redness(0),
        look.redness(1),
        look.redness(0) / look.redness(1),
        norm(top),
        norm(middle),
        norm(bottom)
    );
    let clipped = (0..size.1)
        .flat_map(|y| (0..size.0).map(move |x| (x, y)))
        .filter(|&(x, y)| image.pixel(x, y).max_element() >= 1.0)
        .count();
    println!(
        "magenta {:.2} % of the curtain's pixels, {:.2} % above its lowest tenth; {clipped} pixels at or above 1",
        100.0 * look.magenta as f64 / look.pixels.max(1) as f64,
        100.0 * look.magenta_above_lowest_tenth as f64 / look.pixels.max(1) as f64
    );
    report_peaks(&settings);
    if let Some(path) = out {
        write_ppm(&path, &image, size);
    }
}

/// Print each line's paper-mode emission peak beside the physical mode's, the emission
/// weight and (with `PAPER_LOOK_RED` set) the 630.0 nm profile every 10 km.
#[allow(clippy::print_stdout, reason = "a report")]
fn report_peaks(settings: &SkySettings) {
    let air = Atmosphere::msis21();
    let emission = PaperEmission::new(air, &settings.paper, &settings.precipitation, &settings.yields);
    let (bottom_km, _) = air.range_km();
    let profile = paper_profile(air, &settings.paper, &emission, f64::from(settings.top_altitude_km));
    let physical = ColumnModel::new(air, &settings.precipitation, &settings.yields);
    for line in Line::ALL {
        let per_electron: f64 = profile.iter().map(|b| b[line.index()]).sum();
        println!(
            "{:5.1} nm: paper peak {:5.1} km ({per_electron:.3} emissions per electron), physical peak {:5.1} km",
            line.wavelength_nm(),
            paper_peak_km(air, &profile, line),
            physical.peak_altitude_km(line)
        );
    }
    println!("emission weight {:.3}", emission.weight());
    if std::env::var_os("PAPER_LOOK_RED").is_some() {
        let red = Line::O630.index();
        let most = profile.iter().map(|b| b[red]).fold(0.0, f64::max);
        for (k, b) in profile.iter().enumerate().step_by(10) {
            println!("  {:5.1} km: 630.0 nm {:.3}", bottom_km + k as f64 + 0.5, b[red] / most);
        }
    }
}

/// Write `image` (`size` px) as a binary PPM, sRGB-encoded, to `path`.
fn write_ppm(path: &str, image: &Frame, size: (usize, usize)) {
    let mut ppm = format!("P6 {} {} 255\n", size.0, size.1).into_bytes();
    for y in 0..size.1 {
        for x in 0..size.0 {
            let p = image.pixel(x, y);
            ppm.extend([p.x, p.y, p.z].map(srgb_encode_u8));
        }
    }
    std::fs::write(path, ppm).expect("write the PPM");
}
