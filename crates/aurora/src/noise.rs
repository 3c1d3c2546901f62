//! Coherent noise over space and time (Perlin or simplex, 3-D and 4-D), summed over
//! octaves (fractional Brownian motion), built on the `noise` crate's generators.
//!
//! The aurora adds noise over (x, z, t) to its electric potential (thesis §2.2.3); the
//! time axis is just another coordinate, so animation is smooth and deterministic.
//!
//! ```
//! use phenomena_aurora::noise::{FractalNoise, NoiseKind};
//! let n = FractalNoise { kind: NoiseKind::Perlin, seed: 3, octaves: 4, ..Default::default() }
//!     .sampler();
//! let a = n.sample3(0.3, 1.7, 0.25);
//! assert_eq!(a, n.sample3(0.3, 1.7, 0.25));
//! assert!(a.abs() <= n.bound());
//! ```

use noise::{NoiseFn, OpenSimplex, Perlin};
use serde::{Deserialize, Serialize};

/// The base gradient-noise generator.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseKind {
    /// Improved Perlin noise (Perlin 2002).
    #[default]
    Perlin,
    /// OpenSimplex noise (a patent-free simplex-style noise).
    Simplex,
}

/// Octave-summed noise: Σₖ amplitude·persistenceᵏ · noise(frequency·lacunarityᵏ · p).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FractalNoise {
    /// Generator.
    pub kind: NoiseKind,
    /// Seed of the permutation table.
    pub seed: u32,
    /// Number of octaves (1 = plain noise).
    pub octaves: u32,
    /// Base frequency (cycles per unit of the input coordinates).
    pub frequency: f64,
    /// Amplitude of the first octave.
    pub amplitude: f64,
    /// Frequency ratio between octaves.
    pub lacunarity: f64,
    /// Amplitude ratio between octaves.
    pub persistence: f64,
}

impl Default for FractalNoise {
    fn default() -> Self {
        Self {
            kind: NoiseKind::Perlin,
            seed: 0,
            octaves: 1,
            frequency: 1.0,
            amplitude: 1.0,
            lacunarity: 2.0,
            persistence: 0.5,
        }
    }
}

impl FractalNoise {
    /// An upper bound of |sample|: the generators return values in [-1, 1].
    pub fn bound(&self) -> f64 {
        (0..self.octaves).map(|k| self.amplitude.abs() * self.persistence.abs().powi(k as i32)).sum()
    }

    /// Build the generator (its permutation table) once, for many samples.
    pub fn sampler(&self) -> NoiseSampler {
        let generator = match self.kind {
            NoiseKind::Perlin => Generator::Perlin(Perlin::new(self.seed)),
            NoiseKind::Simplex => Generator::Simplex(OpenSimplex::new(self.seed)),
        };
        NoiseSampler { params: *self, generator }
    }
}

#[derive(Clone, Debug)]
enum Generator {
    Perlin(Perlin),
    Simplex(OpenSimplex),
}

/// A ready-to-sample [`FractalNoise`].
#[derive(Clone, Debug)]
pub struct NoiseSampler {
    params: FractalNoise,
    generator: Generator,
}

impl NoiseSampler {
    /// The parameters this sampler was built from.
    pub fn params(&self) -> &FractalNoise {
        &self.params
    }

    /// An upper bound of |sample|.
    pub fn bound(&self) -> f64 {
        self.params.bound()
    }

    fn sum<const N: usize>(&self, p: [f64; N]) -> f64
    where
        Perlin: NoiseFn<f64, N>,
        OpenSimplex: NoiseFn<f64, N>,
    {
        let mut total = 0.0;
        let mut freq = self.params.frequency;
        let mut amp = self.params.amplitude;
        for _ in 0..self.params.octaves {
            let q = p.map(|c| c * freq);
            let v = match &self.generator {
                Generator::Perlin(g) => g.get(q),
                Generator::Simplex(g) => g.get(q),
            };
            total += amp * v.clamp(-1.0, 1.0);
            freq *= self.params.lacunarity;
            amp *= self.params.persistence;
        }
        total
    }

    /// Noise at a 3-D point (e.g. x, z, t).
    pub fn sample3(&self, x: f64, y: f64, z: f64) -> f64 {
        self.sum([x, y, z])
    }

    /// Noise at a 4-D point (e.g. x, y, z, t).
    pub fn sample4(&self, x: f64, y: f64, z: f64, w: f64) -> f64 {
        self.sum([x, y, z, w])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounded_deterministic_and_varied() {
        for kind in [NoiseKind::Perlin, NoiseKind::Simplex] {
            let n =
                FractalNoise { kind, seed: 11, octaves: 5, frequency: 1.3, ..Default::default() }.sampler();
            let mut min = f64::MAX;
            let mut max = f64::MIN;
            for i in 0..2000 {
                let t = i as f64 * 0.173;
                let a = n.sample3(t, t * 0.7 + 0.1, 0.31 * t);
                let b = n.sample4(t, 0.2, t * 0.5, 1.0 - t);
                assert!(a.abs() <= n.bound() && b.abs() <= n.bound());
                assert_eq!(a, n.sample3(t, t * 0.7 + 0.1, 0.31 * t));
                min = min.min(a);
                max = max.max(a);
            }
            // Gradient noise over 2000 samples spans well over half its range.
            assert!(max - min > 0.5, "{kind:?}: {min}..{max}");
        }
    }

    #[test]
    fn continuous_in_time() {
        let n = FractalNoise { octaves: 3, ..Default::default() }.sampler();
        let dt = 1e-4;
        for i in 0..200 {
            let t = i as f64 * 0.05;
            // Lipschitz: each octave's gradient is bounded (~2.5·freq for Perlin).
            let d = (n.sample3(0.4, 0.9, t + dt) - n.sample3(0.4, 0.9, t)).abs();
            assert!(d < 20.0 * dt, "jump {d} at t = {t}");
        }
    }

    #[test]
    fn seeds_differ() {
        let a = FractalNoise { seed: 1, ..Default::default() }.sampler();
        let b = FractalNoise { seed: 2, ..Default::default() }.sampler();
        let differs = (0..50).any(|i| {
            let x = i as f64 * 0.37 + 0.1;
            a.sample3(x, 0.5, 0.25) != b.sample3(x, 0.5, 0.25)
        });
        assert!(differs);
    }
}
