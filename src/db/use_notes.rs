//! Uses of stored rows noted in memory, so a read never writes: the store writes them later, in
//! one transaction off the request path, before it evicts the least recently used rows.

use std::collections::HashMap;
use std::hash::Hash;
use std::sync::Mutex;

/// Keys read since their uses were last written, with when (ms since the epoch).
pub struct UseNotes<K> {
    notes: Mutex<HashMap<K, i64>>,
    /// Notes kept before [`UseNotes::note`] asks for a write.
    max: usize,
}

impl<K: Eq + Hash> UseNotes<K> {
    pub fn new(max: usize) -> Self {
        Self {
            notes: Mutex::new(HashMap::new()),
            max,
        }
    }

    /// Notes a use of `key` at `at_ms`; `true` when the notes are full and should be written.
    pub fn note(&self, key: K, at_ms: i64) -> bool {
        let Ok(mut notes) = self.notes.lock() else {
            return false;
        };
        notes.insert(key, at_ms);
        notes.len() >= self.max
    }

    /// The notes so far, leaving none.
    pub fn take(&self) -> HashMap<K, i64> {
        self.notes
            .lock()
            .map(|mut n| std::mem::take(&mut *n))
            .unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_latest_use_of_a_key_is_kept_and_a_full_set_asks_for_a_write() {
        let notes = UseNotes::new(2);
        assert!(!notes.note("a", 1));
        assert!(!notes.note("a", 5));
        assert!(notes.note("b", 3));
        let taken = notes.take();
        assert_eq!((taken["a"], taken["b"]), (5, 3));
        assert!(notes.take().is_empty());
    }
}
