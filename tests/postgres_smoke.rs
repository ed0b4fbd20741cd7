//! The PostgreSQL the tests start answers through sqlx's pure-Rust driver.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

mod common;

#[tokio::test]
async fn a_postgres_started_by_the_test_answers() {
    let pg = common::postgres::Postgres::start();
    let pool = sqlx::postgres::PgPoolOptions::new()
        .max_connections(2)
        .connect(&pg.url)
        .await
        .unwrap();
    let (n,): (i32,) = sqlx::query_as("SELECT 40 + 2")
        .fetch_one(&pool)
        .await
        .unwrap();
    assert_eq!(n, 42);
}
