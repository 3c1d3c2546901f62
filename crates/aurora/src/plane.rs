//! The plane view: the x-z simulation plane seen from above, like the thesis's Figs 2.9,
//! 2.10, 2.12 and 2.14. Particle density as colour, the intermediate target shape's
//! segments and control points over it, optionally the potential and E arrows. For
//! artists to check motion quickly, and as evidence that shapes are followed.

use glam::{Vec2, Vec3};
use phenomena_core::image::Frame;
use serde::{Deserialize, Serialize};

use crate::sim::AuroraSim;

/// What the plane view shows.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlaneView {
    /// Colour the background by the potential (blue low, red high, Fig 2.12).
    pub potential: bool,
    /// Draw E as arrows every this many cells (0 = none).
    pub arrows_every_cells: u32,
    /// Draw the intermediate target shape.
    pub shape: bool,
}

impl Default for PlaneView {
    fn default() -> Self {
        Self { potential: false, arrows_every_cells: 0, shape: true }
    }
}

/// Maps plane km to pixels, preserving aspect (the plane is centred, letterboxed).
struct Mapping {
    scale: f32,
    offset: Vec2,
    origin: Vec2,
}

impl Mapping {
    #[inline]
    fn to_px(&self, p: Vec2) -> Vec2 {
        (p - self.origin) * self.scale + self.offset
    }
}

/// Draw the plane view of `sim` at `width × height` (linear RGB).
pub fn render_plane(sim: &AuroraSim, width: usize, height: usize, view: &PlaneView) -> Frame {
    let mut frame = Frame::new(width, height);
    if width == 0 || height == 0 {
        return frame;
    }
    let grid = sim.grid();
    let extent = grid.extent_km();
    let scale = (width as f32 / extent.x).min(height as f32 / extent.y);
    let offset = (Vec2::new(width as f32, height as f32) - extent * scale) * 0.5;
    let map = Mapping { scale, offset, origin: grid.origin_km };
    let field = sim.field();

    if view.potential && !field.potential_noisy.is_empty() {
        let (lo, hi) =
            field.potential_noisy.iter().fold((f64::MAX, f64::MIN), |(l, h), &v| (l.min(v), h.max(v)));
        let span = (hi - lo).max(1e-30);
        for y in 0..height {
            for x in 0..width {
                let p = (Vec2::new(x as f32 + 0.5, y as f32 + 0.5) - offset) / scale + grid.origin_km;
                if let Some((i, j)) = grid.cell_of(p) {
                    let t = ((field.potential_noisy[grid.index(i, j)] - lo) / span) as f32;
                    frame.set_pixel(x, y, diverging(t) * 0.35);
                }
            }
        }
    }

    // Particle density: count per pixel, shown on a logarithmic heat ramp.
    let mut counts = vec![0u32; width * height];
    for &p in &sim.particles().position_km {
        let q = map.to_px(p);
        if q.x >= 0.0 && q.y >= 0.0 && (q.x as usize) < width && (q.y as usize) < height {
            counts[q.y as usize * width + q.x as usize] += 1;
        }
    }
    let max = counts.iter().copied().max().unwrap_or(0).max(1);
    let norm = (1.0 + max as f32).ln();
    for (k, &c) in counts.iter().enumerate() {
        if c > 0 {
            let t = (1.0 + c as f32).ln() / norm;
            let (x, y) = (k % width, k / width);
            frame.set_pixel(x, y, frame.pixel(x, y) + heat(t));
        }
    }

    if view.arrows_every_cells > 0 && !field.e.is_empty() {
        let every = view.arrows_every_cells as usize;
        let emax = field.e.iter().fold(0.0f32, |m, e| m.max(e.length())).max(1e-30);
        let len_km = grid.cell_km * every as f32 * 0.9;
        for j in (every / 2..grid.nz).step_by(every) {
            for i in (every / 2..grid.nx).step_by(every) {
                let c = grid.center(i, j);
                let e = field.e[grid.index(i, j)] / emax;
                line(&mut frame, map.to_px(c), map.to_px(c + e * len_km), Vec3::splat(0.6));
            }
        }
    }

    if view.shape {
        let shape = &field.shape;
        for (a, b) in shape.segments() {
            line(&mut frame, map.to_px(a), map.to_px(b), Vec3::new(0.05, 0.8, 0.1));
        }
        for &p in &shape.points {
            let q = map.to_px(p);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    plot(&mut frame, q.x as i64 + dx, q.y as i64 + dy, Vec3::ONE);
                }
            }
        }
    }
    frame
}

/// Blue (0) through white (0.5) to red (1).
fn diverging(t: f32) -> Vec3 {
    let t = t.clamp(0.0, 1.0);
    if t < 0.5 {
        Vec3::new(0.1, 0.2, 1.0).lerp(Vec3::ONE, t * 2.0)
    } else {
        Vec3::ONE.lerp(Vec3::new(1.0, 0.15, 0.1), (t - 0.5) * 2.0)
    }
}

/// Black through red and yellow to white.
fn heat(t: f32) -> Vec3 {
    let t = t.clamp(0.0, 1.0);
    Vec3::new((t * 3.0).min(1.0), (t * 3.0 - 1.0).clamp(0.0, 1.0), (t * 3.0 - 2.0).clamp(0.0, 1.0))
}

fn plot(frame: &mut Frame, x: i64, y: i64, c: Vec3) {
    if x >= 0 && y >= 0 && (x as usize) < frame.width() && (y as usize) < frame.height() {
        frame.set_pixel(x as usize, y as usize, c);
    }
}

/// A one-pixel line from a to b (pixel coordinates).
fn line(frame: &mut Frame, a: Vec2, b: Vec2, c: Vec3) {
    let steps = (b - a).abs().max_element().ceil().clamp(1.0, 1e5) as usize;
    for k in 0..=steps {
        let p = a.lerp(b, k as f32 / steps as f32);
        plot(frame, p.x as i64, p.y as i64, c);
    }
}
