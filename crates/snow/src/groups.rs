//! Polygon groups (§2.1): sets of up-facing triangles that never overlap seen from
//! straight above, so each group has one top-down z-buffer (its snow map).
//!
//! The paper grouped by hand. Here the groups are made automatically by greedy colouring
//! of the overlap graph: triangles taken from the highest down, each given the smallest
//! group that holds no triangle overlapping it (positive-area overlap of the x-z
//! projections; touching edges do not count). A scene may instead give group ids per
//! object, which are used as they are.

use glam::{Vec2, Vec3};

use crate::mesh::Mesh;

/// Least upward component of a unit normal for a triangle to hold snow at all: faces at
/// 89.9° or steeper are left out (their top-down projection has no area).
pub const MIN_UP: f32 = 1e-3;

/// Groups of a mesh: `group[t]` for each triangle (`None` for triangles that face down or
/// sideways), and the number of groups.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Groups {
    /// Group of each triangle.
    pub group: Vec<Option<u32>>,
    /// Number of groups.
    pub count: u32,
}

/// Projection onto the ground plane (x, z).
fn flat(p: Vec3) -> Vec2 {
    Vec2::new(p.x, p.z)
}

/// Whether two 2-D triangles overlap with positive area (separating-axis test with a
/// tolerance of `eps` metres, so shared edges and corners do not count).
pub fn overlap_2d(a: &[Vec2; 3], b: &[Vec2; 3], eps: f32) -> bool {
    for tri in [a, b] {
        for k in 0..3 {
            let e = tri[(k + 1) % 3] - tri[k];
            let axis = Vec2::new(-e.y, e.x);
            let len = axis.length();
            if len == 0.0 {
                continue;
            }
            let axis = axis / len;
            let (a0, a1) = interval(a, axis);
            let (b0, b1) = interval(b, axis);
            if a1 <= b0 + eps || b1 <= a0 + eps {
                return false;
            }
        }
    }
    true
}

fn interval(t: &[Vec2; 3], axis: Vec2) -> (f32, f32) {
    let d = [t[0].dot(axis), t[1].dot(axis), t[2].dot(axis)];
    (d[0].min(d[1]).min(d[2]), d[0].max(d[1]).max(d[2]))
}

/// Group the up-facing triangles of `mesh` automatically (see the module docs).
pub fn auto_groups(mesh: &Mesh) -> Groups {
    let n = mesh.len();
    let up: Vec<usize> = (0..n).filter(|&t| mesh.normal(t).y > MIN_UP).collect();
    let mut group = vec![None; n];
    if up.is_empty() {
        return Groups { group, count: 0 };
    }
    let tri2 = |t: usize| mesh.triangles[t].map(flat);
    // A uniform grid over the x-z bounds for candidate pairs.
    let (lo, hi) = up
        .iter()
        .flat_map(|&t| mesh.triangles[t])
        .fold((Vec2::splat(f32::MAX), Vec2::splat(f32::MIN)), |(lo, hi), p| {
            (lo.min(flat(p)), hi.max(flat(p)))
        });
    let cells = ((up.len() as f32).sqrt().ceil() as usize).clamp(1, 1024);
    let size = ((hi - lo) / cells as f32).max(Vec2::splat(1e-6));
    let cell_range = |t: usize| {
        let tri = tri2(t);
        let (a, b) = tri
            .iter()
            .fold((Vec2::splat(f32::MAX), Vec2::splat(f32::MIN)), |(a, b), &p| (a.min(p), b.max(p)));
        let c0 = ((a - lo) / size).floor().max(Vec2::ZERO);
        let c1 = ((b - lo) / size).floor().min(Vec2::splat(cells as f32 - 1.0));
        (c0.x as usize..=c1.x as usize, c0.y as usize..=c1.y as usize)
    };
    let mut grid: Vec<Vec<usize>> = vec![Vec::new(); cells * cells];
    // Highest first (by the highest vertex), ties by index: deterministic.
    let mut order = up.clone();
    let top = |t: usize| mesh.triangles[t].iter().map(|p| p.y).fold(f32::MIN, f32::max);
    order.sort_by(|&a, &b| top(b).total_cmp(&top(a)).then(a.cmp(&b)));
    let eps = 1e-5 * (hi - lo).max_element().max(1.0);
    let mut count = 0u32;
    let mut used = Vec::new();
    for &t in &order {
        let (xs, zs) = cell_range(t);
        let me = tri2(t);
        used.clear();
        for cz in zs.clone() {
            for cx in xs.clone() {
                for &o in &grid[cz * cells + cx] {
                    if let Some(g) = group[o]
                        && overlap_2d(&me, &tri2(o), eps)
                    {
                        used.push(g);
                    }
                }
            }
        }
        used.sort_unstable();
        used.dedup();
        let g = (0..).find(|g| used.binary_search(g).is_err()).unwrap_or(0);
        group[t] = Some(g);
        count = count.max(g + 1);
        for cz in zs {
            for cx in xs.clone() {
                grid[cz * cells + cx].push(t);
            }
        }
    }
    Groups { group, count }
}

/// Groups given per object: `object_group[o]` for every object `o` of the mesh; only
/// up-facing triangles get one.
pub fn groups_by_object(mesh: &Mesh, object_group: &[u32]) -> Groups {
    let group: Vec<Option<u32>> = (0..mesh.len())
        .map(|t| {
            let o = mesh.object[t] as usize;
            (mesh.normal(t).y > MIN_UP).then(|| object_group.get(o).copied()).flatten()
        })
        .collect();
    let count = group.iter().flatten().max().map_or(0, |g| g + 1);
    Groups { group, count }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::table_scene;

    #[test]
    fn overlap_needs_positive_area() {
        let a = [Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0)];
        let b = [Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)]; // shares an edge
        let c = [Vec2::new(0.2, 0.2), Vec2::new(2.0, 0.2), Vec2::new(0.2, 2.0)];
        let d = [Vec2::new(5.0, 5.0), Vec2::new(6.0, 5.0), Vec2::new(5.0, 6.0)];
        assert!(!overlap_2d(&a, &b, 1e-6));
        assert!(overlap_2d(&a, &c, 1e-6) && overlap_2d(&c, &a, 1e-6));
        assert!(!overlap_2d(&a, &d, 1e-6));
    }

    #[test]
    fn the_table_top_and_the_ground_get_different_groups() {
        let mesh = table_scene(4.0, 1.0, 0.7);
        let g = auto_groups(&mesh);
        // Ground (object 0) and table top overlap from above: two groups at least; the
        // legs' tops are hidden under the table top (they overlap it) and go elsewhere.
        assert!(g.count >= 2);
        let ground: Vec<_> = (0..mesh.len()).filter(|&t| mesh.object[t] == 0).map(|t| g.group[t]).collect();
        let top: Vec<_> = (0..mesh.len())
            .filter(|&t| mesh.object[t] == 1 && mesh.normal(t).y > 0.9)
            .map(|t| g.group[t])
            .collect();
        assert!(ground.iter().all(|x| x.is_some()));
        assert!(ground.iter().all(|x| !top.contains(x)), "ground {ground:?} top {top:?}");
        // Within a group no two triangles overlap.
        for a in 0..mesh.len() {
            for b in a + 1..mesh.len() {
                if g.group[a].is_some() && g.group[a] == g.group[b] {
                    let (ta, tb) = (mesh.triangles[a].map(flat), mesh.triangles[b].map(flat));
                    assert!(!overlap_2d(&ta, &tb, 1e-5), "triangles {a} and {b}");
                }
            }
        }
        // Sides and bottoms get none.
        let down = (0..mesh.len()).filter(|&t| mesh.normal(t).y <= MIN_UP).count();
        assert_eq!(g.group.iter().filter(|x| x.is_none()).count(), down);
    }
}
