//! The server's request parsing, through its router: batch and adaptation ids and bodies of the
//! classification routes (following, deleting, cancelling), and `Accept` headers of `/scene`. Every answer must be a JSON error
//! or a success, never a 500.

use axum::body::Body;
use axum::http::Request;
use http_body_util::BodyExt;
use std::sync::OnceLock;
use tower::ServiceExt;

/// One server for every input (offline, no data, no classifier), and the runtime it runs on.
struct Server {
    runtime: tokio::runtime::Runtime,
    app: axum::Router,
    _db: Option<std::path::PathBuf>,
}

fn server() -> Option<&'static Server> {
    static SERVER: OnceLock<Option<Server>> = OnceLock::new();
    SERVER
        .get_or_init(|| {
            use clap::Parser;
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .ok()?;
            let db =
                std::env::temp_dir().join(format!("citymesh-fuzz-{}.sqlite", std::process::id()));
            let args = citymesh::cli::ServeArgs::try_parse_from([
                "serve",
                "--offline",
                "--dem-dir",
                "/nonexistent",
                "--cache-db",
                db.to_str()?,
                "--assets-dir",
                "/nonexistent",
            ])
            .ok()?;
            let state = runtime
                .block_on(citymesh::server::build_state(&args))
                .ok()?;
            Some(Server {
                app: citymesh::app(state),
                runtime,
                _db: Some(db),
            })
        })
        .as_ref()
}

/// The first byte picks the route; the rest is the id, the body or the header value.
pub fn requests(bytes: &[u8]) {
    let Some(server) = server() else {
        return;
    };
    let Some((&pick, rest)) = bytes.split_first() else {
        return;
    };
    let text = String::from_utf8_lossy(rest);
    let path_safe: String = text
        .chars()
        .filter(|c| c.is_ascii_graphic() && !matches!(c, '?' | '#' | '/' | '%'))
        .take(200)
        .collect();
    let request = match pick % 7 {
        0 => Request::get(format!("/classify/{path_safe}")).body(Body::empty()),
        1 => Request::delete(format!("/classify/{path_safe}")).body(Body::empty()),
        2 => Request::post("/classify")
            .header("content-type", "application/json")
            .body(Body::from(rest.to_vec())),
        3 => Request::post("/classify/adapt")
            .header("content-type", "application/json")
            .body(Body::from(rest.to_vec())),
        5 => Request::get(format!("/classify/adapt/{path_safe}")).body(Body::empty()),
        6 => Request::delete(format!("/classify/adapt/{path_safe}")).body(Body::empty()),
        _ => {
            let accept: String = text
                .chars()
                .filter(|c| c.is_ascii() && !c.is_ascii_control())
                .take(400)
                .collect();
            Request::get("/scene?bbox=8.4000,49.0000,8.4004,49.0003")
                .header("accept", accept)
                .body(Body::empty())
        }
    };
    let Ok(request) = request else {
        return;
    };
    let (status, body) = server
        .runtime
        .block_on(async {
            let response = server.app.clone().oneshot(request).await.ok()?;
            let status = response.status();
            let body = response.into_body().collect().await.ok()?.to_bytes();
            Some((status, body))
        })
        .unwrap_or_default();
    assert!(
        status.as_u16() != 500,
        "500 for route {}: {}",
        pick % 7,
        String::from_utf8_lossy(&body)
    );
    if status.is_client_error() || status.is_server_error() {
        assert!(
            serde_json::from_slice::<serde_json::Value>(&body).is_ok(),
            "{status} without a JSON body"
        );
    }
}
