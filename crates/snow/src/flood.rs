//! The flood stabilisation: the snow brought to rest at the angle of repose
//! (§2.4.1) with work that follows the texels that change, not the depth of the snow.
//!
//! The texels of all maps are the nodes of one graph whose edges are the repose
//! comparisons of [`neighbours`]: towards a neighbour's snow surface, or towards a fixed
//! ground (off the scene, or a cliff down to a lower map: a *sink*, where snow passing
//! the region's edge falls, §2.4.2). A stable state keeps every snow-covered texel within
//! the repose rise of each of its comparisons. Three stages:
//!
//! 1. **Floor**: the highest stable surface under the snow, found bottom-up (a Dijkstra
//!    sweep in increasing height: a texel's cap is its lowest comparison plus the rise,
//!    and lowering it may lower its uphill neighbours' caps). A texel comes down only as
//!    far as the repose check demands, so snow that lay stable before the step stays.
//!    What stands above the floor is the surplus, which must move. An avalanche down a
//!    long slope is settled here in one sweep instead of one texel per pass; the surplus
//!    of a texel held at the repose above a chain at the repose that ends at a sink (an
//!    edge face, a roof's wedge over its eave) goes to the sink at once.
//! 2. **Carry**: the rest of the surplus, visited from the highest texel down (so what
//!    runs down a slope gathers before it settles). On bare ground steeper than the
//!    repose it slides on, in equal shares to the neighbours it is steep towards (Fig 6
//!    (b)-(e)). At the repose, down a chain at the repose to a sink it goes to the sink in
//!    one hop; an amount no larger than one step's snowfall runs on down the steepest way,
//!    as the local rule passes an excess on, to where there is room. Where it fits within
//!    the tolerance it stays; anything else settles by a flood.
//! 3. **Flood**: water-filling in the heights less the repose cone from the source:
//!    texels in increasing `key = surface - (source surface - rise · distance)` are
//!    raised to `source surface - rise · distance + τ`, with τ from the volume (a priority
//!    flood). The result is within the repose by construction: a pile growing from where
//!    the snow lands, a layer down a face at the repose, a foot filling up. A sink whose
//!    key the level reaches takes the rest: it falls (§2.4.2) and settles in turn.
//!
//! Sequential, ordered by height with ties broken by node number (only the first scan
//! for steep texels runs in parallel chunks, joined in order): the same for any thread
//! count. Mass is carried in f64 and written as the f32 depths the maps hold.

use std::collections::BinaryHeap;

use rayon::prelude::*;

use crate::sim::{Regions, SnowMap, Target, neighbours};

/// One part of [`steep_at_first`]'s scan: its lowest ground, highest surface and
/// candidates (the height to come down to, node), in texel order.
type SteepPart = (f32, f32, Vec<(f32, u32)>);

/// Texels a parallel part of [`steep_at_first`]'s scan covers (fixed: the candidates
/// do not depend on the thread count).
const STEEP_CHUNK: usize = 8192;

/// Flag of a flood queue entry that is a sink (an index into `Scratch::sinks`); nodes
/// (map · texels + texel) stay below it ([`Scratch::fits`]).
const SINK: u32 = 1 << 31;

/// The stabilisation's buffers, kept between steps; only a cache (a clone starts empty).
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    /// Per node: the carry's state.
    node: Vec<NodeState>,
    /// Per node: the flood's marks.
    seen: Vec<Seen>,
    /// Floor sweep (lowest first) and carry (highest first).
    buckets: Buckets,
    /// The floor's first candidates: the height each must come down to, node.
    first: Vec<(f32, u32)>,
    /// The flood's frontier, lowest key first.
    frontier: BinaryHeap<u64>,
    /// The flood's wet texels, highest key first (indices into `reached`).
    wet: BinaryHeap<u64>,
    /// A path being followed for the memo.
    path: Vec<u32>,
    /// Texels the current flood reached: node, key, apex (source height less rise · distance).
    reached: Vec<(u32, f64, f64)>,
    /// The current flood's sinks.
    sinks: Vec<Target>,
    /// Nodes whose snow changed this step (each once).
    changed: Vec<u32>,
    flood: u32,
    step: u32,
    /// Snow that left the scene this step, m of depth over one texel.
    fallen: f64,
    /// What the last settle did.
    pub(crate) counts: Counts,
}

/// What one `Scratch::settle` did (for tests and measurements).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Counts {
    /// Texels lowered by the floor.
    pub lowered: u64,
    /// Visits of the carry.
    pub carried: u64,
    /// Floods.
    pub floods: u64,
    /// Texels reached by floods.
    pub flooded: u64,
    /// The most texels one flood reached.
    pub largest_flood: u64,
    /// Carries sent down a chain to a sink in one hop.
    pub conduits: u64,
}

/// A node's state for the floor and the carry, together in memory (one cache line holds
/// what a visit needs).
#[derive(Clone, Copy, Debug, Default)]
struct NodeState {
    /// Snow in transit, m of depth over one texel.
    pending: f64,
    /// The step in which the node's snow last changed.
    changed: u32,
    /// The step of `memo`, and where a chain at the repose from it ends (`MEMO_*`).
    memo_step: u32,
    memo: u32,
}

/// A node's marks for the flood: the flood that queued it, the one that reached it, and
/// its distance from the source.
#[derive(Clone, Copy, Debug, Default)]
struct Seen {
    queued: u32,
    reached: u32,
    distance: u32,
}

impl Clone for Scratch {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// Memo: the chain ends where snow has room (a flood settles it).
const MEMO_ROOM: u32 = u32::MAX;
/// Memo: the chain ends off the scene.
const MEMO_OFF: u32 = u32::MAX - 1;

/// An f32 as a u32 that orders like it (total order; NaN never occurs here).
fn sortable(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 { !b } else { b | 1 << 31 }
}

/// A flood frontier entry: lowest `key` first (ties: larger tag first), with `tag` a
/// node or a `SINK` index.
fn frontier_entry(key: f64, tag: u32) -> u64 {
    u64::from(!sortable(key as f32)) << 32 | u64::from(tag)
}

/// The key of a [`frontier_entry`].
fn frontier_key(e: u64) -> f32 {
    let b = !((e >> 32) as u32);
    f32::from_bits(if b >> 31 == 1 { b & !(1 << 31) } else { !b })
}

/// The maps and their grid as the stages see them.
struct Grid<'a> {
    maps: &'a mut [SnowMap],
    regions: &'a Regions,
    n: usize,
    /// tan(repose) times the texel size, m.
    rise: f32,
    /// The repose tolerance, m (`sim::repose_tolerance`).
    tol: f32,
}

impl Grid<'_> {
    fn texels(&self) -> usize {
        self.n * self.n
    }

    fn split(&self, node: u32) -> (usize, usize) {
        let t = self.texels();
        (node as usize / t, node as usize % t)
    }

    fn node(&self, mi: usize, k: usize) -> u32 {
        (mi * self.texels() + k) as u32
    }

    fn surface(&self, node: u32) -> f32 {
        let (mi, k) = self.split(node);
        self.maps[mi].surface(k)
    }

    fn surface_at(&self, mi: usize, k: usize) -> f32 {
        self.maps[mi].surface(k)
    }

    /// Calls `f(target, height, sink)` for each repose comparison of `node`, in
    /// [`neighbours`]' order; `sink` when the height is a fixed ground (off the scene, or
    /// a cliff down to a lower map) rather than a surface that snow raises.
    fn relations(&self, mi: usize, k: usize, mut f: impl FnMut(Target, f32, bool)) {
        let n = self.n;
        if self.regions.inner[mi].get(k) {
            let m = &self.maps[mi];
            for nk in [k - n, k + 1, k + n, k - 1] {
                f(Target::Map(mi as u32, nk as u32), m.surface(nk), false);
            }
            return;
        }
        for (t, c) in neighbours(self.maps, n, mi, k, self.rise) {
            let sink = match t {
                Target::Off => true,
                Target::Map(o, nk) => c != self.maps[o as usize].surface(nk as usize),
            };
            f(t, c, sink);
        }
    }

    /// The lowest comparison of `node` (the first in order among equals).
    fn lowest(&self, mi: usize, k: usize) -> (Target, f32, bool) {
        let mut low = (Target::Off, f32::INFINITY, true);
        self.relations(mi, k, |t, c, sink| {
            if c < low.1 {
                low = (t, c, sink);
            }
        });
        low
    }

    /// The depth texel `k` of map `mi` must come down to, if it holds snow steeper than
    /// the repose (beyond the tolerance) towards a comparison: [`kept_depth`] under its
    /// lowest comparison.
    fn lowered(&self, mi: usize, k: usize) -> Option<f32> {
        let m = &self.maps[mi];
        let s = m.snow_m[k];
        if !(s > 0.0) {
            return None;
        }
        let low = self.lowest(mi, k).1;
        (m.surface(k) - low - self.rise > self.tol)
            .then(|| kept_depth(m.ground_m[k], low, self.rise, self.tol))
    }

    /// Calls `f(map, texel)` for the texels of other maps next to texel `k` of map `mi`
    /// where their region ends: past their edge they measure to the surfaces at `k`.
    fn uphill_across(&self, mi: usize, k: usize, mut f: impl FnMut(usize, usize)) {
        for (o, r) in self.regions.rim.iter().enumerate() {
            if o != mi && r.get(k) {
                for nk in crate::sim::four(self.n, k) {
                    if self.maps[o].possible(nk) {
                        f(o, nk);
                    }
                }
            }
        }
    }
}

/// The most snow, m, a texel of ground `ground` keeps under a comparison at `low`: a
/// depth whose surface the repose check (`surface - low - rise > tol`, the local rule's
/// own arithmetic) does not find steep, to within one f32 step of the highest surface it
/// accepts (found in steps of the surface's own precision: a few). Snow that passed the
/// check before the step still passes it when nothing under it went down, so the floor
/// takes no snow that lay stable beyond that rounding (test `flood_matches_relaxation`).
fn kept_depth(ground: f32, low: f32, rise: f32, tol: f32) -> f32 {
    let steep = |d: f32| (ground + d) - low - rise > tol;
    // One step of the surface's precision at depth `d`, as a depth.
    let step = |d: f32| {
        let h = ground + d;
        (h.next_up() - h).max(f32::MIN_POSITIVE)
    };
    let mut d = (low + rise + tol - ground).max(0.0);
    while d > 0.0 && steep(d) {
        d = (d - step(d)).max(0.0);
    }
    while !steep(d + step(d)) {
        d += step(d);
    }
    d
}

/// Most buckets of a [`Buckets`] queue.
const MAX_BUCKETS: usize = 1 << 16;

/// Nodes queued by height in buckets of a fixed width, emptied lowest or highest bucket
/// first (last in, first out within one): O(1) a node. With buckets narrower than the
/// repose rise, a node's uphill neighbours (the floor) or downhill targets (the carry)
/// always fall in another bucket, so the order within a bucket does not matter.
#[derive(Debug, Default)]
struct Buckets {
    lists: Vec<Vec<u32>>,
    base: f32,
    per_m: f32,
    /// No bucket before this one (in emptying order) holds a node.
    at: usize,
    highest_first: bool,
}

impl Buckets {
    /// Empty, for heights in `lo..=hi` (others go to the end buckets) in buckets of
    /// `width` (wider when more than `MAX_BUCKETS` would be needed).
    fn reset(&mut self, lo: f32, hi: f32, width: f32, highest_first: bool) {
        let span = (hi - lo).max(0.0);
        let count = ((span / width).ceil() as usize + 1).clamp(1, MAX_BUCKETS);
        for l in &mut self.lists {
            l.clear();
        }
        self.lists.resize_with(count.max(self.lists.len()), Vec::new);
        self.lists.truncate(count);
        self.base = lo;
        self.per_m = if span > 0.0 { (count - 1) as f32 / span } else { 0.0 };
        self.highest_first = highest_first;
        self.at = if highest_first { 0 } else { count - 1 };
    }

    fn push(&mut self, height: f32, node: u32) {
        let b = (((height - self.base) * self.per_m).max(0.0) as usize).min(self.lists.len() - 1);
        self.lists[b].push(node);
        self.at = if self.highest_first { self.at.max(b) } else { self.at.min(b) };
    }

    fn pop(&mut self) -> Option<u32> {
        loop {
            if let Some(node) = self.lists[self.at].pop() {
                return Some(node);
            }
            if self.highest_first {
                self.at = self.at.checked_sub(1)?;
            } else if self.at + 1 < self.lists.len() {
                self.at += 1;
            } else {
                return None;
            }
        }
    }
}

/// The floor's first candidates in `first`: every snow-covered texel steeper than the
/// repose after the snowfall, with the height it must come down to (for the queue's
/// order). Returns the lowest ground and the highest surface of the maps.
fn steep_at_first(g: &Grid, first: &mut Vec<(f32, u32)>) -> (f32, f32) {
    let (n, texels) = (g.n, g.texels());
    let per_map = texels.div_ceil(STEEP_CHUNK);
    // Each map's texels in chunks, in parallel, each chunk on its own; the candidates
    // joined in map and texel order, and the smallest and largest (exact, so in any
    // order) merged: the one pass's candidates and extremes.
    let parts: Vec<SteepPart> = (0..g.maps.len() * per_map)
        .into_par_iter()
        .map(|c| {
            let (mi, part) = (c / per_map, c % per_map);
            let (m, inner) = (&g.maps[mi], &g.regions.inner[mi]);
            let (mut lo, mut hi, mut out) = (f32::INFINITY, f32::NEG_INFINITY, Vec::new());
            for k in part * STEEP_CHUNK..((part + 1) * STEEP_CHUNK).min(texels) {
                let ground = m.ground_m[k];
                lo = lo.min(ground);
                let s = m.snow_m[k];
                if !(s > 0.0) {
                    continue;
                }
                let h = ground + s;
                hi = hi.max(h);
                let low = if inner.get(k) {
                    m.surface(k - n).min(m.surface(k + 1)).min(m.surface(k + n)).min(m.surface(k - 1))
                } else {
                    g.lowest(mi, k).1
                };
                if h - low - g.rise > g.tol {
                    out.push(((low + g.rise).max(ground), g.node(mi, k)));
                }
            }
            (lo, hi, out)
        })
        .collect();
    first.clear();
    first.reserve(parts.iter().map(|p| p.2.len()).sum());
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for (l, h, out) in parts {
        (lo, hi) = (lo.min(l), hi.max(h));
        first.extend(out);
    }
    (lo, hi)
}

/// Queue for the floor what lowering texel `k` of map `mi` made steep: a neighbour on
/// its map that stands more than the rise (and the tolerance) above the new surface;
/// across a region's edge the comparison is worked out in full.
fn queue_uphill(g: &Grid, queue: &mut Buckets, mi: usize, k: usize) {
    let v = g.surface_at(mi, k);
    let m = &g.maps[mi];
    for j in crate::sim::four(g.n, k) {
        if m.snow_m[j] > 0.0 && m.surface(j) - (v + g.rise) > g.tol {
            queue.push((v + g.rise).max(m.ground_m[j]), g.node(mi, j));
        }
    }
    if g.regions.any_rim.get(k) {
        g.uphill_across(mi, k, |o, j| {
            if let Some(d) = g.lowered(o, j) {
                queue.push(g.maps[o].ground_m[j] + d, g.node(o, j));
            }
        });
    }
}

impl Scratch {
    /// Whether `maps` maps of `texels` texels can be numbered below [`SINK`] (and the
    /// memo's marks): 127 maps of 4096² texels, far past any memory budget.
    pub(crate) fn fits(maps: usize, texels: usize) -> bool {
        maps.checked_mul(texels).is_some_and(|nodes| nodes < MEMO_OFF.min(SINK) as usize)
    }

    /// The nodes (map · texels + texel) whose snow the last [`Scratch::settle`] changed.
    pub(crate) fn changed(&self) -> &[u32] {
        &self.changed
    }

    /// Bring the snow of `maps` to rest (the module's three stages). Returns the snow that
    /// left the scene, m of depth over one texel.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn settle(
        &mut self,
        maps: &mut [SnowMap],
        regions: &Regions,
        n: usize,
        rise: f32,
        tol: f32,
        small: f32,
    ) -> f64 {
        let nodes = maps.len() * n * n;
        // Every carry empties what it takes: only the length changes.
        self.node.resize(nodes, NodeState::default());
        self.seen.resize(nodes, Seen::default());
        self.step = self.step.wrapping_add(1);
        if self.step == 0 {
            // After 2³² steps: the stamps start again.
            self.node.iter_mut().for_each(|v| (v.changed, v.memo_step) = (0, 0));
            self.step = 1;
        }
        self.changed.clear();
        self.fallen = 0.0;
        self.counts = Counts::default();
        let mut grid = Grid { maps, regions, n, rise, tol };
        let (lo, hi) = self.floor(&mut grid);
        self.carry(&mut grid, lo, hi, small);
        self.fallen
    }

    fn note_change(&mut self, node: u32) {
        if self.node[node as usize].changed != self.step {
            self.node[node as usize].changed = self.step;
            self.changed.push(node);
        }
    }

    /// Stage 1: lower every snow surface to the highest stable one under it, lowest
    /// first; what comes off is left in `pending` (or sent to a sink). Returns the lowest
    /// ground and the highest surface of the maps.
    fn floor(&mut self, g: &mut Grid) -> (f32, f32) {
        let mut first = std::mem::take(&mut self.first);
        let (lo, hi) = steep_at_first(g, &mut first);
        if !lo.is_finite() || !hi.is_finite() {
            self.first = first;
            return (0.0, 0.0);
        }
        let mut queue = std::mem::take(&mut self.buckets);
        queue.reset(lo, hi, 0.5 * g.rise, false);
        for &(v, node) in &first {
            queue.push(v, node);
        }
        self.first = first;
        while let Some(node) = queue.pop() {
            let (mi, k) = g.split(node);
            let Some(new) = g.lowered(mi, k) else { continue };
            let old = g.maps[mi].snow_m[k];
            if !(new < old) {
                continue;
            }
            g.maps[mi].snow_m[k] = new;
            self.counts.lowered += 1;
            self.note_change(node);
            self.surplus(g, node, f64::from(old) - f64::from(new), new > 0.0);
            queue_uphill(g, &mut queue, mi, k);
        }
        self.buckets = queue;
        (lo, hi)
    }

    /// Where the floor puts the `surplus` it took from `node`: held at the repose
    /// (`holds`) on a chain at the repose down to a sink (an edge face, a roof's wedge),
    /// straight to the sink, as the carry would send it (the chain below is settled:
    /// lower texels first); else in `pending`, for the carry.
    fn surplus(&mut self, g: &Grid, node: u32, surplus: f64, holds: bool) {
        match holds.then(|| self.conduit(g, node)).flatten() {
            Some(Target::Off) => {
                self.counts.conduits += 1;
                self.fallen += surplus;
            }
            Some(Target::Map(o, nk)) => {
                self.counts.conduits += 1;
                let target = g.node(o as usize, nk as usize);
                self.node[target as usize].pending += surplus;
                self.note_change(target);
            }
            None => self.node[node as usize].pending += surplus,
        }
    }

    /// Stage 2: move the surplus downhill, highest texel first, until it is settled or has
    /// left the scene.
    fn carry(&mut self, g: &mut Grid, lo: f32, hi: f32, small: f32) {
        self.buckets.reset(lo, hi, 0.5 * g.rise, true);
        for i in 0..self.changed.len() {
            let node = self.changed[i];
            if self.node[node as usize].pending > 0.0 {
                self.buckets.push(g.surface(node), node);
            }
        }
        while let Some(node) = self.buckets.pop() {
            let amount = std::mem::take(&mut self.node[node as usize].pending);
            if !(amount > 0.0) {
                continue;
            }
            self.counts.carried += 1;
            let (mi, k) = g.split(node);
            let h = g.surface_at(mi, k);
            let (_, low, _) = g.lowest(mi, k);
            let over = h - low - g.rise;
            if over > g.tol {
                // Bare ground steeper than the repose: the snow slides on, in equal shares
                // to every comparison it is steep towards (Fig 6 (b)-(e)).
                let mut steep = [Target::Off; 4];
                let mut count = 0;
                g.relations(mi, k, |t, c, _| {
                    if h - c - g.rise > g.tol {
                        steep[count] = t;
                        count += 1;
                    }
                });
                for &t in &steep[..count] {
                    self.deliver(g, t, amount / count as f64);
                }
            } else if over >= -g.tol
                && let Some(t) = self.conduit(g, node)
            {
                self.counts.conduits += 1;
                self.deliver(g, t, amount);
            } else if over >= -g.tol && amount <= f64::from(small) {
                // At the repose with room further down: a small amount runs down the
                // steepest way to where there is room, as the local rule passes an excess
                // on (merging with what else runs there).
                let (t, _, _) = g.lowest(mi, k);
                self.deliver(g, t, amount);
            } else if let depth = f64::from(g.maps[mi].snow_m[k]) + amount
                && f64::from(kept_depth(g.maps[mi].ground_m[k], low, g.rise, g.tol)) >= depth
            {
                // Room for all of it within the tolerance: it stays (a flood would raise
                // this texel alone).
                g.maps[mi].snow_m[k] = depth as f32;
                self.note_change(node);
            } else {
                self.flood(g, node, amount);
            }
        }
    }

    /// Send `amount` to `target`: off the scene, or to a node's `pending` (queued for the
    /// carry at its height).
    fn deliver(&mut self, g: &Grid, target: Target, amount: f64) {
        match target {
            Target::Off => self.fallen += amount,
            Target::Map(o, nk) => {
                let node = g.node(o as usize, nk as usize);
                self.node[node as usize].pending += amount;
                self.buckets.push(g.surface_at(o as usize, nk as usize), node);
            }
        }
    }

    /// Where a chain of texels at (or over) the repose starting at `node` ends, if it
    /// ends at a sink: each texel's lowest comparison is within the tolerance of its
    /// surface less the rise, so snow arriving anywhere on it cannot stop before the sink
    /// (an edge face, or a roof's held wedge above its eave). `None` when the chain
    /// reaches a texel with room. Memoised for the step.
    fn conduit(&mut self, g: &Grid, node: u32) -> Option<Target> {
        self.path.clear();
        let mut cur = node;
        let end = loop {
            if self.node[cur as usize].memo_step == self.step {
                break self.node[cur as usize].memo;
            }
            self.path.push(cur);
            let (mi, k) = g.split(cur);
            let (t, low, sink) = g.lowest(mi, k);
            if g.surface_at(mi, k) < low + g.rise - g.tol {
                break MEMO_ROOM;
            }
            match (t, sink) {
                (Target::Off, _) => break MEMO_OFF,
                (Target::Map(o, nk), true) => break g.node(o as usize, nk as usize),
                (Target::Map(o, nk), false) => cur = g.node(o as usize, nk as usize),
            }
        };
        for &p in &self.path {
            self.node[p as usize].memo_step = self.step;
            self.node[p as usize].memo = end;
        }
        match end {
            MEMO_ROOM => None,
            MEMO_OFF => Some(Target::Off),
            sink => {
                let (o, nk) = g.split(sink);
                Some(Target::Map(o as u32, nk as u32))
            }
        }
    }

    /// Stage 3: settle `amount` arriving at `source` by water-filling in `key = surface -
    /// apex`, apex = source surface - rise · distance (distance through the texels reached,
    /// so neighbours' apexes differ by at most one rise): the texels below the level τ
    /// are raised to apex + τ. A sink reached first caps τ at its key and takes the rest.
    fn flood(&mut self, g: &mut Grid, source: u32, amount: f64) {
        self.flood = self.flood.wrapping_add(1);
        if self.flood == 0 {
            self.seen.fill(Seen::default());
            self.flood = 1;
        }
        let id = self.flood;
        self.frontier.clear();
        self.wet.clear();
        self.reached.clear();
        self.sinks.clear();
        let top = f64::from(g.surface(source));
        self.seen[source as usize].queued = id;
        self.seen[source as usize].distance = 0;
        self.frontier.push(frontier_entry(0.0, source));
        // The wet texels' keys: their sum and count give the level that holds `amount`.
        let mut wet = (0.0f64, 0usize);
        let level = |(sum, count): (f64, usize)| (amount + sum) / count as f64;
        let level = loop {
            let next = self.frontier.peek().map_or(f64::INFINITY, |&e| f64::from(frontier_key(e)));
            if wet.1 > 0 && level(wet) <= next {
                break level(wet);
            }
            let Some(e) = self.frontier.pop() else { break level(wet) };
            let tag = e as u32;
            if tag & SINK != 0 {
                // The level reaches an edge: it stays there and the rest falls.
                self.dry(&mut wet, |_| next);
                let held = wet.1 as f64 * next - wet.0;
                let target = self.sinks[(tag & !SINK) as usize];
                self.deliver(g, target, (amount - held).max(0.0));
                break next;
            }
            if self.seen[tag as usize].reached != id {
                let key = self.reach(g, tag, id, top);
                wet = (wet.0 + key, wet.1 + 1);
                // Texels the level does not reach stay dry (their neighbours stay queued).
                self.dry(&mut wet, level);
            }
        };
        self.counts.floods += 1;
        self.counts.flooded += self.reached.len() as u64;
        self.counts.largest_flood = self.counts.largest_flood.max(self.reached.len() as u64);
        self.fill(g, level);
    }

    /// The flood reaches `node` (flood `id`, from a source at `top`): recorded as wet with
    /// its key, and its comparisons queued (sinks as such). Returns its key.
    fn reach(&mut self, g: &Grid, node: u32, id: u32, top: f64) -> f64 {
        let rise = f64::from(g.rise);
        self.seen[node as usize].reached = id;
        let d = self.seen[node as usize].distance;
        let apex = top - rise * f64::from(d);
        let (mi, k) = g.split(node);
        let key = f64::from(g.surface_at(mi, k)) - apex;
        let i = self.reached.len() as u32;
        self.reached.push((node, key, apex));
        self.wet.push(u64::from(sortable(key as f32)) << 32 | u64::from(i));
        let below = apex - rise;
        let (frontier, sinks, seen) = (&mut self.frontier, &mut self.sinks, &mut self.seen);
        g.relations(mi, k, |t, c, sink| {
            if sink {
                frontier.push(frontier_entry(f64::from(c) - below, SINK | sinks.len() as u32));
                sinks.push(t);
                return;
            }
            let Target::Map(o, nk) = t else { return };
            let m = g.node(o as usize, nk as usize) as usize;
            let v = &mut seen[m];
            if v.reached == id || (v.queued == id && v.distance <= d + 1) {
                return;
            }
            v.queued = id;
            v.distance = d + 1;
            frontier.push(frontier_entry(f64::from(c) - below, m as u32));
        });
        key
    }

    /// Leave dry, highest key first, the wet texels whose key is at or over `level` of
    /// the rest (`wet`: the sum and count of the wet keys).
    fn dry(&mut self, wet: &mut (f64, usize), level: impl Fn((f64, usize)) -> f64) {
        while let Some(&w) = self.wet.peek() {
            let key = self.reached[(w as u32) as usize].1;
            if key < level(*wet) {
                break;
            }
            self.wet.pop();
            *wet = (wet.0 - key, wet.1 - 1);
        }
    }

    /// Raise the flood's wet texels to apex + `level`.
    fn fill(&mut self, g: &mut Grid, level: f64) {
        for idx in 0..self.wet.len() {
            let (node, _, apex) = self.reached[(self.wet.as_slice()[idx] as u32) as usize];
            let (mi, k) = g.split(node);
            let m = &mut g.maps[mi];
            let depth = (apex + level - f64::from(m.ground_m[k])) as f32;
            if depth > m.snow_m[k] {
                m.snow_m[k] = depth;
                self.node[node as usize].memo_step = 0;
                self.note_change(node);
            }
        }
    }
}
