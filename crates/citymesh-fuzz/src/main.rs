//! `citymesh-fuzz [SECONDS_PER_TARGET] [TARGET...]`: runs the fuzz targets (all by default) for
//! the given seconds each (default 10), seeded from `CITYMESH_FUZZ_SEED` (default: the clock),
//! with seed inputs from `CITYMESH_DATA_DIR` (default `../shared/data`). Prints executions per
//! target; exits 1 when any input panicked (it is saved under `crates/citymesh-fuzz/regressions/`).
#![allow(clippy::print_stdout)]

use citymesh_fuzz::{TARGETS, find, run};
use std::path::PathBuf;
use std::time::Duration;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seconds: f64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(10.0);
    let names: Vec<&str> = args.iter().skip(1).map(String::as_str).collect();
    let targets: Vec<_> = if names.is_empty() {
        TARGETS.to_vec()
    } else {
        names
            .iter()
            .map(|n| {
                find(n).unwrap_or_else(|| {
                    eprintln!(
                        "unknown target {n}; known: {}",
                        TARGETS.map(|t| t.name).join(", ")
                    );
                    std::process::exit(2)
                })
            })
            .collect()
    };
    let seed = std::env::var("CITYMESH_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(1, |d| d.as_secs())
        });
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let data = std::env::var_os("CITYMESH_DATA_DIR")
        .map_or_else(|| root.join("../../../shared/data"), PathBuf::from);
    let out = root.join("regressions");
    // Panics are expected and caught; keep their messages short.
    std::panic::set_hook(Box::new(|info| eprintln!("panic: {info}")));
    println!("seed {seed}, {seconds} s per target");
    let mut total = 0;
    let mut crashed = false;
    for (i, target) in targets.into_iter().enumerate() {
        let report = run(
            target,
            Duration::from_secs_f64(seconds),
            seed.wrapping_add(i as u64),
            &data,
            &out,
        );
        println!(
            "{:<10} {:>12} executions  {} crashes",
            report.target,
            report.executions,
            report.crashes.len()
        );
        for c in &report.crashes {
            println!("           saved {c}");
        }
        total += report.executions;
        crashed |= !report.crashes.is_empty();
    }
    println!("total      {total:>12} executions");
    if crashed {
        std::process::exit(1);
    }
}
