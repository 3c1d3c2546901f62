//! Sparkle scenes: `[sparkle]` (the glints of Hwang and Noma's stochastic model, §2-3:
//! diamond dust or leaf glitter) and its `[render]`.

use phenomena_core::image::Frame;
use phenomena_core::validate::Issues;
use phenomena_sparkle::{
    Background, DepthWindow, Method, RenderSettings, SparkleConfig, SparkleError, SparkleRenderer, SparkleSim,
};
use serde::{Deserialize, Serialize};

use crate::assets::Assets;
use crate::budget::Estimate;
use crate::cache::PointCache;
use crate::error::BuildError;
use crate::phenomenon::{Built, Capability, Pass, Phenomenon, Stage, View, add_light};
use crate::settings::SceneSettings;

/// A sparkle scene file (diamond dust or leaf glitter).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SparkleScene {
    /// `[scene]`.
    #[serde(default)]
    pub scene: SceneSettings,
    /// `[sparkle]`.
    #[serde(default)]
    pub sparkle: SparkleConfig,
    /// `[render]`.
    #[serde(default)]
    pub render: RenderSettings,
}

impl Phenomenon for SparkleScene {
    const NAME: &'static str = "sparkle";
    const ABOUT: &'static str =
        "diamond dust and leaf glitter: only the facets that can be seen are made (Hwang and Noma)";
    const VIEWS: &'static [View] =
        &[View { name: "glints", about: "the glints (and glare) over the sky, the crown or an image" }];
    const STARTER: &'static str = include_str!("../starters/sparkle.toml");
    const CAN: &'static [Capability] = &[Capability::Points, Capability::EmissionOnly];
    type Sim = SparkleSim;
    type Renderer = SparkleRenderer;
    type Loaded = Option<Frame>;

    fn settings(&self) -> &SceneSettings {
        &self.scene
    }

    fn settings_mut(&mut self) -> &mut SceneSettings {
        &mut self.scene
    }

    fn validate(&self, i: &mut Issues) {
        if let Err(e) = self.sparkle.validate() {
            i.extend_prefixed("sparkle", e);
        }
        if let Err(e) = self.render.validate() {
            i.extend_prefixed("render", e);
        }
    }

    fn view(&self) -> &'static str {
        "glints"
    }

    fn set_view(&mut self, _view: &str) {}

    fn load(&self, assets: &Assets) -> Result<Option<Frame>, BuildError> {
        match &self.render.background {
            Background::Image { path } => Ok(Some(assets.image("render.background.path", path)?)),
            _ => Ok(None),
        }
    }

    fn check(&self, _background: &Option<Frame>) -> Result<Vec<String>, BuildError> {
        SparkleSim::check(&self.sparkle).map_err(sim_refusal)?;
        let (w, h) = self.scene.size();
        SparkleRenderer::check(&self.render, w, h).map_err(|e| BuildError::render("render", e))?;
        Ok(self.warnings())
    }

    /// The facets seen (and the ghosts followed for `memory_frames`), in two sets of
    /// arrays (this frame's and the last, kept for reuse); brute force: every facet; the
    /// frame, its background and the band sums.
    fn estimate(&self, _background: &Option<Frame>) -> Estimate {
        let c = &self.sparkle;
        let n = c.virtual_count() as f64;
        let (w, h) = (f64::from(self.scene.width), f64::from(self.scene.height));
        let images = ("frame, background and band sums", 3.0 * w * h * 12.0);
        if c.method == Method::BruteForce {
            return Estimate::of(
                format!("{n:.0} facets stepped (brute force); {w}x{h} pixels"),
                vec![("every facet", n * 40.0), images],
            );
        }
        let mut unchecked = Vec::new();
        let seen = c.expected_visible().unwrap_or_else(|| {
            unchecked.push(format!(
                "how many facets of a normal lobe are seen: known frame by frame (at most {:e} candidates)",
                phenomena_sparkle::MAX_CANDIDATES
            ));
            0.0
        });
        let ghosts = seen * 0.3 * f64::from(c.memory_frames);
        let mut estimate = Estimate::of(
            format!("{n:.0} virtual facets, about {seen:.0} seen; {w}x{h} pixels"),
            vec![("glints and ghosts (two sets of arrays)", 2.0 * (seen + ghosts) * 48.0), images],
        );
        estimate.unchecked = unchecked;
        estimate
    }

    /// [`Pass::Behind`]: the glints farther than the shot's medium (all of them when it
    /// has none); [`Pass::Front`]: the nearer ones. Each is drawn only where no surface
    /// is nearer.
    fn compose(sim: &SparkleSim, renderer: &mut SparkleRenderer, pass: Pass, stage: &mut Stage) {
        let medium = stage.medium_depth_m;
        let glints = match pass {
            Pass::Behind => {
                if !stage.backdrop {
                    stage.under(&renderer.background(sim));
                }
                let near_m = if medium.is_finite() { medium } else { 0.0 };
                renderer.render_glints(sim, DepthWindow { near_m, far_m: Some(&stage.depth) })
            }
            Pass::Front if medium.is_finite() => {
                let far: Vec<f32> = stage.depth.iter().map(|d| d.min(medium)).collect();
                renderer.render_glints(sim, DepthWindow { near_m: 0.0, far_m: Some(&far) })
            }
            _ => return,
        };
        add_light(&mut stage.image, glints);
        match stage.layers.iter_mut().find(|l| l.0 == "sparkle") {
            Some((_, own, _)) => add_light(own, glints),
            None => stage.layers.push(("sparkle", glints.clone(), None)),
        }
    }

    fn frame_time_s(&self) -> f64 {
        f64::from(self.sparkle.dt_s())
    }

    fn emission_only(&mut self) {
        self.render.background = Background::Black;
    }

    /// The glints seen now: position (m), normal, intensity (k_s I_l (N·H)^n) and the
    /// frame each became visible.
    fn points(built: &Built<Self>) -> Result<PointCache, String> {
        let g = built.sim.glints();
        let mut c = PointCache::default();
        c.push_vec3(["x", "y", "z"], g.position_m.iter().map(|v| v.to_array()));
        c.push_vec3(["nx", "ny", "nz"], g.normal.iter().map(|v| v.to_array()));
        c.push_f32("intensity", g.intensity.clone());
        c.push_u32("birth_frame", g.birth_frame.clone());
        c.comments.push("units: position m (y up); intensity k_s I_l (N.H)^n".into());
        Ok(c)
    }

    fn build(&self, background: Option<Frame>) -> Result<Built<Self>, BuildError> {
        let sim = SparkleSim::new(self.sparkle, self.scene.seed).map_err(sim_refusal)?;
        let (w, h) = self.scene.size();
        let renderer = SparkleRenderer::new(self.render.clone(), w, h, background.as_ref())
            .map_err(|e| BuildError::render("render", e))?;
        Ok(Built { sim, renderer, warnings: self.warnings() })
    }
}

impl SparkleScene {
    /// A scene that can show nothing says so.
    fn warnings(&self) -> Vec<String> {
        let p = &self.sparkle.phong;
        if p.cos_theta().is_some() {
            return Vec::new();
        }
        vec![format!(
            "no facet can be seen: threshold_i_e {} is not below k_s I_l = {}; the frames show the background only",
            p.threshold_i_e,
            p.specular_k_s * p.light_intensity
        )]
    }
}

/// The simulation's refusal, its invalid settings at their keys.
fn sim_refusal(e: SparkleError) -> BuildError {
    match e {
        SparkleError::Invalid(c) => BuildError::invalid("sparkle", c),
        other => BuildError::refused(other),
    }
}
