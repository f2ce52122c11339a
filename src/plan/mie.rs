//! Mie layers: the optics of spheres (monodisperse or a size distribution,
//! `physics::mie`, `physics::psd`) at one wavelength, and the largest size
//! parameter a spec asks for (its cost).

use super::lower::resolve_index;
use crate::material::{MieSpec, ScattererSpec, SizeDistributionSpec, Spec, SpecError};
use crate::physics::expansion::GreekCoefficients;

pub(super) fn mie_optics(
    path: &str,
    m: &MieSpec,
    wavelength_nm: Option<f64>,
) -> Result<(f64, GreekCoefficients), SpecError> {
    let wl =
        wavelength_nm.ok_or_else(|| SpecError::new("wavelengths_nm", "required for Mie layers"))?;
    let index = resolve_index(&format!("{path}.material"), &m.material, Some(wl))?;
    let optics = match &m.size_distribution {
        Some(d) => crate::physics::mie_optics_distribution(
            index,
            m.host_index,
            wl,
            &to_psd(d),
            &psd_quadrature(d),
            None,
        ),
        None => crate::physics::mie_optics(index, m.host_index, wl, m.radius_um, None, None),
    };
    optics
        .map(|o| (o.albedo, o.coefficients))
        .map_err(|e| SpecError::new(path, e.to_string()))
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
    for layer in &spec.layers {
        if let ScattererSpec::Mie(m) = &layer.scatterer {
            let k_per_um = 2.0 * std::f64::consts::PI * 1000.0 * m.host_index / lambda_min_nm;
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
