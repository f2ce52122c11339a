//! What a job computes and the bytes it stores: the one place that decides
//! the result format.
//!
//! The result is a **BRDF table** (docs/table-format.md, `src/brdf`): per
//! wavelength the Fourier coefficients `f^m(μ_o, μ_i) = ρ^m/μ_i` of the
//! Mueller BRDF on the default polar grid ([`PolarGrid::default`]), the
//! specular matrices of a mirror base, and JSON metadata with the canonical
//! spec and its id. Each wavelength is solved at the spec's streams, or to
//! its `solver.tolerance` (then with the solver's error estimate,
//! `solver::accuracy`). The bytes are a deterministic function of the spec:
//! timings live in the job's row, not in the table (its `wall_time_ms`
//! fields are 0), so a re-solve reproduces the same digest.

use crate::brdf::format::{self, DataType};
use crate::brdf::table::{self, BuildOptions};
use crate::brdf::{BrdfError, Table};
use crate::material::Spec;
use crate::plan::{Plan, WavelengthPart};
use crate::solver;
use std::time::Instant;

/// Media type of stored bytes in table format version 4, which every table
/// without a top interface is written in (`brdf::format::version_of`).
pub const MEDIA_TYPE: &str = "application/vnd.polbrdf.table; version=4";

/// Media type of stored bytes in table format version 5 (a table under a
/// top interface whose correction records carry its index).
pub const MEDIA_TYPE_V5: &str = "application/vnd.polbrdf.table; version=5";

/// Media type of stored bytes in table format version 6 (a table under a
/// rough top interface, with its surface records).
pub const MEDIA_TYPE_V6: &str = "application/vnd.polbrdf.table; version=6";

/// The media type of table bytes, by the format version in their header.
pub fn media_type_of(bytes: &[u8]) -> &'static str {
    match bytes
        .get(8..12)
        .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
    {
        Some(5) => MEDIA_TYPE_V5,
        Some(6) => MEDIA_TYPE_V6,
        _ => MEDIA_TYPE,
    }
}

/// Whether a row's media type is one this build reads and writes
/// (versions 4 to 6): a row stored in another version is stale and is
/// solved again on its next request (`Jobs::result_bytes`).
pub fn is_current_media_type(media_type: Option<&str>) -> bool {
    matches!(media_type, Some(MEDIA_TYPE | MEDIA_TYPE_V5 | MEDIA_TYPE_V6))
}

#[cfg(test)]
#[test]
fn media_types_name_the_format_versions() {
    use crate::brdf::format::{OLDEST_READ_VERSION, VERSION};
    assert!(MEDIA_TYPE.ends_with(&format!("; version={OLDEST_READ_VERSION}")));
    assert!(MEDIA_TYPE_V5.ends_with("; version=5"));
    assert!(MEDIA_TYPE_V6.ends_with(&format!("; version={VERSION}")));
    for (v, media) in [(5u32, MEDIA_TYPE_V5), (6, MEDIA_TYPE_V6)] {
        let mut header = b"PBRDFTAB".to_vec();
        header.extend_from_slice(&v.to_le_bytes());
        assert_eq!(media_type_of(&header), media);
        assert!(is_current_media_type(Some(media_type_of(&header))));
    }
    assert!(!is_current_media_type(Some(
        "application/vnd.polbrdf.table; version=3"
    )));
}

/// Precision of the stored coefficients (lossless).
pub const DATA_TYPE: DataType = DataType::F64;

/// A finished solve.
#[derive(Clone, Debug)]
pub struct Solved {
    /// The result bytes.
    pub bytes: Vec<u8>,
    /// Their media type.
    pub media_type: &'static str,
    /// Wall time per wavelength (ms).
    pub wall_time_ms: Vec<f64>,
    /// Largest estimated relative error of f11 over the wavelengths
    /// (`solver::accuracy`), when the table records one.
    pub error_estimate: Option<f64>,
}

/// Why a solve failed: the spec cannot be solved at some wavelength, or the
/// solver rejected the problem. Deterministic, so final.
#[derive(Clone, Debug, PartialEq)]
pub struct SolveFailure {
    /// Whose refusal it is.
    pub kind: SolveFailureKind,
    /// JSON path in the spec, when known.
    pub path: Option<String>,
    /// What went wrong.
    pub message: String,
    /// The wavelength (nm) being solved.
    pub wavelength_nm: Option<f64>,
}

/// Solve every wavelength of a spec (one [`Table::from_spec`] per
/// wavelength, so that progress can be reported, then one table with the
/// per-wavelength streams and error estimates in its metadata);
/// `on_wavelength(done, total, ms)` is called after each wavelength and
/// `on_progress(fraction of the job)` after each batch of Fourier orders
/// (approximate, not always increasing). A `solver.tolerance` may pick up to
/// `max_streams` streams; not reaching it there is a solver failure.
pub fn solve(
    spec: &Spec,
    max_streams: usize,
    on_progress: &(dyn Fn(f64) + Sync),
    on_wavelength: &mut dyn FnMut(usize, usize, f64),
) -> Result<Solved, SolveFailure> {
    // One lowering: Mie and the expansion once per wavelength, the id once.
    let plan =
        Plan::lower_naming_wavelength(spec).map_err(|(e, wl)| failure(BrdfError::Spec(e), wl))?;
    // The default grid, or the one the spec's needs ask for.
    let grid = table::plan_grid(&plan);
    let total = plan.wavelengths.len();
    let mut built = Vec::with_capacity(total);
    let mut wall = Vec::with_capacity(total);
    for k in 0..total {
        let wl = plan.wavelengths[k].wavelength_nm;
        let t0 = Instant::now();
        let options = BuildOptions {
            max_streams,
            on_progress: &|_, _, x| on_progress((k as f64 + x) / total as f64),
        };
        let mut one =
            table::build_wavelength(&plan, k, &grid, &options).map_err(|e| failure(e, wl))?;
        if one.block.f.iter().any(|x| !x.is_finite()) {
            return Err(failure(
                BrdfError::Solver(solver::SolverError::NonFinite("BRDF coefficients".into())),
                wl,
            ));
        }
        // Timings belong to the job's row; the bytes stay deterministic.
        one.block.wall_time_ms = 0.0;
        built.push(one);
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        wall.push(ms);
        on_wavelength(k + 1, total, ms);
    }
    let error_estimate = built
        .iter()
        .filter_map(|b| b.error_estimate.as_ref().map(|e| e.max_err_f11))
        .filter(|e| e.is_finite())
        .reduce(f64::max);
    let table = Table::from_plan(&plan, grid, built).map_err(|e| failure(e, None))?;
    let bytes = format::to_bytes(&table, DATA_TYPE).map_err(|e| failure(e, None))?;
    Ok(Solved {
        media_type: media_type_of(&bytes),
        bytes,
        wall_time_ms: wall,
        error_estimate,
    })
}

/// One wavelength of a multi-wavelength request (`plan::wavelength_parts`)
/// and, when it is cached, the verified bytes of its stored result.
pub struct PartInput {
    /// The one-wavelength request.
    pub part: WavelengthPart,
    /// Its cached table bytes (in [`MEDIA_TYPE`]), or `None` to solve it.
    pub cached: Option<Vec<u8>>,
}

/// A part solved by [`solve_parts`]: a result of its own, to be stored
/// under its id.
pub struct SolvedPart {
    /// The one-wavelength request.
    pub part: WavelengthPart,
    /// Its result.
    pub solved: Solved,
}

/// What [`solve_parts`] reports as it goes.
pub struct PartSinks<'a> {
    /// Before each part is solved (the service counts per-wavelength
    /// solves with it).
    pub on_solve_start: &'a mut dyn FnMut(),
    /// As soon as a part is solved: a result of its own, kept even if a
    /// later part fails.
    pub on_part_solved: &'a mut dyn FnMut(SolvedPart),
    /// Fraction of the request done (per batch of Fourier orders).
    pub on_progress: &'a (dyn Fn(f64) + Sync),
    /// `(done, total, ms)` after each part, read or solved.
    pub on_wavelength: &'a mut dyn FnMut(usize, usize, f64),
}

/// Solve a multi-wavelength request through its one-wavelength parts:
/// cached parts are read, the others solved ([`solve`], the same bytes a
/// request for that wavelength alone stores), and the table assembled
/// ([`Table::assemble`]) under the request's canonical spec and id.
pub fn solve_parts(
    spec_canonical_json: &str,
    spec_id: &str,
    parts: Vec<PartInput>,
    max_streams: usize,
    sinks: PartSinks,
) -> Result<Solved, SolveFailure> {
    let PartSinks {
        on_solve_start,
        on_part_solved,
        on_progress,
        on_wavelength,
    } = sinks;
    let total = parts.len();
    let mut tables = Vec::with_capacity(total);
    let mut wall = Vec::with_capacity(total);
    for (k, input) in parts.into_iter().enumerate() {
        let wl = Some(input.part.wavelength_nm);
        let t0 = Instant::now();
        let bytes = match input.cached {
            Some(bytes) => bytes,
            None => {
                on_solve_start();
                let progress = |x: f64| on_progress((k as f64 + x) / total as f64);
                let s = solve(&input.part.spec, max_streams, &progress, &mut |_, _, _| {})?;
                let bytes = s.bytes.clone();
                on_part_solved(SolvedPart {
                    part: input.part,
                    solved: s,
                });
                bytes
            }
        };
        // Read back from the stored bytes (not kept from the solve): the
        // assembled table is then the same whether a part was cached or
        // solved now (the stored bytes leave the wall times out).
        tables.push(format::from_bytes(&bytes).map_err(|e| failure(e, wl))?);
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        wall.push(ms);
        on_wavelength(k + 1, total, ms);
    }
    let (bytes, error_estimate) = assemble(spec_canonical_json, spec_id, tables)?;
    Ok(Solved {
        media_type: media_type_of(&bytes),
        bytes,
        wall_time_ms: wall,
        error_estimate,
    })
}

/// The stored bytes of a request assembled from its parts' tables, and its
/// largest error estimate.
pub fn assemble(
    spec_canonical_json: &str,
    spec_id: &str,
    tables: Vec<Table>,
) -> Result<(Vec<u8>, Option<f64>), SolveFailure> {
    let spec = serde_json::from_str(spec_canonical_json)
        .map_err(|e| failure(BrdfError::Format(format!("canonical spec: {e}")), None))?;
    let table = Table::assemble(spec, spec_id, tables).map_err(|e| failure(e, None))?;
    let error_estimate = table
        .metadata
        .wavelengths
        .iter()
        .filter_map(|w| w.error_estimate.as_ref().map(|e| e.max_err_f11))
        .filter(|e| e.is_finite())
        .reduce(f64::max);
    let bytes = format::to_bytes(&table, DATA_TYPE).map_err(|e| failure(e, None))?;
    Ok((bytes, error_estimate))
}

/// Whose refusal a [`SolveFailure`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolveFailureKind {
    /// The spec (lowering, or its wavelengths).
    Spec,
    /// The solver.
    Solver,
}

fn failure(e: BrdfError, wavelength_nm: Option<f64>) -> SolveFailure {
    match e {
        BrdfError::Spec(s) => SolveFailure {
            kind: SolveFailureKind::Spec,
            path: Some(s.path),
            message: s.message,
            wavelength_nm,
        },
        BrdfError::Solver(s) => SolveFailure {
            kind: SolveFailureKind::Solver,
            path: None,
            message: s.to_string(),
            wavelength_nm,
        },
        // Duplicate wavelengths and the like.
        other => SolveFailure {
            kind: SolveFailureKind::Spec,
            path: Some("wavelengths_nm".into()),
            message: other.to_string(),
            wavelength_nm,
        },
    }
}
