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
use serde::{Deserialize, Serialize};

use crate::shape::Shape;

const SITES: Purpose = Purpose::named("aurora.small_scale.sites");

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
    /// Arc length from the sheet's first point, km.
    pub s_km: f32,
    /// Signed distance from the sheet (positive to the left of its direction), km.
    pub n_km: f32,
    /// The sheet's length, km.
    pub length_km: f32,
    /// Which chain of linked points (sheet) it is.
    pub chain: u32,
    /// Unit tangent along the sheet.
    pub tangent: Vec2,
}

/// One segment of a chain: start, unit direction, length, arc length at its start.
#[derive(Clone, Copy, Debug)]
struct Segment {
    a: Vec2,
    dir: Vec2,
    len: f32,
    s0: f32,
    chain: u32,
}

/// The sheets' segments with their arc lengths, bucketed for nearest-segment queries.
#[derive(Clone, Debug)]
struct SheetIndex {
    segments: Vec<Segment>,
    chain_length: Vec<f32>,
    origin: Vec2,
    cell: f32,
    nx: usize,
    nz: usize,
    start: Vec<u32>,
    items: Vec<u32>,
    reach: f32,
}

impl SheetIndex {
    fn new(shape: &Shape, reach: f32) -> Self {
        let n = shape.points.len();
        let mut has_prev = vec![false; n];
        for &j in shape.next.iter().flatten() {
            if let Some(h) = has_prev.get_mut(j as usize) {
                *h = true;
            }
        }
        let (mut segments, mut chain_length) = (Vec::new(), Vec::new());
        let mut visited = vec![false; n];
        // Heads first (open chains), then whatever is left (closed loops), in point order.
        let heads = (0..n).filter(|&i| !has_prev[i]).chain(0..n);
        for head in heads {
            if visited[head] || shape.next[head].is_none() {
                continue;
            }
            let chain = chain_length.len() as u32;
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
            chain_length.push(s);
        }
        let (lo, hi) = segments.iter().fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), g| {
            let b = g.a + g.dir * g.len;
            (lo.min(g.a).min(b), hi.max(g.a).max(b))
        });
        let cell = reach.max(1e-3);
        let origin = if segments.is_empty() { Vec2::ZERO } else { lo - Vec2::splat(reach) };
        let span = if segments.is_empty() { Vec2::ZERO } else { (hi + Vec2::splat(reach) - origin) / cell };
        let (nx, nz) = ((span.x as usize + 1).min(2048), (span.y as usize + 1).min(2048));
        let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); nx * nz];
        for (k, g) in segments.iter().enumerate() {
            let b = g.a + g.dir * g.len;
            let (lo, hi) = (g.a.min(b) - Vec2::splat(reach), g.a.max(b) + Vec2::splat(reach));
            let (i0, j0) = cell_of(origin, cell, nx, nz, lo);
            let (i1, j1) = cell_of(origin, cell, nx, nz, hi);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    buckets[j * nx + i].push(k as u32);
                }
            }
        }
        let mut start = Vec::with_capacity(nx * nz + 1);
        let mut items = Vec::new();
        for b in &buckets {
            start.push(items.len() as u32);
            items.extend_from_slice(b);
        }
        start.push(items.len() as u32);
        Self { segments, chain_length, origin, cell, nx, nz, start, items, reach }
    }

    /// The nearest sheet within reach of `p`.
    fn place(&self, p: Vec2) -> Option<SheetPlace> {
        if self.segments.is_empty() {
            return None;
        }
        let q = (p - self.origin) / self.cell;
        if q.x < 0.0 || q.y < 0.0 || q.x >= self.nx as f32 || q.y >= self.nz as f32 {
            return None;
        }
        let c = q.y as usize * self.nx + q.x as usize;
        let mut best: Option<(f32, SheetPlace)> = None;
        for &k in &self.items[self.start[c] as usize..self.start[c + 1] as usize] {
            let g = &self.segments[k as usize];
            let d = p - g.a;
            let t = d.dot(g.dir).clamp(0.0, g.len);
            let off = d - g.dir * t;
            let dist2 = off.length_squared();
            if dist2 <= self.reach * self.reach && best.as_ref().is_none_or(|(b, _)| dist2 < *b) {
                let n_km = g.dir.perp_dot(d);
                let place = SheetPlace {
                    s_km: g.s0 + t,
                    n_km,
                    length_km: self.chain_length[g.chain as usize],
                    chain: g.chain,
                    tangent: g.dir,
                };
                best = Some((dist2, place));
            }
        }
        best.map(|(_, p)| p)
    }
}

fn cell_of(origin: Vec2, cell: f32, nx: usize, nz: usize, p: Vec2) -> (usize, usize) {
    let q = ((p - origin) / cell).max(Vec2::ZERO);
    ((q.x as usize).min(nx - 1), (q.y as usize).min(nz - 1))
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
    flicker: Option<PatchField>,
    pulsating: Option<PatchField>,
}

/// One sheet's sites now.
#[derive(Clone, Debug, Default)]
struct ChainNow {
    /// The folds' phase offset, radians.
    fold_phase: f32,
    /// Curl site of `curl_life[0]`.
    curl_first: i64,
    /// Each curl site's life envelope now (0-1).
    curl_life: Vec<f32>,
    /// Ray site of `rays[0]`.
    ray_first: i64,
    /// Each ray's centre (in spacings) and strength.
    rays: Vec<(f32, f32)>,
}

/// Uniform in [0, 1) for a site: the same for the same (seed, kind, a, b, c).
fn site_random(seed: u64, kind: u64, a: i64, b: i64, c: u64) -> f32 {
    let key = (a as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
        ^ (b as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
        ^ c.wrapping_mul(0x1656_67b1_9e37_79f9)
        ^ kind;
    Stream::new(seed, SITES, key).next_f32()
}

/// Smooth step from 0 at `e0` to 1 at `e1`.
fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl SmallScale {
    fn prepare(&self, shape: &Shape, time_s: f64, seed: u64) -> Prepared {
        let sheets = SheetIndex::new(shape, self.reach_km);
        let t = time_s as f32;
        let chains = sheets
            .chain_length
            .iter()
            .enumerate()
            .map(|(c, &l)| self.chain_now(c as i64, l, t, seed))
            .collect();
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
        Prepared { params: *self, sheets, time_s, chains, flicker, pulsating }
    }

    fn chain_now(&self, chain: i64, length: f32, t: f32, seed: u64) -> ChainNow {
        let mut now = ChainNow {
            fold_phase: site_random(seed, 1, chain, 0, 0) * std::f32::consts::TAU,
            ..ChainNow::default()
        };
        let c = &self.curls;
        if c.amplitude_km > 0.0 && c.share > 0.0 {
            // Sites are centred on the wave's crests (θ = π/2, σ = j + ¼), where a
            // trochoid loops; site j lives in window k (1.5 lifetimes long, its own
            // offset) with chance `share`, as sin² over one lifetime.
            let sigma = |s: f32| (s - c.speed_km_s * t) / c.wavelength_km + 0.25;
            now.curl_first = sigma(0.0).floor() as i64;
            let last = sigma(length).floor() as i64;
            now.curl_life = (now.curl_first..=last)
                .map(|j| {
                    let window = 1.5 * c.lifetime_s;
                    let u = t / window + site_random(seed, 2, j, chain, 0);
                    let k = u.floor();
                    let life = (u - k) * 1.5;
                    if site_random(seed, 3, j, chain, k as i64 as u64) >= c.share || life >= 1.0 {
                        0.0
                    } else {
                        (std::f32::consts::PI * life).sin().powi(2)
                    }
                })
                .collect();
        }
        let r = &self.rays;
        if r.contrast > 0.0 {
            let sigma = |s: f32| (s - r.speed_km_s * t) / r.spacing_km;
            let reach = (3.0 * r.width_km / r.spacing_km).ceil() as i64 + 1;
            now.ray_first = sigma(0.0).floor() as i64 - reach;
            let last = sigma(length).floor() as i64 + reach;
            now.rays = (now.ray_first..=last)
                .map(|j| {
                    let centre = j as f32 + 0.5 + 0.8 * (site_random(seed, 4, j, chain, 0) - 0.5);
                    (centre, 0.5 + site_random(seed, 5, j, chain, 0))
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
        let nx = ((hi.x - lo.x) as i64 + 2 * span + 1).clamp(1, 4096) as usize;
        let nz = ((hi.y - lo.y) as i64 + 2 * span + 1).clamp(1, 4096) as usize;
        let mut field =
            Self { kind, spacing, radius, share, span, first, nx, nz, patches: Vec::new(), time_s, seed };
        field.patches = (0..nx * nz)
            .map(|k| field.compute(first.0 + (k % nx) as i64, first.1 + (k / nx) as i64))
            .collect();
        field
    }

    /// Site (i, j)'s patch, from its random numbers.
    fn compute(&self, i: i64, j: i64) -> Patch {
        let h = [0u64, 1, 2, 3, 4, 5].map(|c| site_random(self.seed, self.kind.key(), i, j, c));
        if h[2] >= self.share {
            return Patch::default();
        }
        let (sin, cos) = (std::f32::consts::PI * h[5]).sin_cos();
        // Axes radius × (1 ± 0.3), by the site's second number.
        let stretch = 1.0 + 0.6 * (h[1] - 0.5);
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

    /// The point `p` (plane km) where it is drawn, and its brightness factor.
    pub fn apply(&self, p: Vec2) -> (Vec2, f32) {
        let mut gain = self.patches(p);
        let Some(place) = self.sheets.place(p) else { return (p, gain) };
        let s = &self.params;
        let t = self.time_s as f32;
        let chain = &self.chains[place.chain as usize];
        // Fade towards the edge of reach, so displaced and undisplaced particles meet.
        let near = smoothstep(s.reach_km, 0.5 * s.reach_km, place.n_km.abs());
        let (along, normal) = self.displacement(chain, &place, t);
        let drawn = p + (place.tangent * along + place.tangent.perp() * normal) * near;
        if s.rays.contrast > 0.0 {
            gain *= 1.0 + near * (self.rays(chain, &place, t) - 1.0);
        }
        if s.end_taper_km > 0.0 {
            let from_end = place.s_km.min(place.length_km - place.s_km);
            gain *= 1.0 + near * (smoothstep(0.0, s.end_taper_km, from_end) - 1.0);
        }
        (drawn, gain)
    }

    /// The sheet's displacement at `place`: (along, normal), km.
    fn displacement(&self, chain: &ChainNow, place: &SheetPlace, t: f32) -> (f32, f32) {
        use std::f32::consts::{PI, TAU};
        let s = &self.params;
        let mut normal = 0.0;
        let folds = &s.folds;
        if folds.amplitude_km > 0.0 {
            let phase = TAU * (place.s_km - folds.speed_km_s * t) / folds.wavelength_km + chain.fold_phase;
            normal += folds.amplitude_km * phase.sin();
        }
        let c = &s.curls;
        let mut along = 0.0;
        if !chain.curl_life.is_empty() {
            let sigma = (place.s_km - c.speed_km_s * t) / c.wavelength_km;
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

    /// Ray brightness factor along the sheet (mean 1).
    fn rays(&self, chain: &ChainNow, place: &SheetPlace, t: f32) -> f32 {
        let r = &self.params.rays;
        let sigma = (place.s_km - r.speed_km_s * t) / r.spacing_km;
        let w = r.width_km / r.spacing_km;
        let reach = (3.0 * w).ceil() as i64 + 1;
        let j0 = sigma.floor() as i64;
        let mut sum = 0.0;
        for j in j0 - reach..=j0 + reach {
            let Some(&(centre, strength)) =
                usize::try_from(j - chain.ray_first).ok().and_then(|k| chain.rays.get(k))
            else {
                continue;
            };
            let d = (sigma - centre) / w;
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
        assert_eq!(p.length_km, 100.0);
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
                f64::from(prepared.rays(&prepared.chains[place.chain as usize], &place, 0.0))
            })
            .sum::<f64>()
            / f64::from(n);
        assert!((mean - 1.0).abs() < 0.02, "mean ray factor {mean}");
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
