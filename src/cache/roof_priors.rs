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
use std::sync::atomic::{AtomicU64, Ordering};

/// How many priors as heavy as a scope may make the priors' memory share holds at once:
/// sources cut their scopes so each prior weighs at most the share over this.
pub const PRIORS_KEPT: u64 = 4;

pub struct RoofPriors {
    fitted: moka::future::Cache<PriorScope, Arc<RoofPrior>>,
    /// Counts invalidations. A prior fitted while one ran may have learned from the old data:
    /// it is answered, but not kept (moka would otherwise insert it after the invalidation).
    invalidations: AtomicU64,
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
            invalidations: AtomicU64::new(0),
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
        let before = self.invalidations.load(Ordering::SeqCst);
        let prior = self
            .fitted
            .try_get_with(scope, async {
                fitted_now = true;
                fit.await
            })
            .await
            .map_err(|e: Arc<AppError>| (*e).clone())?;
        if fitted_now && self.invalidations.load(Ordering::SeqCst) != before {
            self.fitted.invalidate(&scope).await;
        }
        Ok((prior, !fitted_now))
    }

    /// Drops the priors whose scope data changed over `area` touches.
    pub fn invalidate_area(&self, area: &GeoBbox) {
        self.invalidations.fetch_add(1, Ordering::SeqCst);
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
        self.invalidations.fetch_add(1, Ordering::SeqCst);
        self.fitted.invalidate_all();
    }

    /// Bytes held now.
    pub async fn weighted_size(&self) -> u64 {
        self.fitted.run_pending_tasks().await;
        self.fitted.weighted_size()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)] // test code: failing is the point
    use super::*;
    use citymesh_core::geo::TileCoord;

    fn prior() -> Arc<RoofPrior> {
        Arc::new(RoofPrior::fit(&[]))
    }

    /// Whether `scope`'s prior is held (fitting one when it is not).
    async fn held(priors: &RoofPriors, scope: PriorScope) -> bool {
        priors.fitted.run_pending_tasks().await;
        priors
            .get_or_fit(scope, async { Ok(prior()) })
            .await
            .unwrap()
            .1
    }

    #[tokio::test]
    async fn one_fit_per_scope_until_its_area_changes() {
        let priors = RoofPriors::new(1 << 20);
        let t = TileCoord::containing(14, 8.4, 49.05);
        let scope = PriorScope::DataTile(t);
        assert!(!held(&priors, scope).await);
        assert!(held(&priors, scope).await);
        // A change elsewhere keeps it; one over its tile drops it.
        priors.invalidate_area(&"9.0,50.0,9.1,50.1".parse().unwrap());
        assert!(held(&priors, scope).await);
        priors.invalidate_area(&t.bounds());
        assert!(!held(&priors, scope).await);
    }

    #[tokio::test]
    async fn a_prior_fitted_while_data_changed_is_answered_but_not_kept() {
        let priors = Arc::new(RoofPriors::new(1 << 20));
        let scope = PriorScope::Everything;
        let during = priors.clone();
        let (_, was_held) = priors
            .get_or_fit(scope, async move {
                during.invalidate_all();
                Ok(prior())
            })
            .await
            .unwrap();
        assert!(!was_held);
        assert!(!held(&priors, scope).await);
        assert!(held(&priors, scope).await);
    }
}
