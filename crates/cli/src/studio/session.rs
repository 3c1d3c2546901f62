//! One studio session (one browser tab): its scenes (one per phenomenon tab), their
//! simulations and timelines, and the thread that steps, renders and encodes the
//! preview.
//!
//! Protocol. The page sends JSON text messages with a `type` ([`Incoming`]). The
//! session answers with JSON text (`hello`, `scene`, `time`, `frame`, `notice`,
//! `error`, `saved`, `progress`, `rendered`) and binary preview frames: a header of four
//! little-endian `u32` (generation, frame, width, height) followed by a JPEG. A
//! `frame` text message with the frame's timings and counters precedes each image.
//!
//! Time. A tab's preview is a timeline of the scene's frames, numbered as final renders
//! number them (frame `f` is the state after `f + 1` steps). It plays at the scene's
//! own rate ([`preview_fps`]), loops or stops at the scene's length, and any frame can
//! be shown (`seek`): simulation states are kept in memory ([`Timeline`]) so going back
//! does not simulate again from frame 0. A change keeps the frame shown: when only how
//! frames are drawn changed (the checkpoint's identity and seed are the new scene's:
//! `[render]`, and `[scene]` but its seed), the new renderer takes over the running
//! simulation's state; otherwise the simulation runs again from frame 0 to that frame,
//! and the `time` message says which (`change`). A runner steered live (the flame's
//! wind) no longer simulates its scene from frame 0: it keeps and carries no state.
//!
//! Every accepted scene change increments the generation; the page ignores frames of
//! older generations, and the thread drains every queued command before it renders, so
//! no stale frame is computed after a change arrives. Each tab keeps its own undo and
//! redo history and the scene it was loaded or saved as (`dirty`).
//!
//! The scene, its simulation and its frames all come from the scene layer
//! (`phenomena_scene`): the preview and the final renders run its [`Runner`], and every
//! file a scene reads comes through its sandbox ([`Assets::Sandbox`]): only the files
//! uploaded to this session, by plain name.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, TryRecvError};
use std::time::{Duration, Instant};

use phenomena_aurora::editor::{self, Drawn, EditOp};
use phenomena_scene::aurora::AuroraScene;
use phenomena_scene::output::to_srgb8;
use phenomena_scene::{
    Assets, Format, FrameRecord, FrameSink, Limits, Output, Runner, Scene, Simulate, SinkError, Steer,
    registry, shipped,
};
use serde::Deserialize;
use serde_json::{Value, json};

use super::final_render::{self, Request};
use super::timeline::Timeline;

/// A message to the page.
pub(crate) enum Out {
    /// JSON text.
    Text(String),
    /// A preview frame (header + JPEG).
    Binary(Vec<u8>),
}

/// Largest preview, pixels per side.
const MAX_PREVIEW_SIDE: u32 = 1920;

/// Edits a tab remembers for undo.
const MAX_UNDO: usize = 200;

/// The preview's rate, frames per second: the scene's own (1 / its frame time) for
/// phenomena shown in real time (frame times from 1/60 s to 1 s: the flame at 60, the
/// aurora and sparkle at 30), 30 for time-lapse scenes (the snow's frames are hours).
/// Never over 60: the rest of the machine stays free for other tabs and final renders.
pub(crate) fn preview_fps(scene: &Scene) -> f64 {
    let t = scene.frame_time_s();
    if !t.is_finite() || t <= 0.0 || t > 1.0 { 30.0 } else { (1.0 / t).min(60.0) }
}

/// What the page may send.
#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub(crate) enum Incoming {
    /// Open a phenomenon's tab: its scene, simulation and frame as they were left, or
    /// its first shipped scene the first time.
    Tab {
        phenomenon: String,
    },
    /// Load a shipped scene by name (see `hello.builtins`).
    Builtin {
        name: String,
    },
    /// Load a scene in its JSON form (what `scene` messages carry: a preset the page
    /// kept), named `name`.
    Scene {
        phenomenon: String,
        scene: Value,
        #[serde(default)]
        name: Option<String>,
    },
    /// Load a scene file's text (errors come back with line and column).
    Toml {
        text: String,
        name: Option<String>,
    },
    /// Set one parameter: a dotted path into the scene (`flame.emitter.rate_per_s`).
    /// Setting the value it has does nothing, unless `reload` (a file of that name
    /// was uploaded again).
    Set {
        path: String,
        value: Value,
        #[serde(default)]
        reload: bool,
    },
    Play,
    Pause,
    /// One frame on (pauses).
    Step,
    /// Show frame `frame` (pauses): from the nearest state kept at or before it.
    Seek {
        frame: u32,
    },
    /// Loop at the scene's end (`true`, the default) or stop there.
    Loop {
        on: bool,
    },
    /// Back to frame 0 of the same scene.
    Reset,
    /// Undo the tab's last edit.
    Undo,
    /// Redo the last edit undone.
    Redo,
    /// The preview size in pixels.
    Preview {
        width: u32,
        height: u32,
    },
    /// The flame's wind force density, N/m³ (the paper's §6 mouse drag), applied live;
    /// `start` begins a new drag (one undo entry per drag).
    Wind {
        force: [f32; 3],
        #[serde(default)]
        start: bool,
    },
    /// An aurora editing operation (thesis §3.1; `phenomena_aurora::editor`).
    Aurora(EditOp),
    /// Ask for the scene as TOML (for download), saved as `name` (default: the
    /// scene's name).
    Save {
        #[serde(default)]
        name: Option<String>,
    },
    /// Render the scene at its own size to the studio's output folder.
    RenderFinal(Request),
    /// Tests only: a command that fails inside the session thread.
    #[cfg(test)]
    Panic,
}

/// A command to the session thread.
pub(crate) enum Command {
    Page(Box<Incoming>),
    /// The snow mesh of the current state as GLB (for the download route).
    SnowGlb(tokio::sync::oneshot::Sender<Result<Vec<u8>, String>>),
    /// The tab closed.
    Close,
}

/// Parse a page message; the error is a sentence for the page.
pub(crate) fn parse_command(text: &str) -> Result<Command, String> {
    serde_json::from_str::<Incoming>(text)
        .map(|m| Command::Page(Box::new(m)))
        .map_err(|e| format!("malformed message: {e}"))
}

/// The first message of a session.
pub(crate) fn hello(id: &str, controls: &super::controls::Catalogue) -> String {
    json!({
        "type": "hello",
        "session": id,
        "phenomena": registry::PHENOMENA
            .iter()
            .map(|p| {
                let formats: Vec<&str> = Format::of(*p).iter().map(|f| f.name()).collect();
                json!({"name": p.name(), "about": p.about(), "formats": formats})
            })
            .collect::<Vec<_>>(),
        "builtins": shipped::SHIPPED
            .iter()
            .map(|b| json!({"name": b.name, "phenomenon": b.phenomenon, "title": b.title}))
            .collect::<Vec<_>>(),
        "featured": controls.featured(),
        "limits": { "upload_bytes": super::MAX_UPLOAD_BYTES, "message_bytes": super::MAX_MESSAGE_BYTES },
    })
    .to_string()
}

/// A scene from its JSON form (not validated).
pub(crate) fn scene_from_json(phenomenon: &str, v: Value) -> Result<Scene, String> {
    registry::phenomenon(phenomenon)
        .ok_or_else(|| format!("unknown phenomenon `{phenomenon}`: use {}", registry::names()))?
        .scene_from_json(v)
}

/// The scene as a TOML file `phenomena render` accepts.
pub(crate) fn scene_toml(scene: &Scene) -> Result<String, String> {
    Ok(format!(
        "# Saved by phenomena studio. Render it with:\n#   phenomena render {}.toml --out out\n\n{}",
        scene.phenomenon().name(),
        scene.to_toml()?
    ))
}

/// A scene's name as the studio shows it and names its renders by: at most 64
/// letters, digits, spaces, dots, `-` and `_` (others become `_`), not starting with a
/// dot; `None` when nothing is left.
fn plain_name(name: &str) -> Option<String> {
    let plain: String = name
        .trim()
        .chars()
        .take(64)
        .map(|c| if c.is_ascii_alphanumeric() || " ._-".contains(c) { c } else { '_' })
        .collect();
    let plain = plain.trim_start_matches('.').trim().to_string();
    (!plain.is_empty()).then_some(plain)
}

/// The session's files: only what was uploaded to it, by plain name, each at most the
/// upload cap.
fn sandbox(dir: &Path) -> Assets {
    Assets::Sandbox { dir: dir.to_path_buf(), max_bytes: super::MAX_UPLOAD_BYTES as u64 }
}

/// A tab's scene at one point of its history.
#[derive(Clone)]
struct Snapshot {
    scene: Scene,
    drawn: Drawn,
    /// For the scene before a file or preset was opened: its name and what it was
    /// opened or saved as (an edit keeps both).
    file: Option<(String, Scene)>,
}

/// One phenomenon tab: its scene, simulation, timeline and edit history.
struct Tab {
    scene: Scene,
    /// The aurora editor's record of the sheets the artist drew.
    drawn: Drawn,
    /// The scene's name (final renders' folders, saving): the shipped scene's, the
    /// uploaded file's, or what it was saved as.
    name: String,
    /// What the scene was when loaded or last saved (the page's dirty marker).
    baseline: Scene,
    runner: Option<Runner>,
    timeline: Timeline,
    /// The frame shown (as final renders number them).
    frame: u32,
    /// The frame being reached (simulating or restoring), if not shown yet.
    target: Option<u32>,
    /// The preview size the runner renders at.
    size: (u32, u32),
    undo: Vec<Snapshot>,
    redo: Vec<Snapshot>,
    /// What the last undo entry stands for when consecutive edits make one (`wind`).
    coalesce: Option<&'static str>,
    /// The runner was steered live (the flame's wind): its state is no longer what
    /// its scene gives, so it is not kept or carried over.
    steered: bool,
    /// The simulation's state while the tab is put aside (its runner is dropped).
    parked: Option<Vec<u8>>,
}

impl Tab {
    fn new(scene: Scene, name: String, budget: usize) -> Self {
        Self {
            drawn: scene.get::<AuroraScene>().map(|a| Drawn::of(&a.aurora)).unwrap_or_default(),
            baseline: scene.clone(),
            scene,
            name,
            runner: None,
            timeline: Timeline::new(budget),
            frame: 0,
            target: None,
            size: (0, 0),
            undo: Vec::new(),
            redo: Vec::new(),
            coalesce: None,
            steered: false,
            parked: None,
        }
    }

    /// The scene's frames (the timeline's length).
    fn length(&self) -> u32 {
        self.scene.settings().frames.max(1)
    }

    /// The scene now, with its name and baseline when `file`.
    fn snapshot(&self, file: bool) -> Snapshot {
        Snapshot {
            scene: self.scene.clone(),
            drawn: self.drawn.clone(),
            file: file.then(|| (self.name.clone(), self.baseline.clone())),
        }
    }

    /// Take `s` as the tab's scene.
    fn take(&mut self, s: Snapshot) {
        self.scene = s.scene;
        self.drawn = s.drawn;
        if let Some((name, baseline)) = s.file {
            (self.name, self.baseline) = (name, baseline);
        }
    }

    /// Record the scene now for undo before an edit (`opening`: a file or preset
    /// replaces it); consecutive edits with the same `coalesce` make one entry (a wind
    /// drag's many messages).
    fn remember(&mut self, coalesce: Option<&'static str>, opening: bool) {
        if coalesce.is_none() || self.coalesce != coalesce {
            self.undo.push(self.snapshot(opening));
            if self.undo.len() > MAX_UNDO {
                self.undo.remove(0);
            }
        }
        self.coalesce = coalesce;
        self.redo.clear();
    }
}

struct Session {
    dir: tempfile::TempDir,
    out_root: PathBuf,
    out: tokio::sync::mpsc::Sender<Out>,
    /// The tab shown.
    tab: Option<Tab>,
    /// The other tabs, as they were left, by phenomenon.
    stash: HashMap<&'static str, Tab>,
    generation: u32,
    playing: bool,
    looping: bool,
    preview: (u32, u32),
    next_due: Instant,
    /// When the page last saw a frame of a catch-up (`None`: a catch-up starts).
    told: Option<Instant>,
    render_cancel: Option<Arc<AtomicBool>>,
    /// The final render running, if any (one at a time per session).
    render_thread: Option<std::thread::JoinHandle<()>>,
    /// This session's share of the memory budget (previews and final renders).
    limits: Limits,
    encoder: std::sync::mpsc::SyncSender<EncodeJob>,
}

/// A preview frame for the encoder thread.
struct EncodeJob {
    /// generation, frame, width, height.
    header: [u32; 4],
    /// 8-bit sRGB, interleaved.
    rgb: Vec<u8>,
    /// The `frame` message, completed with `encode_ms`.
    stats: Value,
}

/// The preview as a frame sink: each frame tone mapped here, JPEG-encoded on the
/// encoder thread (which overlaps the next step).
struct PreviewSink<'a> {
    generation: u32,
    /// The frame shown (as final renders number them).
    shown: u32,
    /// The scene's frames.
    length: u32,
    encoder: &'a std::sync::mpsc::SyncSender<EncodeJob>,
}

impl FrameSink for PreviewSink<'_> {
    fn write(&mut self, out: &Output<'_>) -> Result<(), SinkError> {
        let t = Instant::now();
        let rgb = to_srgb8(out.frame, &out.exposure);
        let (w, h) = (out.frame.width() as u32, out.frame.height() as u32);
        let r = out.record;
        let stats = json!({
            "type": "frame",
            "generation": self.generation,
            "frame": self.shown,
            "length": self.length,
            "step_ms": r.step_ms,
            "render_ms": r.render_ms,
            "ahead_ms": r.ahead_ms,
            "tonemap_ms": t.elapsed().as_secs_f64() * 1e3,
            "counters": r.counters,
        });
        let job = EncodeJob { header: [self.generation, self.shown, w, h], rgb, stats };
        self.encoder.send(job).map_err(|_| SinkError("the page went away".into()))
    }
}
/// Encode preview frames as JPEG and send them, each after its `frame` message, until
/// the session drops its sender or the page goes away.
fn encode_frames(jobs: Receiver<EncodeJob>, out: tokio::sync::mpsc::Sender<Out>) {
    for mut job in jobs {
        let t = Instant::now();
        let [_, _, w, h] = job.header;
        let mut bytes = Vec::with_capacity(16 + job.rgb.len() / 8);
        for v in job.header {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        let encoded = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 85).encode(
            &job.rgb,
            w,
            h,
            image::ExtendedColorType::Rgb8,
        );
        let ok = encoded.is_ok();
        let message = match encoded {
            Ok(()) => {
                job.stats["encode_ms"] = json!(t.elapsed().as_secs_f64() * 1e3);
                Out::Text(job.stats.to_string())
            }
            Err(e) => Out::Text(
                json!({"type": "error", "message": format!("cannot encode the preview: {e}")}).to_string(),
            ),
        };
        if out.blocking_send(message).is_err() || (ok && out.blocking_send(Out::Binary(bytes)).is_err()) {
            return;
        }
    }
}

/// Why the loop ends.
struct Closed;

/// Run a session until its page goes away.
pub(crate) fn run(
    dir: tempfile::TempDir,
    out_root: PathBuf,
    limits: Limits,
    inbox: Receiver<Command>,
    out: tokio::sync::mpsc::Sender<Out>,
) {
    // One frame waits while one is encoded: a slow page or encoder slows the session.
    let (encoder, jobs) = std::sync::mpsc::sync_channel::<EncodeJob>(1);
    let frames_out = out.clone();
    let encoding = std::thread::Builder::new()
        .name("studio-encode".into())
        .spawn(move || encode_frames(jobs, frames_out));
    if encoding.is_err() {
        let _ = out.blocking_send(Out::Text(
            json!({"type": "error", "message": "cannot start the preview encoder"}).to_string(),
        ));
        return;
    }
    let mut s = Session {
        encoder,
        dir,
        out_root,
        out,
        tab: None,
        stash: HashMap::new(),
        generation: 0,
        playing: true,
        looping: true,
        preview: (640, 360),
        next_due: Instant::now(),
        told: None,
        render_cancel: None,
        render_thread: None,
        limits,
    };
    let _ = s.loop_until_closed(&inbox);
    if let Some(cancel) = &s.render_cancel {
        cancel.store(true, Ordering::Relaxed);
    }
}

/// What keeps a scene out of the studio: its validation problems, except that an aurora
/// with no sheets yet is where the editor starts (the preview waits for a stroke).
fn studio_problems(scene: &Scene) -> Vec<phenomena_core::validate::Issue> {
    let mut problems = scene.validate();
    if scene.get::<AuroraScene>().is_some() {
        problems.retain(|i| i.field != "aurora.keyframes[0].sheets");
    }
    problems
}

/// A list of problems as one line.
fn joined(problems: &[phenomena_core::validate::Issue]) -> String {
    problems.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ")
}

/// The page's error message for `problems`, with their fields.
fn problems_message(prefix: &str, problems: &[phenomena_core::validate::Issue]) -> Value {
    json!({
        "type": "error",
        "message": format!("{prefix}{}", joined(problems)),
        "issues": problems.iter().map(|i| json!({"field": i.field, "message": i.to_string()})).collect::<Vec<_>>(),
    })
}

/// What the session does next.
enum Next {
    /// Wait for a command (nothing to simulate).
    Wait,
    /// Simulate one more frame toward the frame asked for.
    CatchUp,
    /// Play: the next frame when due.
    PlayAt(Instant),
}

impl Session {
    fn loop_until_closed(&mut self, inbox: &Receiver<Command>) -> Result<(), Closed> {
        loop {
            // Every queued command first, so nothing stale is rendered.
            let command = match self.next() {
                Next::Wait => Some(inbox.recv().map_err(|_| Closed)?),
                Next::CatchUp => match inbox.try_recv() {
                    Ok(c) => Some(c),
                    Err(TryRecvError::Empty) => None,
                    Err(TryRecvError::Disconnected) => return Err(Closed),
                },
                Next::PlayAt(due) => {
                    match inbox.recv_timeout(due.saturating_duration_since(Instant::now())) {
                        Ok(c) => Some(c),
                        Err(RecvTimeoutError::Timeout) => None,
                        Err(RecvTimeoutError::Disconnected) => return Err(Closed),
                    }
                }
            };
            match command {
                Some(c) => self.guarded(|s| s.command(c))?,
                None => self.guarded(|s| s.tick(inbox))?,
            }
        }
    }

    fn next(&self) -> Next {
        match &self.tab {
            Some(Tab { runner: Some(_), target: Some(_), .. }) => Next::CatchUp,
            Some(Tab { runner: Some(_), .. }) if self.playing => Next::PlayAt(self.next_due),
            _ => Next::Wait,
        }
    }

    /// Work when no command waits: one step toward the frame asked for, or the next
    /// frame of play when it is due.
    fn tick(&mut self, inbox: &Receiver<Command>) -> Result<(), Closed> {
        let catching_up = self.tab.as_ref().and_then(|t| t.target).is_some();
        if catching_up {
            return self.catch_up();
        }
        let Some(tab) = &self.tab else { return Ok(()) };
        self.next_due = Instant::now() + Duration::from_secs_f64(1.0 / preview_fps(&tab.scene));
        if tab.frame + 1 >= tab.length() {
            // The end of the scene: loop, or stop there (a one-frame scene stops).
            if self.looping && tab.length() > 1 {
                return self.go_to(0);
            }
            self.playing = false;
            return self.send_time(None);
        }
        let generation = self.generation;
        let Some(mut record) = self.step()? else { return Ok(()) };
        let stepped = self.frames_done();
        loop {
            match inbox.try_recv() {
                Ok(c) => self.command(c)?,
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => return Err(Closed),
            }
        }
        // Shown unless a command changed the scene or moved in time (and showed).
        let same = self.generation == generation && self.frames_done() == stepped;
        if same { self.show(&mut record) } else { Ok(()) }
    }

    /// Frames the active tab's simulation has done.
    fn frames_done(&self) -> Option<u32> {
        self.tab.as_ref().and_then(|t| t.runner.as_ref()).map(Runner::frames_done)
    }

    /// Run `f`; if it panics (a bug), stop the simulation, keep the scene and tell the
    /// page, so the session stays usable (reset or load a scene) instead of vanishing.
    fn guarded(&mut self, f: impl FnOnce(&mut Self) -> Result<(), Closed>) -> Result<(), Closed> {
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(self))) {
            Ok(result) => result,
            Err(payload) => {
                let what = payload
                    .downcast_ref::<&str>()
                    .map(|s| (*s).to_string())
                    .or_else(|| payload.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "no message".into());
                tracing::error!("a studio session recovered from a panic: {what}");
                if let Some(tab) = &mut self.tab {
                    tab.runner = None;
                    tab.target = None;
                }
                self.playing = false;
                self.error(format!(
                    "the session hit an internal error and stopped its simulation ({what}); the scene is kept: press reset or load a scene to go on"
                ))
            }
        }
    }

    fn command(&mut self, command: Command) -> Result<(), Closed> {
        match command {
            Command::Close => Err(Closed),
            Command::SnowGlb(reply) => {
                let _ = reply.send(self.snow_glb());
                Ok(())
            }
            Command::Page(m) => self.handle(*m),
        }
    }

    fn send(&self, value: Value) -> Result<(), Closed> {
        self.out.blocking_send(Out::Text(value.to_string())).map_err(|_| Closed)
    }

    fn notice(&self, message: impl Into<String>) -> Result<(), Closed> {
        self.send(json!({"type": "notice", "message": message.into()}))
    }

    fn error(&self, message: impl Into<String>) -> Result<(), Closed> {
        self.send(json!({"type": "error", "message": message.into()}))
    }

    fn handle(&mut self, m: Incoming) -> Result<(), Closed> {
        match m {
            Incoming::Tab { phenomenon } => self.open_tab(&phenomenon),
            Incoming::Builtin { name } => self.load_builtin(name),
            Incoming::Toml { text, name } => {
                self.load_toml(&text, name.unwrap_or_else(|| "uploaded.toml".into()))
            }
            Incoming::Scene { phenomenon, scene, name } => self.load_json(&phenomenon, scene, name),
            Incoming::Set { path, value, reload } => self.set(&path, value, reload),
            Incoming::Play => {
                self.playing = true;
                self.next_due = Instant::now();
                self.send_time(None)
            }
            Incoming::Pause => {
                self.playing = false;
                self.send_time(None)
            }
            Incoming::Step => {
                self.playing = false;
                let next = self.tab.as_ref().map(|t| t.target.unwrap_or(t.frame) + 1);
                next.map_or(Ok(()), |f| self.go_to(f))
            }
            Incoming::Seek { frame } => {
                self.playing = false;
                self.go_to(frame)
            }
            Incoming::Loop { on } => {
                self.looping = on;
                self.send_time(None)
            }
            // After a stop (an error), a new simulation; else frame 0 again.
            Incoming::Reset if self.frames_done().is_none() => {
                if let Some(tab) = &mut self.tab {
                    (tab.frame, tab.target, tab.parked) = (0, None, None);
                }
                self.restart()
            }
            Incoming::Reset => self.go_to(0),
            Incoming::Undo => self.undo(false),
            Incoming::Redo => self.undo(true),
            Incoming::Preview { width, height } => self.resize(width, height),
            Incoming::Wind { force, start } => self.wind(force, start),
            Incoming::Aurora(op) => self.aurora(op),
            Incoming::Save { name } => self.save(name),
            Incoming::RenderFinal(request) => self.render_final(&request),
            #[cfg(test)]
            Incoming::Panic => panic!("a test asked for a panic"),
        }
    }

    fn resize(&mut self, width: u32, height: u32) -> Result<(), Closed> {
        if !(16..=MAX_PREVIEW_SIDE).contains(&width) || !(16..=MAX_PREVIEW_SIDE).contains(&height) {
            return self.error(format!(
                "preview {width}x{height}: each side must be in [16, {MAX_PREVIEW_SIDE}] pixels"
            ));
        }
        self.preview = (width, height);
        self.restart()
    }
}
/// Build the preview's runner of `scene` at `size`; the error is the page's message.
fn build_runner(scene: &Scene, size: (u32, u32), assets: &Assets, limits: &Limits) -> Result<Runner, Value> {
    let mut scene = scene.clone();
    let s = scene.settings_mut();
    (s.width, s.height) = size;
    if let Some(a) = scene.get::<AuroraScene>()
        && a.aurora.keyframes.first().is_none_or(|k| k.sheets.is_empty())
    {
        return Err(
            json!({"type": "notice", "message": "draw a sheet on the source canvas to start the aurora"}),
        );
    }
    let problems = scene.validate();
    if !problems.is_empty() {
        return Err(problems_message("the preview waits for a valid scene: ", &problems));
    }
    match Runner::with_limits(&scene, assets, limits) {
        Ok(mut runner) => {
            runner.set_preview(true);
            runner.set_clock(crate::render::wall_clock());
            Ok(runner)
        }
        Err(e) => {
            let issues = e.key().map(|k| json!([{"field": k, "message": e.to_string()}]));
            Err(json!({
                "type": "error",
                "message": format!("cannot start the simulation: {e}"),
                "issues": issues.unwrap_or(json!([])),
            }))
        }
    }
}

/// Build `tab`'s runner for its scene at `size`, aiming at the frame it shows or was
/// going to; returns `"render"` when the simulation's state carried over (only how
/// frames are drawn changed: the checkpoint's identity and seed are the new scene's) or
/// `"simulation"` when it runs again from frame 0. The old runner is dropped before the
/// new one is built (one simulation in memory, and its state once as bytes).
fn rebuild(tab: &mut Tab, size: (u32, u32), assets: &Assets, limits: &Limits) -> Result<&'static str, Value> {
    let frame = tab.target.unwrap_or(tab.frame).min(tab.length() - 1);
    tab.target = None;
    tab.frame = frame;
    let old = tab.runner.take();
    // A steered runner's state is not its scene's (the wind changed under it).
    let carried = old.filter(|_| !tab.steered).and_then(|o| o.checkpoint().ok()).or(tab.parked.take());
    tab.steered = false;
    let mut runner = build_runner(&tab.scene, size, assets, limits)?;
    tab.size = size;
    let kept = carried.is_some_and(|bytes| runner.restore(&bytes).is_ok());
    if !kept {
        tab.timeline.clear();
    }
    // Past the frame (a shorter scene, a step ahead): back to it through the states kept.
    if runner.frames_done() > frame + 1 {
        let restored = tab.timeline.at_or_before(frame + 1).is_some_and(|(_, b)| runner.restore(b).is_ok());
        if !restored {
            drop(runner);
            runner = build_runner(&tab.scene, size, assets, limits)?;
        }
    }
    tab.runner = Some(runner);
    tab.target = Some(frame);
    Ok(if kept { "render" } else { "simulation" })
}

impl Session {
    /// The memory a tab's timeline may hold: a quarter of the session's share.
    fn timeline_budget(&self) -> usize {
        usize::try_from(self.limits.memory_bytes / 4).unwrap_or(usize::MAX)
    }

    /// Make frame `frame` of the active tab the one to show (within the scene's
    /// length): from the latest state kept at or before it when that saves steps, else
    /// from the state now or a new simulation; the steps left run in [`Self::catch_up`].
    fn go_to(&mut self, frame: u32) -> Result<(), Closed> {
        let assets = sandbox(self.dir.path());
        let (limits, preview) = (self.limits, self.preview);
        let Some(tab) = &mut self.tab else { return Ok(()) };
        let frame = frame.min(tab.length() - 1);
        let Some(runner) = &mut tab.runner else { return Ok(()) };
        let (want, done) = (frame + 1, runner.frames_done());
        let jump = tab.timeline.at_or_before(want).filter(|(f, _)| *f > done || want < done);
        let restored = jump.map(|(_, bytes)| runner.restore(bytes).is_ok());
        if restored == Some(false) {
            tab.timeline.clear();
        }
        if restored != Some(true) && want < done {
            tab.runner = None;
            tab.steered = false;
            match build_runner(&tab.scene, preview, &assets, &limits) {
                Ok(fresh) => tab.runner = Some(fresh),
                Err(message) => return self.send(message),
            }
        }
        tab.target = Some(frame);
        self.told = None;
        self.send_time(None)
    }

    /// One step toward the frame asked for; shown when reached, and now and then on the
    /// way (the first step at once, then every half second) so the page sees progress.
    fn catch_up(&mut self) -> Result<(), Closed> {
        let Some(target) = self.tab.as_ref().and_then(|t| t.target) else { return Ok(()) };
        if self.frames_done().is_some_and(|done| done > target) {
            if let Some(tab) = &mut self.tab {
                tab.target = None;
            }
            self.show(&mut FrameRecord::default())?;
            return self.send_time(None);
        }
        let Some(mut record) = self.step()? else { return Ok(()) };
        let reached = record.frame >= target;
        let progress = !reached && self.told.is_none_or(|t| t.elapsed() > Duration::from_millis(500));
        if reached || progress {
            self.show(&mut record)?;
        } else if let Some(runner) = self.tab.as_mut().and_then(|t| t.runner.as_mut())
            && runner.render_memory().is_some()
        {
            // A frame that depends on the renders before it: rendered, not shown.
            runner.output(&mut record, &mut Simulate).map_err(|_| Closed)?;
        }
        if reached {
            if let Some(tab) = &mut self.tab {
                tab.target = None;
            }
            return self.send_time(None);
        }
        if progress {
            self.told = Some(Instant::now());
            self.send(json!({"type": "time", "catching_up": {"frame": record.frame, "target": target}}))?;
        }
        Ok(())
    }

    /// The active tab's simulation built again for its scene now, keeping the frame
    /// shown: the page hears the scene, then how time was kept (`change`).
    fn restart(&mut self) -> Result<(), Closed> {
        self.generation = self.generation.wrapping_add(1);
        self.send_scene()?;
        let assets = sandbox(self.dir.path());
        let Some(tab) = &mut self.tab else { return Ok(()) };
        let result = rebuild(tab, self.preview, &assets, &self.limits);
        let warnings: Vec<String> = tab.runner.as_ref().map(|r| r.warnings().to_vec()).unwrap_or_default();
        let frame = tab.target.unwrap_or(tab.frame);
        match result {
            Ok(change) => {
                for w in warnings {
                    self.notice(format!("warning: {w}"))?;
                }
                self.next_due = Instant::now();
                self.told = None;
                self.send_time(Some(change))?;
                // A state already at the frame is shown at once.
                if self.frames_done() == Some(frame + 1) { self.catch_up() } else { Ok(()) }
            }
            Err(message) => self.send(message),
        }
    }

    /// Where the active tab is in time.
    fn send_time(&self, change: Option<&'static str>) -> Result<(), Closed> {
        let Some(tab) = &self.tab else { return Ok(()) };
        let mut msg = json!({
            "type": "time",
            "generation": self.generation,
            "frame": tab.frame,
            "target": tab.target,
            "length": tab.length(),
            "fps": preview_fps(&tab.scene),
            "playing": self.playing,
            "looping": self.looping,
            // States kept, as the frames they show.
            "kept": tab.timeline.kept().iter().map(|f| f - 1).collect::<Vec<_>>(),
            "kept_every": tab.timeline.every(),
            "kept_bytes": tab.timeline.bytes(),
        });
        if let Some(c) = change {
            msg["change"] = json!(c);
        }
        self.send(msg)
    }

    fn send_scene(&self) -> Result<(), Closed> {
        let Some(tab) = &self.tab else { return Ok(()) };
        let mut msg = json!({
            "type": "scene",
            "generation": self.generation,
            "phenomenon": tab.scene.phenomenon().name(),
            "scene": tab.scene.to_json(),
            "name": tab.name,
            "dirty": tab.scene != tab.baseline,
            "undo": tab.undo.len(),
            "redo": tab.redo.len(),
        });
        if let Some(a) = tab.scene.get::<AuroraScene>() {
            msg["editor"] = serde_json::to_value(editor::view(&a.aurora, &tab.drawn)).unwrap_or(Value::Null);
        }
        self.send(msg)
    }

    /// One step of the active tab; `None` without a simulation or when it stopped (the
    /// page is told). The state is offered to the timeline.
    fn step(&mut self) -> Result<Option<FrameRecord>, Closed> {
        let Some(tab) = &mut self.tab else { return Ok(None) };
        let Some(runner) = &mut tab.runner else { return Ok(None) };
        match runner.step() {
            Ok(record) => {
                if !tab.steered {
                    tab.timeline.offer(runner);
                }
                Ok(Some(record))
            }
            Err(e) => {
                tab.runner = None;
                tab.target = None;
                self.playing = false;
                self.error(format!("{e}"))?;
                Ok(None)
            }
        }
    }

    /// Render the active tab's state now and send it to the page.
    fn show(&mut self, record: &mut FrameRecord) -> Result<(), Closed> {
        let generation = self.generation;
        let Some(tab) = &mut self.tab else { return Ok(()) };
        let length = tab.length();
        let Some(runner) = &mut tab.runner else { return Ok(()) };
        let Some(frame) = runner.frames_done().checked_sub(1) else { return Ok(()) };
        tab.frame = frame;
        record.frame = frame;
        let mut sink = PreviewSink { generation, shown: frame, length, encoder: &self.encoder };
        runner.output(record, &mut sink).map_err(|_| Closed)
    }
}
impl Session {
    /// Put the active tab aside as it is.
    /// Put the active tab aside: its simulation's state kept as checkpoint bytes (the
    /// runner and the timeline's states are freed, so tabs put aside hold no more than
    /// their states).
    fn stash_active(&mut self) {
        if let Some(mut tab) = self.tab.take() {
            if let Some(runner) = tab.runner.take()
                && !tab.steered
            {
                tab.parked = runner.checkpoint().ok();
            }
            tab.timeline.clear();
            self.stash.insert(tab.scene.phenomenon().name(), tab);
        }
    }

    /// Show `phenomenon`'s tab: as it was left, or with its first shipped scene.
    fn open_tab(&mut self, phenomenon: &str) -> Result<(), Closed> {
        let Some(entry) = registry::phenomenon(phenomenon) else {
            return self.error(format!("unknown phenomenon `{phenomenon}`: use {}", registry::names()));
        };
        let active = self.tab.as_ref().is_some_and(|t| t.scene.phenomenon() == entry);
        if !active {
            self.stash_active();
            self.tab = self.stash.remove(entry.name());
        }
        match &self.tab {
            // The tab shown already: the runner goes on where it was.
            Some(t) if active && t.runner.is_some() && t.size == self.preview => {
                self.generation = self.generation.wrapping_add(1);
                self.send_scene()?;
                let frame = t.target.unwrap_or(t.frame);
                self.go_to(frame)
            }
            // Back from aside: built again from its parked state.
            Some(_) => self.restart(),
            None => match shipped::SHIPPED.iter().find(|s| s.phenomenon == entry.name()) {
                Some(first) => self.load_builtin(first.name.to_string()),
                None => self.error(format!("no shipped scene of {phenomenon}")),
            },
        }
    }

    /// Open `scene` named `name` in its phenomenon's tab at frame 0 (undo goes back to
    /// the scene before).
    fn open(&mut self, scene: Scene, name: String) -> Result<(), Closed> {
        let name = plain_name(&name).unwrap_or_else(|| scene.phenomenon().name().to_string());
        let entry = scene.phenomenon();
        if self.tab.as_ref().is_none_or(|t| t.scene.phenomenon() != entry) {
            self.stash_active();
            self.tab = self.stash.remove(entry.name());
        }
        let budget = self.timeline_budget();
        match &mut self.tab {
            Some(tab) => {
                tab.remember(None, true);
                let drawn = scene.get::<AuroraScene>().map(|a| Drawn::of(&a.aurora)).unwrap_or_default();
                tab.take(Snapshot { scene: scene.clone(), drawn, file: Some((name, scene)) });
                tab.runner = None;
                tab.timeline.clear();
                (tab.frame, tab.target, tab.parked, tab.steered) = (0, None, None, false);
            }
            None => self.tab = Some(Tab::new(scene, name, budget)),
        }
        self.restart()
    }

    /// Open the shipped scene `name`.
    fn load_builtin(&mut self, name: String) -> Result<(), Closed> {
        match shipped::shipped(&name) {
            Some(b) => match b.scene() {
                Ok(scene) => self.open(scene, name),
                Err(e) => self.error(format!("shipped scene {name} is invalid: {e}")),
            },
            None => self.error(format!("no shipped scene `{name}`")),
        }
    }

    /// Open a scene file's text; its problems go back with line and column.
    fn load_toml(&mut self, text: &str, name: String) -> Result<(), Closed> {
        match phenomena_scene::parse(text, &name) {
            Ok(scene) => {
                let stem =
                    Path::new(&name).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or(name);
                self.open(scene, stem)
            }
            Err(e) => self.send(json!({
                "type": "error",
                "message": format!("{name} was not loaded: {e}"),
                "located": e.0.iter().map(|l| json!({"line": l.line, "column": l.column, "message": l.message})).collect::<Vec<_>>(),
            })),
        }
    }

    /// Open a scene in its JSON form (a preset the page kept).
    fn load_json(&mut self, phenomenon: &str, scene: Value, name: Option<String>) -> Result<(), Closed> {
        let s = match scene_from_json(phenomenon, scene) {
            Ok(s) => s,
            Err(e) => return self.error(format!("scene refused: {e}")),
        };
        let problems = studio_problems(&s);
        if !problems.is_empty() {
            return self.error(format!("scene refused: {}", joined(&problems)));
        }
        self.open(s, name.unwrap_or_else(|| phenomenon.to_string()))
    }

    /// The scene as TOML for the page to download, as `name` (a plain file name) if
    /// given; what is saved becomes the scene the dirty marker compares with.
    fn save(&mut self, name: Option<String>) -> Result<(), Closed> {
        let Some(tab) = &mut self.tab else { return self.error("no scene to save: load one first") };
        if let Some(n) = name {
            let trimmed = n.trim().trim_end_matches(".toml");
            if plain_name(trimmed).as_deref() != Some(trimmed) {
                return self.error(format!(
                    "save as {:?}: use 1 to 64 letters, digits, spaces, dots, - and _ (not starting with a dot)",
                    n.chars().take(80).collect::<String>()
                ));
            }
            tab.name = trimmed.to_string();
        }
        match scene_toml(&tab.scene) {
            Ok(text) => {
                tab.baseline = tab.scene.clone();
                let problems = tab.scene.validate();
                let msg = json!({
                    "type": "saved",
                    "name": format!("{}.toml", tab.name),
                    "scene_name": tab.name,
                    "toml": text,
                    "dirty": false,
                    "valid": problems.is_empty(),
                    "problems": problems.iter().map(ToString::to_string).collect::<Vec<_>>(),
                });
                self.send(msg)
            }
            Err(e) => self.error(format!("cannot write the scene as TOML: {e}")),
        }
    }

    fn set(&mut self, path: &str, value: Value, reload: bool) -> Result<(), Closed> {
        let Some(tab) = &self.tab else { return self.error("no scene yet: load one first") };
        let candidate = match tab.scene.with_value(path, value.clone()) {
            Ok(c) => c,
            Err(e) => {
                self.send(json!({"type": "error", "message": format!("{path} = {value}: {e}"), "issues": [{"field": path, "message": e}]}))?;
                return self.send_scene();
            }
        };
        if candidate == tab.scene && !reload {
            return Ok(()); // nothing changes: no undo entry, no new simulation
        }
        let problems = studio_problems(&candidate);
        if !problems.is_empty() {
            self.send(problems_message("", &problems))?;
            return self.send_scene(); // the page's controls go back to the scene's values
        }
        if let Some(tab) = &mut self.tab {
            tab.remember(None, false);
            tab.scene = candidate;
        }
        self.restart()
    }

    /// Undo the last edit (or redo the last undone): the scene before it, at the same
    /// frame.
    fn undo(&mut self, redo: bool) -> Result<(), Closed> {
        let Some(tab) = &mut self.tab else { return Ok(()) };
        let Some(back) = (if redo { tab.redo.pop() } else { tab.undo.pop() }) else {
            return self.notice(if redo { "nothing to redo" } else { "nothing to undo" });
        };
        let now = tab.snapshot(back.file.is_some());
        if redo {
            tab.undo.push(now)
        } else {
            tab.redo.push(now)
        }
        tab.coalesce = None;
        tab.take(back);
        self.restart()
    }

    /// The flame's wind, steered live: the same simulation continues (no new
    /// generation), the scene keeps the new wind, and the states kept after this frame
    /// (simulated in the old wind) are forgotten. A drag is one edit for undo.
    fn wind(&mut self, force: [f32; 3], start: bool) -> Result<(), Closed> {
        use phenomena_scene::flame::WIND_PATH;
        let Some(tab) = &mut self.tab else { return self.error("wind applies to flame scenes") };
        let value = json!({ "force_n_m3": force });
        let Ok(updated) = tab.scene.with_value(WIND_PATH, value.clone()) else {
            return self.error("wind applies to flame scenes");
        };
        if let Some(runner) = &mut tab.runner {
            match runner.steer(WIND_PATH, &value) {
                Steer::Applied => {
                    // The states kept are of the scene before; the scene now blows
                    // from frame 0. Going back simulates the scene as it is now.
                    tab.timeline.clear();
                    tab.steered = true;
                }
                Steer::NotLive => return self.error("wind applies to flame scenes"),
                Steer::Refused(e) => return self.error(format!("wind {force:?} refused: {e}")),
            }
        }
        if start {
            tab.coalesce = None; // a new drag: an edit of its own
        }
        tab.remember(Some("wind"), false);
        tab.scene = updated;
        let (undo, dirty) = (tab.undo.len(), tab.scene != tab.baseline);
        self.send(json!({"type": "wind", "force": force, "path": WIND_PATH, "undo": undo, "dirty": dirty}))
    }

    fn snow_glb(&self) -> Result<Vec<u8>, String> {
        match self.tab.as_ref().and_then(|t| t.runner.as_ref()) {
            Some(runner) if runner.phenomenon().name() == "snow" => {
                runner.export("snow-mesh", "glb").map(|e| e.bytes)
            }
            _ => Err("the session is not running a snow scene".into()),
        }
    }

    fn render_final(&mut self, request: &Request) -> Result<(), Closed> {
        let Some(tab) = &self.tab else { return self.error("no scene to render") };
        let scene = tab.scene.clone();
        let problems = scene.validate();
        if !problems.is_empty() {
            return self.error(format!("the scene is not valid: {}", joined(&problems)));
        }
        let plan = match request.plan(&scene) {
            Ok(plan) => plan,
            Err(e) => return self.error(format!("render final: {e}")),
        };
        if self.render_thread.as_ref().is_some_and(|t| !t.is_finished()) {
            return self.error("a final render is still running: wait for it to finish");
        }
        let dir = match final_render::render_folder(&self.out_root, &tab.name, plan.format) {
            Ok(dir) => dir,
            Err(e) => return self.error(format!("render final: {e:#}")),
        };
        let cancel = Arc::new(AtomicBool::new(false));
        self.render_cancel = Some(cancel.clone());
        let out = self.out.clone();
        let send = move |v: Value| out.blocking_send(Out::Text(v.to_string())).is_ok();
        let (first, last) = (plan.frames.start, plan.frames.end - 1);
        let shown = dir.display().to_string();
        match final_render::spawn(scene, plan, sandbox(self.dir.path()), self.limits, dir, cancel, send) {
            Ok(thread) => {
                self.render_thread = Some(thread);
                self.notice(format!("rendering frames {first} to {last} to {shown}"))
            }
            Err(e) => self.error(format!("cannot start the render: {e}")),
        }
    }

    fn aurora(&mut self, op: EditOp) -> Result<(), Closed> {
        let Some(a) = self.tab.as_ref().and_then(|t| t.scene.get::<AuroraScene>()) else {
            return self.error("aurora editing needs an aurora scene: open the Aurora tab");
        };
        let mut config = a.aurora.clone();
        let Some(tab) = &mut self.tab else { return Ok(()) };
        let mut drawn = tab.drawn.clone();
        match editor::edit(&mut config, &mut drawn, op) {
            Ok(message) => {
                tab.remember(None, false);
                if let Some(a) = tab.scene.get_mut::<AuroraScene>() {
                    a.aurora = config;
                }
                tab.drawn = drawn;
                self.restart()?;
                if let Some(m) = message {
                    self.notice(m)?;
                }
                Ok(())
            }
            Err(refusal) => self.send(json!({"type": "refused", "message": refusal.to_string()})),
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    #[test]
    fn saved_scenes_read_back_identically() {
        for b in &shipped::SHIPPED {
            let scene = b.scene().unwrap();
            let text = scene_toml(&scene).unwrap();
            let back = phenomena_scene::parse(&text, "saved.toml")
                .unwrap_or_else(|e| panic!("{}: {e}\n{text}", b.name));
            assert_eq!(back, scene, "{}", b.name);
            let json = scene.to_json();
            assert_eq!(scene_from_json(scene.phenomenon().name(), json).unwrap(), scene, "{}", b.name);
        }
    }
}
