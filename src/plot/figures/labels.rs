//! The words of the figures: names of materials, bases, thicknesses,
//! incident states and solver settings in titles, legends and footnotes.

use crate::material::{BaseSpec, MaterialSpec, ScattererSpec, Spec, ThicknessSpec};
use crate::plan::StreamPolicy;
use crate::solver::Thickness;
use std::path::Path;

/// A Stokes vector as `1:0:0:0` text (labels, CSV).
pub fn stokes_text(s: [f64; 4]) -> String {
    s.map(|c| format!("{c}")).join(":")
}

/// `[I, Q, U, V]` and, for the states of Fig. 4 of Collin et al. 2014 and
/// their opposites, their name in words.
pub fn stokes_name(s: [f64; 4]) -> String {
    let v = stokes_text(s);
    let name = match v.as_str() {
        "1:0:0:0" => "unpolarized",
        "1:1:0:0" => "linear, in the plane of incidence",
        "1:-1:0:0" => "linear, perpendicular",
        "1:0:1:0" => "linear at +45°",
        "1:0:0:1" => "right circular",
        "1:0:0:-1" => "left circular",
        _ => return format!("[{}]", v.replace(':', ", ")),
    };
    format!("[{}] {name}", v.replace(':', ", "))
}

/// The top layer's scatterer: material and radius, or the phase function.
pub(super) fn material_name(spec: &Spec) -> String {
    let Some(layer) = spec.layers.first() else {
        return "no layer".into();
    };
    let Some(scatterer) = layer.optical_scatterer() else {
        return match &layer.pigments {
            Some(p) => {
                let names: Vec<String> = p.iter().map(|q| q.material.label()).collect();
                format!(
                    "{} film, {} µm",
                    names.join(" + "),
                    layer.thickness_um.unwrap_or(f64::NAN)
                )
            }
            None => "layer".into(),
        };
    };
    match scatterer {
        ScattererSpec::Mie(m) => {
            let mat = m.material.label();
            match m.radius_um {
                Some(r) => format!("{mat}, r = {r} µm"),
                None => format!("{mat} (size distribution)"),
            }
        }
        ScattererSpec::Expansion(_) => "expansion".into(),
        ScattererSpec::Rayleigh { .. } => "Rayleigh".into(),
        ScattererSpec::HenyeyGreenstein { g, .. } => format!("Henyey–Greenstein g = {g}"),
    }
}

/// The base under the layers.
pub(super) fn base_name(spec: &Spec) -> String {
    match &spec.base {
        BaseSpec::Black => "black".into(),
        BaseSpec::Lambertian { albedo } => format!("Lambertian {albedo}"),
        BaseSpec::Fresnel { material, .. } => match material {
            MaterialSpec::Index { n, k } => format!("mirror n = {n} + {k}i"),
            other => other.label(),
        },
        BaseSpec::RoughFresnel {
            material, alpha, ..
        } => match material {
            MaterialSpec::Index { n, k } => format!("rough n = {n} + {k}i, α = {alpha}"),
            other => format!("rough {}, α = {alpha}", other.label()),
        },
    }
}

/// The optical thickness of the spec's top layer (a film's at
/// `wavelength_nm`; NaN where it cannot be lowered).
pub(super) fn spec_thickness(spec: &Spec, wavelength_nm: Option<f64>) -> Thickness {
    let Some(layer) = spec.layers.first() else {
        return Thickness::Finite(0.0);
    };
    match &layer.optical_thickness {
        Some(ThicknessSpec::Number(t)) => Thickness::Finite(*t),
        Some(ThicknessSpec::Word(_)) => Thickness::Infinite,
        None => crate::plan::problem(spec, wavelength_nm)
            .map(|p| p.layers[0].thickness)
            .unwrap_or(Thickness::Finite(f64::NAN)),
    }
}

/// An optical thickness in a legend (`∞` for a semi-infinite layer).
pub(super) fn tau_text(t: f64) -> String {
    if t.is_infinite() {
        "∞".into()
    } else {
        format!("{t}")
    }
}

/// The last component of a path (the whole text when it has none).
pub(super) fn file_name(path: &str) -> String {
    Path::new(path)
        .file_name()
        .map_or(path.to_string(), |f| f.to_string_lossy().into_owned())
}

/// `, λ = W nm`, or nothing for a wavelength-free spec.
pub(super) fn wl_text(wl: Option<f64>) -> String {
    wl.map_or(String::new(), |w| format!(", λ = {w} nm"))
}

/// The stream policy in words.
pub(super) fn policy_text(p: StreamPolicy) -> String {
    match p {
        StreamPolicy::Fixed(n) => format!("{n} streams"),
        StreamPolicy::Tolerance(t) => format!("streams for tolerance {t}"),
    }
}
