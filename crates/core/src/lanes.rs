//! Eight f32 lanes over plain slices: the loads, adds and run masks that the SIMD loops
//! of the phenomena share (the aurora's pair sweeps, the flame's density pass and splat
//! stamp). Operations are `wide`'s lane-wise IEEE ones, so a lane gives the bits of the
//! same scalar expression.
//!
//! ```
//! use phenomena_core::lanes::{add, in_run, load};
//! let mut out = [1.0f32; 10];
//! add(&mut out, load(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]));
//! assert_eq!(out[7], 9.0);
//! assert_eq!(in_run(3).to_bitmask(), 0b111);
//! ```

use wide::f32x8;

/// Lanes per vector.
pub const LANES: usize = 8;

/// Eight values from the start of `s` (at least eight long).
#[inline]
pub fn load(s: &[f32]) -> f32x8 {
    let a: [f32; LANES] = s[..LANES].try_into().expect("eight lanes");
    f32x8::from(a)
}

/// `out[l] += v[l]` for the lanes that fall inside `out` (all eight when it is long
/// enough, as one vector operation).
#[inline]
pub fn add(out: &mut [f32], v: f32x8) {
    if out.len() >= LANES {
        let o = &mut out[..LANES];
        let sum = load(o) + v;
        o.copy_from_slice(&sum.to_array());
    } else {
        for (o, x) in out.iter_mut().zip(v.to_array()) {
            *o += x;
        }
    }
}

/// Lanes holding one of the `remaining` items left in a run (all when ≥ 8).
#[inline]
pub fn in_run(remaining: usize) -> f32x8 {
    const INDEX: [f32; LANES] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];
    f32x8::from(INDEX).simd_lt(f32x8::splat(remaining.min(LANES) as f32))
}
