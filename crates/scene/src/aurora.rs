//! Aurora scenes: `[aurora]` (artist shapes, field and particle motion of Sekiguchi
//! 2018, §2.1-2.3) and its `[render]` (the sky view of §2.4 or the plane view).

use std::fmt::Write as _;

use phenomena_aurora::{
    AuroraConfig, AuroraError, AuroraRenderer, AuroraSim, AuroraView, ColourMode, RenderSettings,
    SkyBackground,
};
use phenomena_core::clock::SharedClock;
use phenomena_core::image::Frame;
use phenomena_core::validate::{Issue, Issues};
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::assets::Assets;
use crate::budget::Estimate;
use crate::cache::PointCache;
use crate::error::BuildError;
use crate::phenomenon::{
    Built, Capability, ExportKind, Exported, Pass, Phenomenon, Scratch, Stage, View, VolumeOptions, VolumeOut,
};
use crate::settings::SceneSettings;

/// An aurora scene file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AuroraScene {
    /// `[scene]`.
    #[serde(default)]
    pub scene: SceneSettings,
    /// `[aurora]`.
    #[serde(default)]
    pub aurora: AuroraConfig,
    /// `[render]`.
    #[serde(default)]
    pub render: RenderSettings,
}

/// The sky preview emits for about this many particles per frame (every k-th particle,
/// k times the weight, the phase turning each frame: an unbiased thinning, see
/// `SkyRenderer::set_particle_subset`); final renders use all of them. 30,000 at 14
/// points a particle emit about as many points as 15,000 did at 28, and the preview of
/// scene 2 is 2.3 dB closer to the full image (aurora `tests/sampling_quality.rs`).
const PREVIEW_PARTICLES: usize = 30_000;

impl Phenomenon for AuroraScene {
    const NAME: &'static str = "aurora";
    const ABOUT: &'static str =
        "the artist-controllable aurora: drawn shapes, charged particles, emission lines (Sekiguchi 2018)";
    const VIEWS: &'static [View] = &[
        View { name: "sky", about: "the aurora in the sky through the scene's camera (thesis §2.4)" },
        View { name: "plane", about: "the x-z simulation plane from above (thesis Figs 2.9-2.14)" },
    ];
    const EXPORTS: &'static [ExportKind] = &[
        ExportKind {
            name: "particles",
            about: "the particles after a frame: x,z,vx,vz (km, km/s)",
            formats: &["csv"],
        },
        ExportKind {
            name: "shape",
            about: "the intermediate target shape at a frame: sheet,index,x,z,next",
            formats: &["csv"],
        },
    ];
    const STARTER: &'static str = include_str!("../starters/aurora.toml");
    const CAN: &'static [Capability] = &[Capability::Volume, Capability::Points];
    type Sim = AuroraSim;
    type Renderer = AuroraRenderer;
    type Loaded = Option<Frame>;

    fn settings(&self) -> &SceneSettings {
        &self.scene
    }

    fn settings_mut(&mut self) -> &mut SceneSettings {
        &mut self.scene
    }

    fn validate(&self, i: &mut Issues) {
        match self.aurora.validate() {
            Err(e) => i.extend_prefixed("aurora", e),
            Ok(()) => {
                if let Err(e) = self.render.sky.validate() {
                    i.extend_prefixed("render.sky", e);
                }
                if let Err(e) = self.aurora.animation() {
                    i.extend_prefixed("aurora", vec![Issue::described(e.field(), e.to_string())]);
                }
            }
        }
    }

    fn render_memory(&self) -> Option<&'static str> {
        let sky = &self.render.sky;
        (self.render.view == AuroraView::Sky && sky.afterglow && sky.mode == ColourMode::Physical)
            .then_some("[render.sky] afterglow = true carries each line's light from frame to frame")
    }

    fn view(&self) -> &'static str {
        match self.render.view {
            AuroraView::Sky => "sky",
            AuroraView::Plane => "plane",
        }
    }

    fn set_view(&mut self, view: &str) {
        self.render.view = if view == "plane" { AuroraView::Plane } else { AuroraView::Sky };
    }

    fn load(&self, assets: &Assets) -> Result<Option<Frame>, BuildError> {
        match (&self.render.view, &self.render.sky.background) {
            (AuroraView::Sky, SkyBackground::Image { path }) => {
                Ok(Some(assets.image("render.sky.background.path", path)?))
            }
            _ => Ok(None),
        }
    }

    fn check(&self, _background: &Option<Frame>) -> Result<Vec<String>, BuildError> {
        // The simulation checks what validation already did (parameters, shapes).
        let (w, h) = self.scene.size();
        AuroraRenderer::check(&self.render, w, h).map_err(|e| BuildError::render("render.sky", e))?;
        Ok(Vec::new())
    }

    /// Particles (up to twice the start after redistribution: scene 2 grows by 1.6x),
    /// the field's grid and charges, and in the sky view the emission points of a frame
    /// (16 bytes each, filed by band as they are emitted and kept between frames; the
    /// physical mode through a perspective camera deposits them as it emits them into
    /// tiles, which keep at most eight images' line images, counted too, as a frame may
    /// take either path), the paper mode's pooled falls, the line images and the night's
    /// still part (16 bytes a pixel).
    fn estimate(&self, _background: &Option<Frame>) -> Estimate {
        let a = &self.aurora;
        let particles = f64::from(a.motion.particles) * if a.redistribution.enabled { 2.0 } else { 1.0 };
        let cells = f64::from(a.plane.cells[0]) * f64::from(a.plane.cells[1]);
        let (w, h) = (f64::from(self.scene.width), f64::from(self.scene.height));
        let sky = &self.render.sky;
        let per_particle = match sky.mode {
            // Each of the five lines rounds to at least one point.
            ColourMode::Physical => f64::from(sky.points_per_particle) + 5.0,
            ColourMode::Paper => f64::from(sky.paper.collisions),
        };
        let mut parts = vec![
            ("particles", particles * 96.0),
            ("field grid", cells * 48.0),
            ("charges", f64::from(a.field.charges) * 16.0),
        ];
        let work = match self.render.view {
            AuroraView::Sky => {
                parts.push(("emission points of a frame", particles * per_particle * 16.0));
                if sky.mode == ColourMode::Physical {
                    parts.push(("emission tiles", 8.0 * w * h * 5.0 * 4.0));
                }
                if sky.mode == ColourMode::Paper && sky.paper.falls == phenomena_aurora::fall::Falls::Pooled {
                    // At most one point a collision, 16 bytes each, twice while the pool
                    // is gathered.
                    let pool = f64::from(sky.paper.pool_size) * f64::from(sky.paper.collisions) * 16.0;
                    parts.push(("pooled falls", 2.0 * pool));
                }
                parts.push(("line images and frame", w * h * (10.0 * 4.0 + 12.0)));
                parts.push(("the night's still part", w * h * 16.0));
                format!(
                    "{particles:.0} particles at most × {per_particle:.0} emission points; a {}x{} field every {} frames; {w}x{h} pixels",
                    a.plane.cells[0], a.plane.cells[1], a.shape.renew_every_frames
                )
            }
            AuroraView::Plane => {
                parts.push(("frame", w * h * 16.0));
                format!(
                    "{particles:.0} particles at most; a {}x{} field; {w}x{h} pixels",
                    a.plane.cells[0], a.plane.cells[1]
                )
            }
        };
        Estimate::of(work, parts)
    }

    /// [`Pass::Sky`]: the aurora (and its stars and far ground) behind everything: the
    /// shot's backdrop.
    fn compose(sim: &AuroraSim, renderer: &mut AuroraRenderer, pass: Pass, stage: &mut Stage) {
        if pass == Pass::Sky {
            let sky = renderer.render(sim);
            stage.under(sky);
            stage.layers.push(("aurora", sky.clone(), None));
        }
    }

    fn frame_time_s(&self) -> f64 {
        f64::from(self.aurora.motion.time_step_s)
    }

    /// Twice the volume of the particles now: the particles grow to about twice the
    /// start after redistribution (scene 2: 1.6x), spreading over more voxel columns.
    fn volume_bytes(built: &Built<Self>, options: &VolumeOptions) -> Result<u64, String> {
        let voxel_km = options.voxel_m.map_or(1.0, |m| m / 1e3);
        let now = built.renderer.volume_bytes(&built.sim, voxel_km).map_err(|e| e.to_string())?;
        Ok(now.saturating_mul(2))
    }

    /// One emission grid per line (`aurora_557_7`, ...: rayleighs per metre of path) in
    /// metres ([`phenomena_aurora::volume`]), 1 km voxels by default.
    fn volume(
        built: &Built<Self>,
        options: &VolumeOptions,
        _scratch: &mut Scratch,
        out: &mut VolumeOut<'_>,
    ) -> Result<Value, String> {
        use phenomena_core::vdb::AnyGrid;
        let voxel_km = options.voxel_m.map_or(1.0, |m| m / 1e3);
        let need = built.renderer.volume_bytes(&built.sim, voxel_km).map_err(|e| e.to_string())?;
        options.admit(need, &format!("{voxel_km} km"))?;
        let grids = built.renderer.line_volumes(&built.sim, voxel_km).map_err(|e| e.to_string())?;
        let any: Vec<AnyGrid<'_>> = grids.iter().map(AnyGrid::from).collect();
        Ok(crate::phenomenon::encode_volume(&any, out))
    }

    /// The particles as the feet of their field lines at the top of the sky view's
    /// atmosphere, in metres (x east, y altitude, z north, the plane centred over the
    /// origin), with their velocity (m/s) and id.
    fn points(built: &Built<Self>) -> Result<PointCache, String> {
        let p = built.sim.particles();
        let grid = built.sim.grid();
        let centre = grid.origin_km + grid.extent_km() * 0.5;
        let top_m = top_altitude_m(built);
        let mut c = PointCache::default();
        c.push_vec3(
            ["x", "y", "z"],
            p.position_km.iter().map(|q| [(q.x - centre.x) * 1e3, top_m, (q.y - centre.y) * 1e3]),
        );
        c.push_vec3(["vx", "vy", "vz"], p.velocity_km_s.iter().map(|v| [v.x * 1e3, 0.0, v.y * 1e3]));
        c.push_u32("id", p.id.iter().map(|&i| i as u32).collect());
        c.comments.push("units: position m (x east, y altitude, z north), velocity m/s".into());
        Ok(c)
    }

    fn build(&self, background: Option<Frame>) -> Result<Built<Self>, BuildError> {
        let sim = AuroraSim::new(self.aurora.clone(), self.scene.seed).map_err(|e| match e {
            AuroraError::Invalid(c) => BuildError::invalid("aurora", c),
            AuroraError::Shape(s) => {
                BuildError::Invalid(vec![Issue::described(format!("aurora.{}", s.field()), s.to_string())])
            }
            other => BuildError::refused(other),
        })?;
        let (w, h) = self.scene.size();
        let renderer = AuroraRenderer::new(self.render.clone(), w, h, background.as_ref())
            .map_err(|e| BuildError::render("render.sky", e))?;
        Ok(Built { sim, renderer, warnings: Vec::new() })
    }

    fn set_clock(built: &mut Built<Self>, clock: &SharedClock) {
        built.sim.set_clock(clock.clone());
        built.renderer.set_clock(clock.clone());
    }

    fn before_render(built: &mut Built<Self>, preview: Option<u32>) {
        let (stride, phase) = match preview {
            Some(frame) => {
                let k = built.sim.particles().len().div_ceil(PREVIEW_PARTICLES).max(1);
                (k, frame as usize % k)
            }
            None => (1, 0),
        };
        built.renderer.set_particle_subset(stride, phase);
    }

    fn render_detail(built: &Built<Self>) -> Option<Value> {
        built.renderer.timings().and_then(|t| serde_json::to_value(t).ok())
    }

    fn export(built: &Built<Self>, name: &str, format: &str) -> Result<Exported, String> {
        if format != "csv" {
            return Err(format!("aurora {name} exports are csv, not {format}"));
        }
        let sim = &built.sim;
        let mut text = String::new();
        let rows = match name {
            "particles" => {
                text.push_str("x,z,vx,vz\n");
                let p = sim.particles();
                for (x, v) in p.position_km.iter().zip(&p.velocity_km_s) {
                    let _ = writeln!(text, "{},{},{},{}", x.x, x.y, v.x, v.y);
                }
                p.len()
            }
            "shape" => {
                text.push_str("sheet,index,x,z,next\n");
                let sh = &sim.field().shape;
                for i in 0..sh.points.len() {
                    let next = sh.next.get(i).copied().flatten();
                    let next = next
                        .and_then(|j| sh.index_in_sheet.get(j as usize))
                        .map(ToString::to_string)
                        .unwrap_or_default();
                    let p = sh.points[i];
                    let (sheet, index) = (sh.sheet[i], sh.index_in_sheet[i]);
                    let _ = writeln!(text, "{sheet},{index},{},{},{next}", p.x, p.y);
                }
                sh.points.len()
            }
            other => return Err(format!("aurora scenes export particles or shape, not `{other}`")),
        };
        Ok(Exported { bytes: text.into_bytes(), summary: format!("{rows} rows") })
    }
}

/// The altitude of the simulation plane in the sky view, metres.
fn top_altitude_m(built: &Built<AuroraScene>) -> f32 {
    built.renderer.settings().sky.top_altitude_km * 1e3
}
