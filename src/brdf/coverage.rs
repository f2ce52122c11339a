//! The part of the full table a request needs (docs/spec.md, `needs.stokes`
//! and `needs.theta_i_deg`; docs/table-format.md): which Mueller elements
//! and which incident nodes are synthesized and stored, and which queries
//! a reduced table can answer.
//!
//! **Incident nodes.** A table evaluates at `θ_i` through the grid's 1-D
//! Lagrange stencil (`PolarGrid::stencil`, (T2) of docs/table-format.md).
//! It keeps exactly the nodes those stencils touch with a non-zero weight:
//! for a range `[min, max]` every node of every stencil inside it (the
//! stencil start is non-decreasing in θ, so from the first node of
//! `stencil(min)` to the last of `stencil(max)`: the range's nodes plus the
//! stencil margin); for a list of angles the nodes of each angle's
//! stencil (one node for an angle on a node, whose weights are exactly
//! `(…, 0, 1, 0, …)`). The interpolation inside the coverage is therefore
//! the full table's, weight for weight: a reduced table equals the full
//! one there up to round-off, and nothing is extrapolated outside it.

use super::BrdfError;
use super::grid::PolarGrid;
use super::table::Table;
use crate::material::needs::{IncidentNeed, StokesNeed};
use crate::physics::stokes::Mueller;
use crate::solver::ReflectionFourier;

/// How close (degrees) a query's `θ_i` must be to a listed angle of
/// `needs.theta_i_deg` to be evaluated there: far above the rounding of a
/// decimal angle, far below any physical resolution.
pub const ANGLE_TOLERANCE_DEG: f64 = 1e-9;

/// The grid nodes a table holds on the incident axis (module doc):
/// increasing, every node without a need.
pub fn incident_nodes(grid: &PolarGrid, need: Option<&IncidentNeed>) -> Vec<usize> {
    let n = grid.len();
    let Some(need) = need else {
        return (0..n).collect();
    };
    let mut held = vec![false; n];
    let mut touch = |theta_deg: f64, all: bool| {
        let st = grid.stencil(theta_deg);
        for k in 0..st.len {
            if all || st.w[k] != 0.0 {
                held[st.start + k] = true;
            }
        }
    };
    match need {
        IncidentNeed::Angles(a) => a.iter().for_each(|&t| touch(t, false)),
        IncidentNeed::Range(r) => {
            touch(r.min, true);
            touch(r.max, true);
            let (lo, hi) = (
                grid.stencil(r.min).start,
                grid.stencil(r.max).start + grid.stencil(r.max).len,
            );
            held[lo..hi].iter_mut().for_each(|h| *h = true);
        }
    }
    (0..n).filter(|&i| held[i]).collect()
}

/// The incident polar angle a query's `theta_i_deg` is evaluated at: the
/// query's own inside a range (or without a need), the listed angle within
/// [`ANGLE_TOLERANCE_DEG`] of it for a list; else a query error starting
/// `theta_i_deg = …` (so the service's 422 names the field) that names
/// the need.
pub fn incident_theta(need: Option<&IncidentNeed>, theta_i_deg: f64) -> Result<f64, BrdfError> {
    match need {
        None => Ok(theta_i_deg),
        Some(IncidentNeed::Range(r)) if (r.min..=r.max).contains(&theta_i_deg) => Ok(theta_i_deg),
        Some(IncidentNeed::Angles(a)) => a
            .iter()
            .copied()
            .find(|&x| (x - theta_i_deg).abs() <= ANGLE_TOLERANCE_DEG)
            .ok_or_else(|| outside(need, theta_i_deg)),
        Some(IncidentNeed::Range(_)) => Err(outside(need, theta_i_deg)),
    }
}

fn outside(need: Option<&IncidentNeed>, theta_i_deg: f64) -> BrdfError {
    let held = match need {
        Some(IncidentNeed::Angles(a)) => format!(
            "the angles [{}] only",
            a.iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
        Some(IncidentNeed::Range(r)) => format!("[{}, {}]", r.min, r.max),
        None => "every angle".into(),
    };
    BrdfError::Query(format!(
        "theta_i_deg = {theta_i_deg} is outside the incident angles this result holds \
         (needs.theta_i_deg: {held}); it is never extrapolated: submit a spec whose \
         needs.theta_i_deg covers it"
    ))
}

/// `f^m = ρ^m / μ_i` (T0 of docs/table-format.md) for the first `rows`
/// outgoing and `cols` incident Stokes components at the incident grid
/// nodes `incident`: element `(p, q)` of order `m`, outgoing node `o` and
/// the `k`-th held incident node at `(((m·N + o)·K + k)·rows + p)·cols + q`.
/// Only what is stored is computed.
pub fn synthesize(
    refl: &ReflectionFourier,
    grid: &PolarGrid,
    rows: usize,
    cols: usize,
    incident: &[usize],
) -> Vec<f64> {
    let ns = refl.ns;
    let (n, kn) = (grid.len(), incident.len());
    let mut f = vec![0.0; refl.rho.len() * n * kn * rows * cols];
    for (m, rho) in refl.rho.iter().enumerate() {
        for o in 0..n {
            for (k, &i) in incident.iter().enumerate() {
                let inv = 1.0 / grid.mu[i];
                let base = ((m * n + o) * kn + k) * rows * cols;
                for p in 0..rows {
                    for q in 0..cols {
                        f[base + p * cols + q] = rho[(o * ns + p, i * ns + q)] * inv;
                    }
                }
            }
        }
    }
    f
}

/// `m` with the elements outside the first `rows × cols` set to zero.
pub fn keep(m: &Mueller, rows: usize, cols: usize) -> Mueller {
    let mut out = [[0.0; 4]; 4];
    for p in 0..rows {
        out[p][..cols].copy_from_slice(&m[p][..cols]);
    }
    out
}

/// The first `rows × cols` elements of `m` as nested rows (the shape the
/// API and the CLI answer a reduced table with: `[[m00], [m10], [m20],
/// [m30]]` for column 0, `[[m00]]` for f11).
pub fn nested(m: &Mueller, (rows, cols): (usize, usize)) -> Vec<Vec<f64>> {
    m.iter().take(rows).map(|r| r[..cols].to_vec()).collect()
}

/// The names `mPQ` of the elements of a `rows × cols` shape, row-major.
pub fn element_names((rows, cols): (usize, usize)) -> Vec<String> {
    (0..rows)
        .flat_map(|p| (0..cols).map(move |q| format!("m{p}{q}")))
        .collect()
}

/// What a table lacks of the full product, in words naming the needs; `None`
/// for a complete table.
pub fn lacks(table: &Table) -> Option<String> {
    let stokes = match table.metadata.stokes {
        StokesNeed::Full => None,
        StokesNeed::UnpolarizedIn => Some(
            "the Mueller columns 1-3 (it holds column 0 only: needs.stokes = \"unpolarized_in\")"
                .to_string(),
        ),
        StokesNeed::Intensity => {
            Some("every element but m00 (it holds f11 only: needs.stokes = \"intensity\")".into())
        }
    };
    let incident = table.metadata.theta_i_deg.as_ref().map(|need| {
        let held = match need {
            IncidentNeed::Angles(a) => format!("{a:?}"),
            IncidentNeed::Range(r) => format!("[{}, {}]", r.min, r.max),
        };
        format!("incident angles outside needs.theta_i_deg = {held}")
    });
    match (stokes, incident) {
        (None, None) => None,
        (Some(a), None) | (None, Some(a)) => Some(a),
        (Some(a), Some(b)) => Some(format!("{a} and {b}")),
    }
}

/// A query error unless the table is the full product (every element at
/// every incident direction), for uses that need all of it (`what`: e.g.
/// "the Mitsuba export").
pub fn require_complete(table: &Table, what: &str) -> Result<(), BrdfError> {
    match lacks(table) {
        None => Ok(()),
        Some(missing) => Err(BrdfError::Query(format!(
            "{what} needs the full 4x4 matrix at every incident direction, and this result \
             lacks {missing}: submit the spec without these needs"
        ))),
    }
}

/// A query error unless the table holds the Mueller column of every
/// incident Stokes component that `stokes_in` (I, Q, U, V) excites: an
/// `"unpolarized_in"` table answers unpolarized light only, an
/// `"intensity"` table f11 of unpolarized light. `path` names the field.
pub fn require_stokes_in(table: &Table, stokes_in: &[f64; 4], path: &str) -> Result<(), BrdfError> {
    let polarized = stokes_in[1..].iter().any(|&x| x != 0.0);
    match table.metadata.stokes {
        StokesNeed::Full => Ok(()),
        s if polarized => Err(BrdfError::Query(format!(
            "{path} = {stokes_in:?} is polarized, and this result holds only the response to \
             unpolarized light (needs.stokes = \"{}\": Mueller column 0{}); submit the spec \
             without needs.stokes",
            s.name(),
            if s == StokesNeed::Intensity {
                ", f11 only"
            } else {
                ""
            }
        ))),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::needs::IncidentRange;

    #[test]
    fn ranges_keep_the_stencil_margin_and_angles_only_their_weights() {
        let g = PolarGrid::graded(64).unwrap();
        assert_eq!(incident_nodes(&g, None).len(), 64);
        // An angle on a node keeps that node only; 0 is node 0.
        let on = incident_nodes(&g, Some(&IncidentNeed::Angles(vec![0.0, g.theta_deg[20]])));
        assert_eq!(on, vec![0, 20]);
        // Between nodes: the 6 of its stencil.
        let off = incident_nodes(&g, Some(&IncidentNeed::Angles(vec![30.0])));
        assert_eq!(off.len(), 6);
        let st = g.stencil(30.0);
        assert_eq!(off, (st.start..st.start + 6).collect::<Vec<_>>());
        // A range: every stencil inside it is held.
        let r = IncidentNeed::Range(IncidentRange {
            min: 20.0,
            max: 40.0,
        });
        let held = incident_nodes(&g, Some(&r));
        for k in 0..=200 {
            let t = 20.0 + 0.1 * k as f64;
            let st = g.stencil(t);
            for j in st.start..st.start + st.len {
                assert!(held.contains(&j), "{t}: node {j}");
            }
        }
        assert!(held.len() < 64 / 2, "{}", held.len());
    }

    #[test]
    fn queries_outside_the_coverage_are_refused_naming_the_field() {
        let a = IncidentNeed::Angles(vec![0.0, 30.0, 60.0]);
        assert_eq!(incident_theta(Some(&a), 30.0 + 1e-12).unwrap(), 30.0);
        let e = incident_theta(Some(&a), 31.0).unwrap_err().to_string();
        assert!(e.starts_with("theta_i_deg = 31 "), "{e}");
        assert!(e.contains("needs.theta_i_deg"), "{e}");
        let r = IncidentNeed::Range(IncidentRange {
            min: 10.0,
            max: 20.0,
        });
        assert_eq!(incident_theta(Some(&r), 15.5).unwrap(), 15.5);
        assert!(incident_theta(Some(&r), 20.01).is_err());
        assert!(incident_theta(Some(&r), 9.99).is_err());
        assert_eq!(incident_theta(None, 89.0).unwrap(), 89.0);
    }

    #[test]
    fn shapes_and_names() {
        let m: Mueller = [[1.0, 2.0, 3.0, 4.0]; 4];
        assert_eq!(nested(&m, (4, 1)), vec![vec![1.0]; 4]);
        assert_eq!(nested(&m, (1, 1)), vec![vec![1.0]]);
        assert_eq!(element_names((4, 1)), ["m00", "m10", "m20", "m30"]);
        assert_eq!(keep(&m, 1, 1)[0], [1.0, 0.0, 0.0, 0.0]);
        assert_eq!(keep(&m, 1, 1)[1], [0.0; 4]);
    }
}
