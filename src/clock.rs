//! The one clock stores stamp their rows with (Unix milliseconds), injected where it is read so
//! that tests move time instead of sleeping past a timestamp: [`Clock::system`] in the server,
//! [`Clock::manual`] in a test, which then calls [`Clock::advance`].

use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};
use std::time::Duration;

/// Wall-clock time as the stores see it.
#[derive(Debug, Clone, Default)]
pub struct Clock {
    /// `None`: the system's clock; otherwise a time that moves only when told.
    manual: Option<Arc<AtomicI64>>,
}

impl Clock {
    /// The system's clock.
    pub fn system() -> Self {
        Self::default()
    }

    /// A clock standing at `start_ms` (Unix milliseconds) until it is advanced.
    pub fn manual(start_ms: i64) -> Self {
        Self {
            manual: Some(Arc::new(AtomicI64::new(start_ms))),
        }
    }

    /// A manual clock standing at the system's time now.
    pub fn manual_from_now() -> Self {
        Self::manual(Self::system().now_ms())
    }

    /// Unix milliseconds.
    pub fn now_ms(&self) -> i64 {
        match &self.manual {
            Some(at) => at.load(Ordering::SeqCst),
            None => std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX)),
        }
    }

    /// Unix seconds (whole, rounded down).
    pub fn now_secs(&self) -> i64 {
        self.now_ms().div_euclid(1000)
    }

    /// Moves a manual clock forward by `by`; the system's clock is not moved (answers false).
    pub fn advance(&self, by: Duration) -> bool {
        match &self.manual {
            Some(at) => {
                at.fetch_add(
                    i64::try_from(by.as_millis()).unwrap_or(i64::MAX),
                    Ordering::SeqCst,
                );
                true
            }
            None => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_manual_clock_moves_only_when_advanced_and_its_clones_with_it() {
        let clock = Clock::manual(1_700_000_000_999);
        let seen_by_a_store = clock.clone();
        assert_eq!(clock.now_secs(), 1_700_000_000);
        assert!(clock.advance(Duration::from_millis(1)));
        assert_eq!(seen_by_a_store.now_ms(), 1_700_000_001_000);
        assert_eq!(seen_by_a_store.now_secs(), 1_700_000_001);
        assert!(!Clock::system().advance(Duration::from_secs(1)));
        assert!(Clock::system().now_secs() > 1_700_000_000);
    }
}
