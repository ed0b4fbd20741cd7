//! A real PostgreSQL server for the tests, started here in a temporary folder on 127.0.0.1
//! (Debian's `postgresql` 15; `initdb` refuses root, so it runs as the `postgres` user), and
//! stopped when dropped. Fails loudly when PostgreSQL is not installed (`scripts/test`
//! installs it).

use std::path::PathBuf;
use std::process::Command;

const BIN: &str = "/usr/lib/postgresql/15/bin";

pub struct Postgres {
    dir: tempfile::TempDir,
    /// `postgres://test@127.0.0.1:PORT/postgres`.
    pub url: String,
}

fn run(args: &[&str]) {
    let out = Command::new("runuser")
        .args(["-u", "postgres", "--"])
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("runuser: {e}"));
    assert!(
        out.status.success(),
        "{args:?}: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

impl Postgres {
    pub fn start() -> Self {
        let initdb = PathBuf::from(BIN).join("initdb");
        assert!(
            initdb.is_file(),
            "PostgreSQL 15 is missing ({}): scripts/test installs Debian's postgresql",
            initdb.display()
        );
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().to_str().unwrap().to_owned();
        assert!(
            Command::new("chown")
                .args(["postgres", &d])
                .status()
                .unwrap()
                .success()
        );
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let data = format!("{d}/data");
        run(&[
            initdb.to_str().unwrap(),
            "-D",
            &data,
            "-A",
            "trust",
            "-U",
            "test",
            "--no-sync",
        ]);
        let options = format!("-k {d} -c listen_addresses=127.0.0.1 -p {port} -c fsync=off");
        run(&[
            &format!("{BIN}/pg_ctl"),
            "-D",
            &data,
            "-l",
            &format!("{d}/log"),
            "-o",
            &options,
            "-w",
            "start",
        ]);
        Self {
            dir,
            url: format!("postgres://test@127.0.0.1:{port}/postgres"),
        }
    }
}

impl Drop for Postgres {
    fn drop(&mut self) {
        let data = self.dir.path().join("data");
        let _ = Command::new("runuser")
            .args(["-u", "postgres", "--", &format!("{BIN}/pg_ctl"), "-D"])
            .arg(&data)
            .args(["-m", "immediate", "-w", "stop"])
            .output();
    }
}
