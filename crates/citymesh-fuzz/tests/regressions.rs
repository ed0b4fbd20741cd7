//! Every input the fuzzer ever found failing (`regressions/<target>-NNN.bin`) runs through its
//! target again: each must now pass. The folder holds only inputs that once failed.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use citymesh_fuzz::find;
use std::path::PathBuf;

#[test]
fn every_saved_failure_now_passes() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("regressions");
    let mut checked = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let Some((target, _)) = name.rsplit_once('-') else {
            continue;
        };
        let Some(target) = find(target) else {
            continue;
        };
        let bytes = std::fs::read(&path).unwrap();
        (target.run)(&bytes);
        checked += 1;
    }
    // The count of kept regressions: changes only when a new failure is saved.
    assert_eq!(
        checked,
        std::fs::read_dir(&dir)
            .unwrap()
            .filter(|e| e
                .as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "bin"))
            .count()
    );
}
