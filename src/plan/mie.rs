//! Mie layers: the optics of spheres (monodisperse or a size distribution,
//! `physics::mie`, `physics::psd`) at one wavelength, and the largest size
//! parameter a spec asks for (its cost).

use super::lower::resolve_index;
use crate::material::{
    HostSpec, LayerForm, MieSpec, ScattererSpec, SizeDistributionSpec, Spec, SpecError,
};
use crate::physics::MieOptics;
use crate::physics::expansion::GreekCoefficients;

/// Single-scattering albedo and Greek coefficients of a Mie layer at one
/// wavelength.
pub(super) fn mie_optics(
    path: &str,
    m: &MieSpec,
    wavelength_nm: Option<f64>,
) -> Result<(f64, GreekCoefficients), SpecError> {
    mie_population(path, m, wavelength_nm).map(|o| (o.albedo, o.coefficients))
}

/// The real part of a host medium at one wavelength (Mie theory's host
/// index; docs/spec.md, Absorbing binders).
pub(super) fn host_real_index(
    path: &str,
    host: &HostSpec,
    wavelength_nm: f64,
) -> Result<f64, SpecError> {
    host.index_at(wavelength_nm)
        .map(|n| n.n)
        .map_err(|e| SpecError::new(path, e.to_string()))
}

/// Mie theory for the population of `m` at one wavelength (`path`: the
/// JSON path of `m`).
pub(super) fn mie_population(
    path: &str,
    m: &MieSpec,
    wavelength_nm: Option<f64>,
) -> Result<MieOptics, SpecError> {
    let wl =
        wavelength_nm.ok_or_else(|| SpecError::new("wavelengths_nm", "required for Mie layers"))?;
    let index = resolve_index(&format!("{path}.material"), &m.material, Some(wl))?;
    let host = host_real_index(&format!("{path}.host_index"), &m.host_index, wl)?;
    let optics = match &m.size_distribution {
        Some(d) => crate::physics::mie_optics_distribution(
            index,
            host,
            wl,
            &to_psd(d),
            &psd_quadrature(d),
            None,
        ),
        None => crate::physics::mie_optics(index, host, wl, m.radius_um, None, None),
    };
    optics.map_err(|e| SpecError::new(path, e.to_string()))
}

/// Quadrature settings of a size distribution: the defaults, with the
/// explicit integration limits when given.
fn psd_quadrature(d: &SizeDistributionSpec) -> crate::physics::psd::PsdQuadrature {
    let radius_range_um = match d.radius_limits_um() {
        (Some(lo), Some(hi)) => Some([lo, hi]),
        _ => None,
    };
    crate::physics::psd::PsdQuadrature {
        radius_range_um,
        ..Default::default()
    }
}

fn to_psd(s: &SizeDistributionSpec) -> crate::physics::psd::SizeDistribution {
    match *s {
        SizeDistributionSpec::Lognormal {
            r_g_um, sigma_g, ..
        } => crate::physics::psd::SizeDistribution::LogNormal { r_g_um, sigma_g },
        SizeDistributionSpec::Gamma {
            r_eff_um, v_eff, ..
        } => crate::physics::psd::SizeDistribution::Gamma { r_eff_um, v_eff },
    }
}

/// The largest Mie size parameter `x = 2π r n_host/λ` the spec asks for, over
/// its Mie layers and wavelengths (for a size distribution, at the upper cut
/// of its radius integral, `psd::SizeDistribution::upper_cut_um`); 0 with
/// no Mie layer. It sets the cost of the Mie series (≈ x terms) and of the
/// expansion (≈ 2x terms), so the service caps it before queueing.
pub fn max_size_parameter(spec: &Spec) -> f64 {
    let Some(wavelengths) = &spec.wavelengths_nm else {
        return 0.0;
    };
    let Some(lambda_min_nm) = wavelengths.iter().copied().reduce(f64::min) else {
        return 0.0;
    };
    let mut x_max: f64 = 0.0;
    for (i, layer) in spec.layers.iter().enumerate() {
        for (_, m) in populations(i, layer) {
            let n_host = host_index_max(&m.host_index, wavelengths);
            let k_per_um = 2.0 * std::f64::consts::PI * 1000.0 * n_host / lambda_min_nm;
            let r_um = match (&m.radius_um, &m.size_distribution) {
                (Some(r), _) => *r,
                (None, Some(d)) => match d.radius_limits_um() {
                    (_, Some(hi)) => hi,
                    _ => to_psd(d).upper_cut_um(
                        k_per_um,
                        crate::physics::psd::PsdQuadrature::default().tail_fraction,
                    ),
                },
                (None, None) => 0.0,
            };
            x_max = x_max.max(k_per_um * r_um);
        }
    }
    x_max
}

/// The particle populations of layer `i`, each with its JSON path: a Mie
/// scatterer (`layers[i].scatterer.mie`), or each pigment of a film in its
/// binder (`layers[i].pigments[j]`).
pub fn populations(i: usize, layer: &crate::material::LayerSpec) -> Vec<(String, MieSpec)> {
    match layer.form() {
        Ok(LayerForm::Optical {
            scatterer: ScattererSpec::Mie(m),
            ..
        }) => vec![(format!("layers[{i}].scatterer.mie"), m.clone())],
        Ok(LayerForm::Film {
            pigments, binder, ..
        }) => pigments
            .iter()
            .enumerate()
            .map(|(j, p)| (format!("layers[{i}].pigments[{j}]"), p.in_binder(binder)))
            .collect(),
        _ => Vec::new(),
    }
}

/// The JSON path of the medium of a population at `path` (from
/// [`populations`]): a Mie scatterer's `host_index`, a film's `binder`.
pub fn host_path(path: &str) -> String {
    match path.rsplit_once(".pigments[") {
        Some((layer, _)) => format!("{layer}.binder"),
        None => format!("{path}.host_index"),
    }
}

/// The largest real part of a host over the spec's wavelengths (1 where it
/// cannot be evaluated: `check_solvable` reports that).
fn host_index_max(host: &HostSpec, wavelengths_nm: &[f64]) -> f64 {
    wavelengths_nm
        .iter()
        .filter_map(|&wl| host.index_at(wl).ok())
        .map(|n| n.n)
        .fold(1.0, f64::max)
}
