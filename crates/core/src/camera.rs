//! Cameras: look-at placement with a perspective, orthographic, fisheye (dome master) or
//! equirectangular (360°) projection to pixels.
//!
//! World space is right-handed with +y up. A camera looks from `position` towards
//! `look_at`; image x grows to the right and image y grows downwards, in continuous pixel
//! coordinates (pixel centres at +0.5). Lengths are "metres" in the names below but any
//! unit works as long as the scene uses one throughout (the aurora uses km).
//!
//! ```
//! use glam::Vec3;
//! use phenomena_core::camera::{Camera, Projection};
//! let cam = Camera {
//!     position: Vec3::new(0.0, 0.0, 5.0),
//!     look_at: Vec3::ZERO,
//!     up: Vec3::Y,
//!     projection: Projection::Perspective { fov_y_deg: 90.0 },
//! };
//! let view = cam.view(200, 100).unwrap();
//! let p = view.project(Vec3::ZERO).unwrap();
//! assert_eq!((p.x_px, p.y_px, p.depth), (100.0, 50.0, 5.0));
//! // With a 90° vertical field of view, y = 5 at depth 5 is the top edge.
//! assert!((view.project(Vec3::new(0.0, 5.0, 0.0)).unwrap().y_px - 0.0).abs() < 1e-4);
//! ```

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::validate::Issues;

/// How the camera maps view space to the image.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Projection {
    /// Pinhole perspective with a vertical field of view in degrees.
    Perspective {
        /// Vertical field of view, degrees.
        fov_y_deg: f32,
    },
    /// Parallel projection showing `height_m` world units from top to bottom.
    Orthographic {
        /// World-space height of the view, metres.
        height_m: f32,
    },
    /// Equidistant fisheye, the planetarium "dome master" format: the angle from the
    /// view direction maps linearly to the distance from the image centre, and the circle
    /// inscribed in the image spans `fov_deg` (180 for a dome). Outside it is black.
    Fisheye {
        /// Full field of view across the inscribed circle, degrees, in (0, 360].
        fov_deg: f32,
    },
    /// Equirectangular 360° × 180° panorama: image x is the azimuth around the camera's
    /// up vector (the view direction at the centre), image y the elevation (+90° at the top).
    Equirectangular,
}

/// The projection's mapping from view-space directions to pixels, prepared for one size.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Perspective,
    Orthographic,
    /// Half the field of view, radians.
    Fisheye {
        half_fov_rad: f32,
    },
    /// Pixels per radian of elevation (`scale` is per radian of azimuth); equal for a 2:1
    /// image.
    Equirectangular {
        scale_y: f32,
    },
}

/// A look-at camera.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    /// Eye position, metres.
    #[serde(deserialize_with = "crate::serde_vec::vec3")]
    pub position: Vec3,
    /// Point the camera looks at, metres.
    #[serde(deserialize_with = "crate::serde_vec::vec3")]
    pub look_at: Vec3,
    /// Approximate up direction (need not be orthogonal to the view direction).
    #[serde(default = "default_up")]
    #[serde(deserialize_with = "crate::serde_vec::vec3")]
    pub up: Vec3,
    /// Projection.
    pub projection: Projection,
}

fn default_up() -> Vec3 {
    Vec3::Y
}

/// A point projected to the image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projected {
    /// Image x, pixels (0 = left edge).
    pub x_px: f32,
    /// Image y, pixels (0 = top edge).
    pub y_px: f32,
    /// Distance along the view direction, metres.
    pub depth: f32,
    /// Pixels per metre at this depth (the scale of a small object facing the camera).
    pub px_per_m: f32,
}

/// A perspective or orthographic view as numbers ([`CameraView::pinhole`]). With
/// d = p - eye (component by component) and dot products summed x, y, z in that order:
/// depth = d·forward; s = scale / depth for a perspective view (a point projects only
/// when depth > [`NEAR_M`]) or s = scale for an orthographic one; then
/// x_px = centre_px.0 + (d·right) s and y_px = centre_px.1 - (d·up) s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pinhole {
    /// Eye position, metres.
    pub eye: Vec3,
    /// Unit image-right direction.
    pub right: Vec3,
    /// Unit image-up direction.
    pub up: Vec3,
    /// Unit view direction.
    pub forward: Vec3,
    /// Image centre, pixels.
    pub centre_px: (f32, f32),
    /// Focal length in pixels (perspective) or pixels per metre (orthographic).
    pub scale: f32,
    /// Whether s divides by depth.
    pub perspective: bool,
}

/// A camera prepared for one image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraView {
    eye: Vec3,
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    width: f32,
    height: f32,
    /// Focal length in pixels (perspective), pixels per metre (orthographic) or pixels per
    /// radian (fisheye, equirectangular).
    scale: f32,
    kind: Kind,
}

/// Distance below which a point counts as behind a perspective camera, metres.
pub const NEAR_M: f32 = 1e-4;

impl Camera {
    /// A three-quarter view from above of the box `lo..=hi` (metres, y up) for a
    /// `width × height` image: a 45° perspective camera looking at the box's centre from
    /// 40° of azimuth off +z towards +x and 30° above the horizon, at the nearest
    /// distance where every corner of the box is inside the view, plus 10 % of margin. A
    /// corner at (x, y) across and z along the view direction from the centre is in view
    /// from distance d when |x| ≤ (d + z)·tan(half the horizontal field) and
    /// |y| ≤ (d + z)·tan(half the vertical field); the eye also stays outside the box's
    /// bounding sphere. For scenes whose file gives no camera.
    pub fn framing(lo: Vec3, hi: Vec3, width: usize, height: usize) -> Camera {
        const FOV_Y_DEG: f32 = 45.0;
        let centre = 0.5 * (lo + hi);
        let (azimuth, elevation) = (40f32.to_radians(), 30f32.to_radians());
        let towards_eye =
            Vec3::new(azimuth.sin() * elevation.cos(), elevation.sin(), azimuth.cos() * elevation.cos());
        let forward = -towards_eye;
        let right = forward.cross(Vec3::Y).normalize();
        let up = right.cross(forward);
        let tan_y = (0.5 * FOV_Y_DEG.to_radians()).tan();
        let tan_x = tan_y * width.max(1) as f32 / height.max(1) as f32;
        let half = 0.5 * (hi - lo);
        let mut distance = half.length() + 1e-3;
        for k in 0..8 {
            let sign = |bit: i32| if k & bit != 0 { 1.0 } else { -1.0 };
            let c = Vec3::new(sign(1) * half.x, sign(2) * half.y, sign(4) * half.z);
            let (x, y, z) = (c.dot(right), c.dot(up), c.dot(forward));
            distance = distance.max(x.abs() / tan_x - z).max(y.abs() / tan_y - z);
        }
        Camera {
            position: centre + towards_eye * (1.1 * distance),
            look_at: centre,
            up: Vec3::Y,
            projection: Projection::Perspective { fov_y_deg: FOV_Y_DEG },
        }
    }

    /// Check the camera: finite vectors, distinct eye and target, a usable up vector,
    /// a field of view in (0, 179] degrees or a positive orthographic height.
    pub fn validate(&self, issues: &mut Issues, prefix: &str) {
        for (name, v) in [("position", self.position), ("look_at", self.look_at), ("up", self.up)] {
            issues.vector(&format!("{prefix}.{name}"), &v.to_array(), 1e9);
        }
        let forward = self.look_at - self.position;
        if forward.length() < 1e-6 {
            issues.push(
                format!("{prefix}.look_at"),
                format!("{:?}", self.look_at.to_array()),
                "a point different from the camera position",
            );
        } else if forward.normalize().cross(self.up.normalize_or_zero()).length() < 1e-4 {
            issues.push(
                format!("{prefix}.up"),
                format!("{:?}", self.up.to_array()),
                "a direction not parallel to the view direction",
            );
        }
        match self.projection {
            Projection::Perspective { fov_y_deg } => {
                issues.range_open_low(&format!("{prefix}.projection.fov_y_deg"), fov_y_deg, 0.0, 179.0)
            }
            Projection::Orthographic { height_m } => {
                issues.range_open_low(&format!("{prefix}.projection.height_m"), height_m, 0.0, 1e9)
            }
            Projection::Fisheye { fov_deg } => {
                issues.range_open_low(&format!("{prefix}.projection.fov_deg"), fov_deg, 0.0, 360.0)
            }
            Projection::Equirectangular => {}
        }
    }

    /// [`Camera::validate`] plus a problem if the projection is not planar, for renderers
    /// that need straight lines to stay straight (splats, rasterisation).
    pub fn validate_planar(&self, issues: &mut Issues, prefix: &str) {
        self.validate(issues, prefix);
        if !self.is_planar() {
            issues.push(
                format!("{prefix}.projection"),
                format!("{:?}", self.projection),
                "perspective or orthographic",
            );
        }
    }

    /// Whether the projection maps straight lines to straight lines (perspective and
    /// orthographic), which image-space effects such as screen-space stepping assume.
    pub fn is_planar(&self) -> bool {
        matches!(self.projection, Projection::Perspective { .. } | Projection::Orthographic { .. })
    }

    /// Prepare the camera for a `width × height` image; `None` if the camera is
    /// degenerate (see [`Camera::validate`]) or the image is empty.
    pub fn view(&self, width: usize, height: usize) -> Option<CameraView> {
        let forward = (self.look_at - self.position).try_normalize()?;
        let right = forward.cross(self.up).try_normalize()?;
        let up = right.cross(forward);
        if width == 0 || height == 0 {
            return None;
        }
        let (w, h) = (width as f32, height as f32);
        let (scale, kind) = match self.projection {
            Projection::Perspective { fov_y_deg } if fov_y_deg > 0.0 && fov_y_deg < 180.0 => {
                (0.5 * h / (0.5 * fov_y_deg.to_radians()).tan(), Kind::Perspective)
            }
            Projection::Orthographic { height_m } if height_m > 0.0 => (h / height_m, Kind::Orthographic),
            Projection::Fisheye { fov_deg } if fov_deg > 0.0 && fov_deg <= 360.0 => {
                let half_fov_rad = 0.5 * fov_deg.to_radians();
                (0.5 * w.min(h) / half_fov_rad, Kind::Fisheye { half_fov_rad })
            }
            Projection::Equirectangular => {
                (w / std::f32::consts::TAU, Kind::Equirectangular { scale_y: h / std::f32::consts::PI })
            }
            _ => return None,
        };
        Some(CameraView {
            eye: self.position,
            right,
            up,
            forward,
            width: width as f32,
            height: height as f32,
            scale,
            kind,
        })
    }
}

impl CameraView {
    /// Project a world point; `None` if it is behind (or at) a perspective camera, or
    /// outside a fisheye's circle.
    #[inline]
    pub fn project(&self, p: Vec3) -> Option<Projected> {
        match self.kind {
            Kind::Perspective | Kind::Orthographic => {
                let d = p - self.eye;
                let depth = d.dot(self.forward);
                let (cx, cy) = (0.5 * self.width, 0.5 * self.height);
                let px_per_m = if self.kind == Kind::Perspective {
                    if !(depth > NEAR_M) {
                        return None;
                    }
                    self.scale / depth
                } else {
                    self.scale
                };
                Some(Projected {
                    x_px: cx + d.dot(self.right) * px_per_m,
                    y_px: cy - d.dot(self.up) * px_per_m,
                    depth,
                    px_per_m,
                })
            }
            _ => self.project_curved(p),
        }
    }

    /// [`CameraView::project`] for the fisheye and equirectangular kinds, out of line so
    /// that the planar kinds' few operations inline into the callers' loops.
    #[inline(never)]
    fn project_curved(&self, p: Vec3) -> Option<Projected> {
        let d = p - self.eye;
        let depth = d.dot(self.forward);
        let (cx, cy) = (0.5 * self.width, 0.5 * self.height);
        match self.kind {
            Kind::Fisheye { half_fov_rad } => {
                let distance = d.length();
                if !(distance > NEAR_M) {
                    return None;
                }
                let (dx, dy) = (d.dot(self.right), d.dot(self.up));
                let rho = dx.hypot(dy);
                let theta = rho.atan2(depth);
                if theta > half_fov_rad {
                    return None;
                }
                let r_px = theta * self.scale;
                let (ux, uy) = if rho > 0.0 { (dx / rho, dy / rho) } else { (0.0, 0.0) };
                Some(Projected {
                    x_px: cx + r_px * ux,
                    y_px: cy - r_px * uy,
                    depth: distance,
                    px_per_m: self.scale / distance,
                })
            }
            Kind::Equirectangular { scale_y } => {
                let distance = d.length();
                if !(distance > NEAR_M) {
                    return None;
                }
                let (dx, dy) = (d.dot(self.right), d.dot(self.up));
                let azimuth = dx.atan2(depth);
                let elevation = (dy / distance).clamp(-1.0, 1.0).asin();
                Some(Projected {
                    x_px: cx + azimuth * self.scale,
                    y_px: cy - elevation * scale_y,
                    depth: distance,
                    px_per_m: self.scale / distance,
                })
            }
            Kind::Perspective | Kind::Orthographic => None,
        }
    }

    /// An orthographic view's projection as three affine maps of the world point p:
    /// `x_px`, `y_px` and `depth` are each `w.xyz · p + w.w` for the rows `[x, y, depth]`
    /// returned (what [`CameraView::project`] computes, rearranged: equal up to f32
    /// rounding). `None` for the other projections, which are not affine.
    pub fn orthographic_affine(&self) -> Option<[glam::Vec4; 3]> {
        if self.kind != Kind::Orthographic {
            return None;
        }
        let (cx, cy, s) = (0.5 * self.width, 0.5 * self.height, self.scale);
        let (r, u, f) = (self.right * s, -self.up * s, self.forward);
        Some([r.extend(cx - self.eye.dot(r)), u.extend(cy - self.eye.dot(u)), f.extend(-self.eye.dot(f))])
    }

    /// The camera's frame for projecting many points at once (in SIMD lanes, say), for
    /// perspective and orthographic views; `None` for fisheye and equirectangular ones.
    /// [`Pinhole`] documents the formula; it is the one [`CameraView::project`] uses,
    /// operation for operation, so lanes that follow it get the same bits.
    pub fn pinhole(&self) -> Option<Pinhole> {
        let perspective = match self.kind {
            Kind::Perspective => true,
            Kind::Orthographic => false,
            _ => return None,
        };
        Some(Pinhole {
            eye: self.eye,
            right: self.right,
            up: self.up,
            forward: self.forward,
            centre_px: (0.5 * self.width, 0.5 * self.height),
            scale: self.scale,
            perspective,
        })
    }

    /// The primary ray through continuous pixel position `(x_px, y_px)`: origin and unit
    /// direction. For a fisheye, positions outside its circle give directions past the
    /// field of view.
    pub fn ray(&self, x_px: f32, y_px: f32) -> (Vec3, Vec3) {
        let sx = (x_px - 0.5 * self.width) / self.scale;
        let sy = (0.5 * self.height - y_px) / self.scale;
        match self.kind {
            Kind::Perspective => (self.eye, (self.forward + self.right * sx + self.up * sy).normalize()),
            Kind::Orthographic => (self.eye + self.right * sx + self.up * sy, self.forward),
            Kind::Fisheye { .. } => {
                // (sx, sy) is the angle from the view direction times the unit image direction.
                let theta = sx.hypot(sy);
                let (ux, uy) = if theta > 0.0 { (sx / theta, sy / theta) } else { (0.0, 0.0) };
                let (s, c) = theta.sin_cos();
                (self.eye, (self.forward * c + (self.right * ux + self.up * uy) * s).normalize())
            }
            Kind::Equirectangular { scale_y } => {
                let (azimuth, elevation) = (sx, (0.5 * self.height - y_px) / scale_y);
                let (sa, ca) = azimuth.sin_cos();
                let (se, ce) = elevation.sin_cos();
                (self.eye, (self.forward * (ca * ce) + self.right * (sa * ce) + self.up * se).normalize())
            }
        }
    }

    /// Solid angle of the pixel that world point `p` projects into, steradians (for a
    /// parallel projection: the pixel's area in square metres). Perspective: cos³θ/f²
    /// with θ the angle from the view axis and f the focal length in pixels; fisheye
    /// (equidistant): sin θ/(θ s²) with s pixels per radian; equirectangular:
    /// cos(elevation)/(s_x s_y). Summed over every pixel this gives the field of view's
    /// solid angle (tested).
    pub fn pixel_solid_angle(&self, p: Vec3) -> f32 {
        let d = p - self.eye;
        let distance = d.length();
        match self.kind {
            Kind::Orthographic => 1.0 / (self.scale * self.scale),
            Kind::Perspective => {
                let c = (d.dot(self.forward) / distance).max(1e-6);
                c * c * c / (self.scale * self.scale)
            }
            Kind::Fisheye { .. } => {
                let theta = (d.dot(self.forward) / distance).clamp(-1.0, 1.0).acos();
                let ratio = if theta > 1e-4 { theta.sin() / theta } else { 1.0 };
                ratio / (self.scale * self.scale)
            }
            Kind::Equirectangular { scale_y } => {
                let cos_elevation = (1.0 - (d.dot(self.up) / distance).powi(2)).max(0.0).sqrt();
                cos_elevation / (self.scale * scale_y)
            }
        }
    }

    /// Whether straight lines stay straight (perspective or orthographic).
    pub fn is_planar(&self) -> bool {
        matches!(self.kind, Kind::Perspective | Kind::Orthographic)
    }

    /// Whether this is a perspective view.
    pub fn is_perspective(&self) -> bool {
        self.kind == Kind::Perspective
    }

    /// Image size (width, height), pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width as usize, self.height as usize)
    }

    /// Unit view direction.
    pub fn forward(&self) -> Vec3 {
        self.forward
    }

    /// Image-plane components (right, down) of a world-space direction, in metres;
    /// multiply by [`Projected::px_per_m`] for pixels.
    pub fn image_direction(&self, dir: Vec3) -> (f32, f32) {
        (dir.dot(self.right), -dir.dot(self.up))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_keeps_every_corner_of_the_box_in_the_image() {
        let boxes = [
            (Vec3::new(-20.0, 0.0, -15.0), Vec3::new(20.0, 8.0, 15.0)), // a yard
            (Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 0.8, 0.5)),     // a table
            (Vec3::new(100.0, 5.0, -3.0), Vec3::new(101.0, 60.0, -2.0)), // a tower, off centre
            (Vec3::ZERO, Vec3::ZERO),                                   // a point
        ];
        for (lo, hi) in boxes {
            for (w, h) in [(1280, 720), (256, 256), (360, 640)] {
                let camera = Camera::framing(lo, hi, w, h);
                let mut issues = Issues::default();
                camera.validate_planar(&mut issues, "camera");
                assert!(issues.into_result().is_ok(), "{camera:?}");
                let view = camera.view(w, h).unwrap();
                assert!(camera.position.y > hi.y, "from above: {camera:?}");
                let (mut lo_px, mut hi_px) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
                for k in 0..8 {
                    let corner = Vec3::select(glam::BVec3::new(k & 1 != 0, k & 2 != 0, k & 4 != 0), hi, lo);
                    let p = view.project(corner).unwrap();
                    assert!(
                        (0.0..=w as f32).contains(&p.x_px) && (0.0..=h as f32).contains(&p.y_px),
                        "{corner} of {lo}..{hi} at {w}x{h}: ({}, {})",
                        p.x_px,
                        p.y_px
                    );
                    lo_px = [lo_px[0].min(p.x_px), lo_px[1].min(p.y_px)];
                    hi_px = [hi_px[0].max(p.x_px), hi_px[1].max(p.y_px)];
                }
                // Tight: the box spans most of the image's width or height (not all of it: the
                // nearest corner binds one side; the far side is further and looks smaller).
                let fill = ((hi_px[0] - lo_px[0]) / w as f32).max((hi_px[1] - lo_px[1]) / h as f32);
                assert!(hi == lo || fill > 0.6, "{lo}..{hi} at {w}x{h}: fills {fill}");
            }
        }
    }

    #[test]
    fn the_orthographic_affine_maps_project_like_project() {
        let view = cam(Projection::Orthographic { height_m: 7.0 }).view(320, 200).unwrap();
        let [x, y, d] = view.orthographic_affine().unwrap();
        for k in 0..200 {
            let t = k as f32 * 0.37;
            let p = Vec3::new(4.0 * t.sin(), 3.0 * (1.3 * t).cos(), 5.0 * (0.7 * t).sin());
            let q = view.project(p).unwrap();
            let f = |r: glam::Vec4| r.truncate().dot(p) + r.w;
            // The same sums in another order: a few f32 ulps of the largest term (~200).
            assert!((f(x) - q.x_px).abs() < 1e-4 && (f(y) - q.y_px).abs() < 1e-4, "{p}");
            assert!((f(d) - q.depth).abs() < 1e-5, "{p}");
        }
        assert!(
            cam(Projection::Perspective { fov_y_deg: 50.0 })
                .view(32, 32)
                .unwrap()
                .orthographic_affine()
                .is_none()
        );
    }

    #[test]
    fn the_pinhole_formula_gives_the_bits_project_gives() {
        for projection in
            [Projection::Perspective { fov_y_deg: 50.0 }, Projection::Orthographic { height_m: 7.0 }]
        {
            let view = cam(projection).view(320, 200).unwrap();
            let ph = view.pinhole().unwrap();
            let mut behind = 0;
            for k in 0..400 {
                let t = k as f32 * 0.37;
                let p = Vec3::new(9.0 * t.sin(), 3.0 * (1.3 * t).cos(), 9.0 * (0.7 * t).sin());
                let d = p - ph.eye;
                let depth = d.x * ph.forward.x + d.y * ph.forward.y + d.z * ph.forward.z;
                let s = if ph.perspective { ph.scale / depth } else { ph.scale };
                let x = ph.centre_px.0 + (d.x * ph.right.x + d.y * ph.right.y + d.z * ph.right.z) * s;
                let y = ph.centre_px.1 - (d.x * ph.up.x + d.y * ph.up.y + d.z * ph.up.z) * s;
                match view.project(p) {
                    Some(q) => {
                        assert!(!ph.perspective || depth > NEAR_M);
                        assert_eq!((x.to_bits(), y.to_bits()), (q.x_px.to_bits(), q.y_px.to_bits()), "{p}");
                    }
                    None => {
                        assert!(ph.perspective && !(depth > NEAR_M), "{p}");
                        behind += 1;
                    }
                }
            }
            // Points on both sides of a perspective camera were tried.
            assert!(!ph.perspective || (behind > 20 && behind < 380), "{behind}");
        }
        let fisheye = cam(Projection::Fisheye { fov_deg: 180.0 }).view(64, 64).unwrap();
        assert!(fisheye.pinhole().is_none());
    }

    fn cam(projection: Projection) -> Camera {
        Camera {
            position: Vec3::new(1.0, 2.0, 6.0),
            look_at: Vec3::new(0.0, 0.5, 0.0),
            up: Vec3::Y,
            projection,
        }
    }

    #[test]
    fn ray_and_project_are_inverse() {
        for projection in [
            Projection::Perspective { fov_y_deg: 50.0 },
            Projection::Orthographic { height_m: 3.0 },
            Projection::Fisheye { fov_deg: 180.0 },
            Projection::Equirectangular,
        ] {
            let v = cam(projection).view(320, 200).unwrap();
            // The fisheye's circle has radius 100 px about (160, 100): corners lie outside.
            let corners = !matches!(projection, Projection::Fisheye { .. });
            let inner = [(160.0, 100.0), (120.3, 60.7), (200.2, 150.1), (161.0, 100.0)];
            let outer = [(0.5, 0.5), (300.2, 12.7)];
            for (x, y) in inner.into_iter().chain(outer.into_iter().filter(|_| corners)) {
                let (o, d) = v.ray(x, y);
                let p = v.project(o + d * 4.0).unwrap();
                assert!((p.x_px - x).abs() < 1e-3 && (p.y_px - y).abs() < 1e-3, "{projection:?}");
            }
        }
    }

    #[test]
    fn dome_and_panorama_place_directions_where_their_formats_say() {
        let up = Camera {
            position: Vec3::ZERO,
            look_at: Vec3::Y,
            up: Vec3::Z,
            projection: Projection::Fisheye { fov_deg: 180.0 },
        };
        let v = up.view(200, 200).unwrap();
        // Zenith at the centre; the horizon on the circle's edge (radius 100 px); 45°
        // elevation half way out (equidistant mapping).
        let z = v.project(Vec3::new(0.0, 5.0, 0.0)).unwrap();
        assert!((z.x_px - 100.0).abs() < 1e-4 && (z.y_px - 100.0).abs() < 1e-4);
        let h = v.project(Vec3::new(3.0, 0.0, 0.0)).unwrap();
        assert!(((h.x_px - 100.0).hypot(h.y_px - 100.0) - 100.0).abs() < 1e-3);
        let m = v.project(Vec3::new(0.0, 1.0, 1.0)).unwrap();
        assert!(((m.x_px - 100.0).hypot(m.y_px - 100.0) - 50.0).abs() < 1e-3);
        assert!(v.project(Vec3::new(0.0, -1.0, 0.2)).is_none(), "below the horizon");

        let pano = Camera { projection: Projection::Equirectangular, look_at: Vec3::Z, up: Vec3::Y, ..up };
        let v = pano.view(360, 180).unwrap();
        // Straight ahead at the centre, straight up on the top edge, behind at the side edges.
        let a = v.project(Vec3::Z).unwrap();
        assert!((a.x_px - 180.0).abs() < 1e-3 && (a.y_px - 90.0).abs() < 1e-3);
        assert!(v.project(Vec3::Y * 2.0).unwrap().y_px.abs() < 1e-3);
        let behind = v.project(Vec3::new(-1e-3, 0.0, -1.0)).unwrap();
        assert!((behind.x_px - 360.0).abs() < 0.1 || behind.x_px.abs() < 0.1, "{behind:?}");
    }

    #[test]
    fn pixel_solid_angles_add_up_to_the_field_of_view() {
        // Sum over pixel centres of the solid angle of the direction through each.
        let total = |projection: Projection, w: usize, h: usize| {
            let v = Camera { position: Vec3::ZERO, look_at: Vec3::Z, up: Vec3::Y, projection }
                .view(w, h)
                .unwrap();
            let mut sum = 0.0f64;
            for y in 0..h {
                for x in 0..w {
                    let (o, d) = v.ray(x as f32 + 0.5, y as f32 + 0.5);
                    if v.project(o + d).is_some() {
                        sum += f64::from(v.pixel_solid_angle(o + d * 3.0));
                    }
                }
            }
            sum
        };
        // Equirectangular: the whole sphere, 4π; a 180° dome master: the hemisphere, 2π
        // (its circle's pixel boundary costs about a pixel ring, 0.5 %); a perspective
        // 90° × 90° view: 4 asin(sin²45°) = 2π/3. Tolerances: the midpoint rule's error.
        let pi = std::f64::consts::PI;
        assert!((total(Projection::Equirectangular, 400, 200) / (4.0 * pi) - 1.0).abs() < 1e-3);
        assert!((total(Projection::Fisheye { fov_deg: 180.0 }, 300, 300) / (2.0 * pi) - 1.0).abs() < 0.01);
        let persp = total(Projection::Perspective { fov_y_deg: 90.0 }, 200, 200);
        assert!((persp / (2.0 * pi / 3.0) - 1.0).abs() < 1e-3, "{persp}");
    }

    #[test]
    fn behind_the_camera_is_not_projected() {
        let v = cam(Projection::Perspective { fov_y_deg: 50.0 }).view(10, 10).unwrap();
        assert!(v.project(Vec3::new(2.0, 3.5, 12.0)).is_none());
    }

    #[test]
    fn degenerate_cameras_are_reported() {
        let mut bad = cam(Projection::Perspective { fov_y_deg: 0.0 });
        bad.up = Vec3::new(-1.0, -1.5, -6.0);
        let mut issues = Issues::default();
        bad.validate(&mut issues, "camera");
        let errs = issues.into_result().unwrap_err();
        assert_eq!(errs.len(), 2, "{errs:?}");
        assert!(bad.view(10, 10).is_none());
    }
}
