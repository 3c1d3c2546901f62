//! Snow scenes: `[geometry]` (a built-in scene or a mesh file), `[snow]` (Tokoi and
//! Moriki 2006: maps, probability, accumulation, repose, falling) and `[render]`.

use std::cell::RefCell;
use std::path::PathBuf;

use phenomena_core::validate::Issues;
use phenomena_snow::mesh::{Builtin, Mesh};
use phenomena_snow::{Background, SnowConfig, SnowRenderSettings, SnowRenderer, SnowSim, SnowView, load};
use serde::{Deserialize, Serialize};

use crate::assets::{AssetError, Assets};
use crate::phenomenon::{Built, ExportKind, Exported, Phenomenon, View};
use crate::runner::BuildError;
use crate::settings::SceneSettings;

/// Where a snow scene's geometry comes from (`[geometry]`): a built-in scene or a mesh
/// file (OBJ, glTF/GLB or DXF by extension, relative to the scene file).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SnowGeometry {
    /// A built-in scene (used when `mesh` is not given).
    pub builtin: Builtin,
    /// A mesh file instead.
    pub mesh: Option<PathBuf>,
    /// Scale from the file's units to metres.
    pub scale: f32,
}

impl Default for SnowGeometry {
    fn default() -> Self {
        Self { builtin: Builtin::Table, mesh: None, scale: 1.0 }
    }
}

/// A snow scene file: each frame is one time step of the snowfall.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SnowScene {
    /// `[scene]`.
    #[serde(default)]
    pub scene: SceneSettings,
    /// `[geometry]`.
    #[serde(default)]
    pub geometry: SnowGeometry,
    /// `[snow]`.
    #[serde(default)]
    pub snow: SnowConfig,
    /// `[render]`.
    #[serde(default)]
    pub render: SnowRenderSettings,
}

/// The scene key of the mesh file.
const MESH_KEY: &str = "geometry.mesh";

impl SnowScene {
    /// The triangles: the built-in scene, or the mesh file read through `assets` and
    /// parsed (degenerate triangles dropped, counted in the warnings).
    pub fn mesh(&self, assets: &Assets) -> Result<(Mesh, Vec<String>), BuildError> {
        let Some(file) = &self.geometry.mesh else {
            let mut mesh = self.geometry.builtin.mesh();
            mesh.clean(1e-12);
            return Ok((mesh, Vec::new()));
        };
        let unusable = |message: String| BuildError::Unusable {
            key: MESH_KEY.into(),
            message: format!("{:?}: {message}", file.display().to_string()),
        };
        let ext = file.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
        if !matches!(ext.as_str(), "obj" | "gltf" | "glb" | "dxf") {
            return Err(unusable(format!("unknown mesh format `.{ext}`: use .obj, .gltf, .glb or .dxf")));
        }
        let bytes = assets.read(MESH_KEY, file)?;
        let scale = self.geometry.scale;
        // The first buffer the glTF could not have, with its scene key and URI.
        let refused: RefCell<Option<AssetError>> = RefCell::new(None);
        let loaded = match ext.as_str() {
            "obj" => load::obj(&bytes, scale),
            "dxf" => load::dxf(&bytes, scale),
            _ => load::gltf(
                &bytes,
                |uri| {
                    assets.read_referenced(MESH_KEY, file, uri).map_err(|e| {
                        let problem = e.problem.clone();
                        refused.borrow_mut().get_or_insert(e);
                        problem
                    })
                },
                scale,
            ),
        };
        let loaded = match (loaded, refused.into_inner()) {
            (Ok(l), _) => l,
            (Err(_), Some(asset)) => return Err(asset.into()),
            (Err(e), None) => return Err(unusable(format!("cannot use the mesh: {e}"))),
        };
        let c = loaded.cleaned;
        let mut warnings = Vec::new();
        if c.degenerate + c.non_finite > 0 {
            warnings.push(format!(
                "{}: skipped {} degenerate triangle(s) and {} with non-finite vertices",
                file.display(),
                c.degenerate,
                c.non_finite
            ));
        }
        Ok((loaded.mesh, warnings))
    }
}

impl Phenomenon for SnowScene {
    const NAME: &'static str = "snow";
    const ABOUT: &'static str =
        "snow cover: where snow lands, how it piles up, slides and falls (Tokoi and Moriki 2006)";
    const VIEWS: &'static [View] = &[
        View { name: "scene", about: "the scene and its snow through the camera" },
        View { name: "probability", about: "the snow probability P_a of each map from above (§2.2)" },
    ];
    const EXPORTS: &'static [ExportKind] = &[ExportKind {
        name: "snow-mesh",
        about: "the snow as closed solids per snow patch, with normals",
        formats: &["glb", "obj", "ply"],
    }];
    const STARTER: &'static str = include_str!("../starters/snow.toml");
    type Sim = SnowSim;
    type Renderer = SnowRenderer;

    fn settings(&self) -> &SceneSettings {
        &self.scene
    }

    fn settings_mut(&mut self) -> &mut SceneSettings {
        &mut self.scene
    }

    fn validate(&self, i: &mut Issues) {
        i.range_open_low("geometry.scale", self.geometry.scale, 0.0, 1e6);
        if let Err(e) = self.snow.validate() {
            i.extend_prefixed("snow", e);
        }
        if let Err(e) = self.render.validate() {
            i.extend_prefixed("render", e);
        }
    }

    fn view(&self) -> &'static str {
        match self.render.view {
            SnowView::Scene => "scene",
            SnowView::Probability => "probability",
        }
    }

    fn set_view(&mut self, view: &str) {
        self.render.view = if view == "probability" { SnowView::Probability } else { SnowView::Scene };
    }

    fn build(&self, assets: &Assets) -> Result<Built<Self>, BuildError> {
        let (mesh, warnings) = self.mesh(assets)?;
        let background = match &self.render.background {
            Background::Image { path } => Some(assets.image("render.background.path", path)?),
            Background::Sky => None,
        };
        let sim = SnowSim::new(mesh, self.snow.clone(), self.scene.seed).map_err(BuildError::refused)?;
        let (w, h) = self.scene.size();
        let renderer =
            SnowRenderer::new(self.render.clone(), w, h, background.as_ref()).map_err(BuildError::refused)?;
        Ok(Built { sim, renderer, warnings })
    }

    fn export(built: &Built<Self>, name: &str, format: &str) -> Result<Exported, String> {
        use phenomena_snow::export::{snow_mesh, to_glb, to_obj, to_ply};
        if name != "snow-mesh" {
            return Err(format!("snow scenes export snow-mesh, not `{name}`"));
        }
        let tris = snow_mesh(&built.sim);
        let bytes = match format {
            "glb" => to_glb(&tris),
            "obj" => to_obj(&tris).into_bytes(),
            "ply" => to_ply(&tris),
            other => return Err(format!("snow meshes are glb, obj or ply, not {other}")),
        };
        Ok(Exported {
            bytes,
            summary: format!(
                "{} snow triangles ({:.3} m³ of snow after {:.2} h)",
                tris.triangles(),
                built.sim.volume_m3(),
                built.sim.time_h()
            ),
        })
    }
}
