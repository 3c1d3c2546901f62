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

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, TryRecvError};
use std::time::{Duration, Instant};

use anyhow::{Result, bail};
use phenomena_aurora::shape::{Keyframe, Merge, PointRef, Split, resample, segments_intersect};
use phenomena_core::tonemap::Exposure;
use serde::Deserialize;
use serde_json::{Value, json};

use crate::render::Runner;
use crate::scene::{self, Scene};

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

/// The aurora's sky preview emits for about this many particles per frame (every k-th
/// particle, k times the weight, the phase turning each frame: an unbiased thinning,
/// see `SkyRenderer::set_particle_subset`); final renders use all of them.
const AURORA_PREVIEW_PARTICLES: usize = 15_000;

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
    /// An aurora editing operation.
    Aurora(AuroraOp),
    /// Ask for the scene as TOML (for download).
    Save,
    /// Render the scene at its own size to the studio's output folder.
    RenderFinal {
        frames: Option<u32>,
    },
}

/// Aurora editor operations (thesis §3.1, Figs 3.1-3.3).
#[derive(Debug, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case", deny_unknown_fields)]
pub(crate) enum AuroraOp {
    /// A mouse stroke on keyframe `keyframe`'s canvas, samples in km of the plane.
    Stroke { keyframe: usize, points: Vec<[f32; 2]> },
    /// Open the segment that starts at (sheet, point) during the transition into
    /// `keyframe`.
    Split { keyframe: u32, sheet: u32, point: u32 },
    /// Join two chain ends during the transition into `keyframe`.
    Merge { keyframe: u32, a: PointRef, b: PointRef },
    /// Add a target keyframe at `frame` (a copy of the last one to draw over).
    AddKeyframe { frame: u32 },
    /// Move keyframe `keyframe` to `frame`.
    MoveKeyframe { keyframe: usize, frame: u32 },
    /// Delete target keyframe `keyframe` (and its operations).
    DeleteKeyframe { keyframe: usize },
    /// Start over: no sheets, a source and one target keyframe.
    Clear,
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
        "builtins": super::controls::BUILTINS.iter().map(|b| json!({"name": b.name, "phenomenon": b.phenomenon})).collect::<Vec<_>>(),
        "featured": controls.featured(),
        "limits": { "upload_bytes": super::MAX_UPLOAD_BYTES, "message_bytes": super::MAX_MESSAGE_BYTES },
    })
    .to_string()
}

/// The scene as JSON (the form the page edits).
pub(crate) fn scene_json(scene: &Scene) -> Value {
    let v = match scene {
        Scene::Flame(s) => serde_json::to_value(&**s),
        Scene::Aurora(s) => serde_json::to_value(&**s),
        Scene::Snow(s) => serde_json::to_value(&**s),
        Scene::Sparkle(s) => serde_json::to_value(&**s),
    };
    v.unwrap_or(Value::Null)
}

/// A scene from its JSON form (not validated).
pub(crate) fn scene_from_json(phenomenon: &str, v: Value) -> Result<Scene, String> {
    let e = |e: serde_json::Error| e.to_string();
    Ok(match phenomenon {
        "flame" => Scene::Flame(Box::new(serde_json::from_value(v).map_err(e)?)),
        "aurora" => Scene::Aurora(Box::new(serde_json::from_value(v).map_err(e)?)),
        "snow" => Scene::Snow(Box::new(serde_json::from_value(v).map_err(e)?)),
        "sparkle" => Scene::Sparkle(Box::new(serde_json::from_value(v).map_err(e)?)),
        other => return Err(format!("unknown phenomenon `{other}`")),
    })
}

/// The scene as a TOML file `phenomena render` accepts.
pub(crate) fn scene_toml(scene: &Scene) -> Result<String> {
    let body = match scene {
        Scene::Flame(s) => toml::to_string(&**s)?,
        Scene::Aurora(s) => toml::to_string(&**s)?,
        Scene::Snow(s) => toml::to_string(&**s)?,
        Scene::Sparkle(s) => toml::to_string(&**s)?,
    };
    Ok(format!(
        "# Saved by phenomena studio. Render it with:\n#   phenomena render {}.toml --out out\n\n{body}",
        scene.phenomenon()
    ))
}

/// Set `value` at a dotted path (`a.b.c`, no array indices) in a JSON object. Setting a
/// tagged enum's `kind` replaces the whole table by `{kind = value}` so the new variant
/// starts from its defaults.
pub(crate) fn set_path(root: &mut Value, path: &str, value: Value) -> Result<(), String> {
    let keys: Vec<&str> = path.split('.').collect();
    if keys.iter().any(|k| k.is_empty()) {
        return Err(format!("bad parameter path `{path}`"));
    }
    let (last, parents) = keys.split_last().ok_or_else(|| format!("bad parameter path `{path}`"))?;
    let mut at = root;
    for k in parents {
        at = at
            .get_mut(*k)
            .filter(|v| v.is_object())
            .ok_or_else(|| format!("no parameter `{path}` in this scene"))?;
    }
    let obj = at.as_object_mut().ok_or_else(|| format!("no parameter `{path}` in this scene"))?;
    if *last == "kind" {
        obj.clear();
        obj.insert("kind".into(), value);
        return Ok(());
    }
    // A key the scene's type does not know is refused when the JSON is read back.
    obj.insert((*last).to_string(), value);
    Ok(())
}

/// Files a scene reads (mesh, background image), as written in it.
fn asset_paths(scene: &Scene) -> Vec<(&'static str, PathBuf)> {
    let mut paths = Vec::new();
    match scene {
        Scene::Flame(f) => {
            if let phenomena_flame::Background::Image { path } = &f.render.background {
                paths.push(("render.background.path", PathBuf::from(path)));
            }
        }
        Scene::Snow(s) => {
            if let Some(mesh) = &s.geometry.mesh {
                paths.push(("geometry.mesh", mesh.clone()));
            }
        }
        Scene::Sparkle(s) => {
            if let phenomena_sparkle::Background::Image { path } = &s.render.background {
                paths.push(("render.background.path", path.clone()));
            }
        }
        Scene::Aurora(_) => {}
    }
    paths
}

/// In the studio a scene reads only files uploaded to its session: plain file names,
/// no folders, so a page cannot make the server read anything else on the machine.
fn check_assets(scene: &Scene) -> Result<(), String> {
    for (field, path) in asset_paths(scene) {
        let mut parts = path.components();
        let plain = matches!((parts.next(), parts.next()), (Some(std::path::Component::Normal(_)), None));
        if !plain {
            return Err(format!(
                "{field} = {:?}: in the studio, upload the file and use its plain name (no folders)",
                path.display().to_string()
            ));
        }
    }
    Ok(())
}

/// Editor bookkeeping of the aurora: which sheets of each keyframe the artist drew
/// (the others are placeholders copied from the source, so the scene stays valid while
/// targets are being drawn).
#[derive(Clone, Debug, Default)]
struct Drawn(Vec<Vec<bool>>);

struct Session {
    dir: tempfile::TempDir,
    out_root: PathBuf,
    out: tokio::sync::mpsc::Sender<Out>,
    scene: Option<Scene>,
    drawn: Drawn,
    runner: Option<Runner>,
    generation: u32,
    frame: u32,
    playing: bool,
    preview: (u32, u32),
    next_due: Instant,
    render_cancel: Option<Arc<AtomicBool>>,
    renders: u32,
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
        frame: 0,
        playing: true,
        preview: (640, 360),
        next_due: Instant::now(),
        render_cancel: None,
        renders: 0,
    };
    let _ = s.loop_until_closed(&inbox);
    if let Some(cancel) = &s.render_cancel {
        cancel.store(true, Ordering::Relaxed);
    }
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
                Some(c) => self.command(c)?,
                None => {
                    self.next_due = Instant::now() + Duration::from_secs_f64(1.0 / MAX_PREVIEW_FPS);
                    let generation = self.generation;
                    let Some((step_ms, counters)) = self.step()? else { continue };
                    // What came in during the step goes first: a change makes this
                    // frame stale, and the change's own frame is then the next shown.
                    loop {
                        match inbox.try_recv() {
                            Ok(c) => self.command(c)?,
                            Err(TryRecvError::Empty) => break,
                            Err(TryRecvError::Disconnected) => return Err(Closed),
                        }
                    }
                    if self.generation == generation {
                        self.render_and_send(step_ms, counters)?;
                    }
                }
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
            Incoming::Builtin { name } => match super::controls::builtin(&name) {
                Some(b) => match scene::parse(b.text, Path::new(b.name)) {
                    Ok(scene) => self.replace(scene)?,
                    Err(e) => self.error(format!("shipped scene {name} is invalid: {e}"))?,
                },
                None => self.error(format!("no shipped scene `{name}`"))?,
            },
            Incoming::Toml { text, name } => {
                let name = name.unwrap_or_else(|| "uploaded.toml".into());
                match scene::parse(&text, Path::new(&name)) {
                    Ok(scene) => self.replace(scene)?,
                    Err(e) => self.send(json!({
                        "type": "error",
                        "message": format!("{name} was not loaded: {e}"),
                        "located": e.0.iter().map(|l| json!({"line": l.line, "column": l.column, "message": l.message})).collect::<Vec<_>>(),
                    }))?,
                }
            }
            Incoming::Scene { phenomenon, scene } => match scene_from_json(&phenomenon, scene) {
                Ok(s) => {
                    let problems = s.validate();
                    if problems.is_empty() {
                        self.replace(s)?;
                    } else {
                        self.error(format!(
                            "scene refused: {}",
                            problems.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ")
                        ))?;
                    }
                }
                Err(e) => self.error(format!("scene refused: {e}"))?,
            },
            Incoming::Set { path, value } => self.set(&path, value)?,
            Incoming::Play => {
                self.playing = true;
                self.next_due = Instant::now();
            }
            Incoming::Pause => self.playing = false,
            Incoming::Step => {
                self.playing = false;
                self.advance()?;
            }
            Incoming::Reset => self.rebuild()?,
            Incoming::Preview { width, height } => {
                if !(16..=MAX_PREVIEW_SIDE).contains(&width) || !(16..=MAX_PREVIEW_SIDE).contains(&height) {
                    self.error(format!(
                        "preview {width}x{height}: each side must be in [16, {MAX_PREVIEW_SIDE}] pixels"
                    ))?;
                } else {
                    self.preview = (width, height);
                    self.rebuild()?;
                }
            }
            Incoming::Wind { force } => self.wind(force)?,
            Incoming::Aurora(op) => self.aurora(op)?,
            Incoming::Save => match &self.scene {
                Some(scene) => match scene_toml(scene) {
                    Ok(text) => {
                        let problems = scene.validate();
                        self.send(json!({
                            "type": "saved",
                            "name": format!("{}.toml", scene.phenomenon()),
                            "toml": text,
                            "valid": problems.is_empty(),
                            "problems": problems.iter().map(ToString::to_string).collect::<Vec<_>>(),
                        }))?
                    }
                    Err(e) => self.error(format!("cannot write the scene as TOML: {e:#}"))?,
                },
                None => self.error("no scene to save: load one first")?,
            },
            Incoming::RenderFinal { frames } => self.render_final(frames)?,
        }
        Ok(())
    }

    /// Take a new scene (already valid) and start it.
    fn replace(&mut self, scene: Scene) -> Result<(), Closed> {
        if let Err(e) = check_assets(&scene) {
            return self.error(format!("scene refused: {e}"));
        }
        self.drawn = match &scene {
            Scene::Aurora(a) => {
                Drawn(a.aurora.keyframes.iter().map(|k| vec![true; k.sheets.len()]).collect())
            }
            _ => Drawn::default(),
        };
        self.scene = Some(scene);
        self.rebuild()
    }

    /// The scene the preview runs: the authored one at the preview's size.
    fn preview_scene(&self) -> Option<Scene> {
        let mut scene = self.scene.clone()?;
        let s = scene.settings_mut();
        (s.width, s.height) = self.preview;
        Some(scene)
    }

    /// A new generation: the scene to the page, the simulation rebuilt, its first frame.
    fn rebuild(&mut self) -> Result<(), Closed> {
        self.generation = self.generation.wrapping_add(1);
        self.frame = 0;
        self.runner = None;
        let Some(scene) = self.preview_scene() else {
            return Ok(());
        };
        self.send_scene()?;
        if let Scene::Aurora(a) = &scene
            && a.aurora.keyframes.first().is_none_or(|k| k.sheets.is_empty())
        {
            return self.notice("draw a sheet on the source canvas to start the aurora");
        }
        let problems = scene.validate();
        if !problems.is_empty() {
            return self.send(json!({
                "type": "error",
                "message": format!("the preview waits for a valid scene: {}", problems.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ")),
                "issues": problems.iter().map(|i| json!({"field": i.field, "message": i.to_string()})).collect::<Vec<_>>(),
            }));
        }
        match Runner::new(&scene, self.dir.path()) {
            Ok(runner) => self.runner = Some(runner),
            Err(e) => return self.error(format!("cannot start the simulation: {e:#}")),
        }
        self.next_due = Instant::now();
        self.render_and_send(0.0, Value::Null)
    }

    fn send_scene(&self) -> Result<(), Closed> {
        let Some(scene) = &self.scene else { return Ok(()) };
        let mut msg = json!({
            "type": "scene",
            "generation": self.generation,
            "phenomenon": scene.phenomenon(),
            "scene": scene_json(scene),
        });
        if let Scene::Aurora(a) = scene {
            msg["editor"] = aurora_editor(&a.aurora, &self.drawn);
        }
        self.send(msg)
    }

    /// One frame: step, render, send.
    fn advance(&mut self) -> Result<(), Closed> {
        match self.step()? {
            Some((step_ms, counters)) => self.render_and_send(step_ms, counters),
            None => Ok(()),
        }
    }

    /// One step: its time (ms) and counters; `None` without a simulation or when it
    /// stopped (the page is told).
    fn step(&mut self) -> Result<Option<(f64, Value)>, Closed> {
        let Some(runner) = &mut self.runner else { return Ok(None) };
        let t = Instant::now();
        match runner.step() {
            Ok(counters) => {
                self.frame += 1;
                Ok(Some((t.elapsed().as_secs_f64() * 1e3, counters)))
            }
            Err(e) => {
                self.playing = false;
                self.runner = None;
                self.error(format!("the simulation stopped at frame {}: {e:#}", self.frame + 1))?;
                Ok(None)
            }
        }
    }

    fn render_and_send(&mut self, step_ms: f64, counters: Value) -> Result<(), Closed> {
        let (Some(runner), Some(scene)) = (&mut self.runner, &self.scene) else { return Ok(()) };
        let exposure: Exposure = scene.settings().exposure();
        if let Runner::Aurora { sim, sky: Some(sky), .. } = runner {
            let k = sim.particles().len().div_ceil(AURORA_PREVIEW_PARTICLES).max(1);
            sky.set_particle_subset(k, self.frame as usize % k);
        }
        let t = Instant::now();
        let frame = runner.render();
        let render_ms = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let (w, h) = (frame.width() as u32, frame.height() as u32);
        let rgb = crate::output::to_srgb8(frame, &exposure);
        let tonemap_ms = t.elapsed().as_secs_f64() * 1e3;
        let stats = json!({
            "type": "frame",
            "generation": self.generation,
            "frame": self.frame,
            "step_ms": step_ms,
            "render_ms": render_ms,
            "tonemap_ms": tonemap_ms,
            "counters": counters,
        });
        // JPEG encoding overlaps the next step on the encoder thread.
        let job = EncodeJob { header: [self.generation, self.frame, w, h], rgb, stats };
        self.encoder.send(job).map_err(|_| Closed)
    }

    fn set(&mut self, path: &str, value: Value) -> Result<(), Closed> {
        let Some(scene) = &self.scene else { return self.error("no scene yet: load one first") };
        let phenomenon = scene.phenomenon();
        let mut v = scene_json(scene);
        if let Err(e) = set_path(&mut v, path, value.clone()) {
            return self.error(e);
        }
        let candidate = match scene_from_json(phenomenon, v) {
            Ok(c) => c,
            Err(e) => {
                self.send(json!({"type": "error", "message": format!("{path} = {value}: {e}"), "issues": [{"field": path, "message": e}]}))?;
                return self.send_scene();
            }
        };
        if let Err(e) = check_assets(&candidate) {
            self.send(json!({"type": "error", "message": e, "issues": [{"field": path, "message": e}]}))?;
            return self.send_scene();
        }
        let problems = candidate.validate();
        if !problems.is_empty() {
            self.send(json!({
                "type": "error",
                "message": problems.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "),
                "issues": problems.iter().map(|i| json!({"field": i.field, "message": i.to_string()})).collect::<Vec<_>>(),
            }))?;
            return self.send_scene(); // the page's controls go back to the scene's values
        }
        self.scene = Some(candidate);
        self.rebuild()
    }

    fn wind(&mut self, force: [f32; 3]) -> Result<(), Closed> {
        let Some(Scene::Flame(f)) = &mut self.scene else {
            return self.error("wind applies to flame scenes");
        };
        let wind = phenomena_flame::Wind { force_n_m3: glam::Vec3::from(force), keys: Vec::new() };
        if let Some(Runner::Flame { sim, .. }) = &mut self.runner
            && let Err(e) = sim.set_wind(wind.clone())
        {
            return self.error(format!("wind {force:?} refused: {e}"));
        }
        f.flame.wind = wind;
        // The same simulation continues (no new generation): the drag steers it live.
        self.send(json!({"type": "wind", "force": force}))
    }

    fn snow_glb(&self) -> Result<Vec<u8>, String> {
        match &self.runner {
            Some(Runner::Snow { sim, .. }) => {
                let tris = phenomena_snow::export::snow_mesh(sim);
                Ok(phenomena_snow::export::to_glb(&tris))
            }
            _ => Err("the session is not running a snow scene".into()),
        }
    }

    fn render_final(&mut self, frames: Option<u32>) -> Result<(), Closed> {
        let Some(scene) = self.scene.clone() else { return self.error("no scene to render") };
        let problems = scene.validate();
        if !problems.is_empty() {
            return self.error(format!(
                "the scene is not valid: {}",
                problems.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ")
            ));
        }
        let total = frames.unwrap_or(scene.settings().frames);
        if !(1..=100_000).contains(&total) {
            return self.error(format!("render final: frames = {total}: expected [1, 100000]"));
        }
        if let Some(c) = self.render_cancel.take() {
            c.store(true, Ordering::Relaxed);
        }
        self.renders += 1;
        let stamp =
            std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
        let dir = self.out_root.join(format!("{}-{stamp}-{}", scene.phenomenon(), self.renders));
        let cancel = Arc::new(AtomicBool::new(false));
        self.render_cancel = Some(cancel.clone());
        let out = self.out.clone();
        let assets = self.dir.path().to_path_buf();
        let spawned = std::thread::Builder::new().name("studio-render".into()).spawn(move || {
            let send = |v: Value| out.blocking_send(Out::Text(v.to_string())).is_ok();
            match render_to(&scene, &assets, &dir, total, &cancel, |done| {
                send(json!({"type": "progress", "done": done, "total": total, "dir": dir.display().to_string()}))
            }) {
                Ok(()) => {
                    send(json!({"type": "rendered", "dir": dir.display().to_string(), "frames": total}));
                }
                Err(e) => {
                    send(json!({"type": "error", "message": format!("render final failed: {e:#}")}));
                }
            }
        });
        match spawned {
            Ok(_) => self.notice(format!("rendering {total} frames to {}", self.out_root.display())),
            Err(e) => self.error(format!("cannot start the render: {e}")),
        }
    }

    fn aurora(&mut self, op: AuroraOp) -> Result<(), Closed> {
        let Some(Scene::Aurora(a)) = &self.scene else {
            return self.error("aurora editing needs an aurora scene: open the Aurora tab");
        };
        let mut config = a.aurora.clone();
        let mut drawn = self.drawn.clone();
        match edit_aurora(&mut config, &mut drawn, op) {
            Ok(message) => {
                if let Some(Scene::Aurora(a)) = &mut self.scene {
                    a.aurora = config;
                }
                self.drawn = drawn;
                self.rebuild()?;
                if let Some(m) = message {
                    self.notice(m)?;
                }
                Ok(())
            }
            Err(refusal) => self.send(json!({"type": "refused", "message": refusal})),
        }
    }
}

/// Render `total` frames of `scene` at its own size into `dir` (PNG, with the scene
/// file beside them), reporting after each frame; stops early when cancelled or when
/// `progress` returns false.
fn render_to(
    scene: &Scene,
    assets: &Path,
    dir: &Path,
    total: u32,
    cancel: &AtomicBool,
    mut progress: impl FnMut(u32) -> bool,
) -> Result<()> {
    crate::output::ensure_dir(dir)?;
    crate::output::write_bytes_atomic(&dir.join("scene.toml"), scene_toml(scene)?.as_bytes())?;
    let mut runner = Runner::new(scene, assets)?;
    let exposure = scene.settings().exposure();
    for f in 0..total {
        if cancel.load(Ordering::Relaxed) {
            bail!("cancelled after {f} frames");
        }
        runner.step()?;
        let frame = runner.render();
        let path = dir.join(format!("frame_{f:05}.png"));
        crate::output::write_frame(&path, frame, &[], crate::output::ImageFormat::Png, &exposure)?;
        if !progress(f + 1) {
            bail!("the page went away after {} frames", f + 1);
        }
    }
    Ok(())
}

/// The control points of every sheet of keyframe `k`, resampled as the simulation does.
fn control_points(config: &phenomena_aurora::AuroraConfig, k: usize) -> Vec<Vec<glam::Vec2>> {
    let n = config.shape.control_points_per_sheet as usize;
    config.keyframes[k]
        .sheets
        .iter()
        .map(|s| {
            let pts: Vec<glam::Vec2> = s.iter().map(|p| glam::Vec2::from(*p)).collect();
            resample(&pts, n, config.shape.resample)
        })
        .collect()
}

/// The first sheet of `other` that the polyline `stroke` crosses.
fn crossed(stroke: &[glam::Vec2], other: &[Vec<glam::Vec2>], skip: Option<usize>) -> Option<usize> {
    other.iter().enumerate().filter(|(s, _)| Some(*s) != skip).find_map(|(s, sheet)| {
        let hit =
            stroke.windows(2).any(|a| sheet.windows(2).any(|b| segments_intersect(a[0], a[1], b[0], b[1])));
        hit.then_some(s)
    })
}

/// Apply one editor operation; `Err` is the refusal shown to the artist (and leaves
/// the shapes as they were), `Ok` may carry a hint.
fn edit_aurora(
    config: &mut phenomena_aurora::AuroraConfig,
    drawn: &mut Drawn,
    op: AuroraOp,
) -> Result<Option<String>, String> {
    let (config_before, drawn_before) = (config.clone(), drawn.clone());
    let result = apply_aurora_op(config, drawn, op);
    if result.is_err() {
        (*config, *drawn) = (config_before, drawn_before);
    }
    result
}

fn apply_aurora_op(
    config: &mut phenomena_aurora::AuroraConfig,
    drawn: &mut Drawn,
    op: AuroraOp,
) -> Result<Option<String>, String> {
    let n = config.shape.control_points_per_sheet as usize;
    let last = config.keyframes.len().saturating_sub(1);
    let size = config.plane.size_km;
    match op {
        AuroraOp::Stroke { keyframe: k, points } => {
            if k > last {
                return Err(format!("there is no keyframe {k} (keyframes 0..={last})"));
            }
            if points.len() < 2 {
                return Err("a stroke needs at least two mouse samples: drag to draw".into());
            }
            if let Some(p) =
                points.iter().find(|p| !((0.0..=size.x).contains(&p[0]) && (0.0..=size.y).contains(&p[1])))
            {
                return Err(format!(
                    "stroke point ({}, {}) lies outside the plane [0, {}] x [0, {}] km",
                    p[0], p[1], size.x, size.y
                ));
            }
            let raw: Vec<glam::Vec2> = points.iter().map(|p| glam::Vec2::from(*p)).collect();
            let stroke = resample(&raw, n, config.shape.resample);
            let sheets = control_points(config, k);
            let target = if k == 0 {
                None
            } else {
                match drawn.0[k].iter().position(|d| !d) {
                    Some(s) => Some(s),
                    None => {
                        return Err(format!(
                            "every sheet of keyframe {k} is drawn: draw on the source canvas to add a sheet"
                        ));
                    }
                }
            };
            if let Some(s) = crossed(&stroke, &sheets, target) {
                return Err(format!(
                    "refused: the stroke crosses sheet {s} of keyframe {k} (aurora sheets never cross, thesis §2.2.1)"
                ));
            }
            let sheet: Vec<[f32; 2]> = stroke.iter().map(|p| p.to_array()).collect();
            match target {
                None => {
                    for (kf, d) in config.keyframes.iter_mut().zip(drawn.0.iter_mut()) {
                        kf.sheets.push(sheet.clone());
                        d.push(false);
                    }
                    drawn.0[0][config.keyframes[0].sheets.len() - 1] = true;
                    Ok((last > 0).then(|| {
                        "sheet added: now draw where it goes on the target canvas (the highlighted placeholder)"
                            .to_string()
                    }))
                }
                Some(s) => {
                    config.keyframes[k].sheets[s] = sheet;
                    drawn.0[k][s] = true;
                    Ok(None)
                }
            }
        }
        AuroraOp::Split { keyframe, sheet, point } => {
            config.splits.push(Split { keyframe, start: PointRef { sheet, point } });
            check_animation(config).map(|()| None)
        }
        AuroraOp::Merge { keyframe, a, b } => {
            if a == b {
                return Err("pick two different end points to merge".into());
            }
            config.merges.push(Merge { keyframe, a, b });
            check_animation(config).map(|()| None)
        }
        AuroraOp::AddKeyframe { frame } => {
            let prev = config.keyframes.last().map_or(0, |k| k.frame);
            if frame <= prev && !config.keyframes.is_empty() {
                return Err(format!(
                    "a new keyframe goes after the last one (frame {prev}); got frame {frame}"
                ));
            }
            let sheets = config.keyframes.last().map(|k| k.sheets.clone()).unwrap_or_default();
            drawn.0.push(vec![false; sheets.len()]);
            config.keyframes.push(Keyframe { frame, sheets });
            Ok(Some(format!(
                "keyframe {} added at frame {frame}: draw its sheets",
                config.keyframes.len() - 1
            )))
        }
        AuroraOp::MoveKeyframe { keyframe, frame } => {
            if keyframe > last {
                return Err(format!("there is no keyframe {keyframe}"));
            }
            config.keyframes[keyframe].frame = frame;
            let order_ok = config.keyframes.windows(2).all(|w| w[0].frame < w[1].frame);
            if !order_ok {
                return Err(format!(
                    "keyframe {keyframe} cannot move to frame {frame}: keyframes stay in time order without ties"
                ));
            }
            Ok(None)
        }
        AuroraOp::DeleteKeyframe { keyframe } => {
            if keyframe == 0 {
                return Err("the source keyframe cannot be deleted (use Clear to start over)".into());
            }
            if keyframe > last {
                return Err(format!("there is no keyframe {keyframe}"));
            }
            if config.keyframes.len() <= 2 {
                return Err("an aurora needs a source and at least one target keyframe".into());
            }
            config.keyframes.remove(keyframe);
            drawn.0.remove(keyframe);
            let k = keyframe as u32;
            config.splits.retain(|s| s.keyframe != k);
            config.merges.retain(|m| m.keyframe != k);
            for s in &mut config.splits {
                if s.keyframe > k {
                    s.keyframe -= 1;
                }
            }
            for m in &mut config.merges {
                if m.keyframe > k {
                    m.keyframe -= 1;
                }
            }
            check_animation(config).map(|()| None)
        }
        AuroraOp::Clear => {
            let end = config.keyframes.get(1).map_or(120, |k| k.frame);
            config.keyframes =
                vec![Keyframe { frame: 0, sheets: Vec::new() }, Keyframe { frame: end, sheets: Vec::new() }];
            config.splits.clear();
            config.merges.clear();
            drawn.0 = vec![Vec::new(), Vec::new()];
            Ok(None)
        }
    }
}

fn check_animation(config: &phenomena_aurora::AuroraConfig) -> Result<(), String> {
    config.animation().map(|_| ()).map_err(|e| format!("refused: {e}"))
}

/// What the editor draws: per keyframe, the control points with their links as the
/// simulation sees them at that keyframe (splits open, merges joined), which sheets
/// the artist drew, and the sheet the next stroke on that canvas fills.
fn aurora_editor(config: &phenomena_aurora::AuroraConfig, drawn: &Drawn) -> Value {
    let built = config.animation();
    let keyframes: Vec<Value> = config
        .keyframes
        .iter()
        .enumerate()
        .map(|(k, kf)| {
            let d = drawn.0.get(k).cloned().unwrap_or_else(|| vec![true; kf.sheets.len()]);
            let next_sheet = if k == 0 { Some(kf.sheets.len()) } else { d.iter().position(|x| !x) };
            let shape = match &built {
                Ok(anim) if !kf.sheets.is_empty() => {
                    let s = anim.shape_at(kf.frame as f32);
                    json!({
                        "points": s.points.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>(),
                        "next": s.next,
                        "sheet": s.sheet,
                        "index": s.index_in_sheet,
                    })
                }
                _ => {
                    // The strokes as drawn, each a chain.
                    let (mut points, mut next, mut sheet, mut index) = (vec![], vec![], vec![], vec![]);
                    for (s, stroke) in kf.sheets.iter().enumerate() {
                        for (i, p) in stroke.iter().enumerate() {
                            let id = points.len() as u32;
                            points.push(*p);
                            next.push((i + 1 < stroke.len()).then_some(id + 1));
                            sheet.push(s as u32);
                            index.push(i as u32);
                        }
                    }
                    json!({"points": points, "next": next, "sheet": sheet, "index": index})
                }
            };
            json!({"frame": kf.frame, "drawn": d, "next_sheet": next_sheet, "shape": shape})
        })
        .collect();
    json!({
        "plane_km": [config.plane.size_km.x, config.plane.size_km.y],
        "control_points": config.shape.control_points_per_sheet,
        "built": built.is_ok(),
        "problem": built.err().map(|e| e.to_string()),
        "keyframes": keyframes,
    })
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    fn line(x0: f32, z0: f32, x1: f32, z1: f32) -> Vec<[f32; 2]> {
        (0..20).map(|i| i as f32 / 19.0).map(|t| [x0 + (x1 - x0) * t, z0 + (z1 - z0) * t]).collect()
    }

    fn stroke(keyframe: usize, points: Vec<[f32; 2]>) -> AuroraOp {
        AuroraOp::Stroke { keyframe, points }
    }

    #[test]
    fn the_editor_draws_sources_then_targets_and_refuses_crossings() {
        let mut c = phenomena_aurora::AuroraConfig::default();
        let mut d = Drawn::default();
        edit_aurora(&mut c, &mut d, AuroraOp::Clear).unwrap();
        edit_aurora(&mut c, &mut d, stroke(0, line(50.0, 100.0, 300.0, 100.0))).unwrap();
        edit_aurora(&mut c, &mut d, stroke(0, line(50.0, 200.0, 300.0, 200.0))).unwrap();
        let n = c.shape.control_points_per_sheet as usize;
        assert_eq!(c.keyframes[0].sheets.len(), 2);
        assert_eq!(c.keyframes[0].sheets[0].len(), n, "strokes are stored resampled");
        assert_eq!(d.0[1], vec![false, false], "targets start as placeholders");
        let e = edit_aurora(&mut c, &mut d, stroke(0, line(100.0, 50.0, 100.0, 250.0))).unwrap_err();
        assert!(e.contains("crosses sheet 0"), "{e}");
        // The target's next stroke fills sheet 0; one that crosses sheet 1 is refused.
        let e = edit_aurora(&mut c, &mut d, stroke(1, line(50.0, 120.0, 300.0, 260.0))).unwrap_err();
        assert!(e.contains("crosses sheet 1"), "{e}");
        edit_aurora(&mut c, &mut d, stroke(1, line(50.0, 130.0, 300.0, 150.0))).unwrap();
        assert_eq!(d.0[1], vec![true, false]);
        let v = aurora_editor(&c, &d);
        assert_eq!(v["built"], true, "{v}");
        assert_eq!(v["keyframes"][1]["next_sheet"], 1);
        assert!(c.validate().is_ok());
    }

    #[test]
    fn split_and_merge_change_the_links_and_bad_ones_are_refused() {
        let mut c = phenomena_aurora::AuroraConfig::default();
        let mut d = Drawn::default();
        edit_aurora(&mut c, &mut d, AuroraOp::Clear).unwrap();
        edit_aurora(&mut c, &mut d, stroke(0, line(50.0, 100.0, 300.0, 100.0))).unwrap();
        let links = |c: &phenomena_aurora::AuroraConfig| {
            let v =
                aurora_editor(c, &Drawn(c.keyframes.iter().map(|k| vec![true; k.sheets.len()]).collect()));
            v["keyframes"][1]["shape"]["next"].as_array().unwrap().iter().filter(|x| !x.is_null()).count()
        };
        let n = c.shape.control_points_per_sheet as usize;
        assert_eq!(links(&c), n - 1);
        edit_aurora(&mut c, &mut d, AuroraOp::Split { keyframe: 1, sheet: 0, point: 5 }).unwrap();
        // A split adds two points and opens one segment: n + 1 points, n - 2 + 2 links... the chain
        // a -> m1 and m2 -> b, so the link count grows by one and one segment is open.
        assert_eq!(links(&c), n);
        let e = edit_aurora(&mut c, &mut d, AuroraOp::Split { keyframe: 1, sheet: 0, point: (n - 1) as u32 })
            .unwrap_err();
        assert!(e.contains("starts no segment"), "{e}");
        edit_aurora(&mut c, &mut d, AuroraOp::AddKeyframe { frame: 240 }).unwrap();
        // Merge the two ends of the split (the added points n and n + 1) in the next transition.
        let a = PointRef { sheet: 0, point: n as u32 };
        let b = PointRef { sheet: 0, point: n as u32 + 1 };
        edit_aurora(&mut c, &mut d, AuroraOp::Merge { keyframe: 2, a, b }).unwrap();
        let e = edit_aurora(
            &mut c,
            &mut d,
            AuroraOp::Merge { keyframe: 2, a: PointRef { sheet: 0, point: 3 }, b },
        )
        .unwrap_err();
        assert!(e.contains("refused"), "{e}");
        assert!(c.validate().is_ok());
        let e = edit_aurora(&mut c, &mut d, AuroraOp::MoveKeyframe { keyframe: 2, frame: 10 }).unwrap_err();
        assert!(e.contains("time order"), "{e}");
        edit_aurora(&mut c, &mut d, AuroraOp::DeleteKeyframe { keyframe: 2 }).unwrap();
        assert!(c.merges.is_empty() && c.keyframes.len() == 2);
    }

    #[test]
    fn saved_scenes_read_back_identically() {
        for b in super::super::controls::BUILTINS {
            let scene = scene::parse(b.text, Path::new(b.name)).unwrap();
            let text = scene_toml(&scene).unwrap();
            let back = scene::parse(&text, Path::new("saved.toml"))
                .unwrap_or_else(|e| panic!("{}: {e}\n{text}", b.name));
            assert_eq!(back, scene, "{}", b.name);
            let json = scene_json(&scene);
            assert_eq!(scene_from_json(scene.phenomenon(), json).unwrap(), scene, "{}", b.name);
        }
    }

    #[test]
    fn scenes_read_only_plain_uploaded_names() {
        let mut scene = scene::parse(super::super::controls::BUILTINS[0].text, Path::new("f")).unwrap();
        assert!(check_assets(&scene).is_ok());
        for (path, ok) in
            [("bg.png", true), ("../bg.png", false), ("/etc/passwd", false), ("a/bg.png", false)]
        {
            if let Scene::Flame(f) = &mut scene {
                f.render.background = phenomena_flame::Background::Image { path: path.into() };
            }
            assert_eq!(check_assets(&scene).is_ok(), ok, "{path}");
        }
    }

    #[test]
    fn set_path_sets_leaves_and_resets_tagged_tables() {
        let mut v =
            json!({"render": {"background": {"kind": "checker", "light": [1, 1, 1]}, "intensity": 1}});
        set_path(&mut v, "render.intensity", json!(2)).unwrap();
        set_path(&mut v, "render.background.kind", json!("sky")).unwrap();
        assert_eq!(v, json!({"render": {"background": {"kind": "sky"}, "intensity": 2}}));
        assert!(set_path(&mut v, "render.nothing.x", json!(1)).is_err());
        assert!(set_path(&mut v, "render..x", json!(1)).is_err());
    }
}
