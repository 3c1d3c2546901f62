//! `phenomena export`: data products other than frames.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Result, bail};
use phenomena_core::color::{
    Observer, blackbody_srgb_normalized, blackbody_xyz, srgb_encode_u8, xy_chromaticity,
};

use crate::output;
use crate::scene::Scene;
use phenomena_aurora::AuroraSim;

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
        output::ensure_dir(parent)?;
    }
    match format {
        TableFormat::Csv => output::write_bytes_atomic(out, blackbody_csv(&temps).as_bytes())?,
        TableFormat::Png => {
            let rgb: Vec<u8> = temps
                .iter()
                .flat_map(|&t| {
                    let c = blackbody_srgb_normalized(t);
                    [c.x, c.y, c.z].map(|v| srgb_encode_u8(v as f32))
                })
                .collect();
            output::write_png_rgb8(out, temps.len() as u32, 1, &rgb)?;
        }
    }
    Ok(format!("wrote {} temperatures ({min_k}-{max_k} K) to {}", temps.len(), out.display()))
}

/// Write the aurora's model atmosphere table.
pub(crate) fn atmosphere(out: &Path) -> Result<String> {
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        output::ensure_dir(parent)?;
    }
    let air = phenomena_aurora::atmosphere::Atmosphere::msis21();
    output::write_bytes_atomic(out, air.to_csv().as_bytes())?;
    let (lo, hi) = air.range_km();
    Ok(format!(
        "wrote the NRLMSIS 2.1 atmosphere ({lo}-{hi} km, {} rows) to {}",
        air.samples().len(),
        out.display()
    ))
}

/// Write the aurora's 1-D column model for one precipitation.
pub(crate) fn aurora_profile(
    energy_kev: f64,
    spectrum: phenomena_aurora::deposition::Spectrum,
    flux_erg: f64,
    out: &Path,
) -> Result<String> {
    use phenomena_aurora::deposition::{ColumnModel, Precipitation, Yields};
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
    let model = ColumnModel::new(
        phenomena_aurora::atmosphere::Atmosphere::msis21(),
        &precipitation,
        &Yields::default(),
    );
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        output::ensure_dir(parent)?;
    }
    output::write_bytes_atomic(out, model.to_csv().as_bytes())?;
    let green = model.column_photons_cm2_s(phenomena_aurora::emission::Line::O557) / 1e6;
    Ok(format!(
        "wrote the column model ({} rows; 557.7 nm column {green:.0} R, peak at {} km) to {}",
        model.altitudes_km().len(),
        model.peak_altitude_km(phenomena_aurora::emission::Line::O557),
        out.display()
    ))
}

/// Mesh file formats for the snow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MeshFile {
    Glb,
    Obj,
    Ply,
}

/// Simulate a snow scene for `time_h` hours (default: its frames' worth) and write the
/// snow mesh.
pub(crate) fn snow_mesh(
    scene_path: &Path,
    format: MeshFile,
    time_h: Option<f64>,
    out: &Path,
) -> Result<String> {
    use phenomena_snow::export::{snow_mesh, to_glb, to_obj, to_ply};
    let scene = crate::scene::load(scene_path)?;
    let Scene::Snow(s) = &scene else {
        bail!(
            "{} holds a {} scene; snow meshes come from snow scenes",
            scene_path.display(),
            scene.phenomenon()
        );
    };
    let dt = f64::from(s.snow.time_step_h);
    let time = time_h.unwrap_or(f64::from(s.scene.frames) * dt);
    if !(time.is_finite() && (0.0..=1e5).contains(&time)) {
        bail!("--time-h {time} is out of range: expected hours in [0, 100000]");
    }
    let mesh = crate::render::snow_mesh(s, scene_path.parent().unwrap_or(Path::new(".")))?;
    let mut sim = phenomena_snow::SnowSim::new(mesh, s.snow.clone(), s.scene.seed)?;
    let steps = (time / dt).round() as u64;
    for _ in 0..steps {
        sim.step();
    }
    let tris = snow_mesh(&sim);
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        output::ensure_dir(parent)?;
    }
    let bytes = match format {
        MeshFile::Glb => to_glb(&tris),
        MeshFile::Obj => to_obj(&tris).into_bytes(),
        MeshFile::Ply => to_ply(&tris),
    };
    output::write_bytes_atomic(out, &bytes)?;
    Ok(format!(
        "wrote {} snow triangles ({:.3} m³ of snow after {:.2} h, {steps} steps) to {}",
        tris.triangles(),
        sim.volume_m3(),
        steps as f64 * dt,
        out.display()
    ))
}

/// What `export` writes of an aurora.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum AuroraData {
    /// `x,z,vx,vz` per particle.
    Particles,
    /// `sheet,index,x,z,next` per control point of the intermediate target shape.
    Shape,
}

/// Simulate an aurora scene through frame `frame` and write its particles or shape.
pub(crate) fn aurora(scene_path: &Path, frame: u32, out: &Path, what: AuroraData) -> Result<String> {
    let scene = crate::scene::load(scene_path)?;
    let Scene::Aurora(s) = &scene else {
        bail!(
            "{} holds a {} scene; particles and shapes are exported from aurora scenes",
            scene_path.display(),
            scene.phenomenon()
        );
    };
    if frame >= s.scene.frames {
        bail!("--frame {frame} is past the scene's {} frames (0..{})", s.scene.frames, s.scene.frames);
    }
    let mut sim = AuroraSim::new(s.aurora.clone(), s.scene.seed)?;
    for _ in 0..=frame {
        sim.step()?;
    }
    let mut text = String::new();
    let rows = match what {
        AuroraData::Particles => {
            text.push_str("x,z,vx,vz\n");
            let p = sim.particles();
            for (x, v) in p.position_km.iter().zip(&p.velocity_km_s) {
                let _ = writeln!(text, "{},{},{},{}", x.x, x.y, v.x, v.y);
            }
            p.len()
        }
        AuroraData::Shape => {
            text.push_str("sheet,index,x,z,next\n");
            let sh = &sim.field().shape;
            for i in 0..sh.points.len() {
                let next = sh.next[i].map(|j| sh.index_in_sheet[j as usize].to_string()).unwrap_or_default();
                let p = sh.points[i];
                let _ = writeln!(text, "{},{},{},{},{next}", sh.sheet[i], sh.index_in_sheet[i], p.x, p.y);
            }
            sh.points.len()
        }
    };
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        output::ensure_dir(parent)?;
    }
    output::write_bytes_atomic(out, text.as_bytes())?;
    Ok(format!("wrote {rows} rows after frame {frame} to {}", out.display()))
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
