//! Snow maps and their evolution (§2.1-2.4): the snow-possible region of each polygon
//! group from its top-down z-buffer, the snow probability from depth maps of many
//! snowfall directions, accumulation S_a(T) = ∫ P_a M(t) dt, stabilisation at the angle
//! of repose and falling onto lower maps.

use crate::raster::{Cull, DepthBuffer, RasterError, Rasterizer, rasterize};
use glam::{Vec2, Vec3};
use phenomena_core::camera::{Camera, CameraView, Projection};
use phenomena_core::rng::{Purpose, Stream};
use phenomena_core::validate::{InvalidConfig, Issue, Issues};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wide::{f32x8, i32x8};

use crate::groups::{Groups, auto_groups, groups_by_object};
use crate::mesh::Mesh;

const DIRECTIONS: Purpose = Purpose::named("snow.directions");

/// Parameters of the snow model (`[snow]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SnowConfig {
    /// Texels along each side of the snow maps (the paper: 100-200).
    pub map_resolution: u32,
    /// Free border around the scene's footprint, m.
    pub margin_m: f32,
    /// Snowfall directions for the probability (§2.2.2; the paper used 5).
    pub directions: u32,
    /// Mean tilt of the snowfall from the vertical towards +x and +z, degrees (wind).
    pub main_tilt_deg: [f32; 2],
    /// Standard deviation of the tilt about the mean, degrees (0: all straight down the
    /// main direction, a sharp shadow).
    pub spread_deg: f32,
    /// Pixels along each side of the depth map of each direction.
    pub shadow_resolution: u32,
    /// Snowfall rate M(t), cm of snow depth per hour.
    pub rate_cm_per_h: f32,
    /// Simulated time per step, hours.
    pub time_step_h: f32,
    /// Angle of repose, degrees (the paper's experiments: 45; fresh dry snow 40-50).
    pub repose_deg: f32,
    /// How snow is moved to rest at the angle of repose (§2.4).
    pub stabiliser: Stabiliser,
    /// Most passes of the local rule per step (all of them with `stabiliser =
    /// "relaxation"`, the final check's with `"flood"`).
    pub max_passes: u32,
    /// Group per object instead of the automatic grouping (one entry per object).
    pub object_groups: Option<Vec<u32>>,
    /// Recompute the probability every this many steps, with the snow lying so far as an
    /// occluder (0: once at the start, as the paper holds P_a constant while animating).
    pub probability_every_steps: u32,
}

impl Default for SnowConfig {
    fn default() -> Self {
        Self {
            map_resolution: 128,
            margin_m: 0.1,
            directions: 32,
            main_tilt_deg: [0.0, 0.0],
            spread_deg: 10.0,
            shadow_resolution: 256,
            rate_cm_per_h: 2.0,
            time_step_h: 0.1,
            repose_deg: 45.0,
            stabiliser: Stabiliser::Flood,
            max_passes: 4096,
            object_groups: None,
            probability_every_steps: 0,
        }
    }
}

impl SnowConfig {
    /// Every problem, with the field, the value and the valid range.
    pub fn validate(&self) -> Result<(), Vec<Issue>> {
        let mut i = Issues::default();
        i.count("map_resolution", u64::from(self.map_resolution), 4..=4096);
        i.range("margin_m", self.margin_m, 0.0..=1e4);
        i.count("directions", u64::from(self.directions), 1..=4096);
        for (k, t) in self.main_tilt_deg.iter().enumerate() {
            i.range(&format!("main_tilt_deg[{k}]"), *t, -80.0..=80.0);
        }
        i.range("spread_deg", self.spread_deg, 0.0..=45.0);
        i.count("shadow_resolution", u64::from(self.shadow_resolution), 8..=8192);
        i.range("rate_cm_per_h", self.rate_cm_per_h, 0.0..=1000.0);
        i.range_open_low("time_step_h", self.time_step_h, 0.0, 1000.0);
        i.range_open_low("repose_deg", self.repose_deg, 0.0, 89.0);
        i.count("max_passes", u64::from(self.max_passes), 1..=1_000_000);
        i.into_result()
    }
}

/// How the snow is brought to rest at the angle of repose after each accumulation (§2.4).
/// Both keep §2.4.1's rule (no snow surface steeper than the repose towards any of its 4
/// neighbours; what must go moves downhill) and §2.4.2's (past a region's edge it falls
/// to the highest lower map, or off the scene), and every gram of snow.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stabiliser {
    /// The surplus over the highest stable surface under the snow, found bottom-up in one
    /// ordered sweep, carried downhill in height order and settled by priority floods
    /// (`flood.rs`); then the paper's local rule checks the result. The work follows the
    /// texels that change, not the depth of the snow.
    #[default]
    Flood,
    /// The paper's local rule of Fig 6 (§2.4.1) swept over the maps until no slope
    /// exceeds the repose: each steep texel gives snow to its steep neighbours. The
    /// reference: its passes grow with the length of the slopes and the depth.
    Relaxation,
}

/// Why a snow simulation cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum SnowError {
    /// Parameters out of range.
    #[error(transparent)]
    Invalid(#[from] InvalidConfig),
    /// Nothing to put snow on.
    #[error("the scene has no upward-facing triangle to hold snow")]
    NoSnowSurface,
    /// The scene's footprint has no area.
    #[error("the scene's footprint has zero area")]
    ZeroArea,
    /// The object groups do not cover the objects.
    #[error("object_groups has {given} entries for {objects} objects")]
    ObjectGroups {
        /// Entries given.
        given: usize,
        /// Objects in the scene.
        objects: usize,
    },
    /// The rasteriser refused.
    #[error(transparent)]
    Raster(#[from] RasterError),
    /// A saved state does not fit this simulation.
    #[error("the saved state does not fit this simulation: {0}")]
    State(String),
}

/// The square grid shared by all snow maps: texel (i, j) is centred at
/// `origin + (i + 0.5, j + 0.5) · texel_m` in (x, z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// Corner (x, z), m.
    pub origin: Vec2,
    /// Texel size, m.
    pub texel_m: f32,
    /// Texels per side.
    pub n: usize,
}

impl Footprint {
    /// Centre of texel (i, j) in (x, z).
    pub fn centre(&self, i: usize, j: usize) -> Vec2 {
        self.origin + (Vec2::new(i as f32, j as f32) + 0.5) * self.texel_m
    }

    /// The top-down camera whose pixels are the texels (image x along +x, image y along
    /// +z), from `above_y`.
    fn top_view(&self, above_y: f32) -> CameraView {
        let side = self.n as f32 * self.texel_m;
        let c = self.origin + Vec2::splat(0.5 * side);
        Camera {
            position: Vec3::new(c.x, above_y, c.y),
            look_at: Vec3::new(c.x, above_y - 1.0, c.y),
            up: Vec3::NEG_Z,
            projection: Projection::Orthographic { height_m: side },
        }
        .view(self.n, self.n)
        .expect("a square grid with positive texels")
    }
}

/// One group's snow map: the height of the surface under each texel (NaN where the group
/// cannot hold snow) and the snow depth on it.
#[derive(Clone, Debug, PartialEq)]
pub struct SnowMap {
    /// Ground height per texel, m (NaN: not snow-possible).
    pub ground_m: Vec<f32>,
    /// Snow depth per texel, m.
    pub snow_m: Vec<f32>,
    /// Snow probability P_a per texel (0 where not snow-possible).
    pub probability: Vec<f32>,
}

impl SnowMap {
    /// Whether texel `k` can hold snow.
    pub fn possible(&self, k: usize) -> bool {
        !self.ground_m[k].is_nan()
    }

    /// Surface height ground + snow at texel `k` (NaN where not possible).
    pub fn surface(&self, k: usize) -> f32 {
        self.ground_m[k] + self.snow_m[k]
    }
}

/// Per-step counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct StepStats {
    /// Snow volume on all maps, m³.
    pub volume_m3: f64,
    /// Snow volume that has left the scene over its edge so far, m³.
    pub fallen_off_m3: f64,
    /// Passes of the local rule this step: all of the relaxation's, or those of the check
    /// after the flood (0 when the flood left nothing steep, as it does).
    pub passes: u32,
    /// Whether the stabilisation met the angle of repose (else it hit `max_passes`).
    pub stable: bool,
    /// Time simulated so far, hours.
    pub time_h: f64,
}

/// The snow cover simulation over one scene.
#[derive(Clone, Debug)]
pub struct SnowSim {
    params: SnowConfig,
    mesh: Mesh,
    groups: Groups,
    footprint: Footprint,
    maps: Vec<SnowMap>,
    directions: Vec<Vec3>,
    /// The scene's triangles for the direction depth maps: those of closed objects
    /// (`Mesh::closed_objects`) first, whose back faces are skipped there.
    casters: Mesh,
    closed_triangles: usize,
    /// Buffers of [`SnowSim::update_probability`], kept between calls.
    exposure: Exposure,
    /// The regions' shapes for the stabilisation, once made (None after `maps_mut`).
    regions: Option<Regions>,
    /// The flood stabilisation's buffers, kept between steps.
    flood: Option<crate::flood::Scratch>,
    /// Visit every texel in every stabilisation pass (the check of the sparse sweep).
    dense_sweeps: bool,
    fallen_off_m3: f64,
    time_h: f64,
    steps: u64,
    top_y: f32,
    /// The seed it was made with (the snow's glitter draws its grains from it).
    seed: u64,
}

/// The polygon groups and footprint of a scene, before any map is drawn.
struct Layout {
    groups: Groups,
    lo: Vec3,
    hi: Vec3,
    extent: f32,
}

impl SnowSim {
    /// Whether [`SnowSim::new`] accepts `mesh` and `params`, without drawing a map or a
    /// depth map: the parameters, the object groups, a surface to hold snow and a
    /// footprint with area (cheap: one pass over the triangles). Gives the number of
    /// snow maps (polygon groups) it would make.
    pub fn check(mesh: &Mesh, params: &SnowConfig) -> Result<usize, SnowError> {
        Self::layout(mesh, params).map(|l| l.groups.count as usize)
    }

    fn layout(mesh: &Mesh, params: &SnowConfig) -> Result<Layout, SnowError> {
        params.validate().map_err(InvalidConfig::from)?;
        let groups = match &params.object_groups {
            Some(og) => {
                let objects = mesh.object.iter().max().map_or(0, |o| *o as usize + 1);
                if og.len() < objects {
                    return Err(SnowError::ObjectGroups { given: og.len(), objects });
                }
                groups_by_object(mesh, og)
            }
            None => auto_groups(mesh),
        };
        if groups.count == 0 {
            return Err(SnowError::NoSnowSurface);
        }
        let (lo, hi) = mesh.bounds().ok_or(SnowError::NoSnowSurface)?;
        let extent = (Vec2::new(hi.x - lo.x, hi.z - lo.z) + 2.0 * params.margin_m).max_element();
        if !(extent > 0.0) {
            return Err(SnowError::ZeroArea);
        }
        Ok(Layout { groups, lo, hi, extent })
    }

    /// Snow maps for `mesh` (cleaned by the caller), with the probability computed once.
    pub fn new(mesh: Mesh, params: SnowConfig, seed: u64) -> Result<Self, SnowError> {
        let Layout { groups, lo, hi, extent } = Self::layout(&mesh, &params)?;
        let n = params.map_resolution as usize;
        let centre = Vec2::new(0.5 * (lo.x + hi.x), 0.5 * (lo.z + hi.z));
        let footprint =
            Footprint { origin: centre - Vec2::splat(0.5 * extent), texel_m: extent / n as f32, n };
        let top_y = hi.y + 1.0;
        let view = footprint.top_view(top_y);
        let mut maps = Vec::with_capacity(groups.count as usize);
        for g in 0..groups.count {
            let tris: Vec<[Vec3; 3]> =
                (0..mesh.len()).filter(|&t| groups.group[t] == Some(g)).map(|t| mesh.triangles[t]).collect();
            // Back faces (seen from above) excluded: the region where the group faces up.
            let (buf, _) = rasterize(&view, &tris, None, Cull::Back)?;
            let ground_m =
                buf.depth().iter().map(|&d| if d.is_finite() { top_y - d } else { f32::NAN }).collect();
            maps.push(SnowMap { ground_m, snow_m: vec![0.0; n * n], probability: vec![0.0; n * n] });
        }
        let directions = snowfall_directions(&params, seed);
        let closed = mesh.closed_objects();
        let is_closed = |t: usize| closed[mesh.object[t] as usize];
        let mut casters = Mesh::default();
        for t in (0..mesh.len()).filter(|&t| is_closed(t)).chain((0..mesh.len()).filter(|&t| !is_closed(t))) {
            casters.push_object(&[mesh.triangles[t]], mesh.object[t]);
        }
        let closed_triangles = (0..mesh.len()).filter(|&t| is_closed(t)).count();
        let mut sim = Self {
            params,
            mesh,
            groups,
            footprint,
            maps,
            directions,
            casters,
            closed_triangles,
            exposure: Exposure::default(),
            regions: None,
            flood: None,
            dense_sweeps: false,
            fallen_off_m3: 0.0,
            time_h: 0.0,
            steps: 0,
            top_y,
            seed,
        };
        sim.update_probability()?;
        Ok(sim)
    }

    /// The parameters.
    pub fn config(&self) -> &SnowConfig {
        &self.params
    }

    /// The scene.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// The polygon groups.
    pub fn groups(&self) -> &Groups {
        &self.groups
    }

    /// The grid of the maps.
    pub fn footprint(&self) -> Footprint {
        self.footprint
    }

    /// The seed the simulation was made with.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The snow maps, one per group.
    pub fn maps(&self) -> &[SnowMap] {
        &self.maps
    }

    /// The snow maps, to change (e.g. to start from lying snow); call
    /// [`SnowSim::update_probability`] afterwards if the change should shade.
    pub fn maps_mut(&mut self) -> &mut [SnowMap] {
        // The grounds may change: find the snow-possible texels again.
        self.exposure.laid_out = false;
        self.regions = None;
        &mut self.maps
    }

    /// Visit every texel in every stabilisation pass instead of only those next to a
    /// change: the same result, slower; for the test that the sparse sweep skips only
    /// texels that cannot move.
    #[doc(hidden)]
    pub fn set_dense_sweeps(&mut self, on: bool) {
        self.dense_sweeps = on;
    }

    /// What the flood stabilisation did in the last step (zero with the relaxation).
    #[doc(hidden)]
    pub fn flood_counts(&self) -> crate::flood::Counts {
        self.flood.as_ref().map(|f| f.counts).unwrap_or_default()
    }

    /// Steps taken so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The snowfall directions (unit vectors pointing the way the snow moves, down).
    pub fn directions(&self) -> &[Vec3] {
        &self.directions
    }

    /// Recompute the snow probability of every texel (§2.2.3): for each direction a depth
    /// map of the whole scene and of the snow lying on it, seen along the direction; a
    /// texel is exposed when its surface point (ground + snow) is not behind that depth
    /// (within a bias of two depth-map pixels); P_a is the share of exposed directions.
    pub fn update_probability(&mut self) -> Result<(), SnowError> {
        let mut exposure = std::mem::take(&mut self.exposure);
        let counted = self.count_exposure(&mut exposure, false);
        if counted.is_ok() {
            let k = self.directions.len().max(1) as f32;
            let n = self.footprint.n;
            let mut out: Vec<&mut [f32]> = self
                .maps
                .iter_mut()
                .map(|m| {
                    m.probability.clear();
                    m.probability.resize(n * n, 0.0);
                    m.probability.as_mut_slice()
                })
                .collect();
            exposure.scatter(&mut out, |i| exposure.exposed(i) / k);
        }
        self.exposure = exposure;
        counted
    }

    /// [`Exposure::count`] over this scene's occluders (closed objects' back faces
    /// skipped), maps and directions.
    fn count_exposure(&self, exposure: &mut Exposure, silhouettes: bool) -> Result<(), SnowError> {
        let cull = Cull::BackAmongFirst(self.closed_triangles);
        let (maps, fp, dirs, params) = (&self.maps, &self.footprint, &self.directions, &self.params);
        exposure.count(&self.occluders(), cull, maps, fp, dirs, params, silhouettes)
    }

    /// For every texel, in how many directions its depth-map sample lies next to a
    /// silhouette: over the sample's depth-map pixel and its 4 neighbours the depth spans
    /// more than 10 pixel widths (an occluder's outline, or a surface seen edge-on). In
    /// those directions the shadow-map test depends on where inside a pixel the outline
    /// runs, which a ray cast resolves exactly.
    pub fn silhouette_directions(&self) -> Result<Vec<Vec<u16>>, SnowError> {
        let mut exposure = Exposure::default();
        self.count_exposure(&mut exposure, true)?;
        let n = self.footprint.n;
        let mut edges: Vec<Vec<u16>> = self.maps.iter().map(|_| vec![0; n * n]).collect();
        let mut out: Vec<&mut [u16]> = edges.iter_mut().map(|e| e.as_mut_slice()).collect();
        exposure.scatter(&mut out, |i| exposure.workers[0].near_outline[i]);
        Ok(edges)
    }

    /// The scene's triangles plus those of the snow on it (so snow can occlude): first
    /// the triangles of closed objects, then the other objects', then the snow's; the
    /// scene's alone, borrowed, while no snow lies anywhere.
    pub fn occluders(&self) -> std::borrow::Cow<'_, Mesh> {
        let min = crate::export::MIN_DEPTH_M;
        // (Blocks without an early exit inside, so the comparisons run in vector lanes.)
        let snowy = |m: &SnowMap| m.snow_m.chunks(256).any(|b| b.iter().fold(false, |a, &s| a | (s > min)));
        if !self.maps.iter().any(snowy) {
            return std::borrow::Cow::Borrowed(&self.casters);
        }
        let snow = crate::export::snow_mesh(self);
        let mut all = self.casters.clone();
        let tris: Vec<[Vec3; 3]> =
            snow.indices.chunks_exact(3).map(|t| [0, 1, 2].map(|k| snow.positions[t[k] as usize])).collect();
        all.push_object(&tris, u32::MAX);
        std::borrow::Cow::Owned(all)
    }

    /// Advance one time step: accumulate (eq 1), then stabilise and let snow fall.
    pub fn step(&mut self) -> Result<StepStats, SnowError> {
        let dt = f64::from(self.params.time_step_h);
        let m = f64::from(self.params.rate_cm_per_h) * 0.01;
        let add = (m * dt) as f32;
        for map in &mut self.maps {
            map.snow_m.par_iter_mut().zip(&map.probability).for_each(|(s, &p)| *s += p * add);
        }
        self.time_h += dt;
        let (passes, stable) = self.stabilise();
        self.steps += 1;
        let every = u64::from(self.params.probability_every_steps);
        if every > 0 && self.steps.is_multiple_of(every) {
            self.update_probability()?;
        }
        Ok(StepStats {
            volume_m3: self.volume_m3(),
            fallen_off_m3: self.fallen_off_m3,
            passes,
            stable,
            time_h: self.time_h,
        })
    }

    /// Simulated time, hours.
    pub fn time_h(&self) -> f64 {
        self.time_h
    }

    /// Snow volume on all maps, m³.
    pub fn volume_m3(&self) -> f64 {
        let t2 = f64::from(self.footprint.texel_m).powi(2);
        self.maps.iter().map(|m| m.snow_m.iter().map(|&s| f64::from(s)).sum::<f64>() * t2).sum()
    }

    /// Snow volume that left the scene so far, m³.
    pub fn fallen_off_m3(&self) -> f64 {
        self.fallen_off_m3
    }

    /// Largest slope excess over tan(repose) of any snow-covered texel towards a
    /// neighbour it could give snow to (≤ 0 when stable).
    pub fn max_slope_excess(&self) -> f32 {
        let tan = self.params.repose_deg.to_radians().tan();
        let t = self.footprint.texel_m;
        let mut worst = f32::MIN;
        for (mi, map) in self.maps.iter().enumerate() {
            for k in 0..map.snow_m.len() {
                if map.snow_m[k] <= 0.0 {
                    continue;
                }
                for (_, h_n) in self.neighbours(mi, k, tan * t) {
                    worst = worst.max((map.surface(k) - h_n) / t - tan);
                }
            }
        }
        worst
    }

    /// [`neighbours`] on this simulation's maps.
    fn neighbours(&self, mi: usize, k: usize, rise: f32) -> impl Iterator<Item = (Target, f32)> + '_ {
        neighbours(&self.maps, self.footprint.n, mi, k, rise)
    }

    /// Bring the snow to rest (§2.4) by the configured [`Stabiliser`]. Returns the passes
    /// of the local rule and whether the repose was met.
    fn stabilise(&mut self) -> (u32, bool) {
        let n = self.footprint.n;
        let texels = n * n;
        // The regions' shapes, kept between steps (the grounds change only through
        // `maps_mut`, which drops them).
        let regions = self.regions.take().unwrap_or_else(|| Regions::new(&self.maps, n));
        let mut active: Vec<Bits> = self.maps.iter().map(|_| Bits::new(texels)).collect();
        // The flood numbers every texel of every map in 31 bits; past that (far past any
        // memory budget) the relaxation does the work.
        let flood = self.params.stabiliser == Stabiliser::Flood
            && crate::flood::Scratch::fits(self.maps.len(), texels);
        if flood {
            let mut scratch = self.flood.take().unwrap_or_default();
            let rise = self.params.repose_deg.to_radians().tan() * self.footprint.texel_m;
            let small = self.params.rate_cm_per_h * 0.01 * self.params.time_step_h;
            let tol = repose_tolerance(self.footprint);
            let fallen = scratch.settle(&mut self.maps, &regions, n, rise, tol, small);
            self.fallen_off_m3 += fallen * f64::from(self.footprint.texel_m).powi(2);
            // The local rule then looks at every texel that changed and at the other maps'
            // texels next to it (a gain can make only the texel itself steep; what a loss
            // makes steep uphill, the flood's floor has settled); it finds the flood's
            // result stable (test `the_flood_leaves_nothing_for_the_local_rule`).
            let mut spare: Vec<Bits> = self.maps.iter().map(|_| Bits::new(texels)).collect();
            for &node in scratch.changed() {
                let (mi, k) = (node as usize / texels, node as usize % texels);
                mark(&regions, n, &mut active, &mut spare, mi, k, false);
            }
            self.flood = Some(scratch);
        } else {
            for (b, m) in active.iter_mut().zip(&self.maps) {
                for (k, &s) in m.snow_m.iter().enumerate() {
                    if s > 0.0 {
                        b.set(k);
                    }
                }
            }
        }
        let result = self.relax(&regions, active);
        self.regions = Some(regions);
        result
    }

    /// The paper's local rule until no slope exceeds the angle of repose (§2.4.1, Fig 6): a
    /// snow-covered texel whose slope to some of its 4 neighbours exceeds the repose gives
    /// half the largest excess (the amount that levels a pair to the repose) times an
    /// over-relaxation factor `OVER_RELAXATION` (at most all its snow), in equal shares,
    /// to those neighbours; past the edge of its region the snow falls to the highest
    /// lower map or off the scene (§2.4.2). Texels are visited in place, maps in order and
    /// texels alternately forwards and backwards, so an avalanche runs across a map in one
    /// pass (a Gauss-Seidel sweep; sequential, hence the same for any thread count). A
    /// pass visits only the texels a change may have made steep (bit sets, starting from
    /// `active`), in the order of the full sweep: the result is bit for bit that of
    /// visiting every texel (test `the_sparse_stabilisation_equals_visiting_every_texel`),
    /// the cost that of the texels that move. Returns the passes and whether the repose
    /// was met.
    fn relax(&mut self, regions: &Regions, mut active: Vec<Bits>) -> (u32, bool) {
        let tan = self.params.repose_deg.to_radians().tan();
        let t = self.footprint.texel_m;
        let tol = repose_tolerance(self.footprint);
        let n = self.footprint.n;
        let texels = n * n;
        let maps = self.maps.len();
        // Texels to look at, one bit each: `active` at first, then those next to a
        // change. The sweep visits only set bits, in the same order as a sweep over every
        // texel, and a texel not marked cannot move snow (neither it nor a neighbour
        // changed since it was last found stable), so the result is that of the full
        // sweep while the cost follows the texels that move.
        if self.dense_sweeps {
            active.iter_mut().for_each(|b| b.fill(texels));
        }
        let mut next: Vec<Bits> = (0..maps).map(|_| Bits::new(texels)).collect();
        let repose = Repose { rise_m: tan * t, tolerance_m: tol };
        for pass in 0..self.params.max_passes {
            let mut moved = false;
            for b in &mut next {
                b.clear();
            }
            for mi in 0..maps {
                moved |= self.sweep(regions, &mut active, &mut next, mi, pass % 2 == 0, repose);
            }
            if !moved {
                return (pass, true);
            }
            std::mem::swap(&mut active, &mut next);
            if self.dense_sweeps {
                active.iter_mut().for_each(|b| b.fill(texels));
            }
        }
        (self.params.max_passes, false)
    }

    /// One pass of the local rule (§2.4.1) over the marked texels of map `mi`, `forward`
    /// or backwards: each snow-covered texel with steep neighbours gives them equal shares
    /// of half the largest excess times `OVER_RELAXATION` (at most all its snow); snow
    /// past the scene's edge is counted as fallen off. The texels a change may have made
    /// steep are marked in `active` (seen later in this pass: a Gauss-Seidel sweep) and
    /// `next`. Returns whether any snow moved.
    fn sweep(
        &mut self,
        regions: &Regions,
        active: &mut [Bits],
        next: &mut [Bits],
        mi: usize,
        forward: bool,
        repose: Repose,
    ) -> bool {
        let n = self.footprint.n;
        let t = self.footprint.texel_m;
        let mut moved = false;
        let mut cursor = if forward { 0 } else { n * n };
        loop {
            // The next marked texel in sweep order (marks made while visiting are seen).
            let found = if forward { active[mi].next_from(cursor) } else { active[mi].prev_before(cursor) };
            let Some(k) = found else { break };
            cursor = if forward { k + 1 } else { k };
            let s = self.maps[mi].snow_m[k];
            if !(s > 0.0) {
                continue;
            }
            let steep = self.steep_neighbours(regions, mi, k, repose);
            if steep.count == 0 {
                continue;
            }
            moved = true;
            let share = (OVER_RELAXATION * 0.5 * steep.largest_m).min(s) / steep.count as f32;
            for &(target, _) in &steep.to[..steep.count] {
                match target {
                    Target::Map(o, nk) => {
                        self.maps[o as usize].snow_m[nk as usize] += share;
                        // Later texels of this pass and all of the next see it.
                        mark(regions, n, active, next, o as usize, nk as usize, false);
                    }
                    Target::Off => self.fallen_off_m3 += f64::from(share) * f64::from(t) * f64::from(t),
                }
            }
            let left = &mut self.maps[mi].snow_m[k];
            *left = (*left - share * steep.count as f32).max(0.0);
            mark(regions, n, active, next, mi, k, true);
        }
        moved
    }

    /// The neighbours of texel `k` of map `mi` that lie lower than the repose allows, in
    /// [`neighbours`]' order, with the excess of each drop over the repose.
    #[inline]
    fn steep_neighbours(&self, regions: &Regions, mi: usize, k: usize, repose: Repose) -> Steep {
        let n = self.footprint.n;
        let map = &self.maps[mi];
        let h = map.surface(k);
        let mut steep = Steep { to: [(Target::Off, 0.0f32); 4], count: 0, largest_m: 0.0 };
        if regions.inner[mi].get(k) {
            // All four neighbours in this map's region: the common case, in `neighbours`'
            // order without its edge cases.
            for nk in [k - n, k + 1, k + n, k - 1] {
                steep.consider(Target::Map(mi as u32, nk as u32), h, map.surface(nk), repose);
            }
        } else {
            for (target, h_n) in self.neighbours(mi, k, repose.rise_m) {
                steep.consider(target, h, h_n, repose);
            }
        }
        steep
    }

    /// Highest point of the scene plus a metre: where the top-down camera sits.
    pub fn top_y(&self) -> f32 {
        self.top_y
    }
}

/// The four neighbours of texel `k` of map `mi`: where snow would go and the height
/// it is compared with. Inside the map's region: the neighbour's surface. Past the
/// region's edge (or the grid's): the edge's height, [`edge_height`] (snow stands up to
/// the repose slope at an edge), and the destination is the highest lower map at that
/// texel, or off the scene.
/// `rise` is tan(repose) times the texel size, m; the maps share an `n`×`n` grid.
pub(crate) fn neighbours(
    maps: &[SnowMap],
    n: usize,
    mi: usize,
    k: usize,
    rise: f32,
) -> impl Iterator<Item = (Target, f32)> + '_ {
    let (i, j) = (k % n, k / n);
    let map = &maps[mi];
    let h = map.surface(k);
    [(0i64, -1i64), (1, 0), (0, 1), (-1, 0)].into_iter().map(move |(dx, dz)| {
        let (ni, nj) = (i as i64 + dx, j as i64 + dz);
        if ni < 0 || nj < 0 || ni >= n as i64 || nj >= n as i64 {
            return (Target::Off, edge_height(map, n, (i, j), (dx, dz)));
        }
        let nk = nj as usize * n + ni as usize;
        if map.possible(nk) {
            return (Target::Map(mi as u32, nk as u32), map.surface(nk));
        }
        // Another group's region continuing this one: a surface split between two
        // maps (a ground square whose two triangles fell into different groups), its
        // ground within the repose rise of this texel's. The two are one surface and
        // the slope is measured to the other's snow surface, higher or lower.
        // (Before, a neighbour a little higher than this texel was not "lower", the
        // texel measured to its own ground, and snow deeper than the rise fell off
        // the scene along the join: a V-shaped trench along the ground's diagonal,
        // found on the yard scene.)
        let g = map.ground_m[k];
        let joined = maps
            .iter()
            .enumerate()
            .filter(|(o, m)| *o != mi && m.possible(nk) && (m.ground_m[nk] - g).abs() <= rise)
            .min_by(|a, b| {
                let (da, db) = ((a.1.ground_m[nk] - g).abs(), (b.1.ground_m[nk] - g).abs());
                da.total_cmp(&db).then(a.0.cmp(&b.0))
            });
        if let Some((o, m)) = joined {
            return (Target::Map(o as u32, nk as u32), m.surface(nk));
        }
        // Falling (§2.4.2): "among the maps with a snow-possible region lower than the
        // source at that point, the highest": chosen by its ground, below the source's
        // surface. Its snow may stand higher than the source: the snow is walled in there
        // and does not move. (Chosen by snow surface before, a texel whose neighbouring
        // pile had risen above it found no lower map and sent its snow off the scene from
        // the middle of the yard, under the bench.)
        let lower = maps
            .iter()
            .enumerate()
            .filter(|(o, m)| *o != mi && m.possible(nk) && m.ground_m[nk] < h)
            .max_by(|a, b| a.1.ground_m[nk].total_cmp(&b.1.ground_m[nk]).then(b.0.cmp(&a.0)));
        // The height the slope is measured to: the edge's own ground (a cliff: the
        // pile at the edge may not stand more than the repose above it), or the lower
        // map's snow surface where that is higher (a neighbouring group at about the
        // same height: the two behave as one surface; measuring to the own ground
        // there sent snow back and forth between the two edges for ever, found on
        // the Stanford bunny).
        let edge = edge_height(map, n, (i, j), (dx, dz));
        match lower {
            Some((o, m)) => (Target::Map(o as u32, nk as u32), edge.max(m.surface(nk))),
            None => (Target::Off, edge),
        }
    })
}

/// The height snow at texel (i, j) of `map` is compared with past its region's edge in
/// direction (dx, dz): its own ground, lowered by the slope that reaches the edge. A
/// slope goes on past the edge: by the smaller of the ground's last two rises towards
/// it, from the two texels behind (so a surface steeper than the repose, a sphere's side
/// near its silhouette, holds no snow at its edge), and not at all when either is flat
/// or missing (a table's top and a stair's tread keep their cornice: a riser behind a
/// tread is a step, not a slope, as the flat tread above it shows). Measured to the own
/// ground alone, every edge texel of a steep surface held one rise of snow: a ring of
/// texel-sized blocks round the primitives' sphere.
fn edge_height(map: &SnowMap, n: usize, (i, j): (usize, usize), (dx, dz): (i64, i64)) -> f32 {
    let ground_at = |back: i64| {
        let (a, b) = (i as i64 - back * dx, j as i64 - back * dz);
        (a >= 0 && b >= 0 && a < n as i64 && b < n as i64)
            .then(|| b as usize * n + a as usize)
            .filter(|&k| map.possible(k))
            .map(|k| map.ground_m[k])
    };
    let g = map.ground_m[j * n + i];
    let slope = match (ground_at(1), ground_at(2)) {
        (Some(g1), Some(g2)) => (g1 - g).min(g2 - g1).max(0.0),
        _ => 0.0,
    };
    g - slope
}

/// How far past the repose a slope may be before snow moves, as a height over one texel:
/// half of the 1e-4 slope tolerance, so that f32 rounding of the final heights
/// cannot push a slope past it.
pub(crate) fn repose_tolerance(fp: Footprint) -> f32 {
    0.5e-4 * fp.texel_m
}

/// Marks, in `active` (the rest of this pass) and `next` (all of the next), what a change
/// of texel `k` of map `mi` can make steep: `k` itself; when `k` lost snow (`lost`), its
/// neighbours on the map (their slopes towards `k` grew; a gain only lowers them); and,
/// either way, the texels of other maps next to `k` where their region ends (past the
/// edge the slope is measured to the surface at `k`, and whether that map counts as the
/// lower one depends on it).
fn mark(
    regions: &Regions,
    n: usize,
    active: &mut [Bits],
    next: &mut [Bits],
    mi: usize,
    k: usize,
    lost: bool,
) {
    let (i, j) = (k % n, k / n);
    let mut both = |o: usize, nk: usize| {
        active[o].set(nk);
        next[o].set(nk);
    };
    both(mi, k);
    if lost {
        if i > 0 {
            both(mi, k - 1);
        }
        if i + 1 < n {
            both(mi, k + 1);
        }
        if j > 0 {
            both(mi, k - n);
        }
        if j + 1 < n {
            both(mi, k + n);
        }
    }
    if regions.any_rim.get(k) {
        for (o, r) in regions.rim.iter().enumerate() {
            if o != mi && r.get(k) {
                for nk in four(n, k) {
                    both(o, nk);
                }
            }
        }
    }
}

/// Over-relaxation of the stabilisation moves. The paper does not say how much snow a
/// steep texel gives; half the excess levels one pair exactly, but chains of such moves
/// relax like diffusion. Measured on the table scene (60 steps of 1 cm, repose 30°), the
/// passes a step needs grew to 512+ at 1.0, 443 at 1.5 and 250 at 1.8 (1.95 is used).
/// The end state is checked against the repose either way.
const OVER_RELAXATION: f32 = 1.95;

/// The 4-neighbours of texel `k` on an `n`×`n` grid that lie on the grid.
pub(crate) fn four(n: usize, k: usize) -> impl Iterator<Item = usize> {
    let (i, j) = (k % n, k / n);
    [(i > 0).then(|| k - 1), (i + 1 < n).then(|| k + 1), (j > 0).then(|| k - n), (j + 1 < n).then(|| k + n)]
        .into_iter()
        .flatten()
}

/// The shape of the snow maps' regions as the stabilisation needs it.
#[derive(Clone, Debug)]
pub(crate) struct Regions {
    /// Per map, the texels outside its region next to one inside it: a change there
    /// steepens slopes measured past the region's edge (to the lower map's surface).
    pub(crate) rim: Vec<Bits>,
    /// Per map, the texels whose four neighbours are all in its region.
    pub(crate) inner: Vec<Bits>,
    /// Texels on any map's rim: most changes are not next to another region.
    pub(crate) any_rim: Bits,
}

impl Regions {
    fn new(maps: &[SnowMap], n: usize) -> Self {
        let texels = n * n;
        let select = |m: &SnowMap, keep: &dyn Fn(&SnowMap, usize) -> bool| {
            let mut b = Bits::new(texels);
            for k in (0..texels).filter(|&k| keep(m, k)) {
                b.set(k);
            }
            b
        };
        let rim: Vec<Bits> = maps
            .iter()
            .map(|m| select(m, &|m, k| !m.possible(k) && four(n, k).any(|nk| m.possible(nk))))
            .collect();
        let inner = maps
            .iter()
            .map(|m| select(m, &|m, k| m.possible(k) && four(n, k).filter(|&nk| m.possible(nk)).count() == 4))
            .collect();
        let mut any_rim = Bits::new(texels);
        for r in &rim {
            for (a, w) in any_rim.0.iter_mut().zip(&r.0) {
                *a |= w;
            }
        }
        Self { rim, inner, any_rim }
    }
}

/// A set of texels, one bit each, walked in either direction.
#[derive(Clone, Debug)]
pub(crate) struct Bits(Vec<u64>);

impl Bits {
    pub(crate) fn new(len: usize) -> Self {
        Self(vec![0; len.div_ceil(64)])
    }

    pub(crate) fn clear(&mut self) {
        self.0.fill(0);
    }

    /// Every texel of `len`.
    pub(crate) fn fill(&mut self, len: usize) {
        self.0.fill(!0);
        if !len.is_multiple_of(64) {
            self.0[len / 64] = (1 << (len % 64)) - 1;
        }
    }

    pub(crate) fn set(&mut self, k: usize) {
        self.0[k / 64] |= 1 << (k % 64);
    }

    pub(crate) fn get(&self, k: usize) -> bool {
        self.0[k / 64] >> (k % 64) & 1 == 1
    }

    /// The first set bit at `from` or after.
    pub(crate) fn next_from(&self, from: usize) -> Option<usize> {
        let mut w = from / 64;
        let mut word = *self.0.get(w)? & (!0u64 << (from % 64));
        loop {
            if word != 0 {
                return Some(w * 64 + word.trailing_zeros() as usize);
            }
            w += 1;
            word = *self.0.get(w)?;
        }
    }

    /// The last set bit before `end`.
    pub(crate) fn prev_before(&self, end: usize) -> Option<usize> {
        if end == 0 {
            return None;
        }
        let last = end - 1;
        let mut w = last / 64;
        let b = last % 64;
        let mut word = self.0[w] & (!0u64 >> (63 - b));
        loop {
            if word != 0 {
                return Some(w * 64 + 63 - word.leading_zeros() as usize);
            }
            if w == 0 {
                return None;
            }
            w -= 1;
            word = self.0[w];
        }
    }
}

/// The angle of repose as the local rule tests it (§2.4.1): a drop to a neighbour is
/// too steep when it exceeds `rise_m` (tan(repose) × texel width) by more than
/// `tolerance_m`.
#[derive(Clone, Copy, Debug)]
struct Repose {
    rise_m: f32,
    tolerance_m: f32,
}

/// A texel's steep neighbours: where snow goes and by how much each drop exceeds the
/// repose (m), the first `count` of `to`, and the largest excess.
struct Steep {
    to: [(Target, f32); 4],
    count: usize,
    largest_m: f32,
}

impl Steep {
    /// Keep `target`, whose height `h_n` lies below the texel's `h`, if the drop exceeds
    /// the repose.
    #[inline]
    fn consider(&mut self, target: Target, h: f32, h_n: f32, repose: Repose) {
        let excess = h - h_n - repose.rise_m;
        if excess > repose.tolerance_m {
            self.to[self.count] = (target, excess);
            self.count += 1;
            self.largest_m = self.largest_m.max(excess);
        }
    }
}

/// Where moved snow goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Target {
    /// Map index and texel.
    Map(u32, u32),
    /// Off the scene (counted).
    Off,
}

/// The snowfall directions: tilts from the vertical drawn from a 2-D normal distribution
/// about the main tilt (§2.2.2), as unit vectors pointing down the way the snow moves.
pub fn snowfall_directions(params: &SnowConfig, seed: u64) -> Vec<Vec3> {
    (0..params.directions)
        .map(|k| {
            let mut rng = Stream::new(seed, DIRECTIONS, u64::from(k));
            let tx = params.main_tilt_deg[0] + params.spread_deg * rng.normal() as f32;
            let tz = params.main_tilt_deg[1] + params.spread_deg * rng.normal() as f32;
            // Clamp to 85°: past that the snow would move sideways.
            let (tx, tz) = (tx.clamp(-85.0, 85.0).to_radians(), tz.clamp(-85.0, 85.0).to_radians());
            Vec3::new(tx.tan(), -1.0, tz.tan()).normalize()
        })
        .collect()
}

/// Buffers of the probability computation, kept between calls (no allocation, no fresh
/// pages, after the first), and which texels can hold snow: the grounds do not change
/// after [`SnowSim::new`] except through [`SnowSim::maps_mut`], which clears `laid_out`.
/// Only a cache: a cloned simulation starts with empty buffers (cloning stays cheap).
#[derive(Debug, Default)]
struct Exposure {
    /// Whether `counts`, `texel` and the points' x and z describe the maps.
    laid_out: bool,
    /// Snow-possible texels per map, in map order.
    counts: Vec<usize>,
    /// The texel index of each point (maps one after another).
    texel: Vec<u32>,
    /// Surface points (ground + snow), eight per group as [x, y, z] lanes; the last
    /// group padded with NaN points (off every depth map: counted, then dropped).
    points: Vec<[f32x8; 3]>,
    /// One per thread, each over its share of the directions; the first holds the sums.
    workers: Vec<Worker>,
}

/// One thread's rasteriser and counts.
#[derive(Clone, Debug, Default)]
struct Worker {
    raster: Rasterizer,
    /// Directions in which each point is exposed (f32 lanes: exact up to 2²⁴).
    exposed: Vec<f32x8>,
    /// Directions in which each point samples next to a silhouette (when asked).
    near_outline: Vec<u16>,
}

impl Clone for Exposure {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl Exposure {
    /// Count, for every snow-possible texel of every map, the `directions` in which its
    /// surface point is exposed (and, when `silhouettes`, those in which it samples next
    /// to a silhouette).
    #[allow(clippy::too_many_arguments)]
    fn count(
        &mut self,
        mesh: &Mesh,
        cull: Cull,
        maps: &[SnowMap],
        fp: &Footprint,
        directions: &[Vec3],
        params: &SnowConfig,
        silhouettes: bool,
    ) -> Result<(), SnowError> {
        let depth_maps = DepthMaps::around(mesh, params)?;
        if !self.laid_out {
            self.lay_out(maps, fp);
        }
        self.set_heights(maps);
        let share = self.share_directions(directions.len(), silhouettes);
        let points = &self.points;
        self.workers.par_iter_mut().zip(directions.par_chunks(share)).try_for_each(
            |(worker, directions)| {
                let Worker { raster, exposed, near_outline } = worker;
                for d in directions {
                    let view = depth_maps.view(*d);
                    let (buf, _) = raster.draw(&view, &mesh.triangles, None, cull)?;
                    depth_maps.count_exposed(exposed, points, &view, buf.depth());
                    depth_maps.count_near_outline(near_outline, points, &view, buf);
                }
                Ok::<(), SnowError>(())
            },
        )?;
        self.sum_workers();
        Ok(())
    }

    /// Number the snow-possible texels of `maps` (those with a ground) in map order and
    /// write their x and z into the points; the heights are [`Exposure::set_heights`]'s.
    fn lay_out(&mut self, maps: &[SnowMap], fp: &Footprint) {
        let n = fp.n;
        // Counted first, then written in place.
        self.counts.clear();
        self.counts.extend(maps.iter().map(|m| m.ground_m.iter().filter(|g| !g.is_nan()).count()));
        let total: usize = self.counts.iter().sum();
        self.texel.resize(total, 0);
        self.points.clear();
        self.points.resize(total.div_ceil(8), [f32x8::splat(f32::NAN); 3]);
        let mut i = 0;
        for map in maps {
            for (j, ground) in map.ground_m.chunks_exact(n).enumerate() {
                for (t, g) in ground.iter().enumerate() {
                    if !g.is_nan() {
                        let xz = fp.centre(t, j);
                        self.texel[i] = (j * n + t) as u32;
                        let [x, _, z] = &mut self.points[i / 8];
                        x.as_mut_array()[i % 8] = xz.x;
                        z.as_mut_array()[i % 8] = xz.y;
                        i += 1;
                    }
                }
            }
        }
        self.laid_out = true;
    }

    /// The points' heights: the surface, ground + snow, m.
    fn set_heights(&mut self, maps: &[SnowMap]) {
        let mut at = 0;
        for (map, &count) in maps.iter().zip(&self.counts) {
            for (i, &t) in (at..at + count).zip(&self.texel[at..at + count]) {
                let t = t as usize;
                self.points[i / 8][1].as_mut_array()[i % 8] = map.ground_m[t] + map.snow_m[t];
            }
            at += count;
        }
    }

    /// Share `directions` directions among the threads in contiguous shares, one worker
    /// per share, every one cleared (with silhouette counts when `silhouettes`); returns
    /// the share. Each share is drawn and tested on its thread into its own counts: the
    /// counts are whole numbers, so their sum does not depend on how they were shared.
    fn share_directions(&mut self, directions: usize, silhouettes: bool) -> usize {
        let (total, groups) = (self.texel.len(), self.points.len());
        let threads = rayon::current_num_threads().clamp(1, directions.max(1));
        let share = directions.div_ceil(threads).max(1);
        // As many workers as shares (which can be fewer than threads).
        let workers = directions.div_ceil(share).max(1);
        self.workers.truncate(workers);
        self.workers.resize_with(workers, || Worker { raster: Rasterizer::serial(), ..Worker::default() });
        for Worker { exposed, near_outline, .. } in &mut self.workers {
            exposed.clear();
            exposed.resize(groups, f32x8::ZERO);
            near_outline.clear();
            near_outline.resize(if silhouettes { total } else { 0 }, 0);
        }
        share
    }

    /// Sum the workers' counts into the first worker's.
    fn sum_workers(&mut self) {
        let (first, rest) = self.workers.split_first_mut().expect("a worker");
        if !rest.is_empty() {
            const CHUNK: usize = 1024;
            first.exposed.par_chunks_mut(CHUNK).enumerate().for_each(|(c, sum)| {
                for other in rest.iter() {
                    for (s, o) in sum.iter_mut().zip(&other.exposed[c * CHUNK..]) {
                        *s += *o;
                    }
                }
            });
            for other in rest.iter() {
                for (s, o) in first.near_outline.iter_mut().zip(&other.near_outline) {
                    *s += o;
                }
            }
        }
    }

    /// Write `f(point)` into each map's texels (`out[m][texel]`); other texels keep
    /// their values.
    fn scatter<T>(&self, out: &mut [&mut [T]], f: impl Fn(usize) -> T) {
        let mut at = 0;
        for (out, &count) in out.iter_mut().zip(&self.counts) {
            for (i, &t) in (at..at + count).zip(&self.texel[at..at + count]) {
                out[t as usize] = f(i);
            }
            at += count;
        }
    }

    /// Exposed directions of point `i`.
    fn exposed(&self, i: usize) -> f32 {
        self.workers[0].exposed[i / 8].as_array()[i % 8]
    }
}

/// The depth maps of the exposure test (§2.2.3): orthographic views of `res` × `res`
/// pixels covering the scene's bounding sphere, one along each snowfall direction.
struct DepthMaps {
    /// Centre of the scene's bounds, m.
    centre: Vec3,
    /// Radius of the sphere the views cover (half the bounds' diagonal plus a metre), m.
    radius_m: f32,
    /// Pixels per side.
    res: usize,
    /// Width of a pixel, m.
    px_m: f32,
    /// How far behind the depth map a point may lie and still be exposed (two pixel
    /// widths), m.
    bias_m: f32,
}

impl DepthMaps {
    /// The depth maps around `mesh` at the configured shadow resolution.
    fn around(mesh: &Mesh, params: &SnowConfig) -> Result<Self, SnowError> {
        let (lo, hi) = mesh.bounds().ok_or(SnowError::NoSnowSurface)?;
        let centre = 0.5 * (lo + hi);
        let radius_m = 0.5 * (hi - lo).length() + 1.0;
        let res = params.shadow_resolution as usize;
        let px_m = 2.0 * radius_m / res as f32;
        Ok(Self { centre, radius_m, res, px_m, bias_m: 2.0 * px_m })
    }

    /// The view down the snowfall direction `d`, from above the scene.
    fn view(&self, d: Vec3) -> CameraView {
        let up = if d.x.abs() < 0.9 { Vec3::X } else { Vec3::Z };
        Camera {
            position: self.centre - d * (2.0 * self.radius_m),
            look_at: self.centre,
            up,
            projection: Projection::Orthographic { height_m: 2.0 * self.radius_m },
        }
        .view(self.res, self.res)
        .expect("a valid direction camera")
    }

    /// Add 1 to `exposed` for every point (eight at a time) that `view`'s depth map
    /// `depth` does not hide: outside the map, or not behind its depth by more than the
    /// bias.
    #[inline]
    fn count_exposed(&self, exposed: &mut [f32x8], points: &[[f32x8; 3]], view: &CameraView, depth: &[f32]) {
        let res = self.res;
        let (zero, limit, last) = (f32x8::ZERO, f32x8::splat(res as f32), f32x8::splat(res as f32 - 1.0));
        let bias = self.bias_m;
        let [ax, ay, az] =
            view.orthographic_affine().expect("an orthographic view").map(|r| r.to_array().map(f32x8::splat));
        let width = i32x8::splat(res as i32);
        for (c, &[x, y, z]) in exposed.iter_mut().zip(points) {
            let qx = x * ax[0] + y * ax[1] + z * ax[2] + ax[3];
            let qy = x * ay[0] + y * ay[1] + z * ay[2] + ay[3];
            let qd = x * az[0] + y * az[1] + z * az[2] + az[3];
            // Outside the scene's depth map nothing is in the way.
            let inside = qx.simd_ge(zero) & qy.simd_ge(zero) & qx.simd_lt(limit) & qy.simd_lt(limit);
            // Pixel indices, clamped (NaN → 0) so that every lane reads a real pixel; for
            // coordinates in [0, res) truncation is the floor.
            let ix = qx.max(zero).min(last).trunc_int();
            let iy = qy.max(zero).min(last).trunc_int();
            let d = f32x8::from((iy * width + ix).to_array().map(|k| depth[k as usize]));
            *c += (!inside | qd.simd_le(d + bias)) & f32x8::ONE;
        }
    }

    /// Add 1 to `near_outline` for every point whose sample in `view`'s depth map `buf`
    /// lies next to a silhouette: over its pixel and the 4 neighbours the depth spans more
    /// than 10 pixel widths (empty pixels count as very far).
    fn count_near_outline(
        &self,
        near_outline: &mut [u16],
        points: &[[f32x8; 3]],
        view: &CameraView,
        buf: &DepthBuffer,
    ) {
        let res = self.res;
        for (i, e) in near_outline.iter_mut().enumerate() {
            let p = Vec3::from_array(points[i / 8].map(|l| l.as_array()[i % 8]));
            let Some(q) = view.project(p) else { continue };
            let (x, y) = (q.x_px.floor() as i64, q.y_px.floor() as i64);
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for (dx, dy) in [(0i64, 0i64), (1, 0), (-1, 0), (0, 1), (0, -1)] {
                let (px, py) = (x + dx, y + dy);
                if px >= 0 && py >= 0 && (px as usize) < res && (py as usize) < res {
                    let d = buf.depth_at(px as usize, py as usize);
                    // Empty pixels (no surface) count as very far.
                    let d = if d.is_finite() { d } else { 1e9 };
                    lo = lo.min(d);
                    hi = hi.max(d);
                }
            }
            *e += u16::from(hi - lo > 10.0 * self.px_m);
        }
    }
}

impl phenomena_core::phenomenon::Simulation for SnowSim {
    type StepStats = StepStats;
    type Error = SnowError;

    fn step(&mut self) -> Result<StepStats, SnowError> {
        SnowSim::step(self)
    }

    fn frames_done(&self) -> u64 {
        self.steps()
    }

    type State = SnowState;

    fn state(&self) -> SnowState {
        SnowSim::state(self)
    }

    fn restore(&mut self, state: SnowState) -> Result<(), SnowError> {
        SnowSim::restore(self, state)
    }
}

/// A checkpoint: what a [`SnowSim`] built from the same configuration and mesh needs to
/// continue bit-identically (the groups, grounds and depth maps are rebuilt from the
/// mesh; the probability is kept because it was drawn from the snow at its last update).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SnowState {
    /// Steps completed.
    pub steps: u64,
    /// Time simulated, hours.
    pub time_h: f64,
    /// Snow volume that has left the scene, m³.
    pub fallen_off_m3: f64,
    /// Snow depth per map and texel, m.
    pub snow_m: Vec<Vec<f32>>,
    /// Snow probability per map and texel.
    pub probability: Vec<Vec<f32>>,
}

impl SnowSim {
    /// A checkpoint of the current state.
    pub fn state(&self) -> SnowState {
        SnowState {
            steps: self.steps,
            time_h: self.time_h,
            fallen_off_m3: self.fallen_off_m3,
            snow_m: self.maps.iter().map(|m| m.snow_m.clone()).collect(),
            probability: self.maps.iter().map(|m| m.probability.clone()).collect(),
        }
    }

    /// Continue from a checkpoint taken with [`SnowSim::state`] of a simulation built
    /// from the same configuration and mesh. Refused, leaving `self` as it was, when
    /// its maps differ in number or size from this simulation's, or hold a depth or
    /// probability that is negative or not finite.
    pub fn restore(&mut self, state: SnowState) -> Result<(), SnowError> {
        let texels = self.maps.first().map_or(0, |m| m.snow_m.len());
        let fits = |v: &[Vec<f32>]| v.len() == self.maps.len() && v.iter().all(|m| m.len() == texels);
        if !fits(&state.snow_m) || !fits(&state.probability) {
            return Err(SnowError::State(format!(
                "{} snow and {} probability maps for {} maps of {texels} texels",
                state.snow_m.len(),
                state.probability.len(),
                self.maps.len()
            )));
        }
        let sane = |v: &[Vec<f32>], top: f32| v.iter().flatten().all(|&x| (0.0..=top).contains(&x));
        if !sane(&state.snow_m, f32::MAX) || !sane(&state.probability, 1.0) {
            return Err(SnowError::State(
                "a depth or probability is negative, above range or not finite".into(),
            ));
        }
        if !(state.time_h.is_finite() && state.fallen_off_m3.is_finite() && state.fallen_off_m3 >= 0.0) {
            return Err(SnowError::State("the time or the fallen volume is not finite".into()));
        }
        for ((map, snow), p) in self.maps.iter_mut().zip(state.snow_m).zip(state.probability) {
            map.snow_m = snow;
            map.probability = p;
        }
        self.steps = state.steps;
        self.time_h = state.time_h;
        self.fallen_off_m3 = state.fallen_off_m3;
        Ok(())
    }

    /// Make this simulation continue as `other` does: what [`SnowSim::restore`] of
    /// `other.state()` makes, without the checks or new buffers (the maps are copied into
    /// this one's). Both must be built from the same configuration and mesh, with grounds
    /// unchanged through [`SnowSim::maps_mut`] (a checkpoint's contract); a simulation
    /// stepped ahead on a spare copy while the frame renders is kept in step so. Maps of
    /// another number or size make this a clone of `other`.
    pub fn sync_from(&mut self, other: &SnowSim) {
        let texels = |s: &SnowSim| s.maps.first().map(|m| m.snow_m.len());
        if self.maps.len() != other.maps.len() || texels(self) != texels(other) {
            *self = other.clone();
            return;
        }
        for (map, from) in self.maps.iter_mut().zip(&other.maps) {
            map.snow_m.clone_from(&from.snow_m);
            map.probability.clone_from(&from.probability);
        }
        self.steps = other.steps;
        self.time_h = other.time_h;
        self.fallen_off_m3 = other.fallen_off_m3;
    }
}
