//! Accepting connections with limits: at most `--max-connections` open at once (further clients
//! wait in the listen backlog), plus `--reserved-connections` that only `/health` and `/metrics`
//! may use (so a flood of connections never blinds monitoring); a first byte within
//! `--first-byte-timeout-s` (a client that connects and says nothing gives its slot back fast),
//! request headers within `--header-timeout-s`, and no connection silent for longer than
//! `--idle-timeout-s` (neither reading nor writing: an idle keep-alive, a client that stopped
//! sending its request, or one that stopped reading its answer). Request bodies are bounded in
//! time by the router (`--body-timeout-s`, a total deadline). The same deadlines hold for HTTP/2
//! counted in requests, not bytes ([`super::streams`]): a connection that opens no stream within
//! `--first-byte-timeout-s`, or has no open stream for `--idle-timeout-s`, is closed, whatever
//! PINGs or SETTINGS it sends. On shutdown, requests in flight finish.

use super::parse_errors;
use super::streams::Streams;
use crate::metrics::{Metrics, SlotLabels};
use axum::Router;
use hyper_util::rt::{TokioExecutor, TokioIo, TokioTimer};
use hyper_util::server::conn::auto::Builder;
use hyper_util::server::graceful::GracefulShutdown;
use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Semaphore;
use tokio::time::{Instant, Sleep};

/// What a client connection may take.
#[derive(Debug, Clone, Copy)]
pub struct ConnectionLimits {
    pub max_connections: usize,
    /// Further connections, for `/health` and `/metrics` only, taken when the others are all
    /// in use.
    pub reserved_connections: usize,
    pub first_byte_timeout: Duration,
    pub header_timeout: Duration,
    pub idle_timeout: Duration,
}

/// Header lines hyper parses; the router allows [`crate::routes::MAX_HEADER_COUNT`].
const HYPER_MAX_HEADERS: usize = 1_000;

/// Paths a reserved connection serves.
const SERVICE_PATHS: [&str; 2] = ["/health", "/metrics"];

/// On a reserved connection: the service routes, and a 503 for everything else.
async fn service_routes_only(
    request: axum::extract::Request,
    next: axum::middleware::Next,
) -> axum::response::Response {
    use axum::response::IntoResponse;
    if SERVICE_PATHS.contains(&request.uri().path()) {
        return next.run(request).await;
    }
    let mut answer = (
        axum::http::StatusCode::SERVICE_UNAVAILABLE,
        axum::Json(crate::error::ErrorBody {
            error: "busy".to_owned(),
            detail: "every connection slot is taken (--max-connections); this one is kept for \
                     /health and /metrics: try again shortly"
                .to_owned(),
            feature: None,
            field: None,
        }),
    )
        .into_response();
    answer.headers_mut().insert(
        axum::http::header::RETRY_AFTER,
        axum::http::HeaderValue::from_static("1"),
    );
    answer
}

/// How long requests in flight may take to finish after a shutdown signal.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(30);

/// Serves `app` on `listener` until `shutdown` completes.
pub async fn serve(
    listener: TcpListener,
    app: Router,
    limits: ConnectionLimits,
    metrics: Arc<Metrics>,
    shutdown: impl Future<Output = ()>,
) {
    let permits = Arc::new(Semaphore::new(limits.max_connections));
    let reserved = Arc::new(Semaphore::new(limits.reserved_connections));
    let reserved_app = app
        .clone()
        .layer(axum::middleware::from_fn(service_routes_only));
    let mut builder = Builder::new(TokioExecutor::new());
    builder
        .http1()
        .timer(TokioTimer::new())
        .header_read_timeout(limits.header_timeout)
        // Far above what the router accepts, so the router refuses (with a JSON body) what
        // hyper would refuse with an empty one.
        .max_headers(HYPER_MAX_HEADERS);
    builder.http2().timer(TokioTimer::new());
    let graceful = GracefulShutdown::new();
    tokio::pin!(shutdown);
    loop {
        // Accept first, then pick the slot: a reserved slot is taken only when every general one
        // is in use at the moment this client arrives (picking before accepting would hand a
        // reserved slot, taken while the general ones were briefly full, to whoever came next).
        // At most this one accepted client waits for a slot; the others wait in the backlog.
        let (stream, peer) = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok(accepted) => accepted,
                Err(e) => {
                    // Out of file descriptors and the like: wait a moment rather than spin.
                    tracing::warn!("accept failed: {e}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            () = &mut shutdown => break,
        };
        // A general slot if one is free, else a reserved one, else whichever frees first.
        let taken = match permits.clone().try_acquire_owned() {
            Ok(p) => Ok((p, false)),
            Err(_) => match reserved.clone().try_acquire_owned() {
                Ok(p) => Ok((p, true)),
                Err(_) => tokio::select! {
                    p = permits.clone().acquire_owned() => p.map(|p| (p, false)),
                    p = reserved.clone().acquire_owned() => p.map(|p| (p, true)),
                    () = &mut shutdown => break,
                },
            },
        };
        let Ok((permit, is_reserved)) = taken else {
            break;
        };
        let open = metrics
            .connections_open
            .get_or_create(&SlotLabels {
                slot: if is_reserved { "reserved" } else { "general" },
            })
            .clone();
        open.inc();
        let _ = stream.set_nodelay(true);
        let streams = Streams::new();
        let io = TokioIo::new(IdleTimeout::new(
            stream,
            limits.first_byte_timeout,
            limits.idle_timeout,
            streams.clone(),
        ));
        let service = streams.service(
            if is_reserved {
                reserved_app.clone()
            } else {
                app.clone()
            },
            peer,
        );
        let connection = graceful.watch(
            builder
                .serve_connection_with_upgrades(io, service)
                .into_owned(),
        );
        // Before its first request, an HTTP/2 connection has the first-byte limit (its request
        // comes whole in the frames after the preface); an HTTP/1 one has the first-byte and the
        // header limits, which the stream and hyper enforce sooner (this is their backstop).
        let first_request = move |http2: bool| {
            if http2 {
                limits.first_byte_timeout
            } else {
                limits.first_byte_timeout + limits.header_timeout
            }
        };
        tokio::spawn(async move {
            tokio::select! {
                served = connection => if let Err(e) = served {
                    tracing::debug!("connection closed: {e}");
                },
                () = streams.idle_for_too_long(first_request, limits.idle_timeout) => {
                    tracing::debug!("connection closed: no request open for too long");
                }
            }
            // The slot is free before the gauge says so.
            drop(permit);
            open.dec();
        });
    }
    tokio::select! {
        () = graceful.shutdown() => {}
        () = tokio::time::sleep(SHUTDOWN_GRACE) => {
            tracing::warn!("requests still running after {} s; stopping anyway", SHUTDOWN_GRACE.as_secs());
        }
    }
}

/// A TCP stream that fails once it has been silent (no byte read or written while waiting for
/// one) for longer than its limit; before the client's first byte, the (shorter) first-byte
/// limit holds.
///
/// Traffic only notes the time; the timer is moved when it fires early (after the last traffic
/// plus the limit), so a busy connection does not touch the timer wheel on every read and write.
struct IdleTimeout {
    inner: TcpStream,
    /// A JSON answer written in place of one of hyper's empty ones (see `parse_errors`): its
    /// bytes, how many are written, and the length hyper asked to write.
    replacing: Option<(Vec<u8>, usize, usize)>,
    limit: Duration,
    /// The idle limit once the client has sent something.
    idle_limit: Duration,
    last_traffic: Instant,
    deadline: Pin<Box<Sleep>>,
    /// The connection's requests, told whether the client's first bytes are the HTTP/2 preface.
    streams: Streams,
    /// Whether the client has sent anything yet.
    spoken: bool,
}

impl IdleTimeout {
    fn new(inner: TcpStream, first_byte: Duration, idle: Duration, streams: Streams) -> Self {
        let first = first_byte.min(idle);
        Self {
            inner,
            replacing: None,
            limit: first,
            idle_limit: idle,
            last_traffic: Instant::now(),
            deadline: Box::pin(tokio::time::sleep(first)),
            streams,
            spoken: false,
        }
    }

    /// Some traffic: the silence starts again.
    fn active(&mut self) {
        self.last_traffic = Instant::now();
    }

    /// Waiting for traffic: an error once the silence has lasted too long.
    fn waiting(&mut self, cx: &mut Context<'_>) -> Poll<io::Error> {
        loop {
            if self.deadline.as_mut().poll(cx).is_pending() {
                return Poll::Pending;
            }
            let due = self.last_traffic + self.limit;
            if due <= Instant::now() {
                return Poll::Ready(io::Error::new(
                    io::ErrorKind::TimedOut,
                    "connection idle for too long",
                ));
            }
            // There was traffic since the timer was set: wait from the last of it.
            self.deadline.as_mut().reset(due);
        }
    }
}

impl AsyncRead for IdleTimeout {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let before = buf.filled().len();
        match Pin::new(&mut self.inner).poll_read(cx, buf) {
            Poll::Ready(result) => {
                if buf.filled().len() > before {
                    if !self.spoken {
                        self.spoken = true;
                        // The preface starts "PRI * HTTP/2.0"; no HTTP/1 method is "PRI".
                        let is_h2 = buf.filled()[before..].starts_with(b"PRI ");
                        self.streams.set_http2(is_h2);
                    }
                    self.active();
                    // The client has spoken: from now on, the idle limit.
                    self.limit = self.idle_limit;
                }
                Poll::Ready(result)
            }
            Poll::Pending => self.waiting(cx).map(Err),
        }
    }
}

impl IdleTimeout {
    /// Writes the JSON answer that replaces hyper's empty one; ready with the length hyper wrote.
    fn poll_replacement(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<usize>> {
        while let Some((bytes, written, _)) = &mut self.replacing
            && *written < bytes.len()
        {
            match Pin::new(&mut self.inner).poll_write(cx, &bytes[*written..]) {
                Poll::Ready(Ok(0)) => return Poll::Ready(Ok(0)),
                Poll::Ready(Ok(n)) => {
                    *written += n;
                    self.active();
                }
                Poll::Ready(Err(e)) => return Poll::Ready(Err(e)),
                Poll::Pending => return self.waiting(cx).map(Err),
            }
        }
        let asked = self.replacing.take().map_or(0, |(_, _, asked)| asked);
        Poll::Ready(Ok(asked))
    }
}

impl AsyncWrite for IdleTimeout {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        data: &[u8],
    ) -> Poll<io::Result<usize>> {
        if self.replacing.is_none()
            && let Some(json) = parse_errors::json_answer(data)
        {
            self.replacing = Some((json, 0, data.len()));
        }
        if self.replacing.is_some() {
            return self.poll_replacement(cx);
        }
        match Pin::new(&mut self.inner).poll_write(cx, data) {
            Poll::Ready(result) => {
                if matches!(result, Ok(n) if n > 0) {
                    self.active();
                }
                Poll::Ready(result)
            }
            Poll::Pending => self.waiting(cx).map(Err),
        }
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        // hyper's empty answers come whole, in the first buffer.
        if self.replacing.is_none()
            && let Some(first) = bufs.iter().find(|b| !b.is_empty())
            && let Some(json) = parse_errors::json_answer(first)
        {
            self.replacing = Some((json, 0, first.len()));
        }
        if self.replacing.is_some() {
            return self.poll_replacement(cx);
        }
        match Pin::new(&mut self.inner).poll_write_vectored(cx, bufs) {
            Poll::Ready(result) => {
                if matches!(result, Ok(n) if n > 0) {
                    self.active();
                }
                Poll::Ready(result)
            }
            Poll::Pending => self.waiting(cx).map(Err),
        }
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}
