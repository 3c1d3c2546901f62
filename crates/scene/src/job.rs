//! A render to files, whole: the frames asked for in an output format, resumed where an
//! earlier run stopped, started from the newest usable checkpoint, writing checkpoints
//! on the way, and refused before the first frame when its outputs cannot fit the
//! memory budget. `phenomena render` and `simulate`, `demo`, the farm's tasks and the
//! studio's final renders all run [`render`].
//!
//! ```
//! use phenomena_scene::job::{self, Job};
//! use phenomena_scene::{Assets, Format, Limits, load};
//!
//! let path = std::path::Path::new("../../scenes/flame-paper.toml");
//! let out = std::env::temp_dir().join("phenomena-job-doc");
//! let exr = Format::named("exr").expect("a registered format");
//! let job = Job { frames: Some(2..4), ..Job::new(&out, exr) };
//! let done = job::render(load(path)?, &Assets::beside(path), &Limits::NONE, &job, &mut ())?;
//! assert!(done.lines[0].starts_with("wrote 2 frame(s)"));
//! assert!(out.join("frame_00003.exr").is_file());
//! # std::fs::remove_dir_all(&out)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::ops::Range;
use std::path::{Path, PathBuf};

use phenomena_core::clock::SharedClock;

use crate::assets::Assets;
use crate::budget::Limits;
use crate::error::{BuildError, RunError, SinkError};
use crate::format::{Format, OutputOptions, Target};
use crate::output::{CheckpointSink, Files, list_checkpoints, read_checkpoint};
use crate::runner::Runner;
use crate::scene::Scene;
use crate::sink::{FrameSink, Observer, Only, Simulate, Tee};

/// What to render and where.
#[derive(Clone, Debug)]
pub struct Job {
    /// The folder of the frames.
    pub out_dir: PathBuf,
    /// The frames written (earlier ones are simulated); `None`: all of the scene's.
    pub frames: Option<Range<u32>>,
    /// The output format.
    pub format: Format,
    /// The formats' options.
    pub options: OutputOptions,
    /// Keep the frames an earlier run finished.
    pub resume: bool,
    /// Write a checkpoint after every this many frames.
    pub checkpoint_every: Option<u32>,
    /// Where checkpoints are written and looked for (default `OUT/checkpoints`).
    pub checkpoint_dir: Option<PathBuf>,
    /// Write frames (`false`: simulate only, writing checkpoints).
    pub images: bool,
    /// The clock that times steps and renders (none: every timing is 0).
    pub clock: Option<SharedClock>,
}

impl Job {
    /// Every frame of the scene in `format` into `out_dir`, nothing else.
    pub fn new(out_dir: impl Into<PathBuf>, format: Format) -> Self {
        Self {
            out_dir: out_dir.into(),
            frames: None,
            format,
            options: OutputOptions::default(),
            resume: false,
            checkpoint_every: None,
            checkpoint_dir: None,
            images: true,
            clock: None,
        }
    }

    /// The checkpoint folder: [`Job::checkpoint_dir`], else `OUT/checkpoints`.
    pub fn checkpoints(&self) -> PathBuf {
        self.checkpoint_dir.clone().unwrap_or_else(|| self.out_dir.join("checkpoints"))
    }
}

/// What a render did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Done {
    /// What was written, a line each (frames, checkpoints, where it started).
    pub lines: Vec<String>,
    /// The frame the simulation started from (a checkpoint's; 0: the beginning).
    pub started_at: u32,
}

/// Why a render did not finish.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// The job does not fit the scene (frames past its end, a format it cannot be
    /// written in, ...).
    #[error("{0}")]
    Refused(String),
    /// The simulation or renderer could not be built, or the outputs do not fit the
    /// budget.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// A file could not be written.
    #[error(transparent)]
    Sink(#[from] SinkError),
    /// The run stopped.
    #[error(transparent)]
    Run(#[from] RunError),
}

/// Render `scene` as `job` says, its files read through `assets`, within `limits`;
/// every frame is reported to `observer`, and so is each checkpoint not used.
pub fn render(
    mut scene: Scene,
    assets: &Assets,
    limits: &Limits,
    job: &Job,
    observer: &mut dyn Observer,
) -> Result<Done, JobError> {
    let total = scene.settings().frames;
    let range = job.frames.clone().unwrap_or(0..total);
    if range.end > total {
        return Err(JobError::Refused(format!(
            "--frames {}..{} goes past the scene's {total} frames (0..{total}): choose frames below {total} or raise [scene] frames",
            range.start, range.end
        )));
    }
    let mut files = if job.images { Some(open_files(&mut scene, job, &range)?) } else { None };
    let checkpoint_dir = job.checkpoints();
    if checkpoint_dir.exists() && !checkpoint_dir.is_dir() {
        return Err(JobError::Refused(format!(
            "--checkpoint-dir {} is a file, not a folder",
            checkpoint_dir.display()
        )));
    }
    let mut checkpoints =
        job.checkpoint_every.map(|n| CheckpointSink::new(&checkpoint_dir, n)).transpose()?;
    let mut runner = Runner::with_limits(&scene, assets, limits)?;
    if let Some(files) = files.as_mut() {
        admit(&mut runner, files.as_mut(), limits)?;
    }
    observer.estimate(runner.estimate());
    for w in runner.warnings() {
        observer.note(w);
    }
    // The first frame to make: with `resume`, the first not finished.
    let first = match &files {
        Some(f) if job.resume => range.clone().find(|&i| !f.finished(i)).unwrap_or(range.end),
        _ => range.start,
    };
    let started_at = restore_newest(&mut runner, &checkpoint_dir, first, limits, observer);
    if let Some(clock) = &job.clock {
        runner.set_clock(clock.clone());
    }
    let mut nothing = Simulate;
    let frames: &mut dyn FrameSink = match files.as_mut() {
        Some(f) => f.as_mut(),
        None => &mut nothing,
    };
    let mut only = Only { frames: range.clone(), sink: frames };
    let mut sinks: Vec<&mut dyn FrameSink> = vec![&mut only];
    if let Some(c) = checkpoints.as_mut() {
        sinks.push(c);
    }
    runner.run(started_at..range.end, &mut Tee::new(sinks), observer)?;
    let mut lines = Vec::new();
    if let Some(f) = &files {
        lines.push(summary(f.as_ref(), job, started_at.saturating_sub(range.start)));
    }
    if let Some(c) = &checkpoints {
        lines.push(format!("wrote {} checkpoint(s) to {}", c.written(), checkpoint_dir.display()));
    }
    if started_at > 0 {
        lines.push(format!("started from the checkpoint at frame {started_at}"));
    }
    if lines.is_empty() {
        lines.push(format!("simulated frames {started_at}..{}", range.end));
    }
    Ok(Done { lines, started_at })
}

/// The files of `job`'s format for the frames of `range`, the scene prepared for it.
fn open_files(scene: &mut Scene, job: &Job, range: &Range<u32>) -> Result<Box<dyn Files>, JobError> {
    let format = job.format;
    let refused = |e: String| JobError::Refused(format!("--format {}: {e}", format.name()));
    format.check(scene.phenomenon()).map_err(refused)?;
    format.prepare(scene).map_err(refused)?;
    let (w, h) = (scene.settings().width, scene.settings().height);
    let target = Target {
        phenomenon: scene.phenomenon(),
        dir: &job.out_dir,
        frames: range.len() as u32,
        size: (w, h),
        fps: frame_rate(scene),
        resume: job.resume,
        options: &job.options,
    };
    Ok(format.open(&target)?)
}

/// A scene's frames per second for a flipbook. The frame time is an f32 of the scene
/// (1/60 reads back as 59.99999...): the rate to a thousandth of a frame per second.
pub fn frame_rate(scene: &Scene) -> f64 {
    (1e3 / scene.frame_time_s()).round() / 1e3
}

/// Check that writing `files` fits the budget beside `runner`'s simulation, before the
/// first frame: what they hold at their peak (a flipbook's atlas, a volume frame's
/// grids, which also checks the voxel size) is added to the runner's estimate, and
/// they are limited to what the budget leaves.
fn admit(runner: &mut Runner, files: &mut dyn Files, limits: &Limits) -> Result<(), JobError> {
    let room = limits.memory_bytes.saturating_sub(runner.estimate().memory_bytes);
    let bytes = files.memory_bytes(runner.state())?;
    files.limit_memory(room);
    if bytes > 0 {
        runner.admit(vec![("writing the frames".to_string(), bytes)], limits)?;
    }
    Ok(())
}

/// What `files` wrote, with the frames a resumed run found before its checkpoint.
fn summary(files: &dyn Files, job: &Job, before_checkpoint: u32) -> String {
    if !job.resume || before_checkpoint == 0 {
        return files.summary(&job.out_dir);
    }
    // With resume, the frames before the checkpoint it started from exist too.
    let (written, kept) = files.counts();
    let kept = kept + before_checkpoint;
    format!("wrote {written} frame(s), kept {kept} finished frame(s) to {}", job.out_dir.display())
}

/// Continue `runner` from the newest checkpoint in `dir` from which frame `first` can
/// be reached (frames simulated ≤ `first`), trying older ones when one is refused
/// (damaged, of another scene or seed, larger than the budget leaves); returns the
/// frames simulated (0: none used, simulate from the start). Each refusal is a note.
fn restore_newest(
    runner: &mut Runner,
    dir: &Path,
    first: u32,
    limits: &Limits,
    observer: &mut dyn Observer,
) -> u32 {
    let candidates = list_checkpoints(dir);
    if let Some(why) = runner.render_memory()
        && first > 0
    {
        if !candidates.is_empty() {
            observer.note(&format!(
                "{why}, which checkpoints do not hold: rendering every frame from 0 (frames before {first} are not written)"
            ));
        }
        return 0;
    }
    // The state read and the simulation built must fit the budget together.
    let room = limits.memory_bytes.saturating_sub(runner.estimate().memory_bytes);
    for (_, path) in candidates.iter().rev().filter(|(f, _)| *f <= first && *f > 0) {
        let refused = match read_checkpoint(path, room) {
            Ok(bytes) => match crate::checkpoint::open(&bytes) {
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
        observer.note(&format!("checkpoint {} not used: {refused}", path.display()));
    }
    if first > 0 && !candidates.is_empty() {
        observer.note(&format!(
            "no usable checkpoint at or before frame {first} in {}: simulating from frame 0",
            dir.display()
        ));
    }
    0
}
