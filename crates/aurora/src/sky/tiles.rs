//! The physical mode's emission deposited as it is emitted (perspective cameras).
//!
//! The banded path ([`SkyRenderer::emit_particle`], [`deposit_banded`]) writes every
//! point (16 bytes) to the band of rows it falls in and reads it back to deposit it: at
//! 640x360, scene 5's 6.7 million points made a 107 MB round trip a frame. Here the
//! particles are cut into at most [`MAX_PARTS`] runs of the store (a fixed number for
//! a given particle count: not the thread count), each run deposits its points straight
//! into its own five line images over the rectangle its columns can reach (its tile),
//! and the tiles are added into the frame row by row in run order. Every pixel sums the
//! same terms in the same order for any thread count, and the same terms as the banded
//! path (in another order: the images agree to rounding, test
//! `tiles_deposit_what_the_bands_deposit`).
//!
//! A column stands on a straight line (its foot plus the field's lean times the descent),
//! and a perspective camera maps a straight segment in front of it to the segment
//! between the images of its ends; so a run's tile is the box of its columns' two
//! ends (the lowest and highest altitude any line's points reach), widened by
//! [`MARGIN_PX`] for rounding and the bilinear footprint, and cut to the image. A column
//! that crosses the camera's near plane makes the tile the whole image; one wholly
//! behind it draws nothing and is left out. If the tiles
//! would hold more than [`MAX_AREA_IMAGES`] images (runs spread over the whole sky),
//! the banded path is taken instead.

use glam::Vec2;
use phenomena_core::image::par_chunks5;

use super::{FrameEmission, Model, NEAR_M, Pinhole, Plane, Projected8, SkyRenderer, project_in_lanes};
use rayon::prelude::*;
use wide::{f32x8, i32x8};

/// Particles a run at most while there are fewer than [`MAX_PARTS`] runs (fewer
/// particles make fewer runs; 30,000 make eight, enough for the cores to share).
const PART_PARTICLES: usize = 4_096;
/// Runs at most: each may hold an image's worth of line images.
const MAX_PARTS: usize = 8;
/// The tiles' total area, in images, above which the banded path is taken (a tile
/// keeps at most twice its memory: eight images' line images at most in all).
const MAX_AREA_IMAGES: usize = 4;
/// Pixels added around a run's box of column ends: the bilinear footprint's one and
/// one for rounding (a point's projection and its column ends' differ by a few ulps of
/// the pixel coordinate).
const MARGIN_PX: i64 = 2;

/// One run's deposit: five line images over pixels `x0..x0 + w`, `y0..y0 + h`.
#[derive(Debug, Default)]
pub(super) struct Tile {
    x0: usize,
    y0: usize,
    w: usize,
    h: usize,
    planes: [Vec<f32>; 5],
    /// Each particle's drawn position and gain (the small-scale motion's, worked out
    /// once for the bounds and the points), in the run's order.
    drawn: Vec<(Vec2, f32)>,
    /// One particle's points before projection (altitude km, photons per point, line).
    lanes: Vec<(f32, f32, u8)>,
    /// Points deposited (those touching the image).
    points: usize,
}

impl SkyRenderer {
    /// Emit and deposit the physical mode's points through a perspective pinhole into
    /// `self.fresh` by runs and tiles; false (nothing done) if the tiles would be too
    /// large, for the banded path to take over.
    pub(super) fn emit_in_tiles(&mut self, frame: &FrameEmission<'_>, ph: &Pinhole) -> bool {
        let Model::Physical { sampler, points, .. } = &self.model else { return false };
        if !self.tiled {
            return false;
        }
        let (width, height) = (self.width, self.height);
        let top = frame.top as f32;
        // The lowest and highest altitude any line's points reach.
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for (k, &m) in points.iter().enumerate() {
            if m > 0 {
                let (a, b) = sampler.range_km(crate::emission::Line::ALL[k]);
                (lo, hi) = (lo.min(a.min(top)), hi.max(b.min(top)));
            }
        }
        if !(lo <= hi) {
            // No line emits (or the table is not finite): the banded path's nothing.
            return false;
        }
        let n = frame.sim.particles().len();
        let parts = n.div_ceil(PART_PARTICLES).clamp(1, MAX_PARTS);
        let mut tiles = std::mem::take(&mut self.tiles);
        tiles.resize_with(parts, Tile::default);
        let run = |p: usize| self.strided(p * n / parts..(p + 1) * n / parts);
        tiles.par_iter_mut().enumerate().for_each(|(p, tile)| {
            tile.bound(self, frame, ph, run(p), [lo, hi]);
        });
        let area: usize = tiles.iter().map(|t| t.w * t.h).sum();
        if area > MAX_AREA_IMAGES * width * height {
            // The memory of tiles this large is not kept.
            tiles.iter_mut().for_each(|t| t.planes = Default::default());
            self.tiles = tiles;
            return false;
        }
        tiles.par_iter_mut().for_each(Tile::clear);
        tiles.par_iter_mut().enumerate().for_each(|(p, tile)| {
            tile.emit(self, frame, ph, run(p));
        });
        let t = self.clock.stopwatch();
        add_tiles(&tiles, &mut self.fresh);
        self.timings.deposit_ms = t.ms();
        self.timings.points = tiles.iter().map(|t| t.points).sum();
        self.tiles = tiles;
        true
    }
}

impl Tile {
    /// Draw the run's particles `run` and find the pixels their columns can reach
    /// (altitudes `ends`): the tile's bounds ([`Tile::clear`] makes its images once
    /// the path is taken).
    fn bound(
        &mut self,
        sky: &SkyRenderer,
        frame: &FrameEmission<'_>,
        ph: &Pinhole,
        run: impl Iterator<Item = usize>,
        ends: [f32; 2],
    ) {
        let (top, drift) = (frame.top as f32, frame.drift.as_vec3());
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        let mut whole = false;
        self.drawn.clear();
        for i in run {
            let (drawn, gain) = frame.drawn(i);
            self.drawn.push((drawn, gain));
            if gain <= 0.0 {
                continue;
            }
            let foot = frame.foot(drawn).as_vec3();
            let q = ends.map(|a| glam::Vec3::new(foot.x, a, foot.z) + drift * (top - a));
            // Depth is linear along the column: with both ends well behind the near
            // plane (half of it, for rounding), no point of it is drawn.
            if q.iter().all(|q| ph.forward.dot(*q - ph.eye) < 0.5 * NEAR_M) {
                continue;
            }
            for q in q {
                match sky.view.project(q) {
                    Some(pr) if pr.x_px.is_finite() && pr.y_px.is_finite() => {
                        lo = lo.min(Vec2::new(pr.x_px, pr.y_px));
                        hi = hi.max(Vec2::new(pr.x_px, pr.y_px));
                    }
                    // Crossing the near plane (or not finite): the column may reach
                    // anywhere.
                    _ => whole = true,
                }
            }
        }
        let span = |lo: f32, hi: f32, size: usize| -> (usize, usize) {
            if whole {
                return (0, size);
            }
            if !(lo <= hi) {
                return (0, 0);
            }
            // Pixel centres sit at half-integers: a point at v touches pixels
            // ⌊v − ½⌋ and ⌊v − ½⌋ + 1.
            let clip = |v: f32| v.clamp(-4.0, size as f32 + 4.0).floor() as i64;
            let a = (clip(lo - 0.5) - MARGIN_PX).clamp(0, size as i64) as usize;
            let b = (clip(hi - 0.5) + 1 + MARGIN_PX + 1).clamp(0, size as i64) as usize;
            (a, b.max(a))
        };
        let ((x0, x1), (y0, y1)) = (span(lo.x, hi.x, sky.width), span(lo.y, hi.y, sky.height));
        (self.x0, self.y0, self.w, self.h) = (x0, y0, x1 - x0, y1 - y0);
    }

    /// The tile's images cleared over its pixels (memory over twice theirs let go).
    fn clear(&mut self) {
        let need = self.w * self.h;
        for plane in &mut self.planes {
            plane.clear();
            if plane.capacity() > 2 * need {
                plane.shrink_to(need);
            }
            plane.resize(need, 0.0);
        }
        self.points = 0;
    }

    /// Emit the run's particles `run` (drawn by [`Tile::bound`]) and deposit their
    /// points.
    fn emit(
        &mut self,
        sky: &SkyRenderer,
        frame: &FrameEmission<'_>,
        ph: &Pinhole,
        run: impl Iterator<Item = usize>,
    ) {
        let (width, height, scale) = (sky.width, sky.height, sky.stride as f32);
        let mut lanes = std::mem::take(&mut self.lanes);
        let drawn = std::mem::take(&mut self.drawn);
        for (i, &(at, gain)) in run.zip(&drawn) {
            if gain <= 0.0 {
                continue;
            }
            let Some(column) = sky.physical_column(frame, i, frame.foot(at), gain) else { continue };
            column.altitudes(&mut lanes);
            project_in_lanes(ph, column.foot, column.top_km, column.drift, &lanes, |g| {
                self.deposit8(g, scale, width, height);
            });
        }
        (self.lanes, self.drawn) = (lanes, drawn);
    }

    /// Bilinear deposit of the points `g`, their weights times `scale` (image pixels, the
    /// image `width × height`), each pixel outside the image dropped: the same terms as
    /// [`super::bilinear`] gives [`super::deposit`], lane by lane (IEEE arithmetic, the
    /// same operations in the same order), worked out eight at a time. Each point's
    /// offset in the tile, and whether all four of its pixels fall inside it, are worked
    /// out in lanes too: such points (nearly all) add their terms directly, the rest go
    /// through [`Tile::add`] (test `lanes_add_the_scalar_bilinear_terms`, with tiles at
    /// and away from the image's corner).
    #[inline]
    fn deposit8(&mut self, g: &Projected8, scale: f32, width: usize, height: usize) {
        let splat = f32x8::splat;
        let weight = g.weight * splat(scale);
        let (fx, fy) = (g.x - splat(0.5), g.y - splat(0.5));
        let inside = fx.simd_ge(splat(-1.0))
            & fx.simd_lt(splat(width as f32))
            & fy.simd_ge(splat(-1.0))
            & fy.simd_lt(splat(height as f32))
            & weight.is_finite();
        let mut ok = g.ok & inside.to_bitmask();
        if ok == 0 {
            return;
        }
        self.points += ok.count_ones() as usize;
        // ⌊f⌋ is exact, as is the conversion of an integer below 2²⁴ (`floor_i32`'s).
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - x0, fy - y0);
        let (wx0, wy0) = (splat(1.0) - tx, splat(1.0) - ty);
        let terms = [weight * wx0 * wy0, weight * tx * wy0, weight * wx0 * ty, weight * tx * ty]
            .map(|t| t.to_array());
        // The points whose four pixels all lie in the tile, and their first pixel's
        // offset in it. A side is at most `MAX_SIDE_PX` = 2¹⁴ (`check_size`), so these
        // integers are exact in f32 and w·h < 2²⁸ fits an i32: the guard on w·h only
        // keeps that so should the limit grow.
        let (lx, ly) = (x0 - splat(self.x0 as f32), y0 - splat(self.y0 as f32));
        let fast = lx.simd_ge(splat(0.0))
            & ly.simd_ge(splat(0.0))
            & lx.simd_lt(splat(self.w as f32 - 1.0))
            & ly.simd_lt(splat(self.h as f32 - 1.0));
        let fast = if self.w * self.h < i32::MAX as usize { fast.to_bitmask() } else { 0 };
        let at = (ly.trunc_int() * i32x8::splat(self.w as i32) + lx.trunc_int()).to_array();
        let (x0, y0) = (x0.to_array(), y0.to_array());
        let w = self.w;
        // Lane by lane in order (two lanes may share a pixel: its sum keeps their order).
        while ok != 0 {
            let l = ok.trailing_zeros() as usize;
            ok &= ok - 1;
            let lane = [terms[0][l], terms[1][l], terms[2][l], terms[3][l]];
            if fast & (1 << l) != 0 {
                add4(&mut self.planes[usize::from(g.lines[l])], at[l] as usize, w, lane);
            } else {
                self.add(x0[l] as i32, y0[l] as i32, g.lines[l], lane, width, height);
            }
        }
    }

    /// Add a point's four bilinear `terms` ([`super::bilinear`]) to line `line`'s image
    /// from pixel (`x0`, `y0`) on.
    #[inline]
    fn add(&mut self, x0: i32, y0: i32, line: u8, terms: [f32; 4], width: usize, height: usize) {
        let (lx, ly) = (i64::from(x0) - self.x0 as i64, i64::from(y0) - self.y0 as i64);
        let w = self.w;
        let plane = &mut self.planes[usize::from(line)];
        if lx >= 0 && ly >= 0 && lx + 1 < w as i64 && ly + 1 < self.h as i64 {
            // All four pixels in the tile.
            add4(plane, ly as usize * w + lx as usize, w, terms);
            return;
        }
        for (c, term) in terms.into_iter().enumerate() {
            let (x, y) = (i64::from(x0) + (c & 1) as i64, i64::from(y0) + (c >> 1) as i64);
            if x < 0 || y < 0 || x >= width as i64 || y >= height as i64 {
                continue;
            }
            let (lx, ly) = (x - self.x0 as i64, y - self.y0 as i64);
            // The tile holds every pixel of the image its columns reach (its bounds
            // above); a miss would be a bound too tight.
            debug_assert!(lx >= 0 && ly >= 0 && lx < w as i64 && ly < self.h as i64, "outside the tile");
            if lx >= 0 && ly >= 0 && lx < w as i64 && ly < self.h as i64 {
                plane[ly as usize * w + lx as usize] += term;
            }
        }
    }
}

/// Add a point's four bilinear `terms` to `plane` (rows `w` wide) from its pixel `at`:
/// at, at + 1, at + w, at + w + 1.
#[inline]
fn add4(plane: &mut [f32], at: usize, w: usize, terms: [f32; 4]) {
    let p = &mut plane[at..at + w + 2];
    p[0] += terms[0];
    p[1] += terms[1];
    p[w] += terms[2];
    p[w + 1] += terms[3];
}

/// The five line images: zero, plus every tile in run order, rows in parallel.
fn add_tiles(tiles: &[Tile], planes: &mut [Plane; 5]) {
    let w = planes[0].width();
    par_chunks5(planes, w).enumerate().for_each(|(y, rows)| {
        for (k, row) in rows.into_iter().enumerate() {
            row.fill(0.0);
            for tile in tiles {
                if (tile.y0..tile.y0 + tile.h).contains(&y) {
                    let from = &tile.planes[k][(y - tile.y0) * tile.w..(y - tile.y0 + 1) * tile.w];
                    for (o, v) in row[tile.x0..tile.x0 + tile.w].iter_mut().zip(from) {
                        *o += v;
                    }
                }
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::super::{BandedPoints, FrameEmission, SkyCamera, SkySettings, Splat, bilinear, floor_i32};
    use super::*;
    use crate::AuroraSim;
    use phenomena_core::rng::{Purpose, Stream};

    #[test]
    fn lanes_add_the_scalar_bilinear_terms() {
        // Points over and around a 37x23 image (on its edges, outside it, at NaN or an
        // infinity, with an infinite or NaN weight), some lanes masked off: deposited
        // eight at a time (`deposit8`), they leave the same bits as the scalar `bilinear`
        // terms added one point at a time, and the same count; into a tile of the whole
        // image and into one at its lower right corner (from pixel (9, 5), its points on
        // or right of and below that).
        let (w, h) = (37usize, 23usize);
        for (t, (tx0, ty0)) in [(0, 0), (9, 5)].into_iter().enumerate() {
            let tile = || {
                let mut t = Tile { x0: tx0, y0: ty0, w: w - tx0, h: h - ty0, ..Tile::default() };
                t.clear();
                t
            };
            let (mut lanes, mut scalar) = (tile(), tile());
            for group in 0..2_000 {
                let mut rng = Stream::new(7, Purpose::named("test.tiles.lanes"), (group * 2 + t) as u64);
                let (splats, ok) = some_points(&mut rng, group, (w, h), (tx0, ty0));
                let g = Projected8 {
                    x: f32x8::from(splats.map(|s| s.x)),
                    y: f32x8::from(splats.map(|s| s.y)),
                    weight: f32x8::from(splats.map(|s| s.weight)),
                    lines: splats.map(|s| s.line),
                    ok,
                };
                lanes.deposit8(&g, 3.0, w, h);
                for (l, s) in splats.iter().enumerate() {
                    let s = Splat { weight: s.weight * 3.0, ..*s };
                    let (fx, fy) = (s.x - 0.5, s.y - 0.5);
                    let inside =
                        fx >= -1.0 && fx < w as f32 && fy >= -1.0 && fy < h as f32 && s.weight.is_finite();
                    if ok & (1 << l) != 0 && inside {
                        scalar.points += 1;
                        let (x0, y0, terms) = bilinear(&s);
                        scalar.add(x0, y0, s.line, terms, w, h);
                    }
                }
            }
            assert!(scalar.points > 5_000, "{} points", scalar.points);
            assert_eq!(lanes.points, scalar.points);
            for k in 0..5 {
                let bits = |t: &Tile| t.planes[k].iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&lanes), bits(&scalar), "tile from ({tx0}, {ty0}), line {k}");
            }
        }
    }

    /// Eight points of group `group` over a `w × h` image for a tile from pixel
    /// (`x0`, `y0`) to the image's far corner, and a mask of lanes. Along each axis a
    /// point is NaN, ±∞, on the near edge ([`near_edge`]), half a pixel past the far
    /// edge, or uniform from where [`near_edge`] says to 3 px past the far edge.
    fn some_points(
        rng: &mut Stream,
        group: usize,
        (w, h): (usize, usize),
        (x0, y0): (usize, usize),
    ) -> ([Splat; 8], u32) {
        let ((edge_x, from_x), (edge_y, from_y)) = (near_edge(x0), near_edge(y0));
        let along = |k: usize, edge: f32, from: f32, size: usize, r: f32| match k {
            0 => f32::NAN,
            1 => f32::INFINITY,
            2 => f32::NEG_INFINITY,
            3 => edge,
            4 => size as f32 + 0.5,
            _ => from + r * (size as f32 + 3.0 - from),
        };
        let splats = std::array::from_fn(|l| Splat {
            x: along((group + l) % 97, edge_x, from_x, w, rng.next_f32()),
            y: along((group + l) % 83, edge_y, from_y, h, rng.next_f32()),
            weight: match (group + l) % 89 {
                0 => f32::INFINITY,
                1 => f32::NAN,
                _ => rng.next_f32(),
            },
            line: (rng.next_u64() % 5) as u8,
        });
        (splats, (rng.next_u64() & 0xff) as u32)
    }

    /// Along an axis where a tile starts at pixel `start`: its near edge point and where
    /// its uniform points start. A tile at the image's edge (0) may be given points out
    /// of the image: half a pixel out and from 3 px out. One starting inside the image
    /// is given none before its first pixel centre (the image's pixels before it are
    /// not the tile's).
    fn near_edge(start: usize) -> (f32, f32) {
        if start == 0 { (-0.5, -3.0) } else { (start as f32 + 0.5, start as f32 + 0.5) }
    }

    #[test]
    fn tiles_deposit_what_the_bands_deposit() {
        // The same frames through the tiles and through the bands (the points are the
        // same: both project with `project_in_lanes`), for two perspective cameras, all
        // particles and a thinned subset. Each pixel of each line image sums the same
        // positive terms in another order; summing n terms in any order errs by at most
        // γ = (n − 1) u/(1 − (n − 1) u) times their sum, u = ε/2 the unit roundoff
        // (Higham, Accuracy and Stability of Numerical Algorithms, 2nd ed., §4.2), so
        // the two sums differ by at most 2γ ≈ (n − 1) ε times the larger (0.1 % added
        // for the γ's denominator), n counted per pixel from the points themselves. A
        // point lost by a tile too tight would leave a pixel short by its whole term.
        let mut config = crate::AuroraConfig::default();
        config.motion.particles = 40_000;
        config.redistribution.enabled = false;
        let mut sim = AuroraSim::new(config, 5).unwrap();
        sim.step().unwrap();
        assert!(sim.particles().len() >= MAX_PARTS * PART_PARTICLES, "every run");
        let (w, h) = (320, 180);
        let orbit = SkyCamera::Orbit {
            altitude_km: 200.0,
            distance_km: 900.0,
            look_at_altitude_km: 150.0,
            fov_y_deg: 30.0,
        };
        for (camera, stride) in [(SkyCamera::default(), 1), (SkyCamera::default(), 3), (orbit, 1)] {
            let settings = SkySettings { camera, ..SkySettings::default() };
            let mut sky = SkyRenderer::new(settings, w, h, None).unwrap();
            sky.set_particle_subset(stride, 1);
            // Terms per pixel and line, from every point the bands are given.
            let mut points = BandedPoints::default();
            points.reset(h, stride as f32);
            let frame = FrameEmission::new(&sky, &sim);
            for i in (1 % stride..sim.particles().len()).step_by(stride) {
                sky.emit_particle(&frame, i, &mut points);
            }
            let mut terms = vec![0u32; 5 * w * h];
            for b in 0..points.bands.len() {
                for s in points.band(b) {
                    let (x0, y0) = (floor_i32(s.x - 0.5), floor_i32(s.y - 0.5));
                    for (x, y) in [(x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1)] {
                        if (0..w as i32).contains(&x) && (0..h as i32).contains(&y) {
                            terms[usize::from(s.line) * w * h + y as usize * w + x as usize] += 1;
                        }
                    }
                }
            }
            let mut images = Vec::new();
            for tiled in [true, false] {
                sky.tiled = tiled;
                sky.emit_and_deposit(&sim);
                images.push(sky.fresh.clone());
            }
            // The tiles' images are the same bits on one thread and on three.
            sky.tiled = true;
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                pool.install(|| sky.emit_and_deposit(&sim));
                assert!(sky.fresh == images[0], "{camera:?}: other bits on {threads} threads");
            }
            let tiles_used = sky.tiles.iter().map(|t| t.w * t.h).sum::<usize>();
            assert!(tiles_used > 0 && tiles_used < 4 * w * h, "{camera:?}: tiles {tiles_used} px");
            let mut lit = 0;
            for k in 0..5 {
                for (p, (a, b)) in images[0][k].data().iter().zip(images[1][k].data()).enumerate() {
                    let n = terms[k * w * h + p];
                    let bound = n.saturating_sub(1) as f32 * f32::EPSILON * a.max(*b) * 1.001;
                    assert!(
                        (a - b).abs() <= bound,
                        "{camera:?} stride {stride}: line {k} pixel {p}: {a} vs {b} ({n} terms)"
                    );
                    lit += usize::from(n > 0);
                }
            }
            assert!(lit > 2_000, "{camera:?}: {lit} pixels lit");
        }
    }
}
