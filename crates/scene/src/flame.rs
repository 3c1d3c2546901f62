//! Flame scenes: `[flame]` (the SPH gas of Inagaki et al., §4) and its `[render]`
//! (§5: blackbody splats, heat shimmer, background).

use phenomena_core::image::Frame;
use phenomena_core::validate::Issues;
use phenomena_flame::{
    Background, FlameConfig, FlameError, FlameRenderer, FlameSim, RenderSettings, View as FlameView,
};
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::assets::Assets;
use crate::budget::Estimate;
use crate::cache::PointCache;
use crate::error::BuildError;
use crate::phenomenon::{
    Built, Capability, MotionVectors, Pass, Phenomenon, Scratch, Stage, Steer, View, VolumeOptions, VolumeOut,
};
use crate::settings::SceneSettings;

/// A flame scene file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FlameScene {
    /// `[scene]`.
    #[serde(default)]
    pub scene: SceneSettings,
    /// `[flame]`.
    #[serde(default)]
    pub flame: FlameConfig,
    /// `[render]`.
    #[serde(default)]
    pub render: RenderSettings,
}

/// The table a studio changes live: `flame.wind` (e.g. `{"force_n_m3": [1, 0, 0]}`).
pub const WIND_PATH: &str = "flame.wind";

impl Phenomenon for FlameScene {
    const NAME: &'static str = "flame";
    const ABOUT: &'static str = "the SPH flame with wind, blackbody colour and heat shimmer (Inagaki et al.)";
    const VIEWS: &'static [View] = &[
        View { name: "flame", about: "the flame over its shimmering background (Fig 8)" },
        View { name: "density", about: "particles as squares coloured by density (Fig 7)" },
    ];
    const STARTER: &'static str = include_str!("../starters/flame.toml");
    const CAN: &'static [Capability] =
        &[Capability::Volume, Capability::Points, Capability::EmissionOnly, Capability::Motion];
    type Sim = FlameSim;
    type Renderer = FlameRenderer;
    type Loaded = Option<Frame>;

    fn settings(&self) -> &SceneSettings {
        &self.scene
    }

    fn settings_mut(&mut self) -> &mut SceneSettings {
        &mut self.scene
    }

    fn validate(&self, i: &mut Issues) {
        if let Err(e) = self.flame.validate() {
            i.extend_prefixed("flame", e);
        }
        if let Err(e) = self.render.validate() {
            i.extend_prefixed("render", e);
        }
    }

    fn view(&self) -> &'static str {
        match self.render.view {
            FlameView::Flame => "flame",
            FlameView::Density => "density",
        }
    }

    fn set_view(&mut self, view: &str) {
        self.render.view = if view == "density" { FlameView::Density } else { FlameView::Flame };
    }

    fn load(&self, assets: &Assets) -> Result<Option<Frame>, BuildError> {
        match &self.render.background {
            Background::Image { path } => Ok(Some(assets.image("render.background.path", path)?)),
            _ => Ok(None),
        }
    }

    fn check(&self, _background: &Option<Frame>) -> Result<Vec<String>, BuildError> {
        let (w, h) = self.scene.size();
        FlameRenderer::check(&self.render, w, h).map_err(|e| BuildError::render("render", e))?;
        Ok(Vec::new())
    }

    /// Particles at the peak (rate × the longest lifetime, capped by `max_particles`)
    /// with their attributes, sorting copies and neighbour lists; the neighbour grid of
    /// the domain box; the frame, its background and the splat planes.
    fn estimate(&self, _background: &Option<Frame>) -> Estimate {
        let f = &self.flame;
        let particles = peak_particles(f);
        let d = f64::from(f.sph.support_radius_m);
        let size = (f.domain.max_m - f.domain.min_m).as_dvec3() / d.max(1e-9) + glam::DVec3::ONE;
        let cells = size.x.ceil() * size.y.ceil() * size.z.ceil();
        let (w, h) = (f64::from(self.scene.width), f64::from(self.scene.height));
        let k = f64::from(self.render.resolution_scale);
        let mut estimate = Estimate::of(
            format!("{particles:.0} particles at the peak; {w}x{h} pixels"),
            vec![
                // ~80 B of attributes, doubled for the reorder into cell order, plus
                // neighbour lists of ~64 entries of 4 B, a splat (~40 B) and its index
                // filed by band.
                ("particles", particles * (160.0 + 256.0 + 60.0)),
                ("neighbour grid", cells * 8.0),
                ("frame and background", 2.0 * w * h * 12.0),
                ("splat planes", 5.0 * w * h * k * k * 4.0),
            ],
        );
        if f.max_burner_rate_per_s().is_none() {
            estimate.unchecked.push(
                "the density at the burner (a point burner or gas born at rest): a render may stop with \"too dense\"".into(),
            );
        }
        estimate
    }

    fn build(&self, background: Option<Frame>) -> Result<Built<Self>, BuildError> {
        let sim = FlameSim::new(self.flame.clone(), self.scene.seed).map_err(|e| match e {
            FlameError::Invalid(c) => BuildError::invalid("flame", c),
            other => BuildError::refused(other),
        })?;
        let (w, h) = self.scene.size();
        let renderer = FlameRenderer::new(self.render.clone(), w, h, background.as_ref())
            .map_err(|e| BuildError::render("render", e))?;
        Ok(Built { sim, renderer, warnings: Vec::new() })
    }

    /// [`Pass::Place`]: the flame's depth is its particles' mean position's, and it is
    /// a light for the surfaces around it ([`FlameRenderer::light`]).
    /// [`Pass::Media`]: its light over the shot so far, which its shimmer refracts; a
    /// splat behind a surface is hidden.
    fn compose(sim: &FlameSim, renderer: &mut FlameRenderer, pass: Pass, stage: &mut Stage) {
        match pass {
            Pass::Place => {
                if let Some(light) = renderer.light(sim.particles(), sim.config()) {
                    stage.lights.push(light);
                }
                let p = &sim.particles().position_m;
                if !p.is_empty() {
                    let sum = p.iter().fold(glam::DVec3::ZERO, |s, v| s + v.as_dvec3());
                    let mean = (sum / p.len() as f64).as_vec3();
                    if let Some(q) = renderer.view().project(mean) {
                        stage.medium_depth_m = stage.medium_depth_m.min(q.depth);
                    }
                }
            }
            Pass::Media => {
                // The flame's own background only when nothing farther gave one.
                stage.under(renderer.background());
                // The shot builds every renderer at its frame's size.
                if renderer.set_background(&stage.image).is_ok()
                    && renderer.set_occluder(Some(&stage.depth)).is_ok()
                {
                    stage.image.clone_from(renderer.render(sim));
                    stage.layers.push(("flame", renderer.emission(), None));
                }
            }
            _ => {}
        }
    }

    fn frame_time_s(&self) -> f64 {
        f64::from(self.flame.frame_time_s)
    }

    fn emission_only(&mut self) {
        self.render.background = Background::Black;
    }

    /// At the peak particle count of [`Phenomenon::estimate`].
    fn volume_bytes(built: &Built<Self>, options: &VolumeOptions) -> Result<u64, String> {
        let voxel_m = options.voxel_m.unwrap_or(0.01);
        let config = built.sim.config();
        let particles = (peak_particles(config) as usize).max(built.sim.particles().len());
        let air = built.sim.air().map_or(0, phenomena_flame::volume::air_velocity_bytes);
        phenomena_flame::volume::volume_bytes(particles, config, voxel_m)
            .map(|n| n + air)
            .map_err(|e| e.to_string())
    }

    /// `density` (kg/m³), `temperature` (K) and `emission` (linear sRGB) grids in metres
    /// ([`phenomena_flame::volume`]), 1 cm voxels by default; with the air around the
    /// flame, also its `velocity` (m/s) at the air's own cells.
    fn volume(
        built: &Built<Self>,
        options: &VolumeOptions,
        scratch: &mut Scratch,
        out: &mut VolumeOut<'_>,
    ) -> Result<Value, String> {
        use phenomena_core::vdb::AnyGrid;
        use phenomena_flame::volume::{air_velocity, air_velocity_bytes, volume_bytes};
        let voxel_m = options.voxel_m.unwrap_or(0.01);
        let air = built.sim.air();
        let need = volume_bytes(built.sim.particles().len(), built.sim.config(), voxel_m)
            .map(|n| n + air.map_or(0, air_velocity_bytes))
            .map_err(|e| e.to_string())?;
        options.admit(need, &format!("{voxel_m} m"))?;
        // With the air around the flame, its velocity (at the air's own cells).
        let velocity = air.map(air_velocity).transpose().map_err(|e| e.to_string())?;
        let r = &built.renderer;
        let voxelizer = scratch.get::<phenomena_flame::volume::Voxelizer>();
        let v = voxelizer
            .voxelize(built.sim.particles(), built.sim.config(), r.settings(), r.lut(), voxel_m)
            .map_err(|e| e.to_string())?;
        let mut grids =
            vec![AnyGrid::from(&v.density), AnyGrid::from(&v.temperature), AnyGrid::from(&v.emission)];
        grids.extend(velocity.as_ref().map(AnyGrid::from));
        Ok(crate::phenomenon::encode_volume(&grids, out))
    }

    /// Position (m), velocity (m/s), temperature (K), density (kg/m³) and id.
    fn points(built: &Built<Self>) -> Result<PointCache, String> {
        let p = built.sim.particles();
        let mut c = PointCache::default();
        c.push_vec3(["x", "y", "z"], p.position_m.iter().map(|v| v.to_array()));
        c.push_vec3(["vx", "vy", "vz"], p.velocity_m_s.iter().map(|v| v.to_array()));
        c.push_f32("temperature", p.temperature_k.clone());
        c.push_f32("density", p.density_kg_m3.clone());
        c.push_u32("id", p.id.iter().map(|&i| i as u32).collect());
        c.comments.push("units: position m (y up), velocity m/s, temperature K, density kg/m^3".into());
        Ok(c)
    }

    /// Where the flame's light moves in one frame time, per pixel of the last render
    /// ([`phenomena_flame::motion`]).
    fn motion(built: &Built<Self>) -> Result<MotionVectors, String> {
        if built.renderer.settings().view != phenomena_flame::View::Flame {
            return Err(
                "--motion: the density view's squares have no motion vectors (use the flame view)".into()
            );
        }
        let sim = &built.sim;
        let field = phenomena_flame::motion::motion_vectors(
            &built.renderer,
            sim.particles(),
            sim.config(),
            sim.config().frame_time_s,
        );
        Ok(MotionVectors { width: field.width, height: field.height, vectors: field.vectors })
    }

    /// The wind ([`WIND_PATH`]) changes live (the paper's §6 mouse drag).
    fn steer(built: &mut Built<Self>, path: &str, value: &Value) -> Steer {
        if path != WIND_PATH {
            return Steer::NotLive;
        }
        let wind: phenomena_flame::Wind = match serde_json::from_value(value.clone()) {
            Ok(w) => w,
            Err(e) => return Steer::Refused(format!("{path} = {value}: {e}")),
        };
        match built.sim.set_wind(wind) {
            Ok(()) => Steer::Applied,
            Err(e) => Steer::Refused(format!("{path} = {value}: {e}")),
        }
    }
}

/// Particles at the peak: the emission rate times the longest lifetime, capped by
/// `max_particles`.
fn peak_particles(f: &FlameConfig) -> f64 {
    let e = &f.emitter;
    let born = f64::from(e.rate_per_s) * f64::from(e.lifetime_s) * (1.0 + f64::from(e.lifetime_jitter));
    born.min(f64::from(f.max_particles)).ceil()
}
