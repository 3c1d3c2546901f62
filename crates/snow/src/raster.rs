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
//! use phenomena_snow::raster::{Cull, rasterize};
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

use phenomena_core::camera::CameraView;

/// Which faces to skip.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cull {
    /// Draw both sides.
    None,
    /// Skip faces seen from behind (clockwise as seen by the camera).
    Back,
    /// Skip faces seen from the front (counter-clockwise as seen by the camera).
    Front,
    /// Skip back faces among the first `n` triangles, draw both sides of the rest: for
    /// scenes that list their closed, outward-facing solids first. Seen from outside, the
    /// nearest surface of a closed solid is always a face turned towards the camera, so
    /// the depth buffer is the same as with [`Cull::None`] (up to which face owns a
    /// pixel centre lying exactly on a silhouette), with fewer fragments drawn.
    BackAmongFirst(usize),
    /// Skip back faces among the triangles from the `n`th on, draw both sides of those
    /// before: for scenes that list their closed, outward-facing solids last (the
    /// snow's, after the scene's own), with the same depth buffer as [`Cull::None`] as
    /// for [`Cull::BackAmongFirst`].
    BackFrom(usize),
}

/// What happened to the triangles of one rasterisation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RasterStats {
    /// Triangles rasterised (they may still cover no pixel centre).
    pub drawn: usize,
    /// Skipped by the cull mode (with an orthographic view, faces culled in world space
    /// before projection count here even when more than 2²⁰ px off-screen).
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
    /// Indexed triangles whose indices are not three a triangle, each naming a vertex.
    #[error(
        "{indices} indices into {vertices} vertices: not three a triangle, each below the vertices' count"
    )]
    Indices {
        /// Indices given.
        indices: usize,
        /// Vertices given.
        vertices: usize,
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
/// Rows per parallel band (large triangles).
const BAND_ROWS: usize = 16;
/// Triangles whose bounding box holds more pixels than this are drawn by bands of rows
/// in parallel; smaller ones by contiguous runs of triangles, each into its own buffer.
const LARGE_PX: usize = 4096;
/// Triangles per run handed to one part.
const RUN: usize = 64;
/// Largest total size of the per-thread buffers, bytes.
const PARTS_BYTES: usize = 64 << 20;

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

impl Setup {
    fn box_px(&self) -> usize {
        (self.rows.1 - self.rows.0 + 1) * (self.cols.1 - self.cols.0 + 1)
    }
}

/// Rasterise `triangles` (world-space vertices) into a `view`-sized depth buffer. `ids`
/// (one per triangle) are stored instead of the triangle index where given.
pub fn rasterize(
    view: &CameraView,
    triangles: &[[Vec3; 3]],
    ids: Option<&[u32]>,
    cull: Cull,
) -> Result<(DepthBuffer, RasterStats), RasterError> {
    let mut r = Rasterizer::default();
    let stats = r.draw(view, triangles, ids, cull)?.1;
    let buf = r.parts.swap_remove(0);
    Ok((buf, stats))
}

/// [`rasterize`] for triangles given as shared vertices `positions` and three
/// `indices` a triangle: each vertex is projected once, not once per triangle corner.
/// The same buffer and counts as [`rasterize`] of the triangles the indices name.
pub fn rasterize_indexed(
    view: &CameraView,
    (positions, indices): (&[Vec3], &[u32]),
    ids: Option<&[u32]>,
    cull: Cull,
) -> Result<(DepthBuffer, RasterStats), RasterError> {
    let mut r = Rasterizer::default();
    let stats = r.draw_indexed(view, (positions, indices), ids, cull)?.1;
    let buf = r.parts.swap_remove(0);
    Ok((buf, stats))
}

/// A rasteriser that keeps its buffers between calls, for many rasterisations of the
/// same size (a depth map per snowfall direction): [`rasterize`] without allocating
/// the buffers again ([`Rasterizer::draw_indexed`] still makes its table of projected
/// vertices each call). Same output as [`rasterize`].
///
/// How it runs: runs of `RUN` consecutive triangles are dealt round-robin to a few
/// parts (about one per thread), each drawing into a buffer of its own; the parts are
/// merged pixel by pixel; triangles with large bounding boxes are then drawn into the
/// merged buffer by bands of rows in parallel. Every step keeps the smallest (depth, id)
/// pair, which does not depend on the order, so the buffer is the same for any thread
/// count (tested).
#[derive(Clone, Debug, Default)]
pub struct Rasterizer {
    parts: Vec<DepthBuffer>,
    serial: bool,
}

impl Rasterizer {
    /// A rasteriser that draws on the calling thread only (same buffers as the parallel
    /// one): for callers that already run one rasterisation per thread.
    pub fn serial() -> Self {
        Self { parts: Vec::new(), serial: true }
    }

    /// Rasterise into the kept buffer and borrow it; see [`rasterize`].
    pub fn draw(
        &mut self,
        view: &CameraView,
        triangles: &[[Vec3; 3]],
        ids: Option<&[u32]>,
        cull: Cull,
    ) -> Result<(&DepthBuffer, RasterStats), RasterError> {
        if !view.is_planar() {
            return Err(RasterError::NotPlanar);
        }
        self.draw_source(view, Projector::new(view), Source::Soup(triangles), ids, cull)
    }

    /// Rasterise indexed triangles into the kept buffer and borrow it; see
    /// [`rasterize_indexed`].
    pub fn draw_indexed(
        &mut self,
        view: &CameraView,
        (positions, indices): (&[Vec3], &[u32]),
        ids: Option<&[u32]>,
        cull: Cull,
    ) -> Result<(&DepthBuffer, RasterStats), RasterError> {
        if !view.is_planar() {
            return Err(RasterError::NotPlanar);
        }
        let named = |&k: &u32| (k as usize) < positions.len();
        if indices.len() % 3 != 0 || !indices.par_iter().all(named) {
            return Err(RasterError::Indices { indices: indices.len(), vertices: positions.len() });
        }
        let (projector, perspective) = (Projector::new(view), view.is_perspective());
        // Every vertex once, in parallel: what each triangle corner naming it would give.
        let corners: Vec<Corner> =
            positions.par_iter().map(|&p| corner(&projector, p, perspective)).collect();
        self.draw_source(
            view,
            projector,
            Source::Indexed { positions, indices, corners: &corners },
            ids,
            cull,
        )
    }

    /// Draw `source` as `projector` (of `view`) projects it.
    fn draw_source(
        &mut self,
        view: &CameraView,
        projector: Projector<'_>,
        source: Source<'_>,
        ids: Option<&[u32]>,
        cull: Cull,
    ) -> Result<(&DepthBuffer, RasterStats), RasterError> {
        let triangles = source.len();
        if let Some(ids) = ids
            && ids.len() != triangles
        {
            return Err(RasterError::IdCount { ids: ids.len(), triangles });
        }
        let (w, h) = view.size();
        let job = Job { projector, source, ids, cull, perspective: view.is_perspective(), w, h };
        let parts = self.prepare_parts(w, h, triangles);
        let runs = triangles.div_ceil(RUN);
        let results: Vec<(RasterStats, Vec<Setup>)> = self
            .parts
            .par_iter_mut()
            .enumerate()
            .map(|(part, buf)| job.draw_runs(buf, (part..runs).step_by(parts)))
            .collect();
        let mut stats = RasterStats::default();
        let mut large = Vec::new();
        for (s, l) in results {
            stats.drawn += s.drawn;
            stats.culled += s.culled;
            stats.degenerate += s.degenerate;
            stats.clipped += s.clipped;
            large.extend(l);
        }
        let (first, rest) = self.parts.split_first_mut().expect("at least one part");
        merge_parts(first, rest);
        job.draw_large(first, &large, self.serial);
        Ok((&self.parts[0], stats))
    }

    /// Keep one buffer per part and return the number of parts: one per thread, but no
    /// more than there are runs of `triangles` triangles to share, nor more than 64 MB of
    /// `w × h` buffers (8 bytes a pixel): a 4K frame gets one part.
    fn prepare_parts(&mut self, w: usize, h: usize, triangles: usize) -> usize {
        let threads = if self.serial { 1 } else { rayon::current_num_threads() };
        let budget = (PARTS_BYTES / (w * h * 8).max(1)).max(1);
        let parts = threads.min(triangles.div_ceil(RUN)).min(budget).clamp(1, 16);
        self.parts.truncate(parts);
        while self.parts.len() < parts {
            self.parts.push(DepthBuffer { width: 0, height: 0, depth: Vec::new(), id: Vec::new() });
        }
        parts
    }
}

/// One rasterisation: the triangles, how they are projected and culled, and the size of
/// the buffer (`w × h` px).
struct Job<'a> {
    projector: Projector<'a>,
    source: Source<'a>,
    ids: Option<&'a [u32]>,
    cull: Cull,
    perspective: bool,
    w: usize,
    h: usize,
}

impl Job<'_> {
    /// Clear `buf` to the buffer's size and draw the triangles of `runs` (runs of `RUN`
    /// consecutive triangles) into it, except the large ones, which are returned (in
    /// triangle order) with the counts.
    fn draw_runs(
        &self,
        buf: &mut DepthBuffer,
        runs: impl Iterator<Item = usize>,
    ) -> (RasterStats, Vec<Setup>) {
        let (w, h, perspective, triangles) = (self.w, self.h, self.perspective, self.source.len());
        buf.width = w;
        buf.height = h;
        buf.depth.clear();
        buf.depth.resize(w * h, f32::INFINITY);
        buf.id.clear();
        buf.id.resize(w * h, NO_ID);
        let mut stats = RasterStats::default();
        let mut large = Vec::new();
        for run in runs {
            let first = run * RUN;
            for t in first..(first + RUN).min(triangles) {
                let id = self.ids.map_or(t as u32, |ids| ids[t]);
                let cull = match self.cull {
                    Cull::BackAmongFirst(n) if t < n => Cull::Back,
                    Cull::BackAmongFirst(_) => Cull::None,
                    Cull::BackFrom(n) if t >= n => Cull::Back,
                    Cull::BackFrom(_) => Cull::None,
                    c => c,
                };
                if self.source.surely_culled(t, &self.projector, cull) {
                    stats.culled += 1;
                    continue;
                }
                let corners = self.source.corners(t, &self.projector, perspective);
                match setup_corners(corners, id, cull, w, h) {
                    Ok(Some(s)) => {
                        stats.drawn += 1;
                        if s.box_px() > LARGE_PX {
                            large.push(s);
                        } else {
                            draw(&s, s.rows.0..s.rows.1 + 1, 0, w, perspective, &mut buf.depth, &mut buf.id);
                        }
                    }
                    Ok(None) => stats.drawn += 1, // wholly off-screen: nothing to draw
                    Err(Skip::Culled) => stats.culled += 1,
                    Err(Skip::Degenerate) => stats.degenerate += 1,
                    Err(Skip::Clipped) => stats.clipped += 1,
                }
            }
        }
        (stats, large)
    }

    /// Draw the `large` triangles into the merged buffer `first`: on this thread when
    /// `serial`, else binned by bands of `BAND_ROWS` rows and the bands drawn in parallel.
    fn draw_large(&self, first: &mut DepthBuffer, large: &[Setup], serial: bool) {
        let (w, h, perspective) = (self.w, self.h, self.perspective);
        if serial {
            for s in large {
                draw(s, s.rows.0..s.rows.1 + 1, 0, w, perspective, &mut first.depth, &mut first.id);
            }
        } else if !large.is_empty() {
            let bands = h.div_ceil(BAND_ROWS);
            let mut bins: Vec<Vec<u32>> = vec![Vec::new(); bands];
            for (k, s) in large.iter().enumerate() {
                for bin in &mut bins[s.rows.0 / BAND_ROWS..=s.rows.1 / BAND_ROWS] {
                    bin.push(k as u32);
                }
            }
            first
                .depth
                .par_chunks_mut(w * BAND_ROWS)
                .zip(first.id.par_chunks_mut(w * BAND_ROWS))
                .zip(&bins)
                .enumerate()
                .for_each(|(band, ((depth, id), bin))| {
                    let r_lo = band * BAND_ROWS;
                    let r_hi = r_lo + depth.len() / w;
                    for &k in bin {
                        let s = &large[k as usize];
                        draw(s, r_lo.max(s.rows.0)..r_hi.min(s.rows.1 + 1), r_lo, w, perspective, depth, id);
                    }
                });
        }
    }
}

/// Merge the parts' buffers `rest` into `first`, pixel by pixel, keeping the smallest
/// (depth, id) pair.
fn merge_parts(first: &mut DepthBuffer, rest: &[DepthBuffer]) {
    if !rest.is_empty() {
        const CHUNK: usize = 4096;
        first.depth.par_chunks_mut(CHUNK).zip(first.id.par_chunks_mut(CHUNK)).enumerate().for_each(
            |(c, (depth, id))| {
                let at = c * CHUNK;
                for other in rest.iter() {
                    let (od, oi) = (&other.depth[at..at + depth.len()], &other.id[at..at + id.len()]);
                    for (((d, i), &od), &oi) in depth.iter_mut().zip(id.iter_mut()).zip(od).zip(oi) {
                        if od < *d || (od == *d && oi < *i) {
                            *d = od;
                            *i = oi;
                        }
                    }
                }
            },
        );
    }
}

/// Draw `s`'s fragments in `rows` into buffers whose first row is `row0`, keeping the
/// smallest (depth, id) per pixel.
#[inline]
fn draw(
    s: &Setup,
    rows: std::ops::Range<usize>,
    row0: usize,
    w: usize,
    perspective: bool,
    depth: &mut [f32],
    id: &mut [u32],
) {
    for_each_fragment(s, rows, |x, y, z| {
        let i = (y - row0) * w + x;
        let z = if perspective { 1.0 / z } else { z } as f32;
        if z < depth[i] || (z == depth[i] && s.id < id[i]) {
            depth[i] = z;
            id[i] = s.id;
        }
    });
}

enum Skip {
    Culled,
    Degenerate,
    Clipped,
}

/// The triangles of one rasterisation.
#[derive(Clone, Copy)]
enum Source<'a> {
    /// Three world-space corners each.
    Soup(&'a [[Vec3; 3]]),
    /// Three indices each into `positions`, whose projections are `corners`.
    Indexed { positions: &'a [Vec3], indices: &'a [u32], corners: &'a [Corner] },
}

impl Source<'_> {
    fn len(&self) -> usize {
        match self {
            Self::Soup(tris) => tris.len(),
            Self::Indexed { indices, .. } => indices.len() / 3,
        }
    }

    /// Triangle `t`'s indices into the positions (indexed only).
    fn indices(indices: &[u32], t: usize) -> [usize; 3] {
        [0, 1, 2].map(|c| indices[3 * t + c] as usize)
    }

    /// Whether triangle `t` is surely culled before it is projected (an indexed
    /// triangle is tested only in an affine view: in a perspective one its projected
    /// corners decide).
    fn surely_culled(&self, t: usize, projector: &Projector<'_>, cull: Cull) -> bool {
        match *self {
            Self::Soup(tris) => projector.surely_culled(&tris[t], cull),
            Self::Indexed { positions, indices, .. } => {
                projector.is_affine()
                    && projector.surely_culled(&Self::indices(indices, t).map(|k| positions[k]), cull)
            }
        }
    }

    /// Triangle `t`'s corners as [`setup_corners`] takes them: a soup's projected now,
    /// an indexed triangle's as its vertices were projected.
    fn corners(&self, t: usize, projector: &Projector<'_>, perspective: bool) -> [Corner; 3] {
        match *self {
            Self::Soup(tris) => tris[t].map(|p| corner(projector, p, perspective)),
            Self::Indexed { indices, corners, .. } => Self::indices(indices, t).map(|k| corners[k]),
        }
    }
}

/// A vertex as [`setup_corners`] meets it.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Corner {
    /// Snapped to 1/256 px, with its depth (orthographic) or 1/depth (perspective).
    At((i64, i64), f64),
    /// A coordinate is not finite.
    NonFinite,
    /// Behind a perspective camera or more than [`MAX_PX`] off-screen.
    Clipped,
}

/// Vertex `p` projected and snapped for [`setup_corners`].
#[inline(always)]
fn corner(view: &Projector, p: Vec3, perspective: bool) -> Corner {
    if !p.is_finite() {
        return Corner::NonFinite;
    }
    let Some((x, y, d)) = view.project(p) else { return Corner::Clipped };
    let (x, y) = (f64::from(x), f64::from(y));
    if !(x.abs() < MAX_PX && y.abs() < MAX_PX) {
        return Corner::Clipped;
    }
    let d = f64::from(d);
    Corner::At(
        (round_half_even(x * SUBPIXEL), round_half_even(y * SUBPIXEL)),
        if perspective { 1.0 / d } else { d },
    )
}

/// Projection to pixels and depth: an orthographic view as three affine maps (nine
/// multiply-adds per vertex), any other planar view through [`CameraView::project`].
#[derive(Clone, Copy)]
enum Projector<'a> {
    /// Rows for x px, y px and depth; the view direction and pixels per metre.
    Affine([[f32; 4]; 3], Vec3, f32),
    View(&'a CameraView),
}

impl<'a> Projector<'a> {
    fn new(view: &'a CameraView) -> Self {
        view.orthographic_affine().map_or(Self::View(view), |[x, y, d]| {
            Self::Affine([x, y, d].map(|r| r.to_array()), d.truncate(), x.truncate().length())
        })
    }

    /// Whether [`Projector::surely_culled`] can ever answer yes.
    fn is_affine(&self) -> bool {
        matches!(self, Self::Affine(..))
    }

    /// (x px, y px, depth); `None` behind a perspective camera.
    #[inline(always)]
    fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        match self {
            Self::Affine(r, ..) => {
                let row = |r: &[f32; 4]| r[0] * p.x + r[1] * p.y + r[2] * p.z + r[3];
                Some((row(&r[0]), row(&r[1]), row(&r[2])))
            }
            Self::View(view) => view.project(p).map(|q| (q.x_px, q.y_px, q.depth)),
        }
    }

    /// Whether `cull` skips `tri` for certain, decided in world space before any
    /// projection (orthographic views only; `false` when unsure). A face is turned away
    /// when its normal n = (b − a) × (c − a) points along the view direction f; on
    /// screen, before rounding, its doubled area is s²(n·f) for s pixels per metre. The
    /// answer is only `true` when s²|n·f| exceeds a bound on every difference between
    /// that and the snapped doubled area [`setup_corners`] tests:
    /// - f32 rounding of n·f and of the rows' own axes: allowed 10⁻⁵ of
    ///   s²|b − a|₁|c − a|₁, far above the few ulps they can be;
    /// - each screen coordinate moved by δ at most: 1/512 px by snapping to 1/256 px, plus
    ///   the f32 rounding of the affine map, at most 4ε(s|p|₁ + |offset|) px for a vertex
    ///   p (ε = 2⁻²⁴; this grows with distance from the origin). Both edges' screen
    ///   components then move by 2δ at most, changing the doubled area by at most
    ///   2δ(|e₁'|₁ + |e₂'|₁) + 8δ², and a world edge e spans at most 2s|e|₁ pixels in
    ///   L1 on screen: 4δs(|b − a|₁ + |c − a|₁) + 8δ², plus 10⁻³ px² to spare.
    ///
    /// So it never skips a triangle that [`setup_corners`] would draw, and the buffer is the same
    /// with or without it (tested, near the origin and 10⁴ m from it).
    #[inline(always)]
    fn surely_culled(&self, tri: &[Vec3; 3], cull: Cull) -> bool {
        let &Self::Affine(rows, forward, s) = self else { return false };
        let want = match cull {
            Cull::Back => 1.0,
            Cull::Front => -1.0,
            _ => return false,
        };
        let (e1, e2) = (tri[1] - tri[0], tri[2] - tri[0]);
        let facing = want * e1.cross(e2).dot(forward);
        let (l1, l2) = (e1.abs().element_sum(), e2.abs().element_sum());
        let far = tri[0].abs().element_sum().max(tri[1].abs().element_sum()).max(tri[2].abs().element_sum());
        let offset = rows[0][3].abs().max(rows[1][3].abs());
        let delta = 1.0 / 512.0 + 4.0 * f32::EPSILON * 0.5 * (s * far + offset);
        let margin = s * s * 1e-5 * l1 * l2 + 4.0 * delta * s * (l1 + l2) + 8.0 * delta * delta + 1e-3;
        s * s * facing > margin
    }
}

/// The old one-triangle entry: [`setup_corners`] of `tri`'s corners.
#[cfg(test)]
fn setup(
    view: &Projector,
    tri: &[Vec3; 3],
    id: u32,
    perspective: bool,
    cull: Cull,
    w: usize,
    h: usize,
) -> Result<Option<Setup>, Skip> {
    setup_corners(tri.map(|p| corner(view, p, perspective)), id, cull, w, h)
}

/// The triangle of `corners` (projected by [`corner`]) ready to draw; `None` when its
/// bounding box holds no pixel centre of the `w × h` buffer. Skipped when a corner is not finite
/// (degenerate), then when one is clipped, then by its snapped area and `cull`.
fn setup_corners(
    corners: [Corner; 3],
    id: u32,
    cull: Cull,
    w: usize,
    h: usize,
) -> Result<Option<Setup>, Skip> {
    if corners.contains(&Corner::NonFinite) {
        return Err(Skip::Degenerate);
    }
    let mut v = [(0i64, 0i64); 3];
    let mut z = [0.0f64; 3];
    for k in 0..3 {
        let Corner::At(at, depth) = corners[k] else { return Err(Skip::Clipped) };
        (v[k], z[k]) = (at, depth);
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

/// Round to the nearest integer, ties to even, for |v| < 2⁵¹: adding 1.5·2⁵² leaves v
/// rounded by the IEEE addition itself, as the low bits of the sum's significand (the
/// exponent is fixed over the whole range), so the integer is a difference of bit
/// patterns (no library call, no saturating conversion).
#[inline]
fn round_half_even(v: f64) -> i64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    (v + MAGIC).to_bits() as i64 - MAGIC.to_bits() as i64
}

/// Call `f(x, y, depth-or-inverse)` for every pixel centre of `s` in `rows`, by the
/// top-left rule.
#[inline(always)]
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
    let sub = SUBPIXEL as i64;
    let scale = 1.0 / s.area2 as f64;
    // E_k at a pixel centre, exact; it changes by a constant per pixel along a row. A
    // centre is inside when every E_k + owns_k - 1 ≥ 0 (E_k > 0, or 0 on an owned edge).
    let step: [i64; 3] = edges.map(|(p, q)| -(q.1 - p.1) * sub);
    let bias: [i64; 3] = owns.map(|o| i64::from(o) - 1);
    let px0 = s.cols.0 as i64 * sub + half;
    for y in rows {
        let py = y as i64 * sub + half;
        // (q - p) × (pt - p) with y down, for each edge (p, q).
        let edge = |(p, q): ((i64, i64), (i64, i64))| (q.0 - p.0) * (py - p.1) - (q.1 - p.1) * (px0 - p.0);
        let mut e = [edge(edges[0]), edge(edges[1]), edge(edges[2])];
        let mut entered = false;
        for x in s.cols.0..=s.cols.1 {
            if ((e[0] + bias[0]) | (e[1] + bias[1]) | (e[2] + bias[2])) >= 0 {
                entered = true;
                // Barycentric weight of vertex k is E_k / area2.
                let z = (e[0] as f64 * s.z[0] + e[1] as f64 * s.z[1] + e[2] as f64 * s.z[2]) * scale;
                f(x, y, z);
            } else if entered {
                // A triangle's pixels in a row are one run.
                break;
            }
            for (e, step) in e.iter_mut().zip(step) {
                *e += step;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use phenomena_core::camera::{Camera, Projection};

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
        let s = setup(&Projector::new(view), tri, 0, false, Cull::None, w, h).ok().flatten();
        let mut out = Vec::new();
        if let Some(s) = s {
            for_each_fragment(&s, s.rows.0..s.rows.1 + 1, |x, y, _| out.push((x, y)));
        }
        out
    }

    #[test]
    fn rounding_is_to_nearest_with_ties_to_even() {
        for (v, r) in [
            (0.0, 0),
            (0.5, 0),
            (1.5, 2),
            (2.5, 2),
            (-0.5, 0),
            (-1.5, -2),
            (-2.5, -2),
            (2.49, 2),
            (-7.51, -8),
        ] {
            assert_eq!(round_half_even(v), r, "{v}");
        }
        // Against the library over the range used (|v| ≤ 2²⁰ px × 256).
        let mut s = 3u64;
        for _ in 0..100_000 {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let v = ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * MAX_PX * SUBPIXEL;
            assert_eq!(round_half_even(v), v.round_ties_even() as i64, "{v}");
            let half = v.floor() + 0.5;
            assert_eq!(round_half_even(half), half.round_ties_even() as i64, "{half}");
        }
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
    fn indexed_triangles_give_the_soups_buffer_and_counts() {
        // Closed octahedra (shared vertices), a few vertices not finite, behind the eye
        // or far off-screen, some triangles large: drawn from their indices and from
        // their corners, the same buffer and counts for orthographic, slanted and
        // perspective views, each cull, given ids or not, on 1 and 3 threads.
        let mut r = uniform(9);
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        for _ in 0..150 {
            let base = positions.len() as u32;
            let c = Vec3::new(r() * 4.0, r() * 2.0, r() * 4.0);
            let s = 0.05 + 0.6 * r().abs();
            positions.extend([Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z].map(|e| c + e * s));
            for (a, b, t) in
                [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
            {
                indices.extend([base + a, base + b, base + t]);
            }
        }
        // A large floor, shared by two triangles.
        let f = positions.len() as u32;
        positions
            .extend([(-6.0, -6.0), (6.0, -6.0), (6.0, 6.0), (-6.0, 6.0)].map(|(x, z)| Vec3::new(x, -1.5, z)));
        indices.extend([f, f + 2, f + 1, f, f + 3, f + 2]);
        positions[7] = Vec3::new(f32::NAN, 0.0, 0.0);
        positions[20] = Vec3::new(0.0, 30.0, 0.0); // behind the perspective eye
        positions[33] = Vec3::new(1e9, 0.0, 0.0); // far off-screen
        let soup: Vec<[Vec3; 3]> =
            indices.chunks_exact(3).map(|t| [0, 1, 2].map(|k| positions[t[k] as usize])).collect();
        let ids: Vec<u32> = (0..soup.len() as u32).map(|t| t * 7 + 3).collect();
        let perspective = Camera {
            position: Vec3::new(0.0, 12.0, 2.0),
            look_at: Vec3::ZERO,
            up: Vec3::Z,
            projection: Projection::Perspective { fov_y_deg: 70.0 },
        }
        .view(90, 70)
        .unwrap();
        let mut checked = 0;
        for view in [top_view(80, 12.0), slanted_view(64, 12.0), perspective] {
            for cull in [Cull::None, Cull::Back, Cull::Front, Cull::BackFrom(600), Cull::BackAmongFirst(500)]
            {
                for ids in [None, Some(&ids[..])] {
                    let soup_drawn = rasterize(&view, &soup, ids, cull).unwrap();
                    for threads in [1, 3] {
                        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                        let drawn = pool
                            .install(|| rasterize_indexed(&view, (&positions, &indices), ids, cull).unwrap());
                        assert_eq!(drawn, soup_drawn, "{cull:?}, {threads} threads");
                    }
                    let (buf, stats) = soup_drawn;
                    assert!(stats.degenerate >= 1 && stats.clipped >= 1 && stats.drawn > 100, "{stats:?}");
                    assert!(buf.ids().iter().filter(|&&i| i != NO_ID).count() > 500);
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 30);
        // Indices that do not name three vertices a triangle are refused.
        for bad in [&indices[..4], &[0, 1, positions.len() as u32][..]] {
            assert_eq!(
                rasterize_indexed(&top_view(8, 1.0), (&positions, bad), None, Cull::None).err(),
                Some(RasterError::Indices { indices: bad.len(), vertices: positions.len() })
            );
        }
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
        assert_eq!(&one, Rasterizer::serial().draw(&view, &tris, None, Cull::None).unwrap().0);
        assert!(one.ids().iter().filter(|&&i| i != NO_ID).count() > 5000);
    }

    /// A little pseudo-random generator for the tests: uniform in [-1, 1).
    fn uniform(seed: u64) -> impl FnMut() -> f32 {
        let mut s = seed;
        move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        }
    }

    /// A view along a slanted direction (like a snowfall depth map).
    fn slanted_view(n: usize, size: f32) -> CameraView {
        let d = Vec3::new(0.3, -1.0, -0.2).normalize();
        Camera {
            position: -d * 20.0,
            look_at: Vec3::ZERO,
            up: Vec3::X,
            projection: Projection::Orthographic { height_m: size },
        }
        .view(n, n)
        .unwrap()
    }

    #[test]
    fn the_world_space_cull_never_skips_a_triangle_setup_would_draw() {
        let view = slanted_view(64, 8.0);
        let projector = Projector::new(&view);
        let mut r = uniform(11);
        let (mut skipped, mut kept_back) = ([0; 3], [0; 3]);
        for k in 0..200_000 {
            // Ordinary triangles, tiny ones, and ones seen almost edge-on; every other
            // lap 10⁴ m from the origin (the affine map's f32 rounding grows with it).
            let far = if (k / 3) % 2 == 1 { Vec3::new(7e3, -4e3, 5e3) } else { Vec3::ZERO };
            let a = far + Vec3::new(r(), r(), r()) * 4.0;
            let scale = [2.0, 0.01, 1.0][k % 3];
            let e1 = Vec3::new(r(), r(), r()) * scale;
            let mut e2 = Vec3::new(r(), r(), r()) * scale;
            if k % 3 == 2 {
                // Nearly parallel to the view direction: an edge-on sliver.
                e2 = view.forward() * r() * 2.0 + e1 * 1e-3 * r();
            }
            let tri = [a, a + e1, a + e2];
            for cull in [Cull::Back, Cull::Front] {
                if projector.surely_culled(&tri, cull) {
                    skipped[k % 3] += 1;
                    assert!(
                        matches!(setup(&projector, &tri, 0, false, cull, 64, 64), Err(Skip::Culled)),
                        "{tri:?}"
                    );
                } else if matches!(setup(&projector, &tri, 0, false, cull, 64, 64), Err(Skip::Culled)) {
                    kept_back[k % 3] += 1;
                }
            }
        }
        // It must do its job on ordinary triangles (a pixel or more across): at least 95 %
        // of those culled are caught before projection (measured: 97.8 %; 99+ % near the
        // origin, where the bound is tighter). Tiny ones and slivers, whose screen area is
        // within the error bound, are left to `setup`.
        assert!(kept_back[0] * 20 < skipped[0], "skipped early {skipped:?}, left to setup {kept_back:?}");
    }

    /// Closed, outward-facing octahedra scattered over a square (triangle soup).
    fn octahedra(count: usize) -> Vec<[Vec3; 3]> {
        let mut r = uniform(5);
        let mut tris = Vec::new();
        for _ in 0..count {
            let c = Vec3::new(r() * 4.0, r() * 2.0, r() * 4.0);
            let q = glam::Quat::from_axis_angle(Vec3::new(r(), r(), r()).normalize_or(Vec3::Y), r() * 3.0);
            let s = 0.1 + 0.5 * r().abs();
            let v = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z].map(|e| c + q * (e * s));
            for (a, b, t) in
                [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
            {
                tris.push([v[a], v[b], v[t]]);
            }
        }
        tris
    }

    #[test]
    fn back_faces_of_closed_solids_do_not_change_the_depth() {
        let view = slanted_view(128, 10.0);
        let mut tris = octahedra(60);
        let closed = tris.len();
        // An open floor after the closed solids: drawn from both sides.
        tris.push([Vec3::new(-5.0, -2.5, -5.0), Vec3::new(5.0, -2.5, 5.0), Vec3::new(5.0, -2.5, -5.0)]);
        let (all, s_all) = rasterize(&view, &tris, None, Cull::None).unwrap();
        let (front, s_front) = rasterize(&view, &tris, None, Cull::BackAmongFirst(closed)).unwrap();
        assert!(s_front.culled > closed / 3 && s_all.culled == 0, "{s_front:?}");
        // Depths equal where both are covered; a pixel centre exactly on a silhouette may
        // belong to a back face alone (none here, but allow that tie).
        let mut differ = 0;
        for (a, b) in all.depth().iter().zip(front.depth()) {
            if a != b {
                differ += 1;
            }
        }
        assert!(differ <= 2, "{differ} pixels differ");
        assert!(all.depth().iter().filter(|d| d.is_finite()).count() > 3000);
        // The kept buffer of a reused rasteriser is the same as a fresh one's.
        let mut r = Rasterizer::default();
        let _ = r.draw(&top_view(40, 10.0), &tris, None, Cull::None).unwrap();
        assert_eq!(r.draw(&view, &tris, None, Cull::BackAmongFirst(closed)).unwrap().0, &front);
        // The same solids listed after the open floor (as the snow's after the scene's).
        let mut last = vec![tris[closed]];
        last.extend_from_slice(&tris[..closed]);
        let (after, s_after) = rasterize(&view, &last, None, Cull::BackFrom(1)).unwrap();
        assert_eq!(s_after.culled, s_front.culled, "{s_after:?}");
        let (after_all, _) = rasterize(&view, &last, None, Cull::None).unwrap();
        let differ = after.depth().iter().zip(after_all.depth()).filter(|(a, b)| a != b).count();
        assert!(differ <= 2, "{differ} pixels differ");
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
