//! `citymesh export` on real Karlsruhe data: a 3D Tiles tree killed with SIGKILL half way and run
//! again ends byte for byte the same as one written in a single run (on one worker and on
//! several), with every content tile of the tree; XYZ exports hold the tiles covering the box.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

mod common;

use common::{data_dir, dem_dir};
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};

const KIT_NORD: &str = "8.367,49.020,8.446,49.119";

fn export(out: &Path, bbox: &str, osm: &str, extra: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_citymesh"));
    c.args(["export", "--bbox", bbox, "--out"])
        .arg(out)
        .args(["--osm"])
        .arg(data_dir().join("osm").join(osm))
        .args(["--dem-dir"])
        .arg(dem_dir())
        .args(["--cache-db", ":memory:", "--log-level", "warn"])
        .args(extra);
    c
}

/// Every file under `dir` with its bytes, by relative path.
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

#[test]
fn an_export_killed_half_way_and_run_again_is_byte_identical_to_one_run() {
    let dir = tempfile::tempdir().unwrap();
    let (whole, resumed) = (dir.path().join("whole"), dir.path().join("resumed"));
    let osm = "karlsruhe-kit-nord.osm.pbf";

    // One uninterrupted run, on all cores.
    let out = export(&whole, KIT_NORD, osm, &[]).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("exported 1366 files (1366 written now, 0 kept)"),
        "{stdout}"
    );
    let expected = tree(&whole);
    // 32 x 32 leaves of at most 400 m and the 341 coarser tiles above them, each with content,
    // plus the tileset (explicit: no subtree).
    assert_eq!(expected.len(), 1366);
    assert!(expected.contains_key("content/0/0/0.glb"));
    assert!(expected.contains_key("tileset.json"));
    assert!(!expected.contains_key("subtrees/0/0/0.subtree"));
    assert!(expected.contains_key("content/5/31/31.glb"));

    // On one worker, killed (SIGKILL) once half the files are written.
    let mut child = export(&resumed, KIT_NORD, osm, &["--workers", "1"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let lines = BufReader::new(child.stdout.take().unwrap()).lines();
    for line in lines {
        let line = line.unwrap();
        if line.contains("(50 %)") {
            break;
        }
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let partial = tree(&resumed);
    assert!(
        !partial.contains_key("tileset.json") && partial.len() < 1366 && partial.len() >= 683,
        "the kill came at {} files",
        partial.len()
    );

    // The same command again finishes the rest, keeping what is there.
    let out = export(&resumed, KIT_NORD, osm, &["--workers", "1"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let kept = partial.keys().filter(|k| !k.ends_with(".partial")).count();
    assert!(
        stdout.contains(&format!(
            "exported 1366 files ({} written now, {kept} kept)",
            1366 - kept
        )),
        "{stdout}"
    );
    let got = tree(&resumed);
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        expected.keys().collect::<Vec<_>>()
    );
    for (path, bytes) in &expected {
        assert!(got[path] == *bytes, "{path} differs");
    }
}

#[test]
fn xyz_export_writes_the_tiles_the_server_serves() {
    let dir = tempfile::tempdir().unwrap();
    let bbox = "8.392,49.043,8.396,49.046";
    let out = export(
        dir.path(),
        bbox,
        "karlsruhe-kirchfeld.osm.pbf",
        &["--format", "xyz", "--zooms", "16-17", "--quiet"],
    )
    .output()
    .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.stdout.is_empty(), "--quiet prints nothing");
    let files = tree(dir.path());
    let bbox_parsed: citymesh_core::geo::GeoBbox = bbox.parse().unwrap();
    let want: Vec<String> = (16..=17)
        .flat_map(|z| citymesh_core::geo::TileCoord::covering(&bbox_parsed, z).tiles())
        .map(|t| format!("{}/{}/{}.glb", t.z, t.x, t.y))
        .collect();
    let mut sorted = want.clone();
    sorted.sort();
    assert_eq!(files.keys().cloned().collect::<Vec<_>>(), sorted);
    // The PLAZA INN hotel's tile holds its row, as the served tile does.
    let t = citymesh_core::geo::TileCoord::containing(16, 8.39366, 49.04397);
    let glb = &files[&format!("16/{}/{}.glb", t.x, t.y)];
    common::assert_valid_glb(glb);
    let rows = common::decode::feature_rows(glb);
    assert!(rows.iter().any(|r| r["osm_id"] == "142104398"));
}

#[test]
fn an_implicit_export_carries_its_subtree_and_the_tileset_names_it() {
    let dir = tempfile::tempdir().unwrap();
    let bbox = "8.392,49.043,8.396,49.046";
    let out = export(
        dir.path(),
        bbox,
        "karlsruhe-kirchfeld.osm.pbf",
        &["--tiling", "implicit", "--quiet"],
    )
    .output()
    .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let files = tree(dir.path());
    let tileset: serde_json::Value = serde_json::from_slice(&files["tileset.json"]).unwrap();
    let implicit = &tileset["root"]["implicitTiling"];
    assert_eq!(
        implicit["subtrees"]["uri"],
        "subtrees/{level}/{x}/{y}.subtree"
    );
    assert_eq!(&files["subtrees/0/0/0.subtree"][..4], b"subt");
    // About 290 m x 330 m: one leaf level below the root, each tile with content.
    let levels = implicit["availableLevels"].as_u64().unwrap();
    let tiles: u64 = (0..levels).map(|l| 1 << (2 * l)).sum();
    assert_eq!(levels, 1);
    assert_eq!(files.len() as u64, tiles + 2);
    assert!(files.contains_key("content/0/0/0.glb"));
}

#[test]
fn a_wrong_export_says_what_to_fix() {
    let dir = tempfile::tempdir().unwrap();
    for (args, says) in [
        (
            vec!["--zooms", "18-16", "--format", "xyz"],
            "18 is above 16",
        ),
        (vec!["--format", "gltf"], "invalid value 'gltf'"),
    ] {
        let out = export(dir.path(), KIT_NORD, "karlsruhe-kit-nord.osm.pbf", &args)
            .output()
            .unwrap();
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{args:?}: {err}");
    }
    let out = export(dir.path(), "8,49,7,48", "karlsruhe-kit-nord.osm.pbf", &[])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--bbox"));
}
