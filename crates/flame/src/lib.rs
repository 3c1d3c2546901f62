//! Real-time flame from particle-based fluid simulation, after Inagaki, Imura, Ikeda,
//! Manabe and Chihara, "Real-time Rendering of Flame Using Particle-based Fluid
//! Simulation" (粒子ベース流体シミュレーションを用いた炎のリアルタイムレンダリング).
//!
//! - [`FlameSim`] (module `sim`): the SPH gas of §4: poly6 density (eq 2-3), pressure
//!   p = k(ρ - ρ0) (eq 11), the symmetrised pressure force (eq 12), a = f/ρ (eq 8), wind
//!   as the external force, and the per-frame loop of §4.3.
//! - [`FlameRenderer`] (module `render`): blackbody colour through CIE XYZ (§5.1, eq
//!   13-17), poly6 splats with additive blending and alpha from density (§5.2), heat
//!   shimmer from accumulated kernel gradients distorting the background (§5.3).
//! - [`volume`]: the SPH fields (density, temperature, emission) sampled on a voxel
//!   grid for OpenVDB files.
//!
//! `Mode::Paper` follows the paper literally (constant temperature per particle);
//! `Mode::Extended`, the default, cools particles with age so the tips redden and adds
//! buoyancy. The paper is silent on how particles leave: here each has a lifetime (the
//! fuel burning out) and particles leaving the domain box are removed.
//!
//! ```
//! use phenomena_flame::{FlameConfig, FlameRenderer, FlameSim, RenderSettings};
//! let mut sim = FlameSim::new(FlameConfig::default(), 1).unwrap();
//! for _ in 0..20 {
//!     sim.step().unwrap();
//! }
//! let mut renderer = FlameRenderer::new(RenderSettings::default(), 64, 36, None).unwrap();
//! let background = renderer.background().clone();
//! let frame = renderer.render(&sim);
//! // The flame is brighter than the background it is drawn over.
//! let (w, h) = (frame.width(), frame.height());
//! let brightest = (0..w * h).map(|i| frame.pixel(i % w, i / w).max_element()).fold(0.0, f32::max);
//! assert!(brightest > background.pixel(0, 0).max_element());
//! ```
//!
//! # Feature flags
//! None yet.

pub mod air;
mod config;
pub mod motion;
pub mod obstacles;
mod render;
mod sim;
pub mod volume;

pub use config::{
    Domain, Emitter, Extended, FlameConfig, MAX_EMITTED_PER_FRAME, Mode, SphParams, Wind, WindKey,
};
pub use phenomena_core::phenomenon::RenderError;
pub use render::{
    BAND_ROWS, Background, BlackbodyLut, Brightness, FlameRenderer, RenderSettings, Shimmer, View,
};
pub use sim::{FlameError, FlameSim, FlameState, MAX_NEIGHBORS, Particles, StepStats};
