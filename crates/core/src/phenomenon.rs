//! The one API shape every phenomenon library follows (after rapier): a plain-data
//! `XConfig`, `XSim::new(config, seed) -> Result<XSim, XError>` (the snow also takes its
//! scene mesh), [`Simulation::step`] once per frame, and an `XRenderer::new(settings,
//! width, height, background)` whose [`Renderer::render`] draws the simulation's current
//! state into a linear frame it keeps. Constructors refuse a bad configuration with the
//! one invalid-config error, [`crate::validate::InvalidConfig`], listing every problem.
//!
//! These traits let code above the phenomena (the scene layer's runner) drive any of
//! them the same way; each library also offers the same methods inherently.

use crate::image::{Frame, Plane};

/// A simulation advanced one frame at a time.
pub trait Simulation: Send {
    /// What one step did (counters, and timings where a clock was given).
    type StepStats: serde::Serialize;
    /// Why a step failed.
    type Error: std::error::Error + Send + Sync + 'static;

    /// Advance one frame.
    fn step(&mut self) -> Result<Self::StepStats, Self::Error>;

    /// Frames stepped so far.
    fn frames_done(&self) -> u64;
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
