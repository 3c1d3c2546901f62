//! One studio session (one browser tab): its scene, its simulation and the thread that
//! steps, renders and encodes the preview.
//!
//! Protocol. The page sends JSON text messages with a `type` ([`Incoming`]). The
//! session answers with JSON text (`hello`, `scene`, `frame`, `notice`, `error`,
//! `saved`, `progress`, `rendered`) and binary preview frames: a header of four
//! little-endian `u32` (generation, frame, width, height) followed by a JPEG. A
//! `frame` text message with the frame's timings and counters precedes each image.
//!
//! Every accepted scene change increments the generation; the page ignores frames of
//! older generations, and the thread drains every queued command before it renders, so
//! no stale frame is computed after a change arrives.
//!
//! The scene, its simulation and its frames all come from the scene layer
//! (`phenomena_scene`): the preview and the final renders run its [`Runner`], and every
//! file a scene reads comes through its sandbox ([`Assets::Sandbox`]): only the files
//! uploaded to this session, by plain name.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, TryRecvError};
use std::time::{Duration, Instant};

use anyhow::Result;
use phenomena_aurora::editor::{self, Drawn, EditOp};
use phenomena_scene::aurora::AuroraScene;
use phenomena_scene::job::Job;
use phenomena_scene::output::{ensure_dir, to_srgb8, write_bytes_atomic};
use phenomena_scene::{
    Assets, Format, FrameRecord, FrameSink, Limits, Observer, Output, Runner, Scene, SinkError, Steer,
    registry, shipped,
};
use serde::Deserialize;
use serde_json::{Value, json};

/// A message to the page.
pub(crate) enum Out {
    /// JSON text.
    Text(String),
    /// A preview frame (header + JPEG).
    Binary(Vec<u8>),
}

/// The preview's frame-rate cap (frames per second): enough for a live view, and the
/// rest of the machine stays free for the other tabs and final renders.
const MAX_PREVIEW_FPS: f64 = 30.0;

/// Largest preview, pixels per side.
const MAX_PREVIEW_SIDE: u32 = 1920;

/// What the page may send.
#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub(crate) enum Incoming {
    /// Load a shipped scene by name (see `hello.builtins`).
    Builtin {
        name: String,
    },
    /// Load a scene in its JSON form (what `scene` messages carry), e.g. when the page
    /// returns to a tab.
    Scene {
        phenomenon: String,
        scene: Value,
    },
    /// Load a scene file's text (errors come back with line and column).
    Toml {
        text: String,
        name: Option<String>,
    },
    /// Set one parameter: a dotted path into the scene (`flame.emitter.rate_per_s`).
    Set {
        path: String,
        value: Value,
    },
    Play,
    Pause,
    Step,
    Reset,
    /// The preview size in pixels.
    Preview {
        width: u32,
        height: u32,
    },
    /// The flame's wind force density, N/m³ (the paper's §6 mouse drag), applied live.
    Wind {
        force: [f32; 3],
    },
    /// An aurora editing operation (thesis §3.1; `phenomena_aurora::editor`).
    Aurora(EditOp),
    /// Ask for the scene as TOML (for download).
    Save,
    /// Render the scene at its own size to the studio's output folder.
    RenderFinal {
        frames: Option<u32>,
        /// `png` (the default), `exr`, `vdb`, `ply` or `flipbook`, as the phenomenon
        /// writes (see `hello.phenomena[].formats`).
        #[serde(default)]
        format: Option<String>,
    },
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
        "builtins": shipped::SHIPPED.iter().map(|b| json!({"name": b.name, "phenomenon": b.phenomenon})).collect::<Vec<_>>(),
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

/// The session's files: only what was uploaded to it, by plain name, each at most the
/// upload cap.
fn sandbox(dir: &Path) -> Assets {
    Assets::Sandbox { dir: dir.to_path_buf(), max_bytes: super::MAX_UPLOAD_BYTES as u64 }
}

struct Session {
    dir: tempfile::TempDir,
    out_root: PathBuf,
    out: tokio::sync::mpsc::Sender<Out>,
    scene: Option<Scene>,
    /// The aurora editor's record of the sheets the artist drew.
    drawn: Drawn,
    runner: Option<Runner>,
    generation: u32,
    playing: bool,
    preview: (u32, u32),
    next_due: Instant,
    render_cancel: Option<Arc<AtomicBool>>,
    /// The final render running, if any (one at a time per session).
    render_thread: Option<std::thread::JoinHandle<()>>,
    /// The scene's name for its final renders' folders: the shipped scene's or the
    /// uploaded file's (the phenomenon's for a scene from the page).
    scene_name: String,
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
    /// Frames simulated when this one was rendered (0: the initial state).
    shown: u32,
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
            "step_ms": r.step_ms,
            "render_ms": r.render_ms,
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
        scene: None,
        drawn: Drawn::default(),
        runner: None,
        generation: 0,
        playing: true,
        preview: (640, 360),
        next_due: Instant::now(),
        render_cancel: None,
        render_thread: None,
        scene_name: String::new(),
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

impl Session {
    fn loop_until_closed(&mut self, inbox: &Receiver<Command>) -> Result<(), Closed> {
        loop {
            // Every queued command first, so nothing stale is rendered.
            let command = if self.playing && self.runner.is_some() {
                let wait = self.next_due.saturating_duration_since(Instant::now());
                if wait.is_zero() {
                    match inbox.try_recv() {
                        Ok(c) => Some(c),
                        Err(TryRecvError::Empty) => None,
                        Err(TryRecvError::Disconnected) => return Err(Closed),
                    }
                } else {
                    match inbox.recv_timeout(wait) {
                        Ok(c) => Some(c),
                        Err(RecvTimeoutError::Timeout) => continue,
                        Err(RecvTimeoutError::Disconnected) => return Err(Closed),
                    }
                }
            } else {
                Some(inbox.recv().map_err(|_| Closed)?)
            };
            match command {
                Some(c) => self.guarded(|s| s.command(c))?,
                None => self.guarded(|s| s.tick(inbox))?,
            }
        }
    }

    /// One preview frame when it is due: step, then handle what came in during the
    /// step (a change makes this frame stale, and the change's own frame is then the
    /// next shown), then show it.
    fn tick(&mut self, inbox: &Receiver<Command>) -> Result<(), Closed> {
        self.next_due = Instant::now() + Duration::from_secs_f64(1.0 / MAX_PREVIEW_FPS);
        let generation = self.generation;
        let Some(mut record) = self.step()? else { return Ok(()) };
        let stepped = self.runner.as_ref().map(Runner::frames_done);
        loop {
            match inbox.try_recv() {
                Ok(c) => self.command(c)?,
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => return Err(Closed),
            }
        }
        // Shown unless a command changed the scene or stepped (and showed) again.
        let same = self.generation == generation && self.runner.as_ref().map(Runner::frames_done) == stepped;
        if same { self.show(&mut record) } else { Ok(()) }
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
                self.runner = None;
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
            Incoming::Builtin { name } => self.load_builtin(name),
            Incoming::Toml { text, name } => {
                self.load_toml(&text, name.unwrap_or_else(|| "uploaded.toml".into()))
            }
            Incoming::Scene { phenomenon, scene } => self.load_json(phenomenon, scene),
            Incoming::Set { path, value } => self.set(&path, value),
            Incoming::Play => {
                self.playing = true;
                self.next_due = Instant::now();
                Ok(())
            }
            Incoming::Pause => {
                self.playing = false;
                Ok(())
            }
            Incoming::Step => {
                self.playing = false;
                if let Some(mut record) = self.step()? {
                    self.show(&mut record)?;
                }
                Ok(())
            }
            Incoming::Reset => self.rebuild(),
            Incoming::Preview { width, height } => {
                if !(16..=MAX_PREVIEW_SIDE).contains(&width) || !(16..=MAX_PREVIEW_SIDE).contains(&height) {
                    return self.error(format!(
                        "preview {width}x{height}: each side must be in [16, {MAX_PREVIEW_SIDE}] pixels"
                    ));
                }
                self.preview = (width, height);
                self.rebuild()
            }
            Incoming::Wind { force } => self.wind(force),
            Incoming::Aurora(op) => self.aurora(op),
            Incoming::Save => self.save(),
            Incoming::RenderFinal { frames, format } => self.render_final(frames, format.as_deref()),
            #[cfg(test)]
            Incoming::Panic => panic!("a test asked for a panic"),
        }
    }

    /// Open the shipped scene `name`.
    fn load_builtin(&mut self, name: String) -> Result<(), Closed> {
        match shipped::shipped(&name) {
            Some(b) => match b.scene() {
                Ok(scene) => {
                    self.scene_name = name;
                    self.replace(scene)
                }
                Err(e) => self.error(format!("shipped scene {name} is invalid: {e}")),
            },
            None => self.error(format!("no shipped scene `{name}`")),
        }
    }

    /// Open a scene file's text; its problems go back with line and column.
    fn load_toml(&mut self, text: &str, name: String) -> Result<(), Closed> {
        match phenomena_scene::parse(text, &name) {
            Ok(scene) => {
                self.scene_name =
                    Path::new(&name).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or(name);
                self.replace(scene)
            }
            Err(e) => self.send(json!({
                "type": "error",
                "message": format!("{name} was not loaded: {e}"),
                "located": e.0.iter().map(|l| json!({"line": l.line, "column": l.column, "message": l.message})).collect::<Vec<_>>(),
            })),
        }
    }

    /// Open a scene in its JSON form (the page returning to a tab); the scene keeps its
    /// name while it is of the same phenomenon.
    fn load_json(&mut self, phenomenon: String, scene: Value) -> Result<(), Closed> {
        let s = match scene_from_json(&phenomenon, scene) {
            Ok(s) => s,
            Err(e) => return self.error(format!("scene refused: {e}")),
        };
        let problems = studio_problems(&s);
        if !problems.is_empty() {
            return self.error(format!("scene refused: {}", joined(&problems)));
        }
        let same = self.scene.as_ref().is_some_and(|old| old.phenomenon().name() == phenomenon);
        if !same || self.scene_name.is_empty() {
            self.scene_name = phenomenon;
        }
        self.replace(s)
    }

    /// The scene as TOML for the page to download.
    fn save(&mut self) -> Result<(), Closed> {
        let Some(scene) = &self.scene else { return self.error("no scene to save: load one first") };
        match scene_toml(scene) {
            Ok(text) => {
                let problems = scene.validate();
                self.send(json!({
                    "type": "saved",
                    "name": format!("{}.toml", scene.phenomenon().name()),
                    "toml": text,
                    "valid": problems.is_empty(),
                    "problems": problems.iter().map(ToString::to_string).collect::<Vec<_>>(),
                }))
            }
            Err(e) => self.error(format!("cannot write the scene as TOML: {e}")),
        }
    }

    /// Take a new scene (already valid) and start it.
    fn replace(&mut self, scene: Scene) -> Result<(), Closed> {
        self.drawn = scene.get::<AuroraScene>().map(|a| Drawn::of(&a.aurora)).unwrap_or_default();
        self.scene = Some(scene);
        self.rebuild()
    }

    /// A new generation: the scene to the page, the simulation rebuilt, its first frame.
    fn rebuild(&mut self) -> Result<(), Closed> {
        self.generation = self.generation.wrapping_add(1);
        self.runner = None;
        let Some(mut scene) = self.scene.clone() else {
            return Ok(());
        };
        self.send_scene()?;
        // The preview runs the authored scene at the preview's size.
        let s = scene.settings_mut();
        (s.width, s.height) = self.preview;
        if let Some(a) = scene.get::<AuroraScene>()
            && a.aurora.keyframes.first().is_none_or(|k| k.sheets.is_empty())
        {
            return self.notice("draw a sheet on the source canvas to start the aurora");
        }
        let problems = scene.validate();
        if !problems.is_empty() {
            return self.send(json!({
                "type": "error",
                "message": format!("the preview waits for a valid scene: {}", joined(&problems)),
                "issues": problems.iter().map(|i| json!({"field": i.field, "message": i.to_string()})).collect::<Vec<_>>(),
            }));
        }
        match Runner::with_limits(&scene, &sandbox(self.dir.path()), &self.limits) {
            Ok(mut runner) => {
                runner.set_preview(true);
                runner.set_clock(crate::render::wall_clock());
                for w in runner.warnings() {
                    self.notice(format!("warning: {w}"))?;
                }
                self.runner = Some(runner);
            }
            Err(e) => {
                let issues = e.key().map(|k| json!([{"field": k, "message": e.to_string()}]));
                return self.send(json!({
                    "type": "error",
                    "message": format!("cannot start the simulation: {e}"),
                    "issues": issues.unwrap_or(json!([])),
                }));
            }
        }
        self.next_due = Instant::now();
        self.show(&mut FrameRecord::default())
    }

    fn send_scene(&self) -> Result<(), Closed> {
        let Some(scene) = &self.scene else { return Ok(()) };
        let mut msg = json!({
            "type": "scene",
            "generation": self.generation,
            "phenomenon": scene.phenomenon().name(),
            "scene": scene.to_json(),
        });
        if let Some(a) = scene.get::<AuroraScene>() {
            msg["editor"] = serde_json::to_value(editor::view(&a.aurora, &self.drawn)).unwrap_or(Value::Null);
        }
        self.send(msg)
    }

    /// One step; `None` without a simulation or when it stopped (the page is told).
    fn step(&mut self) -> Result<Option<FrameRecord>, Closed> {
        let Some(runner) = &mut self.runner else { return Ok(None) };
        match runner.step() {
            Ok(record) => Ok(Some(record)),
            Err(e) => {
                self.playing = false;
                self.runner = None;
                self.error(format!("{e}"))?;
                Ok(None)
            }
        }
    }

    /// Render the current state and send it to the page.
    fn show(&mut self, record: &mut FrameRecord) -> Result<(), Closed> {
        let Some(runner) = &mut self.runner else { return Ok(()) };
        let shown = runner.frames_done();
        let mut sink = PreviewSink { generation: self.generation, shown, encoder: &self.encoder };
        runner.output(record, &mut sink).map_err(|_| Closed)
    }

    fn set(&mut self, path: &str, value: Value) -> Result<(), Closed> {
        let Some(scene) = &self.scene else { return self.error("no scene yet: load one first") };
        let candidate = match scene.with_value(path, value.clone()) {
            Ok(c) => c,
            Err(e) => {
                self.send(json!({"type": "error", "message": format!("{path} = {value}: {e}"), "issues": [{"field": path, "message": e}]}))?;
                return self.send_scene();
            }
        };
        let problems = studio_problems(&candidate);
        if !problems.is_empty() {
            self.send(json!({
                "type": "error",
                "message": joined(&problems),
                "issues": problems.iter().map(|i| json!({"field": i.field, "message": i.to_string()})).collect::<Vec<_>>(),
            }))?;
            return self.send_scene(); // the page's controls go back to the scene's values
        }
        self.scene = Some(candidate);
        self.rebuild()
    }

    /// The flame's wind, steered live: the same simulation continues (no new
    /// generation), and the scene keeps the new wind.
    fn wind(&mut self, force: [f32; 3]) -> Result<(), Closed> {
        use phenomena_scene::flame::WIND_PATH;
        let Some(scene) = &self.scene else { return self.error("wind applies to flame scenes") };
        let value = json!({ "force_n_m3": force });
        let Ok(updated) = scene.with_value(WIND_PATH, value.clone()) else {
            return self.error("wind applies to flame scenes");
        };
        if let Some(runner) = &mut self.runner {
            match runner.steer(WIND_PATH, &value) {
                Steer::Applied => {}
                Steer::NotLive => return self.error("wind applies to flame scenes"),
                Steer::Refused(e) => return self.error(format!("wind {force:?} refused: {e}")),
            }
        }
        self.scene = Some(updated);
        self.send(json!({"type": "wind", "force": force}))
    }

    fn snow_glb(&self) -> Result<Vec<u8>, String> {
        match &self.runner {
            Some(runner) if self.scene.as_ref().is_some_and(|s| s.phenomenon().name() == "snow") => {
                runner.export("snow-mesh", "glb").map(|e| e.bytes)
            }
            _ => Err("the session is not running a snow scene".into()),
        }
    }

    fn render_final(&mut self, frames: Option<u32>, format: Option<&str>) -> Result<(), Closed> {
        let Some(mut scene) = self.scene.clone() else { return self.error("no scene to render") };
        let problems = scene.validate();
        if !problems.is_empty() {
            return self.error(format!("the scene is not valid: {}", joined(&problems)));
        }
        let name = format.unwrap_or("png");
        let Some(format) = Format::named(name) else {
            let all: Vec<&str> = registry::FORMATS.iter().map(|f| f.name()).collect();
            return self.error(format!("render final: no format `{name}`: use {}", all.join(", ")));
        };
        if let Err(e) = format.check(scene.phenomenon()) {
            return self.error(format!("render final: {e}"));
        }
        let total = frames.unwrap_or(scene.settings().frames);
        if !(1..=100_000).contains(&total) {
            return self.error(format!("render final: frames = {total}: expected [1, 100000]"));
        }
        // The count asked for is the scene's length (the saved scene says so).
        scene.settings_mut().frames = total;
        if self.render_thread.as_ref().is_some_and(|t| !t.is_finished()) {
            return self.error("a final render is still running: wait for it to finish");
        }
        let dir = match render_folder(&self.out_root, &self.scene_name, format) {
            Ok(dir) => dir,
            Err(e) => return self.error(format!("render final: {e:#}")),
        };
        let cancel = Arc::new(AtomicBool::new(false));
        self.render_cancel = Some(cancel.clone());
        let out = self.out.clone();
        let assets = sandbox(self.dir.path());
        let limits = self.limits;
        let spawned = std::thread::Builder::new().name("studio-render".into()).spawn(move || {
            let send = |v: Value| out.blocking_send(Out::Text(v.to_string())).is_ok();
            let shown = dir.display().to_string();
            let mut progress = FinalProgress { send: &send, cancel: &cancel, total, dir: &shown };
            // A bug in a render ends that render with a message, not silently.
            let rendered = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                render_to(&scene, &assets, &limits, &dir, total, format, &mut progress)
            }));
            match rendered {
                Ok(Ok(())) => {
                    send(json!({"type": "rendered", "dir": shown, "frames": total}));
                }
                Ok(Err(e)) => {
                    send(json!({"type": "error", "message": format!("render final failed: {e:#}")}));
                }
                Err(_) => {
                    send(json!({"type": "error", "message": "render final failed: an internal error stopped it"}));
                }
            }
        });
        match spawned {
            Ok(thread) => {
                self.render_thread = Some(thread);
                self.notice(format!("rendering {total} frames to {}", self.out_root.display()))
            }
            Err(e) => self.error(format!("cannot start the render: {e}")),
        }
    }

    fn aurora(&mut self, op: EditOp) -> Result<(), Closed> {
        let Some(a) = self.scene.as_ref().and_then(|s| s.get::<AuroraScene>()) else {
            return self.error("aurora editing needs an aurora scene: open the Aurora tab");
        };
        let mut config = a.aurora.clone();
        let mut drawn = self.drawn.clone();
        match editor::edit(&mut config, &mut drawn, op) {
            Ok(message) => {
                if let Some(a) = self.scene.as_mut().and_then(|s| s.get_mut::<AuroraScene>()) {
                    a.aurora = config;
                }
                self.drawn = drawn;
                self.rebuild()?;
                if let Some(m) = message {
                    self.notice(m)?;
                }
                Ok(())
            }
            Err(refusal) => self.send(json!({"type": "refused", "message": refusal.to_string()})),
        }
    }
}

/// A new folder for one final render, its own: `OUT/SCENE-YYYY-MM-DD-HHMMSS-FORMAT`
/// (local time; the scene's name with anything but letters, digits, `.`, `_` and `-`
/// as `_`), created here so no other render (another tab, another studio on the same
/// folder) can take it: when the name is taken, `-2`, `-3`, ... is added.
pub(crate) fn render_folder(out_root: &Path, scene_name: &str, format: Format) -> Result<PathBuf> {
    ensure_dir(out_root)?;
    let mut name: String = scene_name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() || "._-".contains(c) { c } else { '_' })
        .take(64)
        .collect();
    if name.is_empty() || name.starts_with('.') {
        name.insert_str(0, "scene");
    }
    let stamp = chrono::Local::now().format("%Y-%m-%d-%H%M%S");
    let base = format!("{name}-{stamp}-{}", format.name());
    for n in 1..=1000 {
        let dir = if n == 1 { out_root.join(&base) } else { out_root.join(format!("{base}-{n}")) };
        match std::fs::create_dir(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => anyhow::bail!("cannot create {}: {e}", dir.display()),
        }
    }
    anyhow::bail!("cannot find a free folder name like {} in {}", base, out_root.display())
}

/// A final render's progress to the page; stops the render when cancelled or when the
/// page is gone.
struct FinalProgress<'a> {
    send: &'a dyn Fn(Value) -> bool,
    cancel: &'a AtomicBool,
    total: u32,
    dir: &'a str,
}

impl Observer for FinalProgress<'_> {
    fn frame(&mut self, record: &FrameRecord) -> std::ops::ControlFlow<()> {
        let done = record.frame + 1;
        let told =
            (self.send)(json!({"type": "progress", "done": done, "total": self.total, "dir": self.dir}));
        if !told || self.cancel.load(Ordering::Relaxed) {
            std::ops::ControlFlow::Break(())
        } else {
            std::ops::ControlFlow::Continue(())
        }
    }
}

/// Render `total` frames of `scene` at its own size into `dir` in `format` (with the
/// scene file beside them) through the runner, its files from `assets`.
fn render_to(
    scene: &Scene,
    assets: &Assets,
    limits: &Limits,
    dir: &Path,
    total: u32,
    format: Format,
    progress: &mut FinalProgress<'_>,
) -> Result<()> {
    ensure_dir(dir)?;
    let text = scene_toml(scene).map_err(anyhow::Error::msg)?;
    write_bytes_atomic(&dir.join("scene.toml"), text.as_bytes())?;
    let job = Job { frames: Some(0..total), ..Job::new(dir, format) };
    phenomena_scene::job::render(scene.clone(), assets, limits, &job, progress)?;
    Ok(())
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Two final renders started in the same second (two tabs, or two formats of one
    /// scene) get folders of their own, named by scene, date and time and format.
    #[test]
    fn each_final_render_gets_a_folder_of_its_own() {
        let png = || Format::named("png").unwrap();
        let root = tempfile::tempdir().unwrap();
        let a = render_folder(root.path(), "flame-paper", png()).unwrap();
        let b = render_folder(root.path(), "flame-paper", png()).unwrap();
        let c = render_folder(root.path(), "flame-paper", Format::named("exr").unwrap()).unwrap();
        assert!(a != b && a.is_dir() && b.is_dir() && c.is_dir());
        let name = a.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with("flame-paper-20") && name.ends_with("-png"), "{name}");
        assert!(b.file_name().unwrap().to_string_lossy().starts_with(&name), "{}", b.display());
        assert!(c.file_name().unwrap().to_string_lossy().ends_with("-exr"));
        // A hostile name stays one plain folder inside the root.
        let d = render_folder(root.path(), "../x\n/..", png()).unwrap();
        assert_eq!(d.parent().unwrap(), root.path());
        assert!(d.file_name().unwrap().to_string_lossy().starts_with("scene.._x__.."), "{}", d.display());
    }

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
