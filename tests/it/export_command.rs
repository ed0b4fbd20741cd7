//! `citymesh export` on real Karlsruhe data: a 3D Tiles tree killed with SIGKILL half way and run
//! again ends byte for byte the same as one written in a single run (on one worker and on
//! several), with every content tile of the tree; XYZ exports hold the tiles covering the box.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

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
    // An output that cannot be written (here `content` is a file, as a full disk or a read-only
    // mount would refuse): one line naming the file, never a backtrace, even when asked for.
    let blocked = tempfile::tempdir().unwrap();
    std::fs::write(blocked.path().join("content"), "in the way").unwrap();
    let out = export(blocked.path(), KIT_NORD, "karlsruhe-kit-nord.osm.pbf", &[])
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    let named = format!("writing {}", blocked.path().join("content").display());
    assert!(err.contains(&named), "{err}");
    assert!(
        !err.contains("backtrace") && !err.contains("Caused by"),
        "{err}"
    );
}

/// An S3 API (moto's server, from the test venv) on a free port of 127.0.0.1, killed on drop.
struct S3Server {
    child: std::process::Child,
    endpoint: String,
}

impl Drop for S3Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start_s3() -> S3Server {
    // The test venv: `CITYMESH_VENV` if set (as scripts/test takes it), else `.venv`.
    let venv = std::env::var_os("CITYMESH_VENV").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv"),
        std::path::PathBuf::from,
    );
    let moto = venv.join("bin/moto_server");
    assert!(
        moto.exists(),
        "{} is missing: scripts/test installs it (tests/requirements.txt)",
        moto.display()
    );
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let child = Command::new(&moto)
        .args(["-H", "127.0.0.1", "-p", &port.to_string()])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let server = S3Server {
        child,
        endpoint: format!("http://127.0.0.1:{port}"),
    };
    for _ in 0..300 {
        if std::net::TcpStream::connect(("127.0.0.1", port)).is_ok() {
            return server;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    panic!("moto_server did not listen on port {port}");
}

/// A bucket on the test's S3 server, and a client of it.
fn bucket(s3: &S3Server, name: &str) -> object_store::aws::AmazonS3 {
    use std::io::{Read, Write};
    // moto creates a bucket on an unsigned PUT.
    let mut c = std::net::TcpStream::connect(s3.endpoint.trim_start_matches("http://")).unwrap();
    write!(
        c,
        "PUT /{name} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut answer = String::new();
    c.read_to_string(&mut answer).unwrap();
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    object_store::aws::AmazonS3Builder::new()
        .with_endpoint(&s3.endpoint)
        .with_allow_http(true)
        .with_bucket_name(name)
        .with_region("us-east-1")
        .with_access_key_id("test")
        .with_secret_access_key("test")
        .build()
        .unwrap()
}

/// Every object under `prefix` with its bytes, by path relative to the prefix.
fn objects(store: &object_store::aws::AmazonS3, prefix: &str) -> BTreeMap<String, Vec<u8>> {
    use futures_util::TryStreamExt;
    use object_store::ObjectStore;
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let prefix = object_store::path::Path::from(prefix);
        let listed: Vec<_> = store.list(Some(&prefix)).try_collect().await.unwrap();
        let mut out = BTreeMap::new();
        for meta in listed {
            let bytes = store
                .get(&meta.location)
                .await
                .unwrap()
                .bytes()
                .await
                .unwrap();
            let rel = meta.location.as_ref()[prefix.as_ref().len() + 1..].to_owned();
            out.insert(rel, bytes.to_vec());
        }
        out
    })
}

#[test]
fn an_export_to_an_s3_store_equals_the_directory_export_and_resumes() {
    let s3 = start_s3();
    let store = bucket(&s3, "tiles");
    let bbox = "8.392,49.043,8.396,49.046";
    let with_s3 = |c: &mut Command| {
        c.env("AWS_ENDPOINT_URL", &s3.endpoint)
            .env("AWS_ALLOW_HTTP", "true")
            .env("AWS_REGION", "us-east-1")
            .env("AWS_ACCESS_KEY_ID", "test")
            .env("AWS_SECRET_ACCESS_KEY", "test");
    };
    let run = |out: &str| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_citymesh"));
        c.args(["export", "--bbox", bbox, "--out", out, "--osm"])
            .arg(data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf"))
            .arg("--dem-dir")
            .arg(dem_dir())
            .args(["--cache-db", ":memory:", "--log-level", "warn"]);
        with_s3(&mut c);
        let out = c.output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let dir = tempfile::tempdir().unwrap();
    let local = run(dir.path().to_str().unwrap());
    let remote = run("s3://tiles/karlsruhe/3d");
    let files = tree(dir.path());
    let n = files.len();
    assert!(
        local.contains(&format!("exported {n} files ({n} written now, 0 kept)")),
        "{local}"
    );
    assert!(
        remote.contains(&format!("exported {n} files ({n} written now, 0 kept)")),
        "{remote}"
    );
    // The same files, byte for byte, under the prefix.
    assert_eq!(objects(&store, "karlsruhe/3d"), files);
    // A rerun writes nothing; one with a tile and the tileset gone writes those two.
    let again = run("s3://tiles/karlsruhe/3d");
    assert!(
        again.contains(&format!("({} written now, {n} kept)", 0)),
        "{again}"
    );
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        use object_store::ObjectStore;
        for key in [
            "karlsruhe/3d/tileset.json",
            "karlsruhe/3d/content/0/0/0.glb",
        ] {
            store
                .delete(&object_store::path::Path::from(key))
                .await
                .unwrap();
        }
    });
    let resumed = run("s3://tiles/karlsruhe/3d");
    assert!(
        resumed.contains(&format!("(2 written now, {} kept)", n - 2)),
        "{resumed}"
    );
    assert_eq!(objects(&store, "karlsruhe/3d"), files);
    // A store that does not answer, or no bucket, says what to fix.
    let mut c = Command::new(env!("CARGO_BIN_EXE_citymesh"));
    c.args(["export", "--bbox", bbox, "--out", "s3://missing/x", "--osm"])
        .arg(data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf"))
        .args(["--cache-db", ":memory:", "--log-level", "warn"]);
    with_s3(&mut c);
    let out = c.output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--out s3://missing/x"), "{err}");
}

/// Karlsruhe-Kirchfeld's buildings.
const KIRCHFELD: &str = "8.3877,49.0390,8.4039,49.0640";

/// An export as a client reads it from disk: every tile the tileset lists has its content file,
/// and every vertex of every content tile, decoded, lies inside that tile's bounding region.
#[test]
fn every_vertex_of_a_kirchfeld_export_lies_inside_its_tiles_region() {
    let dir = tempfile::tempdir().unwrap();
    let out = export(dir.path(), KIRCHFELD, "karlsruhe-kirchfeld.osm.pbf", &[])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let files = tree(dir.path());
    let tileset: serde_json::Value = serde_json::from_slice(&files["tileset.json"]).unwrap();
    let mut stack = vec![&tileset["root"]];
    let (mut tiles, mut vertices, mut rows) = (0, 0, 0);
    while let Some(tile) = stack.pop() {
        stack.extend(tile["children"].as_array().into_iter().flatten());
        let Some(uri) = tile["content"]["uri"].as_str() else {
            continue;
        };
        let r: Vec<f64> = tile["boundingVolume"]["region"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let glb = files
            .get(uri)
            .unwrap_or_else(|| panic!("{uri} is listed but not exported"));
        tiles += 1;
        rows += common::decode::feature_rows(glb).len();
        vertices += common::decode::assert_inside_region(glb, &r, uri);
    }
    println!("{tiles} content tiles, {vertices} vertices, {rows} building rows");
    // Every file but the tileset is a listed tile's content.
    assert_eq!(tiles, files.len() - 1);
    assert!(vertices > 0 && rows > 0);
}
