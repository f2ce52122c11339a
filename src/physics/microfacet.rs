//! Polarized reflection of a rough surface: the GGX (Trowbridge–Reitz)
//! microfacet model with Smith masking–shadowing and the Fresnel Mueller
//! matrix of each facet (docs/conventions.md §10).
//!
//! The BRDF of a surface of isotropic GGX facets (Walter et al. 2007,
//! eq. 20; Heitz 2014, eq. 99 for the shadowing) is
//!
//! ```text
//! f(ω_i, ω_o) = D(h) G₂(ω_i, ω_o) / (4 cosθ_i cosθ_o) · L(σ_o) M_F(ω_i·h) L(σ_i)
//! h = (ω_i + ω_o)/|ω_i + ω_o|,
//! D(h)  = α² / (π (cos²θ_h (α² − 1) + 1)²),
//! G₂    = 1 / (1 + Λ(θ_i) + Λ(θ_o)),   Λ(θ) = (√(1 + α² tan²θ) − 1)/2,
//! ```
//!
//! a 4×4 Mueller matrix in 1/sr (conventions §6) from the incident ray's
//! meridian frame to the outgoing ray's. `M_F(cos θ_d)` is the Fresnel
//! matrix of [`super::fresnel`] at the facet's local incidence cosine
//! `θ_d`, in the facet's own frames: the `s` vector `y_f = (h × k_in)/|…|`
//! shared by both rays and `x = y_f × k` for each (for `h = ẑ` these are
//! exactly the meridian frames of the flat surface, so the facet matrix is
//! the flat one rotated with the facet). `L(σ)` ([`super::stokes::rotation`])
//! turns the incident meridian frame into the facet frame (`σ_i`) and the
//! facet frame of the reflected ray into its meridian frame (`σ_o`). The
//! model is single reflection off the facets: at large `α` light that
//! would reflect twice is lost (the model's known energy deficit, up to a
//! few percent at `α = 0.5` for a white conductor), and as `α → 0` it tends
//! to the smooth surface's mirror reflection.
//!
//! Directions are given as the solver takes them (conventions §5, §7): the
//! incident ray goes down along `μ_in` at propagation azimuth 0, the
//! reflected one up along `μ_out` at propagation azimuth `Δφ_prop`
//! (`Δφ_prop = 0`: the mirror side).

use super::stokes::{Mueller, mul, rotation_cs};
use super::{PhysicsError, RefractiveIndex, fresnel};

/// A rough interface between an ambient medium of real index
/// `ambient ≥ 1` (air or the binder) and a medium of index `index` (a
/// conductor or a dielectric), with GGX roughness `alpha`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoughSurface {
    /// Real index of the medium the light comes from.
    pub ambient: f64,
    /// Complex index of the reflecting medium.
    pub index: RefractiveIndex,
    /// GGX roughness `α` (the RMS facet slope is `α/√2`).
    pub alpha: f64,
}

/// Smallest cosine at which directions are evaluated (conventions §5).
const MU_MIN: f64 = 1e-6;

type V3 = [f64; 3];

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(a: V3) -> Option<V3> {
    let n = dot(a, a).sqrt();
    (n > 1e-300).then(|| [a[0] / n, a[1] / n, a[2] / n])
}

/// A ray's propagation vector and meridian frame `(e_ϑ, e_ϕ)` (conventions
/// §5) from its cosine to +z (`cos ϑ`) and azimuth: `(k, e_ϑ, e_ϕ)`.
pub fn meridian_frame(cos_theta: f64, azimuth_rad: f64) -> (V3, V3, V3) {
    let c = cos_theta.clamp(-1.0, 1.0);
    let s = (1.0 - c * c).max(0.0).sqrt();
    let (sp, cp) = azimuth_rad.sin_cos();
    ([s * cp, s * sp, c], [c * cp, c * sp, -s], [-sp, cp, 0.0])
}

impl RoughSurface {
    /// A rough surface; `alpha` must be finite and in `(0, 10]`, the indices
    /// as [`fresnel::coefficients`] takes them.
    ///
    /// # Errors
    /// [`PhysicsError::OutOfRange`] naming the offending value.
    pub fn new(ambient: f64, index: RefractiveIndex, alpha: f64) -> Result<Self, PhysicsError> {
        if !(alpha.is_finite() && alpha > 0.0 && alpha <= 10.0) {
            return Err(PhysicsError::OutOfRange {
                name: "alpha",
                value: alpha,
                range: "(0, 10]".into(),
            });
        }
        fresnel::coefficients(ambient, index, 1.0)?;
        Ok(Self {
            ambient,
            index,
            alpha,
        })
    }

    /// The GGX distribution of facet normals `D(h)` (1/sr, normalised so
    /// that `∫ D cos θ_h dω_h = 1`) at `cos θ_h`.
    pub fn distribution(&self, cos_h: f64) -> f64 {
        let a2 = self.alpha * self.alpha;
        let c2 = cos_h * cos_h;
        let d = c2 * (a2 - 1.0) + 1.0;
        a2 / (std::f64::consts::PI * d * d)
    }

    /// Smith's `Λ(θ)` of GGX at `μ = cos θ` (Heitz 2014, eq. 72).
    pub fn lambda(&self, mu: f64) -> f64 {
        let mu = mu.max(MU_MIN);
        let tan2 = (1.0 - mu * mu).max(0.0) / (mu * mu);
        0.5 * ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0)
    }

    /// Height-correlated masking–shadowing `G₂ = 1/(1 + Λ_i + Λ_o)`.
    pub fn shadowing(&self, mu_in: f64, mu_out: f64) -> f64 {
        1.0 / (1.0 + self.lambda(mu_in) + self.lambda(mu_out))
    }

    /// The Mueller BRDF (1/sr) for a ray going down along `mu_in`,
    /// reflected up along `mu_out` at propagation azimuth difference
    /// `dphi_prop` (module doc), in their meridian frames.
    pub fn mueller(&self, mu_out: f64, mu_in: f64, dphi_prop: f64) -> Mueller {
        let (mu_in, mu_out) = (mu_in.clamp(MU_MIN, 1.0), mu_out.clamp(MU_MIN, 1.0));
        let (k_in, th_in, ph_in) = meridian_frame(-mu_in, 0.0);
        let (k_out, th_out, _) = meridian_frame(mu_out, dphi_prop);
        let h = unit([k_out[0] - k_in[0], k_out[1] - k_in[1], k_out[2] - k_in[2]])
            .expect("an upward and a downward ray differ");
        let cos_d = dot(k_out, h).clamp(0.0, 1.0);
        let scale =
            self.distribution(h[2]) * self.shadowing(mu_in, mu_out) / (4.0 * mu_in * mu_out);
        // Facet frames: the s vector shared by both rays (any vector normal
        // to k_in in exact backscatter, where the plane is undefined).
        let y_f = unit(cross(h, k_in)).unwrap_or(ph_in);
        let x_in = cross(y_f, k_in);
        let x_out = cross(y_f, k_out);
        let into_facet = rotation_cs(dot(x_in, th_in), dot(x_in, ph_in));
        let out_of_facet = rotation_cs(dot(th_out, x_out), dot(th_out, y_f));
        let facet = fresnel::mueller(self.ambient, self.index, cos_d)
            .expect("indices validated by RoughSurface::new, cosine clamped");
        let mut m = mul(&out_of_facet, &mul(&facet, &into_facet));
        for row in &mut m {
            for x in row.iter_mut() {
                *x *= scale;
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::C64;
    use crate::physics::quadrature::gauss_legendre_on;
    use crate::physics::stokes::{Jones, jones_to_mueller};
    use std::f64::consts::PI;

    const ALUMINIUM: RefractiveIndex = RefractiveIndex { n: 1.2, k: 7.26 };
    const GLASS: RefractiveIndex = RefractiveIndex { n: 1.5, k: 0.0 };

    fn surfaces() -> Vec<RoughSurface> {
        vec![
            RoughSurface::new(1.0, ALUMINIUM, 0.3).unwrap(),
            RoughSurface::new(1.5, ALUMINIUM, 0.1).unwrap(),
            RoughSurface::new(1.0, GLASS, 0.5).unwrap(),
        ]
    }

    fn geometries() -> Vec<(f64, f64, f64)> {
        let mut g = Vec::new();
        for &mu_out in &[0.15, 0.5, 0.93] {
            for &mu_in in &[0.2, 0.6, 0.99] {
                for &d in &[0.0, 0.4, 1.7, 3.0, -2.2] {
                    g.push((mu_out, mu_in, d));
                }
            }
        }
        g
    }

    fn close(a: &Mueller, b: &Mueller, tol: f64) -> bool {
        let scale = a[0][0].abs().max(b[0][0].abs()).max(1e-300);
        (0..4).all(|p| (0..4).all(|q| (a[p][q] - b[p][q]).abs() <= tol * scale))
    }

    /// The facet reflection by Jones calculus on world-frame fields, with
    /// its own s/p bases (`s ∝ k_in × k_out`, `p = s × k`) and no Stokes
    /// rotation: a field along `e_ϑ` or `e_ϕ` of the incident ray is split
    /// into its s and p parts, each reflected with its Fresnel coefficient,
    /// and the reflected field projected on the outgoing ray's `e_ϑ`, `e_ϕ`.
    #[test]
    fn mueller_matches_jones_calculus_on_world_fields() {
        for s in surfaces() {
            for (mu_out, mu_in, d) in geometries() {
                let (k_in, th_in, ph_in) = meridian_frame(-mu_in, 0.0);
                let (k_out, th_out, ph_out) = meridian_frame(mu_out, d);
                let Some(sv) = unit(cross(k_in, k_out)) else {
                    continue;
                };
                let p_in = cross(sv, k_in);
                let p_out = cross(sv, k_out);
                let h = unit([k_out[0] - k_in[0], k_out[1] - k_in[1], k_out[2] - k_in[2]]).unwrap();
                let c = fresnel::coefficients(s.ambient, s.index, dot(k_out, h)).unwrap();
                let field = |e: V3| -> [C64; 2] {
                    let (es, ep) = (dot(e, sv), dot(e, p_in));
                    let r: Vec<C64> = (0..3)
                        .map(|i| c.r_s * es * sv[i] + c.r_p * ep * p_out[i])
                        .collect();
                    let proj = |b: V3| r[0] * b[0] + r[1] * b[1] + r[2] * b[2];
                    [proj(th_out), proj(ph_out)]
                };
                let (a, b) = (field(th_in), field(ph_in));
                let j: Jones = [[a[0], b[0]], [a[1], b[1]]];
                let scale =
                    s.distribution(h[2]) * s.shadowing(mu_in, mu_out) / (4.0 * mu_in * mu_out);
                let mut want = jones_to_mueller(&j);
                want.iter_mut().flatten().for_each(|x| *x *= scale);
                let got = s.mueller(mu_out, mu_in, d);
                assert!(
                    close(&got, &want, 1e-12),
                    "{s:?} {mu_out} {mu_in} {d}: {got:?} vs {want:?}"
                );
            }
        }
    }

    /// Hovenier's reciprocity, conventions §5: `f(μ, μ0, Δφ) = Δ f(μ0, μ, −Δφ)ᵀ Δ`,
    /// and the mirror symmetry `f(−Δφ) = D f(Δφ) D`, `D = diag(1, 1, −1, −1)`.
    #[test]
    fn reciprocity_and_mirror_symmetry() {
        let delta = [1.0, 1.0, -1.0, 1.0];
        let dsym = [1.0, 1.0, -1.0, -1.0];
        for s in surfaces() {
            for (mu_out, mu_in, d) in geometries() {
                let f = s.mueller(mu_out, mu_in, d);
                let g = s.mueller(mu_in, mu_out, -d);
                let m = s.mueller(mu_out, mu_in, -d);
                let scale = f[0][0];
                for p in 0..4 {
                    for q in 0..4 {
                        let r = delta[p] * g[q][p] * delta[q];
                        assert!((f[p][q] - r).abs() <= 1e-12 * scale, "reciprocity {p}{q}");
                        let r = dsym[p] * m[p][q] * dsym[q];
                        assert!((f[p][q] - r).abs() <= 1e-12 * scale, "mirror {p}{q}");
                    }
                }
            }
        }
    }

    /// In the plane of incidence at the mirror direction the facet is the
    /// surface itself: the matrix is the flat Fresnel matrix times `D G₂/(4μ²)`.
    #[test]
    fn specular_direction_is_the_flat_fresnel_matrix() {
        for s in surfaces() {
            for &mu in &[0.1, 0.45, 0.8, 1.0] {
                let got = s.mueller(mu, mu, 0.0);
                let mut want = fresnel::mueller(s.ambient, s.index, mu).unwrap();
                let scale = s.distribution(1.0) * s.shadowing(mu, mu) / (4.0 * mu * mu);
                want.iter_mut().flatten().for_each(|x| *x *= scale);
                assert!(close(&got, &want, 1e-12), "{mu}: {got:?} vs {want:?}");
            }
        }
    }

    /// `∫ D(h) cos θ_h dω_h = 1`, and Smith's masking obeys the projected-area
    /// identity `∫ G₁(o) ⟨o·h⟩ D(h) dω_h = cos θ_o` with `G₁ = 1/(1 + Λ)`
    /// (Heitz 2014, eq. 8 and 43): checks `D` and `Λ` together.
    #[test]
    fn distribution_is_normalised_and_smith_masking_is_consistent() {
        for &alpha in &[0.05, 0.3, 1.0] {
            let s = RoughSurface::new(1.0, ALUMINIUM, alpha).unwrap();
            for &mu_o in &[1.0f64, 0.7, 0.2] {
                let o = [(1.0 - mu_o * mu_o).sqrt(), 0.0, mu_o];
                // Integrate in θ_h on panels whose edges are equally spaced
                // in √(tan θ_h / α) (the lobe's width is α) up to 90°, with an
                // edge where o·h first turns negative on the circle
                // (θ_h = 90° − θ_o: a kink of the φ integral).
                let mut panels: Vec<f64> = (0..=120)
                    .map(|i| (alpha * (i as f64 / 4.0).powi(2)).atan())
                    .collect();
                panels.push(PI / 2.0);
                panels.push((mu_o / o[0].max(1e-300)).atan());
                panels.sort_by(f64::total_cmp);
                let (mut norm, mut proj) = (0.0, 0.0);
                for win in panels.windows(2) {
                    let (xt, wt) = gauss_legendre_on(12, win[0], win[1]);
                    for (&th, &wt) in xt.iter().zip(&wt) {
                        let (st, ct) = th.sin_cos();
                        let dw = wt * st * s.distribution(ct);
                        norm += 2.0 * PI * dw * ct;
                        // ∫ max(0, A + B cos φ) dφ over the circle, exactly.
                        let (a, b) = (mu_o * ct, o[0] * st);
                        proj += dw
                            * if a >= b {
                                2.0 * PI * a
                            } else {
                                let p0 = (-a / b).acos();
                                2.0 * (a * p0 + b * p0.sin())
                            };
                    }
                }
                assert!((norm - 1.0).abs() < 1e-9, "alpha {alpha}: ∫D cos = {norm}");
                let g1 = 1.0 / (1.0 + s.lambda(mu_o));
                assert!(
                    (g1 * proj - mu_o).abs() < 1e-9,
                    "alpha {alpha} mu {mu_o}: {} vs {mu_o}",
                    g1 * proj
                );
            }
        }
    }
}
