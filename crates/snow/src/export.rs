//! The snow as a triangle mesh (§2.5) and its files: glTF 2.0 binary (GLB), OBJ and PLY.
//!
//! Each snow map gives a closed solid per connected patch of snow: a top surface through
//! the texel corners (height = mean of the surrounding snow texels' ground + snow), a
//! bottom on the ground beneath (mean ground), and vertical sides where a snow texel
//! meets one without snow. Every edge is shared by exactly two faces (tested), so the
//! mesh is watertight. Top vertices are shared and carry smooth normals from the surface
//! gradient; bottom and side faces have their own vertices with flat normals.
//!
//! The library builds bytes; writing files is the caller's (the CLI's) job.

use glam::Vec3;
use rayon::prelude::*;

use crate::sim::{Footprint, SnowMap, SnowSim};

/// Snow thinner than this is no snow for the mesh, m.
pub const MIN_DEPTH_M: f32 = 1e-4;

/// An indexed triangle mesh with per-vertex normals.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions, m.
    pub positions: Vec<Vec3>,
    /// Unit normal per vertex.
    pub normals: Vec<Vec3>,
    /// Three vertex indices per triangle, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

impl TriMesh {
    /// Number of triangles.
    pub fn triangles(&self) -> usize {
        self.indices.len() / 3
    }

    fn vertex(&mut self, p: Vec3, n: Vec3) -> u32 {
        self.positions.push(p);
        self.normals.push(n);
        (self.positions.len() - 1) as u32
    }

    fn quad(&mut self, v: [u32; 4]) {
        self.indices.extend_from_slice(&[v[0], v[1], v[2], v[0], v[2], v[3]]);
    }
}

/// The snow of every map of `sim` as one mesh: the maps' meshes, made in parallel, end
/// to end in map order (the same mesh for any thread count). Each snowy texel is a
/// closed solid: its top, its bottom on the ground and its open sides.
pub fn snow_mesh(sim: &SnowSim) -> TriMesh {
    meshes_joined(sim, Faces::Closed)
}

/// [`snow_mesh`] without the bottoms that lie on the surface holding the snow: those of
/// texels inside a patch (snow on all eight texels around) whose ground is a plane
/// (`Lattice::hides_bottom`). What the renderer draws. Such a bottom faces into that
/// surface, so it can show only from behind the surface (an open sheet seen from below),
/// at the surface's own depth: there it tied with the surface and won some pixels by
/// rounding, a speckle of the snow's underside on the sheet's; without it the sheet
/// shows. At a patch's edge the bottom may overhang the surface's edge (a roof's eave),
/// and under a crease or a step it leaves the surface: those stay. The other faces,
/// vertices and normals come in the same order as in [`snow_mesh`].
pub fn snow_surface(sim: &SnowSim) -> TriMesh {
    meshes_joined(sim, Faces::Open)
}

/// Which texels' solids keep their bottoms.
#[derive(Clone, Copy, PartialEq)]
enum Faces {
    /// Every texel's.
    Closed,
    /// Only those that do not lie on the surface holding the snow.
    Open,
}

/// The maps' meshes, made in parallel, end to end in map order.
fn meshes_joined(sim: &SnowSim, faces: Faces) -> TriMesh {
    let fp = sim.footprint();
    let parts: Vec<TriMesh> = sim.maps().par_iter().map(|map| map_mesh(map, &fp, faces)).collect();
    let mut mesh = TriMesh::default();
    let vertices: usize = parts.iter().map(|p| p.positions.len()).sum();
    mesh.positions.reserve_exact(vertices);
    mesh.normals.reserve_exact(vertices);
    mesh.indices.reserve_exact(parts.iter().map(|p| p.indices.len()).sum());
    for part in parts {
        let offset = mesh.positions.len() as u32;
        mesh.positions.extend(part.positions);
        mesh.normals.extend(part.normals);
        mesh.indices.extend(part.indices.iter().map(|&k| k + offset));
    }
    mesh
}

/// The snow of one map as a mesh.
fn map_mesh(map: &SnowMap, fp: &Footprint, faces: Faces) -> TriMesh {
    let mut mesh = TriMesh::default();
    let lattice = Lattice::new(map, fp);
    let top_index = lattice.top_vertices(&mut mesh);
    // The snowy texels' rows and columns: those of the box of corners but its last.
    let (cols, rows) = &lattice.box_corners;
    for j in rows.start..rows.end.saturating_sub(1) {
        for i in cols.start..cols.end.saturating_sub(1) {
            if lattice.snowy(i as i64, j as i64) {
                lattice.texel_solid(&mut mesh, &top_index, (i, j), faces);
            }
        }
    }
    mesh
}

/// The box of the snowy texels of an `n × n` map as the ranges of lattice columns and
/// rows of its corners (one more than its texels each way); empty ranges without snow.
fn snowy_box(snowy: &[bool], n: usize) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
    let (mut i0, mut i1, mut j0, mut j1) = (n, 0, n, 0);
    for (j, row) in snowy.chunks_exact(n.max(1)).enumerate() {
        if let (Some(a), Some(b)) = (row.iter().position(|&s| s), row.iter().rposition(|&s| s)) {
            (i0, i1, j0, j1) = (i0.min(a), i1.max(b + 1), j0.min(j), j + 1);
        }
    }
    if i0 >= i1 { (0..0, 0..0) } else { (i0..i1 + 1, j0..j1 + 1) }
}

/// Ground steps up to this many texel widths between a snowy texel and a bare one are one
/// continuous surface (slopes up to 72°, the built-in cone's 63° with a margin), where
/// the snow thins out instead of ending in a wall; larger steps, and texels that cannot
/// hold snow (past a table's rim), are edges, where it keeps its side.
const CONTINUOUS_TEXELS: f32 = 3.0;

/// How far the 3 × 3 grounds around a texel may stray from a plane (each second
/// difference), m, for its bottom to count as lying on the ground: 0.1 mm, a hundred
/// times the rounding of a ground height a few metres up (about 10⁻⁶ m).
const PLANAR_M: f32 = 1e-4;

/// Smoothing passes along a patch's edge.
const EDGE_SMOOTHING: usize = 3;

/// A lattice corner with snow on at least one of its four texels.
#[derive(Clone, Copy, Debug)]
struct Corner {
    /// The snow's top there, m.
    top: Vec3,
    /// The ground beneath it, m.
    ground: f32,
    /// On the edge of a patch over a continuous surface: the snow thins to nothing here
    /// (top = ground).
    feathered: bool,
    /// Among four snowy texels (inside a patch: no edge runs through it).
    inside: bool,
}

/// One snow map's texels and the (n+1)² lattice of their corners, through which the
/// mesh's top and bottom pass.
///
/// A patch's edge would otherwise be a staircase in plan, and over a continuous surface
/// (snow that slid off a steep cone) a staircase of texel-high walls. So the corners on
/// an edge move off the lattice to smooth it (a few Laplacian passes along the edge, each
/// corner kept within half a texel of its lattice point), and over a continuous surface
/// the snow thins to nothing there (top = the ground's bilinear interpolation at the
/// moved corner): the edge follows the surface's contour, or the rim's, without steps.
struct Lattice<'a> {
    map: &'a SnowMap,
    fp: &'a Footprint,
    corners: Vec<Option<Corner>>,
    /// Per texel: whether it can hold snow and holds more than [`MIN_DEPTH_M`].
    snowy: Vec<bool>,
    /// The corners that may have snow (those of the box of snowy texels), as ranges of
    /// lattice columns and rows: every corner outside is `None`.
    box_corners: (std::ops::Range<usize>, std::ops::Range<usize>),
}

impl<'a> Lattice<'a> {
    fn new(map: &'a SnowMap, fp: &'a Footprint) -> Self {
        let n = fp.n;
        let snowy: Vec<bool> = (0..n * n).map(|k| map.possible(k) && map.snow_m[k] > MIN_DEPTH_M).collect();
        let box_corners = snowy_box(&snowy, n);
        let mut lattice = Self { map, fp, corners: vec![None; (n + 1) * (n + 1)], snowy, box_corners };
        // Only the box's corners can have snow.
        for c in lattice.box_corners() {
            lattice.corners[c] = lattice.raw_corner(c % (n + 1), c / (n + 1));
        }
        lattice.smooth_edges();
        lattice
    }

    /// The corners of the box of snowy texels, in corner order (row by row).
    fn box_corners(&self) -> impl Iterator<Item = usize> + use<> {
        let n1 = self.fp.n + 1;
        let (cols, rows) = self.box_corners.clone();
        rows.flat_map(move |cj| cols.clone().map(move |ci| cj * n1 + ci))
    }

    /// Whether texel (i, j) lies in the map, can hold snow and holds more than
    /// [`MIN_DEPTH_M`].
    fn snowy(&self, i: i64, j: i64) -> bool {
        let n = self.fp.n;
        i >= 0 && j >= 0 && (i as usize) < n && (j as usize) < n && self.snowy[j as usize * n + i as usize]
    }

    /// The ground of texel (i, j), if it lies in the map and can hold snow.
    fn ground(&self, i: i64, j: i64) -> Option<f32> {
        let n = self.fp.n;
        (i >= 0 && j >= 0 && (i as usize) < n && (j as usize) < n)
            .then(|| j as usize * n + i as usize)
            .filter(|&k| self.map.possible(k))
            .map(|k| self.map.ground_m[k])
    }

    /// The four texels around corner (ci, cj).
    fn around(ci: usize, cj: usize) -> [(i64, i64); 4] {
        [(-1i64, -1i64), (0, -1), (-1, 0), (0, 0)].map(|(di, dj)| (ci as i64 + di, cj as i64 + dj))
    }

    /// Corner (ci, cj) on the lattice: the mean top and ground of its snowy texels; where
    /// the others are bare ground continuous with them, feathered at the ground's mean.
    fn raw_corner(&self, ci: usize, cj: usize) -> Option<Corner> {
        let (mut top, mut ground, mut c) = (0.0f32, 0.0f32, 0);
        for (i, j) in Self::around(ci, cj) {
            if self.snowy(i, j) {
                let k = j as usize * self.fp.n + i as usize;
                top += self.map.surface(k);
                ground += self.map.ground_m[k];
                c += 1;
            }
        }
        if c == 0 {
            return None;
        }
        let (top, ground) = (top / c as f32, ground / c as f32);
        let xz = self.xz(ci, cj);
        if c == 4 {
            // Inside a patch: never feathered, whatever the grounds around.
            return Some(Corner { top: Vec3::new(xz.x, top, xz.y), ground, feathered: false, inside: true });
        }
        let step = CONTINUOUS_TEXELS * self.fp.texel_m;
        let grounds = Self::around(ci, cj).map(|(i, j)| self.ground(i, j));
        let continuous = grounds.iter().all(|g| g.is_some_and(|g| (g - ground).abs() <= step));
        // Fewer than four snowy texels here (four returned above).
        let feathered = continuous;
        let ground =
            if feathered { grounds.iter().map(|g| g.unwrap_or(ground)).sum::<f32>() / 4.0 } else { ground };
        let top = if feathered { ground } else { top };
        Some(Corner { top: Vec3::new(xz.x, top, xz.y), ground, feathered, inside: false })
    }

    /// Position (x, z) of corner (ci, cj) on the lattice, m.
    fn xz(&self, ci: usize, cj: usize) -> glam::Vec2 {
        self.fp.origin + glam::Vec2::new(ci as f32, cj as f32) * self.fp.texel_m
    }

    fn corner(&self, ci: usize, cj: usize) -> Option<Corner> {
        self.corners[cj * (self.fp.n + 1) + ci]
    }

    /// The neighbours of corner (ci, cj) along the patch's edge: the lattice edges from
    /// it that separate a snowy texel from one without snow.
    fn edge_neighbours(&self, ci: usize, cj: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        let (i, j) = (ci as i64, cj as i64);
        // Each lattice edge from the corner and the two texels on either side of it.
        let edges = [((1, 0), (i, j - 1), (i, j)), ((-1, 0), (i - 1, j - 1), (i - 1, j))]
            .into_iter()
            .chain([((0, 1), (i - 1, j), (i, j)), ((0, -1), (i - 1, j - 1), (i, j - 1))]);
        let n = self.fp.n as i64;
        edges
            .filter(move |&((di, dj), a, b)| {
                let (ni, nj) = (i + di, j + dj);
                (0..=n).contains(&ni) && (0..=n).contains(&nj) && self.snowy(a.0, a.1) != self.snowy(b.0, b.1)
            })
            .map(move |((di, dj), _, _)| ((i + di) as usize, (j + dj) as usize))
    }

    /// Laplacian passes over the corners that lie on one edge (two edge neighbours),
    /// each within half a texel of its lattice point; a feathered one at the ground's
    /// bilinear height there, the others at their heights.
    fn smooth_edges(&mut self) {
        let n1 = self.fp.n + 1;
        let chain: Vec<(usize, [(usize, usize); 2])> = self
            .box_corners()
            // A corner among four snowy texels has no edge, one among none no snow.
            .filter(|&c| self.corners[c].is_some_and(|k| !k.inside))
            .filter_map(|c| {
                // Exactly two neighbours (of at most four), both with snow.
                let mut e = self.edge_neighbours(c % n1, c / n1);
                let (a, b) = (e.next()?, e.next()?);
                (e.next().is_none() && [a, b].iter().all(|&(x, z)| self.corner(x, z).is_some()))
                    .then_some((c, [a, b]))
            })
            .collect();
        let half = 0.5 * self.fp.texel_m;
        for _ in 0..EDGE_SMOOTHING {
            // (x, top, z) and ground of each corner after the pass.
            let moved: Vec<(Vec3, f32)> = chain
                .iter()
                .map(|&(c, [a, b])| {
                    let at = |(ci, cj): (usize, usize)| {
                        self.corner(ci, cj).map_or((Vec3::ZERO, 0.0), |k| (k.top, k.ground))
                    };
                    let (here, ground) = at((c % n1, c / n1));
                    let ((pa, ga), (pb, gb)) = (at(a), at(b));
                    let top = here + 0.5 * (0.5 * (pa + pb) - here);
                    let lattice = self.xz(c % n1, c / n1);
                    let xz = lattice
                        + (glam::Vec2::new(top.x, top.z) - lattice)
                            .clamp(glam::Vec2::splat(-half), glam::Vec2::splat(half));
                    (Vec3::new(xz.x, top.y, xz.y), ground + 0.5 * (0.5 * (ga + gb) - ground))
                })
                .collect();
            for (&(c, _), (top, ground)) in chain.iter().zip(moved) {
                let xz = glam::Vec2::new(top.x, top.z);
                let g = self.bilinear_ground(c % n1, c / n1, xz);
                if let Some(k) = self.corners[c].as_mut() {
                    // A feathered corner stays on the ground; another keeps its snow on top
                    // of its ground, both smoothed along the edge (no saw-tooth rim).
                    (k.top, k.ground) = if k.feathered {
                        (Vec3::new(xz.x, g, xz.y), g)
                    } else {
                        (Vec3::new(xz.x, top.y.max(ground), xz.y), ground)
                    };
                }
            }
        }
    }

    /// The ground at `xz` near corner (ci, cj), bilinear over the centres of its four
    /// texels (all possible for a feathered corner).
    fn bilinear_ground(&self, ci: usize, cj: usize, xz: glam::Vec2) -> f32 {
        let g = Self::around(ci, cj).map(|(i, j)| self.ground(i, j).unwrap_or(0.0));
        let f = ((xz - self.xz(ci, cj)) / self.fp.texel_m + 0.5).clamp(glam::Vec2::ZERO, glam::Vec2::ONE);
        let low = g[0] * (1.0 - f.x) + g[1] * f.x;
        let high = g[2] * (1.0 - f.x) + g[3] * f.x;
        low * (1.0 - f.y) + high * f.y
    }

    /// The shared top vertices, one per corner with snow, with normals from central
    /// differences of the corner heights; returns each corner's vertex (`u32::MAX`
    /// where there is none).
    fn top_vertices(&self, mesh: &mut TriMesh) -> Vec<u32> {
        let (n, t) = (self.fp.n, self.fp.texel_m);
        let mut top_index = vec![u32::MAX; (n + 1) * (n + 1)];
        let height = |ci: usize, cj: usize| self.corner(ci, cj).map(|c| c.top.y);
        for c in self.box_corners() {
            let Some(corner) = self.corners[c] else { continue };
            let (ci, cj) = (c % (n + 1), c / (n + 1));
            let h = corner.top.y;
            let hx0 = if ci > 0 { height(ci - 1, cj) } else { None }.unwrap_or(h);
            let hx1 = if ci < n { height(ci + 1, cj) } else { None }.unwrap_or(h);
            let hz0 = if cj > 0 { height(ci, cj - 1) } else { None }.unwrap_or(h);
            let hz1 = if cj < n { height(ci, cj + 1) } else { None }.unwrap_or(h);
            let normal = Vec3::new(-(hx1 - hx0) / (2.0 * t), 1.0, -(hz1 - hz0) / (2.0 * t)).normalize();
            top_index[c] = mesh.vertex(corner.top, normal);
        }
        top_index
    }

    /// Whether snowy texel (i, j)'s bottom lies on the surface that holds its snow: snow
    /// on all eight texels around (at a patch's edge the bottom may reach past that
    /// surface's edge, an overhang whose underside shows) and their ground a plane, each
    /// second difference of the 3 × 3 grounds within [`PLANAR_M`] (under a crease or a
    /// step the corners' mean ground leaves the surface, and an open sheet seen from
    /// below would show the bottom).
    fn hides_bottom(&self, i: usize, j: usize) -> bool {
        let (i, j) = (i as i64, j as i64);
        let mut g = [[0.0f32; 3]; 3];
        for dj in -1..=1 {
            for di in -1..=1 {
                if !self.snowy(i + di, j + dj) {
                    return false;
                }
                // Snowy, so in the map and with ground.
                g[(dj + 1) as usize][(di + 1) as usize] = self.ground(i + di, j + dj).unwrap_or(f32::NAN);
            }
        }
        let flat = |d: f32| d.abs() <= PLANAR_M;
        (0..3).all(|r| flat(g[r][0] - 2.0 * g[r][1] + g[r][2]) && flat(g[0][r] - 2.0 * g[1][r] + g[2][r]))
            && flat(g[2][2] - g[2][0] - g[0][2] + g[0][0])
    }

    /// The faces of snowy texel (i, j): its top quad on the shared vertices `top_index`,
    /// its bottom on the ground (with [`Faces::Open`], only where [`Lattice::hides_bottom`]
    /// does not hold), and a side towards each neighbour without snow (none where both of
    /// the side's corners are feathered, a triangle where one is).
    fn texel_solid(&self, mesh: &mut TriMesh, top_index: &[u32], (i, j): (usize, usize), faces: Faces) {
        let n = self.fp.n;
        let corners = [(i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j)];
        // Top: counter-clockwise seen from above (+y) in x-z is (x,z) → (x,z+1) →
        // (x+1,z+1) → (x+1,z), as for the ground quads.
        mesh.quad(corners.map(|(ci, cj)| top_index[cj * (n + 1) + ci]));
        let at = |ci: usize, cj: usize| self.corner(ci, cj).expect("a snowy texel's corners have snow");
        let bottom_of = |c: Corner| Vec3::new(c.top.x, c.ground, c.top.z);
        if faces == Faces::Closed || !self.hides_bottom(i, j) {
            let b = corners.map(|(ci, cj)| mesh.vertex(bottom_of(at(ci, cj)), Vec3::NEG_Y));
            mesh.quad([b[0], b[3], b[2], b[1]]);
        }
        // Sides where the neighbour has no snow: (corner a, corner b, outward).
        let sides = [
            ((i, j), (i + 1, j), (0i64, -1i64), Vec3::NEG_Z),
            ((i + 1, j), (i + 1, j + 1), (1, 0), Vec3::X),
            ((i + 1, j + 1), (i, j + 1), (0, 1), Vec3::Z),
            ((i, j + 1), (i, j), (-1, 0), Vec3::NEG_X),
        ];
        for (a, bb, (di, dj), outward) in sides {
            if self.snowy(i as i64 + di, j as i64 + dj) {
                continue;
            }
            let (ca, cb) = (at(a.0, a.1), at(bb.0, bb.1));
            // Outward and horizontal, square to the side as its smoothed corners run.
            let run = cb.top - ca.top;
            let normal = Vec3::new(-run.z, 0.0, run.x).normalize_or(outward);
            let normal = if normal.dot(outward) < 0.0 { -normal } else { normal };
            // Bottom a, top a, top b, bottom b: counter-clockwise seen from outside; a
            // feathered corner's top is its bottom.
            let (mut v, mut len) = ([0u32; 4], 0);
            let mut push = |k: u32| {
                v[len] = k;
                len += 1;
            };
            push(mesh.vertex(bottom_of(ca), normal));
            if !ca.feathered {
                push(mesh.vertex(ca.top, normal));
            }
            if !cb.feathered {
                push(mesh.vertex(cb.top, normal));
            }
            push(mesh.vertex(bottom_of(cb), normal));
            match len {
                4 => mesh.quad(v),
                3 => mesh.indices.extend_from_slice(&v[..3]),
                _ => {
                    // Both ends feathered: no side; take back the two unused vertices.
                    mesh.positions.truncate(mesh.positions.len() - 2);
                    mesh.normals.truncate(mesh.normals.len() - 2);
                }
            }
        }
    }
}

/// Wavefront OBJ text (`v`, `vn`, `f v//vn`).
pub fn to_obj(mesh: &TriMesh) -> String {
    let mut out = String::from("# snow from phenomena (metres, y up)\no snow\n");
    for p in &mesh.positions {
        out.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
    }
    for n in &mesh.normals {
        out.push_str(&format!("vn {} {} {}\n", n.x, n.y, n.z));
    }
    for t in mesh.indices.chunks_exact(3) {
        let (a, b, c) = (t[0] + 1, t[1] + 1, t[2] + 1);
        out.push_str(&format!("f {a}//{a} {b}//{b} {c}//{c}\n"));
    }
    out
}

/// Binary little-endian PLY with positions, normals and triangle faces.
pub fn to_ply(mesh: &TriMesh) -> Vec<u8> {
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment snow from phenomena (metres, y up)\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles()
    );
    let mut out = header.into_bytes();
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        for v in [p.x, p.y, p.z, n.x, n.y, n.z] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for t in mesh.indices.chunks_exact(3) {
        out.push(3);
        for &i in t {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    out
}

/// glTF 2.0 binary (GLB): one mesh with POSITION, NORMAL and u32 indices, a white
/// rough material, in one buffer.
pub fn to_glb(mesh: &TriMesh) -> Vec<u8> {
    if mesh.indices.is_empty() {
        // No snow yet: a scene with nothing in it (glTF forbids empty buffers and
        // accessors with count 0, and a scene's node list may not be empty).
        return glb_chunks(
            br#"{"asset":{"version":"2.0","generator":"phenomena"},"scene":0,"scenes":[{}]}"#.to_vec(),
            &[],
        );
    }
    let mut bin = Vec::new();
    for p in &mesh.positions {
        for v in p.to_array() {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    let normals_offset = bin.len();
    for n in &mesh.normals {
        for v in n.to_array() {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    let indices_offset = bin.len();
    for i in &mesh.indices {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let (lo, hi) = mesh
        .positions
        .iter()
        .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let (lo, hi) = if mesh.positions.is_empty() { (Vec3::ZERO, Vec3::ZERO) } else { (lo, hi) };
    let nv = mesh.positions.len();
    let json = format!(
        concat!(
            r#"{{"asset":{{"version":"2.0","generator":"phenomena"}},"scene":0,"scenes":[{{"nodes":[0]}}],"#,
            r#""nodes":[{{"mesh":0,"name":"snow"}}],"#,
            r#""materials":[{{"name":"snow","pbrMetallicRoughness":{{"baseColorFactor":[0.95,0.96,1.0,1.0],"metallicFactor":0.0,"roughnessFactor":0.9}}}}],"#,
            r#""meshes":[{{"name":"snow","primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1}},"indices":2,"material":0}}]}}],"#,
            r#""buffers":[{{"byteLength":{len}}}],"#,
            r#""bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{pl},"target":34962}},{{"buffer":0,"byteOffset":{no},"byteLength":{pl},"target":34962}},{{"buffer":0,"byteOffset":{io},"byteLength":{il},"target":34963}}],"#,
            r#""accessors":[{{"bufferView":0,"componentType":5126,"count":{nv},"type":"VEC3","min":[{x0},{y0},{z0}],"max":[{x1},{y1},{z1}]}},"#,
            r#"{{"bufferView":1,"componentType":5126,"count":{nv},"type":"VEC3"}},"#,
            r#"{{"bufferView":2,"componentType":5125,"count":{ni},"type":"SCALAR"}}]}}"#
        ),
        len = bin.len(),
        pl = nv * 12,
        no = normals_offset,
        io = indices_offset,
        il = mesh.indices.len() * 4,
        nv = nv,
        ni = mesh.indices.len(),
        x0 = lo.x,
        y0 = lo.y,
        z0 = lo.z,
        x1 = hi.x,
        y1 = hi.y,
        z1 = hi.z,
    );
    glb_chunks(json.into_bytes(), &bin)
}

/// One mesh of a scene GLB with its material.
#[derive(Clone, Copy, Debug)]
pub struct GlbPart<'a> {
    /// The mesh's (and its node's) name.
    pub name: &'a str,
    /// The triangles.
    pub mesh: &'a TriMesh,
    /// Base colour (linear RGB), a rough dielectric.
    pub colour: Vec3,
}

/// The camera and the sun of a scene GLB.
#[derive(Clone, Debug)]
pub struct GlbView {
    /// The camera (perspective or orthographic; another projection is left out).
    pub camera: phenomena_core::camera::Camera,
    /// Image width over height.
    pub aspect: f32,
    /// Direction towards the sun (a directional light of `KHR_lights_punctual`).
    pub sun: Vec3,
    /// The sun's colour and intensity (as the renderer uses them).
    pub sun_rgb: Vec3,
    /// The sun's strength.
    pub sun_intensity: f32,
    /// A JSON object put in the scene's `extras` (the renderer's light settings).
    pub extras: String,
}

/// A GLB of several meshes, the camera and the sun, for another renderer (the Cycles
/// reference) or a DCC: meshes with per-vertex normals and a rough material each, a
/// `camera` node looking down its −Z as the camera does, and a `sun` node whose
/// directional light shines down its −Z, away from the sun.
pub fn to_glb_scene(parts: &[GlbPart<'_>], view: &GlbView) -> Vec<u8> {
    let mut bin = Vec::new();
    let (mut views, mut accessors, mut materials, mut meshes, mut nodes) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for part in parts.iter().filter(|p| !p.mesh.indices.is_empty()) {
        let m = part.mesh;
        let first = push_arrays(m, &mut bin, &mut views, &mut accessors);
        let c = part.colour;
        materials.push(format!(
            r#"{{"name":"{}","pbrMetallicRoughness":{{"baseColorFactor":[{},{},{},1.0],"metallicFactor":0.0,"roughnessFactor":1.0}}}}"#,
            part.name, c.x, c.y, c.z
        ));
        meshes.push(format!(
            r#"{{"name":"{}","primitives":[{{"attributes":{{"POSITION":{first},"NORMAL":{}}},"indices":{},"material":{}}}]}}"#,
            part.name,
            first + 1,
            first + 2,
            materials.len() - 1
        ));
        nodes.push(format!(r#"{{"mesh":{},"name":"{}"}}"#, meshes.len() - 1, part.name));
    }
    let (cameras, lights) = view_nodes(view, &mut nodes);
    let roots: Vec<String> = (0..nodes.len()).map(|k| k.to_string()).collect();
    let buffers = if bin.is_empty() {
        String::new()
    } else {
        format!(
            r#""buffers":[{{"byteLength":{}}}],"bufferViews":[{}],"accessors":[{}],"#,
            bin.len(),
            views.join(","),
            accessors.join(",")
        )
    };
    // glTF forbids empty arrays: no materials or meshes when every part is empty.
    let meshes = if meshes.is_empty() {
        String::new()
    } else {
        format!(r#""materials":[{}],"meshes":[{}],"#, materials.join(","), meshes.join(","))
    };
    let json = format!(
        r#"{{"asset":{{"version":"2.0","generator":"phenomena"}},{lights}{}{buffers}{meshes}"nodes":[{}],"scene":0,"scenes":[{{"nodes":[{}],"extras":{}}}]}}"#,
        cameras,
        nodes.join(","),
        roots.join(","),
        view.extras
    );
    glb_chunks(json.into_bytes(), &bin)
}

/// Appends a mesh's positions, normals and indices to `bin` with a buffer view and an
/// accessor each; returns the positions' accessor (normals and indices follow it).
fn push_arrays(
    m: &TriMesh,
    bin: &mut Vec<u8>,
    views: &mut Vec<String>,
    accessors: &mut Vec<String>,
) -> usize {
    let (lo, hi) = m
        .positions
        .iter()
        .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let first = accessors.len();
    for (data, target, accessor) in [
        (
            m.positions.iter().flat_map(|p| p.to_array()).flat_map(f32::to_le_bytes).collect::<Vec<u8>>(),
            34962,
            format!(
                r#""componentType":5126,"count":{},"type":"VEC3","min":[{},{},{}],"max":[{},{},{}]"#,
                m.positions.len(),
                lo.x,
                lo.y,
                lo.z,
                hi.x,
                hi.y,
                hi.z
            ),
        ),
        (
            m.normals.iter().flat_map(|p| p.to_array()).flat_map(f32::to_le_bytes).collect(),
            34962,
            format!(r#""componentType":5126,"count":{},"type":"VEC3""#, m.normals.len()),
        ),
        (
            m.indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
            34963,
            format!(r#""componentType":5125,"count":{},"type":"SCALAR""#, m.indices.len()),
        ),
    ] {
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{},"byteLength":{},"target":{target}}}"#,
            bin.len(),
            data.len()
        ));
        accessors.push(format!(r#"{{"bufferView":{},{accessor}}}"#, views.len() - 1));
        bin.extend_from_slice(&data);
    }
    first
}

/// The camera node (when the projection has a glTF form) and the sun's node, onto
/// `nodes`; returns the JSON members `"cameras"` and the light extension.
fn view_nodes(view: &GlbView, nodes: &mut Vec<String>) -> (String, String) {
    let quat = |q: glam::Quat| format!("[{},{},{},{}]", q.x, q.y, q.z, q.w);
    let cam = &view.camera;
    let forward = (cam.look_at - cam.position).normalize_or(Vec3::NEG_Z);
    let right = forward.cross(cam.up).normalize_or(Vec3::X);
    let up = right.cross(forward);
    let rotation = glam::Quat::from_mat3(&glam::Mat3::from_cols(right, up, -forward)).normalize();
    let projection = match cam.projection {
        phenomena_core::camera::Projection::Perspective { fov_y_deg } => Some(format!(
            r#"{{"type":"perspective","perspective":{{"yfov":{},"aspectRatio":{},"znear":0.05}}}}"#,
            fov_y_deg.to_radians(),
            view.aspect
        )),
        phenomena_core::camera::Projection::Orthographic { height_m } => Some(format!(
            r#"{{"type":"orthographic","orthographic":{{"xmag":{},"ymag":{},"znear":0.0,"zfar":10000.0}}}}"#,
            0.5 * height_m * view.aspect,
            0.5 * height_m
        )),
        _ => None,
    };
    let cameras = projection.map_or_else(String::new, |p| {
        let p0 = cam.position;
        nodes.push(format!(
            r#"{{"camera":0,"name":"camera","translation":[{},{},{}],"rotation":{}}}"#,
            p0.x,
            p0.y,
            p0.z,
            quat(rotation)
        ));
        format!(r#""cameras":[{p}],"#)
    });
    let sun = glam::Quat::from_rotation_arc(Vec3::Z, view.sun.normalize_or(Vec3::Y));
    nodes.push(format!(
        r#"{{"name":"sun","rotation":{},"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}}"#,
        quat(sun)
    ));
    // glTF's light colour lies in [0, 1]: the brightest channel's excess moves to the
    // intensity.
    let peak = view.sun_rgb.max_element().max(1e-6);
    let s = view.sun_rgb / peak;
    let lights = format!(
        r#""extensionsUsed":["KHR_lights_punctual"],"extensions":{{"KHR_lights_punctual":{{"lights":[{{"type":"directional","name":"sun","color":[{},{},{}],"intensity":{}}}]}}}},"#,
        s.x,
        s.y,
        s.z,
        view.sun_intensity * peak
    );
    (cameras, lights)
}

/// The triangles of `mesh` whose object `keep` accepts, flat-shaded (each its own three
/// vertices with the face normal).
pub fn flat_mesh(mesh: &crate::mesh::Mesh, keep: impl Fn(u32) -> bool) -> TriMesh {
    let mut out = TriMesh::default();
    for (t, tri) in mesh.triangles.iter().enumerate().filter(|(t, _)| keep(mesh.object[*t])) {
        let n = mesh.normal(t);
        if n == Vec3::ZERO {
            continue;
        }
        let v = tri.map(|p| out.vertex(p, n));
        out.indices.extend_from_slice(&v);
    }
    out
}

/// A GLB file: header, the JSON chunk padded with spaces, and the BIN chunk when `bin`
/// is not empty (already 4-byte aligned).
fn glb_chunks(mut json: Vec<u8>, bin: &[u8]) -> Vec<u8> {
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let bin_chunk = if bin.is_empty() { 0 } else { 8 + bin.len() };
    let total = 12 + 8 + json.len() + bin_chunk;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::table_scene;

    #[test]
    fn no_snow_is_an_empty_scene_without_a_bin_chunk() {
        let glb = to_glb(&TriMesh::default());
        assert_eq!(&glb[..4], b"glTF");
        assert_eq!(u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize, glb.len());
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        assert_eq!(20 + json_len, glb.len(), "only the JSON chunk");
        let json = std::str::from_utf8(&glb[20..]).unwrap();
        assert!(json.contains(r#""scenes":[{}]"#) && !json.contains("accessors"), "{json}");
    }
    use crate::sim::SnowConfig;
    use std::collections::HashMap;

    fn snowy_sim() -> SnowSim {
        let params = SnowConfig {
            map_resolution: 40,
            directions: 8,
            shadow_resolution: 128,
            rate_cm_per_h: 10.0,
            ..SnowConfig::default()
        };
        let mut sim = SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 2).unwrap();
        for _ in 0..10 {
            sim.step().unwrap();
        }
        sim
    }

    #[test]
    fn a_corner_inside_a_patch_is_its_four_texels_mean() {
        // Where all four texels around a corner hold snow, the corner lies at their mean
        // top and ground (summed in the texels' order), is not feathered, has no edge
        // and is left where it is by the edges' smoothing; every other corner with snow
        // is not `inside`.
        let sim = snowy_sim();
        let fp = sim.footprint();
        let (mut inside, mut edges) = (0, 0);
        for map in sim.maps() {
            let lattice = Lattice::new(map, &fp);
            for c in 0..(fp.n + 1) * (fp.n + 1) {
                let (ci, cj) = (c % (fp.n + 1), c / (fp.n + 1));
                let around = Lattice::around(ci, cj);
                if !around.iter().all(|&(i, j)| lattice.snowy(i, j)) {
                    assert!(lattice.corner(ci, cj).is_none_or(|k| !k.inside));
                    edges += usize::from(lattice.edge_neighbours(ci, cj).next().is_some());
                    continue;
                }
                // So the edges' smoothing may skip it: no lattice edge from it parts snow
                // from bare ground.
                let flagged = lattice.corner(ci, cj).is_some_and(|k| k.inside);
                assert!(flagged && lattice.edge_neighbours(ci, cj).next().is_none());
                let texels = around.map(|(i, j)| j as usize * fp.n + i as usize);
                let mean = |f: &dyn Fn(usize) -> f32| texels.iter().fold(0.0f32, |s, &k| s + f(k)) / 4.0;
                let (top, ground) = (mean(&|k| map.surface(k)), mean(&|k| map.ground_m[k]));
                let xz = lattice.xz(ci, cj);
                let corner = lattice.corner(ci, cj).expect("snow around");
                assert_eq!(
                    (corner.top, corner.ground, corner.feathered),
                    (Vec3::new(xz.x, top, xz.y), ground, false)
                );
                inside += 1;
            }
        }
        assert!(inside >= 100 && edges >= 20, "{inside} corners inside patches, {edges} on edges");
    }

    #[test]
    fn the_maps_meshed_in_parallel_are_the_maps_meshed_one_after_another() {
        // The reference: every map's top vertices and texel solids added to one mesh,
        // map after map, as `snow_mesh` did before it meshed the maps in parallel. The
        // same mesh on one thread and on three, with at least two maps holding snow (so
        // a map's indices must be shifted past the maps' before it, and one whose snow
        // lies inside a smaller box than the map).
        let sim = snowy_sim();
        let fp = sim.footprint();
        let mut reference = TriMesh::default();
        let (mut meshed, mut boxed) = (0, 0);
        for map in sim.maps() {
            let before = reference.positions.len();
            let lattice = Lattice::new(map, &fp);
            // Only the corners of the snowy texels' box are worked out: every corner
            // with snow lies in it.
            for c in 0..(fp.n + 1) * (fp.n + 1) {
                let (ci, cj) = (c % (fp.n + 1), c / (fp.n + 1));
                assert_eq!(
                    lattice.corner(ci, cj).is_some(),
                    lattice.raw_corner(ci, cj).is_some(),
                    "corner {c}"
                );
            }
            boxed += usize::from(lattice.box_corners.0.len() < fp.n || lattice.box_corners.1.len() < fp.n);
            let top_index = lattice.top_vertices(&mut reference);
            for j in 0..fp.n {
                for i in 0..fp.n {
                    if lattice.snowy(i as i64, j as i64) {
                        lattice.texel_solid(&mut reference, &top_index, (i, j), Faces::Closed);
                    }
                }
            }
            meshed += usize::from(reference.positions.len() > before);
        }
        assert!(meshed >= 2, "{meshed} maps with snow");
        // Every index names a vertex (a top vertex the box left out would be u32::MAX).
        assert!(reference.indices.iter().all(|&k| (k as usize) < reference.positions.len()));
        assert!(boxed >= 1, "no map's snow inside a smaller box");
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            assert!(pool.install(|| snow_mesh(&sim)) == reference, "another mesh on {threads} threads");
        }
    }

    #[test]
    fn the_snow_mesh_is_closed_and_holds_the_snow_volume() {
        let sim = snowy_sim();
        let mesh = snow_mesh(&sim);
        assert!(mesh.triangles() > 1000);
        // Weld by position and count each undirected edge: every edge twice, in opposite
        // directions (closed and consistently oriented).
        let key = |p: Vec3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
        let mut id = HashMap::new();
        let welded: Vec<usize> = mesh
            .positions
            .iter()
            .map(|&p| {
                let n = id.len();
                *id.entry(key(p)).or_insert(n)
            })
            .collect();
        let mut edges: HashMap<(usize, usize), i32> = HashMap::new();
        for t in mesh.indices.chunks_exact(3) {
            for k in 0..3 {
                let (a, b) = (welded[t[k] as usize], welded[t[(k + 1) % 3] as usize]);
                *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
        }
        assert!(edges.values().all(|&v| v == 0), "an open or flipped edge");
        // Its volume (divergence theorem) is the snow on the maps, up to the corner
        // averaging of heights (exact for planar patches; within 5 % here).
        let volume: f64 = mesh
            .indices
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize].as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum();
        let snow = sim.volume_m3();
        assert!((volume / snow - 1.0).abs() < 0.05, "mesh {volume} vs snow {snow}");
        assert!(mesh.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-4));
    }

    #[test]
    fn files_have_their_formats_structure() {
        let mesh = snow_mesh(&snowy_sim());
        let obj = to_obj(&mesh);
        assert_eq!(obj.lines().filter(|l| l.starts_with("v ")).count(), mesh.positions.len());
        assert_eq!(obj.lines().filter(|l| l.starts_with("f ")).count(), mesh.triangles());
        let ply = to_ply(&mesh);
        let header_end = ply.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        assert_eq!(ply.len() - header_end, mesh.positions.len() * 24 + mesh.triangles() * 13);
        let glb = to_glb(&mesh);
        assert_eq!(&glb[0..4], b"glTF");
        assert_eq!(u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize, glb.len());
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        assert_eq!(&glb[16..20], b"JSON");
        assert_eq!(json_len % 4, 0);
        let bin_len = u32::from_le_bytes(glb[20 + json_len..24 + json_len].try_into().unwrap()) as usize;
        assert_eq!(&glb[24 + json_len..28 + json_len], b"BIN\0");
        assert_eq!(28 + json_len + bin_len, glb.len());
        let json = std::str::from_utf8(&glb[20..20 + json_len]).unwrap();
        assert!(json.contains(&format!("\"count\":{}", mesh.positions.len())));
        assert!(json.contains(&format!("\"byteLength\":{bin_len}")));
    }
}
