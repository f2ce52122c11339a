//! What the solver refuses before solving: inputs out of range, series
//! the streams cannot integrate.

use super::*;

/// Largest normalised coefficient `|β_l|/(2l+1)` (`l ≥ 2N`) a phase
/// function without a forward peak may have beyond the quadrature's reach.
/// The aliased terms act like an error of that size in the phase function's
/// normalisation on the quadrature; measured: a conservative semi-infinite
/// HG layer (g = −0.6, 8 streams, largest term 2.8e-4) reflects 1 + 1.5e-3
/// of the incident flux, and g = −0.9 at 9 streams (0.15) gave negative
/// radiances (tests/properties.rs).
pub const UNRESOLVED_TOLERANCE: f64 = 1e-4;

/// [`SolverError::Unresolved`] for a layer whose series is longer than `2N`
/// terms, not forward-peaked (`β_1 ≤ 0`, so delta-M does not truncate it)
/// and not negligible beyond `2N − 1`.
pub fn check_resolved(i: usize, layer: &Layer, streams: usize) -> Result<(), SolverError> {
    let beta = &layer.coef.beta;
    let keep = 2 * streams;
    let forward = beta.get(1).is_some_and(|&b| b > 0.0);
    if beta.len() <= keep || forward || layer.albedo == 0.0 {
        return Ok(());
    }
    if matches!(layer.thickness, Thickness::Finite(t) if t <= 0.0) {
        return Ok(());
    }
    let chi = |l: usize| beta[l].abs() / (2 * l + 1) as f64;
    let size = (keep..beta.len()).map(chi).fold(0.0, f64::max);
    if size <= UNRESOLVED_TOLERANCE {
        return Ok(());
    }
    let last_big = (0..beta.len())
        .rev()
        .find(|&l| chi(l) > UNRESOLVED_TOLERANCE)
        .unwrap_or(0);
    Err(SolverError::Unresolved {
        layer: i,
        terms: beta.len() - 1,
        size,
        streams,
        needed: (last_big + 1).div_ceil(2),
    })
}

pub(super) fn validate(problem: &Problem, mu_user: &[f64]) -> Result<(), SolverError> {
    let s = &problem.settings;
    if s.streams == 0 {
        return Err(SolverError::Invalid("solver.streams must be ≥ 1".into()));
    }
    if problem.layers.is_empty() {
        return Err(SolverError::Invalid(
            "at least one layer is required".into(),
        ));
    }
    for (i, l) in problem.layers.iter().enumerate() {
        if !(0.0..=1.0).contains(&l.albedo) {
            return Err(SolverError::Invalid(format!(
                "layers[{i}].albedo = {} is outside [0, 1]",
                l.albedo
            )));
        }
        match l.thickness {
            Thickness::Finite(t) if !(t >= 0.0 && t.is_finite()) => {
                return Err(SolverError::Invalid(format!(
                    "layers[{i}].optical_thickness = {t} must be a finite number ≥ 0"
                )));
            }
            Thickness::Infinite if i + 1 != problem.layers.len() => {
                return Err(SolverError::Invalid(format!(
                    "layers[{i}]: only the last layer may be infinite"
                )));
            }
            _ => {}
        }
        if !s.allow_unresolved {
            check_resolved(i, l, s.streams)?;
        }
    }
    if let Some(i) = &problem.top_interface
        && !(i.index.is_finite() && i.index >= 1.0)
    {
        return Err(SolverError::Invalid(format!(
            "top_interface.index = {} must be a finite real index ≥ 1",
            i.index
        )));
    }
    if let Some(TopInterface {
        alpha: Some(alpha), ..
    }) = &problem.top_interface
    {
        if !(alpha.is_finite() && *alpha > 0.0 && *alpha <= 10.0) {
            return Err(SolverError::Invalid(format!(
                "top_interface.alpha = {alpha} must be in (0, 10]"
            )));
        }
        // No beam crosses a rough interface: the corrections that follow
        // the direct beam (delta-M's single scattering, the mirror base's
        // delta term) have nothing to act on (docs/solver.md).
        if s.delta_m {
            return Err(SolverError::Invalid(
                "delta-M truncation under a rough top interface is not supported yet".into(),
            ));
        }
        if matches!(problem.base, Base::Mirror { .. }) {
            return Err(SolverError::Invalid(
                "a mirror base under a rough top interface is not supported yet".into(),
            ));
        }
    }
    for &mu in mu_user {
        if !(mu > 0.0 && mu <= 1.0) {
            return Err(SolverError::Invalid(format!(
                "direction cosine {mu} is outside (0, 1]"
            )));
        }
    }
    Ok(())
}
