//! `polbrdf._native`: the Rust half of the Python package (docs/python.md).
//!
//! Thin wrappers over the service crate, so that Python answers what the
//! command line and the service answer: `polbrdf mie` ([`mie`]),
//! `polbrdf solve --points` ([`solve_points`]), table builds, reads and
//! fetches through the render-node cache ([`build_table`], [`load_table`])
//! and the table's point evaluation ([`NativeTable::eval_flat`]). Shapes,
//! broadcasting and docstrings live in the Python layer (`polbrdf/`); here
//! everything is flat: `n` direction pairs, `(n, 3)` unit vectors, `(n, 4, 4)`
//! Mueller matrices. Solves and evaluations release the GIL.
//!
//! Errors become exceptions of the classes below; a spec error carries the
//! JSON path of the offending field as `path` (docs/spec.md).

mod table;

use clap::{Args, FromArgMatches};
use numpy::{PyReadonlyArray2, PyUntypedArrayMethods};
use polbrdf::brdf::{BrdfError, Table, table::BuildOptions};
use polbrdf::cli;
use polbrdf::fetch::{self, FetchOptions};
use polbrdf::material::{self, Spec, SpecError as RustSpecError};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use std::path::Path;
use std::time::Duration;
pub use table::NativeTable;

create_exception!(
    _native,
    PolbrdfError,
    PyException,
    "Base class of polbrdf's errors."
);
create_exception!(
    _native,
    SpecError,
    PolbrdfError,
    "A material spec is invalid; `path` names the field (e.g. `layers[0].scatterer.mie.radius_um`) and `message` what is wrong."
);
create_exception!(
    _native,
    QueryError,
    PolbrdfError,
    "A query (directions, wavelength) is outside what a table answers."
);
create_exception!(
    _native,
    FetchError,
    PolbrdfError,
    "A table could not be read from a file or fetched from a service."
);

/// A Python `SpecError` with `path` and `message` set.
fn spec_error(py: Python<'_>, e: &RustSpecError) -> PyErr {
    let err = SpecError::new_err(e.to_string());
    let value = err.value(py);
    // Setting attributes on a fresh exception instance cannot fail.
    let _ = value.setattr("path", e.path.clone());
    let _ = value.setattr("message", e.message.clone());
    err
}

/// The exception of a table error.
pub(crate) fn brdf_error(py: Python<'_>, e: BrdfError) -> PyErr {
    match e {
        BrdfError::Spec(s) => spec_error(py, &s),
        BrdfError::Query(q) => QueryError::new_err(q),
        BrdfError::Format(_) | BrdfError::Io { .. } => FetchError::new_err(e.to_string()),
        BrdfError::Solver(_) => PolbrdfError::new_err(e.to_string()),
    }
}

/// Parse a spec (JSON text) and refuse what `polbrdf solve` would refuse
/// before solving: more streams than `max_streams`, or a problem the
/// solver cannot take (docs/spec.md).
fn checked_spec(py: Python<'_>, text: &str, max_streams: usize) -> PyResult<Spec> {
    let spec = material::parse(text).map_err(|e| spec_error(py, &e))?;
    cli::solve::check(&spec, max_streams).map_err(|e| spec_error(py, &e))?;
    Ok(spec)
}

/// The default stream cap of `polbrdf solve --max-streams` (the service's).
#[pyfunction]
fn default_max_streams() -> usize {
    cli::solve::default_max_streams()
}

/// `polbrdf mie` with these command-line arguments (without the program
/// name, e.g. `["--material", "TiO2", "--wavelength-nm", "550",
/// "--radius-um", "0.2"]`): its JSON document as text.
#[pyfunction]
fn mie(py: Python<'_>, args: Vec<String>) -> PyResult<String> {
    let cmd = cli::mie::MieArgs::augment_args(
        clap::Command::new("polbrdf.mie")
            .no_binary_name(true)
            .disable_help_flag(true),
    );
    let matches = cmd
        .try_get_matches_from(args)
        .map_err(|e| PolbrdfError::new_err(e.render().to_string().trim().to_string()))?;
    let a = cli::mie::MieArgs::from_arg_matches(&matches)
        .map_err(|e| PolbrdfError::new_err(e.to_string()))?;
    let doc = py
        .detach(|| cli::mie::run(&a))
        .map_err(PolbrdfError::new_err)?;
    Ok(doc.to_string())
}

/// Check a spec (JSON text) as `polbrdf solve` does before solving.
#[pyfunction]
fn check_spec(py: Python<'_>, spec_json: &str, max_streams: usize) -> PyResult<()> {
    checked_spec(py, spec_json, max_streams).map(|_| ())
}

/// `polbrdf solve SPEC --points P`: the document (JSON text) for direction
/// pairs `points` of shape `(n, 4)`, columns `theta_i_deg, phi_i_deg,
/// theta_o_deg, phi_o_deg`.
#[pyfunction]
fn solve_points(
    py: Python<'_>,
    spec_json: &str,
    points: PyReadonlyArray2<'_, f64>,
    max_streams: usize,
) -> PyResult<String> {
    let spec = checked_spec(py, spec_json, max_streams)?;
    if points.shape()[1] != 4 {
        return Err(QueryError::new_err(format!(
            "points must have shape (n, 4) (theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg), got {:?}",
            points.shape()
        )));
    }
    let p = points.as_array();
    let pts: Vec<cli::solve::Point> = p
        .rows()
        .into_iter()
        .map(|r| cli::solve::Point {
            theta_i_deg: r[0],
            phi_i_deg: r[1],
            theta_o_deg: r[2],
            phi_o_deg: r[3],
        })
        .collect();
    for (k, q) in pts.iter().enumerate() {
        let d = polbrdf::brdf::Directions {
            theta_i_deg: q.theta_i_deg,
            phi_i_deg: q.phi_i_deg,
            theta_o_deg: q.theta_o_deg,
            phi_o_deg: q.phi_o_deg,
        };
        d.validate()
            .map_err(|e| QueryError::new_err(format!("points[{k}]: {e}")))?;
    }
    let doc = py
        .detach(|| cli::solve::points_document(&spec, "spec", &pts, max_streams))
        .map_err(PolbrdfError::new_err)?;
    Ok(doc.to_string())
}

/// The table a spec requests (on the grid of its `needs`), as the service
/// builds it.
#[pyfunction]
fn build_table(py: Python<'_>, spec_json: &str, max_streams: usize) -> PyResult<NativeTable> {
    let spec = checked_spec(py, spec_json, max_streams)?;
    let options = BuildOptions {
        max_streams,
        ..BuildOptions::default()
    };
    let table = py
        .detach(|| Table::from_spec_needs(&spec, &options))
        .map_err(|e| brdf_error(py, e))?;
    Ok(NativeTable::new(table))
}

/// A table from a file, or from a service result URL
/// (`http://HOST/v1/brdfs/ID`): through the render-node cache `cache_dir`
/// when one is given (docs/deploy.md, Render nodes), else downloaded and
/// verified. `wait_s` polls a queued or running job that long;
/// `revalidate` asks the service about a cached copy.
#[pyfunction]
#[pyo3(signature = (source, cache_dir=None, token=None, revalidate=false, wait_s=None))]
fn load_table(
    py: Python<'_>,
    source: &str,
    cache_dir: Option<String>,
    token: Option<String>,
    revalidate: bool,
    wait_s: Option<f64>,
) -> PyResult<(NativeTable, Option<String>)> {
    let is_url = cli::source::table_url(source).is_some();
    if !is_url {
        let table = py
            .detach(|| polbrdf::brdf::format::read_file(source))
            .map_err(|e| brdf_error(py, e))?;
        return Ok((NativeTable::new(table), None));
    }
    let wait = match wait_s {
        Some(s) if !(s.is_finite() && s >= 0.0) => {
            return Err(QueryError::new_err(format!("wait_s = {s} must be >= 0")));
        }
        Some(s) => Some(Duration::from_secs_f64(s)),
        None => None,
    };
    let fetched = py.detach(|| match cache_dir {
        Some(dir) => {
            let options = FetchOptions {
                revalidate,
                wait,
                token,
            };
            fetch::fetch(source, Path::new(&dir), &options)
                .map(|f| (f.table, Some(f.outcome.name().to_string())))
        }
        None => fetch::download(source, token.as_deref()).map(|t| (t, None)),
    });
    let (table, outcome) = fetched.map_err(|e| FetchError::new_err(e.to_string()))?;
    Ok((NativeTable::new(table), outcome))
}

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("PolbrdfError", py.get_type::<PolbrdfError>())?;
    m.add("SpecError", py.get_type::<SpecError>())?;
    m.add("QueryError", py.get_type::<QueryError>())?;
    m.add("FetchError", py.get_type::<FetchError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(default_max_streams, m)?)?;
    m.add_function(wrap_pyfunction!(mie, m)?)?;
    m.add_function(wrap_pyfunction!(check_spec, m)?)?;
    m.add_function(wrap_pyfunction!(solve_points, m)?)?;
    m.add_function(wrap_pyfunction!(build_table, m)?)?;
    m.add_function(wrap_pyfunction!(load_table, m)?)?;
    m.add_class::<NativeTable>()?;
    Ok(())
}
