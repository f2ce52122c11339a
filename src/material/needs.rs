//! What a request needs of its result (docs/spec.md, "needs"): the part of
//! the full product a scene uses, so that the work and the stored result
//! can be smaller. A spec is a physical material plus its needs; the needs
//! at their defaults are the full product (every Fourier order on the
//! default 64-node grid, with the solver's error estimate) and stay out of
//! the canonical form, so a spec without `needs` keeps its id
//! (docs/service.md, "Ids and versions").
//!
//! Implemented here: `error_estimate` (skips the estimate's extra solves)
//! and `grid` (fewer polar nodes and Fourier orders). The issue's other
//! needs (`stokes`, `theta_i_deg`) are not accepted yet: an unknown field
//! is refused at parse time, never silently ignored.

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
    pub fn validate(&self, tolerance: Option<f64>) -> Result<(), SpecError> {
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
    fn ranges_and_the_tolerance_rule_are_refused_with_their_path() {
        let bad = |json: &str, tol: Option<f64>| {
            serde_json::from_str::<Needs>(json)
                .unwrap()
                .validate(tol)
                .unwrap_err()
        };
        let e = bad(r#"{"error_estimate":false}"#, Some(1e-4));
        assert_eq!(e.path, "needs.error_estimate");
        let e = bad(r#"{"grid":{"polar_nodes":5}}"#, None);
        assert_eq!(e.path, "needs.grid.polar_nodes");
        assert!(e.message.contains("[6, 256]"), "{}", e.message);
        let e = bad(r#"{"grid":{"max_fourier_orders":0}}"#, None);
        assert_eq!(e.path, "needs.grid.max_fourier_orders");
        // Unknown needs (not implemented) are refused, never ignored.
        assert!(serde_json::from_str::<Needs>(r#"{"stokes":"intensity"}"#).is_err());
    }
}
