//! A small HTTP/1.1 load generator for citymesh's benchmarks: N keep-alive connections send GET
//! requests for one path to one address on this machine, for a bounded time and count, and the
//! answer is requests per second and latency percentiles.
//!
//!     loadgen ADDR PATH [--connections 64] [--seconds 10] [--max-requests 2000000]
//!
//! Only loopback addresses are accepted: it is a benchmark tool, not a way to load other hosts.

use std::net::SocketAddr;
use std::time::{Duration, Instant};
use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;

struct Options {
    addr: SocketAddr,
    path: String,
    connections: usize,
    seconds: f64,
    max_requests: usize,
}

fn options() -> Result<Options, String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: loadgen ADDR PATH [--connections N] [--seconds S] [--max-requests N]";
    let addr: SocketAddr = args
        .first()
        .ok_or(usage)?
        .parse()
        .map_err(|e| format!("ADDR: {e}; {usage}"))?;
    if !addr.ip().is_loopback() {
        return Err(format!("{addr} is not a loopback address"));
    }
    let path = args.get(1).ok_or(usage)?.clone();
    let mut o = Options {
        addr,
        path,
        connections: 64,
        seconds: 10.0,
        max_requests: 2_000_000,
    };
    let mut i = 2;
    while i < args.len() {
        let value = args.get(i + 1).ok_or(usage)?;
        match args[i].as_str() {
            "--connections" => o.connections = value.parse().map_err(|_| usage)?,
            "--seconds" => o.seconds = value.parse().map_err(|_| usage)?,
            "--max-requests" => o.max_requests = value.parse().map_err(|_| usage)?,
            _ => return Err(usage.to_owned()),
        }
        i += 2;
    }
    if !(o.seconds > 0.0 && o.seconds <= 300.0) || o.connections == 0 || o.connections > 1024 {
        return Err("--seconds must be in (0, 300] and --connections in 1..=1024".to_owned());
    }
    Ok(o)
}

/// One connection's loop: latencies in microseconds, and bytes of body received.
async fn connection(
    o: std::sync::Arc<Options>,
    deadline: Instant,
    budget: std::sync::Arc<std::sync::atomic::AtomicUsize>,
) -> std::io::Result<(Vec<u32>, u64, usize)> {
    let stream = TcpStream::connect(o.addr).await?;
    stream.set_nodelay(true)?;
    let (read, mut write) = stream.into_split();
    let mut read = BufReader::with_capacity(1 << 16, read);
    let request = format!(
        "GET {} HTTP/1.1\r\nHost: {}\r\nUser-Agent: citymesh-loadgen\r\n\r\n",
        o.path, o.addr
    );
    let mut latencies = Vec::new();
    let (mut bytes, mut errors) = (0u64, 0usize);
    let mut body = vec![0u8; 0];
    let mut line = String::new();
    while Instant::now() < deadline {
        // Take one request from the budget; never below zero, so it bounds all connections.
        let taken = budget.fetch_update(
            std::sync::atomic::Ordering::Relaxed,
            std::sync::atomic::Ordering::Relaxed,
            |left| left.checked_sub(1),
        );
        if taken.is_err() {
            break;
        }
        let started = Instant::now();
        write.write_all(request.as_bytes()).await?;
        line.clear();
        read.read_line(&mut line).await?;
        let ok = line.starts_with("HTTP/1.1 200");
        let mut length = 0usize;
        loop {
            line.clear();
            read.read_line(&mut line).await?;
            if line == "\r\n" || line.is_empty() {
                break;
            }
            if let Some(v) = line.to_ascii_lowercase().strip_prefix("content-length:") {
                length = v.trim().parse().unwrap_or(0);
            }
        }
        body.resize(length, 0);
        read.read_exact(&mut body).await?;
        latencies.push(started.elapsed().as_micros().min(u32::MAX as u128) as u32);
        bytes += length as u64;
        if !ok {
            errors += 1;
        }
    }
    Ok((latencies, bytes, errors))
}

#[tokio::main]
async fn main() {
    let o = match options() {
        Ok(o) => std::sync::Arc::new(o),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let started = Instant::now();
    let deadline = started + Duration::from_secs_f64(o.seconds);
    let budget = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(o.max_requests));
    let tasks: Vec<_> = (0..o.connections)
        .map(|_| tokio::spawn(connection(o.clone(), deadline, budget.clone())))
        .collect();
    let mut all = Vec::new();
    let (mut bytes, mut errors, mut failed) = (0u64, 0usize, 0usize);
    for t in tasks {
        match t.await {
            Ok(Ok((l, b, e))) => {
                all.extend(l);
                bytes += b;
                errors += e;
            }
            _ => failed += 1,
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    all.sort_unstable();
    let pct = |p: f64| {
        all.get(((all.len() as f64 * p).ceil() as usize).saturating_sub(1))
            .map_or(0.0, |&us| f64::from(us) / 1000.0)
    };
    println!(
        "{} requests in {:.2} s over {} connections: {:.0} req/s, {:.1} MB/s; latency ms p50 {:.3}, p90 {:.3}, p99 {:.3}, max {:.3}; non-200 answers {}, failed connections {}",
        all.len(),
        elapsed,
        o.connections,
        all.len() as f64 / elapsed,
        bytes as f64 / elapsed / 1e6,
        pct(0.5),
        pct(0.9),
        pct(0.99),
        pct(1.0),
        errors,
        failed
    );
}
