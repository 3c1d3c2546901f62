//! Exposure and tone mapping: linear HDR radiance to display-referred [0, 1].
//!
//! Renderers produce linear HDR frames; tone mapping happens at the edge (the CLI),
//! followed by the sRGB transfer function in [`crate::color::srgb_encode`].

use serde::{Deserialize, Serialize};

/// A tone-mapping operator, applied per channel after exposure.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ToneMap {
    /// Clip to [0, 1]: exact linear output for values already in range.
    Clamp,
    /// Reinhard's global operator x / (1 + x).
    Reinhard,
    /// Narkowicz's fit of the ACES filmic curve (2015): a film-like shoulder that keeps
    /// hot cores white and lets dim tails fall off smoothly.
    #[default]
    Aces,
}

/// Exposure in photographic stops plus a tone-mapping operator.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Exposure {
    /// Exposure compensation in stops (EV): the image is scaled by 2^ev before mapping.
    pub ev: f32,
    /// The operator.
    pub tone_map: ToneMap,
}

impl Exposure {
    /// Map one linear channel value to display-referred [0, 1]. NaN maps to 0.
    pub fn apply(&self, linear: f32) -> f32 {
        self.apply_scaled(linear, self.ev.exp2())
    }

    /// Map many values: the exposure scale is computed once.
    pub fn apply_all(&self, linear: &[f32], mut out: impl FnMut(f32)) {
        let scale = self.ev.exp2();
        for &v in linear {
            out(self.apply_scaled(v, scale));
        }
    }

    #[inline]
    fn apply_scaled(&self, linear: f32, scale: f32) -> f32 {
        let x = linear * scale;
        // Every operator is within 1e-6 of white at 1e6 (8-bit code 255); clamping there
        // keeps x·(a·x + b) from overflowing to inf/inf = NaN for extreme radiance.
        let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1e6) };
        let y = match self.tone_map {
            ToneMap::Clamp => x,
            ToneMap::Reinhard => x / (1.0 + x),
            ToneMap::Aces => {
                let (a, b, c, d, e) = (2.51, 0.03, 2.43, 0.59, 0.14);
                (x * (a * x + b)) / (x * (c * x + d) + e)
            }
        };
        y.clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn operators_are_monotone_and_bounded() {
        for tone_map in [ToneMap::Clamp, ToneMap::Reinhard, ToneMap::Aces] {
            let e = Exposure { ev: 0.0, tone_map };
            let mut last = -1.0;
            for i in 0..2000 {
                let v = e.apply(i as f32 * 0.01);
                assert!((0.0..=1.0).contains(&v));
                assert!(v >= last, "{tone_map:?} not monotone at {i}");
                last = v;
            }
            assert_eq!(e.apply(f32::NAN), 0.0);
            assert_eq!(e.apply(-5.0), 0.0);
            // Extreme radiance saturates to white, never NaN (which would encode black).
            for v in [1e19, 1e30, f32::MAX, f32::INFINITY] {
                assert!(e.apply(v) >= 0.999_999, "{tone_map:?} at {v}: {}", e.apply(v));
            }
        }
    }

    #[test]
    fn one_stop_doubles_linear_input() {
        let e = Exposure { ev: 1.0, tone_map: ToneMap::Clamp };
        assert_eq!(e.apply(0.25), 0.5);
    }
}
