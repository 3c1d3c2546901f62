//! Motion vectors of a flame frame: where the light of each pixel moves in one frame,
//! for a game engine that blends a flipbook's frames along them (a motion-vector
//! flipbook plays smoothly at a fraction of the frames).
//!
//! Each particle moves on screen by d = P(x + v·dt) − P(x), P the renderer's camera
//! (its own velocity over the frame time). A pixel's vector is the mean of the d of the
//! particles that light it, weighted as they light it: the particle's luminance (its
//! colour as the renderer draws it, §5: blackbody table × intensity × alpha from
//! density) times its splat's poly6 footprint (1 − r²/R²)³ at the pixel's centre, R the
//! splat's radius on screen. Pixels no particle lights get 0.

use rayon::prelude::*;

use crate::config::FlameConfig;
use crate::render::FlameRenderer;
use crate::sim::Particles;

/// A frame's motion vectors: pixel (x, y)'s displacement over one frame at
/// `[y * width + x]`, in pixels, x to the right, y down.
#[derive(Clone, Debug, PartialEq)]
pub struct MotionField {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Displacements, pixels.
    pub vectors: Vec<[f32; 2]>,
}

/// Rec. 709 luminance weights (linear sRGB).
const LUMINANCE: glam::Vec3 = glam::Vec3::new(0.2126, 0.7152, 0.0722);

/// One particle's splat for the motion vectors: centre and radius (pixels), light,
/// displacement (pixels).
struct Mover {
    x: f32,
    y: f32,
    radius: f32,
    light: f32,
    d: [f32; 2],
}

/// Rows of pixels summed together by one task.
const BAND_ROWS: usize = 16;

/// The motion vectors of `p` (simulated with `config`) as `renderer` draws them, over
/// `dt_s` seconds (a frame), at the renderer's frame size (see the module docs). The
/// displacement is first order, v·dt (a particle accelerating over the frame moves by
/// its acceleration times dt²/2 more). Bands of rows are summed in parallel, each
/// adding the particles in their order: the same result for any thread count.
pub fn motion_vectors(
    renderer: &FlameRenderer,
    p: &Particles,
    config: &FlameConfig,
    dt_s: f32,
) -> MotionField {
    let view = renderer.view();
    let (width, height) = view.size();
    let s = renderer.settings();
    let support = config.sph.support_radius_m * s.splat_radius_scale;
    let full_alpha = config.sph.rest_density_kg_m3 * s.full_alpha_density_ratio;
    let movers: Vec<Mover> = (0..p.position_m.len())
        .into_par_iter()
        .filter_map(|i| {
            let x = p.position_m[i];
            let (now, next) = (view.project(x)?, view.project(x + p.velocity_m_s[i] * dt_s)?);
            let alpha = (p.density_kg_m3[i] / full_alpha).clamp(0.0, 1.0);
            let light = (renderer.lut().lookup(p.temperature_k[i]) * (s.intensity * alpha)).dot(LUMINANCE);
            let radius = support * now.px_per_m;
            let d = [next.x_px - now.x_px, next.y_px - now.y_px];
            let usable = light > 0.0 && radius > 0.0 && radius.is_finite() && d.iter().all(|v| v.is_finite());
            usable.then_some(Mover { x: now.x_px, y: now.y_px, radius, light, d })
        })
        .collect();
    let mut vectors = vec![[0.0f32; 2]; width * height];
    vectors.par_chunks_mut(BAND_ROWS * width).enumerate().for_each(|(band, out)| {
        let rows = band * BAND_ROWS..band * BAND_ROWS + out.len() / width;
        // Σ w, Σ w dx, Σ w dy per pixel of the band.
        let mut sums = vec![[0.0f32; 3]; out.len()];
        for m in &movers {
            add(m, &rows, width, &mut sums);
        }
        for (v, &[w, x, y]) in out.iter_mut().zip(&sums) {
            if w > 0.0 {
                *v = [x / w, y / w];
            }
        }
    });
    MotionField { width, height, vectors }
}

/// Adds `m`'s poly6 footprint to the sums of the pixels of `rows` (`sums` holds those
/// rows, `width` pixels each).
#[inline]
fn add(m: &Mover, rows: &std::ops::Range<usize>, width: usize, sums: &mut [[f32; 3]]) {
    let span = |c: f32, lo: usize, hi: usize| {
        let a = ((c - m.radius - 0.5).floor().max(lo as f32) as usize).min(hi);
        let b = ((c + m.radius - 0.5).ceil() + 1.0).clamp(lo as f32, hi as f32) as usize;
        a..b.max(a)
    };
    for py in span(m.y, rows.start, rows.end) {
        let dy = py as f32 + 0.5 - m.y;
        let row = &mut sums[(py - rows.start) * width..(py - rows.start + 1) * width];
        for px in span(m.x, 0, width) {
            let dx = px as f32 + 0.5 - m.x;
            let q = 1.0 - (dx * dx + dy * dy) / (m.radius * m.radius);
            if q > 0.0 {
                let w = m.light * q * q * q;
                let cell = &mut row[px];
                cell[0] += w;
                cell[1] += w * m.d[0];
                cell[2] += w * m.d[1];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::RenderSettings;
    use crate::sim::FlameSim;
    use glam::Vec3;

    /// Two particles apart, one still and one moving right: the pixels each lights
    /// carry its displacement, v·dt times the camera's pixels per metre.
    #[test]
    fn each_particle_carries_its_own_displacement() {
        let config = FlameConfig::default();
        let positions = vec![Vec3::new(-0.2, 0.5, 0.0), Vec3::new(0.2, 0.5, 0.0)];
        let velocities = vec![Vec3::ZERO, Vec3::new(1.5, 0.0, 0.0)];
        let mut sim = FlameSim::with_particles(config.clone(), 1, positions.clone(), velocities).unwrap();
        sim.step().unwrap();
        let renderer = FlameRenderer::new(RenderSettings::default(), 320, 180, None).unwrap();
        let p = sim.particles();
        let field = motion_vectors(&renderer, p, &config, 1.0 / 60.0);
        // The two placed particles (the step also emitted some at the burner, below).
        let placed: Vec<usize> = (0..p.len()).filter(|&i| p.position_m[i].y > 0.3).collect();
        assert_eq!(placed.len(), 2);
        for &i in &placed {
            let pr = renderer.view().project(p.position_m[i]).unwrap();
            let at = pr.y_px as usize * field.width + pr.x_px as usize;
            let next = renderer.view().project(p.position_m[i] + p.velocity_m_s[i] / 60.0).unwrap();
            let want = [next.x_px - pr.x_px, next.y_px - pr.y_px];
            let got = field.vectors[at];
            assert!((got[0] - want[0]).abs() < 1e-4 && (got[1] - want[1]).abs() < 1e-4, "{got:?} {want:?}");
        }
        // The moving particle moves right on screen; nothing lights the corner.
        let right = placed.iter().copied().max_by(|&a, &b| p.position_m[a].x.total_cmp(&p.position_m[b].x));
        let pr = renderer.view().project(p.position_m[right.unwrap()]).unwrap();
        assert!(field.vectors[pr.y_px as usize * field.width + pr.x_px as usize][0] > 0.0);
        assert_eq!(field.vectors[0], [0.0, 0.0]);
    }

    /// Where two particles overlap, a pixel's vector is their displacements' mean
    /// weighted by the light each gives it there (colour luminance × poly6 footprint),
    /// computed here independently of the module's loop.
    #[test]
    fn overlapping_particles_average_by_their_light() {
        let config = FlameConfig::default();
        let positions = vec![Vec3::new(0.0, 0.6, 0.0), Vec3::new(0.02, 0.6, 0.0)];
        let velocities = vec![Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 0.0, 0.0)];
        let mut sim = FlameSim::with_particles(config.clone(), 1, positions, velocities).unwrap();
        sim.step().unwrap();
        let renderer = FlameRenderer::new(RenderSettings::default(), 320, 180, None).unwrap();
        let p = sim.particles();
        let placed: Vec<usize> = (0..p.len()).filter(|&i| p.position_m[i].y > 0.3).collect();
        assert_eq!(placed.len(), 2);
        let field = motion_vectors(&renderer, p, &config, 1.0 / 60.0);
        let s = renderer.settings();
        let view = renderer.view();
        // The pixel half way between the two.
        let (a, b) =
            (view.project(p.position_m[placed[0]]).unwrap(), view.project(p.position_m[placed[1]]).unwrap());
        let (px, py) = (((a.x_px + b.x_px) / 2.0) as usize, ((a.y_px + b.y_px) / 2.0) as usize);
        let (mut w_sum, mut d_sum) = (0.0f64, [0.0f64; 2]);
        for &i in &placed {
            let now = view.project(p.position_m[i]).unwrap();
            let next = view.project(p.position_m[i] + p.velocity_m_s[i] / 60.0).unwrap();
            let alpha = (p.density_kg_m3[i] / config.sph.rest_density_kg_m3 / s.full_alpha_density_ratio)
                .clamp(0.0, 1.0);
            let light =
                f64::from((renderer.lut().lookup(p.temperature_k[i]) * (s.intensity * alpha)).dot(LUMINANCE));
            let radius = f64::from(config.sph.support_radius_m * s.splat_radius_scale * now.px_per_m);
            let (dx, dy) = (px as f64 + 0.5 - f64::from(now.x_px), py as f64 + 0.5 - f64::from(now.y_px));
            let q = (1.0 - (dx * dx + dy * dy) / (radius * radius)).max(0.0);
            let w = light * q * q * q;
            w_sum += w;
            d_sum[0] += w * f64::from(next.x_px - now.x_px);
            d_sum[1] += w * f64::from(next.y_px - now.y_px);
        }
        assert!(w_sum > 0.0, "both particles light the middle pixel");
        let want = [d_sum[0] / w_sum, d_sum[1] / w_sum];
        let got = field.vectors[py * field.width + px];
        // f32 sums of two terms against f64: 1e-4 px.
        assert!(
            (f64::from(got[0]) - want[0]).abs() < 1e-4 && (f64::from(got[1]) - want[1]).abs() < 1e-4,
            "{got:?} {want:?}"
        );
        // Not either particle's own vector: a mixture.
        assert!(got[0] > 1e-3 && got[1] < -1e-3, "{got:?}");
    }
}
