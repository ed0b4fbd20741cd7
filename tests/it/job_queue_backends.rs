//! The roof job queue and the adaptations on SQLite and on PostgreSQL (work in progress, issue
//! 27): each scenario is written once over [`JobQueue`] and run on both backends; on
//! PostgreSQL, the claims of two replicas' pools never take a job twice.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use citymesh::clock::Clock;
use citymesh::db::Database;
use citymesh::roofs::classifier::Prediction;
use citymesh::roofs::jobs::adapt::{AdaptFailure, AdaptationStore, Lease};
use citymesh::roofs::jobs::{JobQueue, MAX_ATTEMPTS, NewJob};
use common::postgres::Postgres;
use std::collections::{BTreeMap, HashSet};
use std::time::Duration;

fn job(id: i64) -> NewJob {
    let x = id as f64 * 1e-3;
    NewJob {
        osm_id: format!("way/{id}"),
        footprint: vec![[8.4 + x, 49.0], [8.4001 + x, 49.0], [8.4001 + x, 49.0001]],
    }
}

fn p() -> Prediction {
    Prediction::new([0.2, 0.7, 0.1])
}

/// A queue on an SQLite database in memory, its leases stamped by `clock`.
async fn sqlite_queue(clock: &Clock) -> JobQueue {
    JobQueue::new(&Database::Sqlite(
        citymesh::db::open(":memory:").await.unwrap(),
    ))
    .with_clock(clock.clone())
}

/// A PostgreSQL started for the test (stopped when the first is dropped) and a queue on it.
async fn pg_queue(clock: &Clock) -> (Postgres, JobQueue) {
    let pg = Postgres::start();
    let pool = citymesh::db::open_postgres(&pg.url, 4).await.unwrap();
    (
        pg,
        JobQueue::new(&Database::Postgres(pool)).with_clock(clock.clone()),
    )
}

async fn a_building_is_queued_once_per_inputs(q: JobQueue, _clock: Clock) {
    let jobs = [job(1), job(2), job(3)];
    let (_, first) = q
        .enqueue("b", "img", "m", &jobs, BTreeMap::new())
        .await
        .unwrap();
    assert_eq!((first.queued, first.already), (3, 0));
    let (_, again) = q
        .enqueue("b", "img", "m", &jobs, BTreeMap::new())
        .await
        .unwrap();
    assert_eq!((again.queued, again.already), (0, 3));
    // Another model or a changed footprint is new work.
    let (_, other) = q
        .enqueue("b", "img", "m2", &jobs[..1], BTreeMap::new())
        .await
        .unwrap();
    assert_eq!(other.queued, 1);
    let mut moved = job(1);
    moved.footprint[0][0] += 1e-5;
    let (_, changed) = q
        .enqueue("b", "img", "m", &[moved], BTreeMap::new())
        .await
        .unwrap();
    assert_eq!(changed.queued, 1);
}

async fn a_lease_that_runs_out_gives_the_job_to_the_next_claim_and_it_completes_once(
    q: JobQueue,
    clock: Clock,
) {
    let (batch, _) = q
        .enqueue("b", "img", "m", &[job(1), job(2)], BTreeMap::new())
        .await
        .unwrap();
    // A worker takes both and dies: a 1 ms lease.
    let dead = q.claim(10, Duration::from_millis(1)).await.unwrap();
    assert_eq!(dead.len(), 2);
    // Once the lease has run out, the next claim takes the same jobs again.
    clock.advance(Duration::from_millis(20));
    let taken = q.claim(10, Duration::from_secs(60)).await.unwrap();
    assert_eq!(
        taken.iter().map(|j| j.id).collect::<Vec<_>>(),
        dead.iter().map(|j| j.id).collect::<Vec<_>>()
    );
    assert!(taken.iter().all(|j| j.attempts == 2));
    assert!(
        q.claim(10, Duration::from_secs(60))
            .await
            .unwrap()
            .is_empty()
    );
    for j in &taken {
        assert!(q.complete(j, p(), 1.0).await.unwrap());
    }
    // The dead worker comes back and tries to complete or fail: refused, nothing stored twice
    // and the new claim's job untouched.
    assert!(!q.complete(&dead[0], p(), 1.0).await.unwrap());
    assert!(!q.fail(&dead[1], "stale", false).await.unwrap());
    assert!(!q.complete(&taken[0], p(), 1.0).await.unwrap());
    let all = q
        .predictions(&"8.3,48.9,8.5,49.1".parse().unwrap(), 100)
        .await
        .unwrap();
    assert_eq!(all.len(), 2);
    let progress = q.progress(&batch).await.unwrap().unwrap();
    assert_eq!(progress.jobs["done"], 2);
    assert!(progress.finished);
}

async fn an_extended_lease_keeps_the_job_from_other_claims(q: JobQueue, clock: Clock) {
    q.enqueue("b", "img", "m", &[job(1)], BTreeMap::new())
        .await
        .unwrap();
    let held = q.claim(10, Duration::from_millis(1)).await.unwrap();
    assert_eq!(
        q.extend(held[0].claim, Duration::from_secs(60))
            .await
            .unwrap(),
        1
    );
    clock.advance(Duration::from_millis(20));
    // The first lease would have run out; the extended one holds.
    assert!(
        q.claim(10, Duration::from_secs(60))
            .await
            .unwrap()
            .is_empty()
    );
    assert!(q.complete(&held[0], p(), 1.0).await.unwrap());
    assert_eq!(
        q.extend(held[0].claim, Duration::from_secs(60))
            .await
            .unwrap(),
        0
    );
}

async fn failures_retry_up_to_the_limit_and_cancel_stops_queued_jobs(q: JobQueue, _clock: Clock) {
    let (batch, _) = q
        .enqueue("b", "img", "m", &[job(1), job(2)], BTreeMap::new())
        .await
        .unwrap();
    for attempt in 1..=MAX_ATTEMPTS {
        let jobs = q.claim(1, Duration::from_secs(60)).await.unwrap();
        assert_eq!(jobs[0].attempts, attempt);
        q.fail(&jobs[0], "no_imagery: busy", true).await.unwrap();
    }
    let progress = q.progress(&batch).await.unwrap().unwrap();
    assert_eq!((progress.jobs["failed"], progress.jobs["queued"]), (1, 1));
    assert_eq!(q.cancel(&batch).await.unwrap(), Some(1));
    let progress = q.progress(&batch).await.unwrap().unwrap();
    assert_eq!(progress.jobs["cancelled"], 1);
    assert!(progress.finished && progress.cancelled);
    assert_eq!(q.cancel(&"0".repeat(32)).await.unwrap(), None);
    assert!(q.progress(&"0".repeat(32)).await.unwrap().is_none());
}

/// One test per backend for each scenario: `sqlite::NAME` and `postgres::NAME`.
macro_rules! on_both_backends {
    ($($scenario:ident),* $(,)?) => {
        mod sqlite {
            $(
                #[tokio::test]
                async fn $scenario() {
                    let clock = super::Clock::manual_from_now();
                    super::$scenario(super::sqlite_queue(&clock).await, clock).await;
                }
            )*
        }
        mod postgres {
            $(
                #[tokio::test]
                async fn $scenario() {
                    let clock = super::Clock::manual_from_now();
                    let (_pg, queue) = super::pg_queue(&clock).await;
                    super::$scenario(queue, clock).await;
                }
            )*
        }
    };
}

on_both_backends!(
    a_building_is_queued_once_per_inputs,
    a_lease_that_runs_out_gives_the_job_to_the_next_claim_and_it_completes_once,
    an_extended_lease_keeps_the_job_from_other_claims,
    failures_retry_up_to_the_limit_and_cancel_stops_queued_jobs,
);

/// Claims until one comes back empty, completing each job; answers the ids claimed.
async fn claim_until_empty(q: JobQueue) -> Vec<i64> {
    let mut ids = Vec::new();
    loop {
        let jobs = q.claim(5, Duration::from_secs(60)).await.unwrap();
        if jobs.is_empty() {
            return ids;
        }
        for j in &jobs {
            assert!(q.complete(j, p(), 1.0).await.unwrap(), "job {} lost", j.id);
            ids.push(j.id);
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn two_replicas_claiming_at_once_never_take_a_job_twice() {
    let pg = Postgres::start();
    let open = || citymesh::db::open_postgres(&pg.url, 5);
    let replicas = [
        JobQueue::new(&Database::Postgres(open().await.unwrap())),
        JobQueue::new(&Database::Postgres(open().await.unwrap())),
    ];
    let jobs: Vec<NewJob> = (1..=200).map(job).collect();
    let (_, counts) = replicas[0]
        .enqueue("b", "img", "m", &jobs, BTreeMap::new())
        .await
        .unwrap();
    assert_eq!(counts.queued, 200);
    // Four claim loops per replica, all at once.
    let loops: Vec<_> = replicas
        .iter()
        .enumerate()
        .flat_map(|(replica, q)| {
            (0..4).map(move |_| {
                let q = q.clone();
                tokio::spawn(async move { (replica, claim_until_empty(q).await) })
            })
        })
        .collect();
    let mut claimed = Vec::new();
    let mut by_replica = [0usize; 2];
    for handle in loops {
        let (replica, ids) = handle.await.unwrap();
        by_replica[replica] += ids.len();
        claimed.extend(ids);
    }
    let distinct: HashSet<i64> = claimed.iter().copied().collect();
    assert_eq!(claimed.len(), 200, "claimed {claimed:?}");
    assert_eq!(distinct.len(), 200, "a job was claimed twice: {claimed:?}");
    assert!(
        by_replica.iter().all(|&n| n > 0),
        "one replica claimed nothing: {by_replica:?}"
    );
    assert_eq!(
        replicas[1].predictions_of("img", "m").await.unwrap().len(),
        200
    );
    let states = replicas[1].states().await.unwrap();
    assert_eq!(states["done"], 200, "{states:?}");
    assert_eq!(states["queued"] + states["running"], 0, "{states:?}");
}

/// An adaptation made, ended too early, one refused while another runs, one left running with
/// a lease that ran out, one cancelled: what the store answers along the way.
async fn adaptations(store: AdaptationStore) -> Vec<serde_json::Value> {
    let live = Lease {
        owner: "replica-1".into(),
        duration: Duration::from_secs(3600),
    };
    let dead = Lease {
        owner: "replica-2".into(),
        duration: Duration::ZERO,
    };
    let area = "8.4,49.0,8.5,49.1";
    let mut seen = Vec::new();
    let [id, other, third, fourth] = ["a", "b", "c", "d"].map(|c| c.repeat(32));
    assert_eq!(store.running("img").await.unwrap(), None);
    store
        .create(&id, area, "img", "m", [30, 25, 5], &live)
        .await
        .unwrap();
    assert_eq!(store.running("img").await.unwrap(), Some(id.clone()));
    assert_eq!(store.running("other").await.unwrap(), None);
    // While it runs, another start for the same imagery is refused (one statement: the check
    // and the insert) with the running one's id; another imagery's starts.
    assert_eq!(
        store
            .start(&other, area, "img", "m", [0; 3], &live)
            .await
            .unwrap(),
        Some(id.clone())
    );
    assert!(store.get(&other).await.unwrap().is_none());
    let running = store.get(&id).await.unwrap().unwrap();
    assert_eq!((running.state.as_str(), running.percent), ("running", 0.0));
    seen.push(serde_json::to_value(running).unwrap());
    let why = "fewer than 20 hipped examples";
    let too_few = Err(AdaptFailure::TooFew(why.into()));
    assert!(store.record(&id, &too_few, false).await.unwrap());
    // An ended adaptation takes no second outcome.
    assert!(!store.record(&id, &too_few, false).await.unwrap());
    let ended = store.get(&id).await.unwrap().unwrap();
    assert_eq!(ended.state, "too_few");
    assert_eq!(ended.error.as_deref(), Some(why));
    assert!(ended.head_id.is_none() && ended.report.is_none());
    seen.push(serde_json::to_value(ended).unwrap());
    assert_eq!(store.running("img").await.unwrap(), None);
    // One left running by a process that died: its lease ran out, so the next start fails it
    // and starts.
    store
        .create(&other, area, "img", "m", [40, 40, 40], &dead)
        .await
        .unwrap();
    assert_eq!(
        store
            .start(&third, area, "img", "m", [0; 3], &live)
            .await
            .unwrap(),
        None
    );
    let lost = store.get(&other).await.unwrap().unwrap();
    assert_eq!(lost.state, "failed");
    seen.push(serde_json::to_value(lost).unwrap());
    // Only the owner extends a lease, and only while it runs.
    assert!(!store.extend(&other, &dead).await.unwrap());
    assert!(!store.extend(&third, &dead).await.unwrap());
    assert!(store.extend(&third, &live).await.unwrap());
    // Cancelled while running: its lease is lost, its outcome not taken.
    assert_eq!(
        store.cancel(&third).await.unwrap().as_deref(),
        Some("running")
    );
    assert!(!store.extend(&third, &live).await.unwrap());
    assert!(!store.record(&third, &too_few, false).await.unwrap());
    let cancelled = store.get(&third).await.unwrap().unwrap();
    assert_eq!(cancelled.state, "cancelled");
    seen.push(serde_json::to_value(cancelled).unwrap());
    // An ended one is left as it is.
    assert_eq!(store.cancel(&id).await.unwrap().as_deref(), Some("too_few"));
    assert_eq!(store.cancel(&fourth).await.unwrap(), None);
    // A restart fails what was left running with a lease that ran out, on either database.
    store
        .create(&fourth, area, "img", "m", [40, 40, 40], &dead)
        .await
        .unwrap();
    assert_eq!(store.interrupt_running().await.unwrap(), 1);
    assert_eq!(store.interrupt_running().await.unwrap(), 0);
    assert_eq!(store.get(&fourth).await.unwrap().unwrap().state, "failed");
    assert_eq!(store.running("img").await.unwrap(), None);
    assert!(store.newest_head("img", "m").await.unwrap().is_none());
    assert!(store.get(&"e".repeat(32)).await.unwrap().is_none());
    seen
}

#[tokio::test]
async fn sqlite_and_postgres_keep_adaptations_alike() {
    let sqlite = citymesh::db::open(":memory:").await.unwrap();
    let sqlite = adaptations(AdaptationStore::new(Database::Sqlite(sqlite))).await;
    let pg = Postgres::start();
    let pool = citymesh::db::open_postgres(&pg.url, 4).await.unwrap();
    let postgres = adaptations(AdaptationStore::new(Database::Postgres(pool.clone()))).await;
    assert_eq!(sqlite, postgres);
    // On PostgreSQL, shared by replicas, a restart leaves a live replica's adaptation running
    // (its lease holds); on SQLite (one process per file) a restart fails whatever ran.
    let live = Lease {
        owner: "replica-1".into(),
        duration: Duration::from_secs(3600),
    };
    let store = AdaptationStore::new(Database::Postgres(pool));
    let id = "f".repeat(32);
    store
        .create(&id, "8.4,49.0,8.5,49.1", "img2", "m", [40, 40, 40], &live)
        .await
        .unwrap();
    assert_eq!(store.interrupt_running().await.unwrap(), 0);
    assert_eq!(store.running("img2").await.unwrap(), Some(id.clone()));
    let sqlite = AdaptationStore::new(Database::Sqlite(
        citymesh::db::open(":memory:").await.unwrap(),
    ));
    sqlite
        .create(&id, "8.4,49.0,8.5,49.1", "img2", "m", [40, 40, 40], &live)
        .await
        .unwrap();
    assert_eq!(sqlite.interrupt_running().await.unwrap(), 1);
}
