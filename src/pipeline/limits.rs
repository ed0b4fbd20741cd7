//! The limits every pipeline step runs under: the request timeout and the generation slots.

use super::Generator;
use super::PipelineError;
use crate::error::AppError;
use std::future::Future;
use tokio::sync::OwnedSemaphorePermit;

/// Runs `work` under the request timeout (503 `timeout` after it).
pub async fn within_timeout<T>(
    generator: &Generator,
    work: impl Future<Output = Result<T, AppError>>,
) -> Result<T, AppError> {
    let limit = generator.limits.request_timeout;
    tokio::time::timeout(limit, work)
        .await
        .map_err(|_| PipelineError::Timeout(limit))?
}

/// A generation slot, waited for at most `--generation-wait-ms` (503 `busy` after it).
pub async fn generation_slot(generator: &Generator) -> Result<OwnedSemaphorePermit, AppError> {
    tokio::time::timeout(
        generator.limits.generation_wait,
        generator.generations.clone().acquire_owned(),
    )
    .await
    .map_err(|_| PipelineError::Busy)?
    .map_err(AppError::internal)
}

/// Runs CPU work on the blocking pool under a generation slot and the request timeout. The slot
/// goes with the work: if the client leaves (the request future is dropped), the work still
/// holds its slot until it ends, so abandoned work never lets more run at once than there are
/// slots; its cost is bounded by the limits on what a request may ask for.
pub async fn run_blocking<T, F>(generator: &Generator, work: F) -> Result<T, AppError>
where
    F: FnOnce() -> Result<T, AppError> + Send + 'static,
    T: Send + 'static,
{
    within_timeout(generator, async {
        let slot = generation_slot(generator).await?;
        tokio::task::spawn_blocking(move || {
            let result = work();
            drop(slot);
            result
        })
        .await?
    })
    .await
}
