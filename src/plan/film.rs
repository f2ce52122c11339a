//! Paint films: a layer given as a geometric thickness, pigments by volume
//! fraction and a binder (docs/spec.md, Films), lowered at one wavelength
//! to the optical thickness, single-scattering albedo and Greek
//! coefficients the solver takes.
//!
//! Independent scattering (van de Hulst 1957, ch. 1; Mishchenko, Travis &
//! Lacis 2002, *Scattering, Absorption, and Emission of Light by Small
//! Particles*, the ensemble averages of ch. 3): the particles of a sparse
//! random mixture scatter as if alone, so extinction and scattering
//! coefficients add over the populations and the mixture's phase matrix
//! (hence each Greek coefficient) is the scattering-coefficient-weighted
//! mean of the populations' normalised ones:
//!
//! * number density `N_i = f_i / ⟨V⟩_i` (volume fraction over the mean
//!   particle volume, `physics::MieOptics::volume_um3`);
//! * `k_ext,i = N_i ⟨C_ext⟩_i`, `k_sca,i = ω_i k_ext,i` (per µm);
//! * the binder's own absorption between the particles,
//!   `k_binder = (4π κ_b / λ) (1 − Σ f_i)` (`κ_b` the binder's imaginary
//!   index, `λ` in µm);
//! * `τ = d (Σ k_ext,i + k_binder)`, `ω = Σ k_sca,i / (Σ k_ext,i + k_binder)`,
//!   `c_l = Σ k_sca,i c_l,i / Σ k_sca,i` for every Greek coefficient `c`.
//!
//! Equivalently the phase matrices are extinction-weighted with the weights
//! `ω_i k_ext,i`. Mie theory for each pigment runs in a host of the
//! binder's real index (the far-field cross sections of a sphere in an
//! absorbing host are not uniquely defined: Mundy, Roux & Smith 1974,
//! Mishchenko 2007); the approximation holds while the binder absorbs
//! little across one particle, `4π κ_b r / λ ≪ 1`.
//!
//! Dense packing: independent scattering overestimates the scattering of
//! closely packed particles (correlated positions interfere); for
//! submicron pigments the error grows past a pigment volume concentration
//! of about 10 % (the hard-sphere structure factor of Percus & Yevick 1958,
//! Phys. Rev. 110, 1, is the usual measure of it).
//! [`DENSE_PVC`] is the level above which [`film_warnings`] says so; no
//! correction is applied.

use super::mie::mie_population;
use crate::material::{HostSpec, PigmentSpec, SpecError};
use crate::physics::RefractiveIndex;
use crate::physics::expansion::GreekCoefficients;

/// Pigment volume concentration above which independent scattering is
/// known to overestimate scattering ([`film_warnings`]).
pub const DENSE_PVC: f64 = 0.10;

/// One pigment of a film at one wavelength.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PigmentOptics {
    /// Particles per µm³.
    pub number_density_per_um3: f64,
    /// Mean extinction cross section per particle, µm².
    pub c_ext_um2: f64,
    /// Mean particle volume, µm³.
    pub volume_um3: f64,
    /// Extinction coefficient `N ⟨C_ext⟩`, per µm.
    pub extinction_per_um: f64,
    /// Single-scattering albedo of the pigment alone.
    pub albedo: f64,
    /// Asymmetry parameter of the pigment alone.
    pub g: f64,
    /// Largest Mie size parameter of the pigment.
    pub size_parameter: f64,
}

/// A film at one wavelength: what the solver takes, and how it was mixed.
#[derive(Clone, Debug)]
pub struct FilmOptics {
    /// `τ = d k_ext`.
    pub optical_thickness: f64,
    /// Single-scattering albedo of the mixture.
    pub albedo: f64,
    /// Mixed Greek coefficients (conventions §4).
    pub coefficients: GreekCoefficients,
    /// Each pigment, in the spec's order.
    pub pigments: Vec<PigmentOptics>,
    /// The binder's index at this wavelength.
    pub binder_index: RefractiveIndex,
    /// The binder's absorption between the pigments `(4πκ_b/λ)(1 − PVC)`,
    /// per µm.
    pub binder_absorption_per_um: f64,
}

impl FilmOptics {
    /// Asymmetry parameter of the mixture (`β_1 / 3`).
    pub fn g(&self) -> f64 {
        self.coefficients.beta.get(1).copied().unwrap_or(0.0) / 3.0
    }
}

/// The film at layer path `p` at `wavelength_nm` (module documentation).
pub fn film_optics(
    p: &str,
    thickness_um: f64,
    pigments: &[PigmentSpec],
    binder: &HostSpec,
    wavelength_nm: f64,
) -> Result<FilmOptics, SpecError> {
    let binder_index = binder
        .index_at(wavelength_nm)
        .map_err(|e| SpecError::new(format!("{p}.binder"), e.to_string()))?;
    let mut parts = Vec::with_capacity(pigments.len());
    let mut coefs = Vec::with_capacity(pigments.len());
    for (j, pigment) in pigments.iter().enumerate() {
        let q = format!("{p}.pigments[{j}]");
        // The binder's index was checked above: a pigment's error is its own.
        let o = mie_population(&q, &pigment.in_binder(binder), Some(wavelength_nm))?;
        let number_density_per_um3 = pigment.volume_fraction / o.volume_um3;
        parts.push(PigmentOptics {
            number_density_per_um3,
            c_ext_um2: o.c_ext_um2,
            volume_um3: o.volume_um3,
            extinction_per_um: number_density_per_um3 * o.c_ext_um2,
            albedo: o.albedo,
            g: o.g,
            size_parameter: o.size_parameter,
        });
        coefs.push(o.coefficients);
    }
    let pvc: f64 = pigments.iter().map(|q| q.volume_fraction).sum();
    let lambda_um = wavelength_nm / 1000.0;
    let binder_absorption_per_um =
        4.0 * std::f64::consts::PI * binder_index.k / lambda_um * (1.0 - pvc);
    let k_ext: f64 =
        parts.iter().map(|q| q.extinction_per_um).sum::<f64>() + binder_absorption_per_um;
    let k_sca: Vec<f64> = parts
        .iter()
        .map(|q| q.albedo * q.extinction_per_um)
        .collect();
    let k_sca_total: f64 = k_sca.iter().sum();
    let weights: Vec<f64> = if k_sca_total > 0.0 {
        k_sca.iter().map(|k| k / k_sca_total).collect()
    } else {
        vec![1.0 / parts.len() as f64; parts.len()]
    };
    Ok(FilmOptics {
        optical_thickness: thickness_um * k_ext,
        albedo: if k_ext > 0.0 {
            (k_sca_total / k_ext).min(1.0)
        } else {
            0.0
        },
        coefficients: mixed(&coefs, &weights),
        pigments: parts,
        binder_index,
        binder_absorption_per_um,
    })
}

/// `Σ w_i c_i` of each Greek coefficient, the series padded with zeros to
/// the longest.
pub fn mixed(coefs: &[GreekCoefficients], weights: &[f64]) -> GreekCoefficients {
    let len = coefs.iter().map(|c| c.beta.len()).max().unwrap_or(1);
    let mut out = GreekCoefficients::zeros(len);
    for (c, &w) in coefs.iter().zip(weights) {
        for (dst, src) in [
            (&mut out.beta, &c.beta),
            (&mut out.alpha, &c.alpha),
            (&mut out.zeta, &c.zeta),
            (&mut out.delta, &c.delta),
            (&mut out.gamma, &c.gamma),
            (&mut out.epsilon, &c.epsilon),
        ] {
            for (d, s) in dst.iter_mut().zip(src) {
                *d += w * s;
            }
        }
    }
    out
}

/// What a film asks of independent scattering that it may not give: a
/// pigment volume concentration above [`DENSE_PVC`]. One message per film
/// layer, with its JSON path.
pub fn film_warnings(spec: &crate::material::Spec) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for (i, layer) in spec.layers.iter().enumerate() {
        if let Ok(crate::material::LayerForm::Film { pigments, .. }) = layer.form() {
            let pvc: f64 = pigments.iter().map(|q| q.volume_fraction).sum();
            if pvc > DENSE_PVC {
                out.push((
                    format!("layers[{i}].pigments"),
                    format!(
                        "pigment volume concentration {:.1} % is above {:.0} %: independent scattering overestimates the scattering of densely packed pigments (no dependent-scattering correction is applied; docs/spec.md, Films)",
                        100.0 * pvc,
                        100.0 * DENSE_PVC
                    ),
                ));
            }
        }
    }
    out
}

/// The optics of every layer of a spec at each of its wavelengths: what the
/// solver is given (`polbrdf mie --spec`, `POST /v1/optics`; docs/spec.md,
/// Layer optics report). Per layer its JSON `path` and `form` (`"optical"`
/// or `"film"`; a film also `thickness_um` and
/// `pigment_volume_concentration`), and per wavelength `wavelength_nm`,
/// `optical_thickness` (a number, or `"infinite"`), `albedo`, `g` and the
/// Greek `expansion` (conventions §4); a film adds `binder_index` `{n, k}`,
/// `binder_absorption_per_um` and per pigment its [`PigmentOptics`]. The
/// `warnings` are [`film_warnings`], each `{path, message}`.
///
/// # Errors
/// The first layer that cannot be lowered ([`super::problem`]'s errors).
pub fn optics_report(spec: &crate::material::Spec) -> Result<serde_json::Value, SpecError> {
    use crate::material::{LayerForm, ThicknessSpec};
    use serde_json::{Value, json};
    let wavelengths = super::wavelengths(spec);
    let mut layers = Vec::with_capacity(spec.layers.len());
    for (i, layer) in spec.layers.iter().enumerate() {
        let path = format!("layers[{i}]");
        let mut per_wavelength = Vec::with_capacity(wavelengths.len());
        let mut entry = json!({ "path": path });
        for &wl in &wavelengths {
            let row = match layer.valid_form() {
                LayerForm::Optical {
                    thickness,
                    scatterer,
                } => {
                    entry["form"] = json!("optical");
                    let (albedo, coef) =
                        super::layer_optics(&format!("{path}.scatterer"), scatterer, wl)?;
                    let tau = match thickness {
                        ThicknessSpec::Number(t) => json!(t),
                        ThicknessSpec::Word(_) => json!("infinite"),
                    };
                    json!({
                        "wavelength_nm": wl,
                        "optical_thickness": tau,
                        "albedo": albedo,
                        "g": coef.beta.get(1).copied().unwrap_or(0.0) / 3.0,
                        "expansion": coef,
                    })
                }
                LayerForm::Film {
                    thickness_um,
                    pigments,
                    binder,
                } => {
                    entry["form"] = json!("film");
                    entry["thickness_um"] = json!(thickness_um);
                    entry["pigment_volume_concentration"] =
                        json!(pigments.iter().map(|q| q.volume_fraction).sum::<f64>());
                    let wl =
                        wl.ok_or_else(|| SpecError::new("wavelengths_nm", "required for films"))?;
                    let f = film_optics(&path, thickness_um, pigments, binder, wl)?;
                    json!({
                        "wavelength_nm": wl,
                        "optical_thickness": f.optical_thickness,
                        "albedo": f.albedo,
                        "g": f.g(),
                        "binder_index": { "n": f.binder_index.n, "k": f.binder_index.k },
                        "binder_absorption_per_um": f.binder_absorption_per_um,
                        "pigments": f.pigments,
                        "expansion": f.coefficients,
                    })
                }
            };
            per_wavelength.push(row);
        }
        entry["optics"] = Value::Array(per_wavelength);
        layers.push(entry);
    }
    let warnings: Vec<Value> = film_warnings(spec)
        .into_iter()
        .map(|(path, message)| json!({ "path": path, "message": message }))
        .collect();
    Ok(json!({
        "wavelengths_nm": spec.wavelengths_nm,
        "layers": layers,
        "warnings": warnings,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::parse;
    use crate::physics::mie::MieResult;
    use crate::solver::Thickness;
    use std::f64::consts::PI;

    fn film(pigments: &str, binder: &str, wavelengths: &str) -> crate::material::Spec {
        parse(&format!(
            r#"{{"wavelengths_nm":{wavelengths},"layers":[{{"thickness_um":25,"pigments":{pigments},"binder":{binder}}}]}}"#
        ))
        .unwrap()
    }

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs()
    }

    /// One monodisperse pigment in a clear binder is the optical layer of
    /// the hand computation `τ = N C_ext d`, `N = f / (4π r³/3)`, with the
    /// sphere's own albedo and expansion.
    #[test]
    fn one_pigment_is_n_c_ext_d() {
        let s = film(
            r#"[{"material":"TiO2","radius_um":0.2,"volume_fraction":0.2}]"#,
            "1.5",
            "[550]",
        );
        let layer = crate::plan::problem(&s, Some(550.0)).unwrap().layers[0].clone();
        let index = crate::physics::materials::refractive_index("TiO2", 550.0).unwrap();
        let sphere = MieResult::for_sphere(index, 1.5, 550.0, 0.2).unwrap();
        let n_per_um3 = 0.2 / (4.0 / 3.0 * PI * 0.2f64.powi(3));
        let tau = n_per_um3 * sphere.qext * PI * 0.2 * 0.2 * 25.0;
        let Thickness::Finite(t) = layer.thickness else {
            panic!("finite")
        };
        assert!(rel(t, tau) < 1e-12, "{t} vs {tau}");
        assert!(rel(layer.albedo, sphere.albedo) < 1e-12);
        // The same expansion as the Mie scatterer of the same spheres.
        let mie = parse(
            r#"{"wavelengths_nm":[550],"layers":[{"optical_thickness":1,"scatterer":{"mie":{"material":"TiO2","radius_um":0.2,"host_index":1.5}}}]}"#,
        )
        .unwrap();
        let m = crate::plan::problem(&mie, Some(550.0)).unwrap().layers[0].clone();
        assert_eq!(layer.coef, m.coef);
    }

    /// Two pigments mix by their scattering coefficients; an absorbing
    /// binder adds `4πκ/λ (1 − PVC)` to the extinction only.
    #[test]
    fn two_pigments_and_an_absorbing_binder_mix_by_hand() {
        let s = film(
            r#"[{"material":"TiO2","radius_um":0.2,"volume_fraction":0.1},
                {"material":{"n":1.6,"k":0.01},"radius_um":0.5,"volume_fraction":0.05}]"#,
            r#"{"n":1.5,"k":0.0001}"#,
            "[600]",
        );
        let layer = crate::plan::problem(&s, Some(600.0)).unwrap().layers[0].clone();
        let tio2 = crate::physics::materials::refractive_index("TiO2", 600.0).unwrap();
        let a = MieResult::for_sphere(tio2, 1.5, 600.0, 0.2).unwrap();
        let b = MieResult::for_sphere(RefractiveIndex::new(1.6, 0.01), 1.5, 600.0, 0.5).unwrap();
        let k_ext = |q: &MieResult, f: f64, r: f64| 3.0 * f * q.qext / (4.0 * r);
        let (ka, kb) = (k_ext(&a, 0.1, 0.2), k_ext(&b, 0.05, 0.5));
        let k_binder = 4.0 * PI * 1e-4 / 0.6 * 0.85;
        let k = ka + kb + k_binder;
        let Thickness::Finite(t) = layer.thickness else {
            panic!("finite")
        };
        assert!(rel(t, 25.0 * k) < 1e-12, "{t} vs {}", 25.0 * k);
        let k_sca = a.albedo * ka + b.albedo * kb;
        assert!(rel(layer.albedo, k_sca / k) < 1e-12);
        // g of the mixture: the scattering-weighted g of the two.
        let g = (a.albedo * ka * a.g + b.albedo * kb * b.g) / k_sca;
        assert!(
            (layer.coef.beta[1] / 3.0 - g).abs() < 1e-9,
            "{} vs {g}",
            layer.coef.beta[1] / 3.0
        );
        assert_eq!(layer.coef.beta[0], 1.0);
    }

    /// A size distribution's number density uses its mean volume: the
    /// film's `τ` is `f ⟨C_ext⟩ / ⟨V⟩ d`.
    #[test]
    fn a_distribution_uses_its_mean_volume() {
        let s = film(
            r#"[{"material":"ZnO","size_distribution":{"lognormal":{"r_g_um":0.15,"sigma_g":1.3}},"volume_fraction":0.08}]"#,
            r#""acrylic""#,
            "[500]",
        );
        let report = optics_report(&s).unwrap();
        let p = &report["layers"][0]["optics"][0]["pigments"][0];
        let (n, c, v) = (
            p["number_density_per_um3"].as_f64().unwrap(),
            p["c_ext_um2"].as_f64().unwrap(),
            p["volume_um3"].as_f64().unwrap(),
        );
        assert!(rel(n * v, 0.08) < 1e-12);
        // ⟨V⟩ of the log-normal (tails cut at 1e-6 of the number).
        let exact = 4.0 / 3.0 * PI * 0.15f64.powi(3) * (4.5 * 1.3f64.ln().powi(2)).exp();
        assert!(rel(v, exact) < 1e-4, "{v} vs {exact}");
        let tau = report["layers"][0]["optics"][0]["optical_thickness"]
            .as_f64()
            .unwrap();
        let binder = report["layers"][0]["optics"][0]["binder_absorption_per_um"]
            .as_f64()
            .unwrap();
        assert!(rel(tau, 25.0 * (n * c + binder)) < 1e-12);
    }

    /// Above 10 % PVC the report warns, naming the film.
    #[test]
    fn dense_films_are_warned_about() {
        let dense = film(
            r#"[{"material":"TiO2","radius_um":0.2,"volume_fraction":0.2}]"#,
            "1.5",
            "[550]",
        );
        let w = film_warnings(&dense);
        assert_eq!(w.len(), 1);
        assert_eq!(w[0].0, "layers[0].pigments");
        assert!(w[0].1.contains("20.0 %"), "{}", w[0].1);
        let sparse = film(
            r#"[{"material":"TiO2","radius_um":0.2,"volume_fraction":0.05}]"#,
            "1.5",
            "[550]",
        );
        assert!(film_warnings(&sparse).is_empty());
    }

    /// Bad films are refused with the path of the bad value.
    #[test]
    fn bad_films_name_their_path() {
        let bad = |layer: &str| {
            parse(&format!(r#"{{"wavelengths_nm":[550],"layers":[{layer}]}}"#)).unwrap_err()
        };
        let tio2 = r#"{"material":"TiO2","radius_um":0.2,"volume_fraction":0.3}"#;
        for (layer, path) in [
            (format!(r#"{{"thickness_um":0,"pigments":[{tio2}]}}"#), "layers[0].thickness_um"),
            (r#"{"thickness_um":10,"pigments":[]}"#.to_string(), "layers[0].pigments"),
            (format!(r#"{{"pigments":[{tio2}]}}"#), "layers[0].thickness_um"),
            (format!(r#"{{"thickness_um":10,"pigments":[{tio2},{tio2},{tio2},{tio2}]}}"#), "layers[0].pigments"),
            (
                r#"{"thickness_um":10,"pigments":[{"material":"TiO2","radius_um":0.2,"volume_fraction":0}]}"#.into(),
                "layers[0].pigments[0].volume_fraction",
            ),
            (
                r#"{"thickness_um":10,"pigments":[{"material":"TiO2","volume_fraction":0.1}]}"#.into(),
                "layers[0].pigments[0]",
            ),
            (format!(r#"{{"thickness_um":10,"pigments":[{tio2}],"binder":0.5}}"#), "layers[0].binder"),
            (format!(r#"{{"thickness_um":10,"pigments":[{tio2}],"binder":"nothing"}}"#), "layers[0].binder"),
            (format!(r#"{{"thickness_um":10,"pigments":[{tio2}],"optical_thickness":1}}"#), "layers[0]"),
        ] {
            assert_eq!(bad(&layer).path, path, "{layer}");
        }
        // A binder whose data do not reach a wavelength is refused before solving.
        let zno = r#"{"material":"ZnO","radius_um":0.2,"volume_fraction":0.3}"#;
        let s = parse(&format!(
            r#"{{"wavelengths_nm":[350],"layers":[{{"thickness_um":10,"pigments":[{zno}],"binder":"acrylic"}}]}}"#
        ))
        .unwrap();
        let e = crate::plan::check_solvable(&s, 64).unwrap_err();
        assert!(e.message.contains("layers[0].binder"), "{e:?}");
    }
}
