//! Artist-controllable aurora, after Sekiguchi, "A study of artist-controllable aurora
//! simulation" (アーティスト制御可能なオーロラシミュレーションに関する研究, master's
//! thesis, University of Tsukuba, 2018).
//!
//! Part 1: artist shapes and keyframes ([`shape`], §2.2.1-2.2.2; edited through
//! [`editor`], §3.1), the electric field of
//! charges near the intermediate target shape ([`field`], §2.2.3), the charged-particle
//! motion ([`motion`], §2.3) and the simulation that ties them together ([`AuroraSim`],
//! with the redistribution of §2.3.4); [`plane`] draws the x-z plane from above.
//!
//! Part 2: the sky view ([`sky`], §2.4): the thesis's stepped fall and emission
//! ([`fall`], `paper` mode) or the physical column model ([`deposition`] over the
//! NRLMSIS [`atmosphere`], default), the five lines and their quenching ([`emission`]),
//! per-line splats, XYZ and sRGB; ground, orbit, dome-master and panorama cameras.
//!
//! Lengths are km in the x-z plane; y (up) is the magnetic field's direction.

pub mod atmosphere;
pub mod chemistry;
mod config;
pub mod degradation;
pub mod deposition;
pub mod editor;
pub mod emission;
pub mod fall;
pub mod field;
pub mod motion;
pub mod night;
pub mod noise;
pub mod pairs;
pub mod plane;
mod render;
pub mod shape;
mod sim;
pub mod sky;
pub mod small_scale;
pub mod transport;
pub mod volume;

pub use config::{
    AuroraConfig, CoulombKernels, FieldParams, MotionParams, Plane, Redistribution, RedistributionRule,
    ShapeParams,
};
pub use plane::PlaneView;
pub use render::{AuroraRenderer, AuroraView, LINE_LAYERS, RenderError, RenderSettings};
pub use sim::{AuroraError, AuroraSim, AuroraState, FieldInputs, FieldState, StepStats};
pub use sky::{ColourMode, SkyBackground, SkyCamera, SkyRenderer, SkySettings, SkyTimings};
