//! Artist-controllable aurora, after Sekiguchi, "Artist-controllable aurora" (2018,
//! `shared/papers/aurora-artist-controllable-sekiguchi-2018.txt`).
//!
//! Part 1 (this crate so far): artist shapes and keyframes ([`shape`]), the electric
//! field from charges near the intermediate target shape, and the charged-particle motion.

pub mod field;
pub mod shape;
