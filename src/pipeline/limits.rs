//! The limits every pipeline step runs under: the request timeout and the generation slots.

use crate::error::AppError;
use crate::state::AppState;
use std::future::Future;
use tokio::sync::OwnedSemaphorePermit;

/// Runs `work` under the request timeout (503 `timeout` after it).
pub async fn within_timeout<T>(
    state: &AppState,
    work: impl Future<Output = Result<T, AppError>>,
) -> Result<T, AppError> {
    let limit = state.limits.request_timeout;
    tokio::time::timeout(limit, work)
        .await
        .map_err(|_| AppError::Unavailable {
            code: "timeout",
            detail: format!(
                "gathering and generating this area took longer than {} s (--request-timeout-s); try a smaller area or again later",
                limit.as_secs_f64()
            ),
            retry_after_secs: 5,
        })?
}

/// A generation slot, waited for at most `--generation-wait-ms` (503 `busy` after it).
pub async fn generation_slot(state: &AppState) -> Result<OwnedSemaphorePermit, AppError> {
    tokio::time::timeout(
        state.limits.generation_wait,
        state.generations.clone().acquire_owned(),
    )
    .await
    .map_err(|_| AppError::Unavailable {
        code: "busy",
        detail:
            "every generation slot is busy: try again in a moment (cached tiles are still served)"
                .to_owned(),
        retry_after_secs: 1,
    })?
    .map_err(AppError::internal)
}

/// Runs CPU work on the blocking pool under a generation slot and the request timeout. The slot
/// goes with the work: if the client leaves (the request future is dropped), the work still
/// holds its slot until it ends, so abandoned work never lets more run at once than there are
/// slots; its cost is bounded by the limits on what a request may ask for.
pub async fn run_blocking<T, F>(state: &AppState, work: F) -> Result<T, AppError>
where
    F: FnOnce() -> Result<T, AppError> + Send + 'static,
    T: Send + 'static,
{
    within_timeout(state, async {
        let slot = generation_slot(state).await?;
        tokio::task::spawn_blocking(move || {
            let result = work();
            drop(slot);
            result
        })
        .await?
    })
    .await
}
