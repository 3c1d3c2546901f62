//! Snow scenes: `[geometry]` (a built-in scene or a mesh file), `[snow]` (Tokoi and
//! Moriki 2006: maps, probability, accumulation, repose, falling) and `[render]`.

use std::cell::RefCell;
use std::path::PathBuf;

use phenomena_core::image::Frame;
use phenomena_core::validate::{Expected, Issue, Issues};
use phenomena_snow::mesh::{Builtin, Mesh};
use phenomena_snow::{
    Background, SnowConfig, SnowError, SnowRenderSettings, SnowRenderer, SnowSim, SnowView, load,
};
use serde::{Deserialize, Serialize};

use crate::assets::{AssetError, Assets};
use crate::budget::Estimate;
use crate::error::BuildError;
use crate::phenomenon::{Built, ExportKind, Exported, Pass, Phenomenon, Stage, View};
use crate::settings::SceneSettings;

/// Where a snow scene's geometry comes from (`[geometry]`): a built-in scene or a mesh
/// file (OBJ, glTF/GLB or DXF by extension, relative to the scene file), not both.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SnowGeometry {
    /// A built-in scene; with neither this nor `mesh`, the table (the paper's Fig 7).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub builtin: Option<Builtin>,
    /// A mesh file instead.
    pub mesh: Option<PathBuf>,
    /// Scale from the file's units to metres.
    pub scale: f32,
}

impl Default for SnowGeometry {
    fn default() -> Self {
        Self { builtin: None, mesh: None, scale: 1.0 }
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

/// A snow scene's files, read: its triangles (and the warnings from reading them) and
/// its background image.
pub struct SnowFiles {
    mesh: Mesh,
    warnings: Vec<String>,
    background: Option<Frame>,
}

/// The scene key of the mesh file.
const MESH_KEY: &str = "geometry.mesh";

impl SnowScene {
    /// A simulation's refusal at the scene key it is about.
    fn refusal(&self, e: SnowError) -> BuildError {
        let geometry = if self.geometry.mesh.is_some() { "geometry.mesh" } else { "geometry.builtin" };
        match e {
            SnowError::Invalid(c) => BuildError::invalid("snow", c),
            SnowError::ObjectGroups { given, objects } => BuildError::Invalid(vec![Issue {
                field: "snow.object_groups".into(),
                value: format!("{given} entries"),
                expected: Expected::Text(format!(
                    "one group number per object of the scene: {objects} entries"
                )),
            }]),
            e @ (SnowError::NoSnowSurface | SnowError::ZeroArea) => {
                BuildError::Unusable { key: geometry.into(), message: e.to_string() }
            }
            other => BuildError::refused(other),
        }
    }

    /// The triangles: the built-in scene, or the mesh file read through `assets` and
    /// parsed (degenerate triangles dropped, counted in the warnings).
    pub fn mesh(&self, assets: &Assets) -> Result<(Mesh, Vec<String>), BuildError> {
        let Some(file) = &self.geometry.mesh else {
            let mut mesh = self.geometry.builtin.unwrap_or(Builtin::Table).mesh();
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
        // The buffers together hold at most one file's cap: a glTF naming one large file
        // many times reads it once within the cap, not many times over.
        let mut left = assets.file_cap();
        let loaded = match ext.as_str() {
            "obj" => load::obj(&bytes, scale),
            "dxf" => load::dxf(&bytes, scale),
            _ => load::gltf(
                &bytes,
                |uri| {
                    let data = assets.read_referenced(MESH_KEY, file, uri).and_then(|data| {
                        left = left.checked_sub(data.len() as u64).ok_or_else(|| AssetError {
                            key: MESH_KEY.into(),
                            written: file.display().to_string(),
                            uri: Some(uri.to_string()),
                            problem: format!(
                                "the glTF's buffers hold more than {} bytes in all",
                                assets.file_cap()
                            ),
                        })?;
                        Ok(data)
                    });
                    data.map_err(|e| {
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

/// A built-in scene's name in scene files.
fn builtin_name(b: Builtin) -> String {
    serde_json::to_value(b).ok().and_then(|v| v.as_str().map(String::from)).unwrap_or_default()
}

impl Phenomenon for SnowScene {
    const NAME: &'static str = "snow";
    const ABOUT: &'static str =
        "snow cover: where snow lands, how it piles up, slides and falls (Tokoi and Moriki 2006)";
    const VIEWS: &'static [View] = &[
        View { name: "scene", about: "the scene and its snow through the camera" },
        View { name: "probability", about: "the snow probability P_a of each map from above (§2.2)" },
    ];
    const EXPORTS: &'static [ExportKind] = &[
        ExportKind {
            name: "snow-mesh",
            about: "the snow as closed solids per snow patch, with normals",
            formats: &["glb", "obj", "ply"],
        },
        ExportKind {
            name: "snow-scene",
            about: "the scene's objects, the snow, the camera and the sun as the renderer draws them",
            formats: &["glb"],
        },
    ];
    const STARTER: &'static str = include_str!("../starters/snow.toml");
    type Sim = SnowSim;
    type Renderer = SnowRenderer;
    type Loaded = SnowFiles;

    fn settings(&self) -> &SceneSettings {
        &self.scene
    }

    fn settings_mut(&mut self) -> &mut SceneSettings {
        &mut self.scene
    }

    fn validate(&self, i: &mut Issues) {
        i.range_open_low("geometry.scale", self.geometry.scale, 0.0, 1e6);
        if let (Some(builtin), Some(mesh)) = (&self.geometry.builtin, &self.geometry.mesh) {
            i.push(
                "geometry.mesh",
                format!("{:?}", mesh.display().to_string()),
                format!(
                    "either a mesh file or builtin = {:?}, not both: remove one of them",
                    builtin_name(*builtin)
                ),
            );
        }
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

    fn load(&self, assets: &Assets) -> Result<SnowFiles, BuildError> {
        let (mesh, warnings) = self.mesh(assets)?;
        let background = match &self.render.background {
            Background::Image { path } => Some(assets.image("render.background.path", path)?),
            Background::Sky => None,
        };
        Ok(SnowFiles { mesh, warnings, background })
    }

    fn check(&self, files: &SnowFiles) -> Result<Vec<String>, BuildError> {
        SnowSim::check(&files.mesh, &self.snow).map_err(|e| self.refusal(e))?;
        let (w, h) = self.scene.size();
        SnowRenderer::check(&self.render, w, h).map_err(|e| BuildError::render("render", e))?;
        Ok(files.warnings.clone())
    }

    /// The snow maps (one per polygon group: ground, snow, probability and the
    /// stabilisation's scratch per texel), the flood stabilisation's buffers (snow in
    /// transit, marks and distances per texel of every map), one depth map per worker thread for the
    /// probability (depth and id per pixel, the rasteriser's parts), the scene's
    /// triangles twice (as given and ordered for culling), the snow mesh drawn each
    /// frame, and the frame with its depth buffer.
    fn estimate(&self, files: &SnowFiles) -> Estimate {
        let c = &self.snow;
        let maps = SnowSim::check(&files.mesh, c).unwrap_or(1) as f64;
        let n2 = f64::from(c.map_resolution).powi(2);
        let s2 = f64::from(c.shadow_resolution).powi(2);
        let threads = rayon::current_num_threads() as f64;
        let triangles = files.mesh.len() as f64;
        let (w, h) = (f64::from(self.scene.width), f64::from(self.scene.height));
        let mut parts = vec![
            ("snow maps", maps * n2 * 32.0),
            ("depth maps (one per thread)", threads * s2 * 16.0),
            ("scene triangles", triangles * 2.0 * 40.0),
            ("snow mesh drawn each frame", maps * n2 * 2.0 * 40.0),
            ("frame and depth buffer", w * h * 20.0),
        ];
        if c.stabiliser == phenomena_snow::Stabiliser::Flood {
            parts.insert(1, ("flood stabilisation's buffers", maps * n2 * 36.0));
        }
        Estimate::of(
            format!(
                "{} directions × {}² depth-map pixels per probability; {maps:.0} maps of {}² texels, up to {} stabilisation passes a step; {triangles:.0} triangles; {w}x{h} pixels",
                c.directions, c.shadow_resolution, c.map_resolution, c.max_passes
            ),
            parts,
        )
    }

    /// [`Pass::Surfaces`]: the scene and its snow over the sky, lit also by the other
    /// phenomena's lights (a fire); its depth hides what is behind a surface from the
    /// passes after.
    fn compose(sim: &SnowSim, renderer: &mut SnowRenderer, pass: Pass, stage: &mut Stage) {
        if pass != Pass::Surfaces {
            return;
        }
        if !stage.backdrop {
            stage.under(&renderer.background());
        }
        renderer.set_lights(&stage.lights);
        let image = renderer.render_over(sim, &stage.image).clone();
        let depth = renderer.depth();
        let (w, h) = (image.width(), image.height());
        let mut own = Frame::new(w, h);
        let mut cover = phenomena_core::image::Plane::new(w, h);
        for (k, (&d, at)) in depth.iter().zip(stage.depth.iter_mut()).enumerate() {
            if d.is_finite() {
                let (x, y) = (k % w, k / w);
                own.set_pixel(x, y, image.pixel(x, y));
                cover.set(x, y, 1.0);
                *at = at.min(d);
            }
        }
        stage.image = image;
        stage.layers.push(("snow", own, Some(cover)));
    }

    fn frame_time_s(&self) -> f64 {
        f64::from(self.snow.time_step_h) * 3600.0
    }

    /// The mesh the snow lies on: its triangles and object ids, bit for bit.
    fn files_identity(files: &SnowFiles) -> Option<u64> {
        let m = &files.mesh;
        let mut bytes = Vec::with_capacity(m.triangles.len() * 40);
        for (t, o) in m.triangles.iter().zip(&m.object) {
            for v in t {
                for c in v.to_array() {
                    bytes.extend_from_slice(&c.to_bits().to_le_bytes());
                }
            }
            bytes.extend_from_slice(&o.to_le_bytes());
        }
        Some(crate::checkpoint::hash_bytes(&bytes))
    }

    fn build(&self, files: SnowFiles) -> Result<Built<Self>, BuildError> {
        let SnowFiles { mesh, warnings, background } = files;
        let sim = SnowSim::new(mesh, self.snow.clone(), self.scene.seed).map_err(|e| self.refusal(e))?;
        let (w, h) = self.scene.size();
        let renderer = SnowRenderer::new(self.render.clone(), w, h, background.as_ref())
            .map_err(|e| BuildError::render("render", e))?;
        Ok(Built { sim, renderer, warnings })
    }

    /// The spare is a clone: the maps and the flood's buffers, the scene's triangles
    /// twice, and one depth map per thread where the probability is drawn again as the
    /// snow lies (a clone's depth maps are made when first drawn).
    fn spare_bytes(&self, files: &SnowFiles) -> u64 {
        let c = &self.snow;
        let maps = SnowSim::check(&files.mesh, c).unwrap_or(1) as f64;
        let n2 = f64::from(c.map_resolution).powi(2);
        let flood = if c.stabiliser == phenomena_snow::Stabiliser::Flood { 36.0 } else { 0.0 };
        let mut bytes = maps * n2 * (32.0 + flood) + files.mesh.len() as f64 * 2.0 * 40.0;
        if c.probability_every_steps > 0 {
            let threads = rayon::current_num_threads() as f64;
            bytes += threads * f64::from(c.shadow_resolution).powi(2) * 16.0;
        }
        bytes as u64
    }

    /// The flood that brings the snow to rest runs on one thread (8-10 ms of the
    /// yard's step); stepped on a spare while the frame renders, the render's threads
    /// fill that time.
    fn sync_spare(sim: &SnowSim, spare: &mut Option<SnowSim>) -> bool {
        match spare {
            Some(s) => s.sync_from(sim),
            None => *spare = Some(sim.clone()),
        }
        true
    }

    fn set_clock(built: &mut Built<Self>, clock: &phenomena_core::clock::SharedClock) {
        built.renderer.set_clock(clock.clone());
    }

    fn render_detail(built: &Built<Self>) -> Option<serde_json::Value> {
        if built.renderer.settings().view == SnowView::Scene {
            serde_json::to_value(built.renderer.timings()).ok()
        } else {
            None
        }
    }

    fn export(built: &Built<Self>, name: &str, format: &str) -> Result<Exported, String> {
        use phenomena_snow::export::{snow_mesh, to_glb, to_obj, to_ply};
        if name == "snow-scene" {
            if format != "glb" {
                return Err(format!("a snow scene is exported as glb, not {format}"));
            }
            let bytes = built.renderer.scene_glb(&built.sim);
            let summary = format!(
                "{} scene triangles, the snow after {:.2} h, the camera and the sun",
                built.sim.mesh().len(),
                built.sim.time_h()
            );
            return Ok(Exported { bytes, summary });
        }
        if name != "snow-mesh" {
            return Err(format!("snow scenes export snow-mesh or snow-scene, not `{name}`"));
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
