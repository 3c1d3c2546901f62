//! `phenomena render` and `simulate`: a scene file's frames through the scene layer's
//! render job ([`phenomena_scene::job`]), with a progress bar, per-frame statistics,
//! signals and the memory budget of the command line.

use std::fmt::Write as _;
use std::ops::{ControlFlow, Range};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use phenomena_core::clock::{Clock, SharedClock};
use phenomena_scene::job::{Job, JobError};
use phenomena_scene::output::{ensure_dir, write_bytes_atomic};
use phenomena_scene::{Assets, BuildError, Format, FrameRecord, Limits, Observer, RunError, Runner, Scene};

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

/// Options of one render, after the command line has been read: the scene layer's
/// [`Job`] and what the command line adds (overrides, threads, statistics).
#[derive(Clone, Debug)]
pub(crate) struct RenderJob {
    pub(crate) job: Job,
    pub(crate) width: Option<u32>,
    pub(crate) height: Option<u32>,
    pub(crate) seed: Option<u64>,
    pub(crate) threads: Option<usize>,
    pub(crate) stats: Option<PathBuf>,
    pub(crate) view: Option<String>,
    pub(crate) quiet: bool,
}

impl RenderJob {
    /// A job writing `format` frames into `out_dir` with every other option at its
    /// default.
    pub(crate) fn new(out_dir: PathBuf, format: Format) -> Self {
        Self {
            job: Job::new(out_dir, format),
            width: None,
            height: None,
            seed: None,
            threads: None,
            stats: None,
            view: None,
            quiet: false,
        }
    }
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
    let total = scene.settings().frames;
    let range = job.job.frames.clone().unwrap_or(0..total);
    let mut progress = Progress::new(range, job.quiet, job.stats.is_some());
    let run = Job { clock: Some(wall_clock()), ..job.job.clone() };
    let located_in = scene.clone();
    CANCELLABLE.store(true, Ordering::SeqCst);
    let result = pool.install(|| phenomena_scene::job::render(scene, assets, &limits(), &run, &mut progress));
    CANCELLABLE.store(false, Ordering::SeqCst);
    progress.bar.finish_and_clear();
    // The stats of the frames done are written even when a later frame failed.
    if let Some(path) = &job.stats {
        write_bytes_atomic(path, progress.stats.as_bytes())?;
    }
    let done = match result {
        Ok(done) => done,
        Err(JobError::Run(RunError::Cancelled { frames })) => bail!(
            "interrupted by a signal after simulating {frames} frame(s): the frames written are whole; render again with --resume to go on"
        ),
        Err(JobError::Build(e)) => return Err(located(&located_in, e)),
        Err(e) => return Err(e.into()),
    };
    Ok(format!("{name}: {} in {:.1} s", done.lines.join("; "), started.elapsed().as_secs_f64()))
}

/// Render the scene file `path`.
pub(crate) fn run(path: &Path, job: &RenderJob) -> Result<String> {
    let scene = phenomena_scene::load(path)?;
    run_scene(scene, &Assets::beside(path), job)
}

/// The progress bar, the `--stats` lines of the frames asked for, and the run's notes
/// as warnings.
struct Progress {
    bar: ProgressBar,
    range: Range<u32>,
    stats: String,
    keep_stats: bool,
    quiet: bool,
}

impl Progress {
    /// Frames up to `range.end` to simulate (from a checkpoint, fewer), those of
    /// `range` written.
    fn new(range: Range<u32>, quiet: bool, keep_stats: bool) -> Self {
        let bar = ProgressBar::with_draw_target(
            Some(u64::from(range.end)),
            if quiet { ProgressDrawTarget::hidden() } else { ProgressDrawTarget::stderr() },
        );
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} {msg} [{bar:30}] {pos}/{len} frames, {elapsed} elapsed, ETA {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        Self { bar, range, stats: String::new(), keep_stats, quiet }
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
        // A run from a checkpoint starts past frame 0.
        self.bar.set_position(u64::from(record.frame) + 1);
        // Checked after the frame's stats are kept: the last frame written has them.
        if INTERRUPTED.load(Ordering::SeqCst) {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }

    fn estimate(&mut self, estimate: &phenomena_scene::Estimate) {
        log_estimate(estimate);
    }

    #[allow(clippy::print_stderr)]
    fn note(&mut self, message: &str) {
        if !self.quiet {
            self.bar.suspend(|| eprintln!("warning: {message}"));
        }
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
