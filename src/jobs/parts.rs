//! Per-wavelength results in the queue (docs/service.md, "Per-wavelength
//! results"): which wavelengths of a request are cached, a request
//! assembled from them with no solve, and the parts a job solves stored as
//! results of their own.

use super::result::{self, PartInput, SolvedPart};
use super::{JobError, Jobs};
use crate::brdf::format;
use crate::material::Spec;
use crate::plan;
use crate::storage::{BlobStore, JobRow, Status, now_ms};

/// Most done rows of a family looked at for a covering result.
const MAX_COVER_CANDIDATES: i64 = 32;

/// A cached result a request (or one of its wavelengths) is answered
/// from: its verified bytes (restricted to the request's needs), its solve
/// time and the id of the result they were read from.
pub(super) struct CachedPart {
    pub(super) bytes: Vec<u8>,
    pub(super) wall_time_ms: f64,
    pub(super) id: String,
}

/// A part solved by a job, its blob stored: the row to record.
pub(super) struct StoredPart {
    pub(super) id: String,
    pub(super) canonical_json: String,
    pub(super) digest: String,
    pub(super) size: i64,
    pub(super) media_type: &'static str,
    pub(super) wall_time_ms: Vec<f64>,
    pub(super) error_estimate: Option<f64>,
}

impl Jobs {
    /// The one-wavelength parts of `spec` with the bytes of those already
    /// cached, their solve times, and the ids of the cached ones.
    pub(super) async fn part_inputs(
        &self,
        spec: &Spec,
    ) -> Result<(Vec<PartInput>, Vec<f64>, Vec<String>), JobError> {
        let mut parts = Vec::new();
        let mut walls = Vec::new();
        let mut covered_by = Vec::new();
        for part in plan::wavelength_parts(spec) {
            let cached = match self.cached_part(&part.id).await? {
                Some(c) => Some(c),
                None => {
                    self.cached_covering(&part.spec, &part.canonical_json, &part.id)
                        .await?
                }
            };
            if let Some(c) = &cached {
                covered_by.push(c.id.clone());
            }
            walls.push(cached.as_ref().map_or(0.0, |c| c.wall_time_ms));
            parts.push(PartInput {
                cached: cached.map(|c| c.bytes),
                part,
            });
        }
        Ok((parts, walls, covered_by))
    }

    /// The verified bytes of the cached per-wavelength result `id`, if it
    /// is done, current and in a current media type ([`result::is_current_media_type`]) (else it is solved).
    async fn cached_part(&self, id: &str) -> Result<Option<CachedPart>, JobError> {
        let Some(row) = self.index.get(id).await? else {
            return Ok(None);
        };
        let usable = row.status == Status::Done
            && row.is_current()
            && result::is_current_media_type(row.media_type.as_deref());
        let Some(digest) = row.digest.clone().filter(|_| usable) else {
            return Ok(None);
        };
        let blobs = self.blobs.clone();
        let bytes = tokio::task::spawn_blocking(move || blobs.get(&digest))
            .await
            .map_err(|e| JobError::Storage(e.to_string()))?
            .map_err(|e| JobError::Storage(e.to_string()))?;
        Ok(bytes.map(|bytes| CachedPart {
            bytes,
            wall_time_ms: row.wall_time_ms.first().copied().unwrap_or(0.0),
            id: id.to_string(),
        }))
    }

    /// A cached result of another request of `spec`'s family that covers
    /// its needs (`plan::spec_may_cover`, `brdf::Table::cover`; docs/service.md,
    /// "Covering results"), cut or resampled to them under `spec`'s
    /// canonical JSON and id. Candidates on the request's own grid first
    /// (copies), then the coarsest finer grid (the cheapest resample).
    pub(super) async fn cached_covering(
        &self,
        spec: &Spec,
        canonical: &str,
        id: &str,
    ) -> Result<Option<CachedPart>, JobError> {
        let family = plan::family_of_spec(spec);
        let rows = self
            .index
            .done_in_family(&family, id, MAX_COVER_CANDIDATES)
            .await?;
        let mut candidates: Vec<(bool, usize, String)> = rows
            .into_iter()
            .filter(|r| result::is_current_media_type(r.media_type.as_deref()))
            .filter_map(|r| {
                let c = crate::material::parse(&r.spec).ok()?;
                let check = plan::spec_may_cover(&c, spec).ok()?;
                Some((check.resample, c.needs.polar_nodes(), r.id))
            })
            .collect();
        candidates.sort();
        for (_, _, cover) in candidates {
            let Some(found) = self.cached_part(&cover).await? else {
                continue;
            };
            let (c, i, request) = (canonical.to_string(), id.to_string(), spec.clone());
            let covered = tokio::task::spawn_blocking(move || {
                let table = format::from_bytes(&found.bytes).map_err(|e| e.to_string())?;
                let spec = serde_json::from_str(&c).map_err(|e| e.to_string())?;
                let table = table.cover(&request, spec, &i)?;
                let bytes =
                    format::to_bytes(&table, result::DATA_TYPE).map_err(|e| e.to_string())?;
                Ok::<_, String>(CachedPart { bytes, ..found })
            })
            .await
            .map_err(|e| JobError::Storage(e.to_string()))?;
            match covered {
                Ok(part) => return Ok(Some(part)),
                Err(e) => tracing::debug!(cover = %cover, reason = %e, "does not cover"),
            }
        }
        Ok(None)
    }

    /// Assemble request `id` from its cached parts, store it and record its
    /// row as done (no solve).
    pub(super) async fn assemble_now(
        &self,
        canonical: &str,
        id: &str,
        bytes: Vec<Vec<u8>>,
        walls: &[f64],
    ) -> Result<JobRow, JobError> {
        let (blobs, c, i) = (self.blobs.clone(), canonical.to_string(), id.to_string());
        let stored = tokio::task::spawn_blocking(move || {
            let tables = bytes
                .iter()
                .map(|b| format::from_bytes(b))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| e.to_string())?;
            let (bytes, estimate) = result::assemble(&c, &i, tables).map_err(|f| f.message)?;
            let digest = blobs.put(&bytes).map_err(|e| e.to_string())?;
            let media_type = result::media_type_of(&bytes);
            Ok::<_, String>((digest, bytes.len() as i64, estimate, media_type))
        })
        .await
        .map_err(|e| JobError::Storage(e.to_string()))?
        .map_err(JobError::Storage)?;
        let (digest, size, estimate, media_type) = stored;
        self.index
            .record_done(
                id,
                canonical,
                &digest,
                size,
                media_type,
                walls,
                estimate,
                now_ms(),
            )
            .await?;
        self.index
            .get(id)
            .await?
            .ok_or_else(|| JobError::Storage(format!("row {id} vanished")))
    }
}

/// Store the blob of a part a job solved (on the solving thread).
pub(super) fn store_part(blobs: &BlobStore, p: SolvedPart) -> Result<StoredPart, String> {
    let digest = blobs.put(&p.solved.bytes).map_err(|e| e.to_string())?;
    Ok(StoredPart {
        id: p.part.id,
        canonical_json: p.part.canonical_json,
        digest,
        size: p.solved.bytes.len() as i64,
        media_type: p.solved.media_type,
        wall_time_ms: p.solved.wall_time_ms,
        error_estimate: p.solved.error_estimate,
    })
}
