//! Fitted roof priors in memory, one per prior scope (all the files' buildings, or one data
//! tile): concurrent requests for the same scope share one fit, and a data change over a scope
//! drops its prior ([`super::invalidation`]). The fit itself is the caller's (the pipeline's).

use super::budget::weight;
use crate::error::AppError;
use crate::source::PriorScope;
use citymesh_core::geo::GeoBbox;
use citymesh_core::roof_prior::RoofPrior;
use std::future::Future;
use std::sync::Arc;

pub struct RoofPriors {
    fitted: moka::future::Cache<PriorScope, Arc<RoofPrior>>,
}

impl RoofPriors {
    /// Priors weighing at most `max_bytes` together.
    pub fn new(max_bytes: u64) -> Self {
        Self {
            fitted: moka::future::Cache::builder()
                .max_capacity(max_bytes)
                .weigher(|_, p: &Arc<RoofPrior>| weight(p.byte_size()))
                .support_invalidation_closures()
                .build(),
        }
    }

    /// The prior of `scope`, fitted by `fit` when none is held (once for concurrent callers).
    /// The second value is whether it was held.
    pub async fn get_or_fit<F>(
        &self,
        scope: PriorScope,
        fit: F,
    ) -> Result<(Arc<RoofPrior>, bool), AppError>
    where
        F: Future<Output = Result<Arc<RoofPrior>, AppError>>,
    {
        let mut fitted_now = false;
        let prior = self
            .fitted
            .try_get_with(scope, async {
                fitted_now = true;
                fit.await
            })
            .await
            .map_err(|e: Arc<AppError>| (*e).clone())?;
        Ok((prior, !fitted_now))
    }

    /// Drops the priors whose scope data changed over `area` touches.
    pub fn invalidate_area(&self, area: &GeoBbox) {
        let area = *area;
        if let Err(e) = self
            .fitted
            .invalidate_entries_if(move |scope, _| scope.touches(&area))
        {
            tracing::warn!("cannot drop roof priors by area ({e}); dropping all");
            self.fitted.invalidate_all();
        }
    }

    /// Drops every prior.
    pub fn invalidate_all(&self) {
        self.fitted.invalidate_all();
    }

    /// Bytes held now.
    pub async fn weighted_size(&self) -> u64 {
        self.fitted.run_pending_tasks().await;
        self.fitted.weighted_size()
    }
}
