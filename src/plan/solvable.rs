//! The cheap checks before any solve: what the physics and the solver
//! would refuse that the spec alone decides (used by the service at
//! submission and by `polbrdf solve` before solving). They lower the
//! non-Mie layers and the base, hence live with the lowering.

use super::mie::{host_path, populations};
use super::{StreamPolicy, layer_optics, stream_policy, surface_indices, wavelengths};
use crate::material::{
    LayerForm, MaterialSpec, MieSpec, ScattererSpec, Spec, SpecError, ThicknessSpec,
};
use crate::physics::RefractiveIndex;
use crate::solver::{self, Layer, SolverError, Thickness};

/// Everything the solver and the physics would refuse at solve time that
/// the spec alone decides, checked cheaply before any solve (the service at
/// `POST /v1/brdfs`, `polbrdf solve` before solving): the first refusal, as
/// a [`SpecError`] naming the field to change and what would work.
///
/// * every named material has refractive-index data at every wavelength
///   (path `wavelengths_nm[k]`);
/// * Mie inputs (a Mie scatterer, each pigment of a film) are inside the
///   validated range of `physics::mie`: a host (binder) of real index ≥ 1,
///   the relative index `m = n_particle/n_host` at every wavelength and,
///   for monodisperse spheres, the size parameter `2π r n_host/λ`;
/// * a Fresnel base's indices are accepted by `physics::fresnel`;
/// * a phase function that is not forward-peaked and longer than the
///   streams can integrate ([`solver::check_resolved`]) is refused, naming
///   the streams it needs: at `solver.streams` (or the default) for fixed
///   streams; for a `solver.tolerance`, at the most streams a tolerance
///   may pick (`max_streams`, rounded down to a level of
///   `solver::accuracy::tolerance_ladder`), and a
///   tolerance needs `max_streams ≥ 4` at all.
///
/// Only Rayleigh, Henyey–Greenstein and expansion layers get the last
/// check: the series of a Mie layer is known only after its Mie solve and
/// expansion, so the solver keeps refusing those (and every other
/// data-dependent failure: a tolerance not met, the expansion's round-off
/// floor) at solve time.
pub fn check_solvable(spec: &Spec, max_streams: usize) -> Result<(), SpecError> {
    let wavelengths = wavelengths(spec);
    for (k, wl) in wavelengths.iter().enumerate() {
        let Some(wl) = *wl else { continue };
        let at = |e: SpecError, material: &str| -> SpecError {
            SpecError::new(
                format!("wavelengths_nm[{k}]"),
                format!("{wl} nm: {material}: {}", e.message),
            )
        };
        for (i, layer) in spec.layers.iter().enumerate() {
            for (mp, m) in populations(i, layer) {
                let material = format!("{mp}.material");
                let index = material_index(&m.material, wl).map_err(|e| at(e, &material))?;
                let host_at = host_path(&mp);
                let host = m
                    .host_index
                    .index_at(wl)
                    .map_err(|e| at(SpecError::new("", e.to_string()), &host_at))?;
                if !(host.n.is_finite() && host.n >= 1.0) {
                    return Err(SpecError::new(
                        host_at,
                        format!(
                            "the host's real index is {} at {wl} nm (wavelengths_nm[{k}]): a binder needs n ≥ 1",
                            host.n
                        ),
                    ));
                }
                check_population(&mp, &m, index, host.n, wl, k)?;
            }
        }
        if let Some((key, material, _)) = spec.base.surface() {
            material_index(material, wl).map_err(|e| at(e, &format!("base.{key}.material")))?;
            surface_indices(spec, Some(wl))?;
        }
    }
    if spec.base.surface().is_some() && spec.wavelengths_nm.is_none() {
        surface_indices(spec, None)?;
    }
    let (path, streams) = match stream_policy(spec) {
        StreamPolicy::Fixed(n) => ("solver.streams", n),
        StreamPolicy::Tolerance(_) => {
            if max_streams < 4 {
                return Err(SpecError::new(
                    "solver.tolerance",
                    format!(
                        "a tolerance needs solves at 2, 3 and 4 streams, but at most {max_streams} are allowed: give solver.streams instead"
                    ),
                ));
            }
            // The largest level `reflection_to_tolerance` may try.
            let ladder = crate::solver::accuracy::tolerance_ladder(max_streams);
            ("solver.tolerance", *ladder.last().expect("max_streams ≥ 4"))
        }
    };
    for (i, l) in spec.layers.iter().enumerate() {
        let LayerForm::Optical {
            thickness,
            scatterer,
        } = l.valid_form()
        else {
            continue;
        };
        if matches!(scatterer, ScattererSpec::Mie(_)) {
            continue;
        }
        let (albedo, coef) = layer_optics(&format!("layers[{i}].scatterer"), scatterer, None)?;
        let layer = Layer {
            thickness: match thickness {
                ThicknessSpec::Number(t) => Thickness::Finite(*t),
                ThicknessSpec::Word(_) => Thickness::Infinite,
            },
            albedo,
            coef,
        };
        if let Err(e) = solver::check_resolved(i, &layer, streams) {
            let needed = match e {
                SolverError::Unresolved { needed, .. } => needed,
                _ => 0,
            };
            let cap = if needed > max_streams {
                format!(
                    "; that is more than the {max_streams} streams allowed here, so make the phase function less backward-peaked"
                )
            } else if path == "solver.tolerance" {
                format!(
                    "; a tolerance picks at most {streams} streams here: give solver.streams ≥ {needed} instead"
                )
            } else {
                String::new()
            };
            return Err(SpecError::new(path, format!("{e}{cap}")));
        }
    }
    Ok(())
}

/// The Mie inputs of the population `m` at JSON path `mp` inside the
/// validated range of `physics::mie` at `wl` (`wavelengths_nm[k]`): the
/// relative index, and for one radius the size parameter.
fn check_population(
    mp: &str,
    m: &MieSpec,
    index: RefractiveIndex,
    n_host: f64,
    wl: f64,
    k: usize,
) -> Result<(), SpecError> {
    let (k_per_um, _) = crate::physics::mie::wavenumber_and_index(index, n_host, wl).map_err(|e| {
        SpecError::new(
            format!("{mp}.material"),
            format!(
                "at {wl} nm (wavelengths_nm[{k}]) with host index {n_host}: {e}; the particle must differ from its binder"
            ),
        )
    })?;
    if let Some(r) = m.radius_um {
        use crate::physics::mie::{SIZE_PARAMETER_MAX, SIZE_PARAMETER_MIN};
        let x = k_per_um * r;
        if !(SIZE_PARAMETER_MIN..=SIZE_PARAMETER_MAX).contains(&x) {
            return Err(SpecError::new(
                format!("{mp}.radius_um"),
                format!(
                    "the Mie size parameter 2π r n_host/λ = {x:.3e} at {wl} nm (wavelengths_nm[{k}]) is outside the validated range [{SIZE_PARAMETER_MIN:e}, {SIZE_PARAMETER_MAX:e}]: choose radius_um between {:.3e} and {:.3e} µm at this wavelength",
                    (SIZE_PARAMETER_MIN / k_per_um).max(1e-6),
                    (SIZE_PARAMETER_MAX / k_per_um).min(1e4)
                ),
            ));
        }
    }
    Ok(())
}

/// The index of a material at one wavelength; the error names the
/// tabulated range of a built-in material.
fn material_index(m: &MaterialSpec, wavelength_nm: f64) -> Result<RefractiveIndex, SpecError> {
    m.index_at(wavelength_nm).map_err(|e| match e {
        crate::physics::PhysicsError::OutOfRange { range, .. } => SpecError::new(
            "wavelengths_nm",
            format!(
                "'{}' has refractive-index data only for {range}: choose wavelengths inside it",
                m.label()
            ),
        ),
        other => SpecError::new("wavelengths_nm", other.to_string()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::{MAX_STREAMS, parse};
    use crate::physics::materials;

    const RAYLEIGH: &str = r#"{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}"#;

    fn hg(g: f64, solver: &str) -> Spec {
        parse(&format!(
            r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"henyey_greenstein":{{"albedo":1,"g":{g}}}}}}}],"solver":{solver}}}"#
        ))
        .unwrap()
    }

    /// Smallest N with |g|^l ≤ 1e-4 for every l ≥ 2N (HG: |β_l|/(2l+1) = |g|^l).
    fn hg_needs(g: f64) -> usize {
        let last_big = (0..)
            .take_while(|&l| g.abs().powi(l) > 1e-4)
            .last()
            .unwrap() as usize;
        (last_big + 1).div_ceil(2)
    }

    #[test]
    fn backward_peaks_are_refused_before_solving() {
        assert_eq!(hg_needs(-0.8), 21); // docs/spec.md
        let e = check_solvable(&hg(-0.8, "{}"), MAX_STREAMS).unwrap_err();
        assert_eq!(e.path, "solver.streams");
        assert!(e.message.contains("at least 21 streams"), "{e}");
        assert!(check_solvable(&hg(-0.8, r#"{"streams":21}"#), MAX_STREAMS).is_ok());
        assert!(check_solvable(&hg(-0.8, r#"{"streams":20}"#), MAX_STREAMS).is_err());
        assert!(check_solvable(&hg(0.8, "{}"), MAX_STREAMS).is_ok());
        // A tolerance may pick up to the largest level of its ladder (4, 6,
        // 8, 12, …, 32, 48, 64) under the cap.
        let needs = hg_needs(-0.9);
        assert!(needs > 32 && needs <= 64, "{needs}");
        let reach = if needs <= 48 { 48 } else { 64 };
        assert!(check_solvable(&hg(-0.9, r#"{"tolerance":1e-3}"#), reach).is_ok());
        let e = check_solvable(&hg(-0.9, r#"{"tolerance":1e-3}"#), reach - 1).unwrap_err();
        assert_eq!(e.path, "solver.tolerance");
        assert!(
            e.message.contains(&format!("at least {needs} streams")),
            "{e}"
        );
        let e = check_solvable(&hg(0.5, r#"{"tolerance":1e-3}"#), 3).unwrap_err();
        assert_eq!(e.path, "solver.tolerance");
    }

    #[test]
    fn wavelengths_outside_the_material_data_are_refused() {
        let (lo, hi) = materials::find("silver").unwrap().wavelength_range_nm();
        let spec = |wl: f64| {
            parse(&format!(
                r#"{{"layers":[{RAYLEIGH}],"base":{{"fresnel":{{"material":"silver"}}}},"wavelengths_nm":[{lo},{wl}]}}"#
            ))
            .unwrap()
        };
        assert!(check_solvable(&spec(hi), MAX_STREAMS).is_ok());
        let e = check_solvable(&spec(hi + 1.0), MAX_STREAMS).unwrap_err();
        assert_eq!(e.path, "wavelengths_nm[1]");
        assert!(e.message.contains("base.fresnel.material"), "{e}");
        assert!(e.message.contains(&format!("[{lo}, {hi}] nm")), "{e}");
    }

    #[test]
    fn mie_inputs_outside_the_validated_range_are_refused() {
        let mie = |material: &str, r: f64, wl: f64| {
            parse(&format!(
                r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"mie":{{"material":{material},"radius_um":{r}}}}}}}],"wavelengths_nm":[{wl}]}}"#
            ))
            .unwrap()
        };
        let e = check_solvable(&mie(r#"{"n":1,"k":0}"#, 0.2, 500.0), MAX_STREAMS).unwrap_err();
        assert_eq!(e.path, "layers[0].scatterer.mie.material");
        // x = 2π · 1e-6 µm / 100 µm = 6.3e-8 < 1e-6.
        let e = check_solvable(&mie(r#"{"n":1.5,"k":0}"#, 1e-6, 1e5), MAX_STREAMS).unwrap_err();
        assert_eq!(e.path, "layers[0].scatterer.mie.radius_um");
        assert!(check_solvable(&mie(r#"{"n":1.5,"k":0}"#, 0.2, 500.0), MAX_STREAMS).is_ok());
    }
}
