//! `SparkleSim`: the visible facets of §2, frame after frame, by the stochastic model or
//! by brute force.
//!
//! **The full system** (what brute force simulates and the stochastic model reproduces):
//! N facets, positions uniform over the space and normals drawn from the population's
//! lobe. Diamond dust (§3.1) moves each frame by one displacement shared by all crystals
//! (fall, wind and a smooth gust), plus each crystal's own random displacement uniform in
//! a small cube, in a periodic box; each normal takes a random rotation of at most δ about
//! a random axis (a Metropolis step against the lobe, so the lobe is kept: for uniform
//! normals every rotation is accepted). Leaves (§3.2) do not move; the sun does.
//!
//! **The stochastic model** holds only the facets seen now, plus "ghosts": facets that
//! stopped being seen within the last `memory_frames` frames, still followed unseen. Frame
//! 0 draws the seen facets directly (module `model`: a binomial count, positions uniform,
//! normals in the cone around each position's own H; in the box with a lobe, a Poisson
//! count per split cell of [`CellTable::split`]). A step moves each held facet with
//! the same dynamics; seen ones that left the cone become ghosts (§2's "delete", delayed),
//! ghosts that turn back into the cone are seen again where they are, ghosts unseen for
//! longer than the memory are dropped. Then the newcomers are added (§2's "stochastically
//! generate"): facets unseen in each remembered frame and seen at t+1. They are drawn
//! exactly by sampling the *destination* first: under the stationary distribution the
//! position at t+1 is uniform and independent of the facet's own displacement j, so
//! x_t = x_{t+1} - D - j; and a facet seen at t+1 had, at t, its normal within θ + δ of
//! H_{t+1}(x_{t+1}). So the candidates are virtual facets with x_{t+1} uniform and N_t in
//! that cap (a binomial count, thinned for lobes; in the box with uniform normals, a
//! Poisson count per region of [`Regions`], drawn region by region in lanes; in the box
//! with a lobe, a Poisson count per adaptively split cell of [`CellTable::split`], whose
//! normals come from the lobe in a window around the cap or are thinned in the cap, and
//! which, like the regions, leave out the inner cap certainly seen at t), moved one
//! step forward to t+1 and
//! walked back through the remembered frames (positions undo each frame's displacement;
//! normals take the same Metropolis step, which is reversible), and kept when seen at
//! t+1 and unseen in every remembered frame. Each newcomer's state has exactly the full
//! system's distribution, so glint lifetimes (followed with the same dynamics) match, and
//! so does how often and after how long a glint returns (up to the memory; tested).
//!
//! Two approximations remain, both documented and small: the newcomers' count is drawn
//! independently of how many are held, as for a Poisson population of mean N (for
//! exactly N facets the count's variance differs by a relative O(p), p the visible
//! fraction, 3·10⁻⁴ in the benchmark scene; the per-region Poisson counts are exactly
//! that population's); and a facet unseen for longer than the
//! memory is forgotten, so a return after a longer gap comes back at a fresh place.

use glam::Vec3;
use phenomena_core::camera::Projection;
use phenomena_core::rng::{Purpose, Stream};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use thiserror::Error;
use wide::f32x8;

use crate::batch::{LANES, LaneRng, Step, V8, first_frame, lane, move_and_test};
use crate::config::{Dust, LightAt, Normals, Population, SparkleConfig};
use crate::model::{CAP_MARGIN_RAD, Eye, Geometry, Lobe, Space, around, in_cap, one_minus_cos};
use phenomena_core::validate::{Expected, InvalidConfig, Issue};

const TRACK: Purpose = Purpose::named("sparkle.track");
const BIRTH: Purpose = Purpose::named("sparkle.birth");
const BRUTE: Purpose = Purpose::named("sparkle.brute");
const GUST: Purpose = Purpose::named("sparkle.gust");
const GHOST: Purpose = Purpose::named("sparkle.ghost");

/// Facets per parallel chunk of held or brute-force particles (fixed: results do not
/// depend on the thread count).
const CHUNK: usize = 4096;
/// Expected birth candidates per parallel chunk (at most `MAX_BIRTH_CHUNKS` chunks):
/// enough work per chunk to outweigh opening its streams.
const CANDIDATES_PER_CHUNK: f64 = 1024.0;
const MAX_BIRTH_CHUNKS: u64 = 256;
/// Birth candidates drawn and tested together.
const CANDIDATE_BATCH: u64 = 4096;

/// Why a simulation cannot be built or stepped.
#[derive(Debug, Error)]
pub enum SparkleError {
    /// The configuration has problems (each names the field, value and valid range).
    #[error(transparent)]
    Invalid(#[from] InvalidConfig),
    /// The light moved so that far more facets became candidates than the memory guard
    /// allows (lobes under a moving sun: their bound is only known frame by frame).
    #[error(
        "frame {frame}: this cone and lobe would draw up to {expected:.3e} candidate facets (at most {max:e}): raise phong.threshold_i_e or phong.exponent_n, or lower the count"
    )]
    TooManyCandidates {
        /// The frame being made.
        frame: u32,
        /// Candidates it would draw.
        expected: f64,
        /// The limit ([`crate::MAX_CANDIDATES`]).
        max: f64,
    },
    /// A saved state does not fit this simulation.
    #[error("the saved state does not fit this simulation: {0}")]
    State(String),
}

/// The facets seen in the current frame, structure of arrays.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Glints {
    /// Positions, metres.
    pub position_m: Vec<Vec3>,
    /// Unit normals.
    pub normal: Vec<Vec3>,
    /// Glint brightness k_s I_l (N·H)^n.
    pub intensity: Vec<f32>,
    /// Frame in which each became visible (0: visible when the simulation started).
    pub birth_frame: Vec<u32>,
}

impl Glints {
    /// Number of glints.
    pub fn len(&self) -> usize {
        self.position_m.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.position_m.is_empty()
    }

    fn push(&mut self, x: Vec3, n: Vec3, intensity: f32, birth: u32) {
        self.position_m.push(x);
        self.normal.push(n);
        self.intensity.push(intensity);
        self.birth_frame.push(birth);
    }

    fn reserve(&mut self, more: usize) {
        self.position_m.reserve(more);
        self.normal.reserve(more);
        self.intensity.reserve(more);
        self.birth_frame.reserve(more);
    }

    fn append(&mut self, other: &mut Glints) {
        self.position_m.append(&mut other.position_m);
        self.normal.append(&mut other.normal);
        self.intensity.append(&mut other.intensity);
        self.birth_frame.append(&mut other.birth_frame);
    }

    /// Set the length (new entries zero; kept capacity is reused). Growing reserves
    /// 1/16 more than asked, not the doubling `Vec` would do: these arrays are reused
    /// frame after frame at about the same length, and their bytes are reported.
    fn resize(&mut self, len: usize) {
        fn room<T>(v: &mut Vec<T>, len: usize) {
            if len > v.capacity() {
                v.reserve_exact(len + len / 16 - v.len());
            }
        }
        room(&mut self.position_m, len);
        room(&mut self.normal, len);
        room(&mut self.intensity, len);
        room(&mut self.birth_frame, len);
        self.position_m.resize(len, Vec3::ZERO);
        self.normal.resize(len, Vec3::ZERO);
        self.intensity.resize(len, 0.0);
        self.birth_frame.resize(len, 0);
    }

    fn bytes(&self) -> u64 {
        (self.position_m.capacity() * 12
            + self.normal.capacity() * 12
            + self.intensity.capacity() * 4
            + self.birth_frame.capacity() * 4) as u64
    }
}

/// Places in a [`Glints`] to write, split among parallel chunks.
struct Slots<'a> {
    x: &'a mut [Vec3],
    n: &'a mut [Vec3],
    v: &'a mut [f32],
    b: &'a mut [u32],
}

impl<'a> Slots<'a> {
    fn of(g: &'a mut Glints) -> Self {
        Self { x: &mut g.position_m, n: &mut g.normal, v: &mut g.intensity, b: &mut g.birth_frame }
    }

    /// The first `at` places and the rest.
    fn split(self, at: usize) -> (Self, Self) {
        let (x0, x1) = self.x.split_at_mut(at);
        let (n0, n1) = self.n.split_at_mut(at);
        let (v0, v1) = self.v.split_at_mut(at);
        let (b0, b1) = self.b.split_at_mut(at);
        (Self { x: x0, n: n0, v: v0, b: b0 }, Self { x: x1, n: n1, v: v1, b: b1 })
    }

    /// Consecutive runs of the given lengths.
    fn chunks(self, lengths: impl Iterator<Item = usize>) -> Vec<Self> {
        let mut out = Vec::new();
        let mut rest = self;
        for len in lengths {
            let (head, tail) = rest.split(len);
            out.push(head);
            rest = tail;
        }
        out
    }

    fn put(&mut self, i: usize, x: Vec3, n: Vec3, v: f32, b: u32) {
        (self.x[i], self.n[i], self.v[i], self.b[i]) = (x, n, v, b);
    }

    /// Every glint of `g`, in order, from the first place on.
    fn put_all(&mut self, g: &Glints) {
        for (i, ((x, n), (v, b))) in
            g.position_m.iter().zip(&g.normal).zip(g.intensity.iter().zip(&g.birth_frame)).enumerate()
        {
            self.put(i, *x, *n, *v, *b);
        }
    }
}

/// How the held facets fare on the way into frame `next`, chunk by chunk of [`CHUNK`]
/// (from their (N·H)² at `next`, -1 where unseen): seen glints are kept or die (ghosts
/// when `memory` > 0); ghosts come back or are still remembered for `memory` frames.
#[derive(Clone, Copy)]
struct Fates<'a> {
    lut: &'a IntensityLut,
    memory: u32,
    next: u32,
}

impl Fates<'_> {
    /// (kept, dying into ghosts) per chunk of the seen glints with (N·H)² `c2`.
    fn count_seen(&self, c2: &[f32]) -> Vec<(usize, usize)> {
        let memory = self.memory;
        c2.par_chunks(CHUNK)
            .map(|c| {
                let kept = c.iter().filter(|&&v| v >= 0.0).count();
                (kept, if memory > 0 { c.len() - kept } else { 0 })
            })
            .collect()
    }

    /// (back, still remembered) per chunk of the ghosts with (N·H)² `g2`, last seen at
    /// `last_seen`.
    fn count_ghosts(&self, g2: &[f32], last_seen: &[u32]) -> Vec<(usize, usize)> {
        let (memory, next) = (self.memory, self.next);
        g2.par_chunks(CHUNK)
            .zip(last_seen.par_chunks(CHUNK))
            .map(|(c, last)| {
                let back = c.iter().filter(|&&v| v >= 0.0).count();
                let still = c.iter().zip(last).filter(|&(&v, &l)| v < 0.0 && next - l <= memory).count();
                (back, still)
            })
            .collect()
    }

    /// Write the seen glints `g` (with (N·H)² `c2`) to their places: the kept ones with
    /// their new intensity into `kept`, the dying ones as ghosts last seen at `next - 1`
    /// into `dead`, per chunk as `tracked` counted them. Returns the lifetimes (frames
    /// seen) of the glints that died, but not of those seen since frame 0.
    fn write_seen(
        &self,
        g: &Glints,
        c2: &[f32],
        tracked: &[(usize, usize)],
        kept: Slots<'_>,
        dead: Slots<'_>,
    ) -> Vec<Vec<u32>> {
        let (lut, memory, next) = (self.lut, self.memory, self.next);
        kept.chunks(tracked.iter().map(|t| t.0))
            .into_par_iter()
            .zip(dead.chunks(tracked.iter().map(|t| t.1)))
            .enumerate()
            .map(|(k, (mut kept, mut dead))| {
                let range = k * CHUNK..((k + 1) * CHUNK).min(g.len());
                let mut lifetimes = Vec::new();
                let (mut a, mut d) = (0, 0);
                for i in range {
                    let (x, nrm, birth) = (g.position_m[i], g.normal[i], g.birth_frame[i]);
                    if c2[i] >= 0.0 {
                        kept.put(a, x, nrm, lut.get(c2[i]), birth);
                        a += 1;
                    } else {
                        if birth > 0 {
                            lifetimes.push(next - birth);
                        }
                        if memory > 0 {
                            dead.put(d, x, nrm, 0.0, next - 1);
                            d += 1;
                        }
                    }
                }
                lifetimes
            })
            .collect()
    }

    /// Write the ghosts `gh` (with (N·H)² `g2`) to their places: those seen again as
    /// glints born at `next` into `back`, those still remembered into `still`, per chunk
    /// as `remembered` counted them. Returns the gaps (frames unseen) of those back.
    fn write_ghosts(
        &self,
        gh: &Glints,
        g2: &[f32],
        remembered: &[(usize, usize)],
        back: Slots<'_>,
        still: Slots<'_>,
    ) -> Vec<Vec<u32>> {
        let (lut, memory, next) = (self.lut, self.memory, self.next);
        back.chunks(remembered.iter().map(|t| t.0))
            .into_par_iter()
            .zip(still.chunks(remembered.iter().map(|t| t.1)))
            .enumerate()
            .map(|(k, (mut back, mut still))| {
                let range = k * CHUNK..((k + 1) * CHUNK).min(gh.len());
                let mut gaps = Vec::new();
                let (mut a, mut s) = (0, 0);
                for i in range {
                    let (x, nrm, last) = (gh.position_m[i], gh.normal[i], gh.birth_frame[i]);
                    if g2[i] >= 0.0 {
                        back.put(a, x, nrm, lut.get(g2[i]), next);
                        a += 1;
                        gaps.push(next - last - 1);
                    } else if next - last <= memory {
                        still.put(s, x, nrm, 0.0, last);
                        s += 1;
                    }
                }
                gaps
            })
            .collect()
    }
}

/// Move every facet of `g` one frame in place (chunk k drawing from stream k of
/// `purpose` for frame `next`) and write (N·H)² where seen, else -1, into `c2`.
#[allow(clippy::too_many_arguments)]
fn forward_in_place(
    g: &mut Glints,
    c2: &mut Vec<f32>,
    motion: Option<&Motion>,
    to: &Seen,
    space: &Space,
    seed: u64,
    purpose: Purpose,
    next: u32,
) {
    c2.clear();
    if g.len() > c2.capacity() {
        c2.reserve_exact(g.len() + g.len() / 16);
    }
    c2.resize(g.len(), 0.0);
    g.position_m
        .par_chunks_mut(CHUNK)
        .zip(g.normal.par_chunks_mut(CHUNK))
        .zip(c2.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(k, ((xs, ns), c2))| {
            let mut rng = LaneRng::new(&mut Stream::new(seed, purpose, (u64::from(next) << 32) | k as u64));
            move_and_test(motion.map(Step::forward), to, space, xs, ns, c2, &mut rng);
        });
}

/// What one frame did (`--stats`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct StepStats {
    /// Frame now shown (0 after `new`). Not serialised: the CLI's stats carry their own.
    #[serde(skip)]
    pub frame: u32,
    /// Virtual particles N (all facets of the full system).
    pub virtual_count: u64,
    /// Facets seen now (held by the stochastic model).
    pub generated: u64,
    /// Facets held unseen because they were seen within the last `memory_frames`.
    pub ghosts: u64,
    /// Facets that became visible in this frame.
    pub births: u64,
    /// Facets that stopped being visible in this frame.
    pub deaths: u64,
    /// Candidate facets drawn and tested for birth (stochastic model).
    pub candidates: u64,
    /// Bytes of particle memory held.
    pub bytes_held: u64,
}

/// k_s I_l c^n for c² = (N·H)² in [cos²θ, 1], tabulated over t = (1 - c²)/(1 - cos²θ)
/// and read by linear interpolation: c^n = (c²)^(n/2) = exp(-k t) nearly,
/// k = ln(k_s I_l / I_e), so the relative error is below k² h²/8 = 4·10⁻⁶ for k = 6 and
/// 1024 intervals h (powf would cost a fifth of a frame; keying on c² saves a square root).
#[derive(Clone, Debug)]
struct IntensityLut {
    one_minus_cos2: f32,
    /// INTERVALS / one_minus_cos2.
    scale: f32,
    /// Brightness at t = i / INTERVALS (a fixed-size array: indices below INTERVALS need
    /// no bounds check).
    table: Box<[f32; IntensityLut::INTERVALS + 1]>,
    /// k = ln(k_s I_l / I_e) is too large for the table (I_e near 0): use powf.
    direct: Option<(f32, f32)>,
}

impl IntensityLut {
    const INTERVALS: usize = 1024;

    fn new(phong: &crate::config::Phong, cos_theta: Option<f64>) -> Self {
        let c0 = cos_theta.unwrap_or(1.0);
        let omc2 = 1.0 - c0 * c0;
        let peak = f64::from(phong.specular_k_s) * f64::from(phong.light_intensity);
        let table = Box::new(std::array::from_fn(|i| {
            let c2 = 1.0 - omc2 * i as f64 / Self::INTERVALS as f64;
            (peak * c2.max(0.0).powf(0.5 * f64::from(phong.exponent_n))) as f32
        }));
        let scale = if omc2 > 0.0 { (Self::INTERVALS as f64 / omc2) as f32 } else { 0.0 };
        // The table's error bound k² h²/8 stays below 1e-4 for k ≤ 12.
        let k = (peak / f64::from(phong.threshold_i_e)).ln();
        let direct = (!(k <= 12.0)).then_some((peak as f32, 0.5 * phong.exponent_n));
        Self { one_minus_cos2: omc2 as f32, scale, table, direct }
    }

    /// Brightness for c² = (N·H)².
    #[inline]
    fn get(&self, c2: f32) -> f32 {
        if let Some((peak, half_n)) = self.direct {
            return peak * c2.max(0.0).powf(half_n);
        }
        if !(self.one_minus_cos2 > 0.0) {
            return self.table[0];
        }
        let t = ((1.0 - c2) * self.scale).clamp(0.0, Self::INTERVALS as f32);
        // (Through u32: converting an f32 to u32 takes fewer instructions than to usize.)
        let i = (t as u32).min(Self::INTERVALS as u32 - 1);
        let f = t - i as f32;
        let i = i as usize;
        self.table[i] + (self.table[i + 1] - self.table[i]) * f
    }
}

/// Everything that decides whether a facet is seen at one frame.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Seen {
    pub(crate) geo: Geometry,
    /// cos²θ (the cone's half-angle θ < 90°; for one-sided facets N·H ≥ 0 is also required).
    pub(crate) cos2_theta: f32,
    pub(crate) two_sided: bool,
    pub(crate) dome: bool,
}

impl Seen {
    /// (N·H)² when the facet at x is seen, else `None`: N·u ≥ cos θ |u| with u = L + V
    /// (H = u/|u|), tested squared so neither H nor its length is needed. On the dome a
    /// leaf must also face the eye and the sun (the crown hides its far side).
    #[inline]
    pub(crate) fn test(&self, x: Vec3, n: Vec3, space: &Space) -> Option<f32> {
        let v = match self.geo.eye {
            Eye::Point(e) => {
                let d = e - x;
                d * (1.0 / d.length_squared().sqrt())
            }
            Eye::Direction(d) => d,
        };
        let l = match self.geo.light {
            LightAt::Direction(d) => d,
            LightAt::Position(p) => {
                let d = p - x;
                d * (1.0 / d.length_squared().sqrt())
            }
        };
        let u = l + v;
        let u2 = u.length_squared();
        let dot = n.dot(u);
        if !(u2 > 1e-12) || (!self.two_sided && dot < 0.0) || !(dot * dot >= self.cos2_theta * u2) {
            return None;
        }
        if self.dome {
            let a = space.radial_axis(x);
            if a.dot(v) <= 0.0 || a.dot(l) <= 0.0 {
                return None;
            }
        }
        Some(dot * dot / u2)
    }
}

/// One frame's motion of the diamond dust.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Motion {
    /// Displacement shared by all crystals, metres.
    pub(crate) shared_m: Vec3,
    /// Half-side of each crystal's own random displacement, metres.
    pub(crate) jitter_m: f32,
    /// Largest rotation, radians.
    pub(crate) rotation_rad: f32,
    /// sin of `rotation_rad`.
    pub(crate) sin_rotation: f32,
    pub(crate) lobe: Lobe,
}

/// Every facet of the full system (brute force).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Everything {
    position_m: Vec<Vec3>,
    normal: Vec<Vec3>,
    /// Frame since which the facet is seen, `u32::MAX` when it is not.
    since: Vec<u32>,
    /// Last frame in which it was seen, `u32::MAX` if never.
    last_seen: Vec<u32>,
}

/// The glints of §2, frame by frame.
#[derive(Clone, Debug)]
pub struct SparkleSim {
    config: SparkleConfig,
    seed: u64,
    frame: u32,
    virtual_count: u64,
    space: Space,
    lobe: Lobe,
    cos_theta: Option<f64>,
    gust_phase: [[f32; 3]; 3],
    intensity: IntensityLut,
    glints: Glints,
    /// Facets seen within the last `memory_frames` frames but not now; `birth_frame`
    /// holds the last frame each was seen.
    ghosts: Glints,
    /// Last frame's arrays, reused for the next frame's (no allocation per frame).
    spare_glints: Glints,
    spare_ghosts: Glints,
    /// (N·H)² or -1 per held glint and ghost, this frame.
    c2: Vec<f32>,
    g2: Vec<f32>,
    everything: Option<Everything>,
    lifetimes: Vec<u32>,
    gaps: Vec<u32>,
    last: StepStats,
    /// The last birth table's split cells' window shapes, for the next one.
    split_memo: SplitMemo,
}

impl SparkleSim {
    /// Build the simulation and generate frame 0's visible facets.
    pub fn new(config: SparkleConfig, seed: u64) -> Result<Self, SparkleError> {
        let mut sim = Self::unstarted(config, seed)?;
        sim.start();
        Ok(sim)
    }

    /// Whether [`SparkleSim::new`] accepts `config`, without generating anything: its
    /// validation and the bound on frame 0's birth candidates (cheap: per-cell tables
    /// only).
    pub fn check(config: &SparkleConfig) -> Result<(), SparkleError> {
        Self::unstarted(*config, 0).map(|_| ())
    }

    /// The simulation before frame 0 is drawn, refused when its candidates would flood.
    fn unstarted(config: SparkleConfig, seed: u64) -> Result<Self, SparkleError> {
        config.validate().map_err(InvalidConfig::from)?;
        let lobe = match config.population {
            Population::DiamondDust(Dust { normals: Normals::Uniform, .. }) => Lobe::new(0.0),
            Population::DiamondDust(Dust { normals: Normals::Plates { tilt_deg }, .. }) => {
                Lobe::from_spread_deg(tilt_deg)
            }
            Population::LeafGlitter(l) => Lobe::from_spread_deg(l.spread_deg),
        };
        let mut gust_phase = [[0.0; 3]; 3];
        for (axis, phases) in gust_phase.iter_mut().enumerate() {
            let mut rng = Stream::new(seed, GUST, axis as u64);
            for p in phases.iter_mut() {
                *p = std::f32::consts::TAU * rng.next_f32();
            }
        }
        let sim = Self {
            space: Space::of(&config.population),
            virtual_count: config.virtual_count(),
            cos_theta: config.phong.cos_theta(),
            intensity: IntensityLut::new(&config.phong, config.phong.cos_theta()),
            config,
            seed,
            frame: 0,
            lobe,
            gust_phase,
            glints: Glints::default(),
            ghosts: Glints::default(),
            spare_glints: Glints::default(),
            spare_ghosts: Glints::default(),
            c2: Vec::new(),
            g2: Vec::new(),
            everything: None,
            lifetimes: Vec::new(),
            gaps: Vec::new(),
            last: StepStats::default(),
            split_memo: SplitMemo::default(),
        };
        if sim.config.method == crate::config::Method::Stochastic
            && let Some(expected) = sim.candidate_bound(0)
            && expected > crate::config::MAX_CANDIDATES
        {
            return Err(InvalidConfig::from(vec![Issue {
                field: "phong.threshold_i_e".into(),
                value: sim.config.phong.threshold_i_e.to_string(),
                expected: Expected::Text(format!(
                    "fewer than {:e} candidate facets per frame: this cone and lobe give up to {expected:.3e}; raise the threshold or the exponent, or lower the count",
                    crate::config::MAX_CANDIDATES
                )),
            }])
            .into());
        }
        Ok(sim)
    }

    /// The number of candidates a birth step into `frame` draws (an upper bound of the
    /// facets seen there); `None` when nothing can be seen.
    fn candidate_bound(&self, frame: u32) -> Option<f64> {
        let c = self.cos_theta?;
        let delta = if frame == 0 { 0.0 } else { self.config.step_rotation_rad() };
        let alpha = (c.acos() + delta + CAP_MARGIN_RAD).min(std::f64::consts::PI);
        let to = self.seen_at(frame);
        let table = CellTable::build(
            &self.space,
            &self.lobe,
            &to.geo,
            alpha,
            self.config.phong.two_sided,
            self.virtual_count,
            None,
            None,
        );
        Some(self.virtual_count as f64 * table.mean_q)
    }

    /// The configuration.
    pub fn config(&self) -> &SparkleConfig {
        &self.config
    }

    /// Frame now shown (0 after `new`).
    pub fn frame(&self) -> u32 {
        self.frame
    }

    /// Time now, seconds.
    pub fn time_s(&self) -> f32 {
        self.frame as f32 * self.config.dt_s()
    }

    /// The facets seen now.
    pub fn glints(&self) -> &Glints {
        &self.glints
    }

    /// Lifetimes, in frames, of the glints that stopped being visible in the last step
    /// and had been born after frame 0 (those visible at the start are left out: their
    /// beginning is unknown).
    pub fn finished_lifetimes(&self) -> &[u32] {
        &self.lifetimes
    }

    /// For each glint born in the last step: how many frames it had been unseen, 1 to
    /// `memory_frames`, or `memory_frames + 1` for longer (or never seen before).
    pub fn birth_gaps(&self) -> &[u32] {
        &self.gaps
    }

    /// Counters of the last frame.
    pub fn stats(&self) -> StepStats {
        self.last
    }

    /// Whether no facet can ever be seen (I_e ≥ k_s I_l): the frames show the background.
    pub fn cone_is_empty(&self) -> bool {
        self.cos_theta.is_none()
    }

    /// Advance one frame. Fails only when a lobe population under a moving light would
    /// draw more candidates than [`crate::MAX_CANDIDATES`] (the state is then unchanged).
    pub fn step(&mut self) -> Result<StepStats, SparkleError> {
        let next = self.frame + 1;
        self.gaps.clear();
        let (births, deaths, candidates) = match self.cos_theta {
            None => (0, 0, 0),
            Some(_) if self.everything.is_some() => self.step_brute(next),
            Some(_) => self.step_stochastic(next)?,
        };
        self.frame = next;
        self.last = self.stats_now(births, deaths, candidates);
        Ok(self.last)
    }

    fn stats_now(&self, births: u64, deaths: u64, candidates: u64) -> StepStats {
        let held = match &self.everything {
            Some(e) => {
                (e.position_m.capacity() * 24 + (e.since.capacity() + e.last_seen.capacity()) * 4) as u64
                    + self.glints.bytes()
            }
            // The held facets, last frame's arrays kept for reuse, and the test results.
            None => {
                self.glints.bytes()
                    + self.ghosts.bytes()
                    + self.spare_glints.bytes()
                    + self.spare_ghosts.bytes()
                    + ((self.c2.capacity() + self.g2.capacity()) * 4) as u64
                    + self.split_memo.bytes()
            }
        };
        StepStats {
            frame: self.frame,
            virtual_count: self.virtual_count,
            generated: self.glints.len() as u64,
            ghosts: self.ghosts.len() as u64,
            births,
            deaths,
            candidates,
            bytes_held: held,
        }
    }

    fn seen_at(&self, frame: u32) -> Seen {
        let cam = &self.config.camera;
        let eye = match cam.projection {
            Projection::Orthographic { .. } => {
                Eye::Direction((cam.position - cam.look_at).normalize_or(Vec3::Z))
            }
            _ => Eye::Point(cam.position),
        };
        let t = frame as f32 * self.config.dt_s();
        Seen {
            geo: Geometry { eye, light: self.config.light.at(t) },
            cos2_theta: self.cos_theta.map_or(4.0, |c| c * c) as f32,
            two_sided: self.config.phong.two_sided,
            dome: matches!(self.space, Space::Dome { .. }),
        }
    }

    /// The dust's motion from `frame - 1` to `frame`; `None` for static leaves.
    fn motion_into(&self, frame: u32) -> Option<Motion> {
        let Population::DiamondDust(d) = self.config.population else { return None };
        let dt = self.config.dt_s();
        let t = (frame as f32 - 0.5) * dt;
        // The gust: three sinusoids per axis (0.13, 0.29, 0.71 Hz, random phases), scaled
        // to an rms of `gust_m_per_s` horizontally and a third of it vertically.
        let freqs = [0.13f32, 0.29, 0.71];
        let mut gust = [0.0f32; 3];
        for (g, phases) in gust.iter_mut().zip(&self.gust_phase) {
            *g =
                freqs.iter().zip(phases).map(|(f, p)| (std::f32::consts::TAU * f * t + p).sin()).sum::<f32>()
                    / 1.5f32.sqrt();
        }
        let gust = Vec3::new(gust[0], gust[1] / 3.0, gust[2]) * d.gust_m_per_s;
        let velocity = d.wind_m_per_s + gust - Vec3::Y * d.fall_speed_m_per_s;
        Some(Motion {
            shared_m: velocity * dt,
            jitter_m: d.turbulence_m_per_s * dt,
            rotation_rad: d.rotation_deg_per_frame.to_radians(),
            sin_rotation: d.rotation_deg_per_frame.to_radians().sin(),
            lobe: self.lobe,
        })
    }

    fn start(&mut self) {
        if self.cos_theta.is_none() {
            self.last = self.stats_now(0, 0, 0);
            return;
        }
        let to = self.seen_at(0);
        if self.config.method == crate::config::Method::BruteForce {
            let n = self.virtual_count as usize;
            // Filled in place, chunk by chunk (no second copy of the population).
            let mut all = Everything {
                position_m: vec![Vec3::ZERO; n],
                normal: vec![Vec3::ZERO; n],
                since: vec![u32::MAX; n],
                last_seen: vec![u32::MAX; n],
            };
            let (space, lobe, lut, seed) = (self.space, self.lobe, &self.intensity, self.seed);
            let parts: Vec<Glints> = all
                .position_m
                .par_chunks_mut(CHUNK)
                .zip(all.normal.par_chunks_mut(CHUNK))
                .zip(all.since.par_chunks_mut(CHUNK))
                .zip(all.last_seen.par_chunks_mut(CHUNK))
                .enumerate()
                .map(|(k, (((xs, ns), since), last))| {
                    let mut rng = Stream::new(seed, BRUTE, k as u64);
                    let mut g = Glints::default();
                    for (((x, nrm), s), l) in
                        xs.iter_mut().zip(ns.iter_mut()).zip(since.iter_mut()).zip(last.iter_mut())
                    {
                        *x = space.sample_in_cell(0, 1, &mut rng);
                        *nrm = lobe.sample(space.radial_axis(*x), &mut rng);
                        if let Some(c) = to.test(*x, *nrm, &space) {
                            g.push(*x, *nrm, lut.get(c), 0);
                            *s = 0;
                            *l = 0;
                        }
                    }
                    g
                })
                .collect();
            for mut g in parts {
                self.glints.append(&mut g);
            }
            self.everything = Some(all);
            self.last = self.stats_now(self.glints.len() as u64, 0, 0);
        } else {
            let (mut born, candidates) = self.generate(&to, 0, None);
            let births = born.len() as u64;
            self.glints.append(&mut born);
            self.last = self.stats_now(births, 0, candidates);
        }
    }

    /// The candidate cells of a birth step into `frame` (tested at `to`), and the cap's
    /// half-angle α = θ + δ + margin they use.
    fn birth_table(&self, to: &Seen, frame: u32, memo: Option<&mut SplitMemo>) -> (CellTable, f64) {
        let motion = if frame == 0 { None } else { self.motion_into(frame) };
        let delta = motion.map_or(0.0, |m| f64::from(m.rotation_rad));
        let theta = self.cos_theta.unwrap_or(1.0).acos();
        let alpha = (theta + delta + CAP_MARGIN_RAD).min(std::f64::consts::PI);
        let two_sided = self.config.phong.two_sided;
        // Births into a later frame skip the normals certainly seen at the one before.
        let from = (frame > 0).then(|| self.seen_at(frame - 1));
        let inner = match (&from, motion, self.space) {
            (Some(from), Some(m), Space::Box { min, size }) => InnerSplit::of(min, size, &m, from, to, theta),
            _ => None,
        };
        let n = self.virtual_count;
        (CellTable::build(&self.space, &self.lobe, &to.geo, alpha, two_sided, n, inner, memo), alpha)
    }

    /// Draw the facets seen at `to` (frame `frame`) that the held set does not already
    /// account for: at frame 0 every facet seen; later, those unseen in each of the
    /// frames `frame - 1 - memory_frames ..= frame - 1` (the others are held, seen or as
    /// ghosts). See the module docs. Returns them and the candidate count.
    fn generate(&self, to: &Seen, frame: u32, table: Option<(CellTable, f64)>) -> (Glints, u64) {
        let motion = if frame == 0 { None } else { self.motion_into(frame) };
        let theta = self.cos_theta.unwrap_or(1.0).acos();
        let (table, alpha) = table.unwrap_or_else(|| self.birth_table(to, frame, None));
        // The frames looked back at, newest first: (test at frame f, motion into f).
        let history: Vec<(Seen, Option<Motion>)> = if frame == 0 {
            Vec::new()
        } else {
            let oldest = frame.saturating_sub(1 + self.config.memory_frames);
            (oldest..frame).rev().map(|f| (self.seen_at(f), self.motion_into(f))).collect()
        };
        let n = self.virtual_count;
        let regions = match (history.first(), motion, self.space) {
            (Some((from, _)), Some(m), Space::Box { min, size }) if table.uniform => {
                // Cells per axis: building a cell costs about what drawing 16 candidates
                // does, so a finer grid pays only when the whole cap holds many more.
                let whole_cap = n as f64 * table.mean_q;
                let cells = ((whole_cap / 16.0).cbrt() as usize).clamp(2, 16);
                Regions::build(min, size, &m, from, to, theta, alpha, self.config.phong.two_sided, cells)
            }
            _ => None,
        };
        let mean_q = regions.as_ref().map_or(table.mean_q, |r| r.mean_q);
        let chunks = ((n as f64 * mean_q / CANDIDATES_PER_CHUNK).ceil() as u64).clamp(1, MAX_BIRTH_CHUNKS);
        let walk = Walk { history: &history, motion, space: &self.space, lut: &self.intensity, frame };
        let births = Births { to, walk, table: &table, lobe: &self.lobe, n, chunks, mean_q };
        let parts: Vec<(Glints, u64)> = (0..chunks)
            .into_par_iter()
            .map(|k| {
                let mut rng = Stream::new(self.seed, BIRTH, (u64::from(frame) << 32) | k);
                let mut lanes = LaneRng::new(&mut rng);
                let mut out = Glints::default();
                let mut seen = Survivors::default();
                let count = match &regions {
                    Some(r) => births.by_region(r, k, &mut rng, &mut lanes, &mut seen, &mut out),
                    None if !table.boxes.is_empty() => {
                        births.by_cells(k, &mut rng, &mut lanes, &mut seen, &mut out)
                    }
                    None => births.by_table(k, &mut rng, &mut lanes, &mut seen, &mut out),
                };
                births.walk.back(&mut seen, &mut lanes, &mut out);
                (out, count)
            })
            .collect();
        let mut all = Glints::default();
        let mut candidates = 0;
        for (mut g, c) in parts {
            all.append(&mut g);
            candidates += c;
        }
        (all, candidates)
    }

    /// Move the held glints (seen, then ghosts) one frame, delete the seen ones that left
    /// the cone (they become ghosts), bring back ghosts seen again, and add the newborn.
    /// Returns (births, deaths, candidates).
    fn step_stochastic(&mut self, next: u32) -> Result<(u64, u64, u64), SparkleError> {
        let to = self.seen_at(next);
        // Lobes: the memory guard's bound comes from the table the births then use.
        let table = if !self.lobe.is_uniform() && self.cos_theta.is_some() {
            let mut memo = std::mem::take(&mut self.split_memo);
            let table = self.birth_table(&to, next, Some(&mut memo));
            self.split_memo = memo;
            let expected = self.virtual_count as f64 * table.0.mean_q;
            if expected > crate::config::MAX_CANDIDATES {
                return Err(SparkleError::TooManyCandidates {
                    frame: next,
                    expected,
                    max: crate::config::MAX_CANDIDATES,
                });
            }
            Some(table)
        } else {
            None
        };
        let motion = self.motion_into(next);
        let memory = self.config.memory_frames;
        let (space, seed) = (self.space, self.seed);
        // Move and test every held facet in place: chunk k of the seen glints draws its
        // random numbers from TRACK stream k, of the ghosts from GHOST stream k.
        let mut c2 = std::mem::take(&mut self.c2);
        let mut g2 = std::mem::take(&mut self.g2);
        forward_in_place(&mut self.glints, &mut c2, motion.as_ref(), &to, &space, seed, TRACK, next);
        forward_in_place(&mut self.ghosts, &mut g2, motion.as_ref(), &to, &space, seed, GHOST, next);
        let (born, candidates) = self.generate(&to, next, table);
        // Seen glints are kept, or die (becoming ghosts last seen at next - 1); ghosts
        // are seen again (a birth after a short gap), still remembered, or forgotten once
        // unseen for more than `memory` frames. Counted per chunk first, then written
        // straight to their places in the next frame's arrays, chunk by chunk in
        // parallel, in the order of the chunks: kept, back, newborn; dead, still.
        let fates = Fates { lut: &self.intensity, memory, next };
        let tracked = fates.count_seen(&c2);
        let remembered = fates.count_ghosts(&g2, &self.ghosts.birth_frame);
        let kept: usize = tracked.iter().map(|t| t.0).sum();
        let back: usize = remembered.iter().map(|t| t.0).sum();
        let dead: usize = tracked.iter().map(|t| t.1).sum();
        let still: usize = remembered.iter().map(|t| t.1).sum();
        let mut glints = std::mem::take(&mut self.spare_glints);
        let mut ghosts = std::mem::take(&mut self.spare_ghosts);
        glints.resize(kept + back + born.len());
        ghosts.resize(dead + still);
        let (to_glints, to_ghosts) = (Slots::of(&mut glints), Slots::of(&mut ghosts));
        let (kept_slots, rest) = to_glints.split(kept);
        let (back_slots, mut born_slots) = rest.split(back);
        let (dead_slots, still_slots) = to_ghosts.split(dead);
        let lifetimes = fates.write_seen(&self.glints, &c2, &tracked, kept_slots, dead_slots);
        let gaps = fates.write_ghosts(&self.ghosts, &g2, &remembered, back_slots, still_slots);
        born_slots.put_all(&born);
        self.lifetimes.clear();
        self.lifetimes.extend(lifetimes.into_iter().flatten());
        self.gaps.extend(gaps.into_iter().flatten());
        self.gaps.extend(std::iter::repeat_n(memory + 1, born.len()));
        let deaths = (self.glints.len() - kept) as u64;
        let births = (back + born.len()) as u64;
        // The old arrays become next frame's spares.
        self.spare_glints = std::mem::replace(&mut self.glints, glints);
        self.spare_ghosts = std::mem::replace(&mut self.ghosts, ghosts);
        (self.c2, self.g2) = (c2, g2);
        Ok((births, deaths, candidates))
    }

    fn step_brute(&mut self, next: u32) -> (u64, u64, u64) {
        let to = self.seen_at(next);
        let motion = self.motion_into(next);
        let lut = &self.intensity;
        let space = self.space;
        let seed = self.seed;
        let memory = self.config.memory_frames;
        let Some(all) = self.everything.as_mut() else { return (0, 0, 0) };
        let parts: Vec<(Glints, Vec<u32>, Vec<u32>, u64)> = all
            .position_m
            .par_chunks_mut(CHUNK)
            .zip(all.normal.par_chunks_mut(CHUNK))
            .zip(all.since.par_chunks_mut(CHUNK))
            .zip(all.last_seen.par_chunks_mut(CHUNK))
            .enumerate()
            .map(|(k, (((xs, ns), since), last))| {
                let mut rng = LaneRng::new(&mut Stream::new(seed, BRUTE, (u64::from(next) << 32) | k as u64));
                let mut g = Glints::default();
                let mut lifetimes = Vec::new();
                let mut gaps = Vec::new();
                let mut deaths = 0;
                let mut c2 = vec![0.0; xs.len()];
                move_and_test(motion.as_ref().map(Step::forward), &to, &space, xs, ns, &mut c2, &mut rng);
                for ((((x, nrm), s), l), &c) in
                    xs.iter().zip(ns.iter()).zip(since.iter_mut()).zip(last.iter_mut()).zip(&c2)
                {
                    if c >= 0.0 {
                        if *s == u32::MAX {
                            *s = next;
                            let gap =
                                if *l == u32::MAX { memory + 1 } else { (next - *l - 1).min(memory + 1) };
                            gaps.push(gap);
                        }
                        *l = next;
                        g.push(*x, *nrm, lut.get(c), *s);
                    } else if *s != u32::MAX {
                        deaths += 1;
                        if *s > 0 {
                            lifetimes.push(next - *s);
                        }
                        *s = u32::MAX;
                    }
                }
                (g, lifetimes, gaps, deaths)
            })
            .collect();
        self.glints = Glints::default();
        self.lifetimes.clear();
        let (mut births, mut deaths) = (0, 0);
        for (mut g, l, gaps, d) in parts {
            self.glints.append(&mut g);
            self.lifetimes.extend(l);
            births += gaps.len() as u64;
            self.gaps.extend(gaps);
            deaths += d;
        }
        (births, deaths, 0)
    }
}

/// Birth candidates seen at t+1, waiting to be walked back through the remembered
/// frames.
#[derive(Default)]
struct Survivors {
    /// At t+1: position, normal and (N·H)².
    x1: Vec<Vec3>,
    n1: Vec<Vec3>,
    c2: Vec<f32>,
    /// Position and normal at the frame the walk has reached.
    x: Vec<Vec3>,
    nrm: Vec<Vec3>,
    /// Scratch of the walk: survivors still unseen, and their test at one frame.
    alive: Vec<u32>,
    seen_then: Vec<f32>,
}

impl Survivors {
    fn len(&self) -> usize {
        self.x1.len()
    }

    /// Keep the lanes of `mask` seen at t+1 (`c2` ≥ 0), in lane order; `n0` is the
    /// normal at t, where the walk starts.
    #[inline]
    fn push_seen(&mut self, x1: &V8, n0: &V8, n1: &V8, c2: f32x8, mask: u32) {
        let mut keep = mask & c2.simd_ge(f32x8::ZERO).to_bitmask();
        let c = c2.to_array();
        while keep != 0 {
            let i = keep.trailing_zeros() as usize;
            keep &= keep - 1;
            let x = lane(x1, i);
            self.x1.push(x);
            self.n1.push(lane(n1, i));
            self.c2.push(c[i]);
            self.x.push(x);
            self.nrm.push(lane(n0, i));
        }
    }
}

/// The walk of birth candidates back through the remembered frames (module docs).
struct Walk<'a> {
    /// (test at frame f, motion into f), newest first.
    history: &'a [(Seen, Option<Motion>)],
    /// The motion into the frame being made.
    motion: Option<Motion>,
    space: &'a Space,
    lut: &'a IntensityLut,
    frame: u32,
}

impl Walk<'_> {
    /// Walk every survivor back: seen in any remembered frame means the facet is held
    /// already; the others are born, into `out`. Going back, the position undoes each
    /// frame's displacement (uniform positions make x_{t+1} and the own step
    /// independent) and the normal takes the same Metropolis step (reversible, so its
    /// reverse kernel is itself). Leaves `s` empty.
    fn back(&self, s: &mut Survivors, lanes: &mut LaneRng, out: &mut Glints) {
        s.alive.clear();
        s.alive.extend(0..s.x1.len() as u32);
        let mut into = self.motion;
        for (k, (seen, m)) in self.history.iter().enumerate() {
            if s.alive.is_empty() {
                break;
            }
            let back = into.as_ref().map(|mi| Step { motion: mi, shift: -1.0, turn: k > 0 });
            s.seen_then.resize(s.x.len(), 0.0);
            move_and_test(back, seen, self.space, &mut s.x, &mut s.nrm, &mut s.seen_then, lanes);
            let mut w = 0;
            for r in 0..s.alive.len() {
                if s.seen_then[r] < 0.0 {
                    (s.alive[w], s.x[w], s.nrm[w]) = (s.alive[r], s.x[r], s.nrm[r]);
                    w += 1;
                }
            }
            s.alive.truncate(w);
            s.x.truncate(w);
            s.nrm.truncate(w);
            into = *m;
        }
        out.reserve(s.alive.len());
        for &i in &s.alive {
            let i = i as usize;
            out.push(s.x1[i], s.n1[i], self.lut.get(s.c2[i]), self.frame);
        }
        s.x1.clear();
        s.n1.clear();
        s.c2.clear();
        s.x.clear();
        s.nrm.clear();
    }
}

/// What the birth chunks draw from: the test at the new frame `to`, the walk back
/// through the remembered frames, the candidate cells, the normals' lobe, the population
/// of `n` virtual facets shared among `chunks` chunks, and the candidate probability per
/// facet `mean_q`.
struct Births<'a> {
    to: &'a Seen,
    walk: Walk<'a>,
    table: &'a CellTable,
    lobe: &'a Lobe,
    n: u64,
    chunks: u64,
    mean_q: f64,
}

impl Births<'_> {
    /// Chunk `k`'s candidates drawn region by region ([`Regions`]: each with its Poisson
    /// count, in lanes), into `seen`, walked back into `out` every [`CANDIDATE_BATCH`];
    /// returns the candidate count.
    fn by_region(
        &self,
        r: &Regions,
        k: u64,
        rng: &mut Stream,
        lanes: &mut LaneRng,
        seen: &mut Survivors,
        out: &mut Glints,
    ) -> u64 {
        let (to, motion, space) = (self.to, self.walk.motion, self.walk.space);
        let mut count = 0;
        // This chunk's run of regions, each with its Poisson count.
        for i in r.range(k, self.chunks) {
            let lambda = self.n as f64 * r.mass[i];
            let Ok(poisson) = rand_distr::Poisson::new(lambda) else { continue };
            let c = rng.sample(&poisson) as u64;
            count += c;
            let (corner, size, omc_inner) = r.boxes[i];
            let omc = (omc_inner as f32, r.one_minus_cos_alpha as f32);
            for start in (0..c).step_by(LANES) {
                let (x1, n0, fine) = to.geo.candidates_in(corner, size, omc, r.two_sided, lanes);
                let (n1, c2) = first_frame(motion.as_ref(), to, space, x1, n0, lanes);
                let lanes_used = (c - start).min(LANES as u64) as u32;
                seen.push_seen(&x1, &n0, &n1, c2, fine & ((1u32 << lanes_used) - 1));
            }
            if seen.len() >= CANDIDATE_BATCH as usize {
                self.walk.back(seen, lanes, out);
            }
        }
        count
    }

    /// Chunk `k`'s candidates from the box's split cells ([`CellTable::split`]): its run
    /// of cells ([`CellTable::range`]), each with its Poisson count (the population of
    /// mean N of the module docs, as [`Births::by_region`] draws), drawn in the cell
    /// (no search for the cell) and tested in lanes into `seen`, walked back into `out`
    /// every [`CANDIDATE_BATCH`]; returns the count.
    fn by_cells(
        &self,
        k: u64,
        rng: &mut Stream,
        lanes: &mut LaneRng,
        seen: &mut Survivors,
        out: &mut Glints,
    ) -> u64 {
        let (to, space, table) = (self.to, self.walk.space, self.table);
        let (mut x1, mut n0) = (Vec::new(), Vec::new());
        let mut count = 0;
        let range = table.range(k, self.chunks);
        let last = range.end;
        for c in range {
            let before = if c == 0 { 0.0 } else { table.cumulative[c - 1] };
            let lambda = self.n as f64 * (table.cumulative[c] - before);
            if let Ok(poisson) = rand_distr::Poisson::new(lambda) {
                let m = rng.sample(&poisson) as u64;
                count += m;
                for _ in 0..m {
                    if let Some((x, n)) = table.draw_in(c, space, self.lobe, &to.geo, rng) {
                        x1.push(x);
                        n0.push(n);
                    }
                }
            }
            // Test and walk back every batch, and what is left after the last cell.
            if x1.len() >= CANDIDATE_BATCH as usize || (c + 1 == last && !x1.is_empty()) {
                self.test_and_walk(&x1, &n0, lanes, seen, out);
                x1.clear();
                n0.clear();
            }
        }
        count
    }

    /// Chunk `k`'s candidates: its share of the facets, a binomial count of them drawn
    /// from the candidate cells ([`CellTable`]) in batches of [`CANDIDATE_BATCH`], each
    /// tested in lanes into `seen` and walked back into `out`; returns the count.
    fn by_table(
        &self,
        k: u64,
        rng: &mut Stream,
        lanes: &mut LaneRng,
        seen: &mut Survivors,
        out: &mut Glints,
    ) -> u64 {
        let (to, space) = (self.to, self.walk.space);
        let (n, chunks) = (self.n, self.chunks);
        let len = n / chunks + u64::from(k < n % chunks);
        let count = rng.binomial(len, self.mean_q);
        let (mut x1, mut n0) = (Vec::new(), Vec::new());
        let mut left = count;
        while left > 0 {
            let batch = left.min(CANDIDATE_BATCH);
            left -= batch;
            x1.clear();
            n0.clear();
            for _ in 0..batch {
                if let Some((x, n)) = self.table.draw(space, self.lobe, &to.geo, rng) {
                    x1.push(x);
                    n0.push(n);
                }
            }
            self.test_and_walk(&x1, &n0, lanes, seen, out);
        }
        count
    }

    /// Candidates (positions `x1` at the new frame, normals `n0` at the one before): each
    /// moved one step and tested in lanes into `seen`, then walked back into `out`.
    fn test_and_walk(
        &self,
        x1: &[Vec3],
        n0: &[Vec3],
        lanes: &mut LaneRng,
        seen: &mut Survivors,
        out: &mut Glints,
    ) {
        let (to, motion, space) = (self.to, self.walk.motion, self.walk.space);
        for (xc, nc) in x1.chunks(LANES).zip(n0.chunks(LANES)) {
            let (x1, n0) = (V8::load(xc), V8::load(nc));
            let (n1, c2) = first_frame(motion.as_ref(), to, space, x1, n0, lanes);
            seen.push_seen(&x1, &n0, &n1, c2, (1u32 << xc.len()) - 1);
        }
        self.walk.back(seen, lanes, out);
    }
}

/// Birth candidates in the periodic box with uniform normals, by region: a facet whose
/// normal at t lay within an inner angle β of ±H_{t+1}(x_{t+1}) was certainly seen at t,
/// so only the annulus between β and α (α = θ + δ + margin) holds candidates.
///
/// The facet moved by at most d (the shared displacement plus its own) without wrapping,
/// so with u = L + V, |u_t(x_t) - u_{t+1}(x_{t+1})| ≤ e = d/r_eye + d/r_lamp + |L_t - L_{t+1}|
/// (V and a lamp's L are 1/r-Lipschitz, r the least distance along the way; the sun's L
/// moves by a chord). A vector within e of u_{t+1} makes an angle of at most
/// η = asin(e/|u_{t+1}|) with it (the ball of radius e around u_{t+1} subtends that
/// half-angle from the origin; none when e ≥ |u_{t+1}|), so H turns by at most η, and a
/// normal within β = θ' - η of ±H_{t+1} (θ' = θ minus the cap margin) is within θ' of
/// ±H_t: seen. The interior of the box is cut into up to 16³ cells (fewer when few
/// candidates are expected), each with the bound over its points (|u_{t+1}| at least its
/// value at the centre minus its Lipschitz constant times the cell's radius); thin slabs
/// along the faces, where a facet may have wrapped from the other side, keep the whole
/// cap.
struct Regions {
    /// (corner, size, 1 - cos β) per region.
    boxes: Vec<(Vec3, Vec3, f64)>,
    /// Candidate probability per virtual facet of each region.
    mass: Vec<f64>,
    /// Sum of `mass` before each region, and over all.
    mass_before: Vec<f64>,
    mass_total: f64,
    mean_q: f64,
    one_minus_cos_alpha: f64,
    two_sided: bool,
}

impl Regions {
    #[allow(clippy::too_many_arguments)]
    fn build(
        min: Vec3,
        size: Vec3,
        m: &Motion,
        from: &Seen,
        to: &Seen,
        theta: f64,
        alpha: f64,
        two_sided: bool,
        cells_per_axis: usize,
    ) -> Option<Self> {
        let omc_alpha = one_minus_cos(alpha);
        let inner = InnerSplit::of(min, size, m, from, to, theta)?;
        let mut boxes = Vec::new();
        let (lo, hi) = (inner.interior.0 - min, min + size - inner.interior.1);
        let (cmin, cmax) = carve_face_slabs(min, min + size, lo, hi, &mut boxes);
        let n = cells_per_axis;
        let cell = (cmax - cmin) / n as f32;
        let bound = InnerCap { radius_m: f64::from(0.5 * cell.length()), ..inner.cap };
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let corner = cmin + cell * Vec3::new(i as f32, j as f32, k as f32);
                    let centre = corner + 0.5 * cell;
                    boxes.push((corner, cell, bound.one_minus_cos_beta(to, centre).min(omc_alpha)));
                }
            }
        }
        let volume = f64::from(size.x) * f64::from(size.y) * f64::from(size.z);
        let sides = if two_sided { 2.0 } else { 1.0 };
        let mass: Vec<f64> = boxes
            .iter()
            .map(|(_, s, omc_inner)| {
                let w = f64::from(s.x) * f64::from(s.y) * f64::from(s.z) / volume;
                w * sides * 0.5 * (omc_alpha - omc_inner)
            })
            .collect();
        // Running sums, so they never decrease (`range` bisects them).
        let mut total = 0.0;
        let mass_before = mass
            .iter()
            .map(|m| {
                let before = total;
                total += m;
                before
            })
            .collect();
        Some(Self {
            boxes,
            mass,
            mass_before,
            mass_total: total,
            mean_q: total.min(1.0),
            one_minus_cos_alpha: omc_alpha,
            two_sided,
        })
    }

    /// The regions birth chunk `k` of `chunks` draws: consecutive runs holding about
    /// equal shares of the candidate mass (the split depends only on the masses).
    fn range(&self, k: u64, chunks: u64) -> std::ops::Range<usize> {
        let total = self.mass_total;
        let at = |k: u64| {
            if k >= chunks {
                self.mass.len()
            } else {
                self.mass_before.partition_point(|&b| b * (chunks as f64) < k as f64 * total)
            }
        };
        at(k)..at(k + 1)
    }
}

/// The slabs along the faces of the box `min..max` where a facet may have wrapped from
/// the other side, `lo` and `hi` thick at the low and high face of each axis, made
/// disjoint by carving axis by axis, pushed to `boxes` with no inner cap (1 - cos β =
/// 0). Returns the interior left.
fn carve_face_slabs(
    min: Vec3,
    max: Vec3,
    lo: Vec3,
    hi: Vec3,
    boxes: &mut Vec<(Vec3, Vec3, f64)>,
) -> (Vec3, Vec3) {
    let (mut cmin, mut cmax) = (min, max);
    for axis in 0..3 {
        let (mut a_lo, mut a_hi) = (cmin, cmax);
        a_hi[axis] = cmin[axis] + lo[axis];
        boxes.push((a_lo, a_hi - a_lo, 0.0));
        a_lo = cmin;
        a_hi = cmax;
        a_lo[axis] = cmax[axis] - hi[axis];
        boxes.push((a_lo, a_hi - a_lo, 0.0));
        cmin[axis] += lo[axis];
        cmax[axis] -= hi[axis];
    }
    (cmin, cmax)
}

/// The inner angle β of an interior cell of [`Regions`] (or a split cell, through
/// [`InnerSplit`]): how far H can turn for a facet
/// that ends in the cell (η, from the bound e on the change of u = L + V), so that
/// normals within β = θ' - η of ±H_{t+1} were certainly seen at t.
struct InnerCap {
    /// The eye and the lamp (the points L and V are 1/r-Lipschitz about).
    far: Vec<Vec3>,
    /// How far the sun's L moves in the step (a chord; 0 for a lamp).
    sun_chord: f64,
    /// Most a facet moves in the step, m.
    reach_m: f64,
    /// Half a cell's diagonal, m.
    radius_m: f64,
    /// θ' = θ minus the cap margin.
    theta_in: f64,
}

impl InnerCap {
    /// 1 - cos β for the cell centred at `centre`, 0 when the cell or a facet's path out
    /// of it comes near the eye or the lamp, or when no bound holds (e ≥ |u_{t+1}|).
    fn one_minus_cos_beta(&self, to: &Seen, centre: Vec3) -> f64 {
        self.one_minus_cos_beta_within(to, centre, self.radius_m)
    }

    /// [`InnerCap::one_minus_cos_beta`] for a cell of half-diagonal `radius` m.
    fn one_minus_cos_beta_within(&self, to: &Seen, centre: Vec3, radius: f64) -> f64 {
        let reach = self.reach_m;
        // Least distances from the cell (and the path of length `reach` out of it) to the
        // eye and the lamp.
        let mut e = self.sun_chord;
        let mut lip = 0.0;
        let mut near = false;
        for p in &self.far {
            let dist = f64::from((*p - centre).length());
            let (r_cell, r_path) = (dist - radius, dist - radius - reach);
            if !(r_path > 0.0) {
                near = true;
                break;
            }
            e += reach / r_path;
            lip += 1.0 / r_cell;
        }
        let u_min = f64::from((to.geo.light_dir(centre) + to.geo.eye_dir(centre)).length()) - lip * radius;
        if near || !(e < u_min) {
            0.0
        } else {
            let eta = (e / u_min).asin();
            if self.theta_in > eta { one_minus_cos(self.theta_in - eta) } else { 0.0 }
        }
    }
}

/// Candidate probabilities per cell for one frame (module `model`'s thinning).
///
/// In the box with a lobe the cells are split adaptively (an extension for speed, not
/// in the paper): each of the 16³ equal cells whose windows would draw more than
/// [`SPLIT_DRAWS`] candidates is cut into eight, recursively, down to [`SPLIT_DEPTH`]
/// halvings (within [`SPLIT_BUDGET`]). Each split cell and side has a [`Window`]: the
/// lobe restricted to angles that hold the cap around ±H(x) for every x of the cell
/// (kept when in the cap), or, where that draws more, normals uniform in the cap thinned
/// by the lobe's density over its bound there. Smaller cells near the eye (where H turns
/// fastest) and along the light's mirror direction bound far more tightly. Either way a
/// cell's accepted candidates are the lobe's normals in the cap (less the inner cap β
/// certainly seen before), so the distribution is the equal cells' (test
/// `a_windows_candidates_carry_the_caps_lobe_mass` against a quadrature, and the
/// brute-force comparisons of `tests/stochastic_matches_brute_force.rs`).
struct CellTable {
    cells: usize,
    /// Cumulative candidate weight over cells (equal cells: their probability; split
    /// cells: expected draws per facet times volume share).
    cumulative: Vec<f64>,
    /// Mean candidate probability per virtual facet (split cells: expected draws per
    /// facet, up to 2 with two sides).
    mean_q: f64,
    /// Per equal cell: bound of the normal density on the +H and −H caps (0 for an
    /// unused side); empty for split cells.
    bound: Vec<[f64; 2]>,
    /// Per equal cell: draw normals from the lobe directly (q would reach 1); empty for
    /// split cells.
    direct: Vec<bool>,
    one_minus_cos_alpha: f64,
    /// cos and sin of α + [`CAP_WIDEN_RAD`] (split cells' first thinning stage).
    wide: (f64, f64),
    uniform: bool,
    /// The box's split cells (corner, size); empty: the space's equal cells.
    boxes: Vec<(Vec3, Vec3)>,
    /// Per split cell: the windows of the +H and −H sides' normals.
    windows: Vec<[Window; 2]>,
}

/// A box cell is split when its bound would draw more candidates than this: evaluating
/// its eight children costs about what drawing and thinning 30-60 candidates does.
const SPLIT_DRAWS: f64 = 64.0;
/// Most halvings of a 16³ cell (down to 1/512 of the box per axis).
const SPLIT_DEPTH: u32 = 5;
/// Most cells one of the 16³ cells is split into (a cell is split only while its cells
/// filed so far and the eight new ones stay within this), so the table holds at most
/// about 4096 · 424 cells of 144 bytes (250 MB) whatever the scene asks for, before the
/// memory guard has seen the candidates it would draw. The sun pillar needs at most 246.
const SPLIT_BUDGET: usize = 384;
/// Most window shapes a [`SplitMemo`] keeps (104 bytes each, 52 MB; the sun pillar's
/// table visits about 57,000 cells); a table that visits more keeps none.
const MEMO_MAX_SHAPES: usize = 500_000;

/// Where the normals of one side's candidates in a split cell are drawn: the lobe
/// restricted to the polar band `w_lo..=w_hi` (cosines to the axis) and the azimuths
/// `phi_c ± half_width` about the axis (the whole circle when `half_width` ≥ π), which
/// holds the cap of half-angle α around ±H(x) for every x of the cell.
#[derive(Clone, Copy, Debug, Default)]
struct Window {
    w_lo: f64,
    w_hi: f64,
    phi_c: f64,
    half_width: f64,
    /// The expected candidates per facet of this side: the lobe's probability in the
    /// window, or, when smaller, the cap's area times `bound`.
    mass: f64,
    /// 1 - cos β: normals within β of ±H(x) were certainly seen at the frame before
    /// (0: none known), so only the annulus β..α holds candidates.
    omc_beta: f64,
    /// When not 0: draw the normal uniformly in the cap around ±H(x) and thin it by the
    /// lobe's density over this bound of it (the equal cells' way), which is cheaper near
    /// the axis, where the window would be the whole band around it.
    bound: f64,
}

/// What a [`Window`] is before the inner cap: its band, azimuths, the lobe's mass in
/// them and the density bound over its caps. These depend only on the eye, the light,
/// the cell, the cap's half-angle and the lobe, so a cell's shapes are kept from one
/// birth table to the next ([`SplitMemo`]).
#[derive(Clone, Copy, Debug, Default)]
struct WindowShape {
    w_lo: f64,
    w_hi: f64,
    phi_c: f64,
    half_width: f64,
    /// The lobe's probability in the window.
    mass: f64,
    /// The lobe's density at `w_hi`.
    bound: f64,
}

impl WindowShape {
    /// The window around the half vector `h` at the cell's centre (None: everywhere),
    /// for caps of half-angle `alpha` and H turning by at most `spread` over the cell;
    /// the lobe's axis is +y. A cap of radius r around a direction at polar angle γ spans
    /// the polar angles γ ± r and, when it holds neither pole (r < γ < π - r), the
    /// azimuths ± asin(sin r / sin γ).
    fn around(lobe: &Lobe, h: Option<Vec3>, alpha: f64, spread: f64) -> Self {
        let r = alpha + spread;
        let (w_lo, w_hi, phi_c, half_width) = match h {
            Some(h) if r < std::f64::consts::PI => {
                // From the components' ratio, not acos(h.y): exact near the poles whatever
                // h's length (f32 rounding would otherwise move the band's edge there).
                let h = h.as_dvec3();
                let gamma = h.x.hypot(h.z).atan2(h.y);
                let (g_lo, g_hi) = ((gamma - r).max(0.0), (gamma + r).min(std::f64::consts::PI));
                let half_width = if gamma > r && gamma + r < std::f64::consts::PI {
                    (r.sin() / gamma.sin()).min(1.0).asin()
                } else {
                    std::f64::consts::PI
                };
                (g_hi.cos(), g_lo.cos(), h.z.atan2(h.x), half_width)
            }
            _ => (-1.0, 1.0, 0.0, std::f64::consts::PI),
        };
        let mass = lobe.polar_mass(w_lo, w_hi) * half_width / std::f64::consts::PI;
        // The density bound over the caps: at the least polar angle the window holds.
        let bound = lobe.density(w_hi);
        Self { w_lo, w_hi, phi_c, half_width, mass, bound }
    }

    /// The window of this shape for caps of `omc_alpha` = 1 − cos α less the inner cap
    /// `omc_beta` (1 − cos β): drawn from the lobe in the window, or uniformly in the
    /// cap and thinned, whichever draws fewer.
    #[inline]
    fn window(&self, omc_alpha: f64, omc_beta: f64) -> Window {
        let &Self { w_lo, w_hi, phi_c, half_width, mass, bound } = self;
        let thinned = 2.0 * std::f64::consts::PI * (omc_alpha - omc_beta) * bound;
        if thinned < mass {
            Window { w_lo, w_hi, phi_c, half_width, mass: thinned, omc_beta, bound }
        } else {
            Window { w_lo, w_hi, phi_c, half_width, mass, omc_beta, bound: 0.0 }
        }
    }
}

impl Window {
    /// [`WindowShape::around`]'s window less the inner cap `omc_beta`.
    #[cfg(test)]
    fn around(lobe: &Lobe, h: Option<Vec3>, alpha: f64, spread: f64, omc_beta: f64) -> Self {
        WindowShape::around(lobe, h, alpha, spread).window(one_minus_cos(alpha), omc_beta)
    }

    /// A candidate normal for the cap of `1 - cos α` = `omc_alpha` around `h` (less the
    /// inner cap β): the lobe's normals there, each drawn with probability
    /// [`Window::mass`] over the lobe's probability of the cap; `None` when rejected.
    ///
    /// Thinned windows thin in two stages (an extension for speed, not in the paper):
    /// first by b / `bound`, b the density's bound over this candidate's own cap
    /// ([`Window::cap_bound`]), before any normal is drawn; then by the density over b.
    /// Their product is the density over `bound`, as one stage's was, for any b between
    /// the cap's largest density and `bound`. `wide` is (cos, sin) of α +
    /// [`CAP_WIDEN_RAD`].
    #[inline]
    fn draw(&self, lobe: &Lobe, h: Vec3, omc_alpha: f64, wide: (f64, f64), rng: &mut Stream) -> Option<Vec3> {
        if self.bound > 0.0 {
            let b = self.cap_bound(lobe, h, wide, rng)?;
            let (beta, a) = (self.omc_beta, omc_alpha);
            let n = around(h, 1.0 - (beta + rng.next_f64() * (a - beta)), rng);
            return (rng.next_f64() * b < lobe.density(f64::from(n.y))).then_some(n);
        }
        let n = self.sample(lobe, rng);
        // 1 - cos of the angle as |n - h|²/2 of unit vectors in f64: no cancellation.
        let omc = 0.5 * (n - h.as_dvec3().normalize()).length_squared();
        (omc <= omc_alpha && omc >= self.omc_beta).then_some(n.as_vec3())
    }

    /// The first stage of [`Window::draw`]'s thinning: b, the lobe's largest density
    /// over the cap around `h` ([`Window::cap_exponent`]), kept with probability
    /// b / `bound`; `None` when not kept. b / `bound` = e^x for x ≤ 0; since e^x is
    /// below 1 / (1 + y + y²/2 + y³/6) for y = −x > 0 (e^y's series), a uniform u at or
    /// above that (with 10⁻¹² to spare for rounding) is rejected without an exponential,
    /// which is most of them.
    #[inline]
    fn cap_bound(&self, lobe: &Lobe, h: Vec3, wide: (f64, f64), rng: &mut Stream) -> Option<f64> {
        let x = self.cap_exponent(lobe, h, wide);
        let (u, y) = (rng.next_f64(), -x);
        if u * (1.0 + y * (1.0 + y * (0.5 + y / 6.0))) >= 1.0 + 1e-12 {
            return None;
        }
        let e = x.exp();
        (u < e).then_some(self.bound * e)
    }

    /// x = κ (w − `w_hi`) ≤ 0, so that `bound` e^x is at least the lobe's density C
    /// e^{κ(c − 1)} at every normal of the cap of half-angle α around `h`: w is the
    /// cosine of the cap's polar angle nearest the lobe's axis +y, max(γ − α, 0) for H's
    /// polar angle γ (cos γ = h.y, sin γ ≥ 0). The cap is taken [`CAP_WIDEN_RAD`] wider
    /// (`wide` = cos and sin of α + that) and w [`CAP_COS_SLACK`] higher, for the f32
    /// rounding of H and of the normals drawn around it (their y within a few ulps of
    /// 1 of the exact ones): a slack in the angle alone is worth nothing in the cosine
    /// next to the axis.
    #[inline]
    fn cap_exponent(&self, lobe: &Lobe, h: Vec3, (cos_a, sin_a): (f64, f64)) -> f64 {
        let hy = f64::from(h.y).clamp(-1.0, 1.0);
        // cos(γ − α) when γ > α, else 1 (the cap holds the axis).
        let w = if hy < cos_a { hy * cos_a + (1.0 - hy * hy).sqrt() * sin_a } else { 1.0 };
        (lobe.kappa * ((w + CAP_COS_SLACK).min(1.0) - self.w_hi)).min(0.0)
    }

    /// A normal of the lobe restricted to the window (axis +y).
    #[inline]
    fn sample(&self, lobe: &Lobe, rng: &mut Stream) -> glam::DVec3 {
        let w = lobe.polar_in(self.w_lo, self.w_hi, rng.next_f64());
        let phi = self.phi_c + (2.0 * rng.next_f64() - 1.0) * self.half_width.min(std::f64::consts::PI);
        let s = (1.0 - w * w).max(0.0).sqrt();
        glam::DVec3::new(s * phi.cos(), w, s * phi.sin())
    }
}

/// The bound of one cell: the density bound on the +H and −H caps, and the candidate
/// probability per facet (1 when normals are drawn from the lobe directly).
struct CellBound {
    bound: [f64; 2],
    q: f64,
    direct: bool,
}

/// The inner caps of split cells: the bound of [`InnerCap`] (its radius set per cell),
/// the test of the new frame, and the interior of the box away from the faces a facet
/// may have wrapped through (cells reaching out of it keep the whole cap).
struct InnerSplit<'a> {
    cap: InnerCap,
    to: &'a Seen,
    interior: (Vec3, Vec3),
}

impl<'a> InnerSplit<'a> {
    /// The inner caps of births from the frame tested by `from` into the one tested by
    /// `to`, through the motion `m`, in the box `min..min + size`; `None` when the step
    /// is as large as the box (keep the whole cap everywhere).
    fn of(min: Vec3, size: Vec3, m: &Motion, from: &Seen, to: &'a Seen, theta: f64) -> Option<Self> {
        let reach = f64::from(m.shared_m.length() + 3f32.sqrt() * m.jitter_m) + 1e-4;
        // Slab thickness at the low and high face of each axis: only faces the step can
        // cross (x_t = x_{t+1} - D - j leaves the box there).
        let lo = (m.shared_m + Vec3::splat(m.jitter_m)).max(Vec3::ZERO) + Vec3::splat(1e-4);
        let hi = (-m.shared_m + Vec3::splat(m.jitter_m)).max(Vec3::ZERO) + Vec3::splat(1e-4);
        if !(lo + hi).cmplt(size * 0.25).all() {
            return None;
        }
        let sun_chord = match (from.geo.light, to.geo.light) {
            (LightAt::Direction(a), LightAt::Direction(b)) => f64::from((a - b).length()),
            _ => 0.0,
        };
        let theta_in = (theta - CAP_MARGIN_RAD).max(0.0);
        let far: Vec<Vec3> = to.geo.points().collect();
        let cap = InnerCap { far, sun_chord, reach_m: reach, radius_m: 0.0, theta_in };
        Some(Self { cap, to, interior: (min + lo, min + size - hi) })
    }
}

/// Inputs of [`CellBound`] that do not change from cell to cell.
struct BoundInputs<'a> {
    /// What births into a later frame know: normals within β of ±H were seen before.
    inner: Option<InnerSplit<'a>>,
    lobe: &'a Lobe,
    geo: &'a Geometry,
    alpha: f64,
    /// 1 − cos `alpha`.
    omc_alpha: f64,
    cap_area: f64,
    two_sided: bool,
}

impl BoundInputs<'_> {
    /// The bound of the cell centred at `centre` with bounding radius `radius`, lobe axis
    /// `axis` there turning by at most `axis_spread` over it.
    fn cell(&self, centre: Vec3, radius: f32, axis: Vec3, axis_spread: f64) -> CellBound {
        let spread = self.geo.half_vector_spread(centre, radius);
        let h = self.geo.half_vector(centre);
        let mut bound = [0.0; 2];
        let mut q = 0.0;
        for (side, sign) in [1.0f32, -1.0].into_iter().enumerate() {
            if side == 1 && !self.two_sided {
                continue;
            }
            let beta = match h {
                Some(h) => {
                    f64::from((h * sign).dot(axis).clamp(-1.0, 1.0)).acos()
                        - axis_spread
                        - spread
                        - self.alpha
                }
                None => 0.0,
            };
            bound[side] = self.lobe.density(beta.max(0.0).cos());
            q += self.cap_area * bound[side];
        }
        let direct = q >= 1.0;
        CellBound { bound, q: q.min(1.0), direct }
    }
}

impl CellTable {
    #[allow(clippy::too_many_arguments)]
    fn build(
        space: &Space,
        lobe: &Lobe,
        geo: &Geometry,
        alpha: f64,
        two_sided: bool,
        facets: u64,
        inner: Option<InnerSplit<'_>>,
        memo: Option<&mut SplitMemo>,
    ) -> Self {
        let uniform = lobe.is_uniform();
        let omc = one_minus_cos(alpha);
        let cap_area = 2.0 * std::f64::consts::PI * omc;
        let inputs = BoundInputs { inner, lobe, geo, alpha, omc_alpha: omc, cap_area, two_sided };
        if let (false, Space::Box { min, size }) = (uniform, *space) {
            return Self::split(&inputs, min, size, facets, omc, memo);
        }
        let cells = space.cell_count(uniform);
        let mut bound = vec![[0.0; 2]; cells];
        let mut direct = vec![false; cells];
        let mut cumulative = Vec::with_capacity(cells);
        let mut total = 0.0;
        for c in 0..cells {
            let q = if uniform {
                bound[c] = [lobe.density(1.0), if two_sided { lobe.density(1.0) } else { 0.0 }];
                inputs.cap_area * (bound[c][0] + bound[c][1])
            } else {
                let (centre, radius, axis_spread) = space.cell_bounds(c, cells);
                let b = inputs.cell(centre, radius, space.radial_axis(centre), axis_spread);
                (bound[c], direct[c]) = (b.bound, b.direct);
                b.q
            };
            total += q;
            cumulative.push(total);
        }
        let mean_q = total / cells as f64;
        Self {
            cells,
            cumulative,
            mean_q: mean_q.min(1.0),
            bound,
            direct,
            one_minus_cos_alpha: omc,
            wide: cap_wide(alpha),
            uniform,
            boxes: Vec::new(),
            windows: Vec::new(),
        }
    }

    /// The box `min..min + size` cut into 16³ cells, each split further while its
    /// windows draw more than [`SPLIT_DRAWS`] of the `facets` (depth first, children in
    /// x, y, z order: the cells depend on the geometry, the facet count and the inner
    /// caps, never on the thread count).
    fn split(
        inputs: &BoundInputs<'_>,
        min: Vec3,
        size: Vec3,
        facets: u64,
        omc: f64,
        memo: Option<&mut SplitMemo>,
    ) -> Self {
        const TOP: usize = 16;
        let cell = size / TOP as f32;
        let share = 1.0 / (TOP * TOP * TOP) as f64;
        // The shapes worked out for the same eye, light, cap and lobe, if any.
        let key = memo_key(inputs, min, size);
        let old = match &memo {
            Some(m) if m.key.as_ref() == Some(&key) => &m.cells[..],
            _ => &[],
        };
        // The 16³ cells in parallel, each split on its own; filed in the grid's order.
        let parts: Vec<(Vec<SplitCell>, Vec<KeptShapes>)> = (0..TOP * TOP * TOP)
            .into_par_iter()
            .map(|c| {
                let (i, j, k) = (c % TOP, (c / TOP) % TOP, c / (TOP * TOP));
                let corner = min + cell * Vec3::new(i as f32, j as f32, k as f32);
                let old = old.get(c).map_or(&[][..], |v| &v[..]);
                let mut out = Vec::with_capacity(old.len());
                let mut shapes = Shapes { old, at: 0, new: Vec::with_capacity(old.len()) };
                visit(inputs, corner, cell, share, facets as f64, (0, 0), &mut out, &mut shapes);
                (out, shapes.new)
            })
            .collect();
        let (parts, shapes): (Vec<_>, Vec<_>) = parts.into_iter().unzip();
        if let Some(memo) = memo {
            // Kept only up to a bound, whatever the scene (the table itself is bounded by
            // `SPLIT_BUDGET`).
            let kept: usize = shapes.iter().map(Vec::len).sum();
            *memo = if kept <= MEMO_MAX_SHAPES {
                SplitMemo { key: Some(key), cells: shapes }
            } else {
                SplitMemo::default()
            };
        }
        let mut table = Self {
            cells: 0,
            cumulative: Vec::new(),
            mean_q: 0.0,
            bound: Vec::new(),
            direct: Vec::new(),
            one_minus_cos_alpha: omc,
            wide: cap_wide(inputs.alpha),
            uniform: false,
            boxes: Vec::new(),
            windows: Vec::new(),
        };
        let cells: usize = parts.iter().map(Vec::len).sum();
        table.cumulative.reserve_exact(cells);
        table.windows.reserve_exact(cells);
        table.boxes.reserve_exact(cells);
        let mut total = 0.0;
        for part in parts {
            for cell in part {
                total += cell.weight;
                table.cumulative.push(total);
                table.windows.push(cell.windows);
                table.boxes.push(cell.bounds);
            }
        }
        table.cells = table.boxes.len();
        // Expected draws per facet: up to 2 with two sides (the chunks and the memory
        // guard count draws; only the equal cells' binomial needs a probability).
        table.mean_q = total;
        table
    }

    /// The split cells birth chunk `k` of `chunks` draws: consecutive runs holding about
    /// equal shares of the candidate weight (the split depends only on the weights).
    fn range(&self, k: u64, chunks: u64) -> std::ops::Range<usize> {
        let total = self.cumulative.last().copied().unwrap_or(0.0);
        let at = |k: u64| {
            if k >= chunks {
                self.cells
            } else {
                self.cumulative.partition_point(|&b| b * (chunks as f64) <= k as f64 * total)
            }
        };
        at(k)..at(k + 1)
    }

    /// One candidate: a position (at the destination frame) and a normal (at the
    /// previous frame) in the cap around ±H there; `None` when thinning rejects it.
    #[inline]
    fn draw(&self, space: &Space, lobe: &Lobe, geo: &Geometry, rng: &mut Stream) -> Option<(Vec3, Vec3)> {
        let c = if self.cells == 1 {
            0
        } else {
            let u = rng.next_f64() * self.cumulative[self.cells - 1];
            self.cumulative.partition_point(|&v| v <= u).min(self.cells - 1)
        };
        self.draw_in(c, space, lobe, geo, rng)
    }

    /// One candidate in cell `c`, `None` when thinning rejects it.
    #[inline]
    fn draw_in(
        &self,
        c: usize,
        space: &Space,
        lobe: &Lobe,
        geo: &Geometry,
        rng: &mut Stream,
    ) -> Option<(Vec3, Vec3)> {
        if let Some(&(corner, size)) = self.boxes.get(c) {
            // A split cell: the normal from its side's window, kept when in the cap.
            let x = corner + size * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let [plus, minus] = &self.windows[c];
            let (window, sign) = if rng.next_f64() * (plus.mass + minus.mass) >= plus.mass {
                (minus, -1.0)
            } else {
                (plus, 1.0)
            };
            let h = geo.half_vector(x)? * sign;
            return window.draw(lobe, h, self.one_minus_cos_alpha, self.wide, rng).map(|n| (x, n));
        }
        let x = space.sample_in_cell(c, self.cells, rng);
        let axis = space.radial_axis(x);
        if self.direct[c] {
            return Some((x, lobe.sample(axis, rng)));
        }
        let h = geo.half_vector(x)?;
        let [b0, b1] = self.bound[c];
        let side = if b1 > 0.0 && rng.next_f64() * (b0 + b1) >= b0 { -1.0 } else { 1.0 };
        let n = in_cap(h * side, self.one_minus_cos_alpha, rng);
        if !self.uniform {
            let b = if side > 0.0 { b0 } else { b1 };
            if rng.next_f64() * b >= lobe.density(f64::from(n.dot(axis))) {
                return None;
            }
        }
        Some((x, n))
    }
}

/// The window shapes of the last birth table's split cells (an extension for speed, not
/// in the paper), for the next table: with the same eye, light, cap, lobe and box
/// ([`memo_key`]) a cell's shapes are the same numbers, and only what the inner cap
/// changes (which cells split, each window's mass) is worked out again. Per 16³ cell,
/// the (path, shapes) of every cell visited, in visiting order: a cell's path is
/// Σ (child + 1)·9^(depth left) over the halvings leading to it, so a cell comes before
/// its children and each child's cells before the next child's, and the order is
/// ascending (looked up from the last one found on). The same table bit for bit as without it
/// (test `kept_window_shapes_give_the_same_table`).
#[derive(Clone, Debug, Default)]
struct SplitMemo {
    key: Option<String>,
    cells: Vec<Vec<KeptShapes>>,
}

/// How much wider than α the caps of [`Window::cap_exponent`] are taken, rad: far above
/// the f32 rounding of H (unit to about 10⁻⁷) and of the normals drawn around it.
const CAP_WIDEN_RAD: f64 = 1e-5;

/// How much higher than the cap's nearest cosine [`Window::cap_exponent`] takes it: 8
/// ulps of 1 in f32, above the rounding of H's and the drawn normals' y (a few ulps).
const CAP_COS_SLACK: f64 = 8.0 * f32::EPSILON as f64;

/// (cos, sin) of α + [`CAP_WIDEN_RAD`], for [`CellTable::wide`].
fn cap_wide(alpha: f64) -> (f64, f64) {
    let a = (alpha + CAP_WIDEN_RAD).min(std::f64::consts::PI);
    (a.cos(), a.sin())
}

/// A visited cell's path and its two sides' window shapes ([`SplitMemo`]).
type KeptShapes = (u32, [WindowShape; 2]);

/// What the window shapes of [`SplitMemo`] are worked out from: the eye and the light,
/// the cap's half-angle, the lobe, the sides and the box, in their debug forms, which
/// tell every f32 and f64 apart (−0.0 from 0.0, where `==` would not).
fn memo_key(inputs: &BoundInputs<'_>, min: Vec3, size: Vec3) -> String {
    format!("{:?}", (inputs.geo, inputs.alpha, inputs.lobe, inputs.two_sided, min, size))
}

impl SplitMemo {
    /// Bytes held.
    fn bytes(&self) -> u64 {
        let inner: usize = self.cells.iter().map(|c| c.capacity() * std::mem::size_of::<KeptShapes>()).sum();
        (inner + self.cells.capacity() * std::mem::size_of::<Vec<KeptShapes>>()) as u64
    }
}

/// One 16³ cell's window shapes as [`visit`] takes and files them.
struct Shapes<'a> {
    old: &'a [KeptShapes],
    /// Where in `old` the next cell's path may be, at the earliest.
    at: usize,
    new: Vec<KeptShapes>,
}

// Paths of cells SPLIT_DEPTH halvings deep fit a u32.
const _: () = assert!(9u64.pow(SPLIT_DEPTH) <= u32::MAX as u64);

/// One split cell: its box (corner, size), its weight (candidates per facet times its
/// share of the box) and its two sides' windows.
struct SplitCell {
    bounds: (Vec3, Vec3),
    weight: f64,
    windows: [Window; 2],
}

/// File the cell `corner..corner + size` (holding `share` of the box) into `out`, or its
/// eight halves (children in x, y, z order) while its windows would draw more than
/// [`SPLIT_DRAWS`] of the `facets`.
///
/// `(depth, path)` places the cell in its 16³ cell's octree ([`SplitMemo`]); its
/// windows' shapes are taken from `shapes.old` when there, and every shape used is
/// filed in `shapes.new` in visiting order.
#[allow(clippy::too_many_arguments)]
fn visit(
    inputs: &BoundInputs<'_>,
    corner: Vec3,
    size: Vec3,
    share: f64,
    facets: f64,
    (depth, path): (u32, u32),
    out: &mut Vec<SplitCell>,
    shapes: &mut Shapes<'_>,
) {
    let centre = corner + 0.5 * size;
    let radius = 0.5 * size.length();
    // Paths come in ascending order: the cell's, if kept, is at or after the last one
    // found, and most often right there.
    let rest = &shapes.old[shapes.at..];
    let found = match rest.first() {
        Some(e) if e.0 == path => Ok(0),
        _ => rest.binary_search_by_key(&path, |e| e.0),
    };
    let shape = match found {
        Ok(k) => {
            shapes.at += k + 1;
            rest[k].1
        }
        Err(k) => {
            shapes.at += k;
            let spread = inputs.geo.half_vector_spread(centre, radius);
            let h = inputs.geo.half_vector(centre);
            let plus = WindowShape::around(inputs.lobe, h, inputs.alpha, spread);
            let minus = if inputs.two_sided {
                WindowShape::around(inputs.lobe, h.map(|h| -h), inputs.alpha, spread)
            } else {
                WindowShape::default()
            };
            [plus, minus]
        }
    };
    shapes.new.push((path, shape));
    let omc_beta = match &inputs.inner {
        Some(inner)
            if corner.cmpge(inner.interior.0).all() && (corner + size).cmple(inner.interior.1).all() =>
        {
            inner.cap.one_minus_cos_beta_within(inner.to, centre, f64::from(radius)).min(inputs.omc_alpha)
        }
        _ => 0.0,
    };
    let plus = shape[0].window(inputs.omc_alpha, omc_beta);
    let minus =
        if inputs.two_sided { shape[1].window(inputs.omc_alpha, omc_beta) } else { Window::default() };
    let q = plus.mass + minus.mass;
    if facets * share * q > SPLIT_DRAWS && depth < SPLIT_DEPTH && out.len() + 8 <= SPLIT_BUDGET {
        let half = 0.5 * size;
        for k in 0..2 {
            for j in 0..2 {
                for i in 0..2 {
                    let at = corner + half * Vec3::new(i as f32, j as f32, k as f32);
                    let child = path + (1 + i + 2 * j + 4 * k) * 9u32.pow(SPLIT_DEPTH - depth - 1);
                    visit(inputs, at, half, share / 8.0, facets, (depth + 1, child), out, shapes);
                }
            }
        }
        return;
    }
    out.push(SplitCell { bounds: (corner, size), weight: share * q, windows: [plus, minus] });
}

impl phenomena_core::phenomenon::Simulation for SparkleSim {
    type StepStats = StepStats;
    type Error = SparkleError;

    fn step(&mut self) -> Result<StepStats, SparkleError> {
        SparkleSim::step(self)
    }

    fn frames_done(&self) -> u64 {
        u64::from(self.frame())
    }

    type State = SparkleState;

    fn state(&self) -> SparkleState {
        SparkleSim::state(self)
    }

    fn restore(&mut self, state: SparkleState) -> Result<(), SparkleError> {
        SparkleSim::restore(self, state)
    }
}

/// A checkpoint: what a [`SparkleSim`] built from the same configuration and seed needs
/// to continue bit-identically (the space, lobe, tables and gust phases are rebuilt;
/// every random number is keyed by seed, purpose, frame and cell, so no stream position
/// is kept).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SparkleState {
    /// Frame now shown.
    pub frame: u32,
    /// The facets seen now.
    pub glints: Glints,
    /// Facets seen within the memory window but not now.
    pub ghosts: Glints,
    /// Every facet, for the brute-force method (`None` for the stochastic one).
    pub everything: Option<Everything>,
}

impl SparkleSim {
    /// A checkpoint of the current state.
    pub fn state(&self) -> SparkleState {
        SparkleState {
            frame: self.frame,
            glints: self.glints.clone(),
            ghosts: self.ghosts.clone(),
            everything: self.everything.clone(),
        }
    }

    /// Continue from a checkpoint taken with [`SparkleSim::state`] of a simulation with
    /// the same configuration and seed. Refused, leaving `self` as it was, when its
    /// method differs (brute force keeps every facet), its arrays differ in length or a
    /// facet is not finite.
    pub fn restore(&mut self, state: SparkleState) -> Result<(), SparkleError> {
        let bad = |what: &str| Err(SparkleError::State(what.to_string()));
        if state.everything.is_some() != self.everything.is_some() {
            return bad("it was saved by the other method (brute force or stochastic)");
        }
        if let Some(e) = &state.everything {
            let n = self.virtual_count as usize;
            if [e.position_m.len(), e.normal.len(), e.since.len(), e.last_seen.len()].iter().any(|&l| l != n)
            {
                return bad("the brute-force population has the wrong number of facets");
            }
            if !e.position_m.iter().chain(&e.normal).all(|v| v.is_finite()) {
                return bad("a facet is not finite");
            }
        }
        for g in [&state.glints, &state.ghosts] {
            let n = g.len();
            if g.normal.len() != n || g.intensity.len() != n || g.birth_frame.len() != n {
                return bad("glint arrays differ in length");
            }
            if !g.position_m.iter().chain(&g.normal).all(|v| v.is_finite())
                || !g.intensity.iter().all(|i| i.is_finite())
            {
                return bad("a glint is not finite");
            }
        }
        self.frame = state.frame;
        self.glints = state.glints;
        self.ghosts = state.ghosts;
        self.everything = state.everything;
        self.last = self.stats_now(0, 0, 0);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{Leaves, Method};

    fn small(method: Method) -> SparkleConfig {
        let mut c = SparkleConfig { method, ..SparkleConfig::default() };
        if let Population::DiamondDust(d) = &mut c.population {
            d.density_per_m3 = 50.0; // 10⁷ crystals
        }
        c.phong.exponent_n = 100.0;
        c
    }

    #[test]
    fn same_seed_same_glints_for_any_thread_count() {
        for method in [Method::Stochastic, Method::BruteForce] {
            let mut c = small(method);
            if let Population::DiamondDust(d) = &mut c.population {
                d.density_per_m3 = 1.0;
            }
            let run = |threads| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                pool.install(|| {
                    let mut sim = SparkleSim::new(c, 9).unwrap();
                    for _ in 0..4 {
                        sim.step().unwrap();
                    }
                    sim.glints().clone()
                })
            };
            let one = run(1);
            assert!(one.len() > 100, "{}", one.len());
            assert_eq!(one, run(3), "{method:?}");
        }
        // Plates: the box's split cells (built in parallel) and their births.
        let mut c = small(Method::Stochastic);
        c.phong.two_sided = true;
        c.light = crate::config::Light::Sun {
            azimuth_deg: 0.0,
            elevation_deg: 10.0,
            azimuth_rate_deg_per_s: 0.0,
            elevation_rate_deg_per_s: 0.0,
        };
        if let Population::DiamondDust(d) = &mut c.population {
            d.density_per_m3 = 2.0;
            d.normals = crate::config::Normals::Plates { tilt_deg: 4.0 };
        }
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut sim = SparkleSim::new(c, 9).unwrap();
                let mut births = 0;
                for _ in 0..4 {
                    births += sim.step().unwrap().births;
                }
                (sim.glints().clone(), births)
            })
        };
        let (one, births) = run(1);
        assert!(one.len() > 100 && births > 10, "{} glints, {births} births", one.len());
        assert_eq!((one, births), run(3), "plates");
    }

    #[test]
    fn kept_window_shapes_give_the_same_table() {
        // Plates under a still sun (the shapes kept from frame to frame) and a moving one
        // (the key changes every frame): at every frame the birth table built with the
        // kept shapes is the one built afresh, bit for bit.
        for rate in [0.0, 2.0] {
            let mut c = small(Method::Stochastic);
            c.phong.two_sided = true;
            c.light = crate::config::Light::Sun {
                azimuth_deg: 0.0,
                elevation_deg: 10.0,
                azimuth_rate_deg_per_s: rate,
                elevation_rate_deg_per_s: 0.0,
            };
            if let Population::DiamondDust(d) = &mut c.population {
                d.density_per_m3 = 2.0;
                d.normals = crate::config::Normals::Plates { tilt_deg: 4.0 };
            }
            let mut sim = SparkleSim::new(c, 9).unwrap();
            let mut memo = SplitMemo::default();
            let mut kept = 0;
            for _ in 0..4 {
                let next = sim.frame() + 1;
                let to = sim.seen_at(next);
                let fresh = sim.birth_table(&to, next, None).0;
                let before = memo.key.clone();
                let reused = sim.birth_table(&to, next, Some(&mut memo)).0;
                kept += usize::from(before.is_some() && before == memo.key);
                assert!(fresh.cells > 4096, "{} cells: none split", fresh.cells);
                assert_eq!(fresh.cells, reused.cells);
                assert_eq!(fresh.boxes, reused.boxes);
                let bits = |t: &CellTable| t.cumulative.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&fresh), bits(&reused), "weights at frame {next}, sun moving {rate}°/s");
                assert_eq!(format!("{:?}", fresh.windows), format!("{:?}", reused.windows));
                sim.step().unwrap();
            }
            assert_eq!(kept, if rate == 0.0 { 3 } else { 0 }, "tables built from kept shapes");
        }
    }

    #[test]
    fn facets_inside_a_regions_inner_cap_were_seen_the_frame_before() {
        // The inner cap of every region is a certainty: a facet at x_{t+1} in the region
        // whose normal at t lies within β of ±H_{t+1}(x_{t+1}) (here: exactly at β, the
        // worst case, at random azimuths) passes the test at t wherever its own step
        // took it. Checked for the benchmark scene (sun) and a lamp scene.
        let lamp = SparkleConfig {
            light: crate::config::Light::Point { position_m: Vec3::new(3.0, 6.0, -25.0) },
            ..SparkleConfig::default()
        };
        for (c, cells) in [(SparkleConfig::default(), 16), (lamp, 16), (SparkleConfig::default(), 3)] {
            let sim = SparkleSim::new(c, 1).unwrap();
            let (from, to) = (sim.seen_at(9), sim.seen_at(10));
            let m = sim.motion_into(10).unwrap();
            let theta = sim.cos_theta.unwrap().acos();
            let alpha = theta + f64::from(m.rotation_rad) + CAP_MARGIN_RAD;
            let Space::Box { min, size } = sim.space else { unreachable!() };
            let r = Regions::build(min, size, &m, &from, &to, theta, alpha, false, cells).unwrap();
            let mut rng = Stream::new(3, BIRTH, 0);
            let mut checked = 0;
            for (corner, cell, omc_inner) in r.boxes.iter().step_by(if cells > 4 { 7 } else { 1 }) {
                if *omc_inner == 0.0 {
                    continue;
                }
                for _ in 0..20 {
                    let x1 = *corner + *cell * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                    let j = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE)
                        * m.jitter_m;
                    let x0 = sim.space.wrap(x1 - m.shared_m - j);
                    let h = to.geo.half_vector(x1).unwrap();
                    let n = crate::model::around(h, 1.0 - omc_inner, &mut rng);
                    assert!(from.test(x0, n, &sim.space).is_some(), "{x1} {omc_inner}");
                    checked += 1;
                }
            }
            assert!(checked > if cells > 4 { 5000 } else { 100 }, "{checked}");
        }
    }

    #[test]
    fn empty_cone_generates_nothing() {
        let mut c = small(Method::Stochastic);
        c.phong.threshold_i_e = 2.0;
        let mut sim = SparkleSim::new(c, 1).unwrap();
        assert!(sim.cone_is_empty());
        assert_eq!(sim.step().unwrap().generated, 0);
    }

    #[test]
    fn memory_follows_the_visible_set() {
        // 10⁹ virtual crystals, about 3·10⁵ seen: well under 50 MB held.
        let mut sim = SparkleSim::new(SparkleConfig::default(), 1).unwrap();
        let s = sim.stats();
        assert_eq!(s.virtual_count, 1_000_000_000);
        let p = sim.config().phong.uniform_fraction();
        let sd = (1e9 * p * (1.0 - p)).sqrt();
        assert!((s.generated as f64 - 1e9 * p).abs() < 5.0 * sd, "{} vs {}", s.generated, 1e9 * p);
        assert!(s.bytes_held < 50_000_000, "{}", s.bytes_held);
        // Once stepping, with the ghosts and the arrays kept for reuse.
        for _ in 0..3 {
            let s = sim.step().unwrap();
            assert!(s.ghosts > 0 && s.bytes_held < 50_000_000, "{s:?}");
        }
    }

    #[test]
    fn birth_chunks_own_every_region_once_and_about_equal_mass() {
        // Chunk k owns the regions whose mass starts in [k, k+1)·total/chunks: runs that
        // follow each other, cover every region once, and hold total/chunks give or take
        // one region's mass.
        let sim = SparkleSim::new(SparkleConfig::default(), 1).unwrap();
        let (from, to) = (sim.seen_at(9), sim.seen_at(10));
        let m = sim.motion_into(10).unwrap();
        let theta = sim.cos_theta.unwrap().acos();
        let alpha = theta + f64::from(m.rotation_rad) + CAP_MARGIN_RAD;
        let Space::Box { min, size } = sim.space else { unreachable!() };
        let r = Regions::build(min, size, &m, &from, &to, theta, alpha, false, 16).unwrap();
        let biggest = r.mass.iter().copied().fold(0.0, f64::max);
        assert!(r.mass.len() > 4096 && biggest > 0.0);
        for chunks in [1u64, 2, 3, 7, 64, 256] {
            let mut next = 0;
            for k in 0..chunks {
                let run = r.range(k, chunks);
                assert_eq!(run.start, next, "{chunks} chunks, chunk {k}");
                next = run.end;
                let share: f64 = r.mass[run].iter().sum();
                let want = r.mass_total / chunks as f64;
                assert!((share - want).abs() <= biggest * (1.0 + 1e-9), "{chunks}/{k}: {share} vs {want}");
            }
            assert_eq!(next, r.mass.len());
        }
    }

    #[test]
    fn survivors_keep_exactly_the_asked_lanes_that_are_seen() {
        let v = |k: f32| V8 {
            x: f32x8::from(std::array::from_fn::<f32, 8, _>(|i| k + i as f32)),
            y: f32x8::splat(k),
            z: f32x8::ZERO,
        };
        let c2 = f32x8::from([0.5, -1.0, 0.2, 0.3, -1.0, 0.0, 0.9, f32::NAN]);
        let mut s = Survivors::default();
        // Asked: lanes 0, 1, 2, 4, 5, 7; seen among them: 0, 2, 5 (NaN is not seen).
        s.push_seen(&v(0.0), &v(10.0), &v(20.0), c2, 0b1011_0111);
        assert_eq!(s.len(), 3);
        assert_eq!(s.x1.iter().map(|p| p.x).collect::<Vec<_>>(), [0.0, 2.0, 5.0]);
        assert_eq!(s.x, s.x1);
        assert_eq!(s.nrm.iter().map(|p| p.x).collect::<Vec<_>>(), [10.0, 12.0, 15.0]);
        assert_eq!(s.n1.iter().map(|p| p.x).collect::<Vec<_>>(), [20.0, 22.0, 25.0]);
        assert_eq!(s.c2, [0.5, 0.2, 0.0]);
    }

    #[test]
    fn leaves_glint_only_on_the_lit_side_facing_the_eye() {
        let c = SparkleConfig {
            population: Population::LeafGlitter(Leaves::default()),
            camera: phenomena_core::camera::Camera {
                position: Vec3::new(0.0, 2.0, 10.0),
                look_at: Vec3::new(0.0, 2.0, -12.0),
                up: Vec3::Y,
                projection: Projection::Perspective { fov_y_deg: 40.0 },
            },
            phong: crate::config::Phong { exponent_n: 200.0, threshold_i_e: 0.05, ..Default::default() },
            ..SparkleConfig::default()
        };
        let sim = SparkleSim::new(c, 2).unwrap();
        let g = sim.glints();
        assert!(g.len() > 100, "{}", g.len());
        let Population::LeafGlitter(l) = c.population else { unreachable!() };
        for &x in &g.position_m {
            assert!(((x - l.centre_m).length() - l.radius_m).abs() < 1e-3);
            assert!((x - l.centre_m).dot(c.camera.position - x) > 0.0);
        }
    }
}

#[cfg(test)]
mod window_tests {
    use super::*;
    const P: Purpose = Purpose::named("test.sparkle.window");

    /// The lobe's probability in the cap of half-angle `alpha` around a direction at
    /// polar angle `gamma` from the axis, by quadrature over the polar angle ψ: the
    /// density times the cap's azimuthal arc 2Δ(ψ) at ψ, cos Δ = (cos α - cos ψ cos γ) /
    /// (sin ψ sin γ).
    /// A unit half vector at polar angle `g` from the lobe's axis +y.
    fn h_at(g: f64) -> Vec3 {
        Vec3::new((g.sin() * 0.6) as f32, g.cos() as f32, (g.sin() * 0.8) as f32)
    }

    /// `shape`'s window for caps of half-angle `alpha`, thinned whatever its own mass
    /// (the first stage is only used there).
    fn thinned(shape: &WindowShape, alpha: f64) -> Window {
        let bound = shape.bound;
        let mass = 2.0 * std::f64::consts::PI * one_minus_cos(alpha) * bound;
        Window { mass, bound, ..shape.window(one_minus_cos(alpha), 0.0) }
    }

    /// `hits` of `n` draws of `w` accepted carry the lobe mass of the cap of half-angle
    /// `alpha` around polar angle `g`: mass·p within 5 binomial standard errors (plus
    /// 1e-6 relative for the quadrature, whose midpoint rule errs by far less).
    fn assert_carries_cap_mass(
        w: &Window,
        (hits, n): (usize, usize),
        (lobe, g, alpha): (&Lobe, f64, f64),
        case: &str,
    ) {
        let p = hits as f64 / n as f64;
        let (got, want) = (w.mass * p, cap_mass(lobe, g, alpha));
        let se = w.mass * (p * (1.0 - p) / n as f64).sqrt();
        assert!((got - want).abs() < 5.0 * se + 1e-6 * want, "{case}: {got} vs {want} (se {se})");
    }

    fn cap_mass(lobe: &Lobe, gamma: f64, alpha: f64) -> f64 {
        let steps = 200_000;
        let (lo, hi) = ((gamma - alpha).max(0.0), (gamma + alpha).min(std::f64::consts::PI));
        let d = (hi - lo) / steps as f64;
        (0..steps)
            .map(|i| {
                let psi = lo + (i as f64 + 0.5) * d;
                let c = (alpha.cos() - psi.cos() * gamma.cos()) / (psi.sin() * gamma.sin());
                let arc = 2.0 * c.clamp(-1.0, 1.0).acos();
                lobe.density(psi.cos()) * arc * psi.sin() * d
            })
            .sum()
    }

    #[test]
    fn two_stage_thinning_keeps_the_caps_lobe_mass() {
        // Thinned windows whose caps lie off the lobe's axis (γ > α, where the first
        // stage's bound is below the window's) and one holding the axis: the mean of
        // mass·[accepted] is the cap's lobe mass within 5 binomial standard errors (plus
        // 1e-6 relative for the quadrature), as for one stage.
        let n = 1_000_000;
        let mut rng = Stream::new(11, P, 0);
        let mut first = 0.0f64;
        for (spread_deg, gamma_deg, alpha_deg, cell_deg) in [
            (4.0, 8.0, 4.2, 1.0),
            (4.0, 14.0, 4.2, 2.0),
            (2.0, 6.0, 3.0, 0.5),
            (4.0, 3.0, 4.2, 1.0),
            (40.0, 120.0, 4.2, 1.0),
        ] {
            let lobe = Lobe::from_spread_deg(spread_deg);
            let (g, alpha) = (f64::to_radians(gamma_deg), f64::to_radians(alpha_deg));
            let h = h_at(g);
            let w = thinned(&WindowShape::around(&lobe, Some(h), alpha, f64::to_radians(cell_deg)), alpha);
            let wide = cap_wide(alpha);
            let mut kept = 0;
            let hits = (0..n)
                .filter(|_| {
                    let mut probe = rng.clone();
                    kept += usize::from(w.cap_bound(&lobe, h, wide, &mut probe).is_some());
                    w.draw(&lobe, h, one_minus_cos(alpha), wide, &mut rng).is_some()
                })
                .count();
            first = first.max(1.0 - kept as f64 / n as f64);
            let case = format!("{spread_deg}° lobe, γ {gamma_deg}°, α {alpha_deg}°");
            assert_carries_cap_mass(&w, (hits, n), (&lobe, g, alpha), &case);
        }
        // The first stage does reject (the cases test it).
        assert!(first > 0.5, "the first stage rejected at most {first} of the draws");
    }

    #[test]
    fn the_first_stages_bound_holds_over_the_whole_cap() {
        // A lobe far narrower than the cap (0.05°: κ about 1.3·10⁶, where a cosine
        // 10⁻⁷ off changes the density by 14 %), H with its cap's edge at the axis or just
        // past it: every normal drawn in the cap has a density of at most the first
        // stage's bound.
        let lobe = Lobe::from_spread_deg(0.05);
        let alpha = 4.2f64.to_radians();
        let (wide, omc) = (cap_wide(alpha), one_minus_cos(alpha));
        let mut rng = Stream::new(5, P, 0);
        for past in [-1e-4, 0.0, 1e-6, 1e-4, 1e-2] {
            let g = alpha + CAP_WIDEN_RAD + past;
            let h = h_at(g);
            let w = thinned(&WindowShape::around(&lobe, Some(h), alpha, 1e-3), alpha);
            let b = w.bound * w.cap_exponent(&lobe, h, wide).exp();
            let mut worst = 0.0f64;
            for _ in 0..200_000 {
                let n = around(h, 1.0 - rng.next_f64() * omc, &mut rng);
                worst = worst.max(lobe.density(f64::from(n.y)) / b);
            }
            assert!(worst <= 1.0 + 1e-12, "γ − α' = {past}: density {worst} times the bound");
        }
        // The cap's point nearest the axis itself, made in f32 as `around` makes its
        // normals (a unit combination, then one Newton step to length 1), for H on a fine
        // grid of polar angles across α: random draws almost never land there.
        let mut worst = 0.0f64;
        for k in 0..4_000 {
            let g = alpha + 1e-3 * (f64::from(k) / 2_000.0 - 1.0);
            let h = h_at(g);
            let w = thinned(&WindowShape::around(&lobe, Some(h), alpha, 1e-3), alpha);
            let b = w.bound * w.cap_exponent(&lobe, h, wide).exp();
            // Towards the axis in the plane of H and +y.
            let t = (Vec3::Y - h * h.y).normalize();
            let p = h * alpha.cos() as f32 + t * alpha.sin() as f32;
            let n = p * (1.5 - 0.5 * p.length_squared());
            worst = worst.max(lobe.density(f64::from(n.y)) / b);
        }
        assert!(worst <= 1.0 + 1e-12, "the cap's nearest point: density {worst} times the bound");
    }

    #[test]
    fn a_windows_candidates_carry_the_caps_lobe_mass() {
        // Each case: the lobe's spread (1°, 4°, 10°), the cap centre's polar angle, α,
        // and the cell's spread; windows (most cases) and thinned cells (a centre near
        // the axis) both. The mean of mass·[accepted] over n draws is the cap's lobe
        // mass, within 5 binomial standard errors (plus 1e-6 relative for the
        // quadrature, whose midpoint rule errs by far less at 200,000 steps).
        let n = 1_000_000;
        let mut rng = Stream::new(7, P, 0);
        let mut kinds = [0; 2];
        for (spread_deg, gamma_deg, alpha_deg, cell_deg) in [
            (1.0, 2.0, 8.0, 0.0),
            (1.0, 9.0, 8.0, 0.0),
            (10.0, 3.0, 4.0, 1.0),
            (10.0, 40.0, 4.0, 0.0),
            (10.0, 40.0, 4.0, 1.0),
            (4.0, 20.0, 4.1, 0.5),
            (1.0, 5.0, 4.1, 0.5),
            (4.0, 171.0, 4.1, 0.5),
        ] {
            let lobe = Lobe::from_spread_deg(spread_deg);
            let (g, alpha) = (f64::to_radians(gamma_deg), f64::to_radians(alpha_deg));
            let h = h_at(g);
            let w = Window::around(&lobe, Some(h), alpha, f64::to_radians(cell_deg), 0.0);
            let wide = cap_wide(alpha);
            let hits =
                (0..n).filter(|_| w.draw(&lobe, h, one_minus_cos(alpha), wide, &mut rng).is_some()).count();
            let kind = if w.bound > 0.0 { "thinned" } else { "window" };
            kinds[usize::from(w.bound > 0.0)] += 1;
            let case = format!("{spread_deg}° lobe, γ {gamma_deg}°, α {alpha_deg}° ({kind})");
            assert_carries_cap_mass(&w, (hits, n), (&lobe, g, alpha), &case);
        }
        assert!(kinds[0] >= 5 && kinds[1] >= 1, "cases by kind (window, thinned): {kinds:?}");
    }
}
