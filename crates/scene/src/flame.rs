//! Flame scenes: `[flame]` (the SPH gas of Inagaki et al., §4) and its `[render]`
//! (§5: blackbody splats, heat shimmer, background).

use phenomena_core::validate::Issues;
use phenomena_flame::{Background, FlameConfig, FlameRenderer, FlameSim, RenderSettings, View as FlameView};
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::assets::Assets;
use crate::phenomenon::{Built, Phenomenon, Steer, View};
use crate::runner::BuildError;
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
    type Sim = FlameSim;
    type Renderer = FlameRenderer;

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

    fn build(&self, assets: &Assets) -> Result<Built<Self>, BuildError> {
        let background = match &self.render.background {
            Background::Image { path } => Some(assets.image("render.background.path", path)?),
            _ => None,
        };
        let sim = FlameSim::new(self.flame.clone(), self.scene.seed).map_err(BuildError::refused)?;
        let (w, h) = self.scene.size();
        let renderer = FlameRenderer::new(self.render.clone(), w, h, background.as_ref())
            .map_err(BuildError::refused)?;
        Ok(Built { sim, renderer, warnings: Vec::new() })
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
