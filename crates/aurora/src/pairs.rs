//! Every close pair once, in 2-D: points sorted into rows of cells, and a half-stencil
//! sweep over them for symmetric SPH passes (a pair's term is computed once and added to
//! both points).
//!
//! [`CellRows`] sorts points by row of cells and, within a row, by cell (the counting-sort
//! order of a dense grid, aurora thesis §2.5.1), but keeps only a start per row: memory
//! and time grow with the number of points and rows, not with the area of the plane, so
//! cells can be small (a fraction of the search radius) over a large, sparsely filled
//! plane.
//!
//! For a point i in cell (x, z) the sweep hands over contiguous index ranges of
//! candidates j: the rest of its own row from i + 1 to `rings` cells to the right, and the
//! `rings` rows above it from `rings` cells left to `rings` cells right. Every unordered
//! pair of points within `rings` cells of each other appears exactly once (tested against
//! brute force below), and the candidate area is half that of the full stencil.
//!
//! Writes to j reach at most `rings` rows above i's row. The sweep runs over fixed
//! stripes of rows in two phases, even stripes then odd stripes, each stripe at least
//! `rings` rows tall: stripes running at the same time write disjoint index windows,
//! each point's accumulators are updated in an order fixed by the points alone, and the
//! result is bit-identical for any thread count.
//!
//! ```
//! use glam::Vec2;
//! use phenomena_aurora::pairs::{CellRows, for_each_half_pair_run};
//! let points = [Vec2::new(3.0, 0.0), Vec2::new(0.0, 0.0), Vec2::new(0.5, 0.0)];
//! let mut rows = CellRows::default();
//! rows.build(&points, 1.0).unwrap();
//! let mut sorted = Vec::new();
//! rows.gather(&points, &mut sorted); // the sweep works on points in sorted order
//! assert_eq!(sorted, [points[1], points[2], points[0]]);
//! let mut count = vec![0u32; 3];
//! for_each_half_pair_run(&rows, 1, &mut count, |window, base, i, runs| {
//!     for j in runs.iter().flat_map(|r| r.clone()) {
//!         if sorted[j].distance(sorted[i]) < 1.0 {
//!             window[i - base] += 1;
//!             window[j - base] += 1;
//!         }
//!     }
//! });
//! assert_eq!(count, [1, 1, 0]);
//! ```

use std::ops::Range;

use glam::Vec2;
use rayon::prelude::*;

use phenomena_core::grid::GridError;

/// Rows of cells per stripe for `rings` = 1; stripes are `rings` times taller.
const STRIPE_ROWS: usize = 1;
/// The most rings [`for_each_half_pair_run`] searches.
pub const MAX_RINGS: usize = 3;
/// The most candidate runs a point can have: its own row and `rings` rows above.
pub const MAX_RUNS: usize = 1 + MAX_RINGS;
/// The most cells along either axis (cell coordinates are 32-bit).
pub const MAX_CELLS_PER_AXIS: usize = 1 << 30;
/// Points per parallel work item in the sort (fixed: no effect on results).
const MIN_LEN: usize = 4096;
/// The most tasks a counting sort places its items by ([`counting_sort`]).
const MAX_SORT_TASKS: usize = 8;

/// 2-D points sorted by row of cells, then by cell within a row, then by their previous
/// order (so the sort is deterministic); rebuilt per step, buffers kept.
#[derive(Clone, Debug, Default)]
pub struct CellRows {
    order: Vec<u32>,
    column: Vec<u32>,
    row_start: Vec<u32>,
    max_cell_count: usize,
    cell: Vec<(u32, u32)>,
    count: Vec<u32>,
    scratch: Vec<u32>,
    /// The bucket of each item of a counting sort.
    keys: Vec<u32>,
}

impl CellRows {
    /// Sort `points` into cells of `cell_size`.
    pub fn build(&mut self, points: &[Vec2], cell_size: f32) -> Result<(), GridError> {
        if !(cell_size > 0.0) || !cell_size.is_finite() {
            return Err(GridError::BadCellSize(cell_size));
        }
        // Minimum and maximum are exact, so the parallel reduction is order-independent;
        // a NaN anywhere makes the extent NaN.
        // Whether all are finite found in the same pass; the first that is not only then.
        let (lo, hi, finite) = points
            .par_iter()
            .with_min_len(MIN_LEN)
            .fold(
                || (Vec2::INFINITY, Vec2::NEG_INFINITY, true),
                |(lo, hi, finite), &p| (lo.min(p), hi.max(p), finite & p.is_finite()),
            )
            .reduce(
                || (Vec2::INFINITY, Vec2::NEG_INFINITY, true),
                |a, b| (a.0.min(b.0), a.1.max(b.1), a.2 & b.2),
            );
        if !finite && let Some(index) = points.iter().position(|p| !p.is_finite()) {
            return Err(GridError::NonFinite { index });
        }
        let inv = 1.0 / cell_size;
        let cells = if points.is_empty() { Vec2::ONE } else { ((hi - lo) * inv).floor() + 1.0 };
        if cells.max_element() > MAX_CELLS_PER_AXIS as f32 {
            let total = f64::from(cells.x) * f64::from(cells.y);
            return Err(GridError::TooManyCells { cells: total.min(usize::MAX as f64) as usize });
        }
        let (columns, rows) = (cells.x as u32, cells.y as usize);
        // Cell of each point; offsets from the minimum are non-negative: truncation is floor.
        self.cell.clear();
        self.cell.par_extend(points.par_iter().with_min_len(MIN_LEN).map(|&p| {
            let c = (p - lo) * inv;
            ((c.y as u32).min(rows as u32 - 1), (c.x as u32).min(columns - 1))
        }));
        // Least-significant-digit radix sort: a stable counting sort by column, then one by
        // row. O(points × tasks + rows + columns), whatever the previous order (each of
        // `counting_sort`'s tasks reads every key).
        self.keys.clear();
        self.keys.par_extend(self.cell.par_iter().with_min_len(MIN_LEN).map(|c| c.1));
        counting_sort(&mut self.count, columns as usize, &self.keys, None, &mut self.scratch);
        let cell = &self.cell;
        self.keys.clear();
        self.keys.par_extend(self.scratch.par_iter().with_min_len(MIN_LEN).map(|&i| cell[i as usize].0));
        counting_sort(&mut self.row_start, rows, &self.keys, Some(&self.scratch), &mut self.order);
        self.column.clear();
        self.column.par_extend(self.order.par_iter().with_min_len(MIN_LEN).map(|&i| cell[i as usize].1));
        // A cell's points are consecutive in sorted order, within their row's run: the
        // longest run of one column within a row, rows in parallel (sequential reads of
        // `column`, not the cells gathered through `order`).
        let this = &*self;
        self.max_cell_count = (0..rows)
            .into_par_iter()
            .map(|r| {
                let span = &this.column[this.row(r)];
                let (mut most, mut run) = (0, 0);
                for k in 0..span.len() {
                    run = if k > 0 && span[k] == span[k - 1] { run + 1 } else { 1 };
                    most = most.max(run);
                }
                most
            })
            .max()
            .unwrap_or(0);
        Ok(())
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// Original index of the k-th point in sorted order.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Number of rows of cells.
    pub fn rows(&self) -> usize {
        self.row_start.len().saturating_sub(1)
    }

    /// The most points any one cell holds.
    pub fn max_cell_count(&self) -> usize {
        self.max_cell_count
    }

    /// Gather `src` into sorted order: `dst[k] = src[order[k]]`.
    pub fn gather<T: Copy + Send + Sync>(&self, src: &[T], dst: &mut Vec<T>) {
        dst.clear();
        dst.par_extend(self.order.par_iter().with_min_len(MIN_LEN).map(|&i| src[i as usize]));
    }

    /// Sorted positions of the points in `row`.
    fn row(&self, row: usize) -> Range<usize> {
        let r = row.min(self.rows());
        self.row_start[r] as usize..self.row_start[(row + 1).min(self.rows())] as usize
    }
}

/// Stable counting sort: `out` lists the items (`items[p]`, or p itself when `items` is
/// `None`) by bucket `keys[p]` (`< buckets`), ties in order of p; `start` receives the
/// start of each bucket and the total (so `buckets + 1` entries). The counts are taken in
/// one pass; the items are then placed by one task per thread (at most
/// [`MAX_SORT_TASKS`]) in parallel, each owning the buckets of about an equal share of
/// the items (so the part of `out` they fill) and reading every key in order. Whatever
/// the cut, each bucket gets its items in order of p: the same output for any thread
/// count (test `many_points_sort_alike_on_any_thread_count`).
fn counting_sort(
    start: &mut Vec<u32>,
    buckets: usize,
    keys: &[u32],
    items: Option<&[u32]>,
    out: &mut Vec<u32>,
) {
    let n = keys.len();
    start.clear();
    start.resize(buckets + 1, 0);
    for &k in keys {
        start[k as usize + 1] += 1;
    }
    for b in 0..buckets {
        start[b + 1] += start[b];
    }
    out.clear();
    out.resize(n, 0);
    // Task t owns buckets cuts[t]..cuts[t + 1]: those starting at or after the t-th
    // share of the items, up to the next task's.
    let tasks = rayon::current_num_threads().clamp(1, MAX_SORT_TASKS);
    let mut cuts: Vec<usize> =
        (0..tasks).map(|t| start[..buckets].partition_point(|&s| (s as usize) < n * t / tasks)).collect();
    cuts[0] = 0;
    cuts.push(buckets);
    let ranges: Vec<Range<usize>> =
        cuts.windows(2).map(|c| start[c[0]] as usize..start[c[1]] as usize).collect();
    let start = &*start;
    disjoint_windows(out, &ranges).into_par_iter().zip(cuts.par_windows(2)).for_each(|(part, c)| {
        let (first, end) = (c[0], c[1]);
        let base = start[first];
        let mut cursor: Vec<u32> = start[first..end].iter().map(|&s| s - base).collect();
        for (p, &k) in keys.iter().enumerate() {
            let k = k as usize;
            if (first..end).contains(&k) {
                let slot = &mut cursor[k - first];
                part[*slot as usize] = items.map_or(p as u32, |items| items[p]);
                *slot += 1;
            }
        }
    });
}

/// Cut `s` into the disjoint ascending `ranges`.
fn disjoint_windows<'a, T>(mut s: &'a mut [T], ranges: &[Range<usize>]) -> Vec<&'a mut [T]> {
    let mut cut = 0;
    let mut out = Vec::with_capacity(ranges.len());
    for r in ranges {
        let (_, tail) = std::mem::take(&mut s).split_at_mut(r.start - cut);
        let (window, tail) = tail.split_at_mut(r.end - r.start);
        out.push(window);
        s = tail;
        cut = r.end;
    }
    out
}

/// Call `visit(window, base, i, runs)` for every point i of `rows` (built with cells of
/// radius / `rings`; point k is the k-th in sorted order) with its half-stencil candidate
/// ranges `runs` (non-empty, all indices > i). `window` is the part of `acc` starting at
/// point `base` that holds every index i and j can take; the visitor filters candidates by
/// distance and adds a pair's terms to `window[i - base]` and `window[j - base]`. Runs in
/// parallel over stripes of rows (see the module docs), so the result does not depend on
/// the thread count.
///
/// # Panics
/// If `acc` does not cover exactly the points, or `rings` is not 1 to [`MAX_RINGS`]
/// (caller bugs, not bad input).
pub fn for_each_half_pair_run<T, F>(rows: &CellRows, rings: usize, acc: &mut [T], visit: F)
where
    T: Send,
    F: Fn(&mut [T], usize, usize, &[Range<usize>]) + Sync,
{
    // A zero-sized second array: no allocation.
    let mut none = vec![(); acc.len()];
    for_each_half_pair_run2(rows, rings, acc, &mut none, |a, _, base, i, runs| visit(a, base, i, runs));
}

/// [`for_each_half_pair_run`] with two accumulator arrays (for structure-of-arrays
/// results, such as the two components of a force), windowed alike.
///
/// # Panics
/// As [`for_each_half_pair_run`].
pub fn for_each_half_pair_run2<A, B, F>(
    rows: &CellRows,
    rings: usize,
    acc: &mut [A],
    acc2: &mut [B],
    visit: F,
) where
    A: Send,
    B: Send,
    F: Fn(&mut [A], &mut [B], usize, usize, &[Range<usize>]) + Sync,
{
    let n = rows.len();
    assert!(acc.len() == n && acc2.len() == n, "accumulators must cover every point");
    assert!((1..=MAX_RINGS).contains(&rings), "rings {rings} must be 1 to {MAX_RINGS}");
    let nz = rows.rows();
    let rows_per = STRIPE_ROWS * rings;
    let stripes = nz.div_ceil(rows_per);
    let stripe_rows = |s: usize| s * rows_per..((s + 1) * rows_per).min(nz);

    for phase in 0..2 {
        // Stripe s writes its own rows and the `rings` rows after it, which belong to
        // stripe s + 1 (the other phase): the windows of one phase are disjoint.
        let stripes_now: Vec<usize> = (phase..stripes).step_by(2).collect();
        let ranges: Vec<Range<usize>> = stripes_now
            .iter()
            .map(|&s| {
                let r = stripe_rows(s);
                rows.row(r.start).start..rows.row(r.end + rings - 1).end
            })
            .collect();
        let mut windows: Vec<_> =
            disjoint_windows(acc, &ranges).into_iter().zip(disjoint_windows(acc2, &ranges)).collect();
        windows.par_iter_mut().zip(&stripes_now).zip(&ranges).for_each(|(((window, window2), &s), range)| {
            sweep_stripe(rows, rings, stripe_rows(s), (window, window2, range.start), &visit);
        });
    }
}

/// Visit every point of the rows `stripe` with its half-stencil runs, as
/// [`for_each_half_pair_run2`] describes; `windows` are the parts of the two accumulator
/// arrays starting at point `base` that the stripe writes.
#[inline]
fn sweep_stripe<A, B, F>(
    rows: &CellRows,
    rings: usize,
    stripe: Range<usize>,
    (window, window2, base): (&mut [A], &mut [B], usize),
    visit: &F,
) where
    F: Fn(&mut [A], &mut [B], usize, usize, &[Range<usize>]),
{
    let column = &rows.column;
    let reach = rings as u32;
    let mut runs: [Range<usize>; MAX_RUNS] = Default::default();
    for row in stripe {
        let own = rows.row(row);
        let mut above = Above::of(rows, row, rings);
        let mut own_end = own.start;
        let mut cell = u32::MAX;
        let mut count = 0;
        for i in own.clone() {
            let kx = column[i];
            if kx != cell {
                // A new cell: its runs, shared by all its points.
                cell = kx;
                let (left, right) = (kx.saturating_sub(reach), kx + reach);
                while own_end < own.end && column[own_end] <= right {
                    own_end += 1;
                }
                count = 1 + above.advance(rows, row, (left, right), &mut runs[1..]);
            }
            runs[0] = i + 1..own_end;
            let first = usize::from(runs[0].is_empty());
            if first < count {
                visit(window, window2, base, i, &runs[first..count]);
            }
        }
    }
}

/// Per row above a row (up to `rings` of them): the candidates' range [lo, hi) of the
/// cells within reach of the current cell, advanced monotonically as the cell column
/// grows along the row.
struct Above {
    ranges: [Range<usize>; MAX_RINGS],
    /// Rows above that exist.
    ups: usize,
}

impl Above {
    /// Empty ranges at the start of each of the `rings` rows above `row`.
    #[inline]
    fn of(rows: &CellRows, row: usize, rings: usize) -> Self {
        let nz = rows.rows();
        let mut ranges: [Range<usize>; MAX_RINGS] = Default::default();
        let ups = (row + 1..=row + rings).take_while(|&u| u < nz).count();
        for (u, a) in ranges.iter_mut().enumerate().take(ups) {
            let r = rows.row(row + 1 + u);
            *a = r.start..r.start;
        }
        Self { ranges, ups }
    }

    /// Advance each range to the cells of columns `left..=right` of its row (above `row`)
    /// and write the non-empty ones to `runs` in row order; returns how many.
    #[inline]
    fn advance(
        &mut self,
        rows: &CellRows,
        row: usize,
        (left, right): (u32, u32),
        runs: &mut [Range<usize>],
    ) -> usize {
        let column = &rows.column;
        let mut count = 0;
        for (u, a) in self.ranges.iter_mut().enumerate().take(self.ups) {
            let end = rows.row(row + 1 + u).end;
            while a.start < end && column[a.start] < left {
                a.start += 1;
            }
            a.end = a.end.max(a.start);
            while a.end < end && column[a.end] <= right {
                a.end += 1;
            }
            if a.start < a.end {
                runs[count] = a.clone();
                count += 1;
            }
        }
        count
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sorted_grid(points: &[Vec2], cell: f32) -> (CellRows, Vec<Vec2>) {
        let mut rows = CellRows::default();
        rows.build(points, cell).unwrap();
        let mut sorted = Vec::new();
        rows.gather(points, &mut sorted);
        (rows, sorted)
    }

    /// Every pair closer than r, once, as (min, max), from the sweep.
    fn swept_pairs(grid: &CellRows, points: &[Vec2], rings: usize, r: f32) -> Vec<(u32, u32)> {
        let mut found: Vec<Vec<u32>> = vec![Vec::new(); points.len()];
        for_each_half_pair_run(grid, rings, &mut found, |window, base, i, runs| {
            assert!(runs.iter().all(|r| r.start > i && !r.is_empty()), "runs hold only later points");
            for j in runs.iter().flat_map(|r| r.clone()) {
                if points[j].distance_squared(points[i]) < r * r {
                    window[i - base].push(j as u32);
                }
            }
        });
        let mut pairs: Vec<(u32, u32)> =
            found.iter().enumerate().flat_map(|(i, js)| js.iter().map(move |&j| (i as u32, j))).collect();
        pairs.sort_unstable();
        pairs
    }

    proptest! {
        #[test]
        fn every_close_pair_exactly_once(
            pts in prop::collection::vec((-3.0f32..3.0, -3.0f32..3.0), 0..400),
            r in 0.05f32..1.5,
            rings in 1usize..=MAX_RINGS,
        ) {
            let points: Vec<Vec2> = pts.iter().map(|&(x, z)| Vec2::new(x, z)).collect();
            let (grid, sorted) = sorted_grid(&points, r / rings as f32);
            let got = swept_pairs(&grid, &sorted, rings, r);
            let mut want = Vec::new();
            for i in 0..sorted.len() {
                for j in i + 1..sorted.len() {
                    if sorted[i].distance_squared(sorted[j]) < r * r {
                        want.push((i as u32, j as u32));
                    }
                }
            }
            // `got` sorted and `want` built ascending: equal lists mean each pair once.
            prop_assert_eq!(got, want);
        }
    }

    /// The order [`CellRows::build`] should give `points` in cells of `cell`, and each
    /// point's (row, column, index) that makes it.
    fn reference_order(points: &[Vec2], cell: f32) -> (Vec<u32>, Vec<(i64, i64, u32)>) {
        let lo = points.iter().fold(Vec2::INFINITY, |m, &p| m.min(p));
        // The same arithmetic as the sort (a product with 1/cell, then truncation).
        let keys: Vec<(i64, i64, u32)> = (0..points.len() as u32)
            .map(|i| {
                let c = (points[i as usize] - lo) * (1.0 / cell);
                (c.y as i64, c.x as i64, i)
            })
            .collect();
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        order.sort_by_key(|&i| keys[i as usize]);
        (order, keys)
    }

    proptest! {
        #[test]
        fn points_are_sorted_by_row_then_cell_then_index(
            pts in prop::collection::vec((-3.0f32..3.0, -3.0f32..3.0), 1..300),
            cell in 0.05f32..2.0,
        ) {
            let points: Vec<Vec2> = pts.iter().map(|&(x, z)| Vec2::new(x, z)).collect();
            let mut rows = CellRows::default();
            rows.build(&points, cell).unwrap();
            let (want, keys) = reference_order(&points, cell);
            let key = |i: u32| keys[i as usize];
            prop_assert_eq!(rows.order(), &want[..]);
            let mut most = 0;
            for i in &want {
                let same = want.iter().filter(|&&j| key(j).0 == key(*i).0 && key(j).1 == key(*i).1).count();
                most = most.max(same);
            }
            prop_assert_eq!(rows.max_cell_count(), most);
        }
    }

    #[test]
    fn many_points_sort_alike_on_any_thread_count() {
        // 60,000 points over about 80 x 20 cells (so every sort task places many, with
        // many ties in a cell): the order is (row, column, index) on 1, 2 and 3 threads.
        let points: Vec<Vec2> = (0..60_000u32)
            .map(|k| {
                let t = k as f32 * 0.618_034;
                Vec2::new((t * 7.3).sin() * 20.0, (t * 3.1).cos() * 5.0)
            })
            .collect();
        let cell = 0.5;
        let (want, keys) = reference_order(&points, cell);
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut rows = CellRows::default();
            pool.install(|| rows.build(&points, cell)).unwrap();
            assert!(rows.order() == &want[..], "{threads} threads: another order");
            assert_eq!(rows.rows() as i64, keys[want[want.len() - 1] as usize].0 + 1, "rows of cells");
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let mut rows = CellRows::default();
        assert_eq!(rows.build(&[Vec2::ZERO], 0.0), Err(GridError::BadCellSize(0.0)));
        assert!(matches!(rows.build(&[Vec2::ZERO], f32::NAN), Err(GridError::BadCellSize(_))));
        assert_eq!(
            rows.build(&[Vec2::ZERO, Vec2::new(f32::NAN, 0.0)], 1.0),
            Err(GridError::NonFinite { index: 1 })
        );
        assert!(matches!(
            rows.build(&[Vec2::ZERO, Vec2::splat(1e30)], 1e-3),
            Err(GridError::TooManyCells { .. })
        ));
        rows.build(&[], 1.0).unwrap();
        assert!(rows.is_empty());
        let mut none: Vec<u32> = Vec::new();
        for_each_half_pair_run(&rows, 1, &mut none, |_, _, _, _| panic!("no points, no pairs"));
    }

    #[test]
    fn sums_are_identical_for_any_thread_count() {
        // Clustered points so many stripes and both phases write the same particles.
        let points: Vec<Vec2> = (0..20_000u32)
            .map(|k| {
                let t = k as f32 * 0.618_034;
                Vec2::new((t * 7.3).sin() * 20.0 + (k % 7) as f32 * 0.01, (t * 3.1).cos() * 20.0)
            })
            .collect();
        let (grid, sorted) = sorted_grid(&points, 0.5);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut sum = vec![0f32; sorted.len()];
            let mut f = vec![Vec2::ZERO; sorted.len()];
            pool.install(|| {
                for_each_half_pair_run(&grid, 1, &mut sum, |w, base, i, runs| {
                    for j in runs.iter().flat_map(|r| r.clone()) {
                        let d = sorted[j].distance(sorted[i]);
                        if d < 0.5 {
                            w[i - base] += 0.5 - d;
                            w[j - base] += 0.5 - d;
                        }
                    }
                });
                for_each_half_pair_run(&grid, 1, &mut f, |w, base, i, runs| {
                    for j in runs.iter().flat_map(|r| r.clone()) {
                        let d = sorted[j] - sorted[i];
                        if d.length() < 0.5 {
                            w[i - base] += d;
                            w[j - base] -= d;
                        }
                    }
                });
            });
            (sum, f.iter().map(|v| v.x).collect::<Vec<_>>(), f.iter().map(|v| v.y).collect::<Vec<_>>())
        };
        let one = run(1);
        assert!(one.0.iter().filter(|&&s| s > 0.0).count() > 10_000, "the test has pairs to sum");
        for threads in [2, 3, 5] {
            let other = run(threads);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&one.0), bits(&other.0), "{threads} threads");
            assert_eq!(bits(&one.1), bits(&other.1), "{threads} threads");
            assert_eq!(bits(&one.2), bits(&other.2), "{threads} threads");
        }
    }
}
