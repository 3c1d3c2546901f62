//! Small, fast motion on top of the artist's shape: folds, curls, drifting rays, ends
//! that thin out, and the flickering and pulsating regimes (`[aurora.small_scale]`; an
//! extension, not in the thesis: the sky view's `paper` mode ignores it).
//!
//! The thesis gives the large form: particles held near the drawn sheets by the field of
//! charges placed on them (§2.2-2.3). Real curtains add, at smaller scales and shorter
//! times (Hallinan & Davis 1970; Nishimura et al. 2020):
//! - **folds**, 20-30 km, moving slowly along the arc: a travelling wave of the sheet's
//!   normal offset;
//! - **curls**, 2-10 km across, living under a second, moving at a few to tens of km/s:
//!   the saturated Kelvin-Helmholtz (diocotron) roll-up of a thin sheet in shear is a
//!   chain of vortices that winds the sheet into loops. Here each point of the sheet
//!   moves on a circle of radius A as the wave passes (a trochoid: along-sheet
//!   A cos θ, normal A sin θ, θ = 2π(s − c t)/λ), which makes loops where 2πA/λ > 1;
//!   each wavelength of the chain grows and decays over its lifetime;
//! - **rays**: field-aligned brightenings about a kilometre wide drifting along the sheet;
//! - **ends**: the brightness fades over `end_taper_km` to each end of a sheet;
//! - **flickering** (a regime): patches a few km across whose brightness oscillates at
//!   7-13 Hz, each at its own frequency and phase;
//! - **pulsating** (a regime): diffuse patches tens of km across switching on and off,
//!   each with its own period of 2-20 s and phase, over a dim background.
//!
//! What is derived and what is not: none of these come out of the thesis's particle
//! dynamics. Its field is that of charges placed on the *target* shape, not of the
//! particles themselves, so a sheet cannot become unstable and roll up in it (the
//! diocotron instability needs the sheet's own charge in a self-consistent field, a
//! Poisson solve of the particles every step), and flicker and pulsation are set by
//! waves far above the simulated plane (Alfvén waves; chorus waves at the equator). They
//! are kinematic models with observed scales as parameters (km, km/s, s, Hz): each
//! particle's foot is displaced and its brightness scaled at render time, as a pure
//! function of its position, the sheet it is near, the time and the seed, so the
//! simulation state, checkpoints and the thesis's motion are untouched. Test
//! `curls_are_measured_at_their_parameters` measures wavelength, speed and size from the
//! displaced particles; the scene tests measure flicker and pulsation from frames.

use glam::Vec2;
use phenomena_core::rng::{Purpose, Stream};
use phenomena_core::validate::Issues;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wide::f32x8;

use crate::field::SegmentBuckets;
use crate::shape::Shape;

const SITES: Purpose = Purpose::named("aurora.small_scale.sites");

/// Most patch sites a frame works out ahead ([`PatchField`]).
const MAX_PATCH_TABLE: usize = 512 * 512;

/// Folds: a travelling wave of the sheet's normal offset.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Folds {
    /// Normal offset amplitude, km (0: none).
    pub amplitude_km: f32,
    /// Wavelength along the sheet, km (observed 20-30).
    pub wavelength_km: f32,
    /// Speed along the sheet, km/s (folds are slow: about 1-5).
    pub speed_km_s: f32,
}

impl Default for Folds {
    fn default() -> Self {
        Self { amplitude_km: 2.0, wavelength_km: 25.0, speed_km_s: 2.0 }
    }
}

/// Curls: a chain of vortices that winds the sheet into loops, each wavelength growing
/// and decaying over its lifetime.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Curls {
    /// Radius of the circle each sheet point moves on at a curl's peak, km (0: none;
    /// loops form above wavelength / 2π: the defaults, 3 km at 8 km, make loops about
    /// 2.5 km along the sheet and 4.5 km across it).
    pub amplitude_km: f32,
    /// Spacing of the curls along the sheet, km (observed 2-10 km across).
    pub wavelength_km: f32,
    /// Speed along the sheet, km/s (observed a few to tens).
    pub speed_km_s: f32,
    /// Lifetime of one curl, s (observed under a second).
    pub lifetime_s: f32,
    /// Chance that a curl site is alive in a given lifetime-and-a-half window (0-1).
    pub share: f32,
}

impl Default for Curls {
    fn default() -> Self {
        Self { amplitude_km: 3.0, wavelength_km: 8.0, speed_km_s: 8.0, lifetime_s: 0.8, share: 0.6 }
    }
}

/// Rays: narrow brightenings drifting along the sheet.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Rays {
    /// Share of the brightness that gathers into rays (0: none, 1: all of it); the mean
    /// brightness along the sheet is kept.
    pub contrast: f32,
    /// Mean spacing of rays along the sheet, km.
    pub spacing_km: f32,
    /// Ray width (Gaussian σ), km.
    pub width_km: f32,
    /// Drift speed along the sheet, km/s.
    pub speed_km_s: f32,
}

impl Default for Rays {
    fn default() -> Self {
        Self { contrast: 0.5, spacing_km: 4.0, width_km: 0.6, speed_km_s: 3.0 }
    }
}

/// Flickering aurora: patches whose brightness oscillates, each at its own frequency.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Flicker {
    /// Switch the regime on.
    pub enabled: bool,
    /// Patch diameter, km (observed a few km).
    pub size_km: f32,
    /// Spacing of patch sites (a jittered grid over the plane), km.
    pub spacing_km: f32,
    /// Share of the sites that flicker (0-1).
    pub share: f32,
    /// Each patch's frequency is drawn uniformly from this range, Hz (observed 7-13,
    /// typically ~10).
    pub frequency_hz: [f32; 2],
    /// Modulation depth at a patch's centre (0-1): brightness × (1 + depth sin ωt).
    pub depth: f32,
}

impl Default for Flicker {
    fn default() -> Self {
        Self {
            enabled: false,
            size_km: 4.0,
            spacing_km: 6.0,
            share: 0.7,
            frequency_hz: [8.0, 12.0],
            depth: 0.9,
        }
    }
}

/// Pulsating aurora: diffuse patches switching on and off, each with its own period.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Pulsating {
    /// Switch the regime on.
    pub enabled: bool,
    /// Patch diameter, km (observed tens to hundreds).
    pub size_km: f32,
    /// Spacing of patch sites (a jittered grid over the plane), km.
    pub spacing_km: f32,
    /// Share of the sites that hold a patch (0-1).
    pub share: f32,
    /// Each patch's period is drawn log-uniformly from this range, s (observed 2-20).
    pub period_s: [f32; 2],
    /// Share of each period a patch is on (0-1).
    pub on_fraction: f32,
    /// Time to switch on or off, s.
    pub edge_s: f32,
    /// Brightness outside patches and of a patch that is off, relative to on (0-1).
    pub background: f32,
}

impl Default for Pulsating {
    fn default() -> Self {
        Self {
            enabled: false,
            size_km: 40.0,
            spacing_km: 50.0,
            share: 0.8,
            period_s: [3.0, 15.0],
            on_fraction: 0.4,
            edge_s: 0.3,
            background: 0.15,
        }
    }
}

/// `[aurora.small_scale]`: see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SmallScale {
    /// Apply any of it (false: the particles are drawn where the simulation puts them,
    /// all equally bright, as in the thesis).
    pub enabled: bool,
    /// Folds.
    pub folds: Folds,
    /// Curls.
    pub curls: Curls,
    /// Rays.
    pub rays: Rays,
    /// Brightness fades over this length to each end of a sheet, km (0: hard ends).
    pub end_taper_km: f32,
    /// Particles farther than this from every sheet are drawn as they are, km.
    pub reach_km: f32,
    /// The flickering regime.
    pub flicker: Flicker,
    /// The pulsating regime.
    pub pulsating: Pulsating,
}

impl Default for SmallScale {
    fn default() -> Self {
        Self {
            enabled: true,
            folds: Folds::default(),
            curls: Curls::default(),
            rays: Rays::default(),
            end_taper_km: 20.0,
            reach_km: 15.0,
            flicker: Flicker::default(),
            pulsating: Pulsating::default(),
        }
    }
}

impl SmallScale {
    /// Every problem, with fields relative to `[aurora.small_scale]`.
    pub fn validate(&self, i: &mut Issues, prefix: &str) {
        let f = |name: &str| format!("{prefix}.{name}");
        i.range(&f("folds.amplitude_km"), self.folds.amplitude_km, 0.0..=100.0);
        i.range(&f("folds.wavelength_km"), self.folds.wavelength_km, 0.1..=10_000.0);
        i.range(&f("folds.speed_km_s"), self.folds.speed_km_s, -1000.0..=1000.0);
        i.range(&f("curls.amplitude_km"), self.curls.amplitude_km, 0.0..=100.0);
        i.range(&f("curls.wavelength_km"), self.curls.wavelength_km, 0.1..=10_000.0);
        i.range(&f("curls.speed_km_s"), self.curls.speed_km_s, -1000.0..=1000.0);
        i.range(&f("curls.lifetime_s"), self.curls.lifetime_s, 0.01..=1e6);
        i.range(&f("curls.share"), self.curls.share, 0.0..=1.0);
        i.range(&f("rays.contrast"), self.rays.contrast, 0.0..=1.0);
        i.range(&f("rays.spacing_km"), self.rays.spacing_km, 0.1..=10_000.0);
        i.range(&f("rays.width_km"), self.rays.width_km, 0.01..=f64::from(self.rays.spacing_km.max(0.01)));
        i.range(&f("rays.speed_km_s"), self.rays.speed_km_s, -1000.0..=1000.0);
        i.range(&f("end_taper_km"), self.end_taper_km, 0.0..=10_000.0);
        i.range(&f("reach_km"), self.reach_km, 0.1..=10_000.0);
        let fl = &self.flicker;
        i.range(&f("flicker.spacing_km"), fl.spacing_km, 0.1..=10_000.0);
        i.range(&f("flicker.size_km"), fl.size_km, 0.01..=f64::from(fl.spacing_km.max(0.1)) * 2.0);
        i.range(&f("flicker.share"), fl.share, 0.0..=1.0);
        i.range(&f("flicker.depth"), fl.depth, 0.0..=1.0);
        range_pair(i, &f("flicker.frequency_hz"), fl.frequency_hz, 0.001..=1000.0);
        let p = &self.pulsating;
        i.range(&f("pulsating.spacing_km"), p.spacing_km, 0.1..=10_000.0);
        i.range(&f("pulsating.size_km"), p.size_km, 0.01..=f64::from(p.spacing_km.max(0.1)) * 2.0);
        i.range(&f("pulsating.share"), p.share, 0.0..=1.0);
        range_pair(i, &f("pulsating.period_s"), p.period_s, 0.01..=1e6);
        i.range(&f("pulsating.on_fraction"), p.on_fraction, 0.01..=0.99);
        i.range(&f("pulsating.background"), p.background, 0.0..=1.0);
        let shortest = f64::from(p.period_s[0].min(p.period_s[1]).max(0.0));
        let on = shortest * f64::from(p.on_fraction.clamp(0.0, 1.0));
        i.range(&f("pulsating.edge_s"), p.edge_s, 0.0..=(on * 0.5).max(0.0));
    }

    /// The displacements and brightness factors at `time_s` for the sheets of `shape`
    /// (the current shape, in plane km), or `None` when nothing applies.
    pub fn at(&self, shape: &Shape, time_s: f64, seed: u64) -> Option<Prepared> {
        self.enabled.then(|| self.prepare(shape, time_s, seed))
    }
}

fn range_pair(i: &mut Issues, field: &str, v: [f32; 2], range: std::ops::RangeInclusive<f64>) {
    i.range(&format!("{field}[0]"), v[0], range.clone());
    i.range(&format!("{field}[1]"), v[1], range);
    if v[0] > v[1] {
        i.push(field, format!("{v:?}"), "a range [low, high] with low <= high");
    }
}

/// Where a point lies relative to the nearest sheet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SheetPlace {
    /// Arc length along the drawn sheet, km: from the sheet's first point, continued
    /// across the pieces a split leaves (in the order of their points), so the waves on
    /// a sheet run on unbroken where it splits.
    pub s_km: f32,
    /// Signed distance from the sheet (positive to the left of its direction), km.
    pub n_km: f32,
    /// Distance from the nearest point of the sheet, km.
    pub distance_km: f32,
    /// Arc length from this piece's first point, km.
    pub from_head_km: f32,
    /// Arc length to this piece's last point, km.
    pub to_tail_km: f32,
    /// Distance from this piece's first point to the nearest end of another piece, km
    /// (infinite when there is none): a split's or merge's ends touch, free ends do not.
    pub head_gap_km: f32,
    /// The same for its last point.
    pub tail_gap_km: f32,
    /// The drawn sheet it belongs to.
    pub sheet: u32,
    /// Which piece (chain of linked points) it is.
    pub chain: u32,
    /// Unit tangent along the sheet.
    pub tangent: Vec2,
}

/// One segment of a chain: start, unit direction, length, arc length at its start
/// within its chain.
#[derive(Clone, Copy, Debug)]
struct Segment {
    a: Vec2,
    dir: Vec2,
    len: f32,
    s0: f32,
    chain: u32,
}

/// A chain of linked points: its sheet, where its arc length starts along the sheet,
/// its length and the gaps at its ends.
#[derive(Clone, Copy, Debug)]
struct Chain {
    sheet: u32,
    s_offset: f32,
    length: f32,
    head_gap: f32,
    tail_gap: f32,
}

/// The sheets' segments with their arc lengths, bucketed for nearest-segment queries.
#[derive(Clone, Debug)]
struct SheetIndex {
    segments: Vec<Segment>,
    chains: Vec<Chain>,
    buckets: SegmentBuckets,
    /// The bucketed segments' starts, directions and lengths in the buckets' order
    /// ([`SegmentBuckets::items`]), eight lanes at a time, padded by seven.
    lanes: ItemLanes,
    reach: f32,
}

/// [`SheetIndex::lanes`]: one entry per bucket item, then [`LANES`] − 1 of padding.
#[derive(Clone, Debug, Default)]
struct ItemLanes {
    ax: Vec<f32>,
    ay: Vec<f32>,
    dx: Vec<f32>,
    dy: Vec<f32>,
    len: Vec<f32>,
}

/// Candidates tested at once by [`SheetIndex::place`].
const LANES: usize = 8;

impl ItemLanes {
    fn new(items: &[u32], segments: &[Segment]) -> Self {
        let mut lanes = Self::default();
        for g in items.iter().map(|&k| &segments[k as usize]) {
            lanes.ax.push(g.a.x);
            lanes.ay.push(g.a.y);
            lanes.dx.push(g.dir.x);
            lanes.dy.push(g.dir.y);
            lanes.len.push(g.len);
        }
        for v in [&mut lanes.ax, &mut lanes.ay, &mut lanes.dx, &mut lanes.dy, &mut lanes.len] {
            v.resize(v.len() + LANES - 1, 0.0);
        }
        lanes
    }

    /// Eight lanes of `v` from `at`.
    #[inline]
    fn load(v: &[f32], at: usize) -> f32x8 {
        f32x8::from(<[f32; LANES]>::try_from(&v[at..at + LANES]).expect("padded"))
    }
}

/// Most bucket cells along one side of a [`SheetIndex`].
const MAX_INDEX_CELLS: f32 = 1024.0;

impl SheetIndex {
    fn new(shape: &Shape, reach: f32) -> Self {
        let (segments, chains) = Self::chains(shape);
        let (lo, hi) = segments.iter().fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), g| {
            let b = g.a + g.dir * g.len;
            (lo.min(g.a).min(b), hi.max(g.a).max(b))
        });
        let (origin, extent) =
            if segments.is_empty() { (Vec2::ZERO, Vec2::ZERO) } else { (lo - reach, hi - lo + 2.0 * reach) };
        // Cells of the reach, or coarser for a small reach over large sheets.
        let cell = reach.max(extent.max_element() / MAX_INDEX_CELLS).max(1e-3);
        let span = extent / cell;
        let (nx, nz) = (span.x as usize + 1, span.y as usize + 1);
        let ends = segments.iter().map(|g| (g.a, g.a + g.dir * g.len));
        let buckets = SegmentBuckets::new(ends, reach, origin, cell, (nx, nz));
        let lanes = ItemLanes::new(buckets.items(), &segments);
        Self { segments, chains, buckets, lanes, reach }
    }

    /// The segments and chains of `shape`: chains followed from their heads (open
    /// chains) then from whatever is left (closed loops), in point order; each sheet's
    /// chains continue its arc length in the order of their first points.
    fn chains(shape: &Shape) -> (Vec<Segment>, Vec<Chain>) {
        let n = shape.points.len();
        let mut has_prev = vec![false; n];
        for &j in shape.next.iter().flatten() {
            if let Some(h) = has_prev.get_mut(j as usize) {
                *h = true;
            }
        }
        let mut segments = Vec::new();
        // (sheet, index of the head in its sheet, length, head point, tail point)
        let mut found: Vec<(u32, u32, f32, Vec2, Vec2)> = Vec::new();
        let mut visited = vec![false; n];
        for head in (0..n).filter(|&i| !has_prev[i]).chain(0..n) {
            if visited[head] || shape.next[head].is_none() {
                continue;
            }
            let chain = found.len() as u32;
            let (mut i, mut s) = (head, 0.0f32);
            while !visited[i] {
                visited[i] = true;
                let Some(j) = shape.next[i].map(|j| j as usize).filter(|&j| j < n) else { break };
                let (a, b) = (shape.points[i], shape.points[j]);
                let len = a.distance(b);
                if len > 0.0 {
                    segments.push(Segment { a, dir: (b - a) / len, len, s0: s, chain });
                }
                s += len;
                i = j;
            }
            let sheet = shape.sheet.get(head).copied().unwrap_or(chain);
            let order = shape.index_in_sheet.get(head).copied().unwrap_or(0);
            found.push((sheet, order, s, shape.points[head], shape.points[i]));
        }
        let ends: Vec<(usize, Vec2)> =
            found.iter().enumerate().flat_map(|(c, f)| [(c, f.3), (c, f.4)]).collect();
        let gap = |c: usize, p: Vec2| {
            ends.iter().filter(|(o, _)| *o != c).map(|(_, q)| p.distance(*q)).fold(f32::INFINITY, f32::min)
        };
        let chains = found
            .iter()
            .enumerate()
            .map(|(c, &(sheet, order, length, head, tail))| {
                let s_offset = found.iter().filter(|o| o.0 == sheet && o.1 < order).map(|o| o.2).sum::<f32>();
                Chain { sheet, s_offset, length, head_gap: gap(c, head), tail_gap: gap(c, tail) }
            })
            .collect();
        (segments, chains)
    }

    /// The nearest sheet within reach of `p`.
    fn place(&self, p: Vec2) -> Option<SheetPlace> {
        if self.segments.is_empty() || !p.is_finite() {
            return None;
        }
        // The nearest segment within reach (the first of equals): its distance², index,
        // foot parameter and offset from its start.
        let mut best: Option<(f32, u32, f32, Vec2)> = None;
        let reach2 = self.reach * self.reach;
        let range = self.buckets.near_range(p);
        let items = self.buckets.items();
        let l = &self.lanes;
        let (px, py) = (f32x8::splat(p.x), f32x8::splat(p.y));
        // Eight candidates at a time, each lane with the scalar operations of
        // `place_scalar` (the same bits: test `lanes_find_the_scalar_place`), then
        // taken in order.
        for at in range.clone().step_by(LANES) {
            let (dx, dy) = (px - ItemLanes::load(&l.ax, at), py - ItemLanes::load(&l.ay, at));
            let (ux, uy) = (ItemLanes::load(&l.dx, at), ItemLanes::load(&l.dy, at));
            // `clamp(0, len)` as max then min: the same value for finite numbers (a
            // dot product of −0 becomes +0, which changes no sum it enters).
            let t = (dx * ux + dy * uy).max(f32x8::ZERO).min(ItemLanes::load(&l.len, at));
            let (ex, ey) = (dx - ux * t, dy - uy * t);
            let dist2 = (ex * ex + ey * ey).to_array();
            let (t, dx, dy) = (t.to_array(), dx.to_array(), dy.to_array());
            for j in 0..(range.end - at).min(LANES) {
                if dist2[j] <= reach2 && best.is_none_or(|(b, ..)| dist2[j] < b) {
                    best = Some((dist2[j], items[at + j], t[j], Vec2::new(dx[j], dy[j])));
                }
            }
        }
        let (dist2, k, t, d) = best?;
        let g = &self.segments[k as usize];
        let chain = &self.chains[g.chain as usize];
        Some(SheetPlace {
            s_km: chain.s_offset + g.s0 + t,
            n_km: g.dir.perp_dot(d),
            distance_km: dist2.sqrt(),
            from_head_km: g.s0 + t,
            to_tail_km: (chain.length - g.s0 - t).max(0.0),
            head_gap_km: chain.head_gap,
            tail_gap_km: chain.tail_gap,
            sheet: chain.sheet,
            chain: g.chain,
            tangent: g.dir,
        })
    }

    /// [`SheetIndex::place`]'s nearest segment found one candidate at a time: its
    /// distance², number, foot parameter and offset (what the lanes must reproduce).
    #[cfg(test)]
    fn place_scalar(&self, p: Vec2) -> Option<(f32, u32, f32, Vec2)> {
        let mut best: Option<(f32, u32, f32, Vec2)> = None;
        for &k in self.buckets.near(p) {
            let g = &self.segments[k as usize];
            let d = p - g.a;
            let t = d.dot(g.dir).clamp(0.0, g.len);
            let dist2 = (d - g.dir * t).length_squared();
            if dist2 <= self.reach * self.reach && best.is_none_or(|(b, ..)| dist2 < b) {
                best = Some((dist2, k, t, d));
            }
        }
        best
    }
}

/// [`SmallScale`] made ready for one moment: see [`Prepared::apply`]. Everything that
/// depends only on a site and the time (a curl's life, a ray's place, a patch's shape
/// and phase) is worked out once here, so a particle costs a few table look-ups.
#[derive(Clone, Debug)]
pub struct Prepared {
    params: SmallScale,
    sheets: SheetIndex,
    time_s: f64,
    chains: Vec<ChainNow>,
    /// Each chain's displacement and ray factor sampled along it ([`ChainTable`]), or
    /// none (worked out per particle) past [`MAX_TABLE_SAMPLES`].
    tables: Vec<ChainTable>,
    flicker: Option<PatchField>,
    pulsating: Option<PatchField>,
}

/// A travelling pattern's position now: the pattern's σ = s/λ − v t/λ is taken as
/// σ' − `whole` with σ' = s/λ − `frac`, `whole` + `frac` = v t/λ worked out in f64, so
/// σ' stays small and exact in f32 however long the scene runs.
#[derive(Clone, Copy, Debug, Default)]
struct Travel {
    whole: i64,
    frac: f32,
}

impl Travel {
    fn new(speed_km_s: f32, wavelength_km: f32, time_s: f64) -> Self {
        let moved = f64::from(speed_km_s) * time_s / f64::from(wavelength_km);
        let whole = moved.floor();
        Self { whole: whole as i64, frac: (moved - whole) as f32 }
    }

    /// σ' at arc length `s_km`.
    fn local(&self, s_km: f32, wavelength_km: f32) -> f32 {
        s_km / wavelength_km - self.frac
    }
}

/// One chain's sites now.
#[derive(Clone, Debug, Default)]
struct ChainNow {
    /// The folds' phase offset, radians.
    fold_phase: f32,
    folds: Travel,
    curls: Travel,
    /// Local curl site (⌊σ' + ¼⌋) of `curl_life[0]`.
    curl_first: i64,
    /// Each curl site's life envelope now (0-1).
    curl_life: Vec<f32>,
    rays: Travel,
    /// Local ray site (⌊σ'⌋) of `ray_sites[0]`.
    ray_first: i64,
    /// Each ray's centre (in local spacings) and strength.
    ray_sites: Vec<(f32, f32)>,
}

/// Widths beyond which a ray's Gaussian is left out of [`Prepared::rays`]: each term
/// left out is under e⁻¹⁸ ≈ 1.5·10⁻⁸ of a ray's peak (times its strength, < 1.5), so
/// the factor moves by under contrast · (2·reach + 1) · 1.5 e⁻¹⁸ / (w √(2π)) (test
/// `rays_cut_at_six_widths_move_by_less_than_the_terms_left_out`), and the `expf`s of
/// the farther sites are not worked out: at the default width 3.2 of the five a
/// particle on average, a third of them underflowing, which is slow (counted over the
/// sites' layout: the nearest centre within 0.9 spacings, the others jittered by ±0.4).
const RAY_CUT_WIDTHS: f32 = 6.0;

/// Samples of a [`ChainTable`] per length scale of the finest pattern on the sheet (the
/// folds' and curls' wavelength / 2π, the rays' width). Linear interpolation between
/// samples `step` apart misses a function by at most step²/8 · max|f''|, and each
/// pattern's |f''| is a small multiple of its amplitude / scale² (test
/// `tables_follow_the_direct_evaluation` derives each bound and checks it): here about
/// 1/(8 · 24²) ≈ 2·10⁻⁴ of an amplitude a multiple. At the defaults the step is 25 m
/// (the rays' 0.6 km width / 24): each component of a drawn position moves by under
/// 0.4 m and the ray factor by under 1.4·10⁻³.
const TABLE_SAMPLES_PER_SCALE: f32 = 24.0;
/// Most samples in all of a frame's tables (3 MiB; about 25 ms of CPU to build at
/// scene 5's rate, as much as some 250,000 particles worked out one by one): sheets
/// that would need more (over 6,500 km at the defaults, or rays much narrower than the
/// default) are worked out per particle instead, as exactly as without tables.
const MAX_TABLE_SAMPLES: usize = 1 << 18;

/// One chain's displacement (along, normal; km) and ray factor at arc lengths
/// `i · step` from its head, read back by linear interpolation: a particle costs two
/// look-ups instead of the patterns' sines, cosines and Gaussians. Thesis scenes 1, 2
/// and 5 have 7-16 particles a sample (scene 2 at frame 100: 127,161 particles, 12,809
/// samples over 320 km of sheet), and a sample costs what a particle did.
#[derive(Clone, Debug)]
struct ChainTable {
    inv_step: f32,
    values: Vec<[f32; 3]>,
}

impl ChainTable {
    /// Samples over a chain `length_km` long at `step_km` apart: both ends covered, at
    /// least two (saturating for a length no table could hold).
    fn samples(length_km: f32, step_km: f32) -> usize {
        ((length_km / step_km).ceil() as usize).saturating_add(1).max(2)
    }

    /// The values at `from_head_km` along the chain (clamped to the samples).
    #[inline]
    fn at(&self, from_head_km: f32) -> [f32; 3] {
        let x = (from_head_km * self.inv_step).max(0.0);
        let i = (x as usize).min(self.values.len() - 2);
        let t = (x - i as f32).min(1.0);
        let (a, b) = (self.values[i], self.values[i + 1]);
        std::array::from_fn(|k| a[k] + (b[k] - a[k]) * t)
    }
}

/// Uniform in [0, 1) for a site: the same for the same (seed, kind, a, b, c).
fn site_random(seed: u64, kind: u64, a: i64, b: i64, c: u64) -> f32 {
    let key = (a as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
        ^ (b as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
        ^ c.wrapping_mul(0x1656_67b1_9e37_79f9)
        ^ kind;
    Stream::new(seed, SITES, key).next_f32()
}

/// Brightness factor `from_end` km from a piece's end whose nearest other piece's end
/// is `gap` km away: a free end fades over `taper` km; an end that meets another piece
/// (a split just opening, a merge) does not, and the fade grows in as the gap opens to
/// two tapers.
fn end_fade(from_end: f32, gap: f32, taper: f32) -> f32 {
    let length = taper * smoothstep(0.0, 2.0 * taper, gap);
    if length <= 1e-3 { 1.0 } else { smoothstep(0.0, length, from_end) }
}

/// Smooth step from 0 at `e0` to 1 at `e1`.
fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl SmallScale {
    fn prepare(&self, shape: &Shape, time_s: f64, seed: u64) -> Prepared {
        let sheets = SheetIndex::new(shape, self.reach_km);
        let chains = sheets.chains.iter().map(|c| self.chain_now(c, time_s, seed)).collect();
        let (lo, hi) = shape.bounds();
        let margin = Vec2::splat(self.reach_km);
        let bounds = (lo - margin, hi + margin);
        let f = &self.flicker;
        let flicker = f.enabled.then(|| {
            PatchField::new(PatchKind::Flicker(*f), f.spacing_km, f.size_km, f.share, bounds, time_s, seed)
        });
        let p = &self.pulsating;
        let pulsating = p.enabled.then(|| {
            PatchField::new(PatchKind::Pulsating(*p), p.spacing_km, p.size_km, p.share, bounds, time_s, seed)
        });
        let mut prepared =
            Prepared { params: *self, sheets, time_s, chains, flicker, pulsating, tables: Vec::new() };
        let step = self.table_step();
        let samples = prepared.sheets.chains.iter().map(|c| ChainTable::samples(c.length, step));
        if samples.fold(0, usize::saturating_add) <= MAX_TABLE_SAMPLES {
            prepared.tables = (0..prepared.chains.len()).map(|k| prepared.table(k, step)).collect();
        }
        prepared
    }

    /// The spacing, km, of the [`ChainTable`]s' samples: [`TABLE_SAMPLES_PER_SCALE`] a
    /// length scale of the finest pattern on (folds' and curls' wavelength / 2π, the
    /// rays' width); 1 km with none on (every sample the same).
    fn table_step(&self) -> f32 {
        use std::f32::consts::TAU;
        let mut scale = f32::INFINITY;
        if self.folds.amplitude_km > 0.0 {
            scale = scale.min(self.folds.wavelength_km / TAU);
        }
        if self.curls.amplitude_km > 0.0 && self.curls.share > 0.0 {
            scale = scale.min(self.curls.wavelength_km / TAU);
        }
        if self.rays.contrast > 0.0 {
            scale = scale.min(self.rays.width_km);
        }
        let step = scale / TABLE_SAMPLES_PER_SCALE;
        if step.is_finite() && step > 0.0 { step } else { 1.0 }
    }

    /// Chain `chain`'s sites at `time_s`: its random numbers keyed by its sheet and
    /// the sites' places along the sheet, so the pieces of a split sheet keep theirs.
    fn chain_now(&self, chain: &Chain, time_s: f64, seed: u64) -> ChainNow {
        let sheet = i64::from(chain.sheet);
        let (from, to) = (chain.s_offset, chain.s_offset + chain.length);
        let f = &self.folds;
        let mut now = ChainNow {
            fold_phase: site_random(seed, 1, sheet, 0, 0) * std::f32::consts::TAU,
            folds: Travel::new(f.speed_km_s, f.wavelength_km, time_s),
            ..ChainNow::default()
        };
        let c = &self.curls;
        if c.amplitude_km > 0.0 && c.share > 0.0 {
            // Sites are centred on the wave's crests (θ = π/2, σ = j + ¼), where a
            // trochoid loops; site j lives in window k (1.5 lifetimes long, its own
            // offset) with chance `share`, as sin² over one lifetime.
            now.curls = Travel::new(c.speed_km_s, c.wavelength_km, time_s);
            let site = |s: f32| (now.curls.local(s, c.wavelength_km) + 0.25).floor() as i64;
            now.curl_first = site(from);
            let window = 1.5 * f64::from(c.lifetime_s);
            now.curl_life = (now.curl_first..=site(to))
                .map(|local| {
                    let j = local - now.curls.whole;
                    let u = time_s / window + f64::from(site_random(seed, 2, j, sheet, 0));
                    let k = u.floor();
                    let life = ((u - k) * 1.5) as f32;
                    if site_random(seed, 3, j, sheet, k as i64 as u64) >= c.share || life >= 1.0 {
                        0.0
                    } else {
                        (std::f32::consts::PI * life).sin().powi(2)
                    }
                })
                .collect();
        }
        let r = &self.rays;
        if r.contrast > 0.0 {
            now.rays = Travel::new(r.speed_km_s, r.spacing_km, time_s);
            let reach = (3.0 * r.width_km / r.spacing_km).ceil() as i64 + 1;
            let site = |s: f32| now.rays.local(s, r.spacing_km).floor() as i64;
            now.ray_first = site(from) - reach;
            now.ray_sites = (now.ray_first..=site(to) + reach)
                .map(|local| {
                    let j = local - now.rays.whole;
                    let centre = local as f32 + 0.5 + 0.8 * (site_random(seed, 4, j, sheet, 0) - 0.5);
                    (centre, 0.5 + site_random(seed, 5, j, sheet, 0))
                })
                .collect();
        }
        now
    }
}

/// Which regime a patch field is and its parameters.
#[derive(Clone, Copy, Debug)]
enum PatchKind {
    Flicker(Flicker),
    Pulsating(Pulsating),
}

impl PatchKind {
    fn key(&self) -> u64 {
        match self {
            Self::Flicker(_) => 6,
            Self::Pulsating(_) => 7,
        }
    }

    /// A patch's value now from its two random numbers: the flicker's sin ωt (−1 to 1)
    /// or the pulsation's on-ness (0 to 1).
    fn value(&self, h0: f32, h1: f32, t: f64) -> f32 {
        match self {
            Self::Flicker(f) => {
                let hz = f64::from(f.frequency_hz[0] + (f.frequency_hz[1] - f.frequency_hz[0]) * h0);
                (std::f64::consts::TAU * (hz * t + f64::from(h1))).sin() as f32
            }
            Self::Pulsating(p) => {
                let (lo, hi) = (f64::from(p.period_s[0]), f64::from(p.period_s[1]));
                let period = lo * (hi / lo).powf(f64::from(h0));
                let u = (t / period + f64::from(h1)).fract() as f32;
                let edge = (f64::from(p.edge_s) / period) as f32;
                if u >= p.on_fraction {
                    0.0
                } else if edge > 0.0 {
                    smoothstep(0.0, edge, u.min(p.on_fraction - u))
                } else {
                    1.0
                }
            }
        }
    }
}

/// One patch: an ellipse about `size` across around `centre` (in spacings), and its
/// value now.
#[derive(Clone, Copy, Debug, Default)]
struct Patch {
    present: bool,
    centre: Vec2,
    cos: f32,
    sin: f32,
    /// Semi-axes, spacings.
    a: f32,
    b: f32,
    value: f32,
}

/// The patches of a jittered grid of sites, worked out over the shape's neighbourhood
/// (sites outside are worked out when asked for).
#[derive(Clone, Debug)]
struct PatchField {
    kind: PatchKind,
    spacing: f32,
    radius: f32,
    share: f32,
    span: i64,
    first: (i64, i64),
    nx: usize,
    nz: usize,
    patches: Vec<Patch>,
    time_s: f64,
    seed: u64,
}

impl PatchField {
    fn new(
        kind: PatchKind,
        spacing: f32,
        size: f32,
        share: f32,
        bounds: (Vec2, Vec2),
        time_s: f64,
        seed: u64,
    ) -> Self {
        let radius = 0.5 * size / spacing;
        let span = (radius + 0.5).ceil() as i64;
        let lo = (bounds.0 / spacing).floor();
        let hi = (bounds.1 / spacing).floor();
        let first = (lo.x as i64 - span, lo.y as i64 - span);
        let nx = ((hi.x - lo.x) as i64 + 2 * span + 1).clamp(1, 1 << 16) as usize;
        let nz = ((hi.y - lo.y) as i64 + 2 * span + 1).clamp(1, 1 << 16) as usize;
        let mut field =
            Self { kind, spacing, radius, share, span, first, nx, nz, patches: Vec::new(), time_s, seed };
        // Sites are worked out ahead only while the table stays small (512² sites, 8 MiB);
        // patches much smaller than the shape are worked out when asked for.
        if nx * nz <= MAX_PATCH_TABLE {
            field.patches = (0..nx * nz)
                .map(|k| field.compute(first.0 + (k % nx) as i64, first.1 + (k / nx) as i64))
                .collect();
        } else {
            (field.nx, field.nz) = (0, 0);
        }
        field
    }

    /// Site (i, j)'s patch, from its random numbers.
    fn compute(&self, i: i64, j: i64) -> Patch {
        let h = [0u64, 1, 2, 3, 4, 5, 6].map(|c| site_random(self.seed, self.kind.key(), i, j, c));
        if h[2] >= self.share {
            return Patch::default();
        }
        let (sin, cos) = (std::f32::consts::PI * h[5]).sin_cos();
        // Axes radius × s and radius / s, s in 1 ± 0.3 by the site's seventh number.
        let stretch = 1.0 + 0.6 * (h[6] - 0.5);
        Patch {
            present: true,
            centre: Vec2::new(i as f32 + 0.5 + 0.6 * (h[3] - 0.5), j as f32 + 0.5 + 0.6 * (h[4] - 0.5)),
            cos,
            sin,
            a: self.radius * stretch,
            b: self.radius / stretch,
            value: self.kind.value(h[0], h[1], self.time_s),
        }
    }

    /// Each patch covering `p` (plane km): its value now and its profile at `p` (1
    /// inside, falling to 0 over the outer 30 % of its radius).
    fn each(&self, p: Vec2, mut f: impl FnMut(f32, f32)) {
        let q = p / self.spacing;
        let (i0, j0) = (q.x.floor() as i64, q.y.floor() as i64);
        for j in j0 - self.span..=j0 + self.span {
            for i in i0 - self.span..=i0 + self.span {
                let (di, dj) = (i - self.first.0, j - self.first.1);
                let patch = if (0..self.nx as i64).contains(&di) && (0..self.nz as i64).contains(&dj) {
                    self.patches[dj as usize * self.nx + di as usize]
                } else {
                    self.compute(i, j)
                };
                if !patch.present {
                    continue;
                }
                let d = q - patch.centre;
                let (u, v) = (d.x * patch.cos + d.y * patch.sin, -d.x * patch.sin + d.y * patch.cos);
                let rho = ((u / patch.a).powi(2) + (v / patch.b).powi(2)).sqrt();
                let b = smoothstep(1.0, 0.7, rho);
                if b > 0.0 {
                    f(patch.value, b);
                }
            }
        }
    }
}

impl Prepared {
    /// The time these values are for, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Where `p` (plane km) lies relative to the nearest sheet, if within reach.
    pub fn place(&self, p: Vec2) -> Option<SheetPlace> {
        self.sheets.place(p)
    }

    /// The point `p` (plane km) where it is drawn, and its brightness factor: the
    /// displacement and ray factor interpolated between samples taken along the chain
    /// once for this moment (test `tables_follow_the_direct_evaluation` bounds the
    /// difference from working them out per particle: 1.5 m and 4.1·10⁻³ at its
    /// settings).
    pub fn apply(&self, p: Vec2) -> (Vec2, f32) {
        self.apply_with(p, |place| match self.tables.get(place.chain as usize) {
            Some(table) => table.at(place.from_head_km),
            None => self.direct_values(place),
        })
    }

    /// [`Prepared::apply`] with the patterns worked out at the particle's own arc
    /// length instead of interpolated (what the tables sample).
    #[cfg(test)]
    fn apply_direct(&self, p: Vec2) -> (Vec2, f32) {
        self.apply_with(p, |place| self.direct_values(place))
    }

    /// `p` drawn with the sheet's displacement and ray factor at its place given by
    /// `values` ([`Prepared::sheet_values`]).
    #[inline]
    fn apply_with(&self, p: Vec2, values: impl FnOnce(&SheetPlace) -> [f32; 3]) -> (Vec2, f32) {
        if !p.is_finite() {
            return (p, 1.0);
        }
        let gain = self.patches(p);
        let Some(place) = self.sheets.place(p) else { return (p, gain) };
        let values = values(&place);
        self.finish(p, gain, &place, values)
    }

    /// [`Prepared::sheet_values`] at `place`, worked out there.
    fn direct_values(&self, place: &SheetPlace) -> [f32; 3] {
        self.sheet_values(&self.chains[place.chain as usize], place.s_km)
    }

    /// The displacement (along, normal) and ray factor at arc length `s_km` of `chain`.
    fn sheet_values(&self, chain: &ChainNow, s_km: f32) -> [f32; 3] {
        let (along, normal) = self.displacement(chain, s_km);
        let rays = if self.params.rays.contrast > 0.0 { self.rays(chain, s_km) } else { 1.0 };
        [along, normal, rays]
    }

    /// Chain `k`'s table at samples `step` km apart.
    fn table(&self, k: usize, step: f32) -> ChainTable {
        let (chain, now) = (&self.sheets.chains[k], &self.chains[k]);
        let n = ChainTable::samples(chain.length, step);
        // Each sample on its own (the same values for any thread count).
        let values = (0..n)
            .into_par_iter()
            .map(|i| self.sheet_values(now, chain.s_offset + i as f32 * step))
            .collect();
        ChainTable { inv_step: 1.0 / step, values }
    }

    /// `p` drawn at `place` with the sheet's `values` there ([`Prepared::sheet_values`])
    /// and the patches' factor `gain`.
    #[inline]
    fn finish(
        &self,
        p: Vec2,
        mut gain: f32,
        place: &SheetPlace,
        [along, normal, rays]: [f32; 3],
    ) -> (Vec2, f32) {
        let s = &self.params;
        // Fade towards the edge of reach, so displaced and undisplaced particles meet.
        let near = smoothstep(s.reach_km, 0.5 * s.reach_km, place.distance_km);
        let drawn = p + (place.tangent * along + place.tangent.perp() * normal) * near;
        if s.rays.contrast > 0.0 {
            gain *= 1.0 + near * (rays - 1.0);
        }
        if s.end_taper_km > 0.0 {
            let fade = end_fade(place.from_head_km, place.head_gap_km, s.end_taper_km)
                * end_fade(place.to_tail_km, place.tail_gap_km, s.end_taper_km);
            gain *= 1.0 + near * (fade - 1.0);
        }
        (drawn, gain)
    }

    /// The sheet's displacement at arc length `s_km`: (along, normal), km.
    fn displacement(&self, chain: &ChainNow, s_km: f32) -> (f32, f32) {
        use std::f32::consts::{PI, TAU};
        let s = &self.params;
        let mut normal = 0.0;
        let folds = &s.folds;
        if folds.amplitude_km > 0.0 {
            let phase = TAU * chain.folds.local(s_km, folds.wavelength_km) + chain.fold_phase;
            normal += folds.amplitude_km * phase.sin();
        }
        let c = &s.curls;
        let mut along = 0.0;
        if !chain.curl_life.is_empty() {
            let sigma = chain.curls.local(s_km, c.wavelength_km);
            let shifted = sigma + 0.25;
            let j = shifted.floor();
            let k = (j as i64 - chain.curl_first).clamp(0, chain.curl_life.len() as i64 - 1) as usize;
            // The site tapers to 0 at its ends.
            let taper = (PI * (shifted - j)).sin().powi(2);
            let a = c.amplitude_km * chain.curl_life[k] * taper;
            let (sin, cos) = (TAU * sigma).sin_cos();
            along += a * cos;
            normal += a * sin;
        }
        (along, normal)
    }

    /// Ray brightness factor at arc length `s_km` (mean 1 along the sheet).
    fn rays(&self, chain: &ChainNow, s_km: f32) -> f32 {
        self.rays_cut(chain, s_km, RAY_CUT_WIDTHS)
    }

    /// [`Prepared::rays`] with the Gaussians cut at `cut` widths.
    fn rays_cut(&self, chain: &ChainNow, s_km: f32, cut: f32) -> f32 {
        let r = &self.params.rays;
        let sigma = chain.rays.local(s_km, r.spacing_km);
        let w = r.width_km / r.spacing_km;
        let reach = (3.0 * w).ceil() as i64 + 1;
        let j0 = sigma.floor() as i64;
        let mut sum = 0.0;
        for j in j0 - reach..=j0 + reach {
            let Some(&(centre, strength)) =
                usize::try_from(j - chain.ray_first).ok().and_then(|k| chain.ray_sites.get(k))
            else {
                continue;
            };
            let d = (sigma - centre) / w;
            if d.abs() > cut {
                continue;
            }
            sum += strength * (-0.5 * d * d).exp();
        }
        // Mean of the sum over σ: mean strength 1 × one Gaussian's area w√(2π) per site.
        let mean = w * (std::f32::consts::TAU).sqrt();
        1.0 - r.contrast + r.contrast * sum / mean
    }

    /// The flickering and pulsating patches' brightness factor at `p`.
    fn patches(&self, p: Vec2) -> f32 {
        let mut gain = 1.0;
        if let Some(field) = &self.flicker
            && let PatchKind::Flicker(f) = field.kind
        {
            let mut wave = 0.0f32;
            field.each(p, |value, b| wave += b * value);
            gain *= (1.0 + f.depth * wave.clamp(-1.0, 1.0)).max(0.0);
        }
        if let Some(field) = &self.pulsating
            && let PatchKind::Pulsating(ps) = field.kind
        {
            let mut on = 0.0f32;
            field.each(p, |value, b| on = on.max(b * value));
            gain *= ps.background + (1.0 - ps.background) * on;
        }
        gain
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(length: f32, points: usize) -> Shape {
        let n = points;
        Shape {
            points: (0..n).map(|i| Vec2::new(length * i as f32 / (n - 1) as f32, 0.0)).collect(),
            next: (0..n).map(|i| (i + 1 < n).then_some(i as u32 + 1)).collect(),
            sheet: vec![0; n],
            index_in_sheet: (0..n as u32).collect(),
        }
    }

    #[test]
    fn places_are_arc_length_and_signed_offset() {
        let shape = straight(100.0, 11);
        let ix = SheetIndex::new(&shape, 5.0);
        let p = ix.place(Vec2::new(37.5, 2.0)).unwrap();
        assert!((p.s_km - 37.5).abs() < 1e-4 && (p.n_km - 2.0).abs() < 1e-5, "{p:?}");
        assert_eq!((p.from_head_km, p.to_tail_km), (37.5, 62.5));
        assert!(p.head_gap_km.is_infinite() && (p.distance_km - 2.0).abs() < 1e-5);
        assert!(ix.place(Vec2::new(37.5, -4.9)).unwrap().n_km < 0.0);
        assert!(ix.place(Vec2::new(37.5, 6.0)).is_none(), "beyond reach");
    }

    #[test]
    fn rays_keep_the_mean_brightness() {
        // The normalisation is the expected mean over σ: averaged over 2000 sites the
        // mean of the factor is 1 within the sampling error of the site strengths
        // (σ of the mean ≈ 0.29/√2000 · contrast ≈ 0.004).
        let s = SmallScale::default();
        let prepared = s.at(&straight(10_000.0, 101), 0.0, 7).unwrap();
        let n = 200_000;
        let mean: f64 = (0..n)
            .map(|k| {
                let place = prepared.place(Vec2::new(8000.0 * k as f32 / n as f32 + 100.0, 0.0)).unwrap();
                f64::from(prepared.rays(&prepared.chains[place.chain as usize], place.s_km))
            })
            .sum::<f64>()
            / f64::from(n);
        assert!((mean - 1.0).abs() < 0.02, "mean ray factor {mean}");
    }

    #[test]
    fn rays_cut_at_six_widths_move_by_less_than_the_terms_left_out() {
        // Against the whole sum of every site within reach, at the default width, a
        // narrow and a wide one: the factor differs by at most the bound of
        // `RAY_CUT_WIDTHS` plus two ulps of its value (an allowance, not derived: the
        // partial sums without the small terms round differently, then the sum is
        // scaled), and some places do differ (the cut is not a no-op).
        for width_km in [Rays::default().width_km, 0.2, 2.0] {
            let s = SmallScale {
                rays: Rays { width_km, contrast: 0.7, ..Rays::default() },
                ..SmallScale::default()
            };
            let prepared = s.at(&straight(10_000.0, 101), 0.0, 7).unwrap();
            let r = &s.rays;
            let w = r.width_km / r.spacing_km;
            let reach = (3.0 * w).ceil() + 1.0;
            let bound = r.contrast * (2.0 * reach + 1.0) * 1.5 * (-18.0f32).exp()
                / (w * std::f32::consts::TAU.sqrt());
            let mut differ = 0;
            for k in 0..100_000 {
                let place = prepared.place(Vec2::new(8000.0 * k as f32 / 100_000.0 + 100.0, 0.0)).unwrap();
                let chain = &prepared.chains[place.chain as usize];
                let (cut, whole) =
                    (prepared.rays(chain, place.s_km), prepared.rays_cut(chain, place.s_km, f32::INFINITY));
                let tolerance = bound + 2.0 * f32::EPSILON * whole.abs();
                assert!(
                    (cut - whole).abs() <= tolerance,
                    "width {width_km}: {cut} vs {whole} (bound {bound})"
                );
                differ += usize::from(cut != whole);
            }
            // (Measured: 1,817, 2,699 and 730 of the 100,000 places.)
            assert!(differ > 0, "width {width_km}: no place differs");
        }
    }

    /// Σ over a row of sites at least `gap` apart (in widths) on either side of a point,
    /// of sup |g(u)| beyond each site's nearest possible distance: at most two sites
    /// (one a side) lie within each band [n·gap, (n+1)·gap), so the sum over the sites
    /// is at most Σₙ 2·sup_{|u| ≥ n·gap} |g(u)| (sup taken on a fine grid to 40 widths).
    fn band_sum(gap: f32, g: impl Fn(f32) -> f32) -> f32 {
        let sup_beyond = |x: f32| (0..4000).map(|k| g(x + k as f32 * 0.01).abs()).fold(0.0f32, f32::max);
        (0..).map(|n| n as f32 * gap).take_while(|&x| x < 40.0).map(|x| 2.0 * sup_beyond(x)).sum()
    }

    /// A sheet of `n` points on three quarters of a circle of radius `r` km.
    fn arc(n: usize, r: f32) -> Shape {
        Shape {
            points: (0..n)
                .map(|i| {
                    let a = 1.5 * i as f32 / (n - 1) as f32;
                    Vec2::new(r * a.cos(), r * a.sin())
                })
                .collect(),
            next: (0..n).map(|i| (i + 1 < n).then_some(i as u32 + 1)).collect(),
            sheet: vec![0; n],
            index_in_sheet: (0..n as u32).collect(),
        }
    }

    /// Two sheets: the first split into two pieces (x 0-100 and 120-220 km at z 0; the
    /// second piece's arc length starts where the first's ends), the second whole
    /// (x 0-220 km at z 60).
    fn split_and_whole() -> Shape {
        let mut shape =
            Shape { points: Vec::new(), next: Vec::new(), sheet: Vec::new(), index_in_sheet: Vec::new() };
        for (sheet, x0, x1, z, first) in
            [(0, 0.0, 100.0, 0.0, 0), (0, 120.0, 220.0, 0.0, 11), (1, 0.0, 220.0, 60.0, 0)]
        {
            let n = 11;
            let base = shape.points.len() as u32;
            for i in 0..n {
                shape.points.push(Vec2::new(x0 + (x1 - x0) * i as f32 / (n - 1) as f32, z));
                shape.next.push((i + 1 < n).then_some(base + i as u32 + 1));
                shape.sheet.push(sheet);
                shape.index_in_sheet.push(first + i as u32);
            }
        }
        shape
    }

    /// How far [`Prepared::apply`] may draw a point from [`Prepared::apply_direct`]
    /// (km) and how far its brightness factor may differ, for tables `step` km apart on
    /// sheets whose arc lengths reach `longest` km, no patches, points within 400 km of
    /// the origin.
    ///
    /// Linear interpolation between samples `step` apart misses a function f by at
    /// most step²/8 · max|f''| (the interpolation error theorem), here with bounds on
    /// each pattern's f'' from its formula (s the arc length, k = 2π/λ):
    /// - folds A sin(k s + φ): |f''| ≤ A k²;
    /// - curls a · sin²(π x) · cos or sin(k s), x = s/λ + ¼ − site, a ≤ A: with
    ///   g = sin²(πx) (|g'| ≤ k/2, |g''| ≤ k²/2) and h the cosine (|h'| ≤ k,
    ///   |h''| ≤ k²), |(gh)''| ≤ |g''| + 2|g'h'| + |h''| ≤ 2.5 k², so |f''| ≤ 2.5 A k²;
    /// - rays 1 − c + c Σ sⱼ G(uⱼ) / (w √(2π)), G = e^{−u²/2}, u in widths w (in
    ///   spacings), sⱼ ≤ 1.5, sites' centres at least 0.2 spacings apart:
    ///   |f''| ≤ c / (w √(2π)) · 1.5 · Σ|G''(uⱼ)| / (w · spacing)², the sum bounded by
    ///   `band_sum`; the cut at six widths adds a jump under its own bound.
    ///
    /// The table and the direct path take the arc length in another order of f32
    /// additions: an allowance (chosen, not derived) of the slope bound times 4 ulps of
    /// the longest arc length
    /// (|f'| ≤ A k for the folds, 1.5 A k for the curls, the rays as above with |G'|),
    /// plus 8 ulps of the value (the interpolation's own rounding), and for the drawn
    /// point 4 ulps of a position 400 km out (the displacement added to it).
    fn table_bounds(small: &SmallScale, step: f32, longest: f32) -> (f32, f32) {
        use std::f32::consts::TAU;
        let (f, c, r) = (small.folds, small.curls, small.rays);
        let (kf, kc) = (TAU / f.wavelength_km, TAU / c.wavelength_km);
        let w = r.width_km / r.spacing_km;
        let gap = 0.2 / w;
        let rays_scale = r.contrast / (w * TAU.sqrt()) * 1.5;
        let rays_f2 =
            rays_scale * band_sum(gap, |u| (u * u - 1.0) * (-0.5 * u * u).exp()) / (r.width_km).powi(2);
        let rays_f1 = rays_scale * band_sum(gap, |u| u * (-0.5 * u * u).exp()) / r.width_km;
        let cut_jump =
            r.contrast * 1.5 * (2.0 * ((3.0 * w).ceil() + 1.0) + 1.0) * (-18.0f32).exp() / (w * TAU.sqrt());
        let ulps = 4.0 * longest * f32::EPSILON;
        let interp = step * step / 8.0;
        let normal = interp * (f.amplitude_km * kf * kf + 2.5 * c.amplitude_km * kc * kc)
            + (f.amplitude_km * kf + 1.5 * c.amplitude_km * kc) * ulps
            + 8.0 * f32::EPSILON * (f.amplitude_km + c.amplitude_km);
        let along = interp * 2.5 * c.amplitude_km * kc * kc
            + 1.5 * c.amplitude_km * kc * ulps
            + 8.0 * f32::EPSILON * c.amplitude_km;
        let drawn = normal.hypot(along) + 4.0 * f32::EPSILON * 400.0;
        let gain = interp * rays_f2 + rays_f1 * ulps + cut_jump + 8.0 * f32::EPSILON * (1.0 + rays_scale);
        (drawn, gain)
    }

    #[test]
    #[allow(clippy::print_stderr, reason = "the measured errors, for the record of a run")]
    fn tables_follow_the_direct_evaluation() {
        // Within `table_bounds` at 180,000 places around a straight sheet, an arc and
        // a split sheet beside a whole one (three chains, one starting its arc length
        // past 0), with every curl site alive and the rays' contrast at 0.8.
        let small = SmallScale {
            curls: Curls { share: 1.0, ..Curls::default() },
            rays: Rays { contrast: 0.8, ..Rays::default() },
            flicker: Flicker { enabled: false, ..Flicker::default() },
            pulsating: Pulsating { enabled: false, ..Pulsating::default() },
            ..SmallScale::default()
        };
        let shapes = [
            ("straight", straight(300.0, 31), 0.7),
            ("arc", arc(40, 200.0), 2.3),
            ("split", split_and_whole(), 1.6),
        ];
        for (name, shape, time_s) in shapes {
            let prepared = small.at(&shape, time_s, 11).unwrap();
            let step = small.table_step();
            assert_eq!(prepared.tables.len(), prepared.chains.len(), "{name}: a table a chain");
            let width = small.rays.width_km;
            assert_eq!(step, width / TABLE_SAMPLES_PER_SCALE, "{name}: the rays' width sets the step");
            let longest = prepared.sheets.chains.iter().map(|c| c.s_offset + c.length).fold(0.0f32, f32::max);
            let (drawn_bound, gain_bound) = table_bounds(&small, step, longest);
            let (mut worst_d, mut worst_g, mut differ, mut placed) = (0.0f32, 0.0f32, 0, 0);
            for k in 0..60_000 {
                // Points over the shape's neighbourhood, most within reach.
                let (t, across) = (k as f32 / 60_000.0, 20.0 * ((k * 7919) % 1000) as f32 / 1000.0 - 10.0);
                let p = match name {
                    "straight" => Vec2::new(-5.0 + 310.0 * t, across),
                    "arc" => Vec2::from_angle(1.5 * t) * (200.0 + across),
                    // Along both sheets in turn.
                    _ => Vec2::new(-5.0 + 230.0 * t, across + if k % 2 == 0 { 0.0 } else { 60.0 }),
                };
                let ((d_t, g_t), (d_e, g_e)) = (prepared.apply(p), prepared.apply_direct(p));
                placed += usize::from(prepared.place(p).is_some());
                let (dd, dg) = ((d_t - d_e).length(), (g_t - g_e).abs());
                assert!(
                    dd <= drawn_bound,
                    "{name} at {p}: drawn {d_t} vs {d_e} ({dd} km, bound {drawn_bound})"
                );
                assert!(dg <= gain_bound, "{name} at {p}: gain {g_t} vs {g_e} ({dg}, bound {gain_bound})");
                (worst_d, worst_g) = (worst_d.max(dd), worst_g.max(dg));
                differ += usize::from(d_t != d_e || g_t != g_e);
            }
            eprintln!(
                "{name}: step {step} km; worst drawn {worst_d:.2e} km (bound {drawn_bound:.2e}), gain {worst_g:.2e} (bound {gain_bound:.2e}); {differ} of {placed} placed points differ"
            );
            assert!(placed > 50_000, "{name}: {placed} points within reach");
            assert!(differ > placed / 2, "{name}: only {differ} points differ: the tables are not in use");
        }
    }

    #[test]
    fn sheets_past_the_cap_are_worked_out_per_particle() {
        // Rays 10 m wide sample every 0.42 m: 300 km would need 720,000 samples, past
        // the cap, so there are no tables and every point is the direct evaluation's.
        let small = SmallScale { rays: Rays { width_km: 0.01, ..Rays::default() }, ..SmallScale::default() };
        let prepared = small.at(&straight(300.0, 31), 0.4, 3).unwrap();
        assert!(prepared.tables.is_empty(), "{} tables", prepared.tables.len());
        for k in 0..5_000 {
            let p = Vec2::new(300.0 * k as f32 / 5_000.0, 8.0 * ((k * 7919) % 1000) as f32 / 1000.0 - 4.0);
            assert_eq!(prepared.apply(p), prepared.apply_direct(p), "at {p}");
        }
        // The default 600 m rays over the same sheet: 12,000 samples, tables.
        let prepared = SmallScale::default().at(&straight(300.0, 31), 0.4, 3).unwrap();
        assert_eq!(prepared.tables.len(), 1);
    }

    #[test]
    fn lanes_find_the_scalar_place() {
        // Every place the lanes find is the one-at-a-time search's, bit for bit, over
        // points in and around a straight sheet and a zigzag of short segments (many
        // candidates a cell, ties between segments sharing an end), and outside the grid.
        let zigzag = Shape {
            points: (0..60).map(|i| Vec2::new(i as f32 * 2.0, if i % 2 == 0 { 0.0 } else { 1.5 })).collect(),
            next: (0..60).map(|i| (i + 1 < 60).then_some(i as u32 + 1)).collect(),
            sheet: vec![0; 60],
            index_in_sheet: (0..60u32).collect(),
        };
        let mut found = 0;
        for shape in [straight(300.0, 31), zigzag] {
            let index = SheetIndex::new(&shape, 15.0);
            for k in 0..40_000u32 {
                let u = (k.wrapping_mul(2_654_435_761) >> 8) as f32 / (1u32 << 24) as f32;
                let p = Vec2::new(-40.0 + 380.0 * k as f32 / 40_000.0, -40.0 + 80.0 * u);
                let want = index.place_scalar(p);
                let got = index.place(p);
                match (want, got) {
                    (None, None) => {}
                    (Some((dist2, k, t, d)), Some(place)) => {
                        let g = &index.segments[k as usize];
                        assert_eq!(place.chain, g.chain, "at {p}");
                        assert_eq!(place.tangent, g.dir, "at {p}");
                        assert_eq!(place.from_head_km.to_bits(), (g.s0 + t).to_bits(), "at {p}");
                        assert_eq!(place.distance_km.to_bits(), dist2.sqrt().to_bits(), "at {p}");
                        assert_eq!(place.n_km.to_bits(), g.dir.perp_dot(d).to_bits(), "at {p}");
                        found += 1;
                    }
                    _ => panic!("at {p}: {want:?} against {got:?}"),
                }
            }
        }
        // Within 15 km of the sheets: 30/80 of the band along the straight sheet's
        // 330 of 380 km, less along the zigzag's 148 (18,596 when written).
        assert!(found > 15_000, "{found} places");
    }

    #[test]
    fn ends_fade_and_the_middle_does_not() {
        let s = SmallScale { rays: Rays { contrast: 0.0, ..Rays::default() }, ..SmallScale::default() };
        let prepared = s.at(&straight(200.0, 21), 0.0, 1).unwrap();
        let gain = |x: f32| prepared.apply(Vec2::new(x, 0.0)).1;
        assert!(gain(0.5) < 0.01 && gain(199.5) < 0.01, "{} {}", gain(0.5), gain(199.5));
        assert_eq!(gain(100.0), 1.0);
        assert!(gain(10.0) > 0.2 && gain(10.0) < 0.8);
    }

    #[test]
    fn patches_from_the_table_are_those_worked_out_when_asked_for() {
        let kind = PatchKind::Pulsating(Pulsating { enabled: true, ..Pulsating::default() });
        let bounds = (Vec2::new(0.0, 0.0), Vec2::new(300.0, 200.0));
        let table = PatchField::new(kind, 50.0, 40.0, 0.8, bounds, 7.3, 11);
        assert!(!table.patches.is_empty());
        let mut none = table.clone();
        (none.nx, none.nz, none.patches) = (0, 0, Vec::new());
        let mut lit = 0;
        for k in 0..2000 {
            let p = Vec2::new((k % 50) as f32 * 7.1 - 20.0, (k / 50) as f32 * 6.3 - 20.0);
            let (mut a, mut b) = (Vec::new(), Vec::new());
            table.each(p, |v, w| a.push((v, w)));
            none.each(p, |v, w| b.push((v, w)));
            assert_eq!(a, b, "at {p}");
            lit += usize::from(!a.is_empty());
        }
        assert!(lit > 500, "{lit} points under a patch");
    }

    /// A sheet split in two whose pieces still touch (as a split is when it opens) is
    /// as bright at the split as along its middle, and its waves run on unbroken; its
    /// outer ends fade; once the pieces are two tapers apart the new ends fade too.
    #[test]
    fn a_split_opening_leaves_no_dark_notch_and_no_jump() {
        // Two pieces of 11 points, x = 0..100 and 100 + gap..200 + gap, of one sheet.
        let split = |gap: f32| {
            let mut shape = straight(100.0, 11);
            let other = straight(100.0, 11);
            shape.points.extend(other.points.iter().map(|p| Vec2::new(p.x + 100.0 + gap, p.y)));
            shape.next.extend(other.next.iter().map(|n| n.map(|j| j + 11)));
            shape.sheet.extend(other.sheet.iter());
            shape.index_in_sheet.extend(other.index_in_sheet.iter().map(|i| i + 11));
            shape
        };
        let s = SmallScale { rays: Rays { contrast: 0.0, ..Rays::default() }, ..SmallScale::default() };
        let joined = s.at(&straight(200.0, 21), 1.3, 4).unwrap();
        let touching = s.at(&split(0.0), 1.3, 4).unwrap();
        for x in [95.0, 99.9, 100.1, 105.0] {
            let p = Vec2::new(x, 0.5);
            assert_eq!(touching.apply(p).1, 1.0, "gain at {x}");
            let (a, b) = (joined.apply(p).0, touching.apply(p).0);
            assert!(a.distance(b) < 1e-3, "at {x}: {a} against {b}");
        }
        assert!(touching.apply(Vec2::new(0.5, 0.0)).1 < 0.01, "the outer end fades");
        let apart = s.at(&split(2.0 * s.end_taper_km), 1.3, 4).unwrap();
        assert!(apart.apply(Vec2::new(99.5, 0.0)).1 < 0.01, "a new end two tapers away fades");
    }

    #[test]
    fn bad_values_are_reported_with_their_range() {
        let mut s = SmallScale::default();
        s.flicker.frequency_hz = [12.0, 8.0];
        s.rays.contrast = 2.0;
        let mut i = Issues::default();
        s.validate(&mut i, "small_scale");
        let e = i.into_result().unwrap_err();
        let text: Vec<String> = e.iter().map(|x| x.to_string()).collect();
        assert!(text.iter().any(|t| t.contains("small_scale.flicker.frequency_hz")), "{text:?}");
        assert!(text.iter().any(|t| t.contains("small_scale.rays.contrast") && t.contains('2')), "{text:?}");
    }
}
