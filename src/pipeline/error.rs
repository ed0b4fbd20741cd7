//! Why the pipeline refused or stopped, in the domain's words; `crate::error` alone turns each
//! into an HTTP answer (status, code, `Retry-After`).

use std::time::Duration;

/// A refusal or a stop of the pipeline.
#[derive(Debug, Clone, thiserror::Error)]
pub enum PipelineError {
    /// The area is not one the core can build (a tile too small for distinct degrees, ...).
    #[error("{0}")]
    InvalidArea(String),
    /// The buildings of the area have more outline nodes than one generation may draw.
    #[error(
        "the buildings here have {nodes} outline nodes, more than the {max} one request may \
         generate (--max-scene-nodes): ask a smaller box or a deeper tile"
    )]
    TooComplex { nodes: usize, max: usize },
    /// Gathering and generating took longer than `--request-timeout-s`.
    #[error(
        "gathering and generating this area took longer than {} s (--request-timeout-s); try a \
         smaller area or again later",
        .0.as_secs_f64()
    )]
    Timeout(Duration),
    /// No generation slot freed up within `--generation-wait-ms`.
    #[error("every generation slot is busy: try again in a moment (cached tiles are still served)")]
    Busy,
    /// The request was dropped before its scene was finished.
    #[error("the request was abandoned before its scene was finished")]
    Abandoned,
    /// The server is shutting down.
    #[error("the server is shutting down: try again in a moment")]
    ShuttingDown,
    /// Measuring a tree's tiles took longer than its share of request timeouts.
    #[error(
        "measuring this tree's tiles took longer than {} s ({} x --request-timeout-s): ask for a \
         smaller bbox",
        .limit.as_secs_f64(), .timeouts
    )]
    MeasureTooLong { limit: Duration, timeouts: u32 },
}
