//! Scene geometry: triangles with an object id, and procedural shapes for the built-in
//! scenes (the table of Fig 7 and primitives like Fig 8).
//!
//! Triangles are counter-clockwise seen from outside (right-handed outward normals),
//! lengths in metres, y up.

use glam::Vec3;

/// A triangle soup with an object id per triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertices of each triangle, counter-clockwise seen from outside.
    pub triangles: Vec<[Vec3; 3]>,
    /// Object of each triangle (index into the scene's objects).
    pub object: Vec<u32>,
}

/// What cleaning a mesh removed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Cleaned {
    /// Triangles with a non-finite vertex.
    pub non_finite: usize,
    /// Triangles of (near) zero area.
    pub degenerate: usize,
}

impl Mesh {
    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Append `other` as object `object`.
    pub fn push_object(&mut self, triangles: &[[Vec3; 3]], object: u32) {
        self.triangles.extend_from_slice(triangles);
        self.object.extend(std::iter::repeat_n(object, triangles.len()));
    }

    /// Unit normal of triangle `t` (zero for a degenerate one).
    pub fn normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.triangles[t];
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// Remove triangles with non-finite vertices or an area below `min_area_m2`;
    /// returns the counts removed.
    pub fn clean(&mut self, min_area_m2: f32) -> Cleaned {
        let mut out = Cleaned::default();
        let mut keep = Vec::with_capacity(self.len());
        for tri in &self.triangles {
            let ok = if !tri.iter().all(|p| p.is_finite()) {
                out.non_finite += 1;
                false
            } else if 0.5 * (tri[1] - tri[0]).cross(tri[2] - tri[0]).length() < min_area_m2 {
                out.degenerate += 1;
                false
            } else {
                true
            };
            keep.push(ok);
        }
        let mut k = 0;
        self.triangles.retain(|_| {
            k += 1;
            keep[k - 1]
        });
        let mut k = 0;
        self.object.retain(|_| {
            k += 1;
            keep[k - 1]
        });
        out
    }

    /// For each object (by id, up to the largest id used), whether its triangles form
    /// closed solids with outward faces: every directed edge (a, b) (vertices compared
    /// bit for bit) is matched by exactly one (b, a) and none repeats, and each shell
    /// (triangles joined through matched edges) encloses a positive signed volume. Seen
    /// from outside, the nearest surface of such an object along any line is a face
    /// turned towards the viewer, so its back faces can be skipped when only the nearest
    /// depth matters.
    pub fn closed_objects(&self) -> Vec<bool> {
        use std::collections::HashMap;
        type Vertex = [u32; 3];
        let objects = self.object.iter().max().map_or(0, |&o| o as usize + 1);
        let key = |p: Vec3| -> Vertex { [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()] };
        // Directed edge of an object → (how many times, one triangle with it).
        let mut edges: HashMap<(u32, Vertex, Vertex), (u32, usize)> = HashMap::new();
        let mut closed = vec![false; objects];
        for (t, (tri, &o)) in self.triangles.iter().zip(&self.object).enumerate() {
            closed[o as usize] = true;
            for k in 0..3 {
                edges.entry((o, key(tri[k]), key(tri[(k + 1) % 3]))).or_insert((0, t)).0 += 1;
            }
        }
        // Shells: union-find over triangles joined by an edge and its reverse.
        let mut parent: Vec<usize> = (0..self.len()).collect();
        fn root(parent: &mut [usize], mut t: usize) -> usize {
            while parent[t] != t {
                parent[t] = parent[parent[t]];
                t = parent[t];
            }
            t
        }
        for (&(o, a, b), &(n, t)) in &edges {
            match edges.get(&(o, b, a)) {
                Some(&(1, u)) if n == 1 => {
                    let (ra, rb) = (root(&mut parent, t), root(&mut parent, u));
                    parent[ra] = rb;
                }
                _ => closed[o as usize] = false,
            }
        }
        let mut volume = vec![0.0f64; self.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            let [a, b, c] = tri.map(|p| p.as_dvec3());
            volume[root(&mut parent, t)] += a.dot(b.cross(c)) / 6.0;
        }
        for t in 0..self.len() {
            if root(&mut parent, t) == t && volume[t] <= 0.0 {
                closed[self.object[t] as usize] = false;
            }
        }
        closed
    }

    /// Axis-aligned bounds (min, max) of all vertices; `None` when empty.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.triangles.iter().flatten();
        let first = *it.next()?;
        Some(it.fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))))
    }
}

/// The ground square from -`half` to `half` in x and z at height 0, facing up.
pub fn ground_square(half: f32) -> [[Vec3; 3]; 2] {
    let g = half;
    quad(Vec3::new(-g, 0.0, -g), Vec3::new(-g, 0.0, g), Vec3::new(g, 0.0, g), Vec3::new(g, 0.0, -g))
}

/// Two triangles of the quad a, b, c, d (counter-clockwise seen from the front).
pub fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> [[Vec3; 3]; 2] {
    [[a, b, c], [a, c, d]]
}

/// The twelve triangles of the box from `lo` to `hi`, outward facing.
pub fn cuboid(lo: Vec3, hi: Vec3) -> Vec<[Vec3; 3]> {
    let p = |x: bool, y: bool, z: bool| {
        Vec3::new(if x { hi.x } else { lo.x }, if y { hi.y } else { lo.y }, if z { hi.z } else { lo.z })
    };
    let faces = [
        // +y (top), seen from above: counter-clockwise in x-z with z towards the viewer...
        quad(p(false, true, false), p(false, true, true), p(true, true, true), p(true, true, false)),
        quad(p(false, false, false), p(true, false, false), p(true, false, true), p(false, false, true)),
        quad(p(true, false, false), p(true, true, false), p(true, true, true), p(true, false, true)),
        quad(p(false, false, false), p(false, false, true), p(false, true, true), p(false, true, false)),
        quad(p(false, false, true), p(true, false, true), p(true, true, true), p(false, true, true)),
        quad(p(false, false, false), p(false, true, false), p(true, true, false), p(true, false, false)),
    ];
    faces.iter().flatten().copied().collect()
}

/// A UV sphere of `radius` around `centre` with `segments` around and `segments / 2`
/// rings, outward facing.
pub fn sphere(centre: Vec3, radius: f32, segments: usize) -> Vec<[Vec3; 3]> {
    let (n, m) = (segments.max(3), (segments / 2).max(2));
    // The seam (i = n) and the poles (j = 0, m) reuse the same vertices bit for bit, so
    // the sphere is closed (`Mesh::closed_objects`).
    let at = |i: usize, j: usize| {
        if j == 0 || j == m {
            return centre + Vec3::Y * if j == 0 { radius } else { -radius };
        }
        let (theta, phi) =
            (j as f32 / m as f32 * std::f32::consts::PI, (i % n) as f32 / n as f32 * std::f32::consts::TAU);
        centre + Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()) * radius
    };
    let mut out = Vec::new();
    for j in 0..m {
        for i in 0..n {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            if j != 0 {
                out.push([a, b, c]);
            }
            if j != m - 1 {
                out.push([a, c, d]);
            }
        }
    }
    out
}

/// A cone with its base centred at `base` (radius `radius`, pointing up `height`),
/// closed at the base, outward facing.
pub fn cone(base: Vec3, radius: f32, height: f32, segments: usize) -> Vec<[Vec3; 3]> {
    let n = segments.max(3);
    let apex = base + Vec3::Y * height;
    let rim = |i: usize| {
        let phi = (i % n) as f32 / n as f32 * std::f32::consts::TAU;
        base + Vec3::new(phi.cos(), 0.0, phi.sin()) * radius
    };
    let mut out = Vec::new();
    for i in 0..n {
        let (a, b) = (rim(i), rim(i + 1));
        out.push([a, apex, b]);
        out.push([a, b, base]);
    }
    out
}

/// The built-in scenes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Builtin {
    /// The paper's Fig 7: a table on a ground square.
    #[default]
    Table,
    /// The paper's Fig 8: primitives on a ground plane.
    Primitives,
    /// Like the paper's Fig 9: a village of about 12,000+ triangles.
    Village,
    /// A small yard like one a user makes in Blender: a house with a steep gable roof,
    /// three trees, a fence and a bench (its stabilisation workload).
    Yard,
}

impl Builtin {
    /// The scene's mesh.
    pub fn mesh(self) -> Mesh {
        match self {
            Builtin::Table => table_scene(4.0, 1.2, 0.7),
            Builtin::Primitives => primitives_scene(),
            Builtin::Village => village_scene(),
            Builtin::Yard => yard_scene(),
        }
    }
}

/// A closed cylinder standing on `base` (radius, height), outward facing.
pub fn cylinder(base: Vec3, radius: f32, height: f32, segments: usize) -> Vec<[Vec3; 3]> {
    let n = segments.max(3);
    let top = base + Vec3::Y * height;
    let rim = |c: Vec3, i: usize| {
        let phi = (i % n) as f32 / n as f32 * std::f32::consts::TAU;
        c + Vec3::new(phi.cos(), 0.0, phi.sin()) * radius
    };
    let mut out = Vec::new();
    for i in 0..n {
        let (a, b, c, d) = (rim(base, i), rim(base, i + 1), rim(top, i + 1), rim(top, i));
        out.extend(quad(a, d, c, b));
        out.push([top, c, d]);
        out.push([base, a, b]);
    }
    out
}

/// Primitives on a ground plane like the paper's Fig 8 (GLUT shapes): objects 0 ground
/// (6 m square), 1 cube, 2 sphere, 3 cone, 4 cylinder. With one group per object this
/// gives the paper's five snow maps.
pub fn primitives_scene() -> Mesh {
    let mut mesh = Mesh::default();
    let g = 3.0;
    mesh.push_object(&ground_square(g), 0);
    mesh.push_object(&cuboid(Vec3::new(-1.9, 0.0, -1.9), Vec3::new(-0.9, 1.0, -0.9)), 1);
    mesh.push_object(&sphere(Vec3::new(1.3, 0.7, -1.3), 0.7, 32), 2);
    mesh.push_object(&cone(Vec3::new(-1.3, 0.0, 1.3), 0.7, 1.4, 32), 3);
    mesh.push_object(&cylinder(Vec3::new(1.3, 0.0, 1.3), 0.5, 0.9, 32), 4);
    mesh
}

/// A house: a box with a gable roof on it (ridge along x) overhanging by `eave` metres.
/// Both are closed solids.
pub fn house(centre: Vec3, size: Vec3, roof_height: f32, eave: f32) -> Vec<[Vec3; 3]> {
    let (hx, hz) = (0.5 * size.x, 0.5 * size.z);
    let mut out = cuboid(centre - Vec3::new(hx, 0.0, hz), centre + Vec3::new(hx, size.y, hz));
    let y = centre.y + size.y;
    let (ex, ez) = (hx + eave, hz + eave);
    let c = centre;
    let ridge0 = Vec3::new(c.x - ex, y + roof_height, c.z);
    let ridge1 = Vec3::new(c.x + ex, y + roof_height, c.z);
    let (a0, a1) = (Vec3::new(c.x - ex, y, c.z - ez), Vec3::new(c.x + ex, y, c.z - ez));
    let (b0, b1) = (Vec3::new(c.x - ex, y, c.z + ez), Vec3::new(c.x + ex, y, c.z + ez));
    // Two roof slopes (upward facing), the flat underside and the two gables.
    out.extend(quad(a0, ridge0, ridge1, a1));
    out.extend(quad(b1, ridge1, ridge0, b0));
    out.extend(quad(a0, a1, b1, b0));
    out.push([a0, b0, ridge0]);
    out.push([a1, ridge1, b1]);
    out
}

/// The larger scene of the paper's Fig 9 (about 12,000+ triangles): a ground square of
/// 40 m with houses, benches and trees placed on a jittered grid (fixed layout).
/// Objects: 0 ground, then one per item.
pub fn village_scene() -> Mesh {
    let mut mesh = Mesh::default();
    let g = 20.0;
    mesh.push_object(&ground_square(g), 0);
    // A fixed pseudo-random layout (an LCG: the same scene on every machine).
    let mut s = 0x5eed_u64;
    let mut r = move || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 33) as f32 / (1u64 << 31) as f32
    };
    let mut object = 1;
    for gz in 0..7 {
        for gx in 0..7 {
            let c = Vec3::new(-16.5 + 5.5 * gx as f32 + r() - 0.5, 0.0, -16.5 + 5.5 * gz as f32 + r() - 0.5);
            let tris = match (gx + 2 * gz) % 4 {
                0 | 2 => house(c, Vec3::new(3.0 + r(), 2.2 + r(), 2.5 + r()), 1.0 + 0.5 * r(), 0.3),
                1 => {
                    // A tree: trunk and three stacked cones.
                    let mut t = cylinder(c, 0.15, 1.0, 16);
                    for (k, (rad, h)) in [(1.4f32, 1.6f32), (1.1, 1.4), (0.8, 1.2)].into_iter().enumerate() {
                        t.extend(cone(c + Vec3::Y * (0.8 + 0.9 * k as f32), rad, h, 64));
                    }
                    t
                }
                _ => {
                    // A bench and a snowman.
                    let mut t = cuboid(c + Vec3::new(-0.9, 0.4, -0.25), c + Vec3::new(0.9, 0.48, 0.25));
                    for sx in [-0.8f32, 0.75] {
                        t.extend(cuboid(c + Vec3::new(sx, 0.0, -0.2), c + Vec3::new(sx + 0.05, 0.4, 0.2)));
                    }
                    let m = c + Vec3::new(0.0, 0.0, 1.2);
                    t.extend(sphere(m + Vec3::Y * 0.4, 0.4, 20));
                    t.extend(sphere(m + Vec3::Y * 1.0, 0.28, 20));
                    t
                }
            };
            mesh.push_object(&tris, object);
            object += 1;
        }
    }
    mesh
}

/// Snowfall on [`yard_scene`], as `scenes/snow-yard.toml` has it: 256² maps,
/// 64 directions of 8° spread, 4 cm/h in 0.25 h steps, repose 35°, 0.3 m margin.
pub fn yard_config() -> crate::SnowConfig {
    crate::SnowConfig {
        map_resolution: 256,
        directions: 64,
        spread_deg: 8.0,
        rate_cm_per_h: 4.0,
        time_step_h: 0.25,
        repose_deg: 35.0,
        margin_m: 0.3,
        ..crate::SnowConfig::default()
    }
}

/// A small yard like one made in Blender 3.4 (ground, a house with
/// a pitched roof, three trees, a fence, a bench; 24 objects): a 12 m ground square, a
/// 5 × 3 × 4 m house whose gable roof (ridge along x, 0.4 m eaves) rises 2.1 m over its
/// 2.4 m half-depth (41°, steeper than a 35° repose, so its snow slides off and piles up
/// under the eaves), three trees (trunk and two stacked cones of 49-51°), a fence of 15
/// posts and two rails on each of the ground's front and left sides, and a bench.
/// Objects: 0 ground, 1 house, 2-4 trees, 5-23 fence posts and rails, 24 bench.
pub fn yard_scene() -> Mesh {
    let mut mesh = Mesh::default();
    mesh.push_object(&ground_square(6.0), 0);
    mesh.push_object(&house(Vec3::new(-1.0, 0.0, -1.5), Vec3::new(5.0, 3.0, 4.0), 2.1, 0.4), 1);
    for (k, (x, z, s)) in
        [(3.6f32, -3.2f32, 1.0f32), (4.2, 1.2, 0.8), (-4.3, 3.4, 1.2)].into_iter().enumerate()
    {
        let c = Vec3::new(x, 0.0, z);
        let mut t = cylinder(c, 0.15 * s, 0.9 * s, 16);
        t.extend(cone(c + Vec3::Y * 0.7 * s, 1.3 * s, 1.5 * s, 48));
        t.extend(cone(c + Vec3::Y * 1.6 * s, 0.9 * s, 1.1 * s, 48));
        mesh.push_object(&t, 2 + k as u32);
    }
    let mut object = 5;
    // Posts every 1.5 m along z = 5.5 (front) and x = -5.5 (left), then two rails each.
    for k in 0..8 {
        let x = -5.25 + 1.5 * k as f32;
        mesh.push_object(&cuboid(Vec3::new(x - 0.05, 0.0, 5.45), Vec3::new(x + 0.05, 1.1, 5.55)), object);
        object += 1;
    }
    for k in 1..8 {
        let z = 5.25 - 1.5 * k as f32;
        mesh.push_object(&cuboid(Vec3::new(-5.55, 0.0, z - 0.05), Vec3::new(-5.45, 1.1, z + 0.05)), object);
        object += 1;
    }
    for y in [0.45f32, 0.9] {
        mesh.push_object(&cuboid(Vec3::new(-5.3, y, 5.47), Vec3::new(5.3, y + 0.08, 5.53)), object);
        mesh.push_object(&cuboid(Vec3::new(-5.53, y, -5.3), Vec3::new(-5.47, y + 0.08, 5.3)), object + 1);
        object += 2;
    }
    let bench = Vec3::new(1.5, 0.0, 2.5);
    let mut b = cuboid(bench + Vec3::new(-0.9, 0.42, -0.22), bench + Vec3::new(0.9, 0.48, 0.22));
    for sx in [-0.8f32, 0.72] {
        b.extend(cuboid(bench + Vec3::new(sx, 0.0, -0.2), bench + Vec3::new(sx + 0.08, 0.42, 0.2)));
    }
    mesh.push_object(&b, object);
    mesh
}

/// The table scene of the paper's Fig 7: a ground square of `ground_m` and a table (top
/// 0.05 m thick at `height_m`, four legs) in its middle. Objects: 0 ground, 1 table.
pub fn table_scene(ground_m: f32, top_m: f32, height_m: f32) -> Mesh {
    let mut mesh = Mesh::default();
    let g = 0.5 * ground_m;
    mesh.push_object(&ground_square(g), 0);
    let t = 0.5 * top_m;
    let mut table = cuboid(Vec3::new(-t, height_m - 0.05, -t), Vec3::new(t, height_m, t));
    let leg = 0.04;
    for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let c = Vec3::new(sx * (t - 2.0 * leg), 0.0, sz * (t - 2.0 * leg));
        table.extend(cuboid(c - Vec3::new(leg, 0.0, leg), c + Vec3::new(leg, height_m - 0.05, leg)));
    }
    mesh.push_object(&table, 1);
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed and outward facing: the divergence theorem gives the volume, positive.
    fn volume(tris: &[[Vec3; 3]]) -> f32 {
        tris.iter().map(|[a, b, c]| a.dot(b.cross(*c)) / 6.0).sum()
    }

    #[test]
    fn the_primitives_are_closed_solids_and_open_or_inside_out_ones_are_not() {
        let mut mesh = Mesh::default();
        let c = Vec3::new(0.3, 0.2, -1.7);
        mesh.push_object(&sphere(c, 0.7, 20), 0);
        mesh.push_object(&cone(c, 0.5, 1.0, 64), 1);
        mesh.push_object(&cylinder(c, 0.15, 1.0, 16), 2);
        mesh.push_object(&house(c, Vec3::new(3.0, 2.0, 2.5), 1.0, 0.3), 3);
        mesh.push_object(&ground_square(2.0), 4);
        let inside_out: Vec<[Vec3; 3]> =
            cuboid(Vec3::ZERO, Vec3::ONE).iter().map(|t| [t[0], t[2], t[1]]).collect();
        mesh.push_object(&inside_out, 5);
        let mut holed = cuboid(Vec3::ZERO, Vec3::ONE);
        holed.pop();
        mesh.push_object(&holed, 6);
        // A large outward box with a small inside-out one apart: the total volume is
        // positive, but one shell faces inwards.
        let mut mixed = cuboid(Vec3::splat(10.0), Vec3::splat(14.0));
        mixed.extend(cuboid(Vec3::splat(20.0), Vec3::splat(21.0)).iter().map(|t| [t[0], t[2], t[1]]));
        mesh.push_object(&mixed, 7);
        assert_eq!(mesh.closed_objects(), vec![true, true, true, true, false, false, false, false]);
        // Every object of the village but its ground.
        let closed = village_scene().closed_objects();
        assert!(!closed[0] && closed[1..].iter().all(|&c| c), "{closed:?}");
    }

    #[test]
    fn primitives_are_closed_and_face_outwards() {
        let b = cuboid(Vec3::new(-1.0, 0.0, -2.0), Vec3::new(1.0, 3.0, 2.0));
        assert!((volume(&b) - 24.0).abs() < 1e-4, "{}", volume(&b));
        let s = sphere(Vec3::new(0.5, 1.0, 0.0), 2.0, 48);
        let exact = 4.0 / 3.0 * std::f32::consts::PI * 8.0;
        assert!(volume(&s) > 0.95 * exact && volume(&s) < exact, "{}", volume(&s));
        let c = cone(Vec3::ZERO, 1.0, 3.0, 64);
        assert!((volume(&c) - std::f32::consts::PI).abs() < 0.01, "{}", volume(&c));
        let y = cylinder(Vec3::new(0.2, 0.0, 0.1), 1.0, 2.0, 64);
        let exact = std::f32::consts::PI * 2.0;
        assert!(volume(&y) > 0.99 * exact && volume(&y) < exact, "{}", volume(&y));
        // The box's top faces point up.
        let mut m = Mesh::default();
        m.push_object(&b, 0);
        assert!(m.normal(0).y > 0.99 && m.normal(1).y > 0.99);
    }

    #[test]
    fn houses_are_closed_and_the_village_is_large() {
        let h = house(Vec3::new(1.0, 0.0, 2.0), Vec3::new(3.0, 2.0, 2.0), 1.0, 0.0);
        // Without eaves: box 3×2×2 plus a prism 3 × (2 × 1 / 2).
        assert!((volume(&h) - 15.0).abs() < 1e-3, "{}", volume(&h));
        let v = village_scene();
        assert!((12_000..16_000).contains(&v.len()), "{} triangles", v.len());
    }

    #[test]
    fn the_yard_is_issue_25s_scene() {
        let y = yard_scene();
        let objects = y.object.iter().max().map_or(0, |&o| o + 1);
        assert_eq!(objects, 25);
        let closed = y.closed_objects();
        assert!(!closed[0] && closed[1..].iter().all(|&c| c), "{closed:?}");
        // The roof is steeper than the scene's 35° repose: its up-facing slopes.
        let roof = (0..y.len())
            .filter(|&t| y.object[t] == 1)
            .map(|t| y.normal(t).y)
            .filter(|&up| up > 0.1 && up < 0.99)
            .fold(1.0f32, f32::min);
        let pitch = roof.acos().to_degrees();
        assert!((41.0..41.4).contains(&pitch), "roof pitch {pitch}°");
        let (lo, hi) = y.bounds().unwrap();
        assert!(lo.x >= -6.0 && hi.x <= 6.0 && lo.z >= -6.0 && hi.z <= 6.0 && hi.y > 5.0, "{lo} {hi}");
    }

    #[test]
    fn cleaning_counts_what_it_drops() {
        let mut m = table_scene(4.0, 1.0, 0.7);
        let n = m.len();
        m.push_object(&[[Vec3::ZERO, Vec3::ZERO, Vec3::X]], 2);
        m.push_object(&[[Vec3::NAN, Vec3::Y, Vec3::X]], 2);
        let c = m.clean(1e-10);
        assert_eq!(c, Cleaned { non_finite: 1, degenerate: 1 });
        assert_eq!((m.len(), m.object.len()), (n, n));
    }
}
