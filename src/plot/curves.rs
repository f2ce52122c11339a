//! The plotted quantities as numbers (pure: no files, no drawing), after
//! Collin, Pattanaik, LiKamWa and Bouatouch, "Computation of Polarized
//! Subsurface BRDF for Rendering", Graphics Interface 2014 ("Collin et al.
//! 2014" below).
//!
//! * Degree of polarization of the reflected light, Collin et al. 2014
//!   eq. (1):
//!   `DOP = √(Q² + U² + V²) / I` of `L = f · E` (conventions §6: `f` the
//!   Mueller BRDF, `E` the incident Stokes irradiance, row = outgoing Stokes).
//! * Error of the scalar RTE, Collin et al. 2014 §4.3: `e = 1 − F_s / F_v`
//!   with `F_v` the (1,1) element of the polarized BRDF and `F_s` the BRDF
//!   of the scalar RTE (same layers, `a1` only), at the same directions and
//!   settings.
//! * Samples of a BRDF along outgoing cosines, optical thicknesses, the plane
//!   of incidence and the hemisphere, from a direct solve at user cosines
//!   ([`solver::reflection`]) or from a table ([`Table::eval`]).
//!
//! Directions follow the graphics convention (conventions §5): the incident
//! direction has azimuth `φ_i = 0`; an outgoing azimuth `φ_o = 180°` is the
//! mirror (forward) side of the plane of incidence, `φ_o = 0` the
//! backscattering side. Cosines `μ0` (incident) and `μ` (outgoing) are those
//! of the paper's figures (it writes `μ_inc = −0.6` for the downward
//! beam; here `μ0 = 0.6`).

use crate::brdf::angles::dphi_prop_rad;
use crate::brdf::{Directions, Table};
use crate::material;
use crate::physics::stokes::{Mueller, apply, degree_of_polarization};
use crate::plan::StreamPolicy;
use crate::solver::{self, Problem, ReflectionFourier, SolverError, Thickness};
use rayon::prelude::*;

/// Unpolarized incident light.
pub const UNPOLARIZED: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

/// The incident Stokes vectors of Fig. 4 of Collin et al. 2014, top to
/// bottom: polarized along `x` of the incident meridian frame (the paper's
/// "horizontal"), at +45°, right circular, unpolarized.
pub const FIG4_STOKES: [[f64; 4]; 4] = [
    [1.0, 1.0, 0.0, 0.0],
    [1.0, 0.0, 1.0, 0.0],
    [1.0, 0.0, 0.0, 1.0],
    [1.0, 0.0, 0.0, 0.0],
];

/// Reflected Stokes radiance `L = f · E` (1/sr per unit irradiance) for the
/// incident Stokes irradiance `e` (conventions §6).
pub fn reflected(f: &Mueller, e: [f64; 4]) -> [f64; 4] {
    apply(f, e)
}

/// Degree of polarization of the reflected light, Collin et al. 2014
/// eq. (1), for the incident Stokes irradiance `e`; 0 where nothing is
/// reflected.
pub fn dop(f: &Mueller, e: [f64; 4]) -> f64 {
    degree_of_polarization(reflected(f, e))
}

/// The scalar-RTE error of Collin et al. 2014 §4.3, `e = 1 − F_s / F_v`.
pub fn scalar_error(f_scalar: f64, f_vector: f64) -> f64 {
    1.0 - f_scalar / f_vector
}

/// `n` per decade logarithmically spaced values from `lo` to `hi` (both
/// included, `0 < lo < hi`): `lo · 10^(k/n)`, the last one exactly `hi`.
pub fn log_space(lo: f64, hi: f64, per_decade: usize) -> Result<Vec<f64>, String> {
    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
        return Err(format!("a log range needs 0 < lo < hi, got {lo}:{hi}"));
    }
    if per_decade == 0 {
        return Err("points per decade must be at least 1".into());
    }
    let decades = (hi / lo).log10();
    let steps = (decades * per_decade as f64 - 1e-9).ceil().max(1.0) as usize;
    Ok((0..=steps)
        .map(|k| {
            if k == steps {
                hi
            } else {
                lo * 10f64.powf(decades * k as f64 / steps as f64)
            }
        })
        .collect())
}

/// `n` outgoing cosines `μ_k = k/n`, `k = 1..=n` (0 excluded: the horizon).
pub fn mu_samples(n: usize) -> Vec<f64> {
    (1..=n).map(|k| k as f64 / n as f64).collect()
}

/// Polar angle (degrees) of a cosine.
pub fn theta_deg(mu: f64) -> f64 {
    mu.clamp(-1.0, 1.0).acos().to_degrees()
}

/// Optical thickness as a plain number (`inf` for a semi-infinite layer).
pub fn tau_value(t: Thickness) -> f64 {
    t.value()
}

/// The problem with the **top** layer's optical thickness replaced by `tau`
/// (how every curve of `dop-vs-mu`, `dop-vs-tau` and `scalar-error` varies
/// the thickness). A semi-infinite top layer is only possible when it is the
/// only layer.
pub fn with_top_thickness(problem: &Problem, tau: Thickness) -> Result<Problem, String> {
    let mut p = problem.clone();
    let n = p.layers.len();
    let top = p
        .layers
        .first_mut()
        .ok_or_else(|| "the spec has no layer".to_string())?;
    if tau == Thickness::Infinite && n > 1 {
        return Err("a semi-infinite top layer needs a one-layer spec".into());
    }
    top.thickness = tau;
    Ok(p)
}

/// The scalar-RTE twin of a problem (`a1` only, same everything else).
pub fn scalar_twin(problem: &Problem) -> Problem {
    let mut p = problem.clone();
    p.settings.polarized = false;
    p
}

/// Solve for beams and observers along `mu` (each in `(0, 1]`) honouring the
/// stream policy as `polbrdf solve` does: fixed streams, or the cheapest
/// level of the tolerance ladder meeting a tolerance (`solver::accuracy`).
pub fn reflect(
    problem: &Problem,
    policy: StreamPolicy,
    mu: &[f64],
) -> Result<ReflectionFourier, SolverError> {
    reflect_with_streams(problem, policy, mu).map(|(r, _)| r)
}

/// [`reflect`] and the streams per hemisphere of the answer (the policy's
/// fixed number, or the level the tolerance driver chose).
pub fn reflect_with_streams(
    problem: &Problem,
    policy: StreamPolicy,
    mu: &[f64],
) -> Result<(ReflectionFourier, usize), SolverError> {
    match policy {
        StreamPolicy::Fixed(n) => {
            let mut p = problem.clone();
            p.settings.streams = n;
            solver::reflection(&p, mu).map(|r| (r, n))
        }
        StreamPolicy::Tolerance(t) => solver::accuracy::reflection_to_tolerance(
            problem,
            mu,
            t,
            material::MAX_STREAMS,
            &|_| {},
        )
        .map(|e| (e.reflection, e.estimate.streams[2])),
    }
}

/// Sorted distinct cosines (for one solve that serves many direction pairs).
pub fn distinct(values: impl IntoIterator<Item = f64>) -> Vec<f64> {
    let mut v: Vec<f64> = values.into_iter().collect();
    v.sort_by(f64::total_cmp);
    v.dedup_by(|a, b| (*a - *b).abs() <= 1e-15);
    v
}

/// The Mueller BRDF (1/sr) of a solve at incident cosine `mu0`, outgoing
/// cosine `mu` and outgoing azimuth `phi_o_deg` (`φ_i = 0`); both cosines
/// must be among the solve's user cosines.
pub fn brdf_at(r: &ReflectionFourier, mu0: f64, mu: f64, phi_o_deg: f64) -> Mueller {
    let index = |m: f64| {
        r.mu.iter()
            .position(|&x| (x - m).abs() <= 1e-15)
            .expect("cosine among the solve's user cosines")
    };
    r.brdf(index(mu), index(mu0), dphi_prop_rad(0.0, phi_o_deg))
}

/// The Mueller BRDF (1/sr) of a table at `(μ0, μ, φ_o)` with `φ_i = 0`.
pub fn table_at(
    table: &Table,
    wavelength_nm: Option<f64>,
    mu0: f64,
    mu: f64,
    phi_o_deg: f64,
) -> Result<Mueller, String> {
    let d = Directions {
        theta_i_deg: theta_deg(mu0),
        phi_i_deg: 0.0,
        theta_o_deg: theta_deg(mu),
        phi_o_deg,
    };
    table.eval(&d, wavelength_nm).map_err(|e| e.to_string())
}

/// One sample of a DOP curve.
#[derive(Clone, Debug, PartialEq)]
pub struct DopSample {
    /// Optical thickness of the top layer (`inf`: semi-infinite).
    pub tau: f64,
    /// Incident Stokes irradiance.
    pub stokes_in: [f64; 4],
    /// Incident cosine.
    pub mu0: f64,
    /// Outgoing cosine.
    pub mu: f64,
    /// Outgoing azimuth (degrees, `φ_i = 0`).
    pub phi_o_deg: f64,
    /// The BRDF's (1,1) element `f11` (1/sr).
    pub f11: f64,
    /// Reflected Stokes radiance per unit irradiance, `f · E` (1/sr).
    pub stokes_out: [f64; 4],
    /// Its degree of polarization, Collin et al. 2014 eq. (1).
    pub dop: f64,
}

impl DopSample {
    /// The sample of BRDF `f` for incident Stokes `e`.
    pub fn new(tau: f64, e: [f64; 4], mu0: f64, mu: f64, phi_o_deg: f64, f: &Mueller) -> Self {
        let s = reflected(f, e);
        Self {
            tau,
            stokes_in: e,
            mu0,
            mu,
            phi_o_deg,
            f11: f[0][0],
            stokes_out: s,
            dop: degree_of_polarization(s),
        }
    }
}

/// Fig. 8 of Collin et al. 2014: DOP against outgoing `μ` at incident `μ0`,
/// one solve per thickness (in parallel), every `(μ, φ_o)` of
/// `mus × phis_deg`.
pub fn dop_vs_mu(
    problem: &Problem,
    policy: StreamPolicy,
    mu0: f64,
    taus: &[Thickness],
    mus: &[f64],
    phis_deg: &[f64],
    e: [f64; 4],
) -> Result<Vec<DopSample>, String> {
    let user = distinct(mus.iter().copied().chain([mu0]));
    per_thickness(problem, taus, |t, p| {
        let r = reflect(p, policy, &user).map_err(|e| e.to_string())?;
        let mut out = Vec::new();
        for &phi in phis_deg {
            for &mu in mus {
                let f = brdf_at(&r, mu0, mu, phi);
                out.push(DopSample::new(tau_value(t), e, mu0, mu, phi, &f));
            }
        }
        Ok(out)
    })
}

/// Fig. 8 of Collin et al. 2014 from a table (one thickness: the table's
/// own, `tau`).
pub fn dop_vs_mu_table(
    table: &Table,
    wavelength_nm: Option<f64>,
    tau: f64,
    mu0: f64,
    mus: &[f64],
    phis_deg: &[f64],
    e: [f64; 4],
) -> Result<Vec<DopSample>, String> {
    // The degree of polarization needs every outgoing component of the
    // columns `e` excites (`needs.stokes` of the table's spec).
    crate::brdf::coverage::require_stokes_in(table, &e, "--stokes").map_err(|e| e.to_string())?;
    if table.shape().0 < 4 {
        return Err("the degree of polarization needs the polarized response (rows 1-3 of the Mueller matrix), and this table holds f11 only (needs.stokes = \"intensity\")".into());
    }
    let mut out = Vec::new();
    for &phi in phis_deg {
        for &mu in mus {
            let f = table_at(table, wavelength_nm, mu0, mu, phi)?;
            out.push(DopSample::new(tau, e, mu0, mu, phi, &f));
        }
    }
    Ok(out)
}

/// Fig. 4 of Collin et al. 2014: DOP against the top layer's optical
/// thickness for several incident Stokes vectors at one direction pair; one
/// solve per thickness (in parallel) serves every incident state.
pub fn dop_vs_tau(
    problem: &Problem,
    policy: StreamPolicy,
    mu0: f64,
    mu: f64,
    phi_o_deg: f64,
    taus: &[Thickness],
    stokes: &[[f64; 4]],
) -> Result<Vec<DopSample>, String> {
    let user = distinct([mu0, mu]);
    per_thickness(problem, taus, |t, p| {
        let r = reflect(p, policy, &user).map_err(|e| e.to_string())?;
        let f = brdf_at(&r, mu0, mu, phi_o_deg);
        Ok(stokes
            .iter()
            .map(|&e| DopSample::new(tau_value(t), e, mu0, mu, phi_o_deg, &f))
            .collect())
    })
}

/// One sample of a scalar-error curve.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorSample {
    /// Optical thickness of the top layer.
    pub tau: f64,
    /// Incident cosine.
    pub mu0: f64,
    /// Outgoing cosine.
    pub mu: f64,
    /// Outgoing azimuth (degrees, `φ_i = 0`).
    pub phi_o_deg: f64,
    /// `F_v`: f11 of the polarized BRDF (1/sr).
    pub f_vector: f64,
    /// `F_s`: the scalar BRDF (1/sr).
    pub f_scalar: f64,
    /// `e = 1 − F_s/F_v`.
    pub e: f64,
}

/// Fig. 7 of Collin et al. 2014: `e = 1 − F_s/F_v` against the top layer's
/// optical thickness for `(μ0, μ)` pairs at outgoing azimuth `phi_o_deg`;
/// per thickness one vector and one scalar solve with the same settings (in
/// parallel).
pub fn scalar_error_vs_tau(
    problem: &Problem,
    policy: StreamPolicy,
    pairs: &[(f64, f64)],
    phi_o_deg: f64,
    taus: &[Thickness],
) -> Result<Vec<ErrorSample>, String> {
    let user = distinct(pairs.iter().flat_map(|&(a, b)| [a, b]));
    per_thickness(problem, taus, |t, p| {
        let pv = {
            let mut v = p.clone();
            v.settings.polarized = true;
            v
        };
        let rv = reflect(&pv, policy, &user).map_err(|e| e.to_string())?;
        let rs = reflect(&scalar_twin(p), policy, &user).map_err(|e| e.to_string())?;
        Ok(pairs
            .iter()
            .map(|&(mu0, mu)| {
                let fv = brdf_at(&rv, mu0, mu, phi_o_deg)[0][0];
                let fs = brdf_at(&rs, mu0, mu, phi_o_deg)[0][0];
                ErrorSample {
                    tau: tau_value(t),
                    mu0,
                    mu,
                    phi_o_deg,
                    f_vector: fv,
                    f_scalar: fs,
                    e: scalar_error(fs, fv),
                }
            })
            .collect())
    })
}

/// One outgoing direction of a lobe, for unpolarized incident light.
#[derive(Clone, Debug, PartialEq)]
pub struct LobeSample {
    /// Outgoing polar angle (degrees).
    pub theta_o_deg: f64,
    /// Outgoing azimuth (degrees, `φ_i = 0`).
    pub phi_o_deg: f64,
    /// f11 (1/sr).
    pub f11: f64,
    /// Reflected Stokes radiance for unpolarized unit irradiance (1/sr).
    pub stokes_out: [f64; 4],
    /// Its degree of polarization.
    pub dop: f64,
}

/// A lobe sample of a table at `(θ_i, φ_i = 0)` and `(θ_o, φ_o)`.
pub fn lobe_sample(
    table: &Table,
    wavelength_nm: Option<f64>,
    theta_i_deg: f64,
    theta_o_deg: f64,
    phi_o_deg: f64,
) -> Result<LobeSample, String> {
    let d = Directions {
        theta_i_deg,
        phi_i_deg: 0.0,
        theta_o_deg,
        phi_o_deg,
    };
    let f = table.eval(&d, wavelength_nm).map_err(|e| e.to_string())?;
    let s = reflected(&f, UNPOLARIZED);
    Ok(LobeSample {
        theta_o_deg,
        phi_o_deg,
        f11: f[0][0],
        stokes_out: s,
        dop: degree_of_polarization(s),
    })
}

/// Signed outgoing angle in the plane of incidence: `+θ_o` on the mirror
/// side (`φ_o = 180°`), `−θ_o` on the backscattering side (`φ_o = 0`), as in
/// `polbrdf export --format csv`.
pub fn signed_theta_deg(theta_o_deg: f64, phi_o_deg: f64) -> f64 {
    if (phi_o_deg.rem_euclid(360.0) - 180.0).abs() < 90.0 {
        theta_o_deg
    } else {
        -theta_o_deg
    }
}

/// The lobe in the plane of incidence: outgoing angles `−90°..=90°` in steps
/// of `step_deg` (signed as [`signed_theta_deg`]).
pub fn lobe_in_plane(
    table: &Table,
    wavelength_nm: Option<f64>,
    theta_i_deg: f64,
    step_deg: f64,
) -> Result<Vec<LobeSample>, String> {
    let n = (90.0 / step_deg).round() as i64;
    (-n..=n)
        .map(|k| {
            let s = k as f64 * 90.0 / n as f64;
            let phi = if s < 0.0 { 0.0 } else { 180.0 };
            lobe_sample(table, wavelength_nm, theta_i_deg, s.abs(), phi)
        })
        .collect()
}

/// The lobe over the hemisphere at cell centres: `θ_o = (j + ½) dθ`,
/// `φ_o = (k + ½) dφ` for `n_theta × n_phi` cells covering `[0, 90°) ×
/// [0, 360°)`, θ-major.
pub fn lobe_map(
    table: &Table,
    wavelength_nm: Option<f64>,
    theta_i_deg: f64,
    n_theta: usize,
    n_phi: usize,
) -> Result<Vec<LobeSample>, String> {
    let (dt, dp) = (90.0 / n_theta as f64, 360.0 / n_phi as f64);
    let mut out = Vec::with_capacity(n_theta * n_phi);
    for j in 0..n_theta {
        for k in 0..n_phi {
            let t = (j as f64 + 0.5) * dt;
            let p = (k as f64 + 0.5) * dp;
            out.push(lobe_sample(table, wavelength_nm, theta_i_deg, t, p)?);
        }
    }
    Ok(out)
}

/// The samples of one solve per optical thickness of the top layer (in
/// parallel, [`with_top_thickness`]): `samples(τ, problem at τ)`, in the
/// order of `taus`; the first error wins.
fn per_thickness<T: Send>(
    problem: &Problem,
    taus: &[Thickness],
    samples: impl Fn(Thickness, &Problem) -> Result<Vec<T>, String> + Sync,
) -> Result<Vec<T>, String> {
    let per_tau: Vec<Result<Vec<T>, String>> = taus
        .par_iter()
        .map(|&t| samples(t, &with_top_thickness(problem, t)?))
        .collect();
    let mut out = Vec::new();
    for part in per_tau {
        out.extend(part?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::PolarGrid;
    use crate::physics::expansion::GreekCoefficients;
    use crate::solver::{Base, Layer, Settings};

    fn one_layer(coef: GreekCoefficients, albedo: f64, tau: f64, base: Base) -> Problem {
        Problem {
            layers: vec![Layer {
                thickness: Thickness::Finite(tau),
                albedo,
                coef,
            }],
            base,
            settings: Settings {
                streams: 8,
                ..Settings::default()
            },
            top_interface: None,
        }
    }

    #[test]
    fn dop_of_pure_states_and_mixtures() {
        let id = crate::physics::stokes::IDENTITY;
        for e in FIG4_STOKES.iter().take(3) {
            assert!((dop(&id, *e) - 1.0).abs() < 1e-15);
        }
        assert_eq!(dop(&id, UNPOLARIZED), 0.0);
        // A depolarizer (Lambertian white: (1/π) diag(1,0,0,0)).
        let mut lambert = [[0.0; 4]; 4];
        lambert[0][0] = 1.0 / std::f64::consts::PI;
        assert_eq!(dop(&lambert, [1.0, 1.0, 0.0, 0.0]), 0.0);
        // Nothing reflected: 0, not NaN.
        assert_eq!(dop(&[[0.0; 4]; 4], [1.0, 1.0, 0.0, 0.0]), 0.0);
        // Half polarized.
        assert!((dop(&id, [2.0, 0.6, 0.0, 0.8]) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn scalar_error_definition() {
        assert_eq!(scalar_error(1.0, 1.0), 0.0);
        assert!((scalar_error(0.89, 1.0) - 0.11).abs() < 1e-15);
        assert!(scalar_error(1.05, 1.0) < 0.0);
    }

    #[test]
    fn log_space_includes_the_ends() {
        let v = log_space(1e-3, 1e3, 4).unwrap();
        assert_eq!(v.len(), 25);
        assert_eq!(v[0], 1e-3);
        assert_eq!(*v.last().unwrap(), 1e3);
        assert!((v[4] - 1e-2).abs() < 1e-15);
        assert!(v.windows(2).all(|w| w[1] > w[0]));
        assert!(log_space(0.0, 1.0, 4).is_err());
        assert!(log_space(1.0, 1.0, 4).is_err());
        assert!(log_space(1.0, 10.0, 0).is_err());
        // A range that is not a whole number of decades still ends at hi.
        let v = log_space(0.5, 20.0, 2).unwrap();
        assert_eq!(*v.last().unwrap(), 20.0);
    }

    #[test]
    fn signed_angles_follow_the_csv_export() {
        assert_eq!(signed_theta_deg(30.0, 180.0), 30.0);
        assert_eq!(signed_theta_deg(30.0, 0.0), -30.0);
        assert_eq!(signed_theta_deg(30.0, -180.0), 30.0);
        assert_eq!(signed_theta_deg(30.0, 350.0), -30.0);
    }

    #[test]
    fn top_thickness_override() {
        let p = one_layer(GreekCoefficients::rayleigh(0.0), 1.0, 1.0, Base::Black);
        let q = with_top_thickness(&p, Thickness::Finite(0.25)).unwrap();
        assert_eq!(q.layers[0].thickness, Thickness::Finite(0.25));
        assert!(with_top_thickness(&q, Thickness::Infinite).is_ok());
        let mut two = p.clone();
        two.layers.push(p.layers[0].clone());
        assert!(with_top_thickness(&two, Thickness::Infinite).is_err());
    }

    /// A Henyey–Greenstein scatterer has no polarization at all (only β_l):
    /// the vector RTE's f11 is the scalar RTE's, so `e = 0`, and unpolarized
    /// light stays unpolarized.
    #[test]
    fn henyey_greenstein_has_no_scalar_error_and_no_polarization() {
        let p = one_layer(
            GreekCoefficients::henyey_greenstein(0.6, 40),
            0.95,
            1.0,
            Base::Lambertian { albedo: 0.5 },
        );
        let taus = [Thickness::Finite(0.01), Thickness::Finite(1.0)];
        let rows = scalar_error_vs_tau(
            &p,
            StreamPolicy::Fixed(8),
            &[(0.6, 0.6), (0.9, 1.0)],
            180.0,
            &taus,
        )
        .unwrap();
        assert_eq!(rows.len(), 4);
        for r in &rows {
            assert!(r.f_vector > 0.0);
            assert!(r.e.abs() < 1e-12, "{r:?}");
        }
        let d = dop_vs_mu(
            &p,
            StreamPolicy::Fixed(8),
            0.6,
            &taus,
            &[0.3, 1.0],
            &[0.0, 180.0],
            UNPOLARIZED,
        )
        .unwrap();
        assert!(d.iter().all(|s| s.dop < 1e-12), "{d:?}");
    }

    /// Rayleigh scattering polarizes: the scalar RTE is off (e ≠ 0), and
    /// the reflected DOP lies in [0, 1] for every input state; a thin layer
    /// on a white Lambertian base reflects mostly depolarized light.
    #[test]
    fn rayleigh_dop_is_bounded_and_a_thin_layer_on_lambertian_depolarizes() {
        let p = one_layer(
            GreekCoefficients::rayleigh(0.0),
            1.0,
            1.0,
            Base::Lambertian { albedo: 1.0 },
        );
        let taus = [
            Thickness::Finite(1e-3),
            Thickness::Finite(1.0),
            Thickness::Infinite,
        ];
        let rows = dop_vs_tau(
            &p,
            StreamPolicy::Fixed(8),
            0.6,
            0.5,
            180.0,
            &taus,
            &FIG4_STOKES,
        )
        .unwrap();
        assert_eq!(rows.len(), 12);
        for r in &rows {
            assert!(
                r.dop.is_finite() && (0.0..=1.0 + 1e-9).contains(&r.dop),
                "{r:?}"
            );
        }
        let thin_unpolarized = &rows[3];
        assert_eq!(thin_unpolarized.tau, 1e-3);
        assert!(thin_unpolarized.dop < 1e-2, "{thin_unpolarized:?}");
        assert_eq!(rows[11].tau, f64::INFINITY);
        let e = scalar_error_vs_tau(
            &p,
            StreamPolicy::Fixed(8),
            &[(0.6, 0.6)],
            180.0,
            &taus[1..2],
        )
        .unwrap();
        assert!(e[0].e.abs() > 1e-3, "{e:?}");
    }

    /// The plane-of-incidence lobe is the table evaluated at those
    /// directions, and the table at its nodes is the direct solve.
    #[test]
    fn lobe_samples_are_table_evaluations() {
        let spec = crate::material::parse(
            r#"{"layers":[{"optical_thickness":0.5,"scatterer":{"rayleigh":{"albedo":0.9}}}],
                "base":{"lambertian":{"albedo":0.3}},"solver":{"streams":8}}"#,
        )
        .unwrap();
        let table = Table::from_spec(&spec, PolarGrid::graded(12).unwrap()).unwrap();
        let lobe = lobe_in_plane(&table, None, 45.0, 5.0).unwrap();
        assert_eq!(lobe.len(), 37);
        for s in &lobe {
            let d = Directions {
                theta_i_deg: 45.0,
                phi_i_deg: 0.0,
                theta_o_deg: s.theta_o_deg,
                phi_o_deg: s.phi_o_deg,
            };
            let f = table.eval(&d, None).unwrap();
            assert_eq!(s.f11, f[0][0]);
            assert_eq!(s.stokes_out, [f[0][0], f[1][0], f[2][0], f[3][0]]);
        }
        let map = lobe_map(&table, None, 45.0, 6, 12).unwrap();
        assert_eq!(map.len(), 72);
        assert!(map.iter().all(|s| s.f11 > 0.0 && s.dop <= 1.0));

        // Table nodes (θ = 0 and θ = 90·sin(π/2·k/11)) reproduce a direct solve.
        let problem = crate::plan::problem(&spec, None).unwrap();
        let mu0 = table.grid.mu[4];
        let mu = table.grid.mu[7];
        let r = reflect(&problem, StreamPolicy::Fixed(8), &distinct([mu0, mu])).unwrap();
        let direct = brdf_at(&r, mu0, mu, 120.0);
        let tabled = table_at(&table, None, mu0, mu, 120.0).unwrap();
        for p in 0..4 {
            for q in 0..4 {
                assert!(
                    (direct[p][q] - tabled[p][q]).abs() <= 1e-9 * direct[0][0],
                    "{p}{q}: {direct:?} vs {tabled:?}"
                );
            }
        }
    }
}
