//! Glints of specular micro-particles, after Hwang and Noma, "Rendering of Particle
//! Systems for Specular Reflection Objects by Stochastic Model"
//! (確率モデルによるパーティクルシステムの描画法).
//!
//! Of N tiny mirror facets only those whose normal lies in the cone of half-angle
//! θ = arccos((I_e/(k_s I_l))^(1/n)) around the half vector H are seen (§2). The
//! stochastic model (`Method::Stochastic`, the paper's method and the default) creates
//! only those, deletes them when they leave the cone and draws newcomers so that the held
//! set has the statistics of the full system; `Method::BruteForce` simulates all N (the
//! paper's "conventional method", Table 1) and is the reference the tests compare with.
//!
//! - [`SparkleConfig`]: the Phong model, light, camera and population: diamond dust in a
//!   box of air (§3.1) or leaves on a hemispherical crown (§3.2).
//! - [`SparkleSim`]: frame 0 on `new`, then `step()`; [`SparkleSim::glints`] is the set seen.
//! - [`SparkleRenderer`]: glints (with optional cross/star glare) over a sky, the shaded
//!   crown or an image, as linear RGB.
//!
//! ```
//! use phenomena_sparkle::{Population, SparkleConfig, SparkleSim};
//! let mut config = SparkleConfig::default(); // 10⁹ crystals of diamond dust
//! let mut sim = SparkleSim::new(config, 7).unwrap();
//! let s = sim.step().unwrap();
//! // About (1 - cos θ)/2 = 3.0e-4 of them are seen: ~3·10⁵ held, not 10⁹.
//! assert_eq!(s.virtual_count, 1_000_000_000);
//! assert!((s.generated as f64 / 1e9 - 3.0e-4).abs() < 1e-5);
//! ```
//!
//! # Feature flags
//! None.

mod batch;
mod config;
mod model;
mod render;
mod sim;

pub use config::{
    Dust, Leaves, Light, LightAt, MAX_BRUTE_FORCE, MAX_CANDIDATES, MAX_EXPECTED_VISIBLE, MAX_VIRTUAL,
    MIN_CONE_DEG, Method, Normals, Phong, Population, SparkleConfig,
};
pub use phenomena_core::phenomenon::RenderError;
pub use render::{Background, DepthWindow, GlareShape, RenderSettings, SparkleRenderer};
pub use sim::{Everything, Glints, SparkleError, SparkleSim, SparkleState, StepStats};
