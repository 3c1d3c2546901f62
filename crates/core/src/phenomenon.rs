//! The one API shape every phenomenon library follows (after rapier): a plain-data
//! `XConfig`, `XSim::new(config, seed) -> Result<XSim, XError>` (the snow also takes its
//! scene mesh), [`Simulation::step`] once per frame, and an `XRenderer::new(settings,
//! width, height, background)` whose [`Renderer::render`] draws the simulation's current
//! state into a linear frame it keeps. Constructors refuse a bad configuration with the
//! one invalid-config error, [`crate::validate::InvalidConfig`], listing every problem.
//!
//! These traits let code above the phenomena (the scene layer's runner) drive any of
//! them the same way; each library also offers the same methods inherently.
//!
//! A simulation's [`Simulation::State`] is everything that is not rebuilt from its
//! configuration, seed (and mesh): particles, maps, frame counters. A simulation built
//! from the same inputs and given a saved state with [`Simulation::restore`] continues
//! bit for bit as the one it was saved from (the scene layer's checkpoints).

use crate::image::{Frame, Plane};
use crate::validate::InvalidConfig;

/// A simulation advanced one frame at a time.
pub trait Simulation: Send {
    /// What one step did (counters, and timings where a clock was given).
    type StepStats: serde::Serialize;
    /// Why a step failed.
    type Error: std::error::Error + Send + Sync + 'static;
    /// Everything needed to continue bit-identically, besides what the simulation is
    /// built from (configuration, seed, mesh).
    type State: serde::Serialize + serde::de::DeserializeOwned + Send;

    /// Advance one frame.
    fn step(&mut self) -> Result<Self::StepStats, Self::Error>;

    /// Frames stepped so far.
    fn frames_done(&self) -> u64;

    /// A copy of the current state.
    fn state(&self) -> Self::State;

    /// Continue from `state`, taken by [`Simulation::state`] of a simulation built from
    /// the same configuration and seed; refused (and `self` unchanged) when its shape
    /// does not fit this simulation.
    fn restore(&mut self, state: Self::State) -> Result<(), Self::Error>;
}

/// A named extra image of a render (an EXR layer), e.g. one emission line.
#[derive(Clone, Copy, Debug)]
pub struct Layer<'a> {
    /// Channel name, e.g. `aurora_557_7.Y`.
    pub name: &'a str,
    /// The image.
    pub plane: &'a Plane,
}

/// Draws a simulation's current state.
pub trait Renderer<S>: Send {
    /// Render `sim` now; the frame is linear (scene-referred) RGB and is kept until the
    /// next call.
    fn render(&mut self, sim: &S) -> &Frame;

    /// The frame of the last [`Renderer::render`] (black before the first).
    fn frame(&self) -> &Frame;

    /// Extra images of the last render, for EXR output (none by default).
    fn layers(&self) -> Vec<Layer<'_>> {
        Vec::new()
    }
}

/// Why a renderer cannot be built: the one error of every phenomenon's renderer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    /// Settings out of range; every problem listed.
    #[error(transparent)]
    Invalid(#[from] InvalidConfig),
    /// The camera cannot make an image of this size (empty, too large, or a degenerate
    /// camera).
    #[error(
        "cannot render a {width}x{height} image: each side must be in 1..=16384 and the camera not degenerate"
    )]
    Size {
        /// Width asked for, pixels.
        width: usize,
        /// Height asked for, pixels.
        height: usize,
    },
    /// The settings ask for an image background but none was given.
    #[error("the background is an image file but none was loaded")]
    MissingBackground,
}

/// Largest frame side a renderer accepts, pixels.
pub const MAX_SIDE_PX: usize = 16384;

/// `Ok` for a frame of `width × height` with each side in `1..=MAX_SIDE_PX`.
pub fn check_size(width: usize, height: usize) -> Result<(), RenderError> {
    if (1..=MAX_SIDE_PX).contains(&width) && (1..=MAX_SIDE_PX).contains(&height) {
        Ok(())
    } else {
        Err(RenderError::Size { width, height })
    }
}

/// The user's background image at the frame's size when the settings ask for one
/// (`wanted`): stretched by [`Frame::resized`], the rule of every phenomenon; `None`
/// when they do not.
pub fn image_background(
    wanted: bool,
    given: Option<&Frame>,
    width: usize,
    height: usize,
) -> Result<Option<Frame>, RenderError> {
    if !wanted {
        return Ok(None);
    }
    Ok(Some(given.ok_or(RenderError::MissingBackground)?.resized(width, height)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_backgrounds() {
        assert!(check_size(1, 16384).is_ok());
        assert_eq!(check_size(0, 5), Err(RenderError::Size { width: 0, height: 5 }));
        assert!(check_size(16385, 5).is_err());
        let img = Frame::new(4, 2);
        assert_eq!(image_background(false, Some(&img), 8, 4), Ok(None));
        assert_eq!(image_background(true, None, 8, 4), Err(RenderError::MissingBackground));
        let bg = image_background(true, Some(&img), 8, 4).unwrap().unwrap();
        assert_eq!((bg.width(), bg.height()), (8, 4));
    }
}
