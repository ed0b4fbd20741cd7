//! Generation and only what it needs: the building source, the DEM, the generation slots, the
//! limits, the metrics, how heights are counted and roofs laid, and, for roofs beyond the tags,
//! the roof jobs' predictions and the roof priors. Handlers reach it through axum's `FromRef`
//! (`State<Generator>`); every pipeline step takes it instead of the whole server state.

use crate::cache::RoofPriors;
use crate::dem::DemStore;
use crate::metrics::Metrics;
use crate::roofs::RoofJobs;
use crate::source::BuildingSource;
use crate::state::{AppState, Limits};
use axum::extract::FromRef;
use citymesh_core::building::{HeightBase, RoofMethod};
use citymesh_core::geo::GeoBbox;
use std::sync::Arc;
use tokio::sync::Semaphore;
use tokio_util::sync::CancellationToken;

/// A handle on what generation needs; one reference count to clone.
#[derive(Clone)]
pub struct Generator(Arc<GeneratorParts>);

/// What a [`Generator`] holds.
pub struct GeneratorParts {
    pub source: Arc<dyn BuildingSource>,
    pub dem: Arc<DemStore>,
    /// Generations running at once at most (`--max-generations`).
    pub generations: Arc<Semaphore>,
    pub limits: Limits,
    pub metrics: Arc<Metrics>,
    /// The ground a building's `height` is counted from (`--height-base`).
    pub height_base: HeightBase,
    /// How hipped, gabled and pyramidal roofs are laid over footprints (`--roof-method`).
    pub roof_method: RoofMethod,
    /// The predictions `roofs=classified` draws.
    pub roofs: Arc<RoofJobs>,
    /// The priors `roofs=inferred` draws, and classified roofs combine with.
    pub priors: Arc<RoofPriors>,
    /// Cancelled when the server shuts down: long measurements stop.
    pub stopping: CancellationToken,
    /// The area the world tileset covers beyond the data held (`--world-area`): its leaves
    /// there may fetch.
    pub world_area: Option<GeoBbox>,
}

impl Generator {
    pub fn new(parts: GeneratorParts) -> Self {
        Self(Arc::new(parts))
    }
}

impl std::ops::Deref for Generator {
    type Target = GeneratorParts;

    fn deref(&self) -> &GeneratorParts {
        &self.0
    }
}

impl FromRef<AppState> for Generator {
    fn from_ref(state: &AppState) -> Self {
        state.generator.clone()
    }
}
