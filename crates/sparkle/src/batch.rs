//! The facet motion and visibility test of `sim`, eight facets at a time in `f32x8`
//! lanes (SSE2 pairs on baseline x86-64, IEEE operations only: no approximate
//! reciprocals, no fused multiply-add unless the whole build targets it).
//!
//! Every facet update of both methods goes through here, so the stochastic model and
//! brute force share one dynamics. Random numbers come from eight generators in lanes
//! ([`LaneRng`]) seeded from each chunk's own [`Stream`], so results depend only on the
//! chunking, never on threads.
//!
//! Per facet and step, in this order for each group of eight: three 24-bit uniforms give
//! the own displacement, two the rotation (radius² and angle in the tangent disc), and
//! for a lobe one more the Metropolis coin ([`move_and_test`]: each group is loaded
//! once, moved, turned, tested and stored). Birth candidates of a region are drawn in
//! lanes too ([`Geometry::candidates_in`]); those of the per-cell table are drawn scalar.

use glam::Vec3;
use phenomena_core::rng::Stream;
use wide::{f32x8, i32x8, u32x8};

use crate::config::LightAt;
use crate::model::{Eye, Geometry, Space};
use crate::sim::{Motion, Seen};

/// Facets per batch.
pub(crate) const LANES: usize = 8;

/// Three coordinates of eight facets.
#[derive(Clone, Copy, Debug)]
pub(crate) struct V8 {
    pub(crate) x: f32x8,
    pub(crate) y: f32x8,
    pub(crate) z: f32x8,
}

impl V8 {
    #[inline]
    pub(crate) fn splat(v: Vec3) -> Self {
        Self { x: f32x8::splat(v.x), y: f32x8::splat(v.y), z: f32x8::splat(v.z) }
    }

    /// Lanes `0..src.len()` from `src` (at most [`LANES`]); the rest repeat the first.
    #[inline(always)]
    pub(crate) fn load(src: &[Vec3]) -> Self {
        if let Ok(a) = <&[Vec3; LANES]>::try_from(src) {
            // A whole group: fixed indices, so no loop and no bounds checks.
            return Self {
                x: f32x8::from([a[0].x, a[1].x, a[2].x, a[3].x, a[4].x, a[5].x, a[6].x, a[7].x]),
                y: f32x8::from([a[0].y, a[1].y, a[2].y, a[3].y, a[4].y, a[5].y, a[6].y, a[7].y]),
                z: f32x8::from([a[0].z, a[1].z, a[2].z, a[3].z, a[4].z, a[5].z, a[6].z, a[7].z]),
            };
        }
        let (mut x, mut y, mut z) = ([src[0].x; LANES], [src[0].y; LANES], [src[0].z; LANES]);
        for (i, v) in src.iter().enumerate() {
            x[i] = v.x;
            y[i] = v.y;
            z[i] = v.z;
        }
        Self { x: x.into(), y: y.into(), z: z.into() }
    }

    #[inline(always)]
    fn store(&self, dst: &mut [Vec3]) {
        let (x, y, z) = (self.x.to_array(), self.y.to_array(), self.z.to_array());
        if let Ok(a) = <&mut [Vec3; LANES]>::try_from(&mut *dst) {
            for i in 0..LANES {
                a[i] = Vec3::new(x[i], y[i], z[i]);
            }
            return;
        }
        for (i, v) in dst.iter_mut().enumerate() {
            *v = Vec3::new(x[i], y[i], z[i]);
        }
    }

    #[inline]
    fn add(self, o: Self) -> Self {
        Self { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }

    #[inline]
    pub(crate) fn sub(self, o: Self) -> Self {
        Self { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }

    #[inline]
    fn scale(self, s: f32x8) -> Self {
        Self { x: self.x * s, y: self.y * s, z: self.z * s }
    }

    /// Same operation order as glam's `Vec3::dot`.
    #[inline]
    pub(crate) fn dot(self, o: Self) -> f32x8 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// glam's `any_orthonormal_pair` (Duff et al. 2017) in lanes: two unit vectors
    /// completing the unit `self` to an orthonormal frame.
    #[inline]
    fn tangents(self) -> (Self, Self) {
        let n = self;
        let sign = n.z.is_sign_negative().select(-f32x8::ONE, f32x8::ONE);
        let k = -f32x8::ONE / (sign + n.z);
        let m = n.x * n.y * k;
        let e1 = V8 { x: f32x8::ONE + sign * n.x * n.x * k, y: sign * m, z: -sign * n.x };
        let e2 = V8 { x: m, y: sign + n.y * n.y * k, z: -n.y };
        (e1, e2)
    }

    /// One Newton step toward length 1, for vectors that are unit up to rounding
    /// (no square root, no division).
    #[inline]
    fn newton_unit(self) -> Self {
        self.scale(f32x8::splat(1.5) - f32x8::splat(0.5) * self.dot(self))
    }

    /// `d * (1 / sqrt(|d|²))`, as `Seen::test` writes it.
    #[inline]
    fn unit(self) -> Self {
        self.scale(f32x8::ONE / self.dot(self).sqrt())
    }
}

/// Eight xoshiro128++ generators (Blackman and Vigna), one per lane, seeded from a
/// scalar stream: random numbers made in lanes, without a scalar loop per lane.
#[derive(Clone, Debug)]
pub(crate) struct LaneRng {
    s: [u32x8; 4],
}

impl LaneRng {
    /// Seeded from 16 words of `rng` (a lane whose four words are all zero, which
    /// xoshiro cannot leave, gets a one).
    pub(crate) fn new(rng: &mut Stream) -> Self {
        let mut s = [[0u32; LANES]; 4];
        for lane in 0..LANES {
            let (a, b) = (rng.next_u64(), rng.next_u64());
            let words = [a as u32, (a >> 32) as u32, b as u32, (b >> 32) as u32];
            for (w, v) in s.iter_mut().zip(words) {
                w[lane] = v;
            }
            if words == [0; 4] {
                s[0][lane] = 1;
            }
        }
        Self { s: s.map(u32x8::from) }
    }

    #[inline]
    fn next(&mut self) -> u32x8 {
        let rotl = |x: u32x8, k: u32| (x << k) | (x >> (32 - k));
        let [s0, s1, s2, s3] = &mut self.s;
        let result = rotl(*s0 + *s3, 7) + *s0;
        let t = *s1 << 9;
        *s2 ^= *s0;
        *s3 ^= *s1;
        *s1 ^= *s2;
        *s0 ^= *s3;
        *s2 ^= t;
        *s3 = rotl(*s3, 11);
        result
    }

    /// Uniform in [0, 1) with 24 bits, per lane.
    #[inline]
    pub(crate) fn unit(&mut self) -> f32x8 {
        let bits: i32x8 = wide::bytemuck::cast(self.next() >> 8);
        f32x8::from_i32x8(bits) * f32x8::splat(1.0 / 16_777_216.0)
    }
}

impl Motion {
    /// Eight positions moved by the shared displacement times `sign` (1 forward, -1 to
    /// undo a frame) plus each facet's own displacement (uniform in the cube of
    /// half-side `jitter_m`: symmetric, so undoing draws a fresh one), then wrapped into
    /// the box in lanes. `false` when some lane needs more than one wrap per axis (a
    /// step as large as the box): the caller wraps those with `Space::wrap`.
    #[inline]
    fn displace_lanes(&self, space: &Space, x: V8, sign: f32, rng: &mut LaneRng) -> (V8, bool) {
        let mut x = x.add(V8::splat(self.shared_m * sign));
        if self.jitter_m != 0.0 {
            let (two, h) = (f32x8::splat(2.0), f32x8::splat(self.jitter_m));
            let mut j = || (rng.unit() * two - f32x8::ONE) * h;
            x = x.add(V8 { x: j(), y: j(), z: j() });
        }
        let ok = wrap_lanes(space, &mut x);
        (x, ok)
    }

    /// Eight normals turned by the random rotation of [`Motion::rotate_lanes`], kept by
    /// the Metropolis rule against the plate lobe around +y (always, for uniform normals).
    #[inline]
    fn turn_lanes(&self, n: V8, rng: &mut LaneRng) -> V8 {
        if self.rotation_rad == 0.0 {
            return n;
        }
        let p = self.rotate_lanes(n, rng);
        if self.lobe.is_uniform() {
            return p;
        }
        // exp(κ (N'·y - N·y)) ≥ u: kept; κ (N'·y - N·y) in f32 has the rounding of
        // the difference of two f32 components, as a scalar computation would.
        let ratio = (f32x8::splat(self.lobe.kappa as f32) * (p.y - n.y)).exp();
        let keep = rng.unit().simd_lt(ratio);
        V8 { x: keep.select(p.x, n.x), y: keep.select(p.y, n.y), z: keep.select(p.z, n.z) }
    }

    /// Move `xs` one frame (see [`Motion::displace_lanes`]); for tests of the motion alone.
    #[cfg(test)]
    pub(crate) fn displace(&self, space: &Space, xs: &mut [Vec3], sign: f32, rng: &mut LaneRng) {
        let step = Step { motion: self, shift: sign, turn: false };
        for xc in xs.chunks_mut(LANES) {
            step.apply(space, xc, &mut [], rng);
        }
    }

    /// Turn every normal (see [`Motion::turn_lanes`]); for tests of the motion alone.
    #[cfg(test)]
    pub(crate) fn turn(&self, ns: &mut [Vec3], rng: &mut LaneRng) {
        for nc in ns.chunks_mut(LANES) {
            self.turn_lanes(V8::load(nc), rng).store(nc);
        }
    }

    /// Eight proposals, each a random rotation of at most δ: N' = N cos ψ + t sin ψ with
    /// the tangent step t sin ψ uniform over the tangent disc of radius sin δ (radius
    /// √u sin δ, angle 2πv), so N' is spread evenly around N, ψ ≤ δ. The proposal's
    /// density depends only on the angle between N and N', so it is symmetric, and the
    /// Metropolis rule of [`Motion::turn`] keeps the lobe. The tangent frame is glam's
    /// `any_orthonormal_pair` written in lanes; the result takes one Newton step toward
    /// length 1 (unit up to rounding already) instead of a square root and a division.
    #[inline]
    fn rotate_lanes(&self, n: V8, rng: &mut LaneRng) -> V8 {
        let rad = rng.unit().sqrt() * f32x8::splat(self.sin_rotation);
        let (s, c) = (rng.unit() * f32x8::splat(std::f32::consts::TAU)).sin_cos();
        let (a, b) = (rad * c, rad * s);
        let cz = (f32x8::ONE - (a * a + b * b)).max(f32x8::ZERO).sqrt();
        let (e1, e2) = n.tangents();
        n.scale(cz).add(e1.scale(a)).add(e2.scale(b)).newton_unit()
    }
}

impl Geometry {
    /// Birth candidates' normals: for each position `xs[i]`, a unit vector at
    /// 1 - cos = `omc[i]` from `side[i]`·H(`xs[i]`) (side ±1), at the azimuth 2π `turn[i]`
    /// about it (`turn` uniform on [0, 1) gives a uniform azimuth); NaN where H does not
    /// exist (L + V vanishes, or the facet sits on the eye or the lamp).
    #[cfg(test)]
    pub(crate) fn around_half_vectors(
        &self,
        xs: &[Vec3],
        side: &[f32],
        omc: &[f32],
        turn: &[f32],
        out: &mut [Vec3],
    ) {
        let chunks = xs.chunks(LANES).zip(side.chunks(LANES)).zip(omc.chunks(LANES)).zip(turn.chunks(LANES));
        for ((((xc, sc), oc), tc), dst) in chunks.zip(out.chunks_mut(LANES)) {
            let lanes = |v: &[f32]| {
                let mut a = [v[0]; LANES];
                a[..v.len()].copy_from_slice(v);
                f32x8::from(a)
            };
            let (p, fine) = self.around_half_lanes(V8::load(xc), lanes(sc), lanes(oc), lanes(tc));
            p.store(dst);
            for (i, v) in dst.iter_mut().enumerate() {
                if fine & (1 << i) == 0 {
                    *v = Vec3::NAN;
                }
            }
        }
    }

    /// Eight normals at 1 - cos = `omc` from `side`·H(x) (side ±1), at the azimuth
    /// 2π `turn` about it, and the mask of the lanes where H exists.
    #[inline]
    fn around_half_lanes(&self, x: V8, side: f32x8, omc: f32x8, turn: f32x8) -> (V8, u32) {
        let v = match self.eye {
            Eye::Point(e) => V8::splat(e).sub(x).unit(),
            Eye::Direction(d) => V8::splat(d),
        };
        let l = match self.light {
            LightAt::Direction(d) => V8::splat(d),
            LightAt::Position(p) => V8::splat(p).sub(x).unit(),
        };
        let u = l.add(v);
        let len2 = u.dot(u);
        let fine = len2.simd_gt(f32x8::splat(1e-12)) & len2.is_finite();
        let axis = u.scale(side / len2.sqrt());
        let (w, s) = (f32x8::ONE - omc, (omc * (f32x8::splat(2.0) - omc)).sqrt());
        let (sn, cs) = (turn * f32x8::splat(std::f32::consts::TAU)).sin_cos();
        let (e1, e2) = axis.tangents();
        let p = axis.scale(w).add(e1.scale(cs * s)).add(e2.scale(sn * s)).newton_unit();
        (p, fine.to_bitmask())
    }

    /// Eight birth candidates in the box `corner + size·[0, 1)³`: positions uniform, and
    /// normals at 1 - cos uniform in [`omc.0`, `omc.1`) from ±H there (the sign a fair
    /// coin when `two_sided`, else +), at a uniform azimuth. Returns positions, normals
    /// and the mask of the lanes where H exists.
    #[inline]
    pub(crate) fn candidates_in(
        &self,
        corner: Vec3,
        size: Vec3,
        omc: (f32, f32),
        two_sided: bool,
        rng: &mut LaneRng,
    ) -> (V8, V8, u32) {
        let mut at = |c: f32, s: f32| f32x8::splat(c) + f32x8::splat(s) * rng.unit();
        let x = V8 { x: at(corner.x, size.x), y: at(corner.y, size.y), z: at(corner.z, size.z) };
        let side = if two_sided {
            rng.unit().simd_lt(f32x8::splat(0.5)).select(-f32x8::ONE, f32x8::ONE)
        } else {
            f32x8::ONE
        };
        let o = f32x8::splat(omc.0) + rng.unit() * f32x8::splat(omc.1 - omc.0);
        let (n, fine) = self.around_half_lanes(x, side, o, rng.unit());
        (x, n, fine)
    }
}

/// A birth candidate's first frame: the normal `n0` (at t) turned by `motion` into
/// t + 1 (unchanged without motion), and (N·H)² at `to` where seen, else -1.
#[inline]
pub(crate) fn first_frame(
    motion: Option<&Motion>,
    to: &Seen,
    space: &Space,
    x1: V8,
    n0: V8,
    rng: &mut LaneRng,
) -> (V8, f32x8) {
    let n1 = match motion {
        Some(m) => m.turn_lanes(n0, rng),
        None => n0,
    };
    (n1, to.test_lanes(space, x1, n1))
}

/// Lane `i` of eight vectors.
#[inline]
pub(crate) fn lane(v: &V8, i: usize) -> Vec3 {
    Vec3::new(v.x.as_array()[i], v.y.as_array()[i], v.z.as_array()[i])
}

/// Wrap into the periodic box, one wrap per axis in lanes; `false` when some lane is
/// still outside (anything further, which a step smaller than the box never needs, is
/// left to `Space::wrap`).
#[inline]
fn wrap_lanes(space: &Space, x: &mut V8) -> bool {
    let Space::Box { min, size } = *space else {
        return true;
    };
    let mut ok = true;
    for (v, lo, s) in [(&mut x.x, min.x, size.x), (&mut x.y, min.y, size.y), (&mut x.z, min.z, size.z)] {
        let (s8, zero) = (f32x8::splat(s), f32x8::ZERO);
        let mut r = *v - f32x8::splat(lo);
        r = r.simd_lt(zero).select(r + s8, r);
        r = r.simd_ge(s8).select(r - s8, r);
        ok &= (r.simd_ge(zero) & r.simd_lt(s8)).all();
        *v = r + f32x8::splat(lo);
    }
    ok
}

/// What one frame does to a facet: displaced by `motion` times `shift` (1 forward, -1
/// back, 0 not at all) and, when `turn`, turned by it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Step<'a> {
    pub(crate) motion: &'a Motion,
    pub(crate) shift: f32,
    pub(crate) turn: bool,
}

impl<'a> Step<'a> {
    /// One frame forward: displaced and turned by `motion`.
    pub(crate) fn forward(motion: &'a Motion) -> Self {
        Self { motion, shift: 1.0, turn: true }
    }

    /// Apply to one group of at most [`LANES`] facets in place (`nc` may be empty when
    /// only positions move); returns the moved lanes. Per group the random numbers come
    /// in a fixed order: the displacement's three, then the rotation's two (and the
    /// Metropolis coin).
    #[inline]
    fn apply(&self, space: &Space, xc: &mut [Vec3], nc: &mut [Vec3], rng: &mut LaneRng) -> (V8, V8) {
        let mut x = V8::load(xc);
        if self.shift != 0.0 {
            let (moved, ok) = self.motion.displace_lanes(space, x, self.shift, rng);
            moved.store(xc);
            x = moved;
            if !ok {
                for v in xc.iter_mut() {
                    *v = space.wrap(*v);
                }
                x = V8::load(xc);
            }
        }
        if nc.is_empty() {
            return (x, x);
        }
        let mut n = V8::load(nc);
        if self.turn {
            n = self.motion.turn_lanes(n, rng);
            n.store(nc);
        }
        (x, n)
    }
}

/// One frame for every facet (moved by `step`, if any) and then tested by `to`: writes
/// (N·H)² per facet when seen, else -1, into `c2`. One pass over the facets, eight at a
/// time: each group is loaded once, moved, turned, tested and stored.
pub(crate) fn move_and_test(
    step: Option<Step<'_>>,
    to: &Seen,
    space: &Space,
    xs: &mut [Vec3],
    ns: &mut [Vec3],
    c2: &mut [f32],
    rng: &mut LaneRng,
) {
    debug_assert!(xs.len() == ns.len() && ns.len() == c2.len());
    for ((xc, nc), out) in xs.chunks_mut(LANES).zip(ns.chunks_mut(LANES)).zip(c2.chunks_mut(LANES)) {
        let (x, n) = match &step {
            Some(s) => s.apply(space, xc, nc, rng),
            None => (V8::load(xc), V8::load(nc)),
        };
        let c = to.test_lanes(space, x, n).to_array();
        out.copy_from_slice(&c[..out.len()]);
    }
}

impl Seen {
    /// `Seen::test` for every facet: `c2[i]` = (N·H)² when facet i is seen, else -1.
    /// Lane for lane the same operations as the scalar test, so the same answers.
    #[cfg(test)]
    pub(crate) fn test_all(&self, space: &Space, xs: &[Vec3], ns: &[Vec3], c2: &mut [f32]) {
        debug_assert!(xs.len() == ns.len() && ns.len() == c2.len());
        for ((xc, nc), out) in xs.chunks(LANES).zip(ns.chunks(LANES)).zip(c2.chunks_mut(LANES)) {
            let c = self.test_lanes(space, V8::load(xc), V8::load(nc)).to_array();
            out.copy_from_slice(&c[..out.len()]);
        }
    }

    /// `Seen::test` for eight facets: (N·H)² where seen, else -1.
    #[inline]
    fn test_lanes(&self, space: &Space, x: V8, n: V8) -> f32x8 {
        let v = match self.geo.eye {
            Eye::Point(e) => V8::splat(e).sub(x).unit(),
            Eye::Direction(d) => V8::splat(d),
        };
        let l = match self.geo.light {
            LightAt::Direction(d) => V8::splat(d),
            LightAt::Position(p) => V8::splat(p).sub(x).unit(),
        };
        let u = l.add(v);
        let u2 = u.dot(u);
        let dot = n.dot(u);
        let mut seen =
            u2.simd_gt(f32x8::splat(1e-12)) & (dot * dot).simd_ge(f32x8::splat(self.cos2_theta) * u2);
        if !self.two_sided {
            seen &= dot.simd_ge(f32x8::ZERO);
        }
        if self.dome
            && let Space::Dome { centre, .. } = *space
        {
            let a = x.sub(V8::splat(centre));
            let len2 = a.dot(a);
            let a = a.unit();
            let fine = len2.simd_gt(f32x8::ZERO);
            let (av, al) = (a.dot(v), a.dot(l));
            // `normalize_or(Vec3::Y)` at the centre itself: the axis is +y.
            let (av, al) = (fine.select(av, v.y), fine.select(al, l.y));
            seen &= av.simd_gt(f32x8::ZERO) & al.simd_gt(f32x8::ZERO);
        }
        seen.select(dot * dot / u2, -f32x8::ONE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use phenomena_core::rng::Purpose;

    const P: Purpose = Purpose::named("test.sparkle.batch");

    /// A motion that only turns normals, by at most `delta`.
    fn turning(delta: f32, lobe: crate::model::Lobe) -> Motion {
        Motion { shared_m: Vec3::ZERO, jitter_m: 0.0, rotation_rad: delta, sin_rotation: delta.sin(), lobe }
    }

    fn random_facets(k: usize, rng: &mut Stream) -> (Vec<Vec3>, Vec<Vec3>) {
        let xs = (0..k)
            .map(|_| Vec3::new(rng.uniform(-20.0, 20.0), rng.uniform(0.0, 30.0), rng.uniform(-60.0, -1.0)))
            .collect();
        let ns = (0..k).map(|_| rng.on_unit_sphere()).collect();
        (xs, ns)
    }

    #[test]
    fn lanes_test_as_the_scalar_test_does() {
        // Wide cones so that both answers occur often, over every eye/light/side/dome case.
        let mut rng = Stream::new(1, P, 0);
        let (xs, ns) = random_facets(1003, &mut rng);
        let spaces = [
            Space::Box { min: Vec3::new(-20.0, 0.0, -60.0), size: Vec3::new(40.0, 30.0, 59.0) },
            Space::Dome { centre: Vec3::new(0.0, 0.0, -30.0), radius: 10.0 },
        ];
        let mut total = 0;
        for eye in [Eye::Point(Vec3::new(0.0, 2.0, 5.0)), Eye::Direction(Vec3::new(0.0, 0.6, 0.8))] {
            for light in
                [LightAt::Direction(Vec3::new(0.6, 0.8, 0.0)), LightAt::Position(Vec3::new(3.0, 8.0, -10.0))]
            {
                for two_sided in [false, true] {
                    for space in spaces {
                        let seen = Seen {
                            geo: Geometry { eye, light },
                            cos2_theta: 0.3,
                            two_sided,
                            dome: matches!(space, Space::Dome { .. }),
                        };
                        let mut c2 = vec![0.0; xs.len()];
                        seen.test_all(&space, &xs, &ns, &mut c2);
                        let mut hits = 0;
                        for i in 0..xs.len() {
                            let scalar = seen.test(xs[i], ns[i], &space).unwrap_or(-1.0);
                            assert_eq!(c2[i].to_bits(), scalar.to_bits(), "facet {i}");
                            hits += usize::from(scalar >= 0.0);
                        }
                        // Both answers in every case (a wrong mask would show).
                        assert!(hits > 0 && hits < xs.len(), "{hits}");
                        total += hits;
                    }
                }
            }
        }
        assert!(total > 2000, "{total}");
    }

    #[test]
    fn rotations_are_unit_within_the_largest_angle_and_spread_evenly() {
        let mut sim_rng = Stream::new(2, P, 0);
        let (_, ns) = random_facets(40_000, &mut sim_rng);
        let delta = 3f32.to_radians();
        let m = turning(delta, crate::model::Lobe::new(0.0));
        let mut turned = ns.clone();
        m.turn(&mut turned, &mut LaneRng::new(&mut sim_rng));
        // The tangent step's length sin ψ is √u sin δ: (sin ψ / sin δ)² is uniform on
        // [0, 1] (mean 1/2, sd 1/√12; tolerance 5 standard errors).
        let mut mean = 0.0;
        for (a, b) in ns.iter().zip(&turned) {
            assert!((b.length() - 1.0).abs() < 1e-5);
            let sin_psi = a.cross(*b).length();
            assert!(sin_psi <= delta.sin() * (1.0 + 1e-4) + 1e-6, "{sin_psi}");
            mean += f64::from((sin_psi / delta.sin()).powi(2));
        }
        mean /= ns.len() as f64;
        assert!((mean - 0.5).abs() < 5.0 / (12.0 * ns.len() as f64).sqrt(), "{mean}");
    }

    #[test]
    fn candidate_normals_sit_at_the_asked_angle_from_the_half_vector_at_a_uniform_azimuth() {
        let geo = Geometry {
            eye: Eye::Point(Vec3::new(0.0, 2.0, 5.0)),
            light: LightAt::Position(Vec3::new(3.0, 8.0, -10.0)),
        };
        let mut rng = Stream::new(4, P, 0);
        let (xs, _) = random_facets(20_003, &mut rng);
        let side: Vec<f32> = (0..xs.len()).map(|i| if i % 3 == 0 { -1.0 } else { 1.0 }).collect();
        let omc: Vec<f32> = (0..xs.len()).map(|_| rng.uniform(0.0, 1e-3)).collect();
        let turn: Vec<f32> = (0..xs.len()).map(|_| rng.next_f32()).collect();
        let mut out = vec![Vec3::ZERO; xs.len()];
        geo.around_half_vectors(&xs, &side, &omc, &turn, &mut out);
        let (mut c1, mut s1) = (0.0f64, 0.0f64);
        for i in 0..xs.len() {
            let h = geo.half_vector(xs[i]).expect("exists here") * side[i];
            let n = out[i];
            assert!((n.length() - 1.0).abs() < 1e-6, "{i}: {}", n.length());
            // 1 - cos to within f32 rounding of unit vectors (a few 1e-7).
            assert!((1.0 - n.dot(h) - omc[i]).abs() < 1e-6, "{i}: {} vs {}", 1.0 - n.dot(h), omc[i]);
            // The azimuth about H in H's own tangent frame is 2π turn.
            let (e1, e2) = h.any_orthonormal_pair();
            let t = (n - h * n.dot(h)).normalize();
            let phi = f64::from(t.dot(e2)).atan2(f64::from(t.dot(e1)));
            let want = std::f64::consts::TAU * f64::from(turn[i]);
            let d = (phi - want).rem_euclid(std::f64::consts::TAU);
            // Rounding of ~1e-7 in n over a tangent of length √(2 omc) ≥ 4.5e-3 (omc ≥ 1e-5)
            // turns the azimuth by < 1e-4 rad; below that the azimuth is not measurable.
            assert!(d.min(std::f64::consts::TAU - d) < 1e-3 || omc[i] < 1e-5, "{i}: {phi} vs {want}");
            c1 += f64::from(t.dot(e1));
            s1 += f64::from(t.dot(e2));
        }
        // Uniform azimuth: mean of cos and sin 0 within 5 standard errors (sd 1/√2).
        let k = xs.len() as f64;
        assert!(c1.abs() / k < 5.0 / (2.0 * k).sqrt() && s1.abs() / k < 5.0 / (2.0 * k).sqrt(), "{c1} {s1}");
        // No half vector: the light exactly behind the facet as seen from the eye.
        let opposed = Geometry { eye: Eye::Direction(Vec3::Z), light: LightAt::Direction(-Vec3::Z) };
        let mut one = [Vec3::ZERO];
        opposed.around_half_vectors(&[Vec3::ZERO], &[1.0], &[1e-4], &[0.5], &mut one);
        assert!(!one[0].is_finite());
    }

    #[test]
    fn region_candidates_fill_their_box_and_annulus_on_both_sides() {
        // Positions within the box, 1 - cos from ±H(x) within the asked range, the side a
        // fair coin (two-sided; fraction within 5 standard errors of 1/2) or always +H.
        let geo = Geometry {
            eye: Eye::Point(Vec3::new(0.0, 2.0, 5.0)),
            light: LightAt::Direction(Vec3::new(0.6, 0.8, 0.0)),
        };
        let (corner, size, omc) = (Vec3::new(-3.0, 1.0, -20.0), Vec3::new(2.0, 0.5, 4.0), (1e-4f32, 1e-3f32));
        let mut rng = LaneRng::new(&mut Stream::new(7, P, 0));
        for two_sided in [true, false] {
            let (mut minus, mut total) = (0usize, 0usize);
            for _ in 0..4000 {
                let (x, n, fine) = geo.candidates_in(corner, size, omc, two_sided, &mut rng);
                assert_eq!(fine, 0xff);
                for i in 0..LANES {
                    let (x, n) = (lane(&x, i), lane(&n, i));
                    assert!(x.cmpge(corner).all() && x.cmple(corner + size).all(), "{x}");
                    let h = geo.half_vector(x).expect("exists here");
                    let side = if n.dot(h) < 0.0 { -1.0 } else { 1.0 };
                    minus += usize::from(side < 0.0);
                    total += 1;
                    let o = 1.0 - n.dot(h * side);
                    // f32 rounding of unit vectors: a few 1e-7.
                    assert!(o > omc.0 - 1e-6 && o < omc.1 + 1e-6, "{o}");
                }
            }
            let frac = minus as f64 / total as f64;
            if two_sided {
                assert!((frac - 0.5).abs() < 5.0 * 0.5 / (total as f64).sqrt(), "{frac}");
            } else {
                assert_eq!(minus, 0);
            }
        }
    }

    #[test]
    fn lane_generators_are_uniform_and_independent() {
        // 2¹⁸ draws per lane into 64 bins: Pearson χ² with 63 degrees of freedom stays
        // below 120 (p ≈ 2·10⁻⁵) per lane; neighbouring lanes' draws are uncorrelated
        // (|r| < 5/√n, five standard errors).
        let mut lanes = LaneRng::new(&mut Stream::new(5, P, 0));
        let n = 1usize << 18;
        let mut bins = vec![[0u32; 64]; LANES];
        let mut prod = [0.0f64; LANES];
        for _ in 0..n {
            let u = lanes.unit().to_array();
            for l in 0..LANES {
                assert!((0.0..1.0).contains(&u[l]));
                bins[l][(u[l] * 64.0) as usize] += 1;
                prod[l] += (f64::from(u[l]) - 0.5) * (f64::from(u[(l + 1) % LANES]) - 0.5);
            }
        }
        let e = n as f64 / 64.0;
        for l in 0..LANES {
            let chi2: f64 = bins[l].iter().map(|&b| (f64::from(b) - e).powi(2) / e).sum();
            assert!(chi2 < 120.0, "lane {l}: χ² {chi2}");
            let r = prod[l] / n as f64 * 12.0;
            assert!(r.abs() < 5.0 / (n as f64).sqrt(), "lanes {l}, {}: r {r}", (l + 1) % LANES);
        }
    }

    #[test]
    fn turning_keeps_the_plate_lobe() {
        // Normals drawn from the lobe stay distributed by it under many Metropolis steps
        // (mean N·y = coth κ - 1/κ; tolerance 5 standard errors of the start sample's
        // spread, steps being correlated only within a normal's own chain).
        let lobe = crate::model::Lobe::from_spread_deg(3.0);
        let mut rng = Stream::new(6, P, 0);
        let mut ns: Vec<Vec3> = (0..20_000).map(|_| lobe.sample(Vec3::Y, &mut rng)).collect();
        let delta = 1f32.to_radians();
        let m = turning(delta, lobe);
        let mut lanes = LaneRng::new(&mut rng);
        for _ in 0..300 {
            m.turn(&mut ns, &mut lanes);
        }
        let k = lobe.kappa;
        let want = 1.0 / k.tanh() - 1.0 / k;
        let ys: Vec<f64> = ns.iter().map(|n| f64::from(n.y)).collect();
        let mean = ys.iter().sum::<f64>() / ys.len() as f64;
        // The spread of N·y under the lobe: var = 1/κ² - 1/sinh²κ ≈ 1/κ².
        let sd = 1.0 / k;
        assert!((mean - want).abs() < 5.0 * sd / (ys.len() as f64).sqrt(), "{mean} vs {want}");
        assert!(ns.iter().all(|n| (n.length() - 1.0).abs() < 1e-5));
    }

    #[test]
    fn wrapping_in_lanes_keeps_facets_in_the_box() {
        let space = Space::Box { min: Vec3::new(-1.0, 0.0, -2.0), size: Vec3::new(2.0, 1.0, 2.0) };
        let m = Motion {
            shared_m: Vec3::new(0.3, -0.2, 0.05),
            jitter_m: 0.1,
            rotation_rad: 0.0,
            sin_rotation: 0.0,
            lobe: crate::model::Lobe::new(0.0),
        };
        let mut rng = Stream::new(3, P, 0);
        let mut lanes = LaneRng::new(&mut rng);
        let mut xs: Vec<Vec3> = (0..1001)
            .map(|_| Vec3::new(rng.uniform(-1.0, 1.0), rng.uniform(0.0, 1.0), rng.uniform(-2.0, 0.0)))
            .collect();
        // Far steps too (the scalar fallback), forward and back.
        for (sign, big) in [(1.0, false), (-1.0, false), (1.0, true)] {
            let mut mm = m;
            if big {
                mm.shared_m = Vec3::new(7.3, -4.1, 5.0);
            }
            for _ in 0..20 {
                mm.displace(&space, &mut xs, sign, &mut lanes);
                for x in &xs {
                    assert!(
                        x.cmpge(Vec3::new(-1.0, 0.0, -2.0)).all() && x.cmplt(Vec3::new(1.0, 1.0, 0.0)).all(),
                        "{x}"
                    );
                }
            }
        }
    }
}
