//! The preview's timeline: simulation states kept in memory so that scrubbing back,
//! looping and render-only changes do not simulate again from frame 0.
//!
//! States are checkpoints ([`Runner::checkpoint`]) taken every `every` frames simulated
//! (starting at [`FIRST_EVERY`]). When the states kept pass the memory budget, `every`
//! doubles and the states off the new spacing are dropped, so any span of frames stays
//! covered at an even spacing whatever the scene's size; frame 0's state (the first
//! step's) is kept while it fits at all.

use std::collections::BTreeMap;

use phenomena_scene::Runner;

/// States are first kept every this many frames simulated.
pub(crate) const FIRST_EVERY: u32 = 8;

/// The most memory a tab's timeline may hold, bytes, whatever the session's share.
pub(crate) const MAX_BUDGET_BYTES: usize = 512 << 20;

/// The states of one simulation (one scene identity and seed).
#[derive(Debug)]
pub(crate) struct Timeline {
    /// Spacing of the states kept, frames simulated.
    every: u32,
    /// Most bytes held.
    budget: usize,
    /// Checkpoint bytes by frames simulated.
    states: BTreeMap<u32, Vec<u8>>,
    bytes: usize,
}

impl Timeline {
    /// An empty timeline holding at most `budget` bytes.
    pub(crate) fn new(budget: usize) -> Self {
        Self { every: FIRST_EVERY, budget: budget.min(MAX_BUDGET_BYTES), states: BTreeMap::new(), bytes: 0 }
    }

    /// Forget every state (the simulation changed).
    pub(crate) fn clear(&mut self) {
        self.states.clear();
        self.bytes = 0;
        self.every = FIRST_EVERY;
    }

    /// Whether the state at `frames_done` would be kept.
    pub(crate) fn wants(&self, frames_done: u32) -> bool {
        (frames_done == 1 || frames_done.is_multiple_of(self.every))
            && !self.states.contains_key(&frames_done)
    }

    /// Keep the runner's state if it falls on the spacing (a checkpoint that cannot be
    /// written is simply not kept: the timeline is a cache).
    pub(crate) fn offer(&mut self, runner: &Runner) {
        let done = runner.frames_done();
        if runner.render_memory().is_some() || !self.wants(done) {
            return;
        }
        if let Ok(bytes) = runner.checkpoint() {
            self.insert(done, bytes);
        }
    }

    /// Keep `bytes` as the state at `frames_done`, then make room.
    pub(crate) fn insert(&mut self, frames_done: u32, bytes: Vec<u8>) {
        self.bytes += bytes.len();
        if let Some(old) = self.states.insert(frames_done, bytes) {
            self.bytes -= old.len();
        }
        while self.bytes > self.budget && !self.states.is_empty() {
            if self.every >= 1 << 20 {
                // Not even the sparsest spacing fits: keep nothing.
                self.states.clear();
                self.bytes = 0;
                return;
            }
            self.every *= 2;
            let every = self.every;
            self.states.retain(|&f, _| f == 1 || f.is_multiple_of(every));
            self.bytes = self.states.values().map(Vec::len).sum();
            if self.bytes > self.budget && self.states.len() == 1 {
                self.states.clear();
                self.bytes = 0;
            }
        }
    }

    /// The latest state at or before `frames_done`: (its frames simulated, its bytes).
    pub(crate) fn at_or_before(&self, frames_done: u32) -> Option<(u32, &[u8])> {
        self.states.range(..=frames_done).next_back().map(|(f, b)| (*f, b.as_slice()))
    }

    /// Frames simulated of the states kept (for the page's timeline).
    pub(crate) fn kept(&self) -> Vec<u32> {
        self.states.keys().copied().collect()
    }

    /// Bytes held.
    pub(crate) fn bytes(&self) -> usize {
        self.bytes
    }

    /// The spacing now.
    pub(crate) fn every(&self) -> u32 {
        self.every
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fill(t: &mut Timeline, frames: u32, size: usize) {
        for f in 1..=frames {
            if t.wants(f) {
                t.insert(f, vec![0; size]);
            }
        }
    }

    /// Within the budget the states are evenly spaced every 8 frames; over it the
    /// spacing doubles until they fit, and the nearest state is never after the frame
    /// asked for.
    #[test]
    fn states_stay_evenly_spaced_within_the_budget() {
        let mut t = Timeline::new(1000);
        fill(&mut t, 64, 10);
        assert_eq!(t.kept(), [1, 8, 16, 24, 32, 40, 48, 56, 64]);
        assert_eq!(t.at_or_before(30).map(|s| s.0), Some(24));
        assert_eq!(t.at_or_before(0), None);
        // 100-byte states: at most 10 fit.
        let mut t = Timeline::new(1000);
        fill(&mut t, 200, 100);
        assert!(t.bytes() <= 1000, "{}", t.bytes());
        let kept = t.kept();
        assert_eq!(kept[0], 1);
        let gaps: Vec<u32> = kept.windows(2).skip(1).map(|w| w[1] - w[0]).collect();
        assert!(gaps.iter().all(|&g| g == t.every()), "{kept:?} every {}", t.every());
        assert!(t.every() >= 32, "every {}", t.every());
        // A state bigger than the whole budget is not kept, and nothing breaks.
        let mut t = Timeline::new(50);
        fill(&mut t, 20, 100);
        assert_eq!(t.bytes(), 0);
        assert!(t.kept().is_empty());
    }

    #[test]
    fn a_cleared_timeline_starts_again() {
        let mut t = Timeline::new(10_000);
        fill(&mut t, 40, 10);
        assert_eq!((t.kept().len(), t.bytes()), (6, 60));
        t.clear();
        assert!(t.kept().is_empty() && t.bytes() == 0 && t.every() == FIRST_EVERY);
    }
}
