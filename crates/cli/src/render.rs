//! `phenomena render`: simulate a scene and write its frames.

use std::fmt::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use phenomena_aurora::plane::render_plane;
use phenomena_aurora::{AuroraSim, AuroraView, RenderSettings as AuroraRenderSettings, SkyRenderer};
use phenomena_core::image::{Frame, Plane};
use phenomena_flame::{Background, FlameRenderer, FlameSim, View, frame_from_srgb8};
use serde::Serialize;

use crate::output::{self, ImageFormat};
use crate::scene::Scene;

/// Options of one render, after the command line has been read.
#[derive(Clone, Debug)]
pub(crate) struct RenderJob {
    pub(crate) scene_path: PathBuf,
    pub(crate) out_dir: PathBuf,
    pub(crate) frames: Option<Range<u32>>,
    pub(crate) width: Option<u32>,
    pub(crate) height: Option<u32>,
    pub(crate) seed: Option<u64>,
    pub(crate) threads: Option<usize>,
    pub(crate) format: ImageFormat,
    pub(crate) resume: bool,
    pub(crate) stats: Option<PathBuf>,
    pub(crate) view: Option<ViewArg>,
    pub(crate) quiet: bool,
}

/// Parse `A..B` (B exclusive), `A..=B` (inclusive) or `N` (the single frame N).
pub(crate) fn parse_frame_range(s: &str) -> Result<Range<u32>, String> {
    let num = |t: &str| {
        t.trim().parse::<u32>().map_err(|_| format!("`{t}` is not a frame number (a whole number from 0)"))
    };
    let range = if let Some((a, b)) = s.split_once("..=") {
        num(a)?..num(b)?.checked_add(1).ok_or("frame number too large")?
    } else if let Some((a, b)) = s.split_once("..") {
        num(a)?..num(b)?
    } else {
        let n = num(s)?;
        n..n.checked_add(1).ok_or("frame number too large")?
    };
    if range.is_empty() {
        return Err(format!("`{s}` is an empty range: use A..B with A < B (B is not rendered) or A..=B"));
    }
    Ok(range)
}

/// What to draw, over all phenomena (each accepts some).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum ViewArg {
    /// The phenomenon as seen by the camera (flame).
    Flame,
    /// Flame particles as squares coloured by density (flame paper Fig 7).
    Density,
    /// The aurora's x-z simulation plane from above (thesis Figs 2.9-2.14).
    Plane,
    /// The aurora in the sky, through the scene's camera (thesis §2.4).
    Sky,
    /// The snow scene through its camera.
    Scene,
    /// The snow probability P_a from above (snow paper §2.2).
    Probability,
}

/// A phenomenon's simulation and renderer, stepped together.
pub(crate) enum Runner {
    Flame {
        sim: Box<FlameSim>,
        renderer: Box<FlameRenderer>,
    },
    Aurora {
        sim: Box<AuroraSim>,
        settings: Box<AuroraRenderSettings>,
        frame: Frame,
        sky: Option<Box<SkyRenderer>>,
    },
    Snow {
        sim: Box<phenomena_snow::SnowSim>,
        settings: Box<phenomena_snow::SnowRenderSettings>,
        frame: Frame,
    },
    Sparkle {
        sim: Box<phenomena_sparkle::SparkleSim>,
        renderer: Box<phenomena_sparkle::SparkleRenderer>,
    },
}

/// Per-frame statistics, one JSON object per line of `--stats`: the frame's timings
/// and the phenomenon's own counters (flattened).
#[derive(Serialize)]
struct FrameStats {
    frame: u32,
    step_ms: f64,
    render_ms: Option<f64>,
    /// The renderer's own breakdown of `render_ms` (the aurora's sky view).
    #[serde(skip_serializing_if = "Option::is_none")]
    render_detail: Option<serde_json::Value>,
    write_ms: Option<f64>,
    skipped: bool,
    #[serde(flatten)]
    detail: serde_json::Value,
}

impl Runner {
    /// Build the simulation and renderer of `scene`; relative asset paths resolve
    /// against `scene_dir`.
    pub(crate) fn new(scene: &Scene, scene_dir: &Path) -> Result<Self> {
        match scene {
            Scene::Flame(s) => {
                let background = match &s.render.background {
                    Background::Image { path } => {
                        let p = scene_dir.join(path);
                        let (w, h, rgb) = output::read_rgb8(&p)?;
                        Some(
                            frame_from_srgb8(w, h, &rgb)
                                .context("background image has an unexpected size")?,
                        )
                    }
                    _ => None,
                };
                let sim = FlameSim::new(s.flame.clone(), s.scene.seed)?;
                let renderer = FlameRenderer::new(
                    s.render.clone(),
                    s.scene.width as usize,
                    s.scene.height as usize,
                    background.as_ref(),
                )?;
                Ok(Runner::Flame { sim: Box::new(sim), renderer: Box::new(renderer) })
            }
            Scene::Aurora(s) => {
                let sim = AuroraSim::new(s.aurora.clone(), s.scene.seed)?;
                let (w, h) = (s.scene.width as usize, s.scene.height as usize);
                let frame = Frame::new(w, h);
                let sky = match s.render.view {
                    AuroraView::Sky => Some(Box::new(SkyRenderer::new(s.render.sky, w, h)?)),
                    AuroraView::Plane => None,
                };
                Ok(Runner::Aurora { sim: Box::new(sim), settings: Box::new(s.render), frame, sky })
            }
            Scene::Snow(s) => {
                let mesh = snow_mesh(s, scene_dir)?;
                let sim = phenomena_snow::SnowSim::new(mesh, s.snow.clone(), s.scene.seed)?;
                let frame = Frame::new(s.scene.width as usize, s.scene.height as usize);
                Ok(Runner::Snow { sim: Box::new(sim), settings: Box::new(s.render), frame })
            }
            Scene::Sparkle(s) => {
                let (w, h) = (s.scene.width as usize, s.scene.height as usize);
                let background = match &s.render.background {
                    phenomena_sparkle::Background::Image { path } => {
                        let p = scene_dir.join(path);
                        let (bw, bh, rgb) = output::read_rgb8(&p)?;
                        Some(
                            frame_from_srgb8(bw, bh, &rgb)
                                .context("background image has an unexpected size")?,
                        )
                    }
                    _ => None,
                };
                let sim = phenomena_sparkle::SparkleSim::new(s.sparkle, s.scene.seed)?;
                if sim.cone_is_empty() {
                    let p = &s.sparkle.phong;
                    eprintln!(
                        "warning: no facet can be seen: threshold_i_e {} is not below k_s I_l = {}; the frames show the background only",
                        p.threshold_i_e,
                        p.specular_k_s * p.light_intensity
                    );
                }
                let renderer =
                    phenomena_sparkle::SparkleRenderer::new(s.render.clone(), w, h, background.as_ref())?;
                Ok(Runner::Sparkle { sim: Box::new(sim), renderer: Box::new(renderer) })
            }
        }
    }

    /// Advance one frame; the phenomenon's counters as JSON.
    pub(crate) fn step(&mut self) -> Result<serde_json::Value> {
        Ok(match self {
            Runner::Flame { sim, .. } => serde_json::to_value(sim.step()?)?,
            Runner::Aurora { sim, .. } => serde_json::to_value(sim.step()?)?,
            Runner::Snow { sim, .. } => serde_json::to_value(sim.step())?,
            Runner::Sparkle { sim, .. } => serde_json::to_value(sim.step()?)?,
        })
    }

    /// Render the current state (into a frame reused across frames).
    pub(crate) fn render(&mut self) -> &Frame {
        match self {
            Runner::Flame { sim, renderer } => renderer.render(sim),
            Runner::Aurora { sim, sky: Some(sky), .. } => sky.render(sim),
            Runner::Aurora { sim, settings, frame, sky: None } => {
                *frame = render_plane(sim, frame.width(), frame.height(), &settings.plane);
                frame
            }
            Runner::Snow { sim, settings, frame } => {
                *frame = phenomena_snow::render(sim, settings, frame.width(), frame.height());
                frame
            }
            Runner::Sparkle { sim, renderer } => renderer.render(sim),
        }
    }

    /// The renderer's timing breakdown of the last render, where it has one.
    fn render_detail(&self) -> Option<serde_json::Value> {
        match self {
            Runner::Aurora { sky: Some(sky), .. } => serde_json::to_value(sky.timings()).ok(),
            _ => None,
        }
    }

    /// The frame of the last [`Runner::render`].
    pub(crate) fn last_frame(&self) -> &Frame {
        match self {
            Runner::Flame { renderer, .. } => renderer.frame(),
            Runner::Aurora { sky: Some(sky), .. } => sky.frame(),
            Runner::Aurora { frame, .. } => frame,
            Runner::Snow { frame, .. } => frame,
            Runner::Sparkle { renderer, .. } => renderer.frame(),
        }
    }

    /// Extra image layers of the last render, for EXR: the aurora's five line images
    /// (named `aurora_557_7.Y` etc., rayleighs in physical mode).
    pub(crate) fn layers(&self) -> Vec<(String, &Plane)> {
        match self {
            Runner::Aurora { sky: Some(sky), .. } => phenomena_aurora::emission::Line::ALL
                .iter()
                .zip(sky.line_images())
                .map(|(line, plane)| {
                    (format!("aurora_{}.Y", format!("{:.1}", line.wavelength_nm()).replace('.', "_")), plane)
                })
                .collect(),
            _ => Vec::new(),
        }
    }
}

/// The triangles of a snow scene: its built-in scene, or its mesh file read and parsed
/// (degenerate triangles dropped with a warning on standard error).
pub(crate) fn snow_mesh(s: &crate::scene::SnowScene, scene_dir: &Path) -> Result<phenomena_snow::mesh::Mesh> {
    use phenomena_snow::load;
    let Some(file) = &s.geometry.mesh else {
        let mut mesh = s.geometry.builtin.mesh();
        mesh.clean(1e-12);
        return Ok(mesh);
    };
    let path = scene_dir.join(file);
    let bytes = std::fs::read(&path).with_context(|| format!("cannot read the mesh {}", path.display()))?;
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    let scale = s.geometry.scale;
    let loaded = match ext.as_str() {
        "obj" => load::obj(&bytes, scale),
        "gltf" | "glb" => {
            let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
            load::gltf(&bytes, |uri| std::fs::read(dir.join(uri)).ok(), scale)
        }
        "dxf" => load::dxf(&bytes, scale),
        other => bail!("{}: unknown mesh format `.{other}`: use .obj, .gltf, .glb or .dxf", path.display()),
    }
    .with_context(|| format!("cannot use the mesh {}", path.display()))?;
    let c = loaded.cleaned;
    if c.degenerate + c.non_finite > 0 {
        eprintln!(
            "warning: {}: skipped {} degenerate triangle(s) and {} with non-finite vertices",
            path.display(),
            c.degenerate,
            c.non_finite
        );
    }
    Ok(loaded.mesh)
}

/// Apply command-line overrides to a scene; a view the phenomenon cannot draw is an
/// error naming the ones it can.
pub(crate) fn apply_overrides(scene: &mut Scene, job: &RenderJob) -> Result<()> {
    let s = scene.settings_mut();
    if let Some(w) = job.width {
        s.width = w;
    }
    if let Some(h) = job.height {
        s.height = h;
    }
    if let Some(seed) = job.seed {
        s.seed = seed;
    }
    match (scene, job.view) {
        (_, None) => {}
        (Scene::Flame(f), Some(ViewArg::Flame)) => f.render.view = View::Flame,
        (Scene::Flame(f), Some(ViewArg::Density)) => f.render.view = View::Density,
        (Scene::Aurora(a), Some(ViewArg::Plane)) => a.render.view = AuroraView::Plane,
        (Scene::Aurora(a), Some(ViewArg::Sky)) => a.render.view = AuroraView::Sky,
        (Scene::Snow(s), Some(ViewArg::Scene)) => s.render.view = phenomena_snow::SnowView::Scene,
        (Scene::Snow(s), Some(ViewArg::Probability)) => s.render.view = phenomena_snow::SnowView::Probability,
        (Scene::Flame(_), Some(v)) => bail!("--view {v:?} is not a flame view: use flame or density"),
        (Scene::Aurora(_), Some(v)) => bail!("--view {v:?} is not an aurora view: use sky or plane"),
        (Scene::Snow(_), Some(v)) => bail!("--view {v:?} is not a snow view: use scene or probability"),
        (Scene::Sparkle(_), Some(v)) => {
            bail!("--view {v:?} is not a sparkle view: sparkle scenes have one view")
        }
    }
    Ok(())
}

/// Run a render job; returns a one-line summary.
pub(crate) fn run(job: &RenderJob) -> Result<String> {
    let scene = crate::scene::load(&job.scene_path)?;
    run_scene(scene, job)
}

/// Render an already parsed scene with a job's options (relative asset paths resolve
/// against the directory of `job.scene_path`).
pub(crate) fn run_scene(mut scene: Scene, job: &RenderJob) -> Result<String> {
    apply_overrides(&mut scene, job)?;
    let issues = scene.validate();
    if !issues.is_empty() {
        let list: Vec<String> = issues.iter().map(|i| format!("  {i}")).collect();
        bail!("the command-line options make the scene invalid:\n{}", list.join("\n"));
    }
    let total = scene.settings().frames;
    let range = job.frames.clone().unwrap_or(0..total);
    if range.end > total {
        bail!(
            "--frames {}..{} goes past the scene's {total} frames (0..{total}): choose frames below {total} or raise [scene] frames",
            range.start,
            range.end
        );
    }
    output::ensure_dir(&job.out_dir)?;
    if let Some(stats) = &job.stats {
        if stats.is_dir() {
            bail!("--stats {} is a directory: give a file name", stats.display());
        }
        if let Some(parent) = stats.parent().filter(|p| !p.as_os_str().is_empty()) {
            output::ensure_dir(parent)?;
        }
    }

    let threads = job.threads.unwrap_or(0);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start the worker threads")?;
    let scene_dir = job.scene_path.parent().unwrap_or(Path::new(".")).to_path_buf();
    pool.install(|| render_frames(&scene, &scene_dir, job, range))
}

fn render_frames(scene: &Scene, scene_dir: &Path, job: &RenderJob, range: Range<u32>) -> Result<String> {
    let started = Instant::now();
    let mut runner = Runner::new(scene, scene_dir)?;
    let exposure = scene.settings().exposure();
    let bar = ProgressBar::with_draw_target(
        Some(u64::from(range.end)),
        if job.quiet { ProgressDrawTarget::hidden() } else { ProgressDrawTarget::stderr() },
    );
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} {msg} [{bar:30}] {pos}/{len} frames, {elapsed} elapsed, ETA {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    let mut tally = Tally::default();
    let result = render_loop(&mut runner, job, &range, &exposure, &bar, &mut tally);
    bar.finish_and_clear();
    // The stats of the frames done are written even when a later frame failed.
    if let Some(path) = &job.stats {
        output::write_bytes_atomic(path, tally.stats_text.as_bytes())?;
    }
    result?;
    let Tally { written, skipped, .. } = tally;
    Ok(format!(
        "{}: wrote {written} frame(s){} to {} in {:.1} s",
        scene.phenomenon(),
        if skipped > 0 { format!(", kept {skipped} finished frame(s)") } else { String::new() },
        job.out_dir.display(),
        started.elapsed().as_secs_f64()
    ))
}

/// What a render loop has done so far.
#[derive(Default)]
struct Tally {
    stats_text: String,
    written: u32,
    skipped: u32,
}

fn render_loop(
    runner: &mut Runner,
    job: &RenderJob,
    range: &Range<u32>,
    exposure: &phenomena_core::tonemap::Exposure,
    bar: &ProgressBar,
    tally: &mut Tally,
) -> Result<()> {
    for frame in 0..range.end {
        let t0 = Instant::now();
        let detail = runner.step().with_context(|| format!("simulation failed at frame {frame}"))?;
        let mut stats = FrameStats {
            frame,
            step_ms: t0.elapsed().as_secs_f64() * 1e3,
            render_ms: None,
            render_detail: None,
            write_ms: None,
            skipped: false,
            detail,
        };
        if frame >= range.start {
            let path = job.out_dir.join(format!("frame_{frame:05}.{}", job.format.extension()));
            if job.resume && path.is_file() {
                stats.skipped = true;
                tally.skipped += 1;
                bar.set_message("resuming");
            } else {
                bar.set_message("rendering");
                let t1 = Instant::now();
                runner.render();
                stats.render_ms = Some(t1.elapsed().as_secs_f64() * 1e3);
                stats.render_detail = runner.render_detail();
                let t2 = Instant::now();
                output::write_frame(&path, runner.last_frame(), &runner.layers(), job.format, exposure)?;
                stats.write_ms = Some(t2.elapsed().as_secs_f64() * 1e3);
                tally.written += 1;
            }
            if job.stats.is_some() {
                let line = serde_json::to_string(&stats).context("cannot encode stats")?;
                let _ = writeln!(tally.stats_text, "{line}");
            }
        } else {
            bar.set_message("simulating");
        }
        bar.inc(1);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_ranges() {
        assert_eq!(parse_frame_range("3..7"), Ok(3..7));
        assert_eq!(parse_frame_range("3..=7"), Ok(3..8));
        assert_eq!(parse_frame_range("5"), Ok(5..6));
        assert!(parse_frame_range("7..3").unwrap_err().contains("empty range"));
        assert!(parse_frame_range("a..3").unwrap_err().contains("not a frame number"));
        assert!(parse_frame_range("-1..3").is_err());
    }
}
