//! The shared core of phenomena: what two or more of the four phenomena use, nothing else.
//!
//! - [`color`]: CIE colour-matching functions, spectral lines, Planck's law, XYZ <-> sRGB.
//! - [`tonemap`]: exposure and tone mapping for display.
//! - [`kernel`]: normalised SPH kernels (poly6, spiky, cubic spline) in 2-D and 3-D.
//! - [`grid`]: uniform-grid neighbour search by counting sort.
//! - [`rng`]: random streams keyed by (seed, purpose, index), for thread-count independence.
//! - [`image`]: planar f32 frames, point deposit, separable Gaussian blur.
//! - [`bands`]: work filed by bands of image rows for deterministic parallel drawing.
//! - [`camera`]: look-at cameras: perspective, orthographic, fisheye, equirectangular.
//! - [`validate`]: configuration problems that name the field, the value and the valid range.
//! - [`phenomenon`]: the one API shape of every phenomenon ([`phenomenon::Simulation`],
//!   [`phenomenon::Renderer`]).
//! - [`clock`]: timings through a clock the caller injects (libraries read no clock).
//! - [`serde_vec`]: strict `[x, y, z]` parsing for configuration files.
//! - [`vdb`]: sparse float and vector grids encoded as OpenVDB `.vdb` files (bytes only).
//!
//! This crate does no file, terminal or network IO and reads no clock.
//!
//! ```
//! use phenomena_core::color::{blackbody_srgb_normalized, blackbody_xyz, xy_chromaticity, Observer};
//! // A 1900 K flame is orange: red is the largest component, blue the smallest.
//! let rgb = blackbody_srgb_normalized(1900.0);
//! assert!(rgb.x == 1.0 && rgb.y > rgb.z);
//! let (x, _y) = xy_chromaticity(blackbody_xyz(Observer::Cie1931TwoDegree, 1900.0)).unwrap();
//! assert!(x > 0.5);
//! ```
//!
//! # Feature flags
//! None yet.

pub mod bands;
pub mod camera;
pub mod clock;
mod cmf_data;
pub mod color;
pub mod grid;
pub mod image;
pub mod kernel;
pub mod lanes;
pub mod phenomenon;
pub mod rng;
pub mod serde_vec;
pub mod tonemap;
pub mod validate;
pub mod vdb;
