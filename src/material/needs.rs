//! What a request needs of its result (docs/spec.md, "needs"): the part of
//! the full product a scene uses, so that the work and the stored result
//! can be smaller. A spec is a physical material plus its needs; the needs
//! at their defaults are the full product (every Fourier order on the
//! default 64-node grid, with the solver's error estimate) and stay out of
//! the canonical form, so a spec without `needs` keeps its id
//! (docs/service.md, "Ids and versions").
//!
//! Implemented here: `error_estimate` (skips the estimate's extra solves),
//! `grid` (fewer polar nodes and Fourier orders), `stokes` (part of the
//! Mueller matrix: column 0, or f11 alone) and `theta_i_deg` (part of the
//! incident directions). An unknown field is refused at parse time, never
//! silently ignored.

use super::SpecError;
use serde::{Deserialize, Serialize};

/// Polar nodes of the default table grid (`brdf::grid::DEFAULT_NODES`).
pub const DEFAULT_POLAR_NODES: usize = 64;

/// Fewest polar nodes a table may have: the 6-node interpolation stencil
/// (`brdf::grid::STENCIL`) needs 6 nodes to be of full degree.
pub const MIN_POLAR_NODES: usize = 6;

/// Most polar nodes a table may have (the solve's user directions grow
/// with them: 256 nodes is 16× the default table).
pub const MAX_POLAR_NODES: usize = 256;

/// What a request needs of its result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Needs {
    /// `false` skips the error estimate's extra solves (at `N/2` and
    /// `3N/4` streams, `solver::accuracy`); the result then states no
    /// estimate. Needed (refused as `false`) with `solver.tolerance`.
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub error_estimate: bool,
    /// The table grid; absent: the default grid with every Fourier order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid: Option<GridNeed>,
    /// Which Mueller elements the result holds; absent: all 16.
    #[serde(default, skip_serializing_if = "StokesNeed::is_full")]
    pub stokes: StokesNeed,
    /// The incident polar angles the scene uses; absent: all of `[0, 90]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub theta_i_deg: Option<IncidentNeed>,
}

/// Which elements of the 4×4 Mueller BRDF a request needs (docs/spec.md,
/// `needs.stokes`; rows = outgoing, columns = incident Stokes component,
/// conventions §6).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StokesNeed {
    /// All 16 elements.
    #[default]
    Full,
    /// Column 0 (`m00, m10, m20, m30`): the polarized response to
    /// unpolarized incident light.
    UnpolarizedIn,
    /// `m00` (f11) alone, still from the vector solution unless
    /// `solver.polarized` is false.
    Intensity,
}

impl StokesNeed {
    /// The full matrix (the default, kept out of the canonical form)?
    pub fn is_full(&self) -> bool {
        *self == StokesNeed::Full
    }

    /// The spelling in the spec and the table metadata.
    pub fn name(self) -> &'static str {
        match self {
            StokesNeed::Full => "full",
            StokesNeed::UnpolarizedIn => "unpolarized_in",
            StokesNeed::Intensity => "intensity",
        }
    }

    /// Rows and columns stored of a solve with `ns` Stokes components
    /// (4, or 1 for a scalar solve, which has f11 only whatever is asked).
    pub fn shape(self, ns: usize) -> (usize, usize) {
        match self {
            StokesNeed::Full => (ns, ns),
            StokesNeed::UnpolarizedIn => (ns, 1),
            StokesNeed::Intensity => (1, 1),
        }
    }
}

/// Most incident angles `needs.theta_i_deg` may list.
pub const MAX_INCIDENT_ANGLES: usize = 256;

/// The incident polar angles a request needs (degrees, graphics
/// convention, conventions §5): a list, or a closed range.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum IncidentNeed {
    /// These angles only (evaluated exactly there, never between them).
    Angles(Vec<f64>),
    /// Every angle in `[min, max]`.
    Range(IncidentRange),
}

/// A closed range of incident polar angles (degrees).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IncidentRange {
    /// Smallest incident polar angle, `[0, 90)`.
    pub min: f64,
    /// Largest incident polar angle, `[min, 90)`.
    pub max: f64,
}

impl IncidentNeed {
    /// Equivalent spellings unified: angles sorted, duplicates and the
    /// sign of zero dropped.
    pub fn normalized(&self) -> Self {
        match self {
            IncidentNeed::Angles(a) => {
                let mut a: Vec<f64> = a.iter().map(|&x| if x == 0.0 { 0.0 } else { x }).collect();
                a.sort_by(f64::total_cmp);
                a.dedup();
                IncidentNeed::Angles(a)
            }
            IncidentNeed::Range(r) => IncidentNeed::Range(IncidentRange {
                min: if r.min == 0.0 { 0.0 } else { r.min },
                max: r.max,
            }),
        }
    }

    /// Ranges: finite, `0 ≤ θ < 90`, `min ≤ max`, a non-empty list of at
    /// most [`MAX_INCIDENT_ANGLES`] (90° itself is grazing incidence,
    /// which carries no irradiance: `E = F cos θ_i = 0`).
    pub fn validate(&self) -> Result<(), SpecError> {
        let angle = |path: String, v: f64| {
            if v.is_finite() && (0.0..90.0).contains(&v) {
                Ok(())
            } else {
                Err(SpecError::new(
                    path,
                    format!("{v} is outside the allowed range [0, 90) degrees"),
                ))
            }
        };
        match self {
            IncidentNeed::Angles(a) => {
                if a.is_empty() || a.len() > MAX_INCIDENT_ANGLES {
                    return Err(SpecError::new(
                        "needs.theta_i_deg",
                        format!(
                            "{} angles: give 1 to {MAX_INCIDENT_ANGLES} (or a range {{\"min\", \"max\"}})",
                            a.len()
                        ),
                    ));
                }
                for (k, &x) in a.iter().enumerate() {
                    angle(format!("needs.theta_i_deg[{k}]"), x)?;
                }
            }
            IncidentNeed::Range(r) => {
                angle("needs.theta_i_deg.min".into(), r.min)?;
                angle("needs.theta_i_deg.max".into(), r.max)?;
                if r.min > r.max {
                    return Err(SpecError::new(
                        "needs.theta_i_deg.max",
                        format!("{} is below min = {}: the range is empty", r.max, r.min),
                    ));
                }
            }
        }
        Ok(())
    }
}

impl Default for Needs {
    fn default() -> Self {
        Self::full()
    }
}

impl Default for GridNeed {
    fn default() -> Self {
        Self {
            polar_nodes: DEFAULT_POLAR_NODES,
            max_fourier_orders: None,
        }
    }
}

/// The table grid a request needs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridNeed {
    /// Polar nodes of the table, shared by incident and outgoing
    /// directions (`brdf::PolarGrid::graded`): in
    /// `[MIN_POLAR_NODES, MAX_POLAR_NODES]`, default 64.
    #[serde(default = "default_polar_nodes")]
    pub polar_nodes: usize,
    /// Most Fourier azimuth orders synthesized (`m = 0..max_fourier_orders`);
    /// absent: until the series converges (`solver::Settings::fourier_tolerance`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_fourier_orders: Option<usize>,
}

fn default_polar_nodes() -> usize {
    DEFAULT_POLAR_NODES
}

fn yes() -> bool {
    true
}

fn is_true(x: &bool) -> bool {
    *x
}

impl Needs {
    /// The full product: what a spec without `needs` asks for.
    pub fn full() -> Self {
        Self {
            error_estimate: true,
            grid: None,
            stokes: StokesNeed::Full,
            theta_i_deg: None,
        }
    }

    /// Is this the full product (then `needs` stays out of the canonical
    /// form)?
    pub fn is_full(&self) -> bool {
        self.normalized() == Self::full()
    }

    /// Equivalent spellings unified: a grid equal to the default grid with
    /// every order is no grid need at all.
    pub fn normalized(&self) -> Self {
        let grid = self.grid.clone().filter(|g| *g != GridNeed::default());
        Self {
            error_estimate: self.error_estimate,
            grid,
            stokes: self.stokes,
            theta_i_deg: self.theta_i_deg.as_ref().map(IncidentNeed::normalized),
        }
    }

    /// Polar nodes of the table.
    pub fn polar_nodes(&self) -> usize {
        self.grid
            .as_ref()
            .map_or(DEFAULT_POLAR_NODES, |g| g.polar_nodes)
    }

    /// Highest Fourier order to synthesize (`solver::Settings::max_order`).
    pub fn max_order(&self) -> Option<usize> {
        self.grid
            .as_ref()
            .and_then(|g| g.max_fourier_orders)
            .map(|m| m - 1)
    }

    /// The needs' own ranges, and the one rule across fields: a
    /// `solver.tolerance` is met by the estimate, so it needs one.
    pub fn validate(&self, tolerance: Option<f64>, polarized: bool) -> Result<(), SpecError> {
        if !polarized && self.stokes == StokesNeed::UnpolarizedIn {
            return Err(SpecError::new(
                "needs.stokes",
                "\"unpolarized_in\" needs the vector solution, but solver.polarized is false: \
                 a scalar solve has f11 only (ask for \"intensity\", or solve polarized)",
            ));
        }
        if let Some(t) = &self.theta_i_deg {
            t.validate()?;
        }
        if !self.error_estimate && tolerance.is_some() {
            return Err(SpecError::new(
                "needs.error_estimate",
                "false is refused with solver.tolerance: a tolerance is met through the error \
                 estimate (give solver.streams instead, or leave error_estimate out)",
            ));
        }
        if let Some(g) = &self.grid {
            if !(MIN_POLAR_NODES..=MAX_POLAR_NODES).contains(&g.polar_nodes) {
                return Err(SpecError::new(
                    "needs.grid.polar_nodes",
                    format!(
                        "{} is outside the allowed range [{MIN_POLAR_NODES}, {MAX_POLAR_NODES}]",
                        g.polar_nodes
                    ),
                ));
            }
            if let Some(m) = g.max_fourier_orders
                && m == 0
            {
                return Err(SpecError::new(
                    "needs.grid.max_fourier_orders",
                    "0 is outside the allowed range [1, ∞) (1 keeps the azimuthal mean only)",
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_grid_is_no_grid_need() {
        let n: Needs = serde_json::from_str(r#"{"grid":{"polar_nodes":64}}"#).unwrap();
        assert!(n.is_full());
        let n: Needs = serde_json::from_str(r#"{"error_estimate":true}"#).unwrap();
        assert!(n.is_full());
        let n: Needs = serde_json::from_str(r#"{"grid":{"polar_nodes":32}}"#).unwrap();
        assert!(!n.is_full());
        assert_eq!(n.polar_nodes(), 32);
        assert_eq!(n.max_order(), None);
        let n: Needs = serde_json::from_str(r#"{"grid":{"max_fourier_orders":3}}"#).unwrap();
        assert_eq!((n.polar_nodes(), n.max_order()), (64, Some(2)));
    }

    #[test]
    fn full_stokes_and_sorted_angles_are_normal_forms() {
        let n: Needs = serde_json::from_str(r#"{"stokes":"full"}"#).unwrap();
        assert!(n.is_full());
        let a: Needs = serde_json::from_str(r#"{"theta_i_deg":[60, 0, 30, 30]}"#).unwrap();
        let b: Needs = serde_json::from_str(r#"{"theta_i_deg":[-0.0, 30, 60]}"#).unwrap();
        assert_eq!(a.normalized(), b.normalized());
        assert!(!a.is_full());
        let n: Needs = serde_json::from_str(r#"{"stokes":"intensity"}"#).unwrap();
        assert_eq!(n.stokes.shape(4), (1, 1));
        assert_eq!(StokesNeed::UnpolarizedIn.shape(4), (4, 1));
        assert_eq!(StokesNeed::Full.shape(1), (1, 1));
    }

    #[test]
    fn ranges_and_the_tolerance_rule_are_refused_with_their_path() {
        let bad = |json: &str, tol: Option<f64>| {
            serde_json::from_str::<Needs>(json)
                .unwrap()
                .validate(tol, true)
                .unwrap_err()
        };
        let e = bad(r#"{"error_estimate":false}"#, Some(1e-4));
        assert_eq!(e.path, "needs.error_estimate");
        let e = bad(r#"{"grid":{"polar_nodes":5}}"#, None);
        assert_eq!(e.path, "needs.grid.polar_nodes");
        assert!(e.message.contains("[6, 256]"), "{}", e.message);
        let e = bad(r#"{"grid":{"max_fourier_orders":0}}"#, None);
        assert_eq!(e.path, "needs.grid.max_fourier_orders");
        let e = bad(r#"{"theta_i_deg":[10, 90]}"#, None);
        assert_eq!(e.path, "needs.theta_i_deg[1]");
        let e = bad(r#"{"theta_i_deg":[]}"#, None);
        assert_eq!(e.path, "needs.theta_i_deg");
        let e = bad(r#"{"theta_i_deg":{"min":-1,"max":10}}"#, None);
        assert_eq!(e.path, "needs.theta_i_deg.min");
        let e = bad(r#"{"theta_i_deg":{"min":40,"max":30}}"#, None);
        assert_eq!(e.path, "needs.theta_i_deg.max");
        let e = serde_json::from_str::<Needs>(r#"{"stokes":"unpolarized_in"}"#)
            .unwrap()
            .validate(None, false)
            .unwrap_err();
        assert_eq!(e.path, "needs.stokes");
        // Unknown needs and values are refused, never ignored.
        assert!(serde_json::from_str::<Needs>(r#"{"stokes":"linear"}"#).is_err());
        assert!(serde_json::from_str::<Needs>(r#"{"theta_o_deg":[10]}"#).is_err());
        assert!(serde_json::from_str::<Needs>(r#"{"theta_i_deg":{"min":1}}"#).is_err());
    }
}
