//! Time measurement for timing breakdowns, injected by the caller: the libraries read
//! no clock themselves (they also build for `wasm32-unknown-unknown`, where
//! `std::time::Instant` panics). A simulation given no clock reports 0 ms.
//!
//! ```
//! use phenomena_core::clock::SharedClock;
//! let clock = SharedClock::default(); // no clock: every timing reads 0
//! let t = clock.stopwatch();
//! assert_eq!(t.ms(), 0.0);
//! ```

use std::sync::Arc;

/// A monotonic clock.
pub trait Clock: Send + Sync {
    /// Milliseconds since an arbitrary fixed origin; never decreases.
    fn now_ms(&self) -> f64;
}

/// The clock of a caller that wants no timings: always 0.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoClock;

impl Clock for NoClock {
    fn now_ms(&self) -> f64 {
        0.0
    }
}

/// A clock as simulations and renderers hold it: cheap to clone, [`NoClock`] by
/// default.
#[derive(Clone)]
pub struct SharedClock(Arc<dyn Clock>);

impl SharedClock {
    /// Share `clock`.
    pub fn new(clock: impl Clock + 'static) -> Self {
        Self(Arc::new(clock))
    }

    /// Start timing now.
    pub fn stopwatch(&self) -> Stopwatch<'_> {
        Stopwatch::start(&*self.0)
    }
}

impl Default for SharedClock {
    fn default() -> Self {
        Self::new(NoClock)
    }
}

impl std::fmt::Debug for SharedClock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SharedClock")
    }
}

/// Time since a start, read from a clock.
pub struct Stopwatch<'a> {
    clock: &'a dyn Clock,
    start_ms: f64,
}

impl<'a> Stopwatch<'a> {
    /// Start now.
    pub fn start(clock: &'a dyn Clock) -> Self {
        Self { clock, start_ms: clock.now_ms() }
    }

    /// Milliseconds since the start.
    pub fn ms(&self) -> f64 {
        self.clock.now_ms() - self.start_ms
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU64, Ordering};

    /// A clock that advances 1.5 ms per reading.
    struct Ticks(AtomicU64);

    impl Clock for Ticks {
        fn now_ms(&self) -> f64 {
            self.0.fetch_add(1, Ordering::Relaxed) as f64 * 1.5
        }
    }

    #[test]
    fn a_stopwatch_reads_the_injected_clock() {
        let clock = Ticks(AtomicU64::new(0));
        let t = Stopwatch::start(&clock);
        assert_eq!(t.ms(), 1.5);
        assert_eq!(t.ms(), 3.0);
    }
}
