//! Sparkle scenes: `[sparkle]` (the glints of Hwang and Noma's stochastic model, §2-3:
//! diamond dust or leaf glitter) and its `[render]`.

use phenomena_core::validate::Issues;
use phenomena_sparkle::{Background, RenderSettings, SparkleConfig, SparkleRenderer, SparkleSim};
use serde::{Deserialize, Serialize};

use crate::assets::Assets;
use crate::phenomenon::{Built, Phenomenon, View};
use crate::runner::BuildError;
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
    type Sim = SparkleSim;
    type Renderer = SparkleRenderer;

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

    fn build(&self, assets: &Assets) -> Result<Built<Self>, BuildError> {
        let background = match &self.render.background {
            Background::Image { path } => Some(assets.image("render.background.path", path)?),
            _ => None,
        };
        let sim = SparkleSim::new(self.sparkle, self.scene.seed).map_err(BuildError::refused)?;
        let mut warnings = Vec::new();
        if sim.cone_is_empty() {
            let p = &self.sparkle.phong;
            warnings.push(format!(
                "no facet can be seen: threshold_i_e {} is not below k_s I_l = {}; the frames show the background only",
                p.threshold_i_e,
                p.specular_k_s * p.light_intensity
            ));
        }
        let (w, h) = self.scene.size();
        let renderer = SparkleRenderer::new(self.render.clone(), w, h, background.as_ref())
            .map_err(BuildError::refused)?;
        Ok(Built { sim, renderer, warnings })
    }
}
