//! What a run may take and what it will take: the memory budget ([`Limits`]) and a
//! scene's estimate ([`Estimate`]), made before anything is built.

use serde::Serialize;

/// What running a scene will cost, estimated from its settings (and its files) before
/// anything is built. Memory counts the large buffers (particles, maps, images, splat
/// lists) at their peak, so it is a floor more than a ceiling; `work` says what one
/// frame does in the phenomenon's own terms.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Estimate {
    /// Memory held at the peak, bytes.
    pub memory_bytes: u64,
    /// The memory by part: (what, bytes).
    pub parts: Vec<(String, u64)>,
    /// The work of one frame.
    pub work: String,
    /// What cannot be checked before running, each a sentence.
    pub unchecked: Vec<String>,
}

impl Estimate {
    /// An estimate of `work` from memory parts (what, bytes).
    pub fn of(work: String, parts: Vec<(&str, f64)>) -> Self {
        let parts: Vec<(String, u64)> =
            parts.into_iter().map(|(what, bytes)| (what.to_string(), bytes.max(0.0).ceil() as u64)).collect();
        Self {
            memory_bytes: parts.iter().map(|p| p.1).fold(0, u64::saturating_add),
            parts,
            work,
            unchecked: Vec::new(),
        }
    }

    /// This estimate with `bytes` more for `what`.
    pub fn with(mut self, what: impl Into<String>, bytes: u64) -> Self {
        self.memory_bytes = self.memory_bytes.saturating_add(bytes);
        self.parts.push((what.into(), bytes));
        self
    }
}

/// Bytes as GiB, for messages.
pub fn gib(bytes: u64) -> String {
    format!("{:.2} GiB", bytes as f64 / f64::from(1u32 << 30))
}

/// How much a run may take. The CLI's default is three quarters of the machine's
/// memory; a library caller sets its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Most memory the scene's estimate may reach, bytes.
    pub memory_bytes: u64,
}

impl Limits {
    /// No limit.
    pub const NONE: Limits = Limits { memory_bytes: u64::MAX };
}

/// What checking a scene found: warnings and the estimate of its cost.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// Warnings, each a sentence.
    pub warnings: Vec<String>,
    /// Memory and work.
    pub estimate: Estimate,
}
