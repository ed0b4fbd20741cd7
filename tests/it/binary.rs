//! The real binary: `citymesh serve` on a free port answers over TCP and stops cleanly on SIGTERM.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::Command;

fn http_get(addr: &str, path: &str) -> (String, Vec<u8>) {
    let mut stream = TcpStream::connect(addr).unwrap();
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut raw = Vec::new();
    stream.read_to_end(&mut raw).unwrap();
    let split = raw.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    (
        String::from_utf8_lossy(&raw[..split]).into_owned(),
        raw[split + 4..].to_vec(),
    )
}

#[test]
fn serve_answers_and_shuts_down_gracefully_on_sigterm() {
    let db = tempfile::tempdir().unwrap();
    let (mut child, addr, lines) = common::serve_binary(db.path(), &[]);
    let (head, body) = http_get(&addr, "/health");
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    let health: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(health["dem_files"], 5);
    // One machine: the SQLite file, no database server.
    assert_eq!(health["database"]["backend"], "sqlite");

    let (head, body) = http_get(&addr, "/tiles/16/34297/22492.glb");
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert_eq!(&body[..4], b"glTF");

    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let exit = child.wait().unwrap();
    assert!(exit.success(), "citymesh exited with {exit} after SIGTERM");
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    assert!(
        rest.iter().any(|l| l.contains("stopped")),
        "no clean stop in the log: {rest:?}"
    );
}
