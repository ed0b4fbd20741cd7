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
fn a_wrong_export_says_what_to_fix() {
    let dir = tempfile::tempdir().unwrap();
    for (args, says) in [
        (
            vec!["--zooms", "18-16", "--format", "xyz"],
            "18 is above 16",
        ),
        (vec!["--format", "gltf"], "invalid value 'gltf'"),
        (
            vec!["--tiling", "implicit"],
            "/3dtiles/tileset.json?bbox=...&tiling=implicit",
        ),
        (
            vec!["--lease-s", "0"],
            "--lease-s must be 1 to 86400 seconds",
        ),
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
    // An output that cannot be written (here `world` is a file, as a read-only mount would
    // refuse): one line naming the file, never a backtrace, even when asked for.
    let blocked = tempfile::tempdir().unwrap();
    std::fs::write(blocked.path().join("world"), "in the way").unwrap();
    let out = export(blocked.path(), KIT_NORD, "karlsruhe-kit-nord.osm.pbf", &[])
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    let named = format!("writing {}", blocked.path().join("world").display());
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
    /// Its working folder, where its request recorder writes.
    _dir: tempfile::TempDir,
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
    let dir = tempfile::tempdir().unwrap();
    let child = Command::new(&moto)
        .args(["-H", "127.0.0.1", "-p", &port.to_string()])
        .current_dir(dir.path())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let server = S3Server {
        child,
        endpoint: format!("http://127.0.0.1:{port}"),
        _dir: dir,
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
        local.contains(&format!("({n} written now, 0 kept")),
        "{local}"
    );
    assert!(
        remote.contains(&format!("({n} written now, 0 kept")),
        "{remote}"
    );
    // The same files, byte for byte, under the prefix.
    assert_eq!(objects(&store, "karlsruhe/3d"), files);
    // A rerun writes nothing; one with a tile and the tileset gone writes those two.
    let again = run("s3://tiles/karlsruhe/3d");
    assert!(
        again.contains(&format!("(0 written now, {n} kept")),
        "{again}"
    );
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let leaf = files.keys().find(|k| k.starts_with("world/15/")).unwrap();
    rt.block_on(async {
        use object_store::ObjectStore;
        for key in [
            "karlsruhe/3d/tileset.json".to_owned(),
            format!("karlsruhe/3d/{leaf}"),
        ] {
            store
                .delete(&object_store::path::Path::from(key))
                .await
                .unwrap();
        }
    });
    let resumed = run("s3://tiles/karlsruhe/3d");
    assert!(
        resumed.contains(&format!("(2 written now, {} kept", n - 2)),
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
    let (mut tiles, mut vertices, mut rows, mut tilesets) = (0, 0, 0, 0);
    let mut files_to_read = vec!["tileset.json".to_owned()];
    while let Some(file) = files_to_read.pop() {
        tilesets += 1;
        let tileset: serde_json::Value = serde_json::from_slice(&files[&file]).unwrap();
        let mut stack = vec![tileset["root"].clone()];
        while let Some(tile) = stack.pop() {
            stack.extend(tile["children"].as_array().into_iter().flatten().cloned());
            let Some(uri) = tile["content"]["uri"].as_str() else {
                continue;
            };
            let path = resolve(&file, uri);
            if path.ends_with(".json") {
                files_to_read.push(path);
                continue;
            }
            let r: Vec<f64> = tile["boundingVolume"]["region"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let glb = files
                .get(&path)
                .unwrap_or_else(|| panic!("{path} is listed but not exported"));
            tiles += 1;
            rows += common::decode::feature_rows(glb).len();
            vertices += common::decode::assert_inside_region(glb, &r, &path);
        }
    }
    println!("{tiles} content tiles, {vertices} vertices, {rows} building rows");
    // Every file is a tileset file reached from the root or a listed tile's content.
    assert_eq!(tiles + tilesets, files.len());
    assert!(vertices > 0 && rows > 0);
}

/// The way from tileset file `base` to `uri` (relative, with `..`).
fn resolve(base: &str, uri: &str) -> String {
    // A file's name is its path: `?v=` names the version of its data, not another file.
    let uri = uri.split('?').next().unwrap_or(uri);
    let mut parts: Vec<&str> = base.split('/').collect();
    parts.pop();
    for p in uri.split('/') {
        match p {
            ".." => {
                parts.pop();
            }
            p => parts.push(p),
        }
    }
    parts.join("/")
}

/// `citymesh export` of everything `osm` holds, its units kept in `state` (a SQLite file).
fn export_all(out: &str, osm: &str, state: &Path, extra: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_citymesh"));
    c.args(["export", "--out", out, "--osm"])
        .arg(data_dir().join("osm").join(osm))
        .arg("--dem-dir")
        .arg(dem_dir())
        .arg("--cache-db")
        .arg(state)
        .args(["--log-level", "warn"])
        .args(extra);
    c
}

/// Runs `c` to its end, which must be a success; answers its `--report` (written to `report`).
fn run_reported(c: &mut Command, report: &Path) -> serde_json::Value {
    let out = c.arg("--report").arg(report).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&std::fs::read(report).unwrap()).unwrap()
}

/// The units of the export state in `state` (a SQLite file) that a run holds.
fn running_units(state: &Path) -> u64 {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let pool = citymesh::db::open(state.to_str().unwrap()).await.unwrap();
        let (n,): (i64,) =
            sqlx::query_as("SELECT COUNT(*) FROM export_units WHERE state = 'running'")
                .fetch_one(&pool)
                .await
                .unwrap();
        pool.close().await;
        u64::try_from(n).unwrap()
    })
}

fn glb_count(files: &BTreeMap<String, Vec<u8>>) -> u64 {
    files.keys().filter(|k| k.ends_with(".glb")).count() as u64
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_whole_export_is_the_world_tileset_the_server_serves_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tree");
    let report = run_reported(
        &mut export_all(
            out.to_str().unwrap(),
            "karlsruhe-kirchfeld.osm.pbf",
            &dir.path().join("state.sqlite"),
            &["--quiet"],
        ),
        &dir.path().join("report.json"),
    );
    let files = tree(&out);
    // Kirchfeld's 4 data tiles: 16 leaves, blocks at zooms 14 (4), 13 (2), 12, 11, 10 and 9
    // (1 each), and the tileset files of zooms 12, 9, 6 and 3 below the root.
    assert_eq!(files.len(), 31);
    assert_eq!(glb_count(&files), 26);
    assert_eq!(report["files"], 31);
    assert_eq!(report["written"], 31);
    // Every scene once: one per content file, nothing generated to measure the tree.
    assert_eq!(report["generated"], 26);
    assert_eq!(report["units"], 5);

    // The server over the same file answers every path with the same bytes, and its tree
    // names no file the export lacks.
    let db = tempfile::tempdir().unwrap();
    let state = common::kirchfeld_state(&db).await;
    let app = common::app_of(state.clone());
    common::world_ready(&state).await;
    let mut listed = std::collections::BTreeSet::new();
    let mut to_read = vec!["tileset.json".to_owned()];
    while let Some(file) = to_read.pop() {
        listed.insert(file.clone());
        let served: serde_json::Value = common::get(&app, &format!("/3dtiles/{file}")).await.json();
        let mut stack = vec![served["root"].clone()];
        while let Some(tile) = stack.pop() {
            stack.extend(tile["children"].as_array().into_iter().flatten().cloned());
            if let Some(uri) = tile["content"]["uri"].as_str() {
                let path = resolve(&file, uri);
                if path.ends_with(".json") {
                    to_read.push(path.clone());
                }
                listed.insert(path);
            }
        }
    }
    assert_eq!(
        listed.iter().collect::<Vec<_>>(),
        files.keys().collect::<Vec<_>>()
    );
    for (path, bytes) in &files {
        let served = common::get(&app, &format!("/3dtiles/{path}")).await;
        assert_eq!(served.status, 200, "{path}");
        assert!(
            served.body == *bytes,
            "{path} differs from what the server serves"
        );
    }
    // Only the root file says what the tree holds.
    let root: serde_json::Value = serde_json::from_slice(&files["tileset.json"]).unwrap();
    assert_eq!(root["asset"]["extras"]["citymesh"]["dataTiles"], 4);
    let below: serde_json::Value =
        serde_json::from_slice(&files["world/12/2143/1405.json"]).unwrap();
    assert!(below["asset"].get("extras").is_none());
}

#[test]
fn an_export_killed_half_way_and_run_again_is_byte_identical_and_generates_each_scene_once() {
    let dir = tempfile::tempdir().unwrap();
    let osm = "karlsruhe-kit-nord.osm.pbf";
    let (whole, resumed) = (dir.path().join("whole"), dir.path().join("resumed"));

    // One uninterrupted run, on all cores.
    let report = run_reported(
        &mut export_all(
            whole.to_str().unwrap(),
            osm,
            &dir.path().join("whole.sqlite"),
            &["--quiet"],
        ),
        &dir.path().join("whole.json"),
    );
    let expected = tree(&whole);
    let (files, glbs) = (expected.len() as u64, glb_count(&expected));
    assert_eq!(report["files"], files);
    assert_eq!(report["written"], files);
    assert_eq!(report["generated"], glbs);
    assert!(expected.contains_key("tileset.json"));

    // On one worker, killed (SIGKILL) once half the files are done.
    let state = dir.path().join("resumed.sqlite");
    let mut child = export_all(resumed.to_str().unwrap(), osm, &state, &["--workers", "1"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // The pipe stays open until the kill (a closed one would end the lines).
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    for line in lines.by_ref() {
        let line = line.unwrap();
        let percent: Option<u64> = line
            .split(" (")
            .nth(1)
            .and_then(|r| r.split(" %").next())
            .and_then(|p| p.parse().ok());
        if percent.is_some_and(|p| p >= 50) {
            break;
        }
    }
    // The line comes as a unit is done, before the next is claimed: the kill waits for the
    // next claim, so that the killed run dies holding a unit (counted again after the kill, as
    // the unit may end between the look and the kill).
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    while running_units(&state) == 0 && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    drop(lines);
    let held = running_units(&state);
    let partial = tree(&resumed);
    assert!(
        !partial.contains_key("tileset.json") && (partial.len() as u64) < files,
        "the kill came at {} of {files} files",
        partial.len()
    );
    assert!(
        !partial.keys().any(|k| k.ends_with(".partial")) || partial.len() > 1,
        "a temporary file at most"
    );
    let kept = partial.keys().filter(|k| !k.ends_with(".partial")).count() as u64;
    let kept_glbs = partial.keys().filter(|k| k.ends_with(".glb")).count() as u64;

    // The same command again finishes the rest: it takes the killed run's units once their
    // lease ends, keeps every file there, and generates exactly the scenes missing.
    let report = run_reported(
        &mut export_all(
            resumed.to_str().unwrap(),
            osm,
            &state,
            &["--workers", "1", "--lease-s", "1", "--quiet"],
        ),
        &dir.path().join("resumed.json"),
    );
    // Units done are not opened again; the killed run's unfinished units keep their files.
    assert!(report["kept"].as_u64().unwrap() < kept, "{report}");
    assert_eq!(report["written"], files - kept);
    assert_eq!(report["generated"], glbs - kept_glbs);
    assert_eq!(report["taken_over"], held, "{report}");
    let got = tree(&resumed);
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        expected.keys().collect::<Vec<_>>()
    );
    for (path, bytes) in &expected {
        assert!(got[path] == *bytes, "{path} differs");
    }
    // Run again when finished: nothing is generated or written.
    let again = run_reported(
        &mut export_all(resumed.to_str().unwrap(), osm, &state, &["--quiet"]),
        &dir.path().join("again.json"),
    );
    assert_eq!(again["generated"], 0);
    assert_eq!(again["written"], 0);
    assert_eq!(again["units"], 0);
}

/// A tmpfs mounted on a folder of its own, unmounted on drop.
struct SmallDisk {
    dir: tempfile::TempDir,
}

impl SmallDisk {
    fn mount(bytes: u64) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let ok = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={bytes}"), "tmpfs"])
            .arg(dir.path())
            .status()
            .unwrap()
            .success();
        assert!(
            ok,
            "cannot mount a tmpfs (the tests run as root, as scripts/test does)"
        );
        Self { dir }
    }

    fn grow(&self, bytes: u64) {
        let ok = Command::new("mount")
            .args(["-o", &format!("remount,size={bytes}")])
            .arg(self.dir.path())
            .status()
            .unwrap()
            .success();
        assert!(ok);
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(self.dir.path()).status();
    }
}

#[test]
fn a_full_disk_stops_the_export_naming_the_file_and_a_rerun_finishes_it() {
    let dir = tempfile::tempdir().unwrap();
    let osm = "karlsruhe-kirchfeld.osm.pbf";
    let whole = dir.path().join("whole");
    run_reported(
        &mut export_all(
            whole.to_str().unwrap(),
            osm,
            &dir.path().join("whole.sqlite"),
            &["--quiet"],
        ),
        &dir.path().join("whole.json"),
    );
    let expected = tree(&whole);
    // The tree takes 1.7 MB; the disk holds 1 MB.
    let disk = SmallDisk::mount(1 << 20);
    let out = disk.dir.path().join("tree");
    let state = dir.path().join("state.sqlite");
    let failed = export_all(out.to_str().unwrap(), osm, &state, &["--quiet"])
        .output()
        .unwrap();
    assert!(!failed.status.success());
    let err = String::from_utf8_lossy(&failed.stderr);
    assert!(err.contains(&format!("--out {}", out.display())), "{err}");
    assert!(err.contains("No space left on device"), "{err}");
    let partial = tree(&out);
    assert!(!partial.contains_key("tileset.json"));
    assert!(
        !partial.keys().any(|k| k.ends_with(".partial")),
        "nothing half written stays"
    );
    for (path, bytes) in &partial {
        assert!(expected[path] == *bytes, "{path} is not whole");
    }
    // Space freed: the same command finishes, at once (the failed run gave its units back).
    disk.grow(16 << 20);
    let report = run_reported(
        &mut export_all(out.to_str().unwrap(), osm, &state, &["--quiet"]),
        &dir.path().join("rerun.json"),
    );
    assert_eq!(report["kept"], partial.len() as u64);
    assert_eq!(tree(&out), expected);
}

/// What the test's S3 server was asked since recording started: (method, path) of each request.
fn recorded(s3: &S3Server) -> Vec<(String, String)> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let text = rt.block_on(async {
        reqwest::get(format!(
            "{}/moto-api/recorder/download-recording",
            s3.endpoint
        ))
        .await
        .unwrap()
        .text()
        .await
        .unwrap()
    });
    // One JSON object per request, not always a line each.
    serde_json::Deserializer::from_str(&text)
        .into_iter::<serde_json::Value>()
        .map(|v| {
            let v = v.unwrap();
            let url = v["url"].as_str().unwrap();
            let path = url.split_once("://").map_or(url, |(_, r)| r);
            let path = &path[path.find('/').unwrap_or(0)..];
            let path = path.split('?').next().unwrap().to_owned();
            (v["method"].as_str().unwrap().to_owned(), path)
        })
        .collect()
}

#[test]
fn two_exporters_on_one_postgres_share_an_s3_export_and_one_killed_is_taken_over() {
    let osm = "karlsruhe-kit-nord.osm.pbf";
    let dir = tempfile::tempdir().unwrap();
    // The same export by one process, to a directory.
    let single = dir.path().join("single");
    run_reported(
        &mut export_all(
            single.to_str().unwrap(),
            osm,
            &dir.path().join("single.sqlite"),
            &["--quiet"],
        ),
        &dir.path().join("single.json"),
    );
    let expected = tree(&single);

    let pg = common::postgres::Postgres::start();
    let s3 = start_s3();
    let store = bucket(&s3, "tiles");
    let start = reqwest_post(&format!(
        "{}/moto-api/recorder/start-recording",
        s3.endpoint
    ));
    assert!(start.contains("True"), "{start}");
    let worker = |quiet: bool| {
        let mut c = export_all(
            "s3://tiles/world",
            osm,
            &dir.path().join("unused.sqlite"),
            &[
                "--database-url",
                &pg.url,
                "--workers",
                "1",
                "--lease-s",
                "2",
            ],
        );
        if quiet {
            c.arg("--quiet");
        }
        c.env("AWS_ENDPOINT_URL", &s3.endpoint)
            .env("AWS_ALLOW_HTTP", "true")
            .env("AWS_REGION", "us-east-1")
            .env("AWS_ACCESS_KEY_ID", "test")
            .env("AWS_SECRET_ACCESS_KEY", "test");
        c
    };
    // The first is killed (SIGKILL) once it has a unit done, with its other under way (it
    // works on two at once); the second starts then, so it cannot have claimed every unit
    // left before the kill, and takes the killed one's over when its lease runs out.
    let mut killed = worker(false).stdout(Stdio::piped()).spawn().unwrap();
    let mut lines = BufReader::new(killed.stdout.take().unwrap()).lines();
    let first = lines.next().unwrap().unwrap();
    assert!(first.contains(" files ("), "{first}");
    killed.kill().unwrap();
    killed.wait().unwrap();
    // The units it died holding (it may hold none, when its other loop was between claims).
    let held = Command::new("psql")
        .args([
            pg.url.as_str(),
            "-tAc",
            "SELECT COUNT(*) FROM export_units WHERE state = 'running'",
        ])
        .output()
        .unwrap();
    let held: u64 = String::from_utf8_lossy(&held.stdout)
        .trim()
        .parse()
        .unwrap();
    let report = dir.path().join("survivor.json");
    let mut survivor = worker(true).arg("--report").arg(&report).spawn().unwrap();
    assert!(survivor.wait().unwrap().success());
    let survived: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();

    // The union is the single process's tree, byte for byte.
    let got = objects(&store, "world");
    assert_eq!(got.len(), expected.len());
    assert!(
        got == expected,
        "the shared export differs from the single one"
    );
    // Every object was written once, by one exporter or the other.
    let mut puts: BTreeMap<String, u32> = BTreeMap::new();
    for (method, path) in recorded(&s3) {
        if method == "PUT"
            && let Some(key) = path.strip_prefix("/tiles/world/")
        {
            *puts.entry(key.to_owned()).or_default() += 1;
        }
    }
    assert_eq!(puts.len(), expected.len());
    let twice: Vec<_> = puts.iter().filter(|(_, n)| **n != 1).collect();
    assert!(twice.is_empty(), "written more than once: {twice:?}");
    // The killed one wrote its share before it died; the survivor wrote the rest.
    let by_survivor = survived["written"].as_u64().unwrap();
    assert!(
        by_survivor < expected.len() as u64,
        "the killed exporter wrote nothing: {survived}"
    );
    assert_eq!(survived["files"], expected.len() as u64);
    // Every unit it died holding was taken over once its lease ran out.
    assert_eq!(survived["taken_over"].as_u64().unwrap(), held, "{survived}");
}

/// POSTs nothing to `url`; answers the body.
fn reqwest_post(url: &str) -> String {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        reqwest::Client::new()
            .post(url)
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap()
    })
}
