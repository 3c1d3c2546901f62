//! Uniform-grid neighbour search by counting sort, in 2-D and 3-D.
//!
//! With the cell size equal to the search (support) radius, every neighbour of a point
//! lies in its own cell or one of the adjacent ones (3×3 in 2-D, 3×3×3 in 3-D); a grid
//! of cells 1/k of the radius searches k rings instead, a tighter box around the search
//! sphere (in 3-D, 15.6 r³ of candidates at k = 2 instead of 27 r³). Points are
//! counting-sorted by cell into contiguous ranges given by a cell-start table, the scheme
//! of the aurora thesis §2.5.1 (cell start/end per cell). The sort is stable, so within a
//! cell points stay in index order and every traversal is deterministic.
//!
//! ```
//! use glam::Vec2;
//! use phenomena_core::grid::NeighborGrid;
//! let points = [Vec2::new(0.0, 0.0), Vec2::new(0.5, 0.0), Vec2::new(3.0, 0.0)];
//! let mut grid = NeighborGrid::default();
//! grid.build(&points, 1.0).unwrap();
//! let mut near = Vec::new();
//! grid.for_each_candidate(points[0], |j| {
//!     if points[j as usize].distance(points[0]) < 1.0 { near.push(j) }
//! });
//! assert_eq!(near, vec![0, 1]);
//! ```

use glam::{Vec2, Vec3};

/// The most cells a grid may allocate (64 Mi cells, 256 MiB of cell table).
pub const MAX_CELLS: usize = 1 << 26;

/// A point type the grid can sort: 2-D or 3-D.
pub trait GridPoint: Copy + Send + Sync {
    /// Number of spatial dimensions, 2 or 3.
    const DIM: usize;
    /// Coordinates padded to three (the third is 0 in 2-D).
    fn coords(self) -> [f32; 3];
    /// Squared distance to another point.
    fn distance_squared(self, other: Self) -> f32;
}

impl GridPoint for Vec2 {
    const DIM: usize = 2;
    #[inline]
    fn coords(self) -> [f32; 3] {
        [self.x, self.y, 0.0]
    }
    #[inline]
    fn distance_squared(self, other: Self) -> f32 {
        (self - other).length_squared()
    }
}

impl GridPoint for Vec3 {
    const DIM: usize = 3;
    #[inline]
    fn coords(self) -> [f32; 3] {
        [self.x, self.y, self.z]
    }
    #[inline]
    fn distance_squared(self, other: Self) -> f32 {
        (self - other).length_squared()
    }
}

/// Why a grid could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// A coordinate was NaN or infinite.
    #[error("point {index} has a non-finite coordinate")]
    NonFinite {
        /// Index of the offending point.
        index: usize,
    },
    /// The cell size was not a positive finite number.
    #[error("cell size {0} must be a positive finite number")]
    BadCellSize(f32),
    /// The points span too many cells for a dense grid.
    #[error("the points span {cells} cells, more than the limit of {MAX_CELLS}")]
    TooManyCells {
        /// Cells the bounding box would need.
        cells: usize,
    },
}

/// A dense uniform grid over the bounding box of a point set, rebuilt per step.
///
/// Buffers are kept between builds, so rebuilding allocates nothing once warm.
#[derive(Clone, Debug, Default)]
pub struct NeighborGrid {
    dim: usize,
    inv_cell: f32,
    origin: [f32; 3],
    dims: [usize; 3],
    cell_start: Vec<u32>,
    sorted: Vec<u32>,
    point_cell: Vec<u32>,
    scratch: Vec<u32>,
}

impl NeighborGrid {
    /// Counting-sort `points` into cells of `cell_size`.
    pub fn build<P: GridPoint>(&mut self, points: &[P], cell_size: f32) -> Result<(), GridError> {
        if !(cell_size > 0.0) || !cell_size.is_finite() {
            return Err(GridError::BadCellSize(cell_size));
        }
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for (index, p) in points.iter().enumerate() {
            let c = p.coords();
            for a in 0..3 {
                if !c[a].is_finite() {
                    return Err(GridError::NonFinite { index });
                }
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        if points.is_empty() {
            lo = [0.0; 3];
            hi = [0.0; 3];
        }
        self.dim = P::DIM;
        self.inv_cell = 1.0 / cell_size;
        self.origin = lo;
        let mut cells = 1usize;
        for a in 0..3 {
            let n = if a < P::DIM {
                // Non-negative extent: truncation is floor (no libm call on the hot path).
                (((hi[a] - lo[a]) * self.inv_cell) as usize).saturating_add(1)
            } else {
                1
            };
            self.dims[a] = n;
            cells = cells.saturating_mul(n);
        }
        if cells > MAX_CELLS {
            return Err(GridError::TooManyCells { cells });
        }

        let mut point_cell = std::mem::take(&mut self.point_cell);
        point_cell.clear();
        point_cell.extend(points.iter().map(|p| self.cell_of(p.coords()) as u32));
        self.point_cell = point_cell;
        self.cell_start.clear();
        self.cell_start.resize(cells + 1, 0);
        for &c in &self.point_cell {
            self.cell_start[c as usize + 1] += 1;
        }
        for c in 0..cells {
            self.cell_start[c + 1] += self.cell_start[c];
        }
        self.sorted.clear();
        self.sorted.resize(points.len(), 0);
        // Stable scatter: a running cursor per cell.
        let cursor = &mut self.scratch;
        cursor.clear();
        cursor.extend_from_slice(&self.cell_start[..cells]);
        for (i, &c) in self.point_cell.iter().enumerate() {
            let slot = &mut cursor[c as usize];
            self.sorted[*slot as usize] = i as u32;
            *slot += 1;
        }
        Ok(())
    }

    /// Cell index of a coordinate triple inside the grid's box.
    #[inline]
    fn cell_of(&self, c: [f32; 3]) -> usize {
        let mut idx = 0usize;
        let mut stride = 1usize;
        #[allow(clippy::needless_range_loop)] // three parallel arrays indexed by axis
        for a in 0..self.dim {
            let k =
                // Inside the box the offset is non-negative: truncation is floor.
                ((((c[a] - self.origin[a]) * self.inv_cell).max(0.0)) as usize).min(self.dims[a] - 1);
            idx += k * stride;
            stride *= self.dims[a];
        }
        idx
    }

    /// Number of cells along each axis (1 for unused axes).
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Point indices in cell order (stable within a cell).
    pub fn sorted_indices(&self) -> &[u32] {
        &self.sorted
    }

    /// The cell of each point, as passed to the last `build`.
    pub fn point_cells(&self) -> &[u32] {
        &self.point_cell
    }

    /// Range into [`Self::sorted_indices`] of the points in `cell` (start..end).
    pub fn cell_range(&self, cell: usize) -> std::ops::Range<usize> {
        self.cell_start[cell] as usize..self.cell_start[cell + 1] as usize
    }

    /// Gather `src` into cell order: `dst[k] = src[sorted[k]]`.
    pub fn gather<T: Copy>(&self, src: &[T], dst: &mut Vec<T>) {
        dst.clear();
        dst.extend(self.sorted.iter().map(|&i| src[i as usize]));
    }

    /// Declare that the caller has reordered its points into cell order (with
    /// [`Self::gather`]), so that sorted position k is now point k.
    pub fn mark_points_sorted(&mut self) {
        self.scratch.clear();
        self.scratch.extend(self.sorted.iter().map(|&i| self.point_cell[i as usize]));
        std::mem::swap(&mut self.point_cell, &mut self.scratch);
        for (k, s) in self.sorted.iter_mut().enumerate() {
            *s = k as u32;
        }
    }

    /// Call `f(j)` for every point j in the cells around `query` (its own cell and the
    /// adjacent ones): a superset of the points within one cell size of `query`, in a
    /// fixed order. Callers filter by distance.
    #[inline]
    pub fn for_each_candidate<P: GridPoint>(&self, query: P, f: impl FnMut(u32)) {
        self.for_each_candidate_in_rings(query, 1, f);
    }

    /// Call `f(j)` for every point j in the cells within `rings` cells of `query`'s cell
    /// (for a grid built with a cell size of radius / `rings`): a superset of the points
    /// within `rings` cell sizes of `query`, in a fixed order. Callers filter by distance.
    #[inline]
    pub fn for_each_candidate_in_rings<P: GridPoint>(&self, query: P, rings: usize, mut f: impl FnMut(u32)) {
        self.for_each_candidate_run(query, rings, |run| {
            for &j in &self.sorted[run] {
                f(j);
            }
        });
    }

    /// Like [`Self::for_each_candidate_in_rings`], but hands over runs of positions in
    /// [`Self::sorted_indices`] (one run per row of cells). After the caller reordered its
    /// points into cell order ([`Self::mark_points_sorted`]), a run is directly a range
    /// of point indices, so the caller can scan its arrays contiguously.
    #[inline]
    pub fn for_each_candidate_run<P: GridPoint>(
        &self,
        query: P,
        rings: usize,
        mut f: impl FnMut(std::ops::Range<usize>),
    ) {
        if self.sorted.is_empty() {
            return;
        }
        let c = query.coords();
        let reach = rings as isize;
        let mut lo = [0usize; 3];
        let mut hi = [0usize; 3];
        for a in 0..self.dim {
            let v = (c[a] - self.origin[a]) * self.inv_cell;
            // Cell coordinate (floor without a libm call); far outside or NaN: no cells.
            if !(v >= -(rings as f32) && v < self.dims[a] as f32 + rings as f32) {
                return;
            }
            let t = v as isize; // truncates towards zero
            let k = if (t as f32) > v { t - 1 } else { t };
            let (l, h) = (k - reach, k + reach);
            if h < 0 || l >= self.dims[a] as isize {
                return;
            }
            lo[a] = l.max(0) as usize;
            hi[a] = (h as usize).min(self.dims[a] - 1);
        }
        let (sx, sy) = (self.dims[0], self.dims[0] * self.dims[1]);
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                // Cells along x are contiguous: one range covers the whole run.
                let row = z * sy + y * sx;
                let start = self.cell_start[row + lo[0]] as usize;
                let end = self.cell_start[row + hi[0] + 1] as usize;
                if start < end {
                    f(start..end);
                }
            }
        }
    }

    /// Indices of all points within `radius` (≤ the cell size) of `query`, ascending.
    pub fn neighbors_within<P: GridPoint>(&self, points: &[P], query: P, radius: f32) -> Vec<u32> {
        let q = query.coords();
        let r2 = radius * radius;
        let mut out = Vec::new();
        self.for_each_candidate(query, |j| {
            let p = points[j as usize].coords();
            let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
            if d2 < r2 {
                out.push(j);
            }
        });
        out.sort_unstable();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn brute<P: GridPoint>(points: &[P], q: P, r: f32) -> Vec<u32> {
        let q = q.coords();
        (0..points.len() as u32)
            .filter(|&j| {
                let p = points[j as usize].coords();
                (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2) < r * r
            })
            .collect()
    }

    proptest! {
        #[test]
        fn grid_equals_brute_force_2d(
            pts in prop::collection::vec((-5.0f32..5.0, -5.0f32..5.0), 0..300),
            r in 0.05f32..3.0,
            q in (-7.0f32..7.0, -7.0f32..7.0),
        ) {
            let points: Vec<Vec2> = pts.iter().map(|&(x, y)| Vec2::new(x, y)).collect();
            let mut grid = NeighborGrid::default();
            grid.build(&points, r).unwrap();
            let mut queries = points.clone();
            queries.push(Vec2::new(q.0, q.1));
            for &query in &queries {
                prop_assert_eq!(grid.neighbors_within(&points, query, r), brute(&points, query, r));
            }
        }

        #[test]
        fn grid_equals_brute_force_3d(
            pts in prop::collection::vec((-2.0f32..2.0, -2.0f32..2.0, -2.0f32..2.0), 0..300),
            r in 0.05f32..1.5,
            q in (-3.0f32..3.0, -3.0f32..3.0, -3.0f32..3.0),
        ) {
            let points: Vec<Vec3> = pts.iter().map(|&(x, y, z)| Vec3::new(x, y, z)).collect();
            let mut grid = NeighborGrid::default();
            grid.build(&points, r).unwrap();
            let mut queries = points.clone();
            queries.push(Vec3::new(q.0, q.1, q.2));
            for &query in &queries {
                prop_assert_eq!(grid.neighbors_within(&points, query, r), brute(&points, query, r));
            }
        }
    }

    proptest! {
        #[test]
        fn finer_cells_with_more_rings_find_the_same_neighbours(
            pts in prop::collection::vec((-2.0f32..2.0, -2.0f32..2.0, -2.0f32..2.0), 0..200),
            r in 0.05f32..1.5,
            rings in 1usize..4,
        ) {
            let points: Vec<Vec3> = pts.iter().map(|&(x, y, z)| Vec3::new(x, y, z)).collect();
            let mut grid = NeighborGrid::default();
            grid.build(&points, r / rings as f32).unwrap();
            for &q in &points {
                let mut found = Vec::new();
                grid.for_each_candidate_in_rings(q, rings, |j| {
                    if points[j as usize].distance_squared(q) < r * r {
                        found.push(j);
                    }
                });
                found.sort_unstable();
                prop_assert_eq!(found, brute(&points, q, r));
            }
        }
    }

    #[test]
    fn reordering_keeps_neighbourhoods() {
        let points: Vec<Vec3> = (0..500)
            .map(|i| {
                let f = i as f32;
                Vec3::new((f * 0.37).sin() * 2.0, (f * 0.11).cos() * 2.0, (f * 0.07).sin())
            })
            .collect();
        let mut grid = NeighborGrid::default();
        grid.build(&points, 0.3).unwrap();
        let mut sorted = Vec::new();
        grid.gather(&points, &mut sorted);
        let old_of_new = grid.sorted_indices().to_vec();
        grid.mark_points_sorted();
        for (new, &old) in old_of_new.iter().enumerate() {
            let a: Vec<u32> = grid
                .neighbors_within(&sorted, sorted[new], 0.3)
                .into_iter()
                .map(|j| old_of_new[j as usize])
                .collect::<std::collections::BTreeSet<_>>()
                .into_iter()
                .collect();
            assert_eq!(a, brute(&points, points[old as usize], 0.3));
        }
        // Cell ranges now index the reordered points directly.
        for c in 0..grid.dims().iter().product::<usize>() {
            for k in grid.cell_range(c) {
                assert_eq!(grid.point_cells()[k] as usize, c);
            }
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let mut grid = NeighborGrid::default();
        assert_eq!(grid.build(&[Vec2::new(f32::NAN, 0.0)], 1.0), Err(GridError::NonFinite { index: 0 }));
        assert_eq!(grid.build(&[Vec2::ZERO], 0.0), Err(GridError::BadCellSize(0.0)));
        assert!(matches!(
            grid.build(&[Vec3::ZERO, Vec3::splat(1e6)], 1e-3),
            Err(GridError::TooManyCells { .. })
        ));
        grid.build::<Vec2>(&[], 1.0).unwrap();
        assert!(grid.neighbors_within::<Vec2>(&[], Vec2::ZERO, 1.0).is_empty());
    }
}
