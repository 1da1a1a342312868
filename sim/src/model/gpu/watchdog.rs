//! The no-progress watchdog: when no ray completes and no memory request issues for
//! `sim.watchdog_cycles` cycles, the simulation stops with every component's state.

/// Tracks the last cycle with progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Watchdog {
    limit: u64,
    last_progress: u64,
}

impl Watchdog {
    /// A watchdog allowing `limit` cycles without progress, starting at cycle 0.
    pub fn new(limit: u64) -> Self {
        Watchdog {
            limit,
            last_progress: 0,
        }
    }

    /// Records progress (a ray completed or a request issued) in cycle `now`.
    pub fn progress(&mut self, now: u64) {
        self.last_progress = self.last_progress.max(now);
    }

    /// The first cycle at which the watchdog fires if nothing progresses before it.
    pub fn deadline(&self) -> u64 {
        self.last_progress
            .saturating_add(self.limit)
            .saturating_add(1)
    }

    /// Whether cycle `now` is past the allowed cycles without progress.
    pub fn expired(&self, now: u64) -> bool {
        now >= self.deadline()
    }

    /// The last cycle with progress.
    pub fn last_progress(&self) -> u64 {
        self.last_progress
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fires_only_after_limit_cycles_without_progress() {
        let mut w = Watchdog::new(100);
        assert!(!w.expired(100));
        assert!(w.expired(101));
        w.progress(50);
        assert!(!w.expired(150));
        assert!(w.expired(151));
        assert_eq!(w.deadline(), 151);
        // Progress never moves the watchdog backwards.
        w.progress(10);
        assert_eq!(w.last_progress(), 50);
    }
}
