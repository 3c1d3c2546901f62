//! The one trait each phenomenon's scene module implements: its file struct (the whole
//! scene file: `[scene]` plus the phenomenon's tables) is the implementing type. Code
//! above it (the runner, the CLI, the studio) reaches phenomena only through their
//! [`crate::registry`] entries, so adding a phenomenon is one module plus one registry
//! line (`tests/contract.rs` runs every entry through every command and format).

use std::fmt::Debug;

use phenomena_core::clock::SharedClock;
use phenomena_core::phenomenon::{Renderer, Simulation};
use phenomena_core::validate::Issues;
use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;

use crate::assets::Assets;
use crate::budget::Estimate;
use crate::cache::PointCache;
use crate::error::BuildError;
use crate::settings::SceneSettings;

/// What a phenomenon can give besides its frames' images; an output format that needs
/// one is offered only for phenomena that have it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Capability {
    /// Its state as OpenVDB grids ([`Phenomenon::volume`]).
    Volume,
    /// Its particles as a point cache ([`Phenomenon::points`]).
    Points,
    /// Its light alone over black, for sprites ([`Phenomenon::emission_only`]).
    EmissionOnly,
    /// Where its frame's light moves in one frame, per pixel ([`Phenomenon::motion`]).
    Motion,
}

/// A frame's motion vectors: pixel (x, y)'s displacement over one frame at
/// `[y * width + x]`, pixels, x to the right and y down ([`Phenomenon::motion`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MotionVectors {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Displacements, pixels.
    pub vectors: Vec<[f32; 2]>,
}

/// A way a phenomenon can draw its frames (`[render] view` and `--view`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct View {
    /// The name in scene files and on the command line.
    pub name: &'static str,
    /// What it shows.
    pub about: &'static str,
}

/// A data product a phenomenon's state can be exported as (`phenomena export NAME`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct ExportKind {
    /// The name (`snow-mesh`).
    pub name: &'static str,
    /// What it holds.
    pub about: &'static str,
    /// File formats, by extension; the first is the default.
    pub formats: &'static [&'static str],
}

/// An exported file's bytes and a one-line summary of what it holds.
#[derive(Clone, Debug, PartialEq)]
pub struct Exported {
    /// The file's bytes.
    pub bytes: Vec<u8>,
    /// e.g. "120000 rows".
    pub summary: String,
}

/// What a live change of a running simulation did ([`Phenomenon::steer`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Steer {
    /// Applied to the running simulation (no restart needed).
    Applied,
    /// This parameter cannot change live: rebuild the simulation.
    NotLive,
    /// The value was refused; the simulation is unchanged.
    Refused(String),
}

/// A built simulation and renderer, with warnings for the user (a scene that can show
/// nothing, triangles dropped from a mesh, ...).
pub struct Built<P: Phenomenon> {
    /// The simulation.
    pub sim: P::Sim,
    /// Its renderer.
    pub renderer: P::Renderer,
    /// Warnings, each a sentence.
    pub warnings: Vec<String>,
}

/// Buffers a sink keeps for a phenomenon between frames (a volume's grids: tens of
/// megabytes a frame that need not be allocated again); the phenomenon decides what.
#[derive(Default)]
pub struct Scratch(pub Option<Box<dyn std::any::Any + Send>>);

impl Scratch {
    /// The buffers of type `T`, made with `T::default()` the first time.
    pub fn get<T: Default + Send + 'static>(&mut self) -> &mut T {
        if !self.0.as_ref().is_some_and(|b| b.is::<T>()) {
            self.0 = Some(Box::new(T::default()));
        }
        match self.0.as_mut().and_then(|b| b.downcast_mut::<T>()) {
            Some(t) => t,
            None => unreachable!("just stored a T"),
        }
    }
}

/// Where a phenomenon's volume goes ([`encode_volume`]).
pub enum VolumeOut<'a> {
    /// One OpenVDB file's bytes (the vector is cleared first).
    Vdb(&'a mut Vec<u8>),
    /// The grids' leaves as they are, one [`LeafGrid`] per grid (the vector is cleared
    /// first): for callers that want arrays rather than a file (the Python module).
    Leaves(&'a mut Vec<LeafGrid>),
}

/// One grid of a volume as its 8³ leaves, the values OpenVDB reads from the `.vdb` file
/// the same grid is written as.
#[derive(Clone, Debug, PartialEq)]
pub struct LeafGrid {
    /// The grid's name (`density`, `aurora_557_7`).
    pub name: String,
    /// Its class (`fog volume`, `unknown`).
    pub class: &'static str,
    /// Values per voxel: 1 (float) or 3 (vec3).
    pub components: usize,
    /// Voxel size, metres.
    pub voxel_size_m: f64,
    /// World position of voxel (0, 0, 0), metres.
    pub translation_m: [f64; 3],
    /// Each leaf's lowest voxel index (a multiple of 8 on each axis).
    pub origins: Vec<[i32; 3]>,
    /// The leaves' values, leaf after leaf in `origins`' order; in a leaf, voxel
    /// (i, j, k) from its origin at (i·64 + j·8 + k)·`components` (OpenVDB's order).
    pub values: Vec<f32>,
}

impl LeafGrid {
    /// The leaves of `grid`.
    pub fn of(grid: &phenomena_core::vdb::AnyGrid<'_>) -> Self {
        use phenomena_core::vdb::AnyGrid;
        let t = grid.transform();
        let mut leaf = LeafGrid {
            name: grid.name().to_string(),
            class: grid.class().as_str(),
            components: 1,
            voxel_size_m: t.voxel_size_m(),
            translation_m: t.translation_m(),
            origins: Vec::new(),
            values: Vec::new(),
        };
        match grid {
            AnyGrid::Float(g) => {
                for (origin, values) in g.leaves() {
                    leaf.origins.push(origin);
                    leaf.values.extend_from_slice(values);
                }
            }
            AnyGrid::Vec3(g) => {
                leaf.components = 3;
                for (origin, values) in g.leaves() {
                    leaf.origins.push(origin);
                    leaf.values.extend(values.iter().flatten());
                }
            }
        }
        leaf
    }
}

/// Put `grids` into `out` (encoded as one OpenVDB file, or as their leaves) and
/// describe each as OpenVDB will report it once read (the manifest written beside each
/// `.vdb`): name, value type, class, active voxels, smallest and largest value, bounding
/// box of the active voxels, voxel size and translation (metres), and the grid's
/// metadata.
pub fn encode_volume(grids: &[phenomena_core::vdb::AnyGrid<'_>], out: &mut VolumeOut<'_>) -> Value {
    match out {
        VolumeOut::Vdb(bytes) => {
            phenomena_core::vdb::encode_into(grids, &phenomena_core::vdb::Metadata::new(), bytes)
        }
        VolumeOut::Leaves(list) => {
            list.clear();
            list.extend(grids.iter().map(LeafGrid::of));
        }
    }
    let list: Vec<Value> = grids
        .iter()
        .map(|g| {
            let s = g.summary();
            let t = g.transform();
            serde_json::json!({
                "name": g.name(),
                "type": g.value_type(),
                "class": g.class().as_str(),
                "active_voxels": s.active_voxels,
                "min": s.min,
                "max": s.max,
                "bbox": s.bbox.map(|(lo, hi)| [lo, hi]),
                "voxel_size_m": t.voxel_size_m(),
                "translation_m": t.translation_m(),
            })
        })
        .collect();
    serde_json::json!({ "grids": list })
}

/// How to voxelise a volume.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VolumeOptions {
    /// Voxel size, metres (`None`: the phenomenon's default, 1 cm for the flame, 1 km for
    /// the aurora).
    pub voxel_m: Option<f64>,
    /// Most bytes a frame's volume may take (what the memory budget leaves beside the
    /// simulation); `None`: no limit. A frame that would need more is refused before
    /// its grids are made.
    pub max_bytes: Option<u64>,
}

impl VolumeOptions {
    /// `need` bytes if they are within [`VolumeOptions::max_bytes`], else why not.
    pub fn admit(&self, need: u64, voxel: &str) -> Result<u64, String> {
        match self.max_bytes {
            Some(max) if need > max => Err(format!(
                "a volume of {voxel} voxels needs up to {} of memory, more than the budget leaves ({}): use larger voxels or a larger memory budget",
                crate::budget::gib(need),
                crate::budget::gib(max)
            )),
            _ => Ok(need),
        }
    }
}

/// The steps of composing a shot of several phenomena ([`crate::shot`]), in order: every
/// phenomenon is asked at every pass and acts at those its light belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pass {
    /// Before any light: a phenomenon says where it is ([`Stage::medium_depth_m`]).
    Place,
    /// Light from beyond everything in the shot (the aurora, ~100 km up, and the stars).
    Sky,
    /// Opaque surfaces over what is beyond them ([`Stage::depth`]).
    Surfaces,
    /// Points of light between the surfaces and the emissive medium (seen through it).
    Behind,
    /// The emissive medium (the flame): its light added, what is behind it refracted.
    Media,
    /// Points of light in front of the medium.
    Front,
}

impl Stage {
    /// Put `background` behind the image when no phenomenon has yet: the image then
    /// holds only light added over black, so the background is added to it.
    pub fn under(&mut self, background: &phenomena_core::image::Frame) {
        if self.backdrop {
            return;
        }
        self.backdrop = true;
        add_light(&mut self.image, background);
    }
}

/// Add `light` to `into`, pixel by pixel (frames of one size).
pub(crate) fn add_light(into: &mut phenomena_core::image::Frame, light: &phenomena_core::image::Frame) {
    for (out, add) in into.planes_mut().into_iter().zip([&light.c0, &light.c1, &light.c2]) {
        for (o, a) in out.data_mut().iter_mut().zip(add.data()) {
            *o += a;
        }
    }
}

/// Every pass in order.
pub const PASSES: [Pass; 6] =
    [Pass::Place, Pass::Sky, Pass::Surfaces, Pass::Behind, Pass::Media, Pass::Front];

/// What composing a shot's frame has made so far, far to near; each phenomenon reads it
/// and adds its light at its [`Pass`]es.
pub struct Stage {
    /// What is seen so far (linear RGB).
    pub image: phenomena_core::image::Frame,
    /// Distance along the view direction to the nearest opaque surface per pixel,
    /// metres (row-major; +∞ where none).
    pub depth: Vec<f32>,
    /// Whether a phenomenon has put its background behind the image yet (the farthest
    /// one does: the aurora's night sky, else the snow's sky, the dust's or the flame's).
    pub backdrop: bool,
    /// Distance of the emissive medium along the view direction, metres (+∞: none).
    pub medium_depth_m: f32,
    /// Lights the phenomena give off for the others' surfaces (a fire): position,
    /// metres, and radiant intensity (the frame's radiance times square metres).
    pub lights: Vec<(glam::Vec3, glam::Vec3)>,
    /// Each phenomenon's own light as it reaches the camera (an EXR layer each:
    /// `<name>.R`, `.G`, `.B`, and `.A` where given).
    pub layers: Vec<(&'static str, phenomena_core::image::Frame, Option<phenomena_core::image::Plane>)>,
    /// Each phenomenon's own extra images (the aurora's lines), by channel name.
    pub extra: Vec<(String, phenomena_core::image::Plane)>,
}

impl Stage {
    /// An empty stage: black, no surfaces, no medium.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            image: phenomena_core::image::Frame::new(width, height),
            depth: vec![f32::INFINITY; width * height],
            backdrop: false,
            medium_depth_m: f32::INFINITY,
            lights: Vec::new(),
            layers: Vec::new(),
            extra: Vec::new(),
        }
    }
}

/// One phenomenon's scene file.
pub trait Phenomenon:
    Serialize + DeserializeOwned + Default + Clone + PartialEq + Debug + Send + Sync + 'static
{
    /// The table name (`flame`): a scene file holding `[flame]` is a flame scene.
    const NAME: &'static str;
    /// One line on what it is and which paper it follows.
    const ABOUT: &'static str;
    /// The views it can draw; the first is the default.
    const VIEWS: &'static [View];
    /// The data it can export.
    const EXPORTS: &'static [ExportKind] = &[];
    /// What it can give besides images, which some output formats need
    /// ([`crate::format::OutputFormat::needs`]).
    const CAN: &'static [Capability] = &[];
    /// A commented scene file holding every default (`phenomena new`).
    const STARTER: &'static str;
    /// Whether this is the composition of the others (a [`crate::shot`]): a file with
    /// two or more phenomenon tables is read as it.
    const COMPOSITE: bool = false;

    /// The simulation.
    type Sim: Simulation + Sync;
    /// Its renderer.
    type Renderer: Renderer<Self::Sim>;
    /// The scene's files, read and decoded (a mesh, a background image).
    type Loaded: Send;

    /// The `[scene]` table.
    fn settings(&self) -> &SceneSettings;
    /// The `[scene]` table, to change.
    fn settings_mut(&mut self) -> &mut SceneSettings;
    /// Every problem of the phenomenon's own tables, with paths from the file's root
    /// (`flame.sph.support_radius_m`, `render.view`).
    fn validate(&self, issues: &mut Issues);
    /// The view drawn (one of [`Phenomenon::VIEWS`]).
    fn view(&self) -> &'static str;
    /// Draw `view` (one of [`Phenomenon::VIEWS`]; others are refused by the caller).
    fn set_view(&mut self, view: &str);
    /// Read the scene's files through `assets` (the only way a scene reads a file).
    fn load(&self, assets: &Assets) -> Result<Self::Loaded, BuildError>;
    /// Every check the simulation and renderer make before they start, without
    /// building them (quick: what `validate` runs); warnings for the user.
    fn check(&self, loaded: &Self::Loaded) -> Result<Vec<String>, BuildError>;
    /// Memory and work, estimated from the settings and the files read.
    fn estimate(&self, loaded: &Self::Loaded) -> Estimate;
    /// Build the simulation and its renderer at the scene's size.
    fn build(&self, loaded: Self::Loaded) -> Result<Built<Self>, BuildError>;

    /// A hash of the files the simulation is built from (the snow's mesh), for
    /// checkpoint identities ([`crate::checkpoint::identity`]); `None` when the
    /// simulation reads none (images only change how frames are drawn).
    fn files_identity(_loaded: &Self::Loaded) -> Option<u64> {
        None
    }

    /// What a checkpoint's identity is made of: the tables the simulation is built from
    /// (by default the file without `[scene]` and `[render]`).
    fn simulation_tables(&self) -> Value {
        crate::checkpoint::simulation_tables(self)
    }

    /// Add this phenomenon's light to a shot at `pass` ([`Pass`]); phenomena that cannot
    /// be part of a shot draw nothing.
    fn compose(_sim: &Self::Sim, _renderer: &mut Self::Renderer, _pass: Pass, _stage: &mut Stage) {}

    /// Seconds of simulated time per frame (a flipbook's playback rate).
    fn frame_time_s(&self) -> f64;

    /// Why a frame's image depends on the frames rendered before it, if it does (the
    /// aurora's afterglow). Such a scene's frames are exact only when every frame from
    /// the first is rendered: the runner renders every frame it simulates, and a
    /// checkpoint (which holds only the simulation) cannot start it.
    fn render_memory(&self) -> Option<&'static str> {
        None
    }

    /// Draw the phenomenon's light alone over black, for flipbooks (called only when
    /// [`Phenomenon::CAN`] holds [`Capability::EmissionOnly`]).
    fn emission_only(&mut self) {}

    /// The current state as OpenVDB grids (the `vdb` format), encoded into `out`
    /// (cleared first, by [`encode_volume`]), returning their manifest; `scratch` is the
    /// phenomenon's to keep buffers in between frames.
    fn volume(
        _built: &Built<Self>,
        _options: &VolumeOptions,
        _scratch: &mut Scratch,
        _out: &mut VolumeOut<'_>,
    ) -> Result<Value, String> {
        Err(format!("{} scenes write no volumes", Self::NAME))
    }

    /// Bytes a volume of the current state takes at `options` (an upper bound; where
    /// the state grows, of its largest), checking the voxel size: called before the
    /// first frame, so a render whose volumes cannot fit is refused before it starts.
    fn volume_bytes(_built: &Built<Self>, _options: &VolumeOptions) -> Result<u64, String> {
        Ok(0)
    }

    /// The current particles as a point cache (the `ply` format).
    fn points(_built: &Built<Self>) -> Result<PointCache, String> {
        Err(format!("{} scenes write no particle caches", Self::NAME))
    }

    /// The last rendered frame's motion vectors (a flipbook's `--motion`; called only
    /// when [`Phenomenon::CAN`] holds [`Capability::Motion`]).
    fn motion(_built: &Built<Self>) -> Result<MotionVectors, String> {
        Err(format!("{} scenes have no motion vectors", Self::NAME))
    }

    /// Give the simulation and renderer a clock for their timing breakdowns.
    fn set_clock(_built: &mut Built<Self>, _clock: &SharedClock) {}
    /// Before a render: `Some(frame)` asks for a fast preview of frame `frame` (the
    /// studio), `None` for the full render.
    fn before_render(_built: &mut Built<Self>, _preview: Option<u32>) {}
    /// The renderer's timing breakdown of the last render, if it has one.
    fn render_detail(_built: &Built<Self>) -> Option<Value> {
        None
    }
    /// Export `name` ([`Phenomenon::EXPORTS`]) in `format`.
    fn export(_built: &Built<Self>, name: &str, _format: &str) -> Result<Exported, String> {
        Err(format!("{} scenes export nothing called `{name}`", Self::NAME))
    }
    /// Make `spare` a copy of `sim` that steps as `sim` would (made the first time), and
    /// say so: the next frame is then stepped on it while this frame renders, and the
    /// next step takes it. `false` (the default): the phenomenon steps after its render.
    /// Worth it where part of the step runs on one thread while the render keeps every
    /// thread busy (the snow's flood); the frames are the same either way.
    fn sync_spare(_sim: &Self::Sim, _spare: &mut Option<Self::Sim>) -> bool {
        false
    }
    /// Bytes the spare of [`Phenomenon::sync_spare`] takes (0: none), charged to a
    /// scene of this phenomenon alone (a shot steps its parts without one).
    fn spare_bytes(&self, _loaded: &Self::Loaded) -> u64 {
        0
    }
    /// Change parameter `path` of the running simulation to `value` without a restart.
    fn steer(_built: &mut Built<Self>, _path: &str, _value: &Value) -> Steer {
        Steer::NotLive
    }
}

#[cfg(test)]
mod tests {
    use phenomena_core::vdb::{AnyGrid, Grid, GridClass, Transform};

    use super::*;

    #[test]
    fn leaves_hold_the_voxels_where_openvdb_reads_them_and_the_same_manifest() {
        let transform = Transform::new(0.5, [1.0, 2.0, 3.0]).unwrap();
        let mut density = Grid::<f32>::new("density", transform, GridClass::FogVolume);
        density.set([1, 2, 3], 4.0);
        density.set([-1, 9, 0], 7.0);
        let mut velocity = Grid::<[f32; 3]>::new("velocity", transform, GridClass::Unknown);
        velocity.set([0, 0, 1], [1.0, 2.0, 3.0]);
        let grids = [AnyGrid::from(&density), AnyGrid::from(&velocity)];
        let (mut bytes, mut leaves) = (Vec::new(), Vec::new());
        let manifest = encode_volume(&grids, &mut VolumeOut::Vdb(&mut bytes));
        assert_eq!(encode_volume(&grids, &mut VolumeOut::Leaves(&mut leaves)), manifest);
        assert!(!bytes.is_empty());
        let [d, v] = &leaves[..] else { panic!("two grids, got {}", leaves.len()) };
        assert_eq!(
            (d.name.as_str(), d.class, d.components, d.voxel_size_m),
            ("density", "fog volume", 1, 0.5)
        );
        assert_eq!(d.translation_m, [1.0, 2.0, 3.0]);
        assert_eq!(d.values.len(), 512 * d.origins.len());
        // Each set voxel at (origin leaf, i·64 + j·8 + k); nothing else is lit.
        for (ijk, want) in [([1, 2, 3], 4.0), ([-1, 9, 0], 7.0)] {
            let origin = Grid::<f32>::leaf_origin(ijk);
            let leaf = d.origins.iter().position(|&o| o == origin).expect("its leaf is listed");
            assert_eq!(d.values[leaf * 512 + Grid::<f32>::leaf_offset(ijk)], want);
        }
        assert_eq!(d.values.iter().filter(|&&x| x != 0.0).count(), 2);
        assert_eq!((v.components, v.origins.as_slice()), (3, &[[0, 0, 0]][..]));
        assert_eq!(v.values[3..6], [1.0, 2.0, 3.0]);
    }
}
