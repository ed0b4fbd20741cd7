//! Fuzz targets for citymesh on stable Rust (cargo-fuzz needs nightly): each target takes bytes
//! and must return without panicking, whatever the bytes are. The driver ([`run`], used by the
//! `citymesh-fuzz` binary and `scripts/fuzz`) feeds them seeded mutations of real inputs and
//! fresh random bytes; a failing input is saved under `crates/citymesh-fuzz/regressions/`, where
//! `tests/regressions.rs` replays every one of them on each test run.

mod building;
mod driver;
mod http;
mod import;
mod targets;

pub use building::decode_building;
pub use driver::{FuzzReport, run};
pub use targets::{TARGETS, Target, find};
