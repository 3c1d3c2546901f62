//! "Render final": a tab's scene rendered at its own size to the studio's output
//! folder on a thread of its own, frames `first..=last` (the frames before are
//! simulated as pre-roll and not written), in any format the phenomenon offers, with
//! the format's options, progress to the page and the folder it went to.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::Result;
use phenomena_scene::atlas::{Alpha, FlipbookSettings};
use phenomena_scene::format::OutputOptions;
use phenomena_scene::job::Job;
use phenomena_scene::output::{ensure_dir, write_bytes_atomic};
use phenomena_scene::{Assets, Format, FrameRecord, Limits, Observer, Scene, registry};
use serde::Deserialize;
use serde_json::{Value, json};

/// Most frames one final render may write.
pub(crate) const MAX_FINAL_FRAMES: u32 = 100_000;

/// What the page asks for.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Request {
    /// Frames from 0 (the older form: `first` and `last` say more).
    #[serde(default)]
    pub(crate) frames: Option<u32>,
    /// First frame written (earlier ones are simulated only).
    #[serde(default)]
    pub(crate) first: Option<u32>,
    /// Last frame written (included).
    #[serde(default)]
    pub(crate) last: Option<u32>,
    /// `png` (the default), `exr`, `vdb`, `ply` or `flipbook`, as the phenomenon writes
    /// (see `hello.phenomena[].formats`).
    #[serde(default)]
    pub(crate) format: Option<String>,
    /// flipbook: cells and grid in powers of two.
    #[serde(default)]
    pub(crate) pot: bool,
    /// flipbook: the last K frames cross-faded into the first for a seamless loop.
    #[serde(default)]
    pub(crate) loop_frames: u32,
    /// flipbook: `straight` (the default) or `premultiplied` alpha.
    #[serde(default)]
    pub(crate) alpha: Option<String>,
    /// flipbook: cells cut to the content's bounds.
    #[serde(default)]
    pub(crate) crop: bool,
}

/// A render the page asked for, checked: the frames written, the format and its options.
pub(crate) struct Plan {
    pub(crate) frames: std::ops::Range<u32>,
    pub(crate) format: Format,
    pub(crate) options: OutputOptions,
}

impl Request {
    /// Check the request against `scene`; the error is a sentence for the page naming
    /// the offending value and what is valid.
    pub(crate) fn plan(&self, scene: &Scene) -> Result<Plan, String> {
        let name = self.format.as_deref().unwrap_or("png");
        let Some(format) = Format::named(name) else {
            let all: Vec<&str> = registry::FORMATS.iter().map(|f| f.name()).collect();
            return Err(format!("no format `{name}`: use {}", all.join(", ")));
        };
        format.check(scene.phenomenon()).map_err(|e| e.to_string())?;
        let first = self.first.unwrap_or(0);
        let last = match (self.last, self.frames) {
            (Some(last), _) => last,
            (None, Some(n)) if n >= 1 => first.saturating_add(n - 1),
            (None, Some(n)) => return Err(format!("frames = {n}: expected [1, {MAX_FINAL_FRAMES}]")),
            (None, None) => scene.settings().frames.max(1) - 1,
        };
        if last < first {
            return Err(format!("last frame {last} is before the first, {first}: expected last ≥ first"));
        }
        if last >= MAX_FINAL_FRAMES {
            return Err(format!("last frame {last}: expected [0, {}]", MAX_FINAL_FRAMES - 1));
        }
        let alpha = match self.alpha.as_deref() {
            None | Some("straight") => Alpha::Straight,
            Some("premultiplied") => Alpha::Premultiplied,
            Some(other) => return Err(format!("alpha `{other}`: use straight or premultiplied")),
        };
        let count = last - first + 1;
        if self.loop_frames > 0 && self.loop_frames >= count {
            return Err(format!(
                "loop {} frames: expected fewer than the {count} frames written (0: no loop)",
                self.loop_frames
            ));
        }
        let flipbook = FlipbookSettings {
            power_of_two: self.pot,
            alpha,
            loop_frames: self.loop_frames,
            crop: self.crop,
            motion: false,
        };
        Ok(Plan {
            frames: first..last + 1,
            format,
            options: OutputOptions { flipbook, ..OutputOptions::default() },
        })
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
    frames: std::ops::Range<u32>,
    dir: &'a str,
}

impl Observer for FinalProgress<'_> {
    fn frame(&mut self, record: &FrameRecord) -> std::ops::ControlFlow<()> {
        let done = record.frame + 1;
        let told = (self.send)(json!({
            "type": "progress",
            "done": done,
            "total": self.frames.end,
            "first": self.frames.start,
            "pre_roll": record.frame < self.frames.start,
            "dir": self.dir,
        }));
        if !told || self.cancel.load(Ordering::Relaxed) {
            std::ops::ControlFlow::Break(())
        } else {
            std::ops::ControlFlow::Continue(())
        }
    }
}

/// Run `plan` for `scene` (its files from `assets`) into `dir` on a new thread; the
/// page hears `progress`, then `rendered` or `error`. Returns the thread.
pub(crate) fn spawn(
    mut scene: Scene,
    plan: Plan,
    assets: Assets,
    limits: Limits,
    dir: PathBuf,
    cancel: Arc<AtomicBool>,
    send: impl Fn(Value) -> bool + Send + 'static,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    // The scene written beside the frames runs at least to the last frame.
    let s = scene.settings_mut();
    s.frames = s.frames.max(plan.frames.end);
    std::thread::Builder::new().name("studio-render".into()).spawn(move || {
        let shown = dir.display().to_string();
        let frames = plan.frames.clone();
        let mut progress =
            FinalProgress { send: &send, cancel: &cancel, frames: frames.clone(), dir: &shown };
        // A bug in a render ends that render with a message, not silently.
        let rendered = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            render_to(&scene, &assets, &limits, &dir, &plan, &mut progress)
        }));
        let (first, last) = (frames.start, frames.end - 1);
        let message = match rendered {
            Ok(Ok(files)) => json!({
                "type": "rendered",
                "dir": shown,
                "frames": frames.len(),
                "first": first,
                "last": last,
                "files": files,
            }),
            Ok(Err(e)) => json!({"type": "error", "message": format!("render final failed: {e:#}")}),
            Err(_) => {
                json!({"type": "error", "message": "render final failed: an internal error stopped it"})
            }
        };
        send(message);
    })
}

/// Render `plan` of `scene` at its own size into `dir` (with the scene file beside the
/// frames) through the scene layer's job; the names of the files in `dir` after.
fn render_to(
    scene: &Scene,
    assets: &Assets,
    limits: &Limits,
    dir: &Path,
    plan: &Plan,
    progress: &mut FinalProgress<'_>,
) -> Result<Vec<String>> {
    ensure_dir(dir)?;
    let text = super::session::scene_toml(scene).map_err(anyhow::Error::msg)?;
    write_bytes_atomic(&dir.join("scene.toml"), text.as_bytes())?;
    let job = Job { frames: Some(plan.frames.clone()), options: plan.options, ..Job::new(dir, plan.format) };
    phenomena_scene::job::render(scene.clone(), assets, limits, &job, progress)?;
    let mut files: Vec<String> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .collect();
    files.sort();
    Ok(files)
}

#[cfg(test)]
mod tests {
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

    /// The frames asked for, the format and its options are checked with the
    /// offending value named.
    #[test]
    fn requests_are_checked_with_the_offending_value_named() {
        let scene = phenomena_scene::shipped::shipped("flame-paper").unwrap().scene().unwrap();
        let ok = |r: Request| r.plan(&scene).map(|p| p.frames);
        assert_eq!(ok(Request::default()), Ok(0..scene.settings().frames));
        assert_eq!(ok(Request { frames: Some(3), ..Request::default() }), Ok(0..3));
        assert_eq!(ok(Request { first: Some(30), last: Some(33), ..Request::default() }), Ok(30..34));
        let err = |r: Request| r.plan(&scene).err().unwrap();
        assert!(
            err(Request { first: Some(5), last: Some(4), ..Request::default() }).contains("last frame 4")
        );
        assert!(
            err(Request { format: Some("gif".into()), ..Request::default() }).contains("no format `gif`")
        );
        let alpha =
            Request { alpha: Some("pre".into()), format: Some("flipbook".into()), ..Request::default() };
        assert!(err(alpha).contains("alpha `pre`"));
        let looped = Request { first: Some(0), last: Some(3), loop_frames: 4, ..Request::default() };
        assert!(err(looped).contains("loop 4 frames"));
        let plan = Request { pot: true, loop_frames: 2, first: Some(0), last: Some(7), ..Request::default() };
        let flipbook = plan.plan(&scene).unwrap().options.flipbook;
        assert!(flipbook.power_of_two && flipbook.loop_frames == 2 && flipbook.alpha == Alpha::Straight);
    }
}
