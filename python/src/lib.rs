//! phenomena's Python module, `phenomena._native`: a scene file as the CLI reads it, its
//! simulation stepped and rendered through the scene crate's one [`Runner`], its state
//! and exports, as bytes and JSON the pure-Python package `phenomena` (beside this crate)
//! turns into numpy arrays. Nothing here simulates or renders: every frame and export is
//! the one the `phenomena` command writes for the same scene.
//!
//! Long work runs with the GIL released; a progress callback (called between frames
//! with the GIL held) can stop it by returning `False`, and Ctrl+C stops it between
//! frames. Errors are `phenomena.SceneError` (with every problem's file, line and
//! column where the scene has them) or `ValueError`.

use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard, TryLockError};
use std::time::Duration;

use phenomena_core::image::{Frame, Plane};
use phenomena_core::phenomenon::Layer;
use phenomena_scene::{
    Assets, BuildError, FrameRecord, FrameSink, LeafGrid, Limits, Observer, Output, RunError, Runner, Scene,
    Simulate, SinkError, VolumeOptions, VolumeOut,
};
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

/// A problem: its file, line and column (0 when the scene has no place for it) and
/// what is wrong.
type Problem = (String, usize, usize, String);

/// `phenomena.SceneError(message, problems)`, the Python package's exception.
fn scene_error(py: Python<'_>, message: String, problems: Vec<Problem>) -> PyErr {
    let class = py.import("phenomena._errors").and_then(|m| m.getattr("SceneError"));
    match class.and_then(|c| c.call1((message.clone(), problems))) {
        Ok(instance) => PyErr::from_value(instance),
        Err(_) => PyValueError::new_err(message),
    }
}

/// A build error located in the scene file as the CLI locates it (each problem of an
/// invalid configuration at its own key).
fn build_error(py: Python<'_>, scene: &Scene, e: BuildError) -> PyErr {
    let place = |key: &str, message: String| -> Problem {
        match scene.locate(key, message.clone()) {
            Some(at) => (at.file.display().to_string(), at.line, at.column, at.message),
            None => (String::new(), 0, 0, message),
        }
    };
    let problems: Vec<Problem> = match &e {
        BuildError::Invalid(issues) => issues.iter().map(|i| place(&i.field, i.to_string())).collect(),
        _ => match e.key() {
            Some(key) => vec![place(key, e.to_string())],
            None => vec![(String::new(), 0, 0, e.to_string())],
        },
    };
    let message = problems
        .iter()
        .map(
            |(file, line, column, m)| {
                if *line > 0 { format!("{file}:{line}:{column}: {m}") } else { m.clone() }
            },
        )
        .collect::<Vec<_>>()
        .join("\n");
    scene_error(py, message, problems)
}

/// Why a run stopped, as a Python exception.
fn run_error(e: RunError) -> PyErr {
    match e {
        RunError::Cancelled { frames } => {
            PyKeyboardInterrupt::new_err(format!("stopped after {frames} frames (cancelled)"))
        }
        other => PyValueError::new_err(other.to_string()),
    }
}

/// Calls the user's progress callback after each frame (GIL taken for the call only)
/// and stops the run when it returns `False` or Ctrl+C was pressed.
struct Progress<'a> {
    callback: Option<&'a Py<PyAny>>,
    /// Frames simulated before the call (`callback(done, total)` counts from there).
    start: u32,
    /// Frames the call will simulate.
    total: u32,
    /// An exception the callback raised, given back after the run.
    error: Option<PyErr>,
    /// Each frame's record as JSON, kept when asked for.
    records: Option<Vec<String>>,
}

impl Observer for Progress<'_> {
    fn frame(&mut self, record: &FrameRecord) -> ControlFlow<()> {
        if let Some(list) = &mut self.records {
            list.push(serde_json::to_string(record).unwrap_or_default());
        }
        Python::attach(|py| {
            if let Err(e) = py.check_signals() {
                self.error = Some(e);
                return ControlFlow::Break(());
            }
            let Some(callback) = self.callback else { return ControlFlow::Continue(()) };
            match callback.call1(py, ((record.frame + 1).saturating_sub(self.start), self.total)) {
                Ok(v) if v.bind(py).is(&*pyo3::types::PyBool::new(py, false)) => ControlFlow::Break(()),
                Ok(_) => ControlFlow::Continue(()),
                Err(e) => {
                    self.error = Some(e);
                    ControlFlow::Break(())
                }
            }
        })
    }
}

/// Keeps the frame a run hands over: linear RGB and the extra layers.
struct Capture {
    frame: Frame,
    layers: Vec<(String, Plane)>,
}

impl FrameSink for Capture {
    fn write(&mut self, out: &Output<'_>) -> Result<(), SinkError> {
        self.frame = out.frame.clone();
        self.layers = out.layers.iter().map(|l| (l.name.to_string(), l.plane.clone())).collect();
        Ok(())
    }
}

/// A frame's bytes as Python gives them to numpy: little-endian f32.
fn f32_bytes<'py>(py: Python<'py>, values: &[f32]) -> Bound<'py, PyBytes> {
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    PyBytes::new(py, &bytes)
}

/// A rendered frame: `(rgb, width, height, [(layer, values)])`, values little-endian f32.
type Rendered<'py> = (Bound<'py, PyBytes>, usize, usize, Vec<(String, Bound<'py, PyBytes>)>);

/// One grid's leaves: `(name, class, components, voxel_m, translation_m, origins i32,
/// values f32)`.
type Leaves<'py> = (String, &'static str, usize, f64, [f64; 3], Bound<'py, PyBytes>, Bound<'py, PyBytes>);

/// A scene, its simulation and renderer (`phenomena.Scene` wraps it). Python may call
/// it from several threads: one call at a time works on it.
#[pyclass(module = "phenomena._native")]
struct NativeScene {
    inner: Mutex<Inner>,
    /// The thread (a [`thread_number`]) whose call holds `inner`, 0 when none does.
    owner: AtomicU64,
}

/// A number for the calling thread, unique in the process (never 0).
fn thread_number() -> u64 {
    static NEXT: AtomicU64 = AtomicU64::new(1);
    thread_local!(static NUMBER: u64 = NEXT.fetch_add(1, Ordering::Relaxed));
    NUMBER.with(|n| *n)
}

/// A call's hold on a scene: the scene, and its owner cleared when the call ends.
struct Held<'a> {
    guard: MutexGuard<'a, Inner>,
    owner: &'a AtomicU64,
}

impl Drop for Held<'_> {
    fn drop(&mut self) {
        self.owner.store(0, Ordering::SeqCst);
    }
}

impl std::ops::Deref for Held<'_> {
    type Target = Inner;
    fn deref(&self) -> &Inner {
        &self.guard
    }
}

impl std::ops::DerefMut for Held<'_> {
    fn deref_mut(&mut self) -> &mut Inner {
        &mut self.guard
    }
}

/// What a [`NativeScene`] holds.
struct Inner {
    scene: Scene,
    assets: Assets,
    limits: Limits,
    runner: Option<Runner>,
}

impl NativeScene {
    fn new(scene: Scene, assets: Assets, max_memory_bytes: Option<u64>) -> Self {
        let limits = max_memory_bytes.map_or(Limits::NONE, |b| Limits { memory_bytes: b });
        Self::holding(Inner { scene, assets, limits, runner: None })
    }

    fn holding(inner: Inner) -> Self {
        Self { inner: Mutex::new(inner), owner: AtomicU64::new(0) }
    }

    /// The scene, for one call. Another thread's call is waited for with the GIL
    /// released (it may need the GIL to finish); a call from this thread while one of
    /// its own is running (a progress callback using the scene it reports on) is
    /// refused, as it could never be served.
    fn lock(&self, py: Python<'_>) -> PyResult<Held<'_>> {
        let me = thread_number();
        if self.owner.load(Ordering::SeqCst) == me {
            return Err(PyRuntimeError::new_err(
                "this scene is busy with a call that is reporting progress: a progress callback cannot use the scene it reports on",
            ));
        }
        let guard = loop {
            match self.inner.try_lock() {
                Ok(guard) => break guard,
                Err(TryLockError::WouldBlock) => py.detach(|| std::thread::sleep(Duration::from_micros(200))),
                Err(TryLockError::Poisoned(_)) => {
                    return Err(PyValueError::new_err(
                        "an earlier call on this scene failed midway: load it again",
                    ));
                }
            }
        };
        self.owner.store(me, Ordering::SeqCst);
        Ok(Held { guard, owner: &self.owner })
    }
}

impl Inner {
    /// Render frame `frame` at `width` x `height` ([`NativeScene::render`]).
    fn render(
        &mut self,
        py: Python<'_>,
        frame: Option<u32>,
        width: Option<u32>,
        height: Option<u32>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<Capture> {
        let this = self;
        let settings = this.scene.settings();
        let (w, h) = (width.unwrap_or(settings.width), height.unwrap_or(settings.height));
        // The current state's frame, before a new size can start the run again.
        let frame = frame.unwrap_or(this.frames_done().saturating_sub(1));
        if frame >= 1_000_000 {
            return Err(PyValueError::new_err(format!(
                "frame {frame} is out of range: expected [0, 999999]"
            )));
        }
        this.resize(py, w, h)?;
        let done = this.frames_done();
        let memory = this.scene.render_memory().is_some();
        // The frame asked for is behind the state, or would need a second render of it
        // (a scene whose frames depend on earlier renders): start again from frame 0.
        if done > frame + 1 || (memory && done == frame + 1) {
            this.runner = None;
        }
        let mut capture = Capture { frame: Frame::new(0, 0), layers: Vec::new() };
        if this.frames_done() == frame + 1 {
            let runner = this.runner(py)?;
            let mut record = FrameRecord { frame, ..FrameRecord::default() };
            py.detach(|| runner.output(&mut record, &mut capture)).map_err(run_error)?;
        } else {
            this.run(py, frame..frame + 1, &mut capture, progress.as_ref())?;
        }
        Ok(capture)
    }

    /// Frames simulated so far.
    fn frames_done(&self) -> u32 {
        self.runner.as_ref().map_or(0, Runner::frames_done)
    }

    /// The runner, built (validated, files read, within the memory budget) if there is none.
    fn runner(&mut self, py: Python<'_>) -> PyResult<&mut Runner> {
        if self.runner.is_none() {
            let inner = &mut *self;
            let built = py.detach(move || Runner::with_limits(&inner.scene, &inner.assets, &inner.limits));
            self.runner = Some(built.map_err(|e| build_error(py, &self.scene, e))?);
        }
        match self.runner.as_mut() {
            Some(r) => Ok(r),
            None => unreachable!("built above"),
        }
    }

    /// Simulate up to frame `frames.end`, giving the frames of `frames` to `sink`;
    /// returns each simulated frame's record as JSON. A scene whose frames depend on
    /// earlier renders is rendered every frame, as the command does.
    fn run(
        &mut self,
        py: Python<'_>,
        frames: std::ops::Range<u32>,
        sink: &mut (dyn FrameSink + Send),
        progress: Option<&Py<PyAny>>,
    ) -> PyResult<Vec<String>> {
        let runner = self.runner(py)?;
        let start = runner.frames_done();
        let total = frames.end.saturating_sub(start);
        let mut observer =
            Progress { callback: progress, start, total, error: None, records: Some(Vec::new()) };
        let result = py.detach(|| runner.run(frames, sink, &mut observer));
        if let Some(e) = observer.error {
            return Err(e);
        }
        result.map_err(run_error)?;
        Ok(observer.records.unwrap_or_default())
    }

    /// Make the frames `width` x `height`, keeping the simulation's state (a checkpoint
    /// keeps across sizes) unless its frames depend on earlier renders. Nothing changes
    /// when the new size cannot be built.
    fn resize(&mut self, py: Python<'_>, width: u32, height: u32) -> PyResult<()> {
        let settings = self.scene.settings();
        if (settings.width, settings.height) == (width, height) {
            return Ok(());
        }
        let mut scene = self.scene.clone();
        scene.settings_mut().width = width;
        scene.settings_mut().height = height;
        if let Some(i) = scene.validate().first() {
            return Err(PyValueError::new_err(i.to_string()));
        }
        let state = match &self.runner {
            Some(r) if r.render_memory().is_none() && r.frames_done() > 0 => {
                Some(r.checkpoint().map_err(|e| PyValueError::new_err(e.0))?)
            }
            _ => None,
        };
        let mut resized = Inner { scene, assets: self.assets.clone(), limits: self.limits, runner: None };
        if let Some(bytes) = state {
            let runner = resized.runner(py)?;
            runner.restore(&bytes).map_err(|e| PyValueError::new_err(e.to_string()))?;
        }
        *self = resized;
        Ok(())
    }
}

#[pymethods]
impl NativeScene {
    /// Read a scene file (files it names are read beside it).
    #[staticmethod]
    #[pyo3(signature = (path, max_memory_bytes=None))]
    fn load(py: Python<'_>, path: PathBuf, max_memory_bytes: Option<u64>) -> PyResult<Self> {
        let scene = phenomena_scene::load(&path).map_err(|e| match e {
            phenomena_scene::LoadError::Scene(errors) => located(py, errors),
            other => scene_error(
                py,
                other.to_string(),
                vec![(path.display().to_string(), 0, 0, other.to_string())],
            ),
        })?;
        Ok(Self::new(scene, Assets::beside(&path), max_memory_bytes))
    }

    /// A scene from its text; `name` names it in messages; files it names come from
    /// `files` (name to bytes) or, without them, from the folder `base_dir`.
    #[staticmethod]
    #[pyo3(signature = (text, name="scene.toml", files=None, base_dir=None, max_memory_bytes=None))]
    fn from_toml(
        py: Python<'_>,
        text: &str,
        name: &str,
        files: Option<BTreeMap<String, Vec<u8>>>,
        base_dir: Option<PathBuf>,
        max_memory_bytes: Option<u64>,
    ) -> PyResult<Self> {
        let scene = phenomena_scene::parse(text, name).map_err(|e| located(py, e))?;
        let assets = match (files, base_dir) {
            (Some(files), _) => Assets::Memory(files),
            (None, Some(dir)) => Assets::Folder { dir },
            (None, None) => Assets::beside(Path::new(name)),
        };
        Ok(Self::new(scene, assets, max_memory_bytes))
    }

    /// What the scene is, as JSON: phenomenon, `[scene]`, frame time, view, exports.
    fn info(&self, py: Python<'_>) -> PyResult<String> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        let p = this.scene.phenomenon();
        Ok(serde_json::json!({
            "phenomenon": p.name(),
            "scene": this.scene.settings(),
            "frame_time_s": this.scene.frame_time_s(),
            "view": this.scene.view(),
            "exports": p.exports(),
            "render_memory": this.scene.render_memory(),
        })
        .to_string())
    }

    /// The scene's tables as JSON.
    fn to_json(&self, py: Python<'_>) -> PyResult<String> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        Ok(this.scene.to_json().to_string())
    }

    /// The scene as TOML text.
    fn to_toml(&self, py: Python<'_>) -> PyResult<String> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        this.scene.to_toml().map_err(PyValueError::new_err)
    }

    /// The same scene with `path` (`snow.repose_deg`) set to the JSON `value`, validated.
    fn with_value(&self, py: Python<'_>, path: &str, value: &str) -> PyResult<Self> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        let value: serde_json::Value =
            serde_json::from_str(value).map_err(|e| PyValueError::new_err(format!("{path}: {e}")))?;
        let scene = this.scene.with_value(path, value).map_err(PyValueError::new_err)?;
        if let Some(i) = scene.validate().first() {
            return Err(scene_error(py, i.to_string(), vec![(String::new(), 0, 0, i.to_string())]));
        }
        Ok(Self::holding(Inner { scene, assets: this.assets.clone(), limits: this.limits, runner: None }))
    }

    /// Everything `phenomena validate` checks, without building the simulation: the
    /// files load, the simulation and renderer accept the scene, the memory estimate is
    /// within the budget. Returns the report as JSON (warnings, estimate).
    fn validate(&self, py: Python<'_>) -> PyResult<String> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        let checked = {
            let this = &mut *this;
            py.detach(move || this.scene.check(&this.assets, &this.limits))
        };
        let report = checked.map_err(|e| build_error(py, &this.scene, e))?;
        Ok(serde_json::json!({
            "warnings": report.warnings,
            "memory_bytes": report.estimate.memory_bytes,
            "work": report.estimate.work,
            "unchecked": report.estimate.unchecked,
        })
        .to_string())
    }

    /// Frames simulated so far.
    fn frames_done(&self, py: Python<'_>) -> PyResult<u32> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        Ok(this.frames_done())
    }

    /// Warnings found while building, each a sentence.
    fn warnings(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        Ok(this.runner(py)?.warnings().to_vec())
    }

    /// Simulate `count` frames; returns each frame's record as JSON.
    #[pyo3(signature = (count=1, progress=None))]
    fn step(&self, py: Python<'_>, count: u32, progress: Option<Py<PyAny>>) -> PyResult<Vec<String>> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        let done = this.frames_done();
        let end = done.checked_add(count).filter(|&e| e <= 1_000_000).ok_or_else(|| {
            PyValueError::new_err(format!(
                "{count} more frames after {done} is out of range: at most 1000000 in all"
            ))
        })?;
        this.run(py, done..end, &mut Simulate, progress.as_ref())
    }

    /// Render frame `frame` (the state after `frame + 1` steps; `None`: the current
    /// state, after one step if none was taken), at `width` x `height` if given.
    /// Simulates forward as needed; a frame already passed is simulated again from 0.
    #[pyo3(signature = (frame=None, width=None, height=None, progress=None))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        frame: Option<u32>,
        width: Option<u32>,
        height: Option<u32>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<Rendered<'py>> {
        let mut guard = self.lock(py)?;
        let capture = guard.render(py, frame, width, height, progress)?;
        let layers = capture.layers.iter().map(|(name, p)| (name.clone(), f32_bytes(py, p.data()))).collect();
        let (w, h) = (capture.frame.width(), capture.frame.height());
        Ok((f32_bytes(py, &capture.frame.to_interleaved()), w, h, layers))
    }

    /// Render as [`NativeScene::render`] and write the frame as the `exr` format writes
    /// it (32-bit float linear RGB and, with `layers`, the renderer's layers),
    /// atomically, to `path`.
    #[pyo3(signature = (path, frame=None, width=None, height=None, progress=None, layers=true))]
    #[allow(clippy::too_many_arguments)]
    fn save_exr(
        &self,
        py: Python<'_>,
        path: PathBuf,
        frame: Option<u32>,
        width: Option<u32>,
        height: Option<u32>,
        progress: Option<Py<PyAny>>,
        layers: bool,
    ) -> PyResult<()> {
        let mut guard = self.lock(py)?;
        let capture = guard.render(py, frame, width, height, progress)?;
        let planes = if layers { capture.layers.as_slice() } else { &[] };
        let layers: Vec<Layer<'_>> = planes.iter().map(|(name, plane)| Layer { name, plane }).collect();
        let image = &capture.frame;
        py.detach(move || phenomena_scene::write_exr(&path, image, &layers))
            .map_err(|e| PyValueError::new_err(e.0))
    }

    /// The whole simulation state as a checkpoint file's bytes.
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        let bytes = this.runner(py)?.checkpoint().map_err(|e| PyValueError::new_err(e.0))?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// Continue from checkpoint `bytes` of this scene; returns the frames simulated.
    fn restore(&self, py: Python<'_>, bytes: &[u8]) -> PyResult<u32> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        this.runner(py)?.restore(bytes).map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// The particles as the `ply` format's point cache bytes.
    fn points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        let bytes = this.runner(py)?.state().points().map_err(|e| PyValueError::new_err(e.0))?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// Export `name` of the current state in `format`: `(bytes, summary)`.
    fn export<'py>(
        &self,
        py: Python<'py>,
        name: &str,
        format: &str,
    ) -> PyResult<(Bound<'py, PyBytes>, String)> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        let runner = this.runner(py)?;
        let exported = py.detach(move || runner.export(name, format)).map_err(PyValueError::new_err)?;
        Ok((PyBytes::new(py, &exported.bytes), exported.summary))
    }

    /// The volume of the current state (the `vdb` format's grids): `(manifest JSON,
    /// [leaves])`; `as_vdb` gives the `.vdb` file's bytes instead of the leaves.
    #[pyo3(signature = (voxel_m=None, as_vdb=false))]
    fn volume<'py>(
        &self,
        py: Python<'py>,
        voxel_m: Option<f64>,
        as_vdb: bool,
    ) -> PyResult<(String, Vec<Leaves<'py>>, Option<Bound<'py, PyBytes>>)> {
        let mut guard = self.lock(py)?;
        let this = &mut *guard;
        let max_bytes = (this.limits.memory_bytes != u64::MAX).then_some(this.limits.memory_bytes);
        let options = VolumeOptions { voxel_m, max_bytes };
        let runner = this.runner(py)?;
        let mut scratch = phenomena_scene::Scratch::default();
        let (manifest, grids, bytes) = py
            .detach(move || {
                let (mut grids, mut bytes) = (Vec::<LeafGrid>::new(), Vec::new());
                let mut out = if as_vdb { VolumeOut::Vdb(&mut bytes) } else { VolumeOut::Leaves(&mut grids) };
                let manifest = runner.state().volume(&options, &mut scratch, &mut out)?;
                Ok::<_, SinkError>((manifest, grids, bytes))
            })
            .map_err(|e| PyValueError::new_err(e.0))?;
        let leaves = grids
            .iter()
            .map(|g| {
                let origins: Vec<u8> = g.origins.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
                (
                    g.name.clone(),
                    g.class,
                    g.components,
                    g.voxel_size_m,
                    g.translation_m,
                    PyBytes::new(py, &origins),
                    f32_bytes(py, &g.values),
                )
            })
            .collect();
        Ok((manifest.to_string(), leaves, as_vdb.then(|| PyBytes::new(py, &bytes))))
    }
}

/// Problems located in scene text, as `SceneError`.
fn located(py: Python<'_>, errors: phenomena_scene::SceneErrors) -> PyErr {
    let problems: Vec<Problem> = errors
        .0
        .iter()
        .map(|l| (l.file.display().to_string(), l.line, l.column, l.message.clone()))
        .collect();
    scene_error(py, errors.to_string(), problems)
}

/// The phenomena a scene can hold, with their exports, as JSON.
#[pyfunction]
fn phenomena() -> String {
    let list: Vec<serde_json::Value> = phenomena_scene::registry::PHENOMENA
        .iter()
        .map(|p| serde_json::json!({ "name": p.name(), "about": p.about(), "exports": p.exports() }))
        .collect();
    serde_json::Value::Array(list).to_string()
}

/// A phenomenon's starter scene text (every default, commented), as `phenomena new` writes.
#[pyfunction]
fn starter(name: &str) -> PyResult<&'static str> {
    phenomena_scene::registry::phenomenon(name)
        .map(|p| p.starter())
        .ok_or_else(|| PyValueError::new_err(format!("no phenomenon `{name}`")))
}

/// The module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<NativeScene>()?;
    m.add_function(wrap_pyfunction!(phenomena, m)?)?;
    m.add_function(wrap_pyfunction!(starter, m)?)?;
    Ok(())
}
