//! Why a scene could not be built ([`BuildError`]), a run stopped ([`RunError`]) or a
//! sink could not take a frame ([`SinkError`]).

use phenomena_core::phenomenon::RenderError;
use phenomena_core::validate::{InvalidConfig, Issue};

use crate::assets::AssetError;
use crate::budget::{Estimate, Limits, gib};

/// Why a scene's simulation or renderer could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The scene is not valid (a scene changed after it was read, say).
    #[error("the scene is not valid: {}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))]
    Invalid(Vec<Issue>),
    /// A file could not be read.
    #[error(transparent)]
    Asset(#[from] AssetError),
    /// A file was read but cannot be used (a mesh that does not parse, say).
    #[error("{key}: {message}")]
    Unusable {
        /// The scene key that names the file.
        key: String,
        /// What is wrong with it.
        message: String,
    },
    /// The simulation or renderer refused the scene.
    #[error("{0}")]
    Refused(String),
    /// The scene would need more memory than the budget allows.
    #[error(
        "the scene needs about {} of memory ({}), more than the budget of {}",
        gib(.estimate.memory_bytes),
        .estimate.work,
        gib(*.limit_bytes)
    )]
    OverBudget {
        /// What it would need.
        estimate: Box<Estimate>,
        /// The budget, bytes.
        limit_bytes: u64,
    },
}

impl BuildError {
    /// The scene key the problem is at, if it is at one.
    pub fn key(&self) -> Option<&str> {
        match self {
            BuildError::Asset(e) => Some(&e.key),
            BuildError::Unusable { key, .. } => Some(key),
            BuildError::Invalid(issues) => issues.first().map(|i| i.field.as_str()),
            BuildError::Refused(_) | BuildError::OverBudget { .. } => None,
        }
    }

    /// A simulation's or renderer's refusal.
    pub fn refused(e: impl std::fmt::Display) -> Self {
        BuildError::Refused(e.to_string())
    }

    /// A constructor's invalid configuration, its fields put under `table` (the key the
    /// configuration sits at in the scene file, e.g. `sparkle` or `render.sky`).
    pub fn invalid(table: &str, config: InvalidConfig) -> Self {
        BuildError::Invalid(config.prefixed(table).issues)
    }

    /// A renderer's refusal: its invalid settings under `table`, anything else as is.
    pub fn render(table: &str, e: RenderError) -> Self {
        match e {
            RenderError::Invalid(c) => Self::invalid(table, c),
            other => Self::refused(other),
        }
    }
}

impl Estimate {
    /// This estimate if it is within `limits`, else the refusal.
    pub fn within(self, limits: &Limits) -> Result<Self, BuildError> {
        if self.memory_bytes > limits.memory_bytes {
            return Err(BuildError::OverBudget {
                estimate: Box::new(self),
                limit_bytes: limits.memory_bytes,
            });
        }
        Ok(self)
    }
}

/// Why a run stopped early.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The simulation failed.
    #[error("the simulation failed at frame {frame}: {message}")]
    Step {
        /// The frame being made.
        frame: u32,
        /// Why.
        message: String,
    },
    /// The sink could not take a frame.
    #[error("frame {frame}: {error}")]
    Sink {
        /// The frame.
        frame: u32,
        /// Why (in the message: not also a `source`, which would print it twice).
        error: SinkError,
    },
    /// The observer asked to stop.
    #[error("stopped after {frames} frame(s)")]
    Cancelled {
        /// Frames finished.
        frames: u32,
    },
    /// The frames asked for start before the simulation's current frame.
    #[error("frame {asked} is already past: the simulation is at frame {at}")]
    Past {
        /// The first frame asked for.
        asked: u32,
        /// Frames already simulated.
        at: u32,
    },
}

/// Why a sink could not take a frame.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct SinkError(pub String);
