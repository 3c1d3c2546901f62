//! `phenomena render`: a scene file's frames through the scene layer's runner into PNG
//! or EXR files, with a progress bar and per-frame statistics.

use std::fmt::Write as _;
use std::ops::{ControlFlow, Range};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use phenomena_core::clock::{Clock, SharedClock};
use phenomena_scene::flipbook::{Alpha, FlipbookOptions};
use phenomena_scene::output::{
    CheckpointSink, Data, DataSink, FlipbookSink, Format, ImageFormat, ImageSink, ensure_dir,
    list_checkpoints, read_checkpoint, write_bytes_atomic,
};
use phenomena_scene::{
    Assets, BuildError, FrameRecord, FrameSink, Limits, Observer, Only, RunError, Runner, Scene, Simulate,
    Tee, VolumeOptions,
};

/// Set by SIGINT or SIGTERM while a render runs: the render stops after its frame.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);
/// Whether a render that can stop between frames is running.
static CANCELLABLE: AtomicBool = AtomicBool::new(false);

/// Handle SIGINT and SIGTERM (what `timeout`, CI runners and container runtimes send):
/// a render stops after the frame it is on, its finished frames whole and no temporary
/// file left; anything else, or a second signal, exits at once (every file is written
/// under a temporary name and renamed, so no output is ever half-written).
pub(crate) fn handle_signals() {
    let installed = ctrlc::set_handler(|| {
        if CANCELLABLE.load(Ordering::SeqCst) && !INTERRUPTED.swap(true, Ordering::SeqCst) {
            return;
        }
        std::process::exit(130);
    });
    if let Err(e) = installed {
        tracing::warn!("cannot handle SIGINT/SIGTERM: {e}");
    }
}

/// Options of one render, after the command line has been read.
#[derive(Clone, Debug)]
pub(crate) struct RenderJob {
    pub(crate) out_dir: PathBuf,
    pub(crate) frames: Option<Range<u32>>,
    pub(crate) width: Option<u32>,
    pub(crate) height: Option<u32>,
    pub(crate) seed: Option<u64>,
    pub(crate) threads: Option<usize>,
    pub(crate) format: Format,
    /// Voxel size of `vdb` frames (the phenomenon's default when not given).
    pub(crate) volume: VolumeOptions,
    /// Layout of a `flipbook`.
    pub(crate) flipbook: FlipbookArgs,
    pub(crate) resume: bool,
    pub(crate) stats: Option<PathBuf>,
    pub(crate) view: Option<String>,
    pub(crate) quiet: bool,
    /// Write a checkpoint after every this many frames.
    pub(crate) checkpoint_every: Option<u32>,
    /// Where checkpoints are written and looked for (default `OUT/checkpoints`).
    pub(crate) checkpoint_dir: Option<PathBuf>,
    /// Write frames (`false`: `simulate`, checkpoints only).
    pub(crate) images: bool,
}

impl RenderJob {
    /// A job writing `format` frames into `out_dir` with every other option at its
    /// default.
    pub(crate) fn new(out_dir: PathBuf, format: Format) -> Self {
        Self {
            out_dir,
            frames: None,
            width: None,
            height: None,
            seed: None,
            threads: None,
            format,
            volume: VolumeOptions::default(),
            flipbook: FlipbookArgs { power_of_two: false, alpha: Alpha::Straight, loop_frames: 0 },
            resume: false,
            stats: None,
            view: None,
            quiet: false,
            checkpoint_every: None,
            checkpoint_dir: None,
            images: true,
        }
    }

    /// The checkpoint folder: `--checkpoint-dir`, else `OUT/checkpoints`.
    fn checkpoints(&self) -> PathBuf {
        self.checkpoint_dir.clone().unwrap_or_else(|| self.out_dir.join("checkpoints"))
    }
}

/// A flipbook's options from the command line (its rate comes from the scene).
#[derive(Clone, Copy, Debug)]
pub(crate) struct FlipbookArgs {
    pub(crate) power_of_two: bool,
    pub(crate) alpha: Alpha,
    pub(crate) loop_frames: u32,
}

/// Where a render's frames go, by format.
pub(crate) enum Frames {
    Image(ImageSink),
    Data(DataSink),
    Flipbook(FlipbookSink),
}

impl Frames {
    /// The sink for `job`'s format, for `frames` frames of `width × height`.
    pub(crate) fn new(job: &RenderJob, frames: u32, width: u32, height: u32, fps: f64) -> Result<Self> {
        let (dir, resume) = (&job.out_dir, job.resume);
        Ok(match job.format {
            Format::Png => Frames::Image(ImageSink::new(dir, ImageFormat::Png, resume)?),
            Format::Exr => Frames::Image(ImageSink::new(dir, ImageFormat::Exr, resume)?),
            Format::Vdb => Frames::Data(DataSink::new(dir, Data::Volume(job.volume), resume)?),
            Format::Ply => Frames::Data(DataSink::new(dir, Data::Points, resume)?),
            Format::Flipbook => {
                if resume {
                    bail!(
                        "--resume keeps finished frame files; a flipbook is one file made of every frame: render it again without --resume"
                    );
                }
                let f = job.flipbook;
                let options = FlipbookOptions {
                    power_of_two: f.power_of_two,
                    alpha: f.alpha,
                    loop_frames: f.loop_frames,
                    fps,
                };
                Frames::Flipbook(FlipbookSink::new(dir, frames, width, height, options)?)
            }
        })
    }

    /// Whether frame `index` is finished, for formats with files per frame.
    fn finished(&self, index: u32) -> bool {
        match self {
            Frames::Image(s) => s.finished(index),
            Frames::Data(s) => s.finished(index),
            Frames::Flipbook(_) => false,
        }
    }

    pub(crate) fn sink(&mut self) -> &mut dyn FrameSink {
        match self {
            Frames::Image(s) => s,
            Frames::Data(s) => s,
            Frames::Flipbook(s) => s,
        }
    }

    /// What was written, for the summary.
    fn summary(&self, kept_before: u32, dir: &Path) -> String {
        let (written, kept) = match self {
            Frames::Image(s) => (s.written(), s.kept()),
            Frames::Data(s) => (s.written(), s.kept()),
            Frames::Flipbook(s) => {
                let l = s.layout();
                return format!(
                    "wrote a flipbook of {} frame(s) in {}x{} cells of {}x{} ({}x{} pixels) to {}",
                    l.frames,
                    l.columns,
                    l.rows,
                    l.frame_width,
                    l.frame_height,
                    l.atlas_width,
                    l.atlas_height,
                    s.image_path().display()
                );
            }
        };
        let kept = kept + kept_before;
        format!(
            "wrote {written} frame(s){} to {}",
            if kept > 0 { format!(", kept {kept} finished frame(s)") } else { String::new() },
            dir.display()
        )
    }
}

/// Check that writing `frames` fits the memory budget beside `runner`'s simulation,
/// before the first frame: a flipbook's atlas and a volume frame's grids are added to
/// the runner's estimate (a volume's voxel size is checked here too), and volumes are
/// limited to what the budget leaves.
pub(crate) fn admit_outputs(
    runner: &mut Runner,
    frames: &mut Frames,
    format: Format,
    scene: &Scene,
    budget: &Limits,
) -> Result<()> {
    let room = budget.memory_bytes.saturating_sub(runner.estimate().memory_bytes);
    let parts = match frames {
        Frames::Flipbook(s) => vec![("the flipbook's atlas".to_string(), s.memory_bytes())],
        Frames::Data(s) => match s.data() {
            Data::Volume(options) => {
                let bytes =
                    runner.volume_bytes(&options).map_err(|e| anyhow::anyhow!("--format vdb: {e}"))?;
                s.limit_volumes(room);
                vec![("a volume frame".to_string(), bytes)]
            }
            Data::Points => Vec::new(),
        },
        Frames::Image(_) => Vec::new(),
    };
    runner
        .admit(parts, budget)
        .map_err(|e| anyhow::anyhow!("--format {}: {:#}", format.name(), located(scene, e)))
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

/// The wall clock, for the timings in `--stats` and the studio.
pub(crate) struct WallClock(Instant);

impl Clock for WallClock {
    fn now_ms(&self) -> f64 {
        self.0.elapsed().as_secs_f64() * 1e3
    }
}

/// A shared wall clock.
pub(crate) fn wall_clock() -> SharedClock {
    SharedClock::new(WallClock(Instant::now()))
}

/// The memory budget of this run, GiB (`--max-memory-gib`), when given.
static BUDGET_GIB: std::sync::OnceLock<Option<f64>> = std::sync::OnceLock::new();

/// Take `--max-memory-gib`.
pub(crate) fn set_budget(gib: Option<f64>) {
    let _ = BUDGET_GIB.set(gib);
}

/// The memory budget: `--max-memory-gib`, or three quarters of the machine's memory
/// (`MemTotal` of /proc/meminfo; no limit where that cannot be read).
pub(crate) fn limits() -> Limits {
    let gib = BUDGET_GIB.get().copied().flatten();
    let bytes = match gib {
        Some(g) => (g * f64::from(1u32 << 30)) as u64,
        None => machine_memory_bytes().map_or(u64::MAX, |m| m / 4 * 3),
    };
    Limits { memory_bytes: bytes }
}

/// The machine's memory, bytes, from /proc/meminfo.
fn machine_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// With `-v`: a scene's memory estimate by part and its work per frame.
pub(crate) fn log_estimate(estimate: &phenomena_scene::Estimate) {
    tracing::info!(
        "estimate: {} of memory; per frame: {}",
        phenomena_scene::gib(estimate.memory_bytes),
        estimate.work
    );
    for (what, bytes) in &estimate.parts {
        tracing::info!("  {what}: {}", phenomena_scene::gib(*bytes));
    }
}

/// Build `scene`'s runner within the memory budget; a problem with a file the scene
/// names is reported at that key's line and column when the scene came from a file.
pub(crate) fn runner(scene: &Scene, assets: &Assets) -> Result<Runner> {
    Runner::with_limits(scene, assets, &limits()).map_err(|e| located(scene, e))
}

/// A build error, located in the scene file where it has a key (each problem of an
/// invalid configuration at its own key).
pub(crate) fn located(scene: &Scene, e: BuildError) -> anyhow::Error {
    if let BuildError::OverBudget { estimate, .. } = &e {
        log_estimate(estimate);
        return anyhow::anyhow!(
            "{e}: lower the scene's size or counts, or raise the budget with --max-memory-gib (-v shows the estimate by part)"
        );
    }
    if let BuildError::Invalid(issues) = &e {
        let lines: Vec<String> = issues
            .iter()
            .map(|i| scene.locate(&i.field, i.to_string()).map_or_else(|| i.to_string(), |at| at.to_string()))
            .collect();
        return anyhow::anyhow!("{}", lines.join("\n"));
    }
    match e.key().and_then(|key| scene.locate(key, e.to_string())) {
        Some(at) => anyhow::anyhow!("{at}"),
        None => anyhow::anyhow!("{e}"),
    }
}

/// Print the runner's warnings.
#[allow(clippy::print_stderr)]
pub(crate) fn warn(runner: &Runner) {
    for w in runner.warnings() {
        eprintln!("warning: {w}");
    }
}

/// Apply command-line overrides to a scene; a view the phenomenon cannot draw is an
/// error naming the ones it can.
pub(crate) fn apply_overrides(scene: &mut Scene, job: &RenderJob) -> Result<()> {
    if let Some(view) = &job.view {
        scene.set_view(view).map_err(|e| anyhow::anyhow!("--view {e}"))?;
    }
    if job.width.is_none() && job.height.is_none() && job.seed.is_none() {
        return Ok(());
    }
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
    Ok(())
}

/// Render an already parsed scene with a job's options, reading its files through
/// `assets`; returns a one-line summary.
pub(crate) fn run_scene(mut scene: Scene, assets: &Assets, job: &RenderJob) -> Result<String> {
    let name = scene.phenomenon().name();
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
    if job.images {
        scene.supports(job.format).map_err(|e| anyhow::anyhow!("--format {}: {e}", job.format.name()))?;
        if job.format == Format::Flipbook {
            scene.emission_only().map_err(anyhow::Error::msg)?;
        }
    }
    let (width, height) = (scene.settings().width, scene.settings().height);
    let fps = frame_rate(&scene);
    let mut images =
        if job.images { Some(Frames::new(job, range.len() as u32, width, height, fps)?) } else { None };
    let checkpoint_dir = job.checkpoints();
    if checkpoint_dir.exists() && !checkpoint_dir.is_dir() {
        bail!("--checkpoint-dir {} is a file, not a folder", checkpoint_dir.display());
    }
    let mut checkpoints =
        job.checkpoint_every.map(|n| CheckpointSink::new(&checkpoint_dir, n)).transpose()?;
    if let Some(stats) = &job.stats {
        if stats.is_dir() {
            bail!("--stats {} is a directory: give a file name", stats.display());
        }
        if let Some(parent) = stats.parent().filter(|p| !p.as_os_str().is_empty()) {
            ensure_dir(parent)?;
        }
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(job.threads.unwrap_or(0))
        .build()
        .context("cannot start the worker threads")?;
    let started = Instant::now();
    let mut started_at = 0;
    pool.install(|| -> Result<()> {
        let mut runner = runner(&scene, assets)?;
        if let Some(frames) = images.as_mut() {
            admit_outputs(&mut runner, frames, job.format, &scene, &limits())?;
        }
        log_estimate(runner.estimate());
        warn(&runner);
        // The first frame to make: with --resume, the first whose file is missing.
        let first = match &images {
            Some(sink) if job.resume => {
                range.clone().find(|&i| !sink.finished(i)).unwrap_or(range.end)
            }
            _ => range.start,
        };
        started_at = restore_newest(&mut runner, &checkpoint_dir, first, job.quiet);
        runner.set_clock(wall_clock());
        let mut progress = Progress::new(range.clone(), started_at, job.quiet, job.stats.is_some());
        let mut nothing = Simulate;
        let image_sink: &mut dyn FrameSink = match images.as_mut() {
            Some(s) => s.sink(),
            None => &mut nothing,
        };
        let mut only = Only { frames: range.clone(), sink: image_sink };
        let mut sinks: Vec<&mut dyn FrameSink> = vec![&mut only];
        if let Some(c) = checkpoints.as_mut() {
            sinks.push(c);
        }
        let mut tee = Tee::new(sinks);
        CANCELLABLE.store(true, Ordering::SeqCst);
        let result = runner.run(started_at..range.end, &mut tee, &mut progress);
        CANCELLABLE.store(false, Ordering::SeqCst);
        progress.bar.finish_and_clear();
        // The stats of the frames done are written even when a later frame failed.
        if let Some(path) = &job.stats {
            write_bytes_atomic(path, progress.stats.as_bytes())?;
        }
        match result {
            Err(RunError::Cancelled { frames }) => bail!(
                "interrupted by a signal after simulating {frames} frame(s): the frames written are whole; render again with --resume to go on"
            ),
            other => Ok(other?),
        }
    })?;
    let mut parts = Vec::new();
    if let Some(sink) = &images {
        // With --resume, the frames before the checkpoint it started from exist too.
        let before = if job.resume { started_at.saturating_sub(range.start) } else { 0 };
        parts.push(sink.summary(before, &job.out_dir));
    }
    if let Some(c) = &checkpoints {
        parts.push(format!("wrote {} checkpoint(s) to {}", c.written(), checkpoint_dir.display()));
    }
    if started_at > 0 {
        parts.push(format!("started from the checkpoint at frame {started_at}"));
    }
    if parts.is_empty() {
        parts.push(format!("simulated frames {started_at}..{}", range.end));
    }
    Ok(format!("{name}: {} in {:.1} s", parts.join("; "), started.elapsed().as_secs_f64()))
}

/// A scene's frames per second for a flipbook. The frame time is an f32 of the scene
/// (1/60 reads back as 59.99999...): the rate to a thousandth of a frame per second.
pub(crate) fn frame_rate(scene: &Scene) -> f64 {
    (1e3 / scene.frame_time_s()).round() / 1e3
}

/// Continue `runner` from the newest checkpoint in `dir` from which frame `first` can
/// be reached (frames simulated ≤ `first`), trying older ones when one is refused
/// (damaged, of another scene or seed); returns the frames simulated (0: none used,
/// simulate from the start). Each refusal is reported.
#[allow(clippy::print_stderr)]
fn restore_newest(runner: &mut Runner, dir: &Path, first: u32, quiet: bool) -> u32 {
    let candidates = list_checkpoints(dir);
    if let Some(why) = runner.render_memory()
        && first > 0
    {
        if !quiet && !candidates.is_empty() {
            eprintln!(
                "note: {why}, which checkpoints do not hold: rendering every frame from 0 (frames before {first} are not written)"
            );
        }
        return 0;
    }
    // The state read and the simulation built must fit the budget together.
    let room = limits().memory_bytes.saturating_sub(runner.estimate().memory_bytes);
    for (_, path) in candidates.iter().rev().filter(|(f, _)| *f <= first && *f > 0) {
        let refused = match read_checkpoint(path, room) {
            Ok(bytes) => match phenomena_scene::checkpoint::open(&bytes) {
                // Named for an earlier frame than it holds (renamed by hand): not usable
                // for `first`.
                Ok((header, _)) if header.frames_done > u64::from(first) => {
                    format!("it holds frame {}, after frame {first}", header.frames_done)
                }
                Ok(_) => match runner.restore(&bytes) {
                    Ok(done) => return done,
                    Err(e) => e.to_string(),
                },
                Err(e) => e.to_string(),
            },
            Err(e) => e.to_string(),
        };
        eprintln!("warning: checkpoint {} not used: {refused}", path.display());
    }
    if first > 0 && !quiet && !candidates.is_empty() {
        eprintln!(
            "note: no usable checkpoint at or before frame {first} in {}: simulating from frame 0",
            dir.display()
        );
    }
    0
}

/// Render the scene file `path`.
pub(crate) fn run(path: &Path, job: &RenderJob) -> Result<String> {
    let scene = phenomena_scene::load(path)?;
    run_scene(scene, &Assets::beside(path), job)
}

/// The progress bar and the `--stats` lines of the frames asked for.
struct Progress {
    bar: ProgressBar,
    range: Range<u32>,
    stats: String,
    keep_stats: bool,
}

impl Progress {
    /// Frames `from..range.end` to simulate, those of `range` written.
    fn new(range: Range<u32>, from: u32, quiet: bool, keep_stats: bool) -> Self {
        let bar = ProgressBar::with_draw_target(
            Some(u64::from(range.end.saturating_sub(from))),
            if quiet { ProgressDrawTarget::hidden() } else { ProgressDrawTarget::stderr() },
        );
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} {msg} [{bar:30}] {pos}/{len} frames, {elapsed} elapsed, ETA {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        Self { bar, range, stats: String::new(), keep_stats }
    }
}

impl Observer for Progress {
    fn frame(&mut self, record: &FrameRecord) -> ControlFlow<()> {
        let wanted = self.range.contains(&record.frame);
        self.bar.set_message(match (wanted, record.skipped) {
            (false, _) => "simulating",
            (true, true) => "resuming",
            (true, false) => "rendering",
        });
        if wanted
            && self.keep_stats
            && let Ok(line) = serde_json::to_string(record)
        {
            let _ = writeln!(self.stats, "{line}");
        }
        self.bar.inc(1);
        // Checked after the frame's stats are kept: the last frame written has them.
        if INTERRUPTED.load(Ordering::SeqCst) {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }
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
