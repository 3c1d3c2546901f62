//! Ray-casting references for the snow probability (§3.3, Table 1).
//!
//! - [`ray_cast_probability`]: per texel of every map, the same snowfall directions as
//!   the shadow-map method, each tested by a ray from the texel's surface point back up
//!   the snowfall direction against every triangle through a bounding-volume hierarchy.
//!   The accuracy reference for the shadow-map probability.
//! - [`naive_vertex_probability`]: the paper's comparison method, per scene vertex with
//!   jittered rays tested against every triangle (no acceleration), for the speed
//!   comparison of Table 1.

use glam::Vec3;
use rayon::prelude::*;

use crate::mesh::Mesh;
use crate::sim::SnowSim;

/// Axis-aligned box.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    lo: Vec3,
    hi: Vec3,
}

impl Aabb {
    fn of(t: &[Vec3; 3]) -> Self {
        Self { lo: t[0].min(t[1]).min(t[2]), hi: t[0].max(t[1]).max(t[2]) }
    }

    fn union(self, o: Self) -> Self {
        Self { lo: self.lo.min(o.lo), hi: self.hi.max(o.hi) }
    }

    /// Whether the ray o + s·d (s in [0, ∞)) meets the box (slab test).
    fn hit(&self, o: Vec3, inv_d: Vec3) -> bool {
        let t0 = (self.lo - o) * inv_d;
        let t1 = (self.hi - o) * inv_d;
        let near = t0.min(t1).max_element();
        let far = t0.max(t1).min_element();
        far >= near.max(0.0)
    }
}

enum Node {
    Leaf { bounds: Aabb, first: u32, count: u32 },
    Inner { bounds: Aabb, left: u32, right: u32 },
}

/// A bounding-volume hierarchy over triangles (median split on the longest axis, up to 4
/// triangles per leaf).
pub struct Bvh {
    nodes: Vec<Node>,
    triangles: Vec<[Vec3; 3]>,
}

impl Bvh {
    /// Build over `triangles`.
    pub fn new(triangles: &[[Vec3; 3]]) -> Self {
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let mut nodes = Vec::new();
        if !triangles.is_empty() {
            build(&mut nodes, triangles, &mut order, 0);
        }
        let triangles = order.iter().map(|&i| triangles[i as usize]).collect();
        Self { nodes, triangles }
    }

    /// Whether the ray from `origin` along `dir` hits any triangle at a distance > `t_min`.
    pub fn occluded(&self, origin: Vec3, dir: Vec3, t_min: f32) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let inv = Vec3::ONE / dir;
        let mut stack = vec![0u32];
        while let Some(n) = stack.pop() {
            match &self.nodes[n as usize] {
                Node::Leaf { bounds, first, count } => {
                    if bounds.hit(origin, inv) {
                        let tris = &self.triangles[*first as usize..(*first + *count) as usize];
                        if tris.iter().any(|t| ray_triangle(origin, dir, t).is_some_and(|s| s > t_min)) {
                            return true;
                        }
                    }
                }
                Node::Inner { bounds, left, right } => {
                    if bounds.hit(origin, inv) {
                        stack.push(*left);
                        stack.push(*right);
                    }
                }
            }
        }
        false
    }
}

fn build(nodes: &mut Vec<Node>, tris: &[[Vec3; 3]], order: &mut [u32], first: u32) -> u32 {
    let bounds = order.iter().map(|&i| Aabb::of(&tris[i as usize])).reduce(Aabb::union).expect("non-empty");
    let me = nodes.len() as u32;
    if order.len() <= 4 {
        nodes.push(Node::Leaf { bounds, first, count: order.len() as u32 });
        return me;
    }
    nodes.push(Node::Leaf { bounds, first: 0, count: 0 }); // placeholder
    let axis = (bounds.hi - bounds.lo)
        .to_array()
        .iter()
        .enumerate()
        .fold(0, |a, (k, &v)| if v > (bounds.hi - bounds.lo).to_array()[a] { k } else { a });
    let centre = |i: u32| {
        let t = &tris[i as usize];
        ((t[0] + t[1] + t[2]) / 3.0).to_array()[axis]
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| centre(a).total_cmp(&centre(b)).then(a.cmp(&b)));
    let (l, r) = order.split_at_mut(mid);
    let left = build(nodes, tris, l, first);
    let right = build(nodes, tris, r, first + mid as u32);
    nodes[me as usize] = Node::Inner { bounds, left, right };
    me
}

/// Möller-Trumbore: distance along `dir` to the triangle, if the ray hits it.
fn ray_triangle(o: Vec3, d: Vec3, t: &[Vec3; 3]) -> Option<f32> {
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - t[0];
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some(e2.dot(q) * inv)
}

/// Distance a reference ray starts above the surface, m: past the texel's own triangle
/// (which passes through the start point) by a margin that the maps' f32 heights keep.
pub const RAY_START_M: f32 = 1e-3;

/// The snow probability of every texel of every map by ray casting with the sim's own
/// directions (see the module docs).
pub fn ray_cast_probability(sim: &SnowSim) -> Vec<Vec<f32>> {
    let bvh = Bvh::new(&sim.occluders().triangles);
    let fp = sim.footprint();
    let n = fp.n;
    let dirs = sim.directions();
    sim.maps()
        .iter()
        .map(|map| {
            (0..n * n)
                .into_par_iter()
                .map(|k| {
                    if !map.possible(k) {
                        return 0.0;
                    }
                    let xz = fp.centre(k % n, k / n);
                    let p = Vec3::new(xz.x, map.surface(k), xz.y);
                    let open = dirs.iter().filter(|d| !bvh.occluded(p, -**d, RAY_START_M)).count();
                    open as f32 / dirs.len() as f32
                })
                .collect()
        })
        .collect()
}

/// The paper's comparison method (§3.3, after its ref. 7): for every vertex of every
/// upward-facing triangle, `rays` rays up the jittered snowfall directions, each tested
/// against every triangle; the vertex's probability is the unblocked share. Returns one
/// value per (triangle, corner).
pub fn naive_vertex_probability(mesh: &Mesh, directions: &[Vec3]) -> Vec<f32> {
    let up: Vec<usize> = (0..mesh.len()).filter(|&t| mesh.normal(t).y > 0.0).collect();
    up.par_iter()
        .flat_map_iter(|&t| {
            mesh.triangles[t].map(|v| {
                let open = directions
                    .iter()
                    .filter(|d| {
                        !mesh
                            .triangles
                            .iter()
                            .any(|tri| ray_triangle(v, -**d, tri).is_some_and(|s| s > RAY_START_M))
                    })
                    .count();
                open as f32 / directions.len().max(1) as f32
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{cuboid, sphere};

    #[test]
    fn the_bvh_agrees_with_testing_every_triangle() {
        let mut tris = cuboid(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 1.0, 1.0));
        tris.extend(sphere(Vec3::new(2.0, 2.0, 0.5), 0.8, 24));
        let bvh = Bvh::new(&tris);
        let mut s = 7u64;
        let mut r = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 33) as f32 / (1u64 << 31) as f32) * 2.0 - 1.0
        };
        for _ in 0..2000 {
            let o = Vec3::new(r() * 4.0, r() * 4.0, r() * 4.0);
            let d = Vec3::new(r(), r(), r()).normalize_or(Vec3::Y);
            let brute = tris.iter().any(|t| ray_triangle(o, d, t).is_some_and(|s| s > 1e-3));
            assert_eq!(bvh.occluded(o, d, 1e-3), brute, "ray {o} {d}");
        }
    }
}
