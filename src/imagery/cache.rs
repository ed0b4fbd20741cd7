//! Fetched imagery tiles in the cache database, with a time to live and a size bound.

use citymesh_core::geo::TileCoord;
use sqlx::SqlitePool;
use std::sync::atomic::{AtomicI64, Ordering};
use std::time::Duration;

pub struct ImageryCache {
    pool: SqlitePool,
    ttl: Duration,
    max_bytes: u64,
    /// Bytes stored, as last counted (counted at start and after each eviction, grown by puts).
    stored: AtomicI64,
}

fn now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

impl ImageryCache {
    pub async fn new(pool: SqlitePool, ttl: Duration, max_bytes: u64) -> sqlx::Result<Self> {
        let stored: i64 =
            sqlx::query_scalar("SELECT COALESCE(SUM(length(bytes)), 0) FROM imagery_tiles")
                .fetch_one(&pool)
                .await?;
        Ok(Self {
            pool,
            ttl,
            max_bytes,
            stored: AtomicI64::new(stored),
        })
    }

    /// The stored bytes of a tile younger than the time to live.
    pub async fn get(&self, imagery_id: &str, t: TileCoord) -> sqlx::Result<Option<Vec<u8>>> {
        let now = now_ms();
        let oldest = now.saturating_sub(i64::try_from(self.ttl.as_millis()).unwrap_or(i64::MAX));
        let bytes: Option<Vec<u8>> = sqlx::query_scalar(
            "UPDATE imagery_tiles SET last_used = ? WHERE imagery_id = ? AND z = ? AND x = ? \
             AND y = ? AND fetched_at >= ? RETURNING bytes",
        )
        .bind(now)
        .bind(imagery_id)
        .bind(i64::from(t.z))
        .bind(i64::from(t.x))
        .bind(i64::from(t.y))
        .bind(oldest)
        .fetch_optional(&self.pool)
        .await?;
        Ok(bytes)
    }

    /// Stores a tile, then evicts the least recently used while the table is over its bound.
    pub async fn put(&self, imagery_id: &str, t: TileCoord, bytes: &[u8]) -> sqlx::Result<()> {
        if bytes.len() as u64 > self.max_bytes {
            return Ok(());
        }
        let now = now_ms();
        sqlx::query(
            "INSERT OR REPLACE INTO imagery_tiles (imagery_id, z, x, y, bytes, fetched_at, \
             last_used) VALUES (?, ?, ?, ?, ?, ?, ?)",
        )
        .bind(imagery_id)
        .bind(i64::from(t.z))
        .bind(i64::from(t.x))
        .bind(i64::from(t.y))
        .bind(bytes)
        .bind(now)
        .bind(now)
        .execute(&self.pool)
        .await?;
        let stored = self.stored.fetch_add(
            i64::try_from(bytes.len()).unwrap_or(i64::MAX),
            Ordering::Relaxed,
        );
        if stored as u64 + bytes.len() as u64 > self.max_bytes {
            self.evict().await?;
        }
        Ok(())
    }

    /// Deletes the least recently used tiles until the table holds at most 90 % of the bound.
    async fn evict(&self) -> sqlx::Result<()> {
        let target = i64::try_from(self.max_bytes / 10 * 9).unwrap_or(i64::MAX);
        sqlx::query(
            "DELETE FROM imagery_tiles WHERE rowid IN (SELECT rowid FROM (SELECT rowid, \
             SUM(length(bytes)) OVER (ORDER BY last_used DESC, rowid DESC) AS kept \
             FROM imagery_tiles) WHERE kept > ?)",
        )
        .bind(target)
        .execute(&self.pool)
        .await?;
        let stored: i64 =
            sqlx::query_scalar("SELECT COALESCE(SUM(length(bytes)), 0) FROM imagery_tiles")
                .fetch_one(&self.pool)
                .await?;
        self.stored.store(stored, Ordering::Relaxed);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn tiles_expire_and_the_least_recently_used_go_first() {
        let pool = crate::db::open(":memory:").await.unwrap();
        let cache = ImageryCache::new(pool.clone(), Duration::from_secs(3600), 10_000)
            .await
            .unwrap();
        let t = |x| TileCoord::new(18, x, 7).unwrap();
        for x in 0..4 {
            cache.put("a", t(x), &[x as u8; 3000]).await.unwrap();
            // Tile 0 is used again before each put: it stays.
            assert!(cache.get("a", t(0)).await.unwrap().is_some());
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
        // 12,000 bytes went in, over the 10,000 bound: the least recently used (tile 1) left, and
        // 9,000 remain.
        assert_eq!(cache.get("a", t(1)).await.unwrap(), None);
        assert_eq!(cache.get("a", t(2)).await.unwrap(), Some(vec![2u8; 3000]));
        assert_eq!(cache.get("a", t(3)).await.unwrap(), Some(vec![3u8; 3000]));
        assert_eq!(cache.get("a", t(0)).await.unwrap(), Some(vec![0u8; 3000]));
        // Another imagery never sees these tiles.
        assert_eq!(cache.get("b", t(0)).await.unwrap(), None);
        // Past the time to live, a tile is not served.
        let short = ImageryCache::new(pool, Duration::from_millis(0), 10_000)
            .await
            .unwrap();
        tokio::time::sleep(Duration::from_millis(2)).await;
        assert_eq!(short.get("a", t(0)).await.unwrap(), None);
    }
}
