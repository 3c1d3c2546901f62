//! Shots: several phenomena in one frame, on one clock, through one camera.
//!
//! A scene file holding two or more phenomenon tables (`[flame]`, `[aurora]`, `[snow]`
//! with its `[geometry]`, `[sparkle]`) is a shot. Each phenomenon keeps its own tables;
//! what they share is the shot's: `[scene]`, `[render.camera]` (metres), `[render.sun]`
//! (towards the sun or the moon: the snow's light and the glints' light) and
//! `aurora_site_km` in `[render]`. Each phenomenon's `[render]` settings move under
//! `[render.<name>]` (`[render.flame]`, ...), without a camera or a sun of their own.
//!
//! **One world.** Metres, +y up, +z north, +x east (the aurora's and the glints'
//! convention for directions). The flame, the snow's geometry and
//! the diamond dust are placed in it by their own tables. The aurora lives in kilometres
//! over the point on the ground below its plane's centre; the shot's origin is at
//! `aurora_site_km` = [east, north] from that point (default 150 km south), so the
//! aurora's camera is the shot's camera with its position divided by 1000 and moved
//! there. At 100 km and more the aurora is beyond everything else in the shot.
//!
//! **One clock.** Every frame steps each simulation once. The flame and the dust move in
//! seconds and must agree (`sparkle.fps` = 1 / `flame.frame_time_s`, checked); the snow
//! steps its snowfall once a frame and the aurora its own time step.
//!
//! **Composition**, far to near ([`Pass`]), per pixel:
//! 1. the sky: the aurora's light (and its stars and far ground) at infinity;
//! 2. opaque surfaces: the snow scene drawn over the sky, lit also by the flame (a
//!    point light of the flame's radiant intensity, no shadows); its depth map hides
//!    what is behind a surface from everything drawn later;
//! 3. glints farther than the flame (the flame's particles' mean depth), each drawn only
//!    where no surface is nearer;
//! 4. the flame: its light is added (a flame absorbs little: what is behind it is seen
//!    through it) and its heat shimmer refracts everything composed so far; a splat
//!    behind a surface is hidden;
//! 5. glints nearer than the flame, added unrefracted.
//!
//! Emissive media add; surfaces replace. The EXR keeps each phenomenon's light as it
//! reaches the camera in its own layer (`aurora.R`, `snow.R` with `snow.A` coverage,
//! `flame.R`, `sparkle.R`, ...) beside the beauty, so a compositor can regrade each.
//! `vdb` frames hold the nearest volume phenomenon's grids (the flame's); each
//! phenomenon's exports are taken from its part.

use std::any::Any;
use std::sync::{Mutex, MutexGuard, PoisonError};

use glam::Vec3;
use phenomena_core::camera::{Camera, Projection};
use phenomena_core::clock::SharedClock;
use phenomena_core::image::Frame;
use phenomena_core::phenomenon::{Layer, Renderer, Simulation};
use phenomena_core::validate::{Issue, Issues};
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::assets::Assets;
use crate::aurora::AuroraScene;
use crate::budget::Estimate;
use crate::error::BuildError;
use crate::flame::FlameScene;
use crate::phenomenon::{
    Built, Capability, ExportKind, Exported, PASSES, Pass, Phenomenon, Scratch, Stage, View, VolumeOptions,
    VolumeOut,
};
use crate::settings::SceneSettings;
use crate::snow::{SnowGeometry, SnowScene};
use crate::sparkle::SparkleScene;

/// Where the sun (or the moon) is: azimuth 0 is −z (south), 90° is +x (east);
/// elevation above the horizon.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sun {
    /// Azimuth, degrees.
    pub azimuth_deg: f32,
    /// Elevation, degrees.
    pub elevation_deg: f32,
}

impl Default for Sun {
    fn default() -> Self {
        Self { azimuth_deg: 200.0, elevation_deg: 12.0 }
    }
}

impl Sun {
    /// Unit direction towards it (the sparkle's convention for a sun).
    pub fn direction(&self) -> Vec3 {
        match self.light().at(0.0) {
            phenomena_sparkle::LightAt::Direction(d) => d,
            phenomena_sparkle::LightAt::Position(p) => p.normalize_or_zero(),
        }
    }

    fn light(&self) -> phenomena_sparkle::Light {
        phenomena_sparkle::Light::Sun {
            azimuth_deg: self.azimuth_deg,
            elevation_deg: self.elevation_deg,
            azimuth_rate_deg_per_s: 0.0,
            elevation_rate_deg_per_s: 0.0,
        }
    }
}

/// A shot's `[render]`: what its phenomena share, and each one's own render settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShotRender {
    /// The one camera, metres.
    pub camera: Camera,
    /// The sun or moon lighting the snow and the glints.
    pub sun: Sun,
    /// The shot's origin from the ground point below the aurora plane's centre, km
    /// (east, north).
    pub aurora_site_km: [f32; 2],
    /// `[render.flame]`: the flame's render settings, without a camera.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flame: Option<phenomena_flame::RenderSettings>,
    /// `[render.aurora]`: the aurora's, without a camera (the sky view).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub aurora: Option<phenomena_aurora::RenderSettings>,
    /// `[render.snow]`: the snow's, without a camera or sun.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub snow: Option<phenomena_snow::SnowRenderSettings>,
    /// `[render.sparkle]`: the glints', without a background.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sparkle: Option<phenomena_sparkle::RenderSettings>,
}

impl Default for ShotRender {
    fn default() -> Self {
        Self {
            camera: Camera {
                position: Vec3::new(0.0, 1.6, -8.0),
                look_at: Vec3::new(0.0, 3.0, 4.0),
                up: Vec3::Y,
                projection: Projection::Perspective { fov_y_deg: 60.0 },
            },
            sun: Sun::default(),
            aurora_site_km: [0.0, -150.0],
            flame: None,
            aurora: None,
            snow: None,
            sparkle: None,
        }
    }
}

/// A scene file of several phenomena (see the module's documentation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShotScene {
    /// `[scene]`.
    #[serde(default)]
    pub scene: SceneSettings,
    /// `[render]`.
    #[serde(default)]
    pub render: ShotRender,
    /// `[flame]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flame: Option<phenomena_flame::FlameConfig>,
    /// `[aurora]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aurora: Option<phenomena_aurora::AuroraConfig>,
    /// `[geometry]`: the snow's scene (with `[snow]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geometry: Option<SnowGeometry>,
    /// `[snow]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub snow: Option<phenomena_snow::SnowConfig>,
    /// `[sparkle]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sparkle: Option<phenomena_sparkle::SparkleConfig>,
}

impl Default for ShotScene {
    /// Every phenomenon at its defaults, through the shot's default camera.
    fn default() -> Self {
        Self {
            scene: SceneSettings::default(),
            render: ShotRender::default(),
            flame: Some(Default::default()),
            aurora: Some(Default::default()),
            geometry: None,
            snow: Some(Default::default()),
            // On the flame's clock (1/60 s a frame).
            sparkle: Some(phenomena_sparkle::SparkleConfig { fps: 60.0, ..Default::default() }),
        }
    }
}

/// Every phenomenon's exports: a shot exports each from its part.
const EXPORTS: [ExportKind; export_count()] = all_exports();

/// The phenomena a shot can hold, with their exports.
const PART_EXPORTS: [&[ExportKind]; 4] =
    [FlameScene::EXPORTS, AuroraScene::EXPORTS, SnowScene::EXPORTS, SparkleScene::EXPORTS];

const fn export_count() -> usize {
    let (mut n, mut i) = (0, 0);
    while i < PART_EXPORTS.len() {
        n += PART_EXPORTS[i].len();
        i += 1;
    }
    n
}

const fn all_exports() -> [ExportKind; export_count()] {
    let mut out = [ExportKind { name: "", about: "", formats: &[] }; export_count()];
    let (mut n, mut i) = (0, 0);
    while i < PART_EXPORTS.len() {
        let mut j = 0;
        while j < PART_EXPORTS[i].len() {
            out[n] = PART_EXPORTS[i][j];
            n += 1;
            j += 1;
        }
        i += 1;
    }
    out
}

/// Why a shot without a flame or an aurora writes no volumes.
const NO_VOLUME: &str = "this shot holds no phenomenon with volumes (a [flame] or an [aurora])";

/// The tables a shot's phenomena may hold, for messages.
const TABLES: &str = "[flame], [aurora], [snow], [sparkle]";

impl ShotScene {
    /// The aurora's camera: the shot's, in km, at the aurora site.
    fn aurora_camera(&self) -> Camera {
        let c = &self.render.camera;
        let [east, north] = self.render.aurora_site_km;
        let site = Vec3::new(east, 0.0, north);
        let position = site + c.position / 1000.0;
        let projection = match c.projection {
            Projection::Orthographic { height_m } => Projection::Orthographic { height_m: height_m / 1000.0 },
            p => p,
        };
        Camera { position, look_at: position + (c.look_at - c.position), up: c.up, projection }
    }

    /// The flame as a scene of its own, seen through the shot's camera.
    pub fn flame_part(&self) -> Option<FlameScene> {
        let flame = self.flame.clone()?;
        let mut render = self.render.flame.clone().unwrap_or_default();
        render.camera = self.render.camera;
        Some(FlameScene { scene: self.scene.clone(), flame, render })
    }

    /// The aurora as a scene of its own: its sky view through the shot's camera.
    pub fn aurora_part(&self) -> Option<AuroraScene> {
        let aurora = self.aurora.clone()?;
        let mut render = self.render.aurora.clone().unwrap_or_default();
        render.view = phenomena_aurora::AuroraView::Sky;
        render.sky.camera = phenomena_aurora::SkyCamera::Custom { camera: self.aurora_camera() };
        Some(AuroraScene { scene: self.scene.clone(), aurora, render })
    }

    /// The snow as a scene of its own, through the shot's camera and under its sun.
    pub fn snow_part(&self) -> Option<SnowScene> {
        let snow = self.snow.clone()?;
        let mut render = self.render.snow.clone().unwrap_or_default();
        render.camera = Some(self.render.camera);
        render.sun_direction = self.render.sun.direction();
        Some(SnowScene {
            scene: self.scene.clone(),
            geometry: self.geometry.clone().unwrap_or_default(),
            snow,
            render,
        })
    }

    /// The glints as a scene of their own: the shot's camera and sun.
    pub fn sparkle_part(&self) -> Option<SparkleScene> {
        let mut sparkle = self.sparkle?;
        sparkle.camera = self.render.camera;
        sparkle.light = self.render.sun.light();
        Some(SparkleScene {
            scene: self.scene.clone(),
            sparkle,
            render: self.render.sparkle.clone().unwrap_or_default(),
        })
    }

    /// Every phenomenon present, far to near.
    fn parts(&self) -> Vec<Box<dyn PartFile>> {
        let mut parts: Vec<Box<dyn PartFile>> = Vec::new();
        if let Some(p) = self.aurora_part() {
            parts.push(Box::new(p));
        }
        if let Some(p) = self.snow_part() {
            parts.push(Box::new(p));
        }
        if let Some(p) = self.sparkle_part() {
            parts.push(Box::new(p));
        }
        if let Some(p) = self.flame_part() {
            parts.push(Box::new(p));
        }
        parts
    }

    /// What the shot's phenomena take from it and must not set themselves.
    fn shared_settings_unset(&self, i: &mut Issues) {
        let one = |i: &mut Issues, field: &str, what: &str| {
            i.push(field, "(set)", format!("nothing: a shot's phenomena share its {what}; remove this"));
        };
        if let Some(r) = &self.render.flame
            && r.camera != phenomena_flame::RenderSettings::default().camera
        {
            one(i, "render.flame.camera", "camera, [render.camera]");
        }
        if let Some(r) = &self.render.aurora
            && r.sky.camera != phenomena_aurora::SkySettings::default().camera
        {
            one(i, "render.aurora.sky.camera", "camera, [render.camera]");
        }
        if let Some(r) = &self.render.snow {
            if r.camera.is_some() {
                one(i, "render.snow.camera", "camera, [render.camera]");
            }
            if r.sun_direction != phenomena_snow::SnowRenderSettings::default().sun_direction {
                one(i, "render.snow.sun_direction", "sun, [render.sun]");
            }
        }
        if let Some(s) = &self.sparkle {
            let d = phenomena_sparkle::SparkleConfig::default();
            if s.camera != d.camera {
                one(i, "sparkle.camera", "camera, [render.camera]");
            }
            if s.light != d.light {
                one(i, "sparkle.light", "sun, [render.sun]");
            }
        }
    }

    /// The shot's own problems: enough phenomena, render tables with their phenomenon,
    /// views a shot can compose, one clock.
    fn validate_shot(&self, i: &mut Issues) {
        let present =
            [self.flame.is_some(), self.aurora.is_some(), self.snow.is_some(), self.sparkle.is_some()];
        if present.iter().filter(|p| **p).count() < 2 {
            i.push("scene", "one phenomenon", format!("a shot of two or more of {TABLES}"));
        }
        for (set, has, table, field) in [
            (self.render.flame.is_some(), self.flame.is_some(), "flame", "render.flame"),
            (self.render.aurora.is_some(), self.aurora.is_some(), "aurora", "render.aurora"),
            (self.render.snow.is_some(), self.snow.is_some(), "snow", "render.snow"),
            (self.render.sparkle.is_some(), self.sparkle.is_some(), "sparkle", "render.sparkle"),
            (self.geometry.is_some(), self.snow.is_some(), "snow", "geometry"),
        ] {
            if set && !has {
                i.push(field, "(set)", format!("no [{field}] table in a shot without a [{table}] table"));
            }
        }
        if let Some(r) = &self.render.flame
            && r.view != phenomena_flame::View::Flame
        {
            i.push("render.flame.view", format!("{:?}", r.view).to_lowercase(), "\"flame\" in a shot");
        }
        if let Some(r) = &self.render.aurora
            && r.view != phenomena_aurora::AuroraView::Sky
        {
            i.push("render.aurora.view", "\"plane\"", "\"sky\" in a shot");
        }
        if let Some(r) = &self.render.snow
            && r.view != phenomena_snow::SnowView::Scene
        {
            i.push("render.snow.view", "\"probability\"", "\"scene\" in a shot");
        }
        if let (Some(f), Some(s)) = (&self.flame, &self.sparkle) {
            let (flame_s, dust_s) = (f64::from(f.frame_time_s), f64::from(s.dt_s()));
            // One clock: the two step times equal to f32 precision.
            if (flame_s - dust_s).abs() > 1e-6 * flame_s {
                i.push(
                    "sparkle.fps",
                    format!("{}", s.fps),
                    format!("{} (1 / flame.frame_time_s): a shot runs on one clock", 1.0 / flame_s),
                );
            }
        }
        self.render.camera.validate_planar(i, "render.camera");
        i.range("render.sun.azimuth_deg", self.render.sun.azimuth_deg, -360.0..=360.0);
        i.range("render.sun.elevation_deg", self.render.sun.elevation_deg, -90.0..=90.0);
        i.vector("render.aurora_site_km", &self.render.aurora_site_km, 1e4);
    }
}

/// A part's problem at its path in the shot's file: its `render.*` under
/// `render.<name>.*`; `scene.*` is the shot's own, checked once.
fn in_shot(name: &str, mut issue: Issue) -> Option<Issue> {
    // What the shot gives every part is checked once, at its own place.
    const SHARED: [&str; 6] = [
        "scene",
        "render.camera",
        "render.sky.camera",
        "render.sun_direction",
        "sparkle.camera",
        "sparkle.light",
    ];
    if SHARED.iter().any(|s| issue.field == *s || issue.field.starts_with(&format!("{s}."))) {
        return None;
    }
    if let Some(rest) = issue.field.strip_prefix("render.") {
        issue.field = format!("render.{name}.{rest}");
    } else if issue.field == "render" {
        issue.field = format!("render.{name}");
    }
    Some(issue)
}

impl Phenomenon for ShotScene {
    const NAME: &'static str = "shot";
    const ABOUT: &'static str = "several phenomena in one frame: one camera, one clock, composed by depth (aurora, snow, glints, flame)";
    const VIEWS: &'static [View] =
        &[View { name: "shot", about: "every phenomenon through the one camera, composed far to near" }];
    const STARTER: &'static str = include_str!("../starters/shot.toml");
    const COMPOSITE: bool = true;
    const CAN: &'static [Capability] = &[Capability::Volume];
    const EXPORTS: &'static [ExportKind] = &EXPORTS;
    type Sim = ShotSim;
    type Renderer = ShotRenderer;
    type Loaded = Vec<Box<dyn Any + Send>>;

    fn settings(&self) -> &SceneSettings {
        &self.scene
    }

    fn settings_mut(&mut self) -> &mut SceneSettings {
        &mut self.scene
    }

    fn validate(&self, i: &mut Issues) {
        self.validate_shot(i);
        self.shared_settings_unset(i);
        for part in self.parts() {
            let mut own = Issues::default();
            part.validate(&mut own);
            if let Err(issues) = own.into_result() {
                for issue in issues.into_iter().filter_map(|e| in_shot(part.name(), e)) {
                    i.push(issue.field, issue.value, issue.expected);
                }
            }
        }
    }

    fn view(&self) -> &'static str {
        "shot"
    }

    fn set_view(&mut self, _view: &str) {}

    fn load(&self, assets: &Assets) -> Result<Self::Loaded, BuildError> {
        self.parts().iter().map(|p| p.load(assets)).collect()
    }

    fn check(&self, loaded: &Self::Loaded) -> Result<Vec<String>, BuildError> {
        let mut warnings = Vec::new();
        for (part, files) in self.parts().iter().zip(loaded) {
            let found = part.check(&**files).map_err(|e| part_error(part.name(), e))?;
            warnings.extend(found.into_iter().map(|w| format!("{}: {w}", part.name())));
        }
        Ok(warnings)
    }

    /// Every phenomenon's estimate, and the shot's own images (the composed frame, the
    /// surfaces' depth and each phenomenon's layer).
    fn estimate(&self, loaded: &Self::Loaded) -> Estimate {
        let parts = self.parts();
        let (w, h) = (u64::from(self.scene.width), u64::from(self.scene.height));
        let mut work = Vec::new();
        let mut total = Estimate::of(String::new(), Vec::new());
        for (part, files) in parts.iter().zip(loaded) {
            let e = part.estimate(&**files);
            work.push(format!("{}: {}", part.name(), e.work));
            for (what, bytes) in e.parts {
                total = total.with(format!("{}: {what}", part.name()), bytes);
            }
            total.unchecked.extend(e.unchecked.into_iter().map(|u| format!("{}: {u}", part.name())));
        }
        let images = w * h * (12 + 4 + 16 * parts.len() as u64);
        total = total.with("the composed frame, depth and layers", images);
        total.work = work.join("; ");
        total
    }

    fn build(&self, loaded: Self::Loaded) -> Result<Built<Self>, BuildError> {
        let (w, h) = self.scene.size();
        let mut parts = Vec::new();
        let mut warnings = Vec::new();
        for (file, files) in self.parts().iter().zip(loaded) {
            let part = file.build(files).map_err(|e| part_error(file.name(), e))?;
            warnings.extend(part.warnings().iter().map(|m| format!("{}: {m}", file.name())));
            parts.push(Mutex::new(part));
        }
        let renderer = ShotRenderer {
            stage: Stage::new(w, h),
            names: Vec::new(),
            clock: SharedClock::default(),
            render_ms: Vec::new(),
        };
        Ok(Built { sim: ShotSim { parts, clock: SharedClock::default() }, renderer, warnings })
    }

    /// `vdb`: the volumes of the nearest phenomenon that has them (the flame, in the
    /// shot's metres; else the aurora, in its own frame).
    fn volume(
        built: &Built<Self>,
        options: &VolumeOptions,
        scratch: &mut Scratch,
        out: &mut VolumeOut<'_>,
    ) -> Result<Value, String> {
        match built.sim.parts.iter().rev().map(open).find(|p| p.can(Capability::Volume)) {
            Some(part) => part.volume(options, scratch, out),
            None => Err(NO_VOLUME.to_string()),
        }
    }

    fn volume_bytes(built: &Built<Self>, options: &VolumeOptions) -> Result<u64, String> {
        match built.sim.parts.iter().rev().map(open).find(|p| p.can(Capability::Volume)) {
            Some(part) => part.volume_bytes(options),
            None => Err(NO_VOLUME.to_string()),
        }
    }

    /// Every phenomenon's simulation and renderer on `clock`, and the shot's timing of
    /// each one's step and composition (without a clock, as for any phenomenon, every
    /// time reads 0: each part's `step_ms` and `render_ms` are there, at 0).
    fn set_clock(built: &mut Built<Self>, clock: &SharedClock) {
        for part in &mut built.sim.parts {
            part.get_mut().unwrap_or_else(PoisonError::into_inner).set_clock(clock);
        }
        built.sim.clock = clock.clone();
        built.renderer.clock = clock.clone();
    }

    /// Each phenomenon's time in the last render (all its passes), ms, with its own
    /// breakdown if it has one: `{"aurora": {"render_ms": …, "emit_ms": …}, …}`.
    fn render_detail(built: &Built<Self>) -> Option<Value> {
        let mut detail = serde_json::Map::new();
        for (part, &(name, ms)) in built.sim.parts.iter().zip(&built.renderer.render_ms) {
            let mut entry = serde_json::Map::new();
            entry.insert("render_ms".into(), ms.into());
            if let Some(Value::Object(own)) = open(part).render_detail() {
                entry.extend(own);
            }
            detail.insert(name.into(), Value::Object(entry));
        }
        Some(Value::Object(detail))
    }

    /// Each phenomenon's own preview (the aurora's thinned particles in the studio).
    fn before_render(built: &mut Built<Self>, preview: Option<u32>) {
        for part in &mut built.sim.parts {
            part.get_mut().unwrap_or_else(PoisonError::into_inner).before_render(preview);
        }
    }

    /// Each phenomenon's exports, from its part of the shot.
    fn export(built: &Built<Self>, name: &str, format: &str) -> Result<Exported, String> {
        built
            .sim
            .parts
            .iter()
            .find_map(|p| open(p).export(name, format))
            .unwrap_or_else(|| Err(format!("this shot holds no phenomenon that exports `{name}`")))
    }

    fn files_identity(loaded: &Self::Loaded) -> Option<u64> {
        // Only the snow's mesh is a file its simulation is built from.
        loaded
            .iter()
            .find_map(|l| l.downcast_ref::<crate::snow::SnowFiles>())
            .and_then(SnowScene::files_identity)
    }

    /// The phenomena's tables and what the shot gives them (the camera: the glints
    /// seen depend on it; the sun).
    fn simulation_tables(&self) -> Value {
        let mut json = crate::checkpoint::simulation_tables(self);
        if let Value::Object(map) = &mut json {
            map.insert("camera".into(), serde_json::to_value(self.render.camera).unwrap_or(Value::Null));
            map.insert("sun".into(), serde_json::to_value(self.render.sun).unwrap_or(Value::Null));
        }
        json
    }

    /// The flame's frame time, else the dust's, the aurora's or the snow's.
    fn frame_time_s(&self) -> f64 {
        self.parts().iter().rev().map(|p| p.frame_time_s()).next().unwrap_or(1.0 / 30.0)
    }

    fn render_memory(&self) -> Option<&'static str> {
        self.parts().iter().find_map(|p| p.render_memory())
    }
}

/// A part's build error in the shot's terms (its render settings under `render.<name>`).
fn part_error(name: &str, e: BuildError) -> BuildError {
    match e {
        BuildError::Invalid(issues) => {
            BuildError::Invalid(issues.into_iter().filter_map(|i| in_shot(name, i)).collect())
        }
        other => other,
    }
}

/// A phenomenon's scene file as a part of a shot, without its type.
trait PartFile {
    fn name(&self) -> &'static str;
    fn validate(&self, i: &mut Issues);
    fn load(&self, assets: &Assets) -> Result<Box<dyn Any + Send>, BuildError>;
    fn check(&self, loaded: &dyn Any) -> Result<Vec<String>, BuildError>;
    fn estimate(&self, loaded: &dyn Any) -> Estimate;
    fn build(&self, loaded: Box<dyn Any + Send>) -> Result<Box<dyn Part>, BuildError>;
    fn frame_time_s(&self) -> f64;
    fn render_memory(&self) -> Option<&'static str>;
}

/// `P`'s files, from the box its [`PartFile::load`] made.
fn files<P: Phenomenon>(loaded: &dyn Any) -> &P::Loaded {
    match loaded.downcast_ref::<P::Loaded>() {
        Some(l) => l,
        None => unreachable!("a shot's parts are loaded and built in the same order"),
    }
}

impl<P: Phenomenon> PartFile for P {
    fn name(&self) -> &'static str {
        P::NAME
    }

    fn validate(&self, i: &mut Issues) {
        Phenomenon::validate(self, i)
    }

    fn load(&self, assets: &Assets) -> Result<Box<dyn Any + Send>, BuildError> {
        Ok(Box::new(Phenomenon::load(self, assets)?))
    }

    fn check(&self, loaded: &dyn Any) -> Result<Vec<String>, BuildError> {
        Phenomenon::check(self, files::<P>(loaded))
    }

    fn estimate(&self, loaded: &dyn Any) -> Estimate {
        Phenomenon::estimate(self, files::<P>(loaded))
    }

    fn build(&self, loaded: Box<dyn Any + Send>) -> Result<Box<dyn Part>, BuildError> {
        let Ok(loaded) = loaded.downcast::<P::Loaded>() else {
            unreachable!("a shot's parts are loaded and built in the same order")
        };
        Ok(Box::new(Phenomenon::build(self, *loaded)?))
    }

    fn frame_time_s(&self) -> f64 {
        Phenomenon::frame_time_s(self)
    }

    fn render_memory(&self) -> Option<&'static str> {
        Phenomenon::render_memory(self)
    }
}

/// A built phenomenon of a shot (its simulation and renderer) without its type.
trait Part: Send {
    fn name(&self) -> &'static str;
    fn warnings(&self) -> &[String];
    fn step(&mut self) -> Result<Value, String>;
    fn frames_done(&self) -> u64;
    fn state(&self) -> Result<Vec<u8>, String>;
    fn restore(&mut self, bytes: &[u8]) -> Result<(), String>;
    fn compose(&mut self, pass: Pass, stage: &mut Stage);
    fn before_render(&mut self, preview: Option<u32>);
    fn set_clock(&mut self, clock: &SharedClock);
    fn render_detail(&self) -> Option<Value>;
    fn can(&self, what: Capability) -> bool;
    fn volume(
        &self,
        options: &VolumeOptions,
        scratch: &mut Scratch,
        out: &mut VolumeOut<'_>,
    ) -> Result<Value, String>;
    fn volume_bytes(&self, options: &VolumeOptions) -> Result<u64, String>;
    fn export(&self, name: &str, format: &str) -> Option<Result<Exported, String>>;
}

impl<P: Phenomenon> Part for Built<P> {
    fn name(&self) -> &'static str {
        P::NAME
    }

    fn warnings(&self) -> &[String] {
        &self.warnings
    }

    fn step(&mut self) -> Result<Value, String> {
        let stats = self.sim.step().map_err(|e| e.to_string())?;
        serde_json::to_value(stats).map_err(|e| e.to_string())
    }

    fn frames_done(&self) -> u64 {
        self.sim.frames_done()
    }

    fn state(&self) -> Result<Vec<u8>, String> {
        postcard::to_stdvec(&self.sim.state()).map_err(|e| e.to_string())
    }

    fn restore(&mut self, bytes: &[u8]) -> Result<(), String> {
        let state: <P::Sim as Simulation>::State = postcard::from_bytes(bytes).map_err(|e| e.to_string())?;
        self.sim.restore(state).map_err(|e| e.to_string())
    }

    fn compose(&mut self, pass: Pass, stage: &mut Stage) {
        P::compose(&self.sim, &mut self.renderer, pass, stage);
        if pass == Pass::Front {
            // The phenomenon's own layers (the aurora's lines), after its light.
            for layer in self.renderer.layers() {
                stage.extra.push((layer.name.to_string(), layer.plane.clone()));
            }
        }
    }

    fn before_render(&mut self, preview: Option<u32>) {
        P::before_render(self, preview)
    }

    fn set_clock(&mut self, clock: &SharedClock) {
        P::set_clock(self, clock)
    }

    fn render_detail(&self) -> Option<Value> {
        P::render_detail(self)
    }

    fn can(&self, what: Capability) -> bool {
        P::CAN.contains(&what)
    }

    fn volume(
        &self,
        options: &VolumeOptions,
        scratch: &mut Scratch,
        out: &mut VolumeOut<'_>,
    ) -> Result<Value, String> {
        P::volume(self, options, scratch, out)
    }

    fn volume_bytes(&self, options: &VolumeOptions) -> Result<u64, String> {
        P::volume_bytes(self, options)
    }

    fn export(&self, name: &str, format: &str) -> Option<Result<Exported, String>> {
        P::EXPORTS.iter().any(|e| e.name == name).then(|| P::export(self, name, format))
    }
}

/// Why a shot's step or checkpoint failed: which phenomenon, and why.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ShotError(String);

/// Every phenomenon of a shot, stepped together, far to near. Each keeps its
/// simulation beside its renderer (behind a lock only so that the shot's renderer can
/// draw them from a shared reference; nothing else holds it).
pub struct ShotSim {
    parts: Vec<Mutex<Box<dyn Part>>>,
    /// Times each part's step (`step_ms` in its stats).
    clock: SharedClock,
}

/// The part, whatever a panic elsewhere did to its lock (the shot's work is on one
/// thread at a time).
fn open(part: &Mutex<Box<dyn Part>>) -> MutexGuard<'_, Box<dyn Part>> {
    part.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Simulation for ShotSim {
    type StepStats = Value;
    type Error = ShotError;
    /// Each phenomenon's state, encoded, far to near.
    type State = Vec<Vec<u8>>;

    fn step(&mut self) -> Result<Value, ShotError> {
        let mut stats = serde_json::Map::new();
        for part in &mut self.parts {
            let part = part.get_mut().unwrap_or_else(PoisonError::into_inner);
            let t = self.clock.stopwatch();
            let mut s = part.step().map_err(|e| ShotError(format!("{}: {e}", part.name())))?;
            if let Value::Object(map) = &mut s {
                map.insert("step_ms".into(), t.ms().into());
            }
            stats.insert(part.name().to_string(), s);
        }
        Ok(Value::Object(stats))
    }

    fn frames_done(&self) -> u64 {
        self.parts.first().map_or(0, |p| open(p).frames_done())
    }

    fn state(&self) -> Vec<Vec<u8>> {
        // A state that cannot be encoded is left empty and refused when restored.
        self.parts.iter().map(|p| open(p).state().unwrap_or_default()).collect()
    }

    /// A part that refuses its state (which the checkpoint's identity makes unlikely)
    /// leaves the parts before it restored, and the run stops.
    fn restore(&mut self, state: Vec<Vec<u8>>) -> Result<(), ShotError> {
        if state.len() != self.parts.len() {
            return Err(ShotError(format!(
                "the checkpoint holds {} phenomena, the shot {}",
                state.len(),
                self.parts.len()
            )));
        }
        for (part, bytes) in self.parts.iter_mut().zip(&state) {
            let part = part.get_mut().unwrap_or_else(PoisonError::into_inner);
            part.restore(bytes).map_err(|e| ShotError(format!("{}: {e}", part.name())))?;
        }
        Ok(())
    }
}

/// Composes a shot's frames ([`Pass`] by pass).
pub struct ShotRenderer {
    stage: Stage,
    /// The layers' channel names, made at each render.
    names: Vec<String>,
    clock: SharedClock,
    /// Each part's time in the last render, all passes, ms, in the parts' order.
    render_ms: Vec<(&'static str, f64)>,
}

impl Renderer<ShotSim> for ShotRenderer {
    fn render(&mut self, sim: &ShotSim) -> &Frame {
        let (w, h) = (self.stage.image.width(), self.stage.image.height());
        self.stage = Stage::new(w, h);
        self.render_ms = sim.parts.iter().map(|p| (open(p).name(), 0.0)).collect();
        for pass in PASSES {
            for (part, (_, ms)) in sim.parts.iter().zip(&mut self.render_ms) {
                let t = self.clock.stopwatch();
                open(part).compose(pass, &mut self.stage);
                *ms += t.ms();
            }
        }
        self.names.clear();
        for (name, _, alpha) in &self.stage.layers {
            for c in ["R", "G", "B"] {
                self.names.push(format!("{name}.{c}"));
            }
            if alpha.is_some() {
                self.names.push(format!("{name}.A"));
            }
        }
        &self.stage.image
    }

    fn frame(&self) -> &Frame {
        &self.stage.image
    }

    /// Each phenomenon's light (`aurora.R`, ..., `snow.A`), then each one's own layers.
    fn layers(&self) -> Vec<Layer<'_>> {
        let mut out = Vec::new();
        let mut names = self.names.iter();
        for (_, frame, alpha) in &self.stage.layers {
            for plane in [&frame.c0, &frame.c1, &frame.c2].into_iter().chain(alpha) {
                if let Some(name) = names.next() {
                    out.push(Layer { name, plane });
                }
            }
        }
        out.extend(self.stage.extra.iter().map(|(name, plane)| Layer { name, plane }));
        out
    }
}
