//! Neighbour lists: every pair of points closer than a radius, found once per step with
//! a [`NeighborGrid`] and kept for the passes that need them (SPH density, then forces).
//!
//! Lists are built in parallel over fixed chunks of points and stored per chunk in
//! compressed-row form, each point's neighbours in grid order (itself included, at
//! distance 0), so every consumer visits pairs in the same order for any thread count.
//!
//! ```
//! use glam::Vec2;
//! use phenomena_core::grid::NeighborGrid;
//! use phenomena_core::neighbors::NeighborLists;
//! let mut points = vec![Vec2::new(0.0, 0.0), Vec2::new(5.0, 5.0), Vec2::new(0.5, 0.0)];
//! let mut grid = NeighborGrid::default();
//! grid.build(&points, 1.0).unwrap();
//! let mut sorted = Vec::new();
//! grid.gather(&points, &mut sorted); // lists need points in cell order
//! grid.mark_points_sorted();
//! let mut lists = NeighborLists::new(2);
//! lists.build(&sorted, &grid, 1, 1.0, 64).unwrap();
//! let total: usize = (0..3).map(|i| lists.get(i).0.len()).sum();
//! assert_eq!(total, 5); // each point itself, plus the close pair twice
//! ```

use rayon::prelude::*;

use crate::grid::{GridPoint, NeighborGrid};

/// Candidates examined between checks of the neighbour limit.
const LIMIT_CHECK: usize = 256;

/// A point had more neighbours than the limit given to [`NeighborLists::build`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("a point has more than {limit} neighbours within the radius")]
pub struct TooManyNeighbors {
    /// The limit.
    pub limit: usize,
}

/// The neighbours of one chunk of points.
#[derive(Clone, Debug, Default)]
pub struct ListChunk {
    start: Vec<u32>,
    index: Vec<u32>,
    dist: Vec<f32>,
}

impl ListChunk {
    /// Neighbours of the chunk's point `o` (indices, and distances in the same order).
    #[inline]
    pub fn neighbors(&self, o: usize) -> (&[u32], &[f32]) {
        let r = self.start[o] as usize..self.start[o + 1] as usize;
        (&self.index[r.clone()], &self.dist[r])
    }

    /// Pairs held (each pair once per side, self-pairs included).
    pub fn pairs(&self) -> usize {
        self.index.len()
    }
}

/// Neighbour lists of a point set, in chunks of a fixed size.
#[derive(Clone, Debug)]
pub struct NeighborLists {
    chunk: usize,
    chunks: Vec<ListChunk>,
}

impl NeighborLists {
    /// Empty lists that will be built in chunks of `chunk` points.
    pub fn new(chunk: usize) -> Self {
        Self { chunk: chunk.max(1), chunks: Vec::new() }
    }

    /// Points per chunk.
    pub fn chunk_size(&self) -> usize {
        self.chunk
    }

    /// The chunks, in point order: chunk c holds points `c·chunk_size ..`.
    pub fn chunks(&self) -> &[ListChunk] {
        &self.chunks
    }

    /// Neighbours of point `i`.
    pub fn get(&self, i: usize) -> (&[u32], &[f32]) {
        self.chunks[i / self.chunk].neighbors(i % self.chunk)
    }

    /// Total pairs held.
    pub fn pairs(&self) -> usize {
        self.chunks.iter().map(ListChunk::pairs).sum()
    }

    /// Find, for every point, all points closer than `radius` (strictly), using `grid`
    /// built over `points` with cells of `radius / rings` and marked sorted (points in
    /// cell order, so runs of cells are index ranges). Fails if a point has more than
    /// `max_neighbors` neighbours (the work would grow quadratically).
    pub fn build<P: GridPoint>(
        &mut self,
        points: &[P],
        grid: &NeighborGrid,
        rings: usize,
        radius: f32,
        max_neighbors: usize,
    ) -> Result<(), TooManyNeighbors> {
        let chunk = self.chunk;
        let n_chunks = points.len().div_ceil(chunk);
        self.chunks.resize_with(n_chunks, ListChunk::default);
        self.chunks.truncate(n_chunks);
        let r2 = radius * radius;
        let too_many = std::sync::atomic::AtomicBool::new(false);
        self.chunks.par_iter_mut().enumerate().for_each(|(c, list)| {
            list.start.clear();
            list.index.clear();
            list.dist.clear();
            let end = ((c + 1) * chunk).min(points.len());
            let mut idx = [0u32; LIMIT_CHECK];
            let mut d2s = [0f32; LIMIT_CHECK];
            for i in c * chunk..end {
                let own = list.index.len();
                list.start.push(own as u32);
                let xi = points[i];
                grid.for_each_candidate_run(xi, rings, |run| {
                    let mut s = run.start;
                    while s < run.end {
                        if list.index.len() - own > max_neighbors {
                            too_many.store(true, std::sync::atomic::Ordering::Relaxed);
                            return;
                        }
                        let e = (s + LIMIT_CHECK).min(run.end);
                        // Branch-free compaction into the chunk's buffers: every candidate
                        // is written, kept (the count advances) only if close.
                        let mut kept = 0;
                        for (k, q) in points[s..e].iter().enumerate() {
                            let d2 = q.distance_squared(xi);
                            idx[kept] = (s + k) as u32;
                            d2s[kept] = d2;
                            kept += usize::from(d2 < r2);
                        }
                        list.index.extend_from_slice(&idx[..kept]);
                        list.dist.extend_from_slice(&d2s[..kept]);
                        s = e;
                    }
                });
                for d in &mut list.dist[own..] {
                    *d = d.sqrt();
                }
            }
            list.start.push(list.index.len() as u32);
        });
        if too_many.load(std::sync::atomic::Ordering::Relaxed) {
            Err(TooManyNeighbors { limit: max_neighbors })
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn lists_equal_brute_force(
            pts in prop::collection::vec((-2.0f32..2.0, -2.0f32..2.0, -2.0f32..2.0), 0..400),
            r in 0.05f32..1.0,
            rings in 1usize..3,
        ) {
            let points: Vec<Vec3> = pts.iter().map(|&(x, y, z)| Vec3::new(x, y, z)).collect();
            let mut grid = NeighborGrid::default();
            grid.build(&points, r / rings as f32).unwrap();
            let mut sorted = Vec::new();
            grid.gather(&points, &mut sorted);
            grid.mark_points_sorted();
            let mut lists = NeighborLists::new(37);
            lists.build(&sorted, &grid, rings, r, usize::MAX).unwrap();
            for (i, &p) in sorted.iter().enumerate() {
                let (idx, dist) = lists.get(i);
                let mut got: Vec<u32> = idx.to_vec();
                got.sort_unstable();
                let want: Vec<u32> =
                    (0..sorted.len() as u32).filter(|&j| sorted[j as usize].distance_squared(p) < r * r).collect();
                prop_assert_eq!(got, want);
                for (&j, &d) in idx.iter().zip(dist) {
                    prop_assert!((d - sorted[j as usize].distance(p)).abs() < 1e-5);
                }
            }
        }
    }

    #[test]
    fn the_neighbour_limit_is_enforced() {
        let points = vec![Vec3::ZERO; 1000];
        let mut grid = NeighborGrid::default();
        grid.build(&points, 1.0).unwrap();
        grid.mark_points_sorted();
        let mut lists = NeighborLists::new(64);
        assert_eq!(lists.build(&points, &grid, 1, 1.0, 100), Err(TooManyNeighbors { limit: 100 }));
        assert!(lists.build(&points, &grid, 1, 1.0, 1000).is_ok());
    }
}
