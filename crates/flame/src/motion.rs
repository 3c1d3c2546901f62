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

/// The motion vectors of `p` (simulated with `config`) as `renderer` draws them, over
/// `dt_s` seconds (a frame), at the renderer's frame size (see the module docs).
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
    // Σ w, Σ w dx, Σ w dy per pixel.
    let mut sums = vec![[0.0f32; 3]; width * height];
    for i in 0..p.position_m.len() {
        let x = p.position_m[i];
        let (Some(now), Some(next)) = (view.project(x), view.project(x + p.velocity_m_s[i] * dt_s)) else {
            continue;
        };
        let alpha = (p.density_kg_m3[i] / full_alpha).clamp(0.0, 1.0);
        let light = (renderer.lut().lookup(p.temperature_k[i]) * (s.intensity * alpha)).dot(LUMINANCE);
        let radius = support * now.px_per_m;
        if !(light > 0.0 && radius > 0.0 && radius.is_finite()) {
            continue;
        }
        let d = [next.x_px - now.x_px, next.y_px - now.y_px];
        let span = |c: f32, n: usize| {
            let lo = (c - radius - 0.5).floor().max(0.0) as usize;
            let hi = ((c + radius - 0.5).ceil().max(-1.0) as i64).min(n as i64 - 1);
            lo..(hi + 1).max(lo as i64) as usize
        };
        for py in span(now.y_px, height) {
            let dy = py as f32 + 0.5 - now.y_px;
            for px in span(now.x_px, width) {
                let dx = px as f32 + 0.5 - now.x_px;
                let q = 1.0 - (dx * dx + dy * dy) / (radius * radius);
                if q > 0.0 {
                    let w = light * q * q * q;
                    let cell = &mut sums[py * width + px];
                    cell[0] += w;
                    cell[1] += w * d[0];
                    cell[2] += w * d[1];
                }
            }
        }
    }
    let vectors = sums.iter().map(|&[w, x, y]| if w > 0.0 { [x / w, y / w] } else { [0.0, 0.0] }).collect();
    MotionField { width, height, vectors }
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
}
