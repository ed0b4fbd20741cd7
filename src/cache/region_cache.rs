//! The tile regions of 3D Tiles trees kept in memory by the tree's region: they are measured on
//! all the tree's content, which costs as much as generating it, so once per region. The
//! tileset and its subtree are made from them. Invalidated with the tiles (changed data changes
//! the content's extent).
//!
//! A measurement is work of its own, not of the request that started it: it runs in a task of
//! its own, requests for the same tree wait for that one measurement, and a request that gives
//! up (its client left, or `--request-timeout-s` passed) leaves it running, so that its result
//! is kept and the next request is answered from it instead of paying again. It stops (its
//! `stop` token is cancelled, which the measuring loop asks before each tile) when the server
//! shuts down, and after [`RegionCache::max_work`] at most, so abandoned work is bounded.

use citymesh_core::tiles3d::TileRegions;
use std::collections::HashMap;
use std::future::Future;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::watch;
use tokio_util::sync::CancellationToken;

/// At most this many trees (each 48 bytes per tile).
const MAX_TREES: u64 = 64;

/// A tree's key: its region (`minLon,minLat,maxLon,maxLat` text) and whether classified roofs
/// were allowed for.
pub type RegionKey = (String, bool);

/// How a measurement ended, shared by everyone who waits for it.
type Outcome<E> = Option<Result<Arc<TileRegions>, E>>;

/// Tile regions by tree, and the measurements under way.
pub struct RegionCache<E> {
    memory: moka::sync::Cache<RegionKey, Arc<TileRegions>>,
    running: Arc<Mutex<HashMap<RegionKey, watch::Receiver<Outcome<E>>>>>,
    /// Counts invalidations: a measurement that began before one is not kept.
    generation: Arc<AtomicU64>,
    /// Measurements started (for the metrics and the tests).
    started: AtomicU64,
}

impl<E> Default for RegionCache<E> {
    fn default() -> Self {
        Self {
            memory: moka::sync::Cache::builder().max_capacity(MAX_TREES).build(),
            running: Arc::default(),
            generation: Arc::default(),
            started: AtomicU64::new(0),
        }
    }
}

/// Why a measurement ended without regions, besides its own error.
pub enum Stopped {
    /// The server is shutting down.
    Shutdown,
    /// It ran longer than its bound.
    TooLong(Duration),
}

impl<E> RegionCache<E>
where
    E: Clone + Send + Sync + 'static,
{
    /// The regions of `key`: kept ones, else those of the measurement under way, else those of a
    /// new one `measure(stop)` makes in a task of its own. The measurement is stopped (`stop`
    /// cancelled) when `shutdown` is, or after `max_work`; `stopped` turns either into the
    /// caller's error. Dropping the returned future leaves the measurement running.
    pub async fn get_or_measure<M, F>(
        &self,
        key: RegionKey,
        measure: M,
        shutdown: &CancellationToken,
        max_work: Duration,
        stopped: fn(Stopped) -> E,
    ) -> Result<Arc<TileRegions>, E>
    where
        M: FnOnce(CancellationToken) -> F,
        F: Future<Output = Result<Arc<TileRegions>, E>> + Send + 'static,
    {
        if let Some(regions) = self.memory.get(&key) {
            return Ok(regions);
        }
        let mut outcome = self.join_or_start(key, measure, shutdown, max_work, stopped);
        let ended = outcome.wait_for(Option::is_some).await;
        match ended.as_deref() {
            Ok(Some(result)) => result.clone(),
            // The task ended without a word: only when it panicked.
            _ => Err(stopped(Stopped::Shutdown)),
        }
    }

    fn join_or_start<M, F>(
        &self,
        key: RegionKey,
        measure: M,
        shutdown: &CancellationToken,
        max_work: Duration,
        stopped: fn(Stopped) -> E,
    ) -> watch::Receiver<Outcome<E>>
    where
        M: FnOnce(CancellationToken) -> F,
        F: Future<Output = Result<Arc<TileRegions>, E>> + Send + 'static,
    {
        let mut running = self
            .running
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(rx) = running.get(&key) {
            return rx.clone();
        }
        // Measured between the check above and the lock: kept already.
        if let Some(regions) = self.memory.get(&key) {
            let (_, rx) = watch::channel(Some(Ok(regions)));
            return rx;
        }
        let (tx, rx) = watch::channel(None);
        running.insert(key.clone(), rx.clone());
        drop(running);
        self.started.fetch_add(1, Ordering::Relaxed);
        let stop = shutdown.child_token();
        let work = measure(stop.clone());
        let generation = self.generation.load(Ordering::Acquire);
        let (memory, all_running, generations) = (
            self.memory.clone(),
            self.running.clone(),
            self.generation.clone(),
        );
        tokio::spawn(async move {
            let result = tokio::select! {
                biased;
                () = stop.cancelled() => Err(stopped(Stopped::Shutdown)),
                () = tokio::time::sleep(max_work) => Err(stopped(Stopped::TooLong(max_work))),
                result = work => result,
            };
            // Whatever ended it, the measuring loop stops at its next tile.
            stop.cancel();
            let mut running = all_running
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            if let Ok(regions) = &result
                && generations.load(Ordering::Acquire) == generation
            {
                memory.insert(key.clone(), regions.clone());
            }
            running.remove(&key);
            drop(running);
            let _ = tx.send(Some(result));
        });
        rx
    }

    /// Measurements started since the server started.
    pub fn measurements_started(&self) -> u64 {
        self.started.load(Ordering::Relaxed)
    }

    /// Drops every tree's regions; measurements under way are not kept.
    pub fn invalidate_all(&self) {
        let running = self
            .running
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        self.generation.fetch_add(1, Ordering::AcqRel);
        self.memory.invalidate_all();
        drop(running);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use citymesh_core::geo::GeoBbox;
    use std::sync::atomic::AtomicUsize;

    type Cache = RegionCache<String>;

    fn stopped(why: Stopped) -> String {
        match why {
            Stopped::Shutdown => "shutdown".into(),
            Stopped::TooLong(d) => format!("too long {}", d.as_secs()),
        }
    }

    fn regions() -> Arc<TileRegions> {
        let root: GeoBbox = "8.40,49.01,8.41,49.02".parse().unwrap();
        Arc::new(TileRegions::new(&root, 0, &mut |_| None, (0.0, 0.0)))
    }

    const LONG: Duration = Duration::from_secs(3600);

    fn key() -> RegionKey {
        ("8.4,49.0,8.5,49.1".into(), false)
    }

    #[tokio::test]
    async fn a_request_that_gives_up_leaves_the_measurement_to_finish_and_be_kept() {
        let cache = Cache::default();
        let shutdown = CancellationToken::new();
        let (release, released) = tokio::sync::oneshot::channel::<()>();
        let calls = Arc::new(AtomicUsize::new(0));
        let measure = |calls: Arc<AtomicUsize>| {
            move |_stop: CancellationToken| async move {
                calls.fetch_add(1, Ordering::SeqCst);
                let _ = released.await;
                Ok(regions())
            }
        };
        // The first request gives up before the measurement ends.
        let first = cache.get_or_measure(key(), measure(calls.clone()), &shutdown, LONG, stopped);
        assert!(tokio::time::timeout(Duration::ZERO, first).await.is_err());
        // The second waits for the same measurement; it ends once.
        let second = cache.get_or_measure(
            key(),
            |_| async { Err("a second measurement".to_owned()) },
            &shutdown,
            LONG,
            stopped,
        );
        release.send(()).unwrap();
        assert!(second.await.is_ok());
        // The third is answered from memory.
        let third = cache
            .get_or_measure(
                key(),
                |_| async { Err("a third measurement".to_owned()) },
                &shutdown,
                LONG,
                stopped,
            )
            .await;
        assert!(third.is_ok());
        assert_eq!(calls.load(Ordering::SeqCst), 1);
        assert_eq!(cache.measurements_started(), 1);
    }

    #[tokio::test]
    async fn shutdown_stops_a_measurement_and_tells_its_work() {
        let cache = Cache::default();
        let shutdown = CancellationToken::new();
        let (seen_tx, seen_rx) = tokio::sync::oneshot::channel::<bool>();
        let waiting = cache.get_or_measure(
            key(),
            |stop: CancellationToken| {
                // Work under way that only ends when told to stop, as the measuring loop does
                // (the future waiting for it is dropped when the measurement stops).
                let blocking = tokio::task::spawn_blocking(move || {
                    while !stop.is_cancelled() {
                        std::thread::yield_now();
                    }
                    let _ = seen_tx.send(true);
                });
                async move {
                    let _ = blocking.await;
                    Err("never".to_owned())
                }
            },
            &shutdown,
            LONG,
            stopped,
        );
        let (result, ()) = tokio::join!(waiting, async { shutdown.cancel() });
        assert_eq!(result.unwrap_err(), "shutdown");
        assert!(seen_rx.await.unwrap(), "the work never saw the stop");
        // Nothing was kept: the next request measures again.
        assert!(
            cache
                .get_or_measure(
                    key(),
                    |_| async { Ok(regions()) },
                    &CancellationToken::new(),
                    LONG,
                    stopped
                )
                .await
                .is_ok()
        );
        assert_eq!(cache.measurements_started(), 2);
    }

    #[tokio::test(start_paused = true)]
    async fn a_measurement_stops_at_its_bound() {
        let cache = Cache::default();
        let result = cache
            .get_or_measure(
                key(),
                |stop: CancellationToken| async move {
                    stop.cancelled().await;
                    Err("never".to_owned())
                },
                &CancellationToken::new(),
                Duration::from_secs(30),
                stopped,
            )
            .await;
        assert_eq!(result.unwrap_err(), "too long 30");
    }

    #[tokio::test]
    async fn a_measurement_begun_before_an_invalidation_is_not_kept() {
        let cache = Cache::default();
        let shutdown = CancellationToken::new();
        let (release, released) = tokio::sync::oneshot::channel::<()>();
        let first = cache.get_or_measure(
            key(),
            |_| async move {
                let _ = released.await;
                Ok(regions())
            },
            &shutdown,
            LONG,
            stopped,
        );
        let (result, ()) = tokio::join!(first, async {
            cache.invalidate_all();
            release.send(()).unwrap();
        });
        assert!(result.is_ok());
        let again = cache
            .get_or_measure(key(), |_| async { Ok(regions()) }, &shutdown, LONG, stopped)
            .await;
        assert!(again.is_ok());
        assert_eq!(cache.measurements_started(), 2);
    }
}
