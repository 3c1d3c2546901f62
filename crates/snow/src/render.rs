//! Pictures of a snow scene: the scene and its snow through a camera, lit by the sun and
//! the sky, with optional fog as in the paper's figures; or the snow probability P_a of
//! the topmost map seen from above.

use crate::raster::{Cull, DepthBuffer, NO_ID, rasterize_indexed};
use glam::Vec3;
use phenomena_core::camera::{Camera, CameraView, Projected};
use phenomena_core::clock::SharedClock;
use phenomena_core::image::Frame;
use phenomena_core::phenomenon::{RenderError, check_size, image_background};
use phenomena_core::validate::{InvalidConfig, Issue, Issues};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::export::{GlbPart, GlbView, TriMesh, snow_mesh, snow_surface, to_glb_scene};
use crate::glitter::{GlintCache, Glitter, Viewing};
use crate::sim::SnowSim;

/// What the frames show.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SnowView {
    /// The scene and the snow through the camera.
    #[default]
    Scene,
    /// P_a of each snow map from above, the maps side by side (dark blue: never
    /// reached, white: always; black: not part of the map).
    Probability,
}

/// What lies behind the scene: where no triangle is seen, and what fog fades towards.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Background {
    /// A pale overcast sky of one colour.
    #[default]
    Sky,
    /// An image file (sRGB, stretched bilinearly to the frame's size); the caller loads
    /// it and passes it to [`SnowRenderer::new`].
    Image {
        /// Path, relative to the scene file.
        path: std::path::PathBuf,
    },
}

/// Render settings of a snow scene (`[render]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SnowRenderSettings {
    /// What to draw.
    pub view: SnowView,
    /// The camera, metres. Without one (no `[render.camera]`), [`Camera::framing`] of
    /// the scene's geometry: a three-quarter view from above with all of it in view.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub camera: Option<Camera>,
    /// Direction towards the sun (need not be unit length).
    #[serde(deserialize_with = "phenomena_core::serde_vec::vec3")]
    pub sun_direction: Vec3,
    /// Fog density per metre (0: no fog); the paper's figures use fog.
    pub fog_per_m: f32,
    /// Falling flakes drawn over the scene view (decoration; none by default).
    pub flakes: Flakes,
    /// Behind the scene.
    pub background: Background,
    /// Sunlight on a surface facing the sun, relative to a white surface's value in the
    /// frame (1.1: the bright day of the paper's figures; a night scene lit by the moon
    /// sets it far lower).
    pub sun_strength: f32,
    /// Light from the whole sky on any surface, same units (0.35).
    pub sky_strength: f32,
    /// Pixels along each side of the sun's shadow map (0: no cast shadows).
    pub shadow_map_px: u32,
    /// The glints of the snow's ice grains in the sun (`[render.glitter]`; an
    /// extension: the sparkle model of Hwang and Noma on the snow, see [`crate::glitter`]).
    pub glitter: Glitter,
}

/// Snowflakes falling through the scene view along the snowfall directions: flake k
/// starts at a place drawn from its own random stream inside a box over the scene and
/// falls along direction k mod (number of directions), wrapping round the box; frame f
/// shows them at display time f / `frames_per_s`. They are hidden behind the scene.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Flakes {
    /// Number of flakes (0: none).
    pub count: u32,
    /// Fall speed, metres per second.
    pub fall_m_per_s: f32,
    /// Flake radius, pixels.
    pub radius_px: f32,
    /// Display frames per second (how far flakes fall between frames).
    pub frames_per_s: f32,
}

impl Default for Flakes {
    fn default() -> Self {
        Self { count: 0, fall_m_per_s: 1.0, radius_px: 1.2, frames_per_s: 30.0 }
    }
}

impl Default for SnowRenderSettings {
    fn default() -> Self {
        Self {
            view: SnowView::Scene,
            camera: None,
            sun_direction: Vec3::new(-0.4, 1.0, 0.3),
            fog_per_m: 0.0,
            flakes: Flakes::default(),
            background: Background::Sky,
            sun_strength: SUN,
            sky_strength: AMBIENT,
            shadow_map_px: 512,
            glitter: Glitter::default(),
        }
    }
}

impl SnowRenderSettings {
    /// Every problem, with fields relative to `[render]`.
    pub fn validate(&self) -> Result<(), Vec<Issue>> {
        let mut i = Issues::default();
        if let Some(camera) = &self.camera {
            camera.validate_planar(&mut i, "camera");
        }
        i.vector("sun_direction", &self.sun_direction.to_array(), 1e6);
        if self.sun_direction.length() < 1e-6 {
            i.push("sun_direction", format!("{:?}", self.sun_direction.to_array()), "a non-zero direction");
        }
        i.range("fog_per_m", self.fog_per_m, 0.0..=100.0);
        i.range("sun_strength", self.sun_strength, 0.0..=1e6);
        i.range("sky_strength", self.sky_strength, 0.0..=1e6);
        i.count("shadow_map_px", u64::from(self.shadow_map_px), 0..=8192);
        self.glitter.validate(&mut i, "glitter");
        i.count("flakes.count", u64::from(self.flakes.count), 0..=1_000_000);
        i.range("flakes.fall_m_per_s", self.flakes.fall_m_per_s, 0.0..=100.0);
        i.range("flakes.radius_px", self.flakes.radius_px, 0.1..=50.0);
        i.range_open_low("flakes.frames_per_s", self.flakes.frames_per_s, 0.0, 1000.0);
        if let Background::Image { path } = &self.background
            && path.as_os_str().is_empty()
        {
            i.push("background.path", "\"\"", "the path of a PNG file");
        }
        i.into_result()
    }
}

/// Linear-light colours of the picture.
const SKY: Vec3 = Vec3::new(0.62, 0.70, 0.82);
/// Colour of the sunlight (slightly warm) and of the light from the blue sky, each of
/// mean 1: a surface the sun does not reach is lit by the sky alone, so it is darker
/// and bluer than a sunlit one, as snow in shadow is.
const SUN_RGB: Vec3 = Vec3::new(1.04, 1.0, 0.96);
const SKY_RGB: Vec3 = Vec3::new(0.80, 0.97, 1.23);
const SNOW_ALBEDO: f32 = 0.9;
const SUN: f32 = 1.1;
const AMBIENT: f32 = 0.35;

/// The scene objects' albedos (greys and a brown), by object id modulo their number.
const PALETTE: [Vec3; 4] = [
    Vec3::new(0.30, 0.28, 0.25),
    Vec3::new(0.35, 0.22, 0.12),
    Vec3::new(0.45, 0.45, 0.47),
    Vec3::new(0.25, 0.32, 0.22),
];

/// Albedo of scene object `o` (greys and a brown, cycling).
fn object_albedo(o: u32) -> Vec3 {
    PALETTE[o as usize % PALETTE.len()]
}

/// Draws a [`SnowSim`] frame by frame into linear RGB.
#[derive(Clone, Debug)]
pub struct SnowRenderer {
    settings: SnowRenderSettings,
    /// The image behind the scene, at the frame's size (`None`: the sky colour).
    background: Option<Frame>,
    frame: Frame,
    /// Distance along the view direction to the nearest surface per pixel of the last
    /// scene view, metres (+∞ where none; empty for the probability view).
    depth: Vec<f32>,
    /// Point lights besides the sun and sky: position (m) and radiant intensity.
    lights: Vec<(Vec3, Vec3)>,
    /// What each pixel of the last scene view shows ([`Seen`]).
    seen: Vec<Seen>,
    /// The scene mesh's smooth normals, worked out once per mesh.
    normals: ObjectNormals,
    /// The snow's grains that may glint, kept from frame to frame.
    glint_cache: GlintCache,
    /// The clock of [`SnowRenderer::timings`] (none: every timing reads 0).
    clock: SharedClock,
    timings: SnowTimings,
}

/// Where the last scene view's time went, ms, in its main parts (0 unless the renderer
/// was given a clock by [`SnowRenderer::set_clock`]), and how much it drew.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SnowTimings {
    /// The snow's surface made into a mesh ([`snow_surface`]).
    pub mesh_ms: f64,
    /// The camera's depth buffer of every triangle (with the shared vertices and
    /// indices it is drawn from, which the shadow map draws from too).
    pub raster_ms: f64,
    /// The sun's shadow map.
    pub shadow_ms: f64,
    /// Every pixel lit (sun, sky, lights, fog), with the scene's smooth normals worked
    /// out again when its mesh changed.
    pub shade_ms: f64,
    /// The snow's glints: the faces that can glint, their grains, their pixels.
    pub glitter_ms: f64,
    /// The falling flakes.
    pub flakes_ms: f64,
    /// Triangles given to the rasteriser, the scene's and the snow's (before the snow's
    /// back faces are culled).
    pub triangles: usize,
    /// Glints the sun lights on pixels that show them.
    pub glints: usize,
}

/// The scene mesh's smooth normals, kept while the mesh stays the same (it does for a
/// whole shot: only the snow on it changes).
#[derive(Clone, Debug, Default)]
struct ObjectNormals {
    scene: Vec<[Vec3; 3]>,
    normals: Vec<[Vec3; 3]>,
}

impl ObjectNormals {
    /// [`smooth_normals`] of `scene`, from the last call's when the mesh is the same.
    fn of(&mut self, scene: &[[Vec3; 3]]) -> &[[Vec3; 3]] {
        if self.scene != scene {
            self.normals = smooth_normals(scene);
            self.scene = scene.to_vec();
        }
        &self.normals
    }
}

/// What a pixel of the scene view shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Seen {
    /// Nothing: the background.
    Background,
    /// A triangle of the scene's mesh.
    Object,
    /// The snow.
    Snow,
}

impl SnowRenderer {
    /// Whether [`SnowRenderer::new`] accepts `settings` at `width × height` (besides
    /// the background image), without allocating any image.
    pub fn check(settings: &SnowRenderSettings, width: usize, height: usize) -> Result<(), RenderError> {
        settings.validate().map_err(InvalidConfig::from)?;
        check_size(width, height)
    }

    /// A renderer of `width × height` frames; `background` is the loaded image (linear
    /// RGB, any size: it is stretched to the frame by [`Frame::resized`]) when the
    /// settings ask for one.
    pub fn new(
        settings: SnowRenderSettings,
        width: usize,
        height: usize,
        background: Option<&Frame>,
    ) -> Result<Self, RenderError> {
        Self::check(&settings, width, height)?;
        let wanted = matches!(settings.background, Background::Image { .. });
        let background = image_background(wanted, background, width, height)?;
        Ok(Self {
            settings,
            background,
            frame: Frame::new(width, height),
            depth: Vec::new(),
            lights: Vec::new(),
            seen: Vec::new(),
            normals: ObjectNormals::default(),
            glint_cache: GlintCache::default(),
            clock: SharedClock::default(),
            timings: SnowTimings::default(),
        })
    }

    /// Time the next scene views' parts with `clock` ([`SnowRenderer::timings`]).
    pub fn set_clock(&mut self, clock: SharedClock) {
        self.clock = clock;
    }

    /// The last scene view's timings (all 0 for the probability view).
    pub fn timings(&self) -> SnowTimings {
        self.timings
    }

    /// The settings.
    pub fn settings(&self) -> &SnowRenderSettings {
        &self.settings
    }

    /// The last rendered frame.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// Draw `sim` (linear RGB). The camera was checked by [`SnowRenderSettings::validate`];
    /// a degenerate one gives a black frame.
    pub fn render(&mut self, sim: &SnowSim) -> &Frame {
        let (w, h) = (self.frame.width(), self.frame.height());
        match self.settings.view {
            SnowView::Scene => {
                (self.frame, self.depth, self.seen) = render_scene(
                    sim,
                    &self.settings,
                    (self.background.as_ref(), &self.lights),
                    (&mut self.normals, &mut self.glint_cache),
                    (&self.clock, &mut self.timings),
                    w,
                    h,
                )
            }
            SnowView::Probability => {
                self.timings = SnowTimings::default();
                (self.frame, self.depth, self.seen) = (render_probability(sim, w, h), Vec::new(), Vec::new())
            }
        }
        &self.frame
    }

    /// Light the next renders also with point lights (a fire): each a position, metres,
    /// and a radiant intensity I in the frame's units of radiance times square metres,
    /// so a surface of albedo ρ at distance r facing the light at angle θ gains
    /// ρ I cos θ / (π r²). Nothing shadows them.
    pub fn set_lights(&mut self, lights: &[(Vec3, Vec3)]) {
        self.lights.clear();
        self.lights.extend_from_slice(lights);
    }

    /// Draw the scene view of `sim` over `behind` (a frame of this renderer's size: what
    /// lies beyond the scene, in place of the background; fog fades towards it), for
    /// composition with other phenomena.
    pub fn render_over(&mut self, sim: &SnowSim, behind: &Frame) -> &Frame {
        let (w, h) = (self.frame.width(), self.frame.height());
        (self.frame, self.depth, self.seen) = render_scene(
            sim,
            &self.settings,
            (Some(behind), &self.lights),
            (&mut self.normals, &mut self.glint_cache),
            (&self.clock, &mut self.timings),
            w,
            h,
        );
        &self.frame
    }

    /// What the settings put behind the scene, at the frame's size (the sky's colour or
    /// the image), for composition with other phenomena.
    pub fn background(&self) -> Frame {
        let (w, h) = (self.frame.width(), self.frame.height());
        self.background.clone().unwrap_or_else(|| {
            let mut f = Frame::new(w, h);
            f.map_pixels(|_| SKY);
            f
        })
    }

    /// The scene as this renderer draws it, as one GLB for another renderer: the
    /// scene's objects (one mesh per colour of the palette), the snow, the camera (the
    /// settings' or the framing one) and the sun, with the light settings in the
    /// scene's `extras` (`sun_strength`, `sky_strength`, `sun_rgb`, `sky_rgb`,
    /// `background_rgb`). The Cycles comparison in CI renders it.
    pub fn scene_glb(&self, sim: &SnowSim) -> Vec<u8> {
        let (w, h) = (self.frame.width(), self.frame.height());
        let s = &self.settings;
        // The objects with the corner normals the renderer shades them with.
        let scene = sim.mesh();
        let corners = smooth_normals(&scene.triangles);
        let objects: Vec<(String, TriMesh, Vec3)> = (0..PALETTE.len() as u32)
            .map(|k| {
                let mut mesh = TriMesh::default();
                for (t, tri) in scene.triangles.iter().enumerate() {
                    if scene.object[t] % PALETTE.len() as u32 == k && scene.normal(t) != Vec3::ZERO {
                        for (p, n) in tri.iter().zip(corners[t]) {
                            mesh.indices.push(mesh.positions.len() as u32);
                            mesh.positions.push(*p);
                            mesh.normals.push(n);
                        }
                    }
                }
                (format!("objects-{k}"), mesh, object_albedo(k))
            })
            .collect();
        let snow = snow_mesh(sim);
        let mut parts: Vec<GlbPart<'_>> =
            objects.iter().map(|(name, mesh, colour)| GlbPart { name, mesh, colour: *colour }).collect();
        parts.push(GlbPart { name: "snow", mesh: &snow, colour: Vec3::splat(SNOW_ALBEDO) });
        let v = |c: Vec3| format!("[{},{},{}]", c.x, c.y, c.z);
        let view = GlbView {
            camera: camera_of(s, sim, w, h),
            aspect: w as f32 / h as f32,
            sun: s.sun_direction.normalize_or_zero(),
            sun_rgb: SUN_RGB,
            sun_intensity: s.sun_strength,
            extras: format!(
                r#"{{"sun_strength":{},"sky_strength":{},"sun_rgb":{},"sky_rgb":{},"background_rgb":{},"width":{w},"height":{h}}}"#,
                s.sun_strength,
                s.sky_strength,
                v(SUN_RGB),
                v(SKY_RGB),
                v(SKY)
            ),
        };
        to_glb_scene(&parts, &view)
    }

    /// What each pixel of the last scene view shows (row-major; empty before the first).
    pub fn seen(&self) -> &[Seen] {
        &self.seen
    }

    /// Distance along the view direction to the nearest surface, metres, per pixel of
    /// the last scene view (row-major; +∞ where no surface is seen); empty before the
    /// first scene view.
    pub fn depth(&self) -> &[f32] {
        &self.depth
    }
}

impl phenomena_core::phenomenon::Renderer<SnowSim> for SnowRenderer {
    fn render(&mut self, sim: &SnowSim) -> &Frame {
        SnowRenderer::render(self, sim)
    }

    fn frame(&self) -> &Frame {
        SnowRenderer::frame(self)
    }
}

/// The settings' camera, or one framing the scene's geometry.
fn camera_of(settings: &SnowRenderSettings, sim: &SnowSim, width: usize, height: usize) -> Camera {
    settings.camera.unwrap_or_else(|| {
        let (lo, hi) = bounds(&sim.mesh().triangles);
        Camera::framing(lo, hi, width, height)
    })
}

/// The triangles the scene view draws as a soup, the scene's then the snow's, and the
/// snow's mesh (for tests: the renderer draws [`indexed`]'s list of the same triangles).
#[cfg(test)]
fn triangles(sim: &SnowSim) -> (Vec<[Vec3; 3]>, TriMesh) {
    let snow = snow_surface(sim);
    let scene = &sim.mesh().triangles;
    let mut tris = Vec::with_capacity(scene.len() + snow.triangles());
    tris.extend_from_slice(scene);
    // In parallel, in order.
    tris.par_extend(
        snow.indices.par_chunks_exact(3).map(|t| [0, 1, 2].map(|k| snow.positions[t[k] as usize])),
    );
    (tris, snow)
}

/// Shared vertices and three indices into them a triangle.
type Indexed = (Vec<Vec3>, Vec<u32>);

/// The triangles the scene view draws, the `scene`'s then the `snow` mesh's, as shared
/// vertices and three indices a triangle, for [`rasterize_indexed`]: the scene's corners
/// each a vertex of its own, then the snow's mesh. `None` past 2³² vertices (what a `u32` index can name).
fn indexed(scene: &[[Vec3; 3]], snow: &TriMesh) -> Option<Indexed> {
    let vertices = scene.len().checked_mul(3)?.checked_add(snow.positions.len())?;
    u32::try_from(vertices).ok()?;
    let offset = u32::try_from(3 * scene.len()).ok()?;
    let mut positions = Vec::with_capacity(vertices);
    positions.extend(scene.iter().flatten());
    positions.extend_from_slice(&snow.positions);
    let mut indices = Vec::with_capacity(3 * scene.len() + snow.indices.len());
    indices.extend(0..offset);
    // The snow's indices name its vertices, so each sum stays below `vertices`; one that
    // does not (a bad mesh) saturates and the rasteriser refuses it.
    indices.par_extend(snow.indices.par_iter().map(|&k| k.saturating_add(offset)));
    Some((positions, indices))
}

/// `f()`, its time (by `clock`) into `ms`.
fn timed<T>(clock: &SharedClock, ms: &mut f64, f: impl FnOnce() -> T) -> T {
    let t = clock.stopwatch();
    let out = f();
    *ms = t.ms();
    out
}

fn render_scene(
    sim: &SnowSim,
    settings: &SnowRenderSettings,
    (background, lights): (Option<&Frame>, &[(Vec3, Vec3)]),
    (normals, glint_cache): (&mut ObjectNormals, &mut GlintCache),
    (clock, timings): (&SharedClock, &mut SnowTimings),
    width: usize,
    height: usize,
) -> (Frame, Vec<f32>, Vec<Seen>) {
    *timings = SnowTimings::default();
    let mut frame = Frame::new(width, height);
    let none = || (vec![f32::INFINITY; width * height], vec![Seen::Background; width * height]);
    let scene = &sim.mesh().triangles;
    let camera = camera_of(settings, sim, width, height);
    let Some(view) = camera.view(width, height) else {
        let (d, seen) = none();
        return (frame, d, seen);
    };
    let snow = timed(clock, &mut timings.mesh_ms, || snow_surface(sim));
    timings.triangles = scene.len() + snow.triangles();
    let sun = settings.sun_direction.normalize_or_zero();
    let Some((buf, shadows, (positions, indices))) =
        depth_and_shadow(&view, (scene, &snow), (sun, settings), (clock, timings))
    else {
        let (d, seen) = none();
        return (frame, d, seen);
    };
    let eye = camera.position;
    let lighting =
        Lighting { settings, sun, shadows, sky_seen: SkyVisibility { sim, fp: sim.footprint() }, lights };
    let t = clock.stopwatch();
    let object_normals = normals.of(scene);
    // Rows in parallel, each pixel on its own: the same bits for any thread count.
    let shade = |x: usize, y: usize| -> Vec3 {
        let id = buf.id_at(x, y);
        let sky = background.map_or(SKY, |b| b.pixel(x, y));
        if id == NO_ID {
            return sky;
        }
        let i = 3 * id as usize;
        let [a, b, c] = [indices[i], indices[i + 1], indices[i + 2]].map(|k| positions[k as usize]);
        // The surface point: its depth along the view direction on the pixel's ray.
        let (o, dir) = view.ray(x as f32 + 0.5, y as f32 + 0.5);
        let p = o + dir * (buf.depth_at(x, y) / dir.dot(view.forward()).max(1e-6));
        let face = (b - a).cross(c - a).normalize_or_zero();
        let (corners, albedo) = match (id as usize).checked_sub(scene.len()) {
            None => (object_normals[id as usize], object_albedo(sim.mesh().object[id as usize])),
            Some(t) => {
                ([0, 1, 2].map(|k| snow.normals[snow.indices[3 * t + k] as usize]), Vec3::splat(SNOW_ALBEDO))
            }
        };
        let mut n = interpolate([a, b, c], corners, p).unwrap_or(face);
        if face.dot(eye - a) < 0.0 {
            n = -n; // light the side facing the camera
        }
        let fog = (-settings.fog_per_m * buf.depth_at(x, y)).exp();
        lighting.at(p, n, albedo) * fog + sky * (1.0 - fog)
    };
    frame.fill_with(shade);
    timings.shade_ms = t.ms();
    timings.glints = timed(clock, &mut timings.glitter_ms, || {
        let mesh = (&snow.positions[..], &snow.indices[..]);
        draw_glitter((sim.seed(), glint_cache), settings, &lighting, (&view, eye), &buf, mesh, &mut frame)
    });
    // Flakes are lit as the snow is: white in the default light.
    let flake_light = (settings.sun_strength + settings.sky_strength) / (SUN + AMBIENT);
    timed(clock, &mut timings.flakes_ms, || {
        draw_flakes(sim, &settings.flakes, &view, &buf, flake_light, &mut frame)
    });
    (frame, buf.depth().to_vec(), seen(&buf, scene.len()))
}

/// The view's depth buffer and the sun's shadow map (towards unit `sun`) of the
/// `scene`'s triangles, then the `snow` mesh's, both drawn from shared vertices (each
/// projected once), and those vertices and indices ([`indexed`]: triangle `id` of the
/// buffer is indices `3 id..3 id + 3`); `None` when the view cannot be drawn.
fn depth_and_shadow(
    view: &CameraView,
    (scene, snow): (&[[Vec3; 3]], &TriMesh),
    (sun, settings): (Vec3, &SnowRenderSettings),
    (clock, timings): (&SharedClock, &mut SnowTimings),
) -> Option<(DepthBuffer, Option<SunShadow>, Indexed)> {
    // The snow's texel solids face outwards and are closed but for the bottoms left out
    // (`snow_surface`: they lie on the planar ground that holds the snow): their back
    // faces (the bottoms, the far sides) are never what the eye or the sun sees first.
    let cull = Cull::BackFrom(scene.len());
    let (indexed, raster) = timed(clock, &mut timings.raster_ms, || {
        let indexed = indexed(scene, snow)?;
        let raster = rasterize_indexed(view, (&indexed.0, &indexed.1), None, cull);
        Some((indexed, raster))
    })?;
    let (buf, _) = raster.ok()?;
    let shadows = timed(clock, &mut timings.shadow_ms, || {
        SunShadow::new_indexed((&indexed.0, &indexed.1), sun, settings.shadow_map_px, cull)
    });
    Some((buf, shadows, indexed))
}

/// The glints of the snow's grains (`snow`: the snow mesh's positions and indices)
/// where the sun reaches them and the eye sees that snow, each lighting its pixel by its
/// face's share of the pixel's footprint, with 12 % of that on the four pixels around
/// that show the scene (the lens's spread: a bright glint blooms past white, a faint
/// far one is lost in the snow's own light). Returns how many glints the sun lights on
/// pixels that show them.
fn draw_glitter(
    (seed, cache): (u64, &mut GlintCache),
    settings: &SnowRenderSettings,
    lighting: &Lighting<'_>,
    (view, eye): (&CameraView, Vec3),
    buf: &DepthBuffer,
    snow: (&[Vec3], &[u32]),
    frame: &mut Frame,
) -> usize {
    let g = &settings.glitter;
    if !(g.grains_per_m2 > 0.0 && g.mirror_radiance > 0.0) || lighting.sun == Vec3::ZERO {
        return 0;
    }
    let up = glinting_faces(snow, lighting, (view, eye), buf, true);
    let gl = cache.glints(&up, Viewing { eye, sun: lighting.sun }, g, seed);
    let colour = SUN_RGB * (settings.sun_strength * g.mirror_radiance * SNOW_ALBEDO);
    let face_m2 = (1e-3 * g.grain_mm).powi(2);
    // Each glint's pixel and light in parallel, added to the frame in the glints' order.
    let shown: Vec<(i64, i64, Vec3, bool)> = gl
        .par_iter()
        .filter_map(|glint| {
            let (x, y, q) = glint_seen(view, buf, glint.position)?;
            let lit = lighting.shadows.as_ref().map_or(1.0, |m| m.lit(glint.position, 1.0));
            let fog = (-settings.fog_per_m * q.depth).exp();
            // The face's share of the pixel's footprint at that depth.
            let share = (face_m2 * q.px_per_m * q.px_per_m).min(1.0);
            Some((x, y, colour * (glint.intensity * lit * fog * share), lit > 0.0))
        })
        .collect();
    add_glints(frame, buf, &shown);
    shown.iter().filter(|s| s.3).count()
}

/// Adds each glint `(x, y, light, _)` (a pixel of the frame) to its pixel and, by
/// [`HALO`], to the four around it, where `buf` shows the scene, in the glints' order:
/// bands of rows in parallel, each adding the glints that reach it, so every pixel sums
/// its glints in the same order as one pass over them all.
fn add_glints(frame: &mut Frame, buf: &DepthBuffer, shown: &[(i64, i64, Vec3, bool)]) {
    let (w, h) = (frame.width() as i64, frame.height() as i64);
    if shown.is_empty() || w == 0 || h == 0 {
        return;
    }
    let mut bands: Vec<Vec<u32>> = vec![Vec::new(); (h as usize).div_ceil(GLINT_BAND_ROWS)];
    for (k, &(_, y, ..)) in shown.iter().enumerate() {
        let (first, last) = ((y - 1).clamp(0, h - 1), (y + 1).clamp(0, h - 1));
        for band in &mut bands[first as usize / GLINT_BAND_ROWS..=last as usize / GLINT_BAND_ROWS] {
            band.push(k as u32);
        }
    }
    frame.par_bands(GLINT_BAND_ROWS, |row0, [r, g, b]| {
        let rows = (row0 as i64)..(row0 as i64 + (r.len() / w as usize) as i64);
        for &k in &bands[row0 / GLINT_BAND_ROWS] {
            let (x, y, c, _) = shown[k as usize];
            for (dx, dy, weight) in [(0, 0, 1.0), (-1, 0, HALO), (1, 0, HALO), (0, -1, HALO), (0, 1, HALO)] {
                let (px, py) = (x + dx, y + dy);
                // Only onto the scene's surfaces (the snow's image covers nothing else).
                if px >= 0 && px < w && rows.contains(&py) && buf.id_at(px as usize, py as usize) != NO_ID {
                    let i = (py - rows.start) as usize * w as usize + px as usize;
                    let add = c * weight;
                    (r[i], g[i], b[i]) = (r[i] + add.x, g[i] + add.y, b[i] + add.z);
                }
            }
        }
    });
}

/// The share of a glint's light on each of the four pixels around its own (the lens's
/// spread).
const HALO: f32 = 0.12;

/// Rows of the frame's bands to which the glints are added in parallel.
const GLINT_BAND_ROWS: usize = 16;

/// The farthest a glint may lie and still be the snow a pixel shows at depth d: 2 cm +
/// 1 % of d behind it (the snow's faces and the depth buffer's rounding), summed in
/// this order (the test's bits). It grows with d.
fn seen_limit(d: f32) -> f32 {
    d + 0.02 + 0.01 * d
}

/// The pixel a glint at `p` lands on and its projection, if the eye sees the snow there
/// (in the frame, and not hidden behind something nearer).
fn glint_seen(view: &CameraView, buf: &DepthBuffer, p: Vec3) -> Option<(i64, i64, Projected)> {
    let q = view.project(p)?;
    let (x, y) = (q.x_px.floor() as i64, q.y_px.floor() as i64);
    let (w, h) = (buf.width() as i64, buf.height() as i64);
    if x < 0 || y < 0 || x >= w || y >= h {
        return None;
    }
    let seen = buf.depth_at(x as usize, y as usize);
    (q.depth <= seen_limit(seen)).then_some((x, y, q))
}

/// The snow's upper faces (of the mesh of `positions` and three `indices` a face) that
/// face the eye and the sun, reach into the frame and are not wholly in shadow: only
/// their grains can glint where the eye sees them. With `skip_hidden` and a perspective
/// or orthographic view, also not those wholly behind what the frame shows there, whose
/// every glint [`glint_seen`] would turn down (the same glints drawn, for less). Each
/// vertex is projected once.
/// In the triangles' order.
fn glinting_faces(
    (positions, indices): (&[Vec3], &[u32]),
    lighting: &Lighting<'_>,
    (view, eye): (&CameraView, Vec3),
    buf: &DepthBuffer,
    skip_hidden: bool,
) -> Vec<[Vec3; 3]> {
    let (fw, fh) = (buf.width() as f32, buf.height() as f32);
    let planar = skip_hidden && view.is_planar();
    let eye_reach = eye.abs().max_element();
    // Each vertex's image once, in parallel (a vertex is a corner of up to six faces).
    let images: Vec<Option<Projected>> = positions.par_iter().map(|&p| view.project(p)).collect();
    // In the frame (or not wholly in front of the eye) and, with `skip_hidden`, not
    // wholly hidden.
    let may_show = |t: &[Vec3; 3], k: [usize; 3]| match screen_box_of(t, k.map(|k| images[k])) {
        None => true,
        Some(b) => {
            b.hi.x >= -2.0
                && b.hi.y >= -2.0
                && b.lo.x <= fw + 2.0
                && b.lo.y <= fh + 2.0
                && !(planar && wholly_hidden(buf, &b, eye_reach))
        }
    };
    // A face whose corners and centre the sun does not reach at all (every shadow-map
    // sample shadowed) has no lit grain, short of a shadow's gap smaller than the face.
    let in_full_shadow = |t: &[Vec3; 3]| {
        lighting.shadows.as_ref().is_some_and(|m| {
            let centre = (t[0] + t[1] + t[2]) / 3.0;
            ![t[0], t[1], t[2], centre].iter().any(|&p| m.any_lit(p, 1.0))
        })
    };
    let face = |f: usize| {
        let k = [indices[3 * f] as usize, indices[3 * f + 1] as usize, indices[3 * f + 2] as usize];
        ([positions[k[0]], positions[k[1]], positions[k[2]]], k)
    };
    // Which to keep, in parallel, straight into place; then those kept, in order.
    let keep: Vec<bool> = (0..indices.len() / 3)
        .into_par_iter()
        .map(|f| {
            let (t, k) = face(f);
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            n.y > 0.0
                && n.dot(eye - t[0]) > 0.0
                && n.dot(lighting.sun) > 0.0
                && may_show(&t, k)
                && !in_full_shadow(&t)
        })
        .collect();
    keep.iter().enumerate().filter(|&(_, &k)| k).map(|(f, _)| face(f).0).collect()
}

/// A triangle's image: its corners' box, pixels, its nearest corner's depth, and the
/// largest size of its corners' coordinates, m.
struct ScreenBox {
    lo: glam::Vec2,
    hi: glam::Vec2,
    near: f32,
    reach: f32,
}

/// The image of `t` whose corners' images are `images`, `None` when a corner does not
/// project (behind the eye).
fn screen_box_of(t: &[Vec3; 3], images: [Option<Projected>; 3]) -> Option<ScreenBox> {
    let mut b = ScreenBox {
        lo: glam::Vec2::splat(f32::INFINITY),
        hi: glam::Vec2::splat(f32::NEG_INFINITY),
        near: f32::INFINITY,
        reach: 0.0,
    };
    for (p, q) in t.iter().zip(images) {
        let q = q?;
        b.reach = b.reach.max(p.abs().max_element());
        b.lo = b.lo.min(glam::Vec2::new(q.x_px, q.y_px));
        b.hi = b.hi.max(glam::Vec2::new(q.x_px, q.y_px));
        b.near = b.near.min(q.depth);
    }
    Some(b)
}

/// Whether every point of a triangle of image `b` lies farther than what each pixel it
/// may land on shows, past [`seen_limit`]: for a perspective or orthographic view,
/// whose depth is linear (so no nearer than the nearest corner) and which maps the
/// triangle into its corners' box (widened by a pixel for rounding). Faces over more
/// than 1,024 pixels are not looked at (false). `eye_reach`: the largest size of the
/// eye's coordinates, m.
fn wholly_hidden(buf: &DepthBuffer, b: &ScreenBox, eye_reach: f32) -> bool {
    let (w, h) = (buf.width() as i64, buf.height() as i64);
    let (x0, y0) = ((b.lo.x.floor() as i64 - 1).max(0), (b.lo.y.floor() as i64 - 1).max(0));
    let (x1, y1) = ((b.hi.x.floor() as i64 + 1).min(w - 1), (b.hi.y.floor() as i64 + 1).min(h - 1));
    if x1 < x0 || y1 < y0 || (x1 - x0 + 1) * (y1 - y0 + 1) > 1024 {
        return false;
    }
    // A glint's place and depth, a few f32 operations on coordinates of these sizes, may
    // come out nearer than the corners by rounding: some 10⁻⁶ of them at most (a few
    // units in the last place), so 10⁻⁵ of them, and 10⁻⁴ of the depth, of slack.
    let nearest = b.near - (1e-4 * b.near + 1e-5 * (b.reach + eye_reach));
    // Hidden when every pixel's limit falls short of it (`seen_limit` never falls as the
    // depth grows, so this is the farthest pixel's limit falling short): stop at the
    // first pixel whose limit does not.
    (y0..=y1).all(|y| (x0..=x1).all(|x| seen_limit(buf.depth_at(x as usize, y as usize)) < nearest))
}

/// What each pixel of `buf` shows, the first `objects` triangles being the scene's.
fn seen(buf: &DepthBuffer, objects: usize) -> Vec<Seen> {
    let kind = |id: u32| match id {
        NO_ID => Seen::Background,
        id if (id as usize) < objects => Seen::Object,
        _ => Seen::Snow,
    };
    buf.ids().iter().map(|&id| kind(id)).collect()
}

/// What lights a point of the scene: the sun (through its shadow map), the sky (as
/// much as the point sees of it) and point lights (a fire).
struct Lighting<'a> {
    settings: &'a SnowRenderSettings,
    /// Unit direction towards the sun.
    sun: Vec3,
    shadows: Option<SunShadow>,
    sky_seen: SkyVisibility<'a>,
    lights: &'a [(Vec3, Vec3)],
}

impl Lighting<'_> {
    /// The light a Lambertian surface of `albedo` at `p` with unit normal `n` sends
    /// back (before fog).
    fn at(&self, p: Vec3, n: Vec3, albedo: Vec3) -> Vec3 {
        let s = self.settings;
        let cos = n.dot(self.sun);
        let sunlit = cos.max(0.0) * self.shadows.as_ref().map_or(1.0, |m| m.lit(p, cos));
        let sky_light = SKY_RGB * (s.sky_strength * self.sky_seen.at(p, n));
        let mut lit = albedo * (SUN_RGB * (s.sun_strength * sunlit) + sky_light);
        for &(at, intensity) in self.lights {
            let d = at - p;
            let r2 = d.length_squared().max(1e-4);
            let cos = n.dot(d / r2.sqrt()).max(0.0);
            lit += albedo * intensity * (cos / (std::f32::consts::PI * r2));
        }
        lit
    }
}

/// Faces meeting at less than this are one smooth surface (a sphere's or a cone's
/// facets), degrees; sharper edges (a box's, a roof's) stay sharp.
const CREASE_DEG: f32 = 40.0;

/// A normal per triangle corner: the area-weighted mean of the normals of the faces
/// sharing that corner's position (bit for bit) that turn less than [`CREASE_DEG`] from
/// this face's, so curved surfaces shade smoothly instead of facet by facet.
fn smooth_normals(tris: &[[Vec3; 3]]) -> Vec<[Vec3; 3]> {
    let key = |p: Vec3| p.to_array().map(f32::to_bits);
    let area_normal: Vec<Vec3> = tris.iter().map(|t| (t[1] - t[0]).cross(t[2] - t[0])).collect();
    let mut around: std::collections::HashMap<[u32; 3], Vec<u32>> = std::collections::HashMap::new();
    for (f, t) in tris.iter().enumerate() {
        for p in t {
            around.entry(key(*p)).or_default().push(f as u32);
        }
    }
    let cos_crease = CREASE_DEG.to_radians().cos();
    tris.iter()
        .zip(&area_normal)
        .map(|(t, own)| {
            let unit = own.normalize_or_zero();
            t.map(|p| {
                let sum = around[&key(p)]
                    .iter()
                    .map(|&g| area_normal[g as usize])
                    .filter(|n| n.normalize_or_zero().dot(unit) >= cos_crease)
                    .fold(Vec3::ZERO, |s, n| s + n);
                let n = sum.normalize_or_zero();
                if n == Vec3::ZERO { unit } else { n }
            })
        })
        .collect()
}

/// The normal at `p` in triangle `tri` interpolated from its corners' `normals`
/// (barycentric weights, clamped to the triangle); `None` for a degenerate triangle.
fn interpolate(tri: [Vec3; 3], normals: [Vec3; 3], p: Vec3) -> Option<Vec3> {
    let (v0, v1, v2) = (tri[1] - tri[0], tri[2] - tri[0], p - tri[0]);
    let (d00, d01, d11) = (v0.dot(v0), v0.dot(v1), v1.dot(v1));
    let (d20, d21) = (v2.dot(v0), v2.dot(v1));
    let den = d00 * d11 - d01 * d01;
    if den.abs() <= f32::EPSILON * d00 * d11 {
        return None;
    }
    let v = ((d11 * d20 - d01 * d21) / den).clamp(0.0, 1.0);
    let w = ((d00 * d21 - d01 * d20) / den).clamp(0.0, 1.0);
    let u = (1.0 - v - w).max(0.0);
    let n = (normals[0] * u + normals[1] * v + normals[2] * w).normalize_or_zero();
    (n != Vec3::ZERO).then_some(n)
}

/// The sun's shadow map: the scene and its snow seen from the sun by a parallel
/// projection over their bounding sphere.
struct SunShadow {
    view: CameraView,
    buf: crate::raster::DepthBuffer,
    /// Size of a shadow-map pixel, m.
    texel_m: f32,
}

impl SunShadow {
    /// The map of `tris` from direction `sun` (unit, towards the sun) at `px` pixels a
    /// side, with faces skipped as `cull` says (see [`SunShadow::framed`]).
    #[cfg(test)]
    fn new(tris: &[[Vec3; 3]], sun: Vec3, px: u32, cull: Cull) -> Option<Self> {
        let bounds = (!tris.is_empty()).then(|| bounds(tris));
        Self::framed(bounds, sun, px, |view| crate::raster::rasterize(view, tris, None, cull))
    }

    /// The map of the triangles of shared vertices and indices `indexed` (towards unit
    /// `sun`, `px` pixels a side, faces skipped as `cull` says; [`rasterize_indexed`]:
    /// the same map as drawing the triangles themselves); see [`SunShadow::framed`].
    fn new_indexed(indexed: (&[Vec3], &[u32]), sun: Vec3, px: u32, cull: Cull) -> Option<Self> {
        let (positions, indices) = indexed;
        // No box to work out for no map (the checks `framed` makes first).
        let drawn = indices.len() >= 3 && px > 0 && sun != Vec3::ZERO;
        let bounds = drawn.then(|| bounds_indexed(positions, indices));
        Self::framed(bounds, sun, px, |view| rasterize_indexed(view, indexed, None, cull))
    }

    /// The map of triangles whose box is `bounds` (`None`: no triangles) from direction
    /// `sun` (unit, towards the sun) at `px` pixels a side, framed on that box and drawn
    /// by `draw`; `None` for no shadows (0 pixels, no sun, nothing to shade, or a map
    /// that cannot be drawn).
    fn framed(
        bounds: Option<(Vec3, Vec3)>,
        sun: Vec3,
        px: u32,
        draw: impl FnOnce(
            &CameraView,
        )
            -> Result<(DepthBuffer, crate::raster::RasterStats), crate::raster::RasterError>,
    ) -> Option<Self> {
        let (lo, hi) = bounds.filter(|_| px > 0 && sun != Vec3::ZERO)?;
        let centre = 0.5 * (lo + hi);
        let radius = (0.5 * (hi - lo).length()).max(1e-3);
        let up = if sun.cross(Vec3::Y).length() > 1e-3 { Vec3::Y } else { Vec3::Z };
        let camera = Camera {
            position: centre + sun * (2.0 * radius),
            look_at: centre,
            up,
            projection: phenomena_core::camera::Projection::Orthographic { height_m: 2.0 * radius },
        };
        let view = camera.view(px as usize, px as usize)?;
        let (buf, _) = draw(&view).ok()?;
        Some(Self { view, buf, texel_m: 2.0 * radius / px as f32 })
    }

    /// Whether any of [`SunShadow::lit`]'s samples is lit (`lit(p, cos) > 0`), stopping at
    /// the first.
    fn any_lit(&self, p: Vec3, cos: f32) -> bool {
        let Some(probe) = self.probe(p, cos) else { return true };
        for dy in -1..=1 {
            for dx in -1..=1 {
                if self.sample_lit(&probe, dx, dy) {
                    return true;
                }
            }
        }
        false
    }

    /// The share of the sun's light reaching `p` (a surface whose normal makes cosine
    /// `cos` with the sun): 3 × 3 shadow-map samples around it (soft edges), each
    /// lit when `p` is no farther from the sun than the nearest surface there, less a
    /// bias of a texel and a half that grows on slopes (no self-shadowing acne).
    fn lit(&self, p: Vec3, cos: f32) -> f32 {
        let Some(probe) = self.probe(p, cos) else { return 1.0 };
        let mut lit = 0;
        for dy in -1..=1 {
            for dx in -1..=1 {
                lit += u32::from(self.sample_lit(&probe, dx, dy));
            }
        }
        lit as f32 / 9.0
    }

    /// Where `p` falls in the map (its texel and depth) and its bias; `None` where it
    /// does not project (lit).
    fn probe(&self, p: Vec3, cos: f32) -> Option<(i64, i64, f32, f32)> {
        let q = self.view.project(p)?;
        let bias = 1.5 * self.texel_m / cos.max(0.2);
        Some((q.x_px.floor() as i64, q.y_px.floor() as i64, q.depth, bias))
    }

    /// Whether the sample (dx, dy) texels from a probe's texel is lit.
    #[inline]
    fn sample_lit(&self, &(cx, cy, depth, bias): &(i64, i64, f32, f32), dx: i64, dy: i64) -> bool {
        let (w, h) = (self.buf.width() as i64, self.buf.height() as i64);
        let (x, y) = ((cx + dx).clamp(0, w - 1), (cy + dy).clamp(0, h - 1));
        depth <= self.buf.depth_at(x as usize, y as usize) + bias
    }
}

/// How much of the sky a surface point sees, from the snow maps' probability P (the
/// share of snowfall directions that reach a texel: the paper's occlusion, a sky
/// visibility around the zenith): P of the map whose surface is at the point for a
/// surface facing up, 1 elsewhere (walls and undersides the maps do not hold). Light
/// the bright snow around reflects keeps a hollow from black: the sky light scales as
/// [`BOUNCE`] + (1 − [`BOUNCE`]) P.
struct SkyVisibility<'a> {
    sim: &'a SnowSim,
    fp: crate::sim::Footprint,
}

impl SkyVisibility<'_> {
    fn at(&self, p: Vec3, n: Vec3) -> f32 {
        if n.y < 0.5 {
            return 1.0;
        }
        let (i, j) = ((p.x - self.fp.origin.x) / self.fp.texel_m, (p.z - self.fp.origin.y) / self.fp.texel_m);
        if !(i >= 0.0 && j >= 0.0 && (i as usize) < self.fp.n && (j as usize) < self.fp.n) {
            return 1.0;
        }
        let k = j as usize * self.fp.n + i as usize;
        let near = 2.0 * self.fp.texel_m;
        self.sim
            .maps()
            .iter()
            .find(|m| m.possible(k) && (m.surface(k) - p.y).abs() <= near)
            .map_or(1.0, |m| BOUNCE + (1.0 - BOUNCE) * m.probability[k])
    }
}

/// The share of the sky light a surface that sees no sky still gets, reflected from the
/// snow around it.
const BOUNCE: f32 = 0.3;

/// Triangles a chunk of [`bounds`] and [`bounds_indexed`] holds.
const BOX_CHUNK: usize = 16_384;

/// The box around `tris` (the origin for none).
fn bounds(tris: &[[Vec3; 3]]) -> (Vec3, Vec3) {
    if tris.is_empty() {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    merged(tris.par_chunks(BOX_CHUNK).map(|chunk| extremes(chunk.iter().copied())).collect())
}

/// The box around the triangles of shared vertices `positions` and three `indices` a
/// triangle: the box [`bounds`] gives for those triangles, in the same chunks (the origin
/// for none).
fn bounds_indexed(positions: &[Vec3], indices: &[u32]) -> (Vec3, Vec3) {
    if indices.len() < 3 {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    let corners = |t: &[u32]| [positions[t[0] as usize], positions[t[1] as usize], positions[t[2] as usize]];
    merged(
        indices.par_chunks(3 * BOX_CHUNK).map(|chunk| extremes(chunk.chunks_exact(3).map(corners))).collect(),
    )
}

/// Nine running extremes of `tris`' corners' coordinates (one per coordinate of a
/// corner: independent comparisons, in vector lanes), smallest and largest.
fn extremes(tris: impl Iterator<Item = [Vec3; 3]>) -> ([f32; 9], [f32; 9]) {
    let (mut lo, mut hi) = ([f32::INFINITY; 9], [f32::NEG_INFINITY; 9]);
    for t in tris {
        let v = [t[0].x, t[0].y, t[0].z, t[1].x, t[1].y, t[1].z, t[2].x, t[2].y, t[2].z];
        for k in 0..9 {
            lo[k] = if v[k] < lo[k] { v[k] } else { lo[k] };
            hi[k] = if v[k] > hi[k] { v[k] } else { hi[k] };
        }
    }
    (lo, hi)
}

/// The box of chunks' [`extremes`], merged in order. The smallest and largest values do
/// not depend on the order they are met in, so this is the box of a one-pass fold (which
/// took 2.2-2.4 ms for the village's 133,000 triangles on one core), equal under `==`: a
/// zero bound met both as +0.0 and −0.0 may keep the other sign, which moves nothing. A
/// NaN coordinate is passed over (an axis of NaNs alone gives +∞ to −∞).
fn merged(parts: Vec<([f32; 9], [f32; 9])>) -> (Vec3, Vec3) {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for (l, h) in parts {
        for k in 0..9 {
            lo[k % 3] = if l[k] < lo[k % 3] { l[k] } else { lo[k % 3] };
            hi[k % 3] = if h[k] > hi[k % 3] { h[k] } else { hi[k % 3] };
        }
    }
    (Vec3::from(lo), Vec3::from(hi))
}

/// Purpose of the flakes' starting places.
const FLAKE: phenomena_core::rng::Purpose = phenomena_core::rng::Purpose::named("snow.flake");

fn draw_flakes(
    sim: &SnowSim,
    flakes: &Flakes,
    view: &phenomena_core::camera::CameraView,
    buf: &crate::raster::DepthBuffer,
    light: f32,
    frame: &mut Frame,
) {
    let dirs = sim.directions();
    let tris = &sim.mesh().triangles;
    if flakes.count == 0 || dirs.is_empty() || tris.is_empty() {
        return;
    }
    let (lo, mut hi) = bounds(tris);
    let extent = hi - lo;
    hi.y += 0.5 * extent.x.max(extent.z);
    let size = (hi - lo).max(Vec3::splat(1e-3));
    let t_s = sim.steps() as f32 / flakes.frames_per_s;
    let (w, h) = (frame.width(), frame.height());
    let r = flakes.radius_px;
    for k in 0..flakes.count {
        let mut rng = phenomena_core::rng::Stream::new(0, FLAKE, u64::from(k));
        let start = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * size;
        let moved = start + dirs[k as usize % dirs.len()] * flakes.fall_m_per_s * t_s;
        let p = lo + moved.rem_euclid(size);
        let Some(q) = view.project(p) else { continue };
        let (cx, cy) = (q.x_px, q.y_px);
        let (x0, x1) = ((cx - r).floor().max(0.0) as usize, ((cx + r).ceil().max(0.0) as usize).min(w));
        let (y0, y1) = ((cy - r).floor().max(0.0) as usize, ((cy + r).ceil().max(0.0) as usize).min(h));
        for y in y0..y1 {
            for x in x0..x1 {
                let (dx, dy) = (x as f32 + 0.5 - cx, y as f32 + 0.5 - cy);
                let cover = (1.0 - (dx * dx + dy * dy).sqrt() / r).clamp(0.0, 1.0);
                if cover > 0.0 && buf.depth_at(x, y) > q.depth {
                    let c = frame.pixel(x, y);
                    frame.set_pixel(x, y, c.lerp(Vec3::splat(1.4 * light), 0.9 * cover));
                }
            }
        }
    }
}

fn render_probability(sim: &SnowSim, width: usize, height: usize) -> Frame {
    // One panel per map, side by side, each showing that map's P_a from above.
    let mut frame = Frame::new(width, height);
    let fp = sim.footprint();
    let n = fp.n;
    let maps = sim.maps().len().max(1);
    let panel = (width / maps).min(height);
    if panel == 0 {
        return frame;
    }
    let x0 = (width - panel * maps) / 2;
    let y0 = (height - panel) / 2;
    for (m, map) in sim.maps().iter().enumerate() {
        for py in 0..panel {
            for px in 0..panel {
                let (u, v) = ((px as f32 + 0.5) / panel as f32, (py as f32 + 0.5) / panel as f32);
                let k = ((v * n as f32) as usize).min(n - 1) * n + ((u * n as f32) as usize).min(n - 1);
                if map.possible(k) {
                    // Dark blue (never reached) to white (always).
                    let c = Vec3::new(0.02, 0.03, 0.12).lerp(Vec3::ONE, map.probability[k]);
                    frame.set_pixel(x0 + m * panel + px, y0 + py, c);
                }
            }
        }
    }
    frame
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::glitter::{Glint, glints};
    use crate::mesh::table_scene;
    use crate::raster::rasterize;
    use crate::sim::SnowConfig;

    #[test]
    fn the_indexed_list_names_the_soups_triangles_in_order() {
        // The shading reads triangle `id` of the depth buffer through the indices: they
        // must name the soup's triangle `id`, the scene's first, then the snow's.
        let sim = snowy_village((60, 8), 20.0, 4);
        let (tris, snow) = triangles(&sim);
        let scene = &sim.mesh().triangles;
        let (positions, indices) = indexed(scene, &snow).expect("fits u32");
        assert!(scene.len() > 100 && snow.triangles() > 100, "both parts present");
        assert_eq!(indices.len(), 3 * tris.len());
        for (t, tri) in tris.iter().enumerate() {
            let corners = [0, 1, 2].map(|k| positions[indices[3 * t + k] as usize]);
            assert_eq!(corners.map(|p| p.to_array()), tri.map(|p| p.to_array()), "triangle {t}");
        }
    }

    #[test]
    fn the_box_is_the_one_pass_folds() {
        // 40,000 triangles (three chunks, the last partial) spread over ±1000 m, with an
        // extreme in a late chunk's last corner.
        let mut rng =
            phenomena_core::rng::Stream::new(3, phenomena_core::rng::Purpose::named("test.bounds"), 0);
        let mut point = || Vec3::new(rng.uniform(-1e3, 1e3), rng.uniform(-1e3, 1e3), rng.uniform(-1e3, 1e3));
        let mut tris: Vec<[Vec3; 3]> = (0..40_000).map(|_| [point(), point(), point()]).collect();
        tris[33_000][2] = Vec3::new(-2e3, 5e3, 1.5e3);
        let fold = |tris: &[[Vec3; 3]]| {
            tris.iter()
                .flatten()
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)))
        };
        for n in [1, 2, 16_384, 16_385, 40_000] {
            assert_eq!(bounds(&tris[..n]), fold(&tris[..n]), "{n} triangles");
        }
        // A zero bound met as +0.0 and −0.0 (a ground at y = 0): equal as numbers.
        let mut ground = tris[..20_000].to_vec();
        for (k, t) in ground.iter_mut().enumerate() {
            t.iter_mut().for_each(|p| p.y = p.y.abs());
            t[k % 3].y = if k % 2 == 0 { 0.0 } else { -0.0 };
        }
        assert_eq!(bounds(&ground), fold(&ground));
        assert_eq!(bounds(&ground).0.y, 0.0);
        assert_eq!(bounds(&tris).0.x, -2e3);
        assert_eq!(bounds(&[]), (Vec3::ZERO, Vec3::ZERO));
        // A NaN coordinate is passed over wherever it lies (glam's fold would start
        // again after it).
        let clean = bounds(&tris);
        tris[100][1].y = f32::NAN;
        tris[20_000][0].x = f32::NAN;
        assert_eq!(bounds(&tris), clean);
        // The same triangles from shared vertices and indices: the same box, bit for bit
        // (zero signs too), the vertices listed in another order than the corners.
        let bits = |(lo, hi): (Vec3, Vec3)| [lo.to_array(), hi.to_array()].map(|v| v.map(f32::to_bits));
        for tris in [&tris[..], &tris[..16_385], &ground[..], &tris[..1], &[]] {
            let corners = 3 * tris.len();
            let positions: Vec<Vec3> = (0..corners).rev().map(|k| tris[k / 3][k % 3]).collect();
            let indices: Vec<u32> = (0..corners).map(|k| (corners - 1 - k) as u32).collect();
            assert_eq!(
                bits(bounds_indexed(&positions, &indices)),
                bits(bounds(tris)),
                "{} triangles",
                tris.len()
            );
        }
    }

    #[test]
    fn glints_added_by_bands_are_the_one_pass_sums() {
        // A 41 × 37 frame (bands of 16, 16 and 5 rows) over a floor that covers only
        // columns 5.. (the rest shows nothing: no glint light there), with glints on the
        // rows either side of each band's edge, on the frame's edges, and many on one
        // pixel (whose sum depends on the order of its terms).
        let (w, h) = (41usize, 37usize);
        let camera = phenomena_core::camera::Camera {
            position: Vec3::new(0.0, 10.0, 0.0),
            look_at: Vec3::ZERO,
            up: Vec3::Z,
            projection: phenomena_core::camera::Projection::Orthographic { height_m: h as f32 },
        };
        let view = camera.view(w, h).unwrap();
        // (The view looks down with +z up the frame, so world x runs leftwards.)
        let (x0, x1, z0, z1) = (-20.5, 20.5 - 5.0, -18.5, 18.5);
        let [a, b, c, d] = [(x0, z0), (x1, z0), (x1, z1), (x0, z1)].map(|(x, z)| Vec3::new(x, 0.0, z));
        let (buf, _) = rasterize(&view, &[[a, c, b], [a, d, c]], None, Cull::None).unwrap();
        assert_eq!(buf.id_at(2, 10), NO_ID);
        assert_ne!(buf.id_at(6, 10), NO_ID);
        let mut rng =
            phenomena_core::rng::Stream::new(5, phenomena_core::rng::Purpose::named("test.glints"), 0);
        let mut shown = Vec::new();
        for y in [0, 1, 14, 15, 16, 17, 31, 32, 33, 35, 36] {
            for x in [0, 4, 5, 6, 20, 39, 40] {
                let light = Vec3::new(rng.uniform(0.0, 3.0), rng.uniform(0.0, 1e-3), rng.uniform(0.0, 7.0));
                shown.push((x, y, light, rng.next_f32() < 0.5));
            }
        }
        for _ in 0..200 {
            let light = Vec3::new(rng.uniform(0.0, 3.0), rng.uniform(0.0, 1e-3), rng.uniform(0.0, 7.0));
            shown.push((20, 16, light, true));
        }
        // The one pass: each glint in turn.
        let mut serial = Frame::new(w, h);
        for &(x, y, c, _) in &shown {
            for (dx, dy, weight) in [(0, 0, 1.0), (-1, 0, HALO), (1, 0, HALO), (0, -1, HALO), (0, 1, HALO)] {
                let (px, py) = (x + dx, y + dy);
                if px >= 0
                    && py >= 0
                    && px < w as i64
                    && py < h as i64
                    && buf.id_at(px as usize, py as usize) != NO_ID
                {
                    let at = serial.pixel(px as usize, py as usize);
                    serial.set_pixel(px as usize, py as usize, at + c * weight);
                }
            }
        }
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut banded = Frame::new(w, h);
            pool.install(|| add_glints(&mut banded, &buf, &shown));
            let bits = |f: &Frame| {
                f.c0.data()
                    .iter()
                    .chain(f.c1.data())
                    .chain(f.c2.data())
                    .map(|v| v.to_bits())
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&banded), bits(&serial), "{threads} threads");
        }
        assert!(serial.pixel(20, 16).x > 0.0 && serial.pixel(6, 17).z > 0.0);
        assert_eq!(serial.pixel(4, 16), Vec3::ZERO);
    }

    fn render(sim: &SnowSim, settings: &SnowRenderSettings, width: usize, height: usize) -> Frame {
        SnowRenderer::new(settings.clone(), width, height, None).unwrap().render(sim).clone()
    }

    /// Stair steps of shading are gone from curved objects: a 24-segment sphere's
    /// smooth corner normals are at most a third as far from the true (radial) normal as
    /// its face normals (about half a facet off; the smooth ones 2.6°, at the
    /// poles' uneven fans); the table's boxes, whose faces meet at 90°, keep their face
    /// normals.
    #[test]
    fn curved_objects_shade_smoothly_and_edges_stay_sharp() {
        let c = Vec3::new(0.0, 1.0, 0.0);
        let tris = crate::mesh::sphere(c, 1.0, 24);
        let smooth = smooth_normals(&tris);
        let angle = |a: Vec3, b: Vec3| a.normalize().dot(b.normalize()).clamp(-1.0, 1.0).acos().to_degrees();
        let (mut worst_smooth, mut worst_face) = (0.0f32, 0.0f32);
        for (t, n) in tris.iter().zip(&smooth) {
            let face = (t[1] - t[0]).cross(t[2] - t[0]);
            for k in 0..3 {
                worst_smooth = worst_smooth.max(angle(n[k], t[k] - c));
                worst_face = worst_face.max(angle(face, t[k] - c));
            }
        }
        assert!(worst_face > 5.0, "face normals {worst_face}° off: the case tests something");
        assert!(worst_smooth < worst_face / 3.0, "smooth normals {worst_smooth}° off, faces {worst_face}°");
        // A corner inside a triangle interpolates: the centre of a facet is near radial.
        let t = tris[tris.len() / 2];
        let mid = (t[0] + t[1] + t[2]) / 3.0;
        let n = interpolate(t, smooth[tris.len() / 2], mid).unwrap();
        assert!(angle(n, mid - c) < worst_face / 3.0);
        let table = crate::mesh::table_scene(4.0, 1.2, 0.7);
        for (t, n) in table.triangles.iter().zip(smooth_normals(&table.triangles)) {
            let face = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
            for k in n {
                assert!(angle(k, face) < 0.01, "a box edge is smoothed");
            }
        }
    }

    #[test]
    fn snow_whitens_the_picture_and_the_probability_map_shows_the_table() {
        let params =
            SnowConfig { map_resolution: 40, directions: 8, rate_cm_per_h: 20.0, ..SnowConfig::default() };
        let mut sim = SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 1).unwrap();
        // Close on the table, so the ground and the table top fill most of the picture.
        let close = Camera {
            position: Vec3::new(3.5, 2.5, 4.5),
            look_at: Vec3::new(0.0, 0.4, 0.0),
            up: Vec3::Y,
            projection: phenomena_core::camera::Projection::Perspective { fov_y_deg: 45.0 },
        };
        let settings = SnowRenderSettings { camera: Some(close), ..SnowRenderSettings::default() };
        let mean = |f: &Frame| f.to_interleaved().iter().map(|&v| f64::from(v)).sum::<f64>();
        let bare = render(&sim, &settings, 96, 64);
        for _ in 0..10 {
            sim.step().unwrap();
        }
        let snowy = render(&sim, &settings, 96, 64);
        assert!(mean(&snowy) > 1.2 * mean(&bare), "{} vs {}", mean(&snowy), mean(&bare));
        let maps = sim.maps().len();
        let p = render(
            &sim,
            &SnowRenderSettings { view: SnowView::Probability, ..settings.clone() },
            64 * maps,
            64,
        );
        // The ground's panel: dark under the table's centre, white in the open; the table
        // top's panel: white at the centre.
        let ground =
            (0..maps).max_by_key(|&m| sim.maps()[m].ground_m.iter().filter(|g| !g.is_nan()).count()).unwrap();
        let top = (0..maps).find(|&m| m != ground && !sim.maps()[m].ground_m[20 * 40 + 20].is_nan()).unwrap();
        assert!(p.pixel(ground * 64 + 32, 32).x < 0.1, "under the table");
        assert!(p.pixel(ground * 64 + 4, 32).x > 0.95, "open ground");
        assert!(p.pixel(top * 64 + 32, 32).x > 0.95, "table top");
    }

    /// Without a camera the scene is framed: every corner of its box is in the picture,
    /// so the scene's pixels reach close to each edge but the sky shows all round it.
    #[test]
    fn without_a_camera_the_geometry_is_framed() {
        let params = SnowConfig { map_resolution: 32, directions: 8, ..SnowConfig::default() };
        for (w, h) in [(160, 90), (90, 160)] {
            let sim = SnowSim::new(table_scene(4.0, 1.2, 0.7), params.clone(), 1).unwrap();
            let frame = render(&sim, &SnowRenderSettings::default(), w, h);
            let scene = |x: usize, y: usize| frame.pixel(x, y) != SKY;
            let (mut x0, mut x1, mut y0, mut y1) = (w, 0, h, 0);
            for y in 0..h {
                for x in 0..w {
                    if scene(x, y) {
                        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
                    }
                }
            }
            assert!(x0 > 0 && y0 > 0 && x1 < w - 1 && y1 < h - 1, "touches an edge: {x0}..{x1}, {y0}..{y1}");
            // The 4 m ground's diagonal nearly spans the bounding sphere: it fills most
            // of the narrower side.
            let fill = ((x1 - x0) as f32 / w as f32).max((y1 - y0) as f32 / h as f32);
            assert!(fill > 0.5, "{w}x{h}: {fill}");
        }
    }

    #[test]
    fn flakes_fall_in_front_of_the_sky_and_move_between_frames() {
        let params = SnowConfig { map_resolution: 32, directions: 8, ..SnowConfig::default() };
        let mut sim = SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 1).unwrap();
        let plain = SnowRenderSettings::default();
        let with =
            SnowRenderSettings { flakes: Flakes { count: 4000, ..Flakes::default() }, ..plain.clone() };
        let a0 = render(&sim, &plain, 160, 120);
        let a1 = render(&sim, &with, 160, 120);
        // Flakes only lighten: every pixel is at least as bright, and many are brighter.
        let lighter = (0..120 * 160)
            .filter(|&i| {
                let (x, y) = (i % 160, i / 160);
                let (p, q) = (a0.pixel(x, y), a1.pixel(x, y));
                assert!(q.y >= p.y - 1e-6 || p.y > 0.9, "flakes darkened ({x}, {y})");
                q.y > p.y + 0.05
            })
            .count();
        assert!(lighter > 200, "{lighter}");
        assert_eq!(a1, render(&sim, &with, 160, 120), "the same frame twice");
        let mask = |sim: &SnowSim| -> Vec<bool> {
            let (p, q) = (render(sim, &plain, 160, 120), render(sim, &with, 160, 120));
            (0..120 * 160).map(|i| q.pixel(i % 160, i / 160).y > p.pixel(i % 160, i / 160).y + 0.05).collect()
        };
        let before = mask(&sim);
        sim.step().unwrap();
        assert_ne!(before, mask(&sim), "flakes moved between frames");
    }

    /// A 50° perspective view from `position` at `look_at`, (width, height) pixels.
    fn view_from(position: Vec3, look_at: Vec3, (w, h): (usize, usize)) -> CameraView {
        let projection = phenomena_core::camera::Projection::Perspective { fov_y_deg: 50.0 };
        Camera { position, look_at, up: Vec3::Y, projection }.view(w, h).unwrap()
    }

    /// The village with (map resolution, directions), after `steps` steps of snow at
    /// `rate` cm/h.
    fn snowy_village((map_resolution, directions): (u32, u32), rate: f32, steps: usize) -> SnowSim {
        let params = SnowConfig { map_resolution, directions, rate_cm_per_h: rate, ..SnowConfig::default() };
        let mut sim = SnowSim::new(crate::mesh::village_scene(), params, 1).unwrap();
        for _ in 0..steps {
            sim.step().unwrap();
        }
        sim
    }

    /// Skipping the faces wholly behind what the frame shows drops no glint the eye
    /// sees: the village (its houses hide snow behind them), from its shipped camera
    /// and from low down, gives the same seen glints with and without the skip, which
    /// drops a good share of the faces.
    #[test]
    fn the_faces_skipped_as_hidden_hold_no_glint_the_eye_sees() {
        let sim = snowy_village((100, 16), 20.0, 10);
        let (tris, snow) = triangles(&sim);
        let scene = sim.mesh().triangles.len();
        let settings = SnowRenderSettings::default();
        let sun = settings.sun_direction.normalize();
        for position in [Vec3::new(24.0, 14.0, 30.0), Vec3::new(18.0, 2.0, 14.0)] {
            let view = view_from(position, Vec3::ZERO, (320, 180));
            let (buf, _) = rasterize(&view, &tris, None, Cull::BackFrom(scene)).unwrap();
            let shadows = SunShadow::new(&tris, sun, settings.shadow_map_px, Cull::BackFrom(scene));
            let sky_seen = SkyVisibility { sim: &sim, fp: sim.footprint() };
            let lighting = Lighting { settings: &settings, sun, shadows, sky_seen, lights: &[] };
            let seen = |faces: &[[Vec3; 3]]| -> Vec<Glint> {
                let viewing = Viewing { eye: position, sun };
                let all = glints(faces, viewing, &settings.glitter, sim.seed());
                all.into_iter().filter(|g| glint_seen(&view, &buf, g.position).is_some()).collect()
            };
            let mesh = (&snow.positions[..], &snow.indices[..]);
            let every = glinting_faces(mesh, &lighting, (&view, position), &buf, false);
            let kept = glinting_faces(mesh, &lighting, (&view, position), &buf, true);
            let (a, b) = (seen(&every), seen(&kept));
            assert!(a.len() > 100, "{position}: {} glints seen: the case tests something", a.len());
            assert_eq!(a, b, "{position}: the glints seen differ");
            assert!(
                kept.len() < every.len() * 9 / 10,
                "{position}: {} of {} faces kept",
                kept.len(),
                every.len()
            );
        }
    }

    /// How the pictures of `closed` and `open` (the scene's `scene` triangles, then the
    /// snow's of `closed_mesh` and `open_mesh`) from `position` looking at `look_at`
    /// compare. On every pixel either both show a triangle of the same corners and, for
    /// the snow's, the same corner normals, at the same depth bits; or (counted, the
    /// first number) `closed` shows a bottom of its snow where `open` shows the scene at
    /// a depth within 10⁻⁴ of it: the bottom lay on that surface, seen from behind, and
    /// won the tie by rounding. The second number: pixels where `open` shows a bottom.
    fn compare_pictures(
        (scene, closed, open): (usize, &[[Vec3; 3]], &[[Vec3; 3]]),
        (closed_mesh, open_mesh): (&TriMesh, &TriMesh),
        position: Vec3,
        look_at: Vec3,
    ) -> (usize, usize) {
        let view = view_from(position, look_at, (640, 360));
        let cull = Cull::BackFrom(scene);
        let (x, _) = rasterize(&view, closed, None, cull).unwrap();
        let (y, _) = rasterize(&view, open, None, cull).unwrap();
        let shown = |id: u32, tris: &[[Vec3; 3]], mesh: &TriMesh| -> Option<([Vec3; 3], [Vec3; 3])> {
            let normals = |t: usize| [0, 1, 2].map(|k| mesh.normals[mesh.indices[3 * t + k] as usize]);
            let k = id as usize;
            (id != NO_ID).then(|| (tris[k], k.checked_sub(scene).map_or([Vec3::ZERO; 3], normals)))
        };
        let bottom = |id: u32, tris: &[[Vec3; 3]]| {
            id != NO_ID && id as usize >= scene && {
                let t = tris[id as usize];
                (t[1] - t[0]).cross(t[2] - t[0]).y < 0.0
            }
        };
        let (mut tied, mut bottoms) = (0, 0);
        for k in 0..x.ids().len() {
            let (a, b) = (x.ids()[k], y.ids()[k]);
            let (da, db) = (x.depth()[k], y.depth()[k]);
            bottoms += usize::from(bottom(b, open));
            if da.to_bits() == db.to_bits() && shown(a, closed, closed_mesh) == shown(b, open, open_mesh) {
                continue;
            }
            let tie = bottom(a, closed) && b != NO_ID && (b as usize) < scene && (da - db).abs() <= 1e-4 * db;
            assert!(tie, "{position}: pixel {k} differs: depth {da} against {db}");
            tied += 1;
        }
        (tied, bottoms)
    }

    /// The scene's triangles then those of `snow`.
    fn with_snow(scene: &[[Vec3; 3]], snow: &TriMesh) -> Vec<[Vec3; 3]> {
        let mut tris = scene.to_vec();
        tris.extend(snow.indices.chunks_exact(3).map(|t| [0, 1, 2].map(|k| snow.positions[t[k] as usize])));
        tris
    }

    /// The snow drawn without the bottoms that lie on its ground is the snow drawn with
    /// them in the village: from its camera, from behind and from low down (under the
    /// benches' snow), the eye's depth buffer and the sun's shadow map are the same bits,
    /// and every pixel shows a triangle of the same corners and normals. (Drawn without
    /// any bottoms, some 30 pixels of the first view, under roofs' eaves, and 110 of the
    /// low one differ.)
    #[test]
    fn the_snow_without_its_hidden_bottoms_draws_the_same_pictures() {
        let sim = snowy_village((200, 64), 5.0, 20);
        let scene = sim.mesh().triangles.clone();
        let (closed_mesh, open_mesh) = (snow_mesh(&sim), snow_surface(&sim));
        let (closed, open) = (with_snow(&scene, &closed_mesh), with_snow(&scene, &open_mesh));
        assert!(open.len() < closed.len() * 3 / 4, "{} of {} triangles", open.len(), closed.len());
        let cull = Cull::BackFrom(scene.len());
        let bits = |d: &[f32]| d.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        let sun = SnowRenderSettings::default().sun_direction.normalize();
        let (a, b) = (
            SunShadow::new(&closed, sun, 2048, cull).unwrap(),
            SunShadow::new(&open, sun, 2048, cull).unwrap(),
        );
        assert!(bits(a.buf.depth()) == bits(b.buf.depth()), "the shadow maps differ");
        for position in
            [Vec3::new(24.0, 14.0, 30.0), Vec3::new(-20.0, 6.0, -26.0), Vec3::new(18.0, 2.0, 14.0)]
        {
            let lists = (scene.len(), closed.as_slice(), open.as_slice());
            let (tied, _) = compare_pictures(lists, (&closed_mesh, &open_mesh), position, Vec3::ZERO);
            assert_eq!(tied, 0, "{position}: pixels differ");
        }
    }

    /// Under an open sheet (one map: two planes meeting at a ridge) seen from below, the
    /// snow's bottoms lay on the sheet and won some pixels by rounding: without them the
    /// sheet shows there, at the same depth within 10⁻⁴. At the crease the corners' mean
    /// ground drops below the ridge, so those bottoms show from below and are kept.
    #[test]
    fn the_bottoms_under_a_crease_stay() {
        let height = |x: f32| 2.4 - 0.2 * x.abs();
        let corner = |x: f32, z: f32| Vec3::new(x, height(x), z);
        let mut mesh = crate::mesh::Mesh::default();
        let mut sheet =
            crate::mesh::quad(corner(-2.0, -2.0), corner(-2.0, 2.0), corner(0.0, 2.0), corner(0.0, -2.0))
                .to_vec();
        sheet.extend(crate::mesh::quad(
            corner(0.0, -2.0),
            corner(0.0, 2.0),
            corner(2.0, 2.0),
            corner(2.0, -2.0),
        ));
        mesh.push_object(&sheet, 0);
        mesh.push_object(&crate::mesh::ground_square(3.0), 1);
        let params = SnowConfig {
            map_resolution: 60,
            directions: 16,
            rate_cm_per_h: 20.0,
            object_groups: Some(vec![0, 1]),
            ..SnowConfig::default()
        };
        let mut sim = SnowSim::new(mesh, params, 1).unwrap();
        for _ in 0..10 {
            sim.step().unwrap();
        }
        let scene = sim.mesh().triangles.clone();
        let (closed_mesh, open_mesh) = (snow_mesh(&sim), snow_surface(&sim));
        let (closed, open) = (with_snow(&scene, &closed_mesh), with_snow(&scene, &open_mesh));
        assert!(open.len() < closed.len(), "no bottom left out: the case tests little");
        let lists = (scene.len(), closed.as_slice(), open.as_slice());
        let below = (Vec3::new(0.3, 0.5, 3.5), Vec3::new(0.0, 2.4, 0.0));
        let (tied, bottoms) = compare_pictures(lists, (&closed_mesh, &open_mesh), below.0, below.1);
        assert!(tied > 1000, "{tied} pixels where a bottom lay on the sheet: the case tests little");
        assert!(bottoms > 0, "no bottom seen from below the crease");
    }
}
