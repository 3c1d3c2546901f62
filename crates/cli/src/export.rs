//! `phenomena export`: data products other than frames.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Result, bail};
use phenomena_core::color::{
    Observer, blackbody_srgb_normalized, blackbody_xyz, srgb_encode_u8, xy_chromaticity,
};

use phenomena_scene::output::{ensure_dir, write_bytes_atomic, write_png_rgb8};
use phenomena_scene::{Assets, Scene, Simulate, registry};

/// Output format of the blackbody table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum TableFormat {
    /// `temperature_k,x,y,r,g,b` rows.
    Csv,
    /// A 1-pixel-high strip, one pixel per temperature, sRGB encoded.
    Png,
}

/// Most rows a table may have.
const MAX_ROWS: f64 = 1_000_000.0;

/// The temperatures `min, min + step, ...` up to `max` inclusive.
pub(crate) fn temperatures(min_k: f64, max_k: f64, step_k: f64) -> Result<Vec<f64>> {
    if !(min_k.is_finite() && min_k > 0.0 && min_k <= 1e6) {
        bail!("--min-k {min_k} is out of range: expected a temperature in (0, 1000000] K");
    }
    if !(max_k.is_finite() && max_k >= min_k && max_k <= 1e6) {
        bail!("--max-k {max_k} is out of range: expected a temperature in [--min-k = {min_k}, 1000000] K");
    }
    if !(step_k.is_finite() && step_k > 0.0) {
        bail!("--step-k {step_k} is out of range: expected a positive step in K");
    }
    let count = ((max_k - min_k) / step_k + 1e-9).floor() + 1.0;
    if count > MAX_ROWS {
        bail!("--step-k {step_k} gives {count} rows, more than the limit of {MAX_ROWS}: use a larger step");
    }
    Ok((0..count as usize).map(|k| min_k + k as f64 * step_k).collect())
}

/// The CSV text: CIE 1931 xy chromaticity (empty for temperatures with no visible
/// emission) and linear sRGB, negatives clipped to 0, scaled so max(r, g, b) = 1.
pub(crate) fn blackbody_csv(temps: &[f64]) -> String {
    let mut out = String::from("temperature_k,x,y,r,g,b\n");
    for &t in temps {
        let xy = xy_chromaticity(blackbody_xyz(Observer::Cie1931TwoDegree, t));
        let rgb = blackbody_srgb_normalized(t);
        let (x, y) =
            xy.map_or((String::new(), String::new()), |(x, y)| (format!("{x:.8}"), format!("{y:.8}")));
        let _ = writeln!(out, "{t},{x},{y},{:.8},{:.8},{:.8}", rgb.x, rgb.y, rgb.z);
    }
    out
}

/// Write the blackbody table.
pub(crate) fn blackbody(
    min_k: f64,
    max_k: f64,
    step_k: f64,
    format: TableFormat,
    out: &Path,
) -> Result<String> {
    let temps = temperatures(min_k, max_k, step_k)?;
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        ensure_dir(parent)?;
    }
    match format {
        TableFormat::Csv => write_bytes_atomic(out, blackbody_csv(&temps).as_bytes())?,
        TableFormat::Png => {
            let rgb: Vec<u8> = temps
                .iter()
                .flat_map(|&t| {
                    let c = blackbody_srgb_normalized(t);
                    [c.x, c.y, c.z].map(|v| srgb_encode_u8(v as f32))
                })
                .collect();
            write_png_rgb8(out, temps.len() as u32, 1, &rgb)?;
        }
    }
    Ok(format!("wrote {} temperatures ({min_k}-{max_k} K) to {}", temps.len(), out.display()))
}

/// Write the aurora's model atmosphere table.
pub(crate) fn atmosphere(out: &Path) -> Result<String> {
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        ensure_dir(parent)?;
    }
    let air = phenomena_aurora::atmosphere::Atmosphere::msis21();
    write_bytes_atomic(out, air.to_csv().as_bytes())?;
    let (lo, hi) = air.range_km();
    Ok(format!(
        "wrote the NRLMSIS 2.1 atmosphere ({lo}-{hi} km, {} rows) to {}",
        air.samples().len(),
        out.display()
    ))
}

/// The files `export aurora-profile --air DIR` reads from DIR: the neutral table, its
/// minor species and its night ionosphere (what `tools/gen_atmosphere.py --out DIR` and
/// `tools/iri90/make_table.sh` write).
pub(crate) const AIR_FILES: [&str; 3] =
    ["atmosphere_msis21.csv", "atmosphere_msis21_minor.csv", "ionosphere_iri90.csv"];

/// The atmosphere of `--air DIR` ([`AIR_FILES`]), or the shipped one.
fn air_tables(
    dir: Option<&Path>,
) -> Result<std::borrow::Cow<'static, phenomena_aurora::atmosphere::Atmosphere>> {
    use phenomena_aurora::atmosphere::{Atmosphere, MinorSpecies, NightIonosphere};
    let Some(dir) = dir else { return Ok(std::borrow::Cow::Borrowed(Atmosphere::msis21())) };
    // Regular files only, capped (a FIFO or a device is refused, not waited on).
    let read = |name: &str| {
        let path = dir.join(name);
        let bytes = phenomena_scene::Assets::beside(&path)
            .read("--air", Path::new(name))
            .map_err(|e| anyhow::anyhow!("--air: cannot read {}: {}", path.display(), e.problem))?;
        String::from_utf8(bytes).map_err(|_| anyhow::anyhow!("--air: {} is not UTF-8 text", path.display()))
    };
    let [neutral, minor, ionosphere] = AIR_FILES;
    let located =
        |name: &'static str| move |e: String| anyhow::anyhow!("--air: {}: {e}", dir.join(name).display());
    let air = Atmosphere::from_csv(&read(neutral)?).map_err(located(neutral))?;
    let minor_species = MinorSpecies::from_csv(&read(minor)?).map_err(located(minor))?;
    let night = NightIonosphere::from_csv(&read(ionosphere)?).map_err(located(ionosphere))?;
    let air = air.with_air_of_its_conditions(minor_species, night).map_err(located(minor))?;
    Ok(std::borrow::Cow::Owned(air))
}

/// What `export aurora-profile` writes besides its profile, and where.
pub(crate) struct ProfileOutputs<'a> {
    /// The profile.
    pub out: &'a Path,
    /// The red line's budget.
    pub red_line: Option<&'a Path>,
    /// The paper mode's expected profile.
    pub paper: Option<&'a Path>,
    /// The aurora's part only (no night glow) in `out`.
    pub aurora_only: bool,
}

/// Write the aurora's 1-D column model for one precipitation, in the shipped atmosphere
/// or the one of `air_dir`.
pub(crate) fn aurora_profile(
    energy_kev: f64,
    spectrum: phenomena_aurora::deposition::Spectrum,
    flux_erg: f64,
    air_dir: Option<&Path>,
    outputs: &ProfileOutputs<'_>,
) -> Result<String> {
    use phenomena_aurora::deposition::{ColumnModel, Precipitation, Yields};
    let ProfileOutputs { out, red_line, paper, aurora_only } = *outputs;
    let precipitation = Precipitation { spectrum, energy_kev, flux_erg_cm2_s: flux_erg };
    let mut issues = phenomena_core::validate::Issues::default();
    precipitation.validate(&mut issues, "");
    if let Err(list) = issues.into_result() {
        let text: Vec<String> = list
            .iter()
            .map(|i| {
                i.to_string().replace(".energy_kev", "--energy-kev").replace(".flux_erg_cm2_s", "--flux-erg")
            })
            .collect();
        bail!("{}", text.join("; "));
    }
    let air = air_tables(air_dir)?;
    let model = ColumnModel::new(&air, &precipitation, &Yields::default());
    let csv = if aurora_only { model.to_csv_aurora_only() } else { model.to_csv() };
    write_creating_folder(out, csv.as_bytes())?;
    let mut also = String::new();
    if let Some(path) = red_line {
        write_creating_folder(path, model.red_line_csv().as_bytes())?;
        also = format!(" and the red line's budget to {}", path.display());
    }
    if let Some(path) = paper {
        also.push_str(&paper_profile_csv(&air, &precipitation, path)?);
    }
    Ok(format!("{}{also}", column_summary(&model, aurora_only, out)))
}

/// `bytes` to `path` atomically, its folder made if missing.
fn write_creating_folder(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        ensure_dir(parent)?;
    }
    Ok(write_bytes_atomic(path, bytes)?)
}

/// Write the `paper` mode's expected emission by altitude (default `[render.sky.paper]`,
/// production ratios from this precipitation's column) as CSV to `path`; returns what
/// the summary says of it.
fn paper_profile_csv(
    air: &phenomena_aurora::atmosphere::Atmosphere,
    precipitation: &phenomena_aurora::deposition::Precipitation,
    path: &Path,
) -> Result<String> {
    use phenomena_aurora::deposition::Yields;
    use phenomena_aurora::emission::Line;
    use phenomena_aurora::fall::{PaperEmission, PaperFall, paper_peak_km, paper_profile};
    let params = PaperFall::default();
    let emission = PaperEmission::new(air, &params, precipitation, &Yields::default());
    let top_km = f64::from(phenomena_aurora::SkySettings::default().top_altitude_km);
    let profile = paper_profile(air, &params, &emission, top_km);
    let (bottom_km, _) = air.range_km();
    let mut csv = String::from("altitude_km,e_391_4,e_427_8,e_557_7,e_630_0,e_670_5\n");
    for (k, row) in profile.iter().enumerate() {
        csv.push_str(&format!("{}", bottom_km + k as f64 + 0.5));
        for v in row {
            csv.push_str(&format!(",{v:.6e}"));
        }
        csv.push('\n');
    }
    write_creating_folder(path, csv.as_bytes())?;
    let peak = |line: Line| paper_peak_km(air, &profile, line);
    Ok(format!(
        "; the paper mode's emission by altitude (557.7 nm peak at {} km, 630.0 nm at {} km) to {}",
        peak(Line::O557),
        peak(Line::O630),
        path.display()
    ))
}

/// One line on the column written to `out`: rows, the green line's column and peak,
/// and the red line's (the aurora's alone, or with the night sky's own glow).
fn column_summary(
    model: &phenomena_aurora::deposition::ColumnModel,
    aurora_only: bool,
    out: &Path,
) -> String {
    use phenomena_aurora::emission::Line;
    let red = if aurora_only {
        format!(
            "630.0 nm {:.0} R of aurora (the night sky's own glow left out), peak at {} km",
            model.column_photons_cm2_s(Line::O630) / 1e6,
            model.peak_altitude_km(Line::O630)
        )
    } else {
        format!(
            "630.0 nm {:.0} R ({:.0} R of it the night sky's own), peak at {} km",
            model.seen_column_photons_cm2_s(Line::O630) / 1e6,
            (model.seen_column_photons_cm2_s(Line::O630) - model.column_photons_cm2_s(Line::O630)) / 1e6,
            model.seen_peak_altitude_km(Line::O630)
        )
    };
    format!(
        "wrote the column model ({} rows; 557.7 nm column {:.0} R, peak at {} km; {red}) to {}",
        model.altitudes_km().len(),
        model.seen_column_photons_cm2_s(Line::O557) / 1e6,
        model.seen_peak_altitude_km(Line::O557),
        out.display()
    )
}

/// Simulate the scene file `scene_path` for `steps` frames and write its export `name`
/// (one of its phenomenon's exports) in `format` to `out`; returns the export's summary.
pub(crate) fn scene_export(
    scene_path: &Path,
    name: &str,
    format: &str,
    steps: impl FnOnce(&Scene) -> Result<u32>,
    out: &Path,
) -> Result<String> {
    let scene = phenomena_scene::load(scene_path)?;
    let p = scene.phenomenon();
    if !p.exports().iter().any(|e| e.name == name) {
        let from: Vec<&str> = registry::PHENOMENA
            .iter()
            .filter(|q| q.exports().iter().any(|e| e.name == name))
            .map(|q| q.name())
            .collect();
        bail!(
            "{} holds a {} scene; `{name}` is exported from {} scenes",
            scene_path.display(),
            p.name(),
            from.join(" and ")
        );
    }
    let steps = steps(&scene)?;
    let mut runner = crate::render::runner(&scene, &Assets::beside(scene_path))?;
    crate::render::warn(&runner);
    runner.run(0..steps, &mut Simulate, &mut ())?;
    let exported = runner.export(name, format).map_err(anyhow::Error::msg)?;
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        ensure_dir(parent)?;
    }
    write_bytes_atomic(out, &exported.bytes)?;
    Ok(format!("wrote {} after {steps} steps to {}", exported.summary, out.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temperature_lists() {
        assert_eq!(temperatures(1000.0, 1300.0, 100.0).unwrap(), vec![1000.0, 1100.0, 1200.0, 1300.0]);
        assert_eq!(temperatures(1000.0, 1350.0, 100.0).unwrap().len(), 4);
        assert_eq!(temperatures(5.0, 5.0, 1.0).unwrap(), vec![5.0]);
        assert!(temperatures(0.0, 10.0, 1.0).unwrap_err().to_string().contains("--min-k 0"));
        assert!(temperatures(10.0, 5.0, 1.0).unwrap_err().to_string().contains("--max-k 5"));
        assert!(temperatures(1.0, 5.0, 0.0).unwrap_err().to_string().contains("--step-k 0"));
        assert!(temperatures(1.0, 1e6, 0.1).unwrap_err().to_string().contains("rows"));
    }

    #[test]
    fn invisible_temperatures_have_no_chromaticity() {
        let csv = blackbody_csv(&[1.0]);
        assert_eq!(csv.lines().nth(1), Some("1,,,0.00000000,0.00000000,0.00000000"));
    }
}
