//! Snow cover, after Tokoi and Moriki, "Real-time modeling of snow-covered shape"
//! (積雪形状のリアルタイムモデリング, 2006).
//!
//! [`mesh`] holds scene triangles and the built-in procedural shapes; [`groups`] makes
//! the polygon groups of §2.1 automatically; [`SnowSim`] builds one top-down snow map per
//! group (§2.1), computes the snow probability from depth maps of jittered snowfall
//! directions (§2.2), accumulates snow (§2.3, eq 1) and moves it to stable positions,
//! letting it fall onto lower maps (§2.4).
//!
//! Lengths are metres, y is up, snowfall rates cm/h of snow depth.
//!
//! ```
//! use phenomena_snow::{SnowConfig, SnowSim, mesh::table_scene};
//! let params = SnowConfig { map_resolution: 32, directions: 8, shadow_resolution: 64, ..SnowConfig::default() };
//! let mut sim = SnowSim::new(table_scene(4.0, 1.2, 0.7), params, 1).unwrap();
//! let stats = sim.step().unwrap();
//! assert!(stats.volume_m3 > 0.0 && stats.stable);
//! ```
//!
//! # Feature flags
//! - `dxf` (default): read DXF meshes ([`load::dxf`]). Off for `wasm32-unknown-unknown`,
//!   where the `dxf` crate's `uuid` dependency has no source of randomness.

pub mod export;
mod flood;
pub mod glitter;
pub mod groups;
pub mod load;
pub mod mesh;
pub mod raster;
pub mod reference;
pub mod render;
mod sim;

#[doc(hidden)]
pub use flood::Counts as FloodCounts;
pub use glitter::Glitter;
pub use phenomena_core::phenomenon::RenderError;
pub use render::{Background, Flakes, Seen, SnowRenderSettings, SnowRenderer, SnowTimings, SnowView};
pub use sim::{
    Footprint, SnowConfig, SnowError, SnowMap, SnowSim, SnowState, Stabiliser, StepStats, snowfall_directions,
};
