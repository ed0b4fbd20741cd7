//! The driver: for a time budget per target, feeds each target seeded mutations of its real seed
//! inputs (bit flips, byte changes, inserted and deleted runs, truncation, splices) and fresh
//! random bytes, catching panics. A failing input is written to the regressions folder.

use super::targets::Target;
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;
use std::time::{Duration, Instant};

/// What one target's run did.
#[derive(Debug, Clone)]
pub struct FuzzReport {
    pub target: &'static str,
    pub executions: u64,
    /// Files written for inputs that panicked.
    pub crashes: Vec<String>,
}

/// Longest seed prefix kept: whole real files are megabytes; their heads carry the structure.
const MAX_SEED_BYTES: usize = 64 * 1024;

fn mutate(rng: &mut ChaCha8Rng, input: &mut Vec<u8>, seeds: &[Vec<u8>]) {
    let rounds = rng.random_range(1..=8);
    for _ in 0..rounds {
        let len = input.len();
        match rng.random_range(0..7) {
            0 if len > 0 => {
                let i = rng.random_range(0..len);
                input[i] ^= 1 << rng.random_range(0..8);
            }
            1 if len > 0 => {
                let i = rng.random_range(0..len);
                input[i] = *b"0123456789-.,{}[]\":<>/ \x00\xff"
                    .get(rng.random_range(0..26))
                    .unwrap_or(&0);
            }
            2 => {
                let i = rng.random_range(0..=len);
                let n = rng.random_range(1..=16);
                let bytes: Vec<u8> = (0..n).map(|_| rng.random()).collect();
                input.splice(i..i, bytes);
            }
            3 if len > 1 => {
                let i = rng.random_range(0..len);
                let j = (i + rng.random_range(1..=64)).min(len);
                input.drain(i..j);
            }
            4 if len > 1 => input.truncate(rng.random_range(0..len)),
            5 if !seeds.is_empty() && len > 0 => {
                // Splice a piece of another seed in.
                let other = &seeds[rng.random_range(0..seeds.len())];
                if !other.is_empty() {
                    let a = rng.random_range(0..other.len());
                    let b = (a + rng.random_range(1..=256)).min(other.len());
                    let at = rng.random_range(0..len);
                    input.splice(at..at, other[a..b].iter().copied());
                }
            }
            _ => {
                // Repeat a run: deep nesting, long numbers.
                if len > 0 {
                    let a = rng.random_range(0..len);
                    let b = (a + rng.random_range(1..=8)).min(len);
                    let run = input[a..b].to_vec();
                    for _ in 0..rng.random_range(1..=32) {
                        input.splice(a..a, run.iter().copied());
                    }
                }
            }
        }
    }
}

/// Runs `target` for `budget`, seeded by `seed`; seed files are read from `data_dir`.
pub fn run(
    target: Target,
    budget: Duration,
    seed: u64,
    data_dir: &Path,
    out_dir: &Path,
) -> FuzzReport {
    let seeds: Vec<Vec<u8>> = target
        .seeds
        .iter()
        .filter_map(|name| std::fs::read(data_dir.join(name)).ok())
        .map(|mut bytes| {
            bytes.truncate(MAX_SEED_BYTES);
            bytes
        })
        .chain(target.inline.iter().map(|s| s.as_bytes().to_vec()))
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let started = Instant::now();
    let mut report = FuzzReport {
        target: target.name,
        executions: 0,
        crashes: Vec::new(),
    };
    let mut input = Vec::new();
    while started.elapsed() < budget {
        // A batch between clock reads.
        for _ in 0..64 {
            if !seeds.is_empty() && rng.random_ratio(3, 4) {
                input.clear();
                let s = &seeds[rng.random_range(0..seeds.len())];
                // Whole seeds rarely: mostly a prefix, which keeps executions fast.
                let cut = if rng.random_ratio(1, 16) {
                    s.len()
                } else {
                    rng.random_range(0..=s.len().min(4096))
                };
                input.extend_from_slice(&s[..cut]);
                mutate(&mut rng, &mut input, &seeds);
            } else {
                let n = rng.random_range(0..=512);
                input.resize(n, 0);
                rng.fill_bytes(&mut input);
            }
            report.executions += 1;
            let run = target.run;
            let bytes = &input;
            // A panic leaves nothing half-changed here: the input is only read.
            if std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(bytes))).is_err() {
                let name = format!(
                    "{}-{:03}.bin",
                    target.name,
                    existing(out_dir, target.name) + 1
                );
                let path = out_dir.join(&name);
                if std::fs::create_dir_all(out_dir).is_ok() && std::fs::write(&path, &input).is_ok()
                {
                    report.crashes.push(path.display().to_string());
                }
            }
        }
    }
    report
}

/// Regression files already kept for a target.
fn existing(dir: &Path, target: &str) -> usize {
    std::fs::read_dir(dir).map_or(0, |entries| {
        entries
            .filter_map(Result::ok)
            .filter(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with(&format!("{target}-"))
            })
            .count()
    })
}
