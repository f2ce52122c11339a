//! The index's record of a result's previews (the console's thumbnails):
//! which blob holds the preview of kind `kind` of the result whose blob is
//! `result_digest` (migrations/0006_previews.sql). The previews are removed
//! with the result's blob.

use super::{Index, StorageError};
use sqlx::Row;

/// A stored preview: its blob digest and size.
pub type Preview = (String, i64);

impl Index {
    /// The preview of kind `kind` of the result with blob `result_digest`.
    pub async fn preview(
        &self,
        result_digest: &str,
        kind: &str,
    ) -> Result<Option<Preview>, StorageError> {
        let row = match self {
            Index::Sqlite(ix) => sqlx::query(
                "SELECT digest, size FROM previews WHERE result_digest = ?1 AND kind = ?2",
            )
            .bind(result_digest)
            .bind(kind)
            .fetch_optional(&ix.pool)
            .await?
            .map(|r| Ok::<_, sqlx::Error>((r.try_get("digest")?, r.try_get("size")?))),
            Index::Postgres(ix) => sqlx::query(
                "SELECT digest, size FROM previews WHERE result_digest = $1 AND kind = $2",
            )
            .bind(result_digest)
            .bind(kind)
            .fetch_optional(&ix.pool)
            .await?
            .map(|r| Ok::<_, sqlx::Error>((r.try_get("digest")?, r.try_get("size")?))),
        };
        Ok(row.transpose()?)
    }

    /// Record a preview (the first record of a key wins: previews are
    /// deterministic, so instances racing to make one store the same
    /// bytes).
    pub async fn put_preview(
        &self,
        result_digest: &str,
        kind: &str,
        preview: &Preview,
        now: i64,
    ) -> Result<(), StorageError> {
        let (digest, size) = preview;
        match self {
            Index::Sqlite(ix) => {
                sqlx::query(
                    "INSERT INTO previews (result_digest, kind, digest, size, created_at)
                     VALUES (?1, ?2, ?3, ?4, ?5) ON CONFLICT DO NOTHING",
                )
                .bind(result_digest)
                .bind(kind)
                .bind(digest)
                .bind(size)
                .bind(now)
                .execute(&ix.pool)
                .await?;
            }
            Index::Postgres(ix) => {
                sqlx::query(
                    "INSERT INTO previews (result_digest, kind, digest, size, created_at)
                     VALUES ($1, $2, $3, $4, $5) ON CONFLICT DO NOTHING",
                )
                .bind(result_digest)
                .bind(kind)
                .bind(digest)
                .bind(size)
                .bind(now)
                .execute(&ix.pool)
                .await?;
            }
        }
        Ok(())
    }

    /// Remove the records of every preview of a result's blob; the preview
    /// blobs they named, for the caller to delete.
    pub async fn take_previews(&self, result_digest: &str) -> Result<Vec<String>, StorageError> {
        let rows = match self {
            Index::Sqlite(ix) => {
                sqlx::query("DELETE FROM previews WHERE result_digest = ?1 RETURNING digest")
                    .bind(result_digest)
                    .fetch_all(&ix.pool)
                    .await?
                    .iter()
                    .map(|r| r.try_get("digest"))
                    .collect::<Result<Vec<String>, _>>()
            }
            Index::Postgres(ix) => {
                sqlx::query("DELETE FROM previews WHERE result_digest = $1 RETURNING digest")
                    .bind(result_digest)
                    .fetch_all(&ix.pool)
                    .await?
                    .iter()
                    .map(|r| r.try_get("digest"))
                    .collect::<Result<Vec<String>, _>>()
            }
        };
        Ok(rows?)
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::on_both;
    use super::*;

    /// Put, get, the first record winning, and removal by result.
    async fn preview_records(url: String) {
        let ix = Index::open(&url).await.unwrap();
        let (r1, r2) = ("1".repeat(64), "2".repeat(64));
        assert_eq!(
            ix.preview(&r1, "thumbnail-intensity-1").await.unwrap(),
            None
        );
        let p = ("a".repeat(64), 120);
        ix.put_preview(&r1, "thumbnail-intensity-1", &p, 5)
            .await
            .unwrap();
        ix.put_preview(&r1, "thumbnail-intensity-1", &("b".repeat(64), 7), 6)
            .await
            .unwrap();
        ix.put_preview(&r1, "thumbnail-dop-1", &("c".repeat(64), 9), 6)
            .await
            .unwrap();
        ix.put_preview(&r2, "thumbnail-dop-1", &("d".repeat(64), 9), 6)
            .await
            .unwrap();
        assert_eq!(
            ix.preview(&r1, "thumbnail-intensity-1").await.unwrap(),
            Some(p)
        );
        let mut gone = ix.take_previews(&r1).await.unwrap();
        gone.sort();
        assert_eq!(gone, ["a".repeat(64), "c".repeat(64)]);
        assert_eq!(ix.preview(&r1, "thumbnail-dop-1").await.unwrap(), None);
        assert!(ix.preview(&r2, "thumbnail-dop-1").await.unwrap().is_some());
        ix.close().await;
    }

    #[tokio::test]
    async fn preview_records_on_both() {
        on_both("preview_records", preview_records).await;
    }
}
