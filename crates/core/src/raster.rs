//! Triangle rasteriser: depth buffers (z-buffers) with an id per pixel, for depth and
//! shadow maps (the snow paper's top-down snow maps and its snowfall-direction depth
//! maps, §2.1-2.2).
//!
//! - Vertices are projected with a planar [`CameraView`] (orthographic or perspective)
//!   and snapped to 1/256 px; coverage uses exact integer edge functions at pixel centres
//!   with the top-left fill rule, so triangles sharing an edge cover each pixel once, with
//!   no gaps and no double coverage.
//! - Depth is interpolated linearly in screen space (orthographic) or as 1/depth
//!   (perspective), in f64, stored as f32.
//! - Each pixel keeps the smallest (depth, id) pair over all fragments: the result does
//!   not depend on the order of the triangles or on the thread count (bands of rows run
//!   in parallel).
//! - Degenerate triangles (zero area, non-finite vertices) and triangles behind a
//!   perspective camera or absurdly far off-screen are skipped and counted; back or front
//!   faces can be culled (front = counter-clockwise as seen by the camera).
//!
//! ```
//! use glam::Vec3;
//! use phenomena_core::camera::{Camera, Projection};
//! use phenomena_core::raster::{Cull, rasterize};
//! // A camera 10 m above the origin looking down, 4 m across 4 pixels.
//! let top = Camera {
//!     position: Vec3::new(0.0, 10.0, 0.0),
//!     look_at: Vec3::ZERO,
//!     up: Vec3::Z,
//!     projection: Projection::Orthographic { height_m: 4.0 },
//! };
//! let view = top.view(4, 4).unwrap();
//! // A floor quad at height 1 m, two triangles.
//! let (a, b, c, d) = (Vec3::new(-2.0, 1.0, -2.0), Vec3::new(2.0, 1.0, -2.0), Vec3::new(2.0, 1.0, 2.0), Vec3::new(-2.0, 1.0, 2.0));
//! let (buf, stats) = rasterize(&view, &[[a, c, b], [a, d, c]], None, Cull::None).unwrap();
//! assert_eq!(stats.drawn, 2);
//! assert!(buf.depth().iter().all(|&z| (z - 9.0).abs() < 1e-6)); // 10 m - 1 m
//! ```

use glam::Vec3;
use rayon::prelude::*;

use crate::camera::CameraView;

/// Which faces to skip.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cull {
    /// Draw both sides.
    None,
    /// Skip faces seen from behind (clockwise as seen by the camera).
    Back,
    /// Skip faces seen from the front (counter-clockwise as seen by the camera).
    Front,
}

/// What happened to the triangles of one rasterisation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RasterStats {
    /// Triangles rasterised (they may still cover no pixel centre).
    pub drawn: usize,
    /// Skipped by the cull mode.
    pub culled: usize,
    /// Skipped: zero area on screen or a non-finite vertex.
    pub degenerate: usize,
    /// Skipped: a vertex behind a perspective camera or more than 2²⁰ px off-screen.
    pub clipped: usize,
}

/// Why a rasterisation cannot run.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RasterError {
    /// The view is a fisheye or panorama: straight edges do not stay straight.
    #[error("the rasteriser needs a perspective or orthographic camera")]
    NotPlanar,
    /// Ids were given but not one per triangle.
    #[error("{ids} ids for {triangles} triangles: give one id per triangle")]
    IdCount {
        /// Ids given.
        ids: usize,
        /// Triangles given.
        triangles: usize,
    },
}

/// A depth buffer with the id of the nearest triangle per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthBuffer {
    width: usize,
    height: usize,
    depth: Vec<f32>,
    id: Vec<u32>,
}

/// Id of pixels no triangle covers.
pub const NO_ID: u32 = u32::MAX;

impl DepthBuffer {
    /// Width, pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height, pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Depth per pixel (distance along the view direction), row-major; +∞ where empty.
    pub fn depth(&self) -> &[f32] {
        &self.depth
    }

    /// Id of the nearest triangle per pixel (its index, or the id given for it);
    /// [`NO_ID`] where empty.
    pub fn ids(&self) -> &[u32] {
        &self.id
    }

    /// Depth at pixel (x, y).
    pub fn depth_at(&self, x: usize, y: usize) -> f32 {
        self.depth[y * self.width + x]
    }

    /// Id at pixel (x, y).
    pub fn id_at(&self, x: usize, y: usize) -> u32 {
        self.id[y * self.width + x]
    }
}

/// Sub-pixel precision of snapped vertices: 1/256 px.
const SUBPIXEL: f64 = 256.0;
/// Largest |coordinate| on screen accepted, pixels (keeps edge functions inside i64).
const MAX_PX: f64 = (1u64 << 20) as f64;
/// Rows per parallel band.
const BAND_ROWS: usize = 16;

/// A triangle prepared for scan conversion.
#[derive(Clone, Copy, Debug)]
struct Setup {
    /// Snapped vertices, 1/256 px, counter-clockwise on screen (y down: the signed area
    /// below is positive).
    v: [(i64, i64); 3],
    /// Depth (orthographic) or 1/depth (perspective) at the vertices, in `v`'s order.
    z: [f64; 3],
    /// Twice the area in (1/256 px)².
    area2: i64,
    /// Pixel rows and columns of the bounding box (inclusive).
    rows: (usize, usize),
    cols: (usize, usize),
    id: u32,
}

/// Rasterise `triangles` (world-space vertices) into a `view`-sized depth buffer. `ids`
/// (one per triangle) are stored instead of the triangle index where given.
pub fn rasterize(
    view: &CameraView,
    triangles: &[[Vec3; 3]],
    ids: Option<&[u32]>,
    cull: Cull,
) -> Result<(DepthBuffer, RasterStats), RasterError> {
    if !view.is_planar() {
        return Err(RasterError::NotPlanar);
    }
    if let Some(ids) = ids
        && ids.len() != triangles.len()
    {
        return Err(RasterError::IdCount { ids: ids.len(), triangles: triangles.len() });
    }
    let (w, h) = view.size();
    let perspective = view.is_perspective();
    let mut stats = RasterStats::default();
    let mut setups = Vec::with_capacity(triangles.len());
    // Set up in parallel (in order), then tally in order.
    let results: Vec<Result<Option<Setup>, Skip>> = triangles
        .par_iter()
        .enumerate()
        .with_min_len(1024)
        .map(|(t, tri)| setup(view, tri, ids.map_or(t as u32, |ids| ids[t]), perspective, cull, w, h))
        .collect();
    for result in results {
        match result {
            Ok(Some(s)) => {
                stats.drawn += 1;
                setups.push(s);
            }
            Ok(None) => stats.drawn += 1, // wholly off-screen: nothing to draw
            Err(Skip::Culled) => stats.culled += 1,
            Err(Skip::Degenerate) => stats.degenerate += 1,
            Err(Skip::Clipped) => stats.clipped += 1,
        }
    }
    // Bin by bands of rows, in triangle order.
    let bands = h.div_ceil(BAND_ROWS);
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); bands];
    for (k, s) in setups.iter().enumerate() {
        for bin in &mut bins[s.rows.0 / BAND_ROWS..=s.rows.1 / BAND_ROWS] {
            bin.push(k as u32);
        }
    }
    let mut depth = vec![f32::INFINITY; w * h];
    let mut id = vec![NO_ID; w * h];
    depth
        .par_chunks_mut(w * BAND_ROWS)
        .zip(id.par_chunks_mut(w * BAND_ROWS))
        .zip(&bins)
        .enumerate()
        .for_each(|(band, ((depth, id), bin))| {
            let r_lo = band * BAND_ROWS;
            let r_hi = r_lo + depth.len() / w;
            for &k in bin {
                let s = &setups[k as usize];
                for_each_fragment(s, r_lo.max(s.rows.0)..r_hi.min(s.rows.1 + 1), |x, y, z| {
                    let i = (y - r_lo) * w + x;
                    let z = if perspective { 1.0 / z } else { z } as f32;
                    if z < depth[i] || (z == depth[i] && s.id < id[i]) {
                        depth[i] = z;
                        id[i] = s.id;
                    }
                });
            }
        });
    Ok((DepthBuffer { width: w, height: h, depth, id }, stats))
}

enum Skip {
    Culled,
    Degenerate,
    Clipped,
}

fn setup(
    view: &CameraView,
    tri: &[Vec3; 3],
    id: u32,
    perspective: bool,
    cull: Cull,
    w: usize,
    h: usize,
) -> Result<Option<Setup>, Skip> {
    if !tri.iter().all(|p| p.is_finite()) {
        return Err(Skip::Degenerate);
    }
    let mut v = [(0i64, 0i64); 3];
    let mut z = [0.0f64; 3];
    for k in 0..3 {
        let p = view.project(tri[k]).ok_or(Skip::Clipped)?;
        let (x, y) = (f64::from(p.x_px), f64::from(p.y_px));
        if !(x.abs() < MAX_PX && y.abs() < MAX_PX) {
            return Err(Skip::Clipped);
        }
        v[k] = (round_half_even(x * SUBPIXEL), round_half_even(y * SUBPIXEL));
        let d = f64::from(p.depth);
        z[k] = if perspective { 1.0 / d } else { d };
    }
    // Signed doubled area with y down: positive for clockwise on screen, which is
    // counter-clockwise as seen by the camera with y up.
    let area2 = (v[1].0 - v[0].0) * (v[2].1 - v[0].1) - (v[1].1 - v[0].1) * (v[2].0 - v[0].0);
    if area2 == 0 {
        return Err(Skip::Degenerate);
    }
    let front = area2 < 0;
    match cull {
        Cull::Back if !front => return Err(Skip::Culled),
        Cull::Front if front => return Err(Skip::Culled),
        _ => {}
    }
    // Orient so that area2 > 0.
    let (v, z, area2) =
        if area2 > 0 { (v, z, area2) } else { ([v[0], v[2], v[1]], [z[0], z[2], z[1]], -area2) };
    let min_x = v.iter().map(|p| p.0).min().unwrap_or(0);
    let max_x = v.iter().map(|p| p.0).max().unwrap_or(0);
    let min_y = v.iter().map(|p| p.1).min().unwrap_or(0);
    let max_y = v.iter().map(|p| p.1).max().unwrap_or(0);
    // Pixel centres (i + 0.5) inside [min, max]: i from ceil(min - 0.5) to floor(max - 0.5),
    // in exact integer arithmetic on the snapped coordinates.
    let (sub, half) = (SUBPIXEL as i64, SUBPIXEL as i64 / 2);
    let first = |lo: i64| (-(-(lo - half)).div_euclid(sub)).max(0);
    let last = |hi: i64, n: usize| (hi - half).div_euclid(sub).min(n as i64 - 1);
    let (c0, c1, r0, r1) = (first(min_x), last(max_x, w), first(min_y), last(max_y, h));
    if c0 > c1 || r0 > r1 {
        return Ok(None);
    }
    Ok(Some(Setup { v, z, area2, rows: (r0 as usize, r1 as usize), cols: (c0 as usize, c1 as usize), id }))
}

/// Round to the nearest integer, ties to even, for |v| < 2⁵¹: adding and subtracting
/// 1.5·2⁵² leaves v rounded by the IEEE addition itself (no library call).
#[inline]
fn round_half_even(v: f64) -> i64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    ((v + MAGIC) - MAGIC) as i64
}

/// Call `f(x, y, depth-or-inverse)` for every pixel centre of `s` in `rows`, by the
/// top-left rule.
fn for_each_fragment(s: &Setup, rows: std::ops::Range<usize>, mut f: impl FnMut(usize, usize, f64)) {
    let [a, b, c] = s.v;
    // Edge k runs from vertex k+1 to k+2; E_k(p) > 0 inside (area2 > 0 orientation).
    let edges = [(b, c), (c, a), (a, b)];
    // Top-left rule: a pixel centre exactly on an edge belongs to the triangle when the
    // edge is a top edge (horizontal, interior below: with y down and this orientation it
    // runs right) or a left edge (interior to its right: it runs up). Two triangles
    // sharing an edge run it in opposite directions, so exactly one owns it.
    let owns: [bool; 3] = edges.map(|(p, q)| {
        let (dx, dy) = (q.0 - p.0, q.1 - p.1);
        (dy == 0 && dx > 0) || dy < 0
    });
    let half = (SUBPIXEL / 2.0) as i64;
    let scale = 1.0 / s.area2 as f64;
    for y in rows {
        let py = y as i64 * SUBPIXEL as i64 + half;
        for x in s.cols.0..=s.cols.1 {
            let px = x as i64 * SUBPIXEL as i64 + half;
            let mut e = [0i64; 3];
            let mut inside = true;
            for k in 0..3 {
                let (p, q) = edges[k];
                // (q - p) × (pt - p) with y down.
                e[k] = (q.0 - p.0) * (py - p.1) - (q.1 - p.1) * (px - p.0);
                // Strictly inside, or on an edge that owns its boundary.
                inside &= e[k] > 0 || (e[k] == 0 && owns[k]);
            }
            if inside {
                // Barycentric weight of vertex k is E_k / area2.
                let z = (e[0] as f64 * s.z[0] + e[1] as f64 * s.z[1] + e[2] as f64 * s.z[2]) * scale;
                f(x, y, z);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Projection};

    /// Looking down from y = 10 over a `size` m square of `n × n` pixels.
    fn top_view(n: usize, size: f32) -> CameraView {
        Camera {
            position: Vec3::new(0.0, 10.0, 0.0),
            look_at: Vec3::ZERO,
            up: Vec3::Z,
            projection: Projection::Orthographic { height_m: size },
        }
        .view(n, n)
        .unwrap()
    }

    fn fragments(view: &CameraView, tri: &[Vec3; 3]) -> Vec<(usize, usize)> {
        let (w, h) = view.size();
        let s = setup(view, tri, 0, false, Cull::None, w, h).ok().flatten();
        let mut out = Vec::new();
        if let Some(s) = s {
            for_each_fragment(&s, s.rows.0..s.rows.1 + 1, |x, y, _| out.push((x, y)));
        }
        out
    }

    #[test]
    fn triangles_sharing_edges_cover_each_pixel_once() {
        // A fan of triangles around an off-grid centre, over a 32 × 32 view: every pixel
        // centre inside the fan's outline is covered exactly once.
        let view = top_view(32, 32.0);
        let c = Vec3::new(0.3, 0.0, -0.7);
        let ring: Vec<Vec3> = (0..7)
            .map(|k| {
                let a = k as f32 / 7.0 * std::f32::consts::TAU;
                Vec3::new(13.0 * a.cos(), 0.0, 13.0 * a.sin())
            })
            .collect();
        let mut count = vec![0u32; 32 * 32];
        for k in 0..7 {
            for (x, y) in fragments(&view, &[c, ring[k], ring[(k + 1) % 7]]) {
                count[y * 32 + x] += 1;
            }
        }
        assert!(count.iter().all(|&n| n <= 1), "a pixel covered twice");
        // The covered area is the heptagon's, to within its perimeter (1 px per px of edge).
        let area = 0.5 * 7.0 * 13.0 * 13.0 * (std::f64::consts::TAU / 7.0).sin();
        let covered = count.iter().filter(|&&n| n == 1).count() as f64;
        let perimeter = 7.0 * 2.0 * 13.0 * (std::f64::consts::PI / 7.0).sin();
        assert!((covered - area).abs() < perimeter, "covered {covered}, area {area}");
        // And axis-aligned pixel-exact squares: a 2-triangle quad over whole pixels.
        let q = [
            Vec3::new(-4.0, 0.0, -4.0),
            Vec3::new(4.0, 0.0, -4.0),
            Vec3::new(4.0, 0.0, 4.0),
            Vec3::new(-4.0, 0.0, 4.0),
        ];
        let mut n = 0;
        n += fragments(&view, &[q[0], q[1], q[2]]).len();
        n += fragments(&view, &[q[0], q[2], q[3]]).len();
        assert_eq!(n, 64);
    }

    #[test]
    fn depth_is_interpolated_and_the_nearest_wins() {
        let view = top_view(16, 16.0);
        // A sloped triangle: height y = 0.25 x + 3.5 (so depth 6.5 - 0.25 x), above a flat
        // one at height 1 everywhere on [-8, 8].
        let slope = |x: f32, z: f32| Vec3::new(x, 0.25 * x + 3.5, z);
        let tri = [slope(-8.0, -8.0), slope(8.0, -8.0), slope(0.0, 8.0)];
        let below = [Vec3::new(-8.0, 1.0, -8.0), Vec3::new(8.0, 1.0, -8.0), Vec3::new(0.0, 1.0, 8.0)];
        let (buf, stats) = rasterize(&view, &[below, tri], None, Cull::None).unwrap();
        assert_eq!(stats.drawn, 2);
        for y in 0..16 {
            for x in 0..16 {
                if buf.id_at(x, y) == NO_ID {
                    continue;
                }
                // Pixel centre x in world: image x grows to the right = -world x here
                // (camera up +z, looking down -y: right = forward × up = -x).
                let wx = 8.0 - (x as f32 + 0.5);
                let expected = 6.5 - 0.25 * wx;
                assert_eq!(buf.id_at(x, y), 1, "the upper triangle is nearer");
                assert!((buf.depth_at(x, y) - expected).abs() < 1e-4, "({x}, {y})");
            }
        }
    }

    #[test]
    fn ties_go_to_the_smaller_id_and_order_does_not_matter() {
        let view = top_view(8, 8.0);
        let t = [Vec3::new(-4.0, 0.0, -4.0), Vec3::new(4.0, 0.0, -4.0), Vec3::new(0.0, 0.0, 4.0)];
        let (a, _) = rasterize(&view, &[t, t], Some(&[7, 3]), Cull::None).unwrap();
        let (b, _) = rasterize(&view, &[t, t], Some(&[3, 7]), Cull::None).unwrap();
        assert_eq!(a, b);
        assert!(a.ids().iter().all(|&i| i == 3 || i == NO_ID));
    }

    #[test]
    fn culling_and_degenerate_triangles_are_counted() {
        let view = top_view(8, 8.0);
        // Counter-clockwise seen from above (+y): x to z... with up = +z and right = -x.
        let ccw = [Vec3::new(-3.0, 0.0, -3.0), Vec3::new(-3.0, 0.0, 3.0), Vec3::new(3.0, 0.0, -3.0)];
        let cw = [ccw[0], ccw[2], ccw[1]];
        let flat = [ccw[0], ccw[0], ccw[1]];
        let bad = [Vec3::NAN, ccw[1], ccw[2]];
        let (_, s) = rasterize(&view, &[ccw, cw, flat, bad], None, Cull::Back).unwrap();
        assert_eq!((s.drawn, s.culled, s.degenerate), (1, 1, 2));
        // Which one is front: the face whose normal points at the camera.
        let n = (ccw[1] - ccw[0]).cross(ccw[2] - ccw[0]);
        assert!(n.y > 0.0, "ccw's right-handed normal points up, at the camera");
        let (buf, _) = rasterize(&view, &[ccw, cw], None, Cull::Back).unwrap();
        assert!(buf.ids().iter().all(|&i| i == 0 || i == NO_ID));
        assert!(buf.ids().contains(&0));
    }

    #[test]
    fn any_thread_count_gives_the_same_buffer() {
        let view = top_view(100, 10.0);
        let mut tris = Vec::new();
        let mut s = 1u64;
        let mut r = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 33) as f32 / (1u64 << 31) as f32) * 10.0 - 5.0
        };
        for _ in 0..500 {
            tris.push([Vec3::new(r(), r(), r()), Vec3::new(r(), r(), r()), Vec3::new(r(), r(), r())]);
        }
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| rasterize(&view, &tris, None, Cull::None).unwrap().0)
        };
        let one = run(1);
        assert_eq!(one, run(2));
        assert_eq!(one, run(3));
        assert!(one.ids().iter().filter(|&&i| i != NO_ID).count() > 5000);
    }

    #[test]
    fn perspective_depth_is_exact_at_pixel_centres() {
        // A plane facing a perspective camera at distance 5: depth 5 everywhere; a plane
        // tilted 45°: depth along the view direction follows the plane exactly (1/depth is
        // linear in screen space).
        let cam = Camera {
            position: Vec3::new(0.0, 0.0, 5.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            projection: Projection::Perspective { fov_y_deg: 60.0 },
        };
        let view = cam.view(40, 40).unwrap();
        let tilted = [Vec3::new(-3.0, -3.0, -3.0), Vec3::new(3.0, -3.0, 3.0), Vec3::new(0.0, 3.0, 0.0)];
        let (buf, _) = rasterize(&view, &[tilted], None, Cull::None).unwrap();
        let mut checked = 0;
        for y in 0..40 {
            for x in 0..40 {
                let d = buf.depth_at(x, y);
                if d.is_infinite() {
                    continue;
                }
                // The ray through the pixel centre meets the plane z = x (world) at depth t:
                // eye (0,0,5) + t·dir, with dir.z/dir.x known: solve 5 + t dz = t dx.
                let (o, dir) = view.ray(x as f32 + 0.5, y as f32 + 0.5);
                let t = (o.z - o.x) / (dir.x - dir.z);
                let depth = (dir * t).dot(view.forward());
                assert!((d - depth).abs() < 1e-4 * depth, "({x}, {y}): {d} vs {depth}");
                checked += 1;
            }
        }
        assert!(checked > 100);
    }
}
