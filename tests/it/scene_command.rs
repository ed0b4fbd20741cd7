//! `citymesh scene`, the batch export: the Karlsruhe-Kirchfeld Overpass JSON and its SRTM file
//! into a GLB on disk, with the figures as JSON; and clear failures for bad input.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use common::{assert_valid_glb, data_dir, dem_dir};
use std::process::Command;

fn scene(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_citymesh"))
        .arg("scene")
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap()
}

#[test]
fn exports_the_whole_scene_and_its_figures() {
    let dir = tempfile::tempdir().unwrap();
    let osm = data_dir().join("osm/karlsruhe-kirchfeld.overpass.json");
    let (glb, stats) = (dir.path().join("k.glb"), dir.path().join("k.json"));
    let out = scene(&[
        "--osm",
        osm.to_str().unwrap(),
        "--dem-dir",
        dem_dir().to_str().unwrap(),
        "-o",
        glb.to_str().unwrap(),
        "--encoding",
        "meshopt",
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(&glb).unwrap();
    assert_valid_glb(&bytes);
    assert_valid_glb(&common::decode::decode_meshopt(&bytes));
    let figures: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
    // Every building and part of the file, whole (no box given).
    assert_eq!(figures["buildings"]["generated"], 3018);
    assert_eq!(figures["bytes"], bytes.len());
    assert_eq!(figures["encoding"], "meshopt");
    assert_eq!(figures["missing_dem"], serde_json::json!([]));
    assert!(String::from_utf8_lossy(&out.stderr).contains("3018 buildings"));

    // The same scene as the server's /scene for a box: buildings cut at the border.
    let boxed = dir.path().join("box.glb");
    let out = scene(&[
        "--osm",
        osm.to_str().unwrap(),
        "--dem-dir",
        dem_dir().to_str().unwrap(),
        "--bbox",
        "8.392,49.046,8.401,49.053",
        "-o",
        boxed.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_valid_glb(&std::fs::read(&boxed).unwrap());
}

#[test]
fn what_is_not_drawn_as_described_is_said_on_the_console_and_in_the_figures() {
    let dir = tempfile::tempdir().unwrap();
    // One house with a roof shape citymesh does not draw, where no SRTM file is given.
    let osm = dir.path().join("one.osm");
    std::fs::write(
        &osm,
        r#"<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6">
  <node id="1" lat="49.0100" lon="8.4000"/>
  <node id="2" lat="49.0100" lon="8.4003"/>
  <node id="3" lat="49.0102" lon="8.4003"/>
  <node id="4" lat="49.0102" lon="8.4000"/>
  <way id="7">
    <nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/>
    <tag k="building" v="church"/>
    <tag k="roof:shape" v="zakomar"/>
  </way>
</osm>"#,
    )
    .unwrap();
    let (glb, stats) = (dir.path().join("one.glb"), dir.path().join("one.json"));
    let empty = tempfile::tempdir().unwrap();
    let out = scene(&[
        "--osm",
        osm.to_str().unwrap(),
        "--dem-dir",
        empty.path().to_str().unwrap(),
        "-o",
        glb.to_str().unwrap(),
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let console = String::from_utf8_lossy(&out.stderr);
    assert!(
        console.contains("warning: SRTM files missing") && console.contains("N49E008"),
        "{console}"
    );
    assert!(
        console.contains(
            "1 buildings with a roof:shape citymesh does not draw (drawn flat): way/7 (zakomar)"
        ),
        "{console}"
    );
    let figures: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
    assert_eq!(
        figures["buildings"]["roof_shape_unsupported_ids"],
        serde_json::json!([{"id": "way/7", "shape": "zakomar"}])
    );
    assert_eq!(figures["missing_dem"], serde_json::json!(["N49E008"]));
}

#[test]
fn bad_input_fails_with_a_message_and_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let osm = data_dir().join("osm/karlsruhe-kirchfeld.overpass.json");
    let glb = dir.path().join("x.glb");
    for (args, says) in [
        (vec!["--osm", "/nonexistent.osm.pbf"], "nonexistent"),
        (
            vec!["--osm", osm.to_str().unwrap(), "--bbox", "8,49,7,50"],
            "--bbox",
        ),
    ] {
        let mut all = args.clone();
        all.extend(["-o", glb.to_str().unwrap()]);
        let out = scene(&all);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{err}");
        assert!(!glb.exists());
    }
}
