//! The adaptive radius quadrature of [`super::bulk_optics`] (module doc of
//! `physics::psd`, Quadrature).

use super::{
    BulkOptics, PsdQuadrature, RadiusRule, SizeDistribution, default_max_nodes, out_of_range,
    radius_limits_um,
};
use crate::physics::mie::{self, AmplitudeTable, MieResult};
use crate::physics::{C64, PhysicsError, RefractiveIndex};
use std::f64::consts::PI;
use std::rc::Rc;

/// Integrand layout: `[C_ext, C_sca, C_abs, g C_sca, then 4 products per angle]`.
const N_BULK: usize = 4;
/// Size-parameter spacing of one unit of `u`.
const U_X_SCALE: f64 = 5.0;
/// Initial panel width in `u`.
pub(super) const U_STEP0: f64 = 0.1;
/// Deepest bisection of a first-level panel (width 0.1 · 2⁻⁴⁵ ≈ 3e-15, the
/// float resolution of `u`).
const MAX_DEPTH: u32 = 45;
/// First-level panels integrated together (their Simpson sums are held
/// until they are accepted).
const WINDOW: usize = 32;
/// Open panels bisected together: their 2 new nodes each form one batch of
/// the amplitude table.
const BATCH_PANELS: usize = 32;

/// An open panel `[a, b]` in `u`: the integrand at `a`, the midpoint and
/// `b`, its Simpson sum and its bisection depth.
struct Panel {
    a: f64,
    b: f64,
    f: [Rc<Vec<f64>>; 3],
    whole: Vec<f64>,
    depth: u32,
}

/// Adaptive Simpson integration in `u = ln r + k r / 5` (see the module doc).
pub(super) struct Integrator<'a> {
    dist: &'a SizeDistribution,
    m: C64,
    k: f64,
    mu: &'a [f64],
    r_min: f64,
    r_max: f64,
    u_min: f64,
    u_max: f64,
    rel_tol: f64,
    max_nodes: usize,
    /// First-level panel width in `u`.
    pub(super) step0: f64,
    /// Smallest share of the tolerance a panel is held to.
    share_floor: f64,
    /// Magnitude each component's error is measured against.
    scale: Vec<f64>,
    /// Integrand evaluations so far.
    evals: usize,
    /// Sum over accepted panels of |Richardson correction| / scale (max over
    /// components at the end).
    err: Vec<f64>,
    /// Panels accepted at `MAX_DEPTH` without meeting the tolerance.
    unresolved: usize,
    /// Accepted panels `[a, b]` in `u` of the last pass.
    panels: Vec<(f64, f64)>,
    /// `π_n`, `τ_n` at `mu` up to the series length at `r_max` (none
    /// without angles).
    table: Option<AmplitudeTable>,
}

impl<'a> Integrator<'a> {
    pub(super) fn new(
        dist: &'a SizeDistribution,
        particle: RefractiveIndex,
        n_host: f64,
        wavelength_nm: f64,
        mu: &'a [f64],
        quad: &PsdQuadrature,
    ) -> Result<Self, PhysicsError> {
        dist.validate()?;
        if !(quad.tail_fraction > 0.0 && quad.tail_fraction <= 1e-2) {
            return Err(out_of_range(
                "tail_fraction",
                quad.tail_fraction,
                "(0, 0.01]".into(),
            ));
        }
        if !(quad.rel_tol > 0.0 && quad.rel_tol < 1.0) {
            return Err(out_of_range("rel_tol", quad.rel_tol, "(0, 1)".into()));
        }
        for &u in mu {
            if !(u.is_finite() && u.abs() <= 1.0 + 1e-12) {
                return Err(out_of_range("mu", u, "[-1, 1]".into()));
            }
        }
        // k: size parameter per µm of radius.
        let (k, m) = mie::wavenumber_and_index(particle, n_host, wavelength_nm)?;
        let [r_min, r_max] = radius_limits_um(dist, k, quad)?;
        let (x_min, x_max) = (k * r_min, k * r_max);
        let range = |r: &str, v: f64| {
            format!(
                "[{:e}, {:e}] ({r} = {v:e} µm)",
                mie::SIZE_PARAMETER_MIN,
                mie::SIZE_PARAMETER_MAX
            )
        };
        if x_min < mie::SIZE_PARAMETER_MIN {
            return Err(out_of_range(
                "size_parameter at the lower cut of the size distribution",
                x_min,
                range("r_min", r_min),
            ));
        }
        if x_max > mie::SIZE_PARAMETER_MAX {
            return Err(out_of_range(
                "size_parameter at the upper cut of the size distribution",
                x_max,
                range("r_max", r_max),
            ));
        }
        let u = |r: f64| r.ln() + k * r / U_X_SCALE;
        let n = N_BULK + 4 * mu.len();
        Ok(Self {
            dist,
            m,
            k,
            mu,
            r_min,
            r_max,
            u_min: u(r_min),
            u_max: u(r_max),
            rel_tol: quad.rel_tol,
            max_nodes: quad.max_nodes.unwrap_or_else(|| default_max_nodes(x_max)),
            step0: U_STEP0,
            share_floor: 0.0,
            scale: vec![0.0; n],
            evals: 0,
            err: vec![0.0; n],
            unresolved: 0,
            panels: Vec::new(),
            table: if mu.is_empty() {
                None
            } else {
                Some(AmplitudeTable::new(mu, table_terms(x_max))?)
            },
        })
    }

    /// Radius at `u` (safeguarded Newton on `t = ln r`).
    fn radius(&self, u: f64) -> f64 {
        let (mut lo, mut hi) = (self.r_min.ln(), self.r_max.ln());
        let mut t = u.min(hi).max(lo);
        for _ in 0..200 {
            let e = self.k * t.exp() / U_X_SCALE;
            let f = t + e - u;
            if f > 0.0 {
                hi = t;
            } else {
                lo = t;
            }
            let mut next = t - f / (1.0 + e);
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            let done = (next - t).abs() <= 1e-15 * t.abs().max(1.0);
            t = next;
            if done {
                break;
            }
        }
        t.exp()
    }

    /// `n(r) dr/du` at `u` and the radius there.
    fn jacobian(&self, u: f64) -> (f64, f64) {
        let r = self.radius(u);
        (
            self.dist.number_density(r) * r / (1.0 + self.k * r / U_X_SCALE),
            r,
        )
    }

    /// The accepted panels of the last pass as a fixed [`RadiusRule`]
    /// (Boole's rule per panel, nodes shared by neighbours merged).
    pub(super) fn rule(&self) -> RadiusRule {
        const BOOLE: [f64; 5] = [7.0, 32.0, 12.0, 32.0, 7.0];
        let mut nodes: Vec<(f64, f64)> = Vec::with_capacity(4 * self.panels.len() + 1);
        for &(a, b) in &self.panels {
            let m = 0.5 * (a + b);
            for (u, c) in [a, 0.5 * (a + m), m, 0.5 * (m + b), b]
                .into_iter()
                .zip(BOOLE)
            {
                nodes.push((u, c * (b - a) / 90.0));
            }
        }
        nodes.sort_by(|p, q| p.0.total_cmp(&q.0));
        let mut merged: Vec<(f64, f64)> = Vec::with_capacity(nodes.len());
        for (u, w) in nodes {
            match merged.last_mut() {
                Some(last) if last.0 == u => last.1 += w,
                _ => merged.push((u, w)),
            }
        }
        let (mut size_parameter, mut weight) = (Vec::new(), Vec::new());
        for (u, w) in merged {
            let (jac, r) = self.jacobian(u);
            size_parameter
                .push((self.k * r).clamp(mie::SIZE_PARAMETER_MIN, mie::SIZE_PARAMETER_MAX));
            weight.push(w * jac);
        }
        RadiusRule {
            m: self.m,
            k: self.k,
            size_parameter,
            weight,
        }
    }

    /// Integrand at each `u` of `us`: `n(r) dr/du · [C…, products…]`, the
    /// angles of a batch taken together ([`AmplitudeTable`]).
    fn eval_batch(&mut self, us: &[f64]) -> Result<Vec<Rc<Vec<f64>>>, PhysicsError> {
        self.evals += us.len();
        if self.evals > self.max_nodes {
            return Err(PhysicsError::Invalid(format!(
                "size-distribution quadrature needs more than max_nodes = {} radius nodes \
                 for rel_tol = {:e} (x_max = {:.4})",
                self.max_nodes,
                self.rel_tol,
                self.k * self.r_max
            )));
        }
        let mut spheres = Vec::with_capacity(us.len());
        let mut jac = Vec::with_capacity(us.len());
        for &u in us {
            let (w, r) = self.jacobian(u);
            let x = (self.k * r).clamp(mie::SIZE_PARAMETER_MIN, mie::SIZE_PARAMETER_MAX);
            spheres.push(MieResult::from_size_parameter(x, self.m)?);
            jac.push((w, r));
        }
        let mut out: Vec<Vec<f64>> = spheres
            .iter()
            .zip(&jac)
            .map(|(sphere, &(w, r))| {
                let geo = PI * r * r * w;
                let mut v = vec![0.0; self.scale.len()];
                v[..N_BULK].copy_from_slice(&[
                    sphere.qext * geo,
                    sphere.qsca * geo,
                    sphere.qabs * geo,
                    sphere.g * sphere.qsca * geo,
                ]);
                v
            })
            .collect();
        if let Some(t) = &self.table {
            t.products_with(&spheres, |j, k, p| {
                let w = jac[j].0;
                let b = N_BULK + 4 * k;
                for (o, v) in out[j][b..b + 4].iter_mut().zip(p) {
                    *o = v * w;
                }
            })?;
        }
        Ok(out.into_iter().map(Rc::new).collect())
    }

    /// Scales from an integral estimate: `C_ext` for `C_ext`, `C_abs`;
    /// `C_sca` for `C_sca`, `g C_sca`; `⟨S11(μ)⟩` for the products at `μ`.
    fn set_scale(&mut self, t: &[f64]) {
        let floor = f64::MIN_POSITIVE;
        self.scale[0] = t[0].abs().max(floor);
        self.scale[1] = t[1].abs().max(floor);
        self.scale[2] = self.scale[0];
        self.scale[3] = self.scale[1];
        for i in 0..self.mu.len() {
            let b = N_BULK + 4 * i;
            let s = t[b].abs().max(floor);
            self.scale[b..b + 4].fill(s);
        }
    }

    /// Composite Simpson on the initial panels for the scales, then adaptive
    /// Simpson on each panel.
    pub(super) fn integrate(&mut self) -> Result<Vec<f64>, PhysicsError> {
        let span = self.u_max - self.u_min;
        let panels = ((span / self.step0).ceil() as usize).max(16);
        if 2 * panels + 1 > self.max_nodes {
            return Err(PhysicsError::Invalid(format!(
                "size-distribution quadrature needs {} radius nodes at its first level \
                 (x_max = {:.4}), more than max_nodes = {}",
                2 * panels + 1,
                self.k * self.r_max,
                self.max_nodes
            )));
        }
        let h = span / panels as f64;
        let us: Vec<f64> = (0..=2 * panels)
            .map(|i| self.u_min + 0.5 * h * i as f64)
            .collect();
        let f = self.eval_batch(&us)?;
        let simpson = |a: &[f64], m: &[f64], b: &[f64]| -> Vec<f64> {
            (0..a.len())
                .map(|j| h / 6.0 * (a[j] + 4.0 * m[j] + b[j]))
                .collect()
        };
        let wholes: Vec<Vec<f64>> = (0..panels)
            .map(|p| simpson(&f[2 * p], &f[2 * p + 1], &f[2 * p + 2]))
            .collect();
        let first = sum_vecs(self.scale.len(), wholes.iter());
        self.set_scale(&first);
        // A panel is held to its share of the tolerance, but not below the
        // share of a panel `floor_depth` bisections down: otherwise a node
        // that lands on a resonance far narrower than the panel (k = 0) is
        // bisected to the float resolution while the error it causes halves
        // with each level anyway. The estimate of the total error is still the
        // sum over all accepted panels; should it exceed rel_tol, the floor is
        // lowered and the pass repeated.
        let mut floor_depth = 8;
        loop {
            self.share_floor = (-(floor_depth as f64)).exp2() / panels as f64;
            self.err.fill(0.0);
            self.unresolved = 0;
            self.panels.clear();
            let mut total = vec![0.0; self.scale.len()];
            for window in (0..panels).collect::<Vec<_>>().chunks(WINDOW) {
                let level = window
                    .iter()
                    .map(|&p| Panel {
                        a: self.u_min + h * p as f64,
                        // `b` is the next panel's `a` exactly, so the rule merges them.
                        b: self.u_min + h * (p + 1) as f64,
                        f: [f[2 * p].clone(), f[2 * p + 1].clone(), f[2 * p + 2].clone()],
                        whole: wholes[p].clone(),
                        depth: 0,
                    })
                    .collect();
                self.adapt(level, &mut total)?;
            }
            if self.rel_error_estimate() <= self.rel_tol || floor_depth >= MAX_DEPTH {
                return Ok(total);
            }
            floor_depth += 8;
        }
    }

    /// Sum of the accepted panels' error estimates relative to each quantity's
    /// scale, worst quantity.
    fn rel_error_estimate(&self) -> f64 {
        self.err
            .iter()
            .zip(&self.scale)
            .map(|(e, s)| e / s)
            .fold(0.0, f64::max)
    }

    /// Adaptive Simpson on the panels of `open`: up to [`BATCH_PANELS`]
    /// open panels at a time are bisected, their new nodes evaluated as one
    /// batch, and the halves that miss the test go back on the stack. Each
    /// panel's test depends on its own values only, so the panels accepted
    /// are those of a depth-first recursion, and the stack (at most
    /// `BATCH_PANELS` per level of depth) bounds the memory. Accepted panels
    /// add their Richardson-corrected sums to `total`.
    fn adapt(&mut self, mut open: Vec<Panel>, total: &mut [f64]) -> Result<(), PhysicsError> {
        while !open.is_empty() {
            let level = open.split_off(open.len().saturating_sub(BATCH_PANELS));
            let us: Vec<f64> = level
                .iter()
                .flat_map(|p| {
                    let m = 0.5 * (p.a + p.b);
                    [0.5 * (p.a + m), 0.5 * (m + p.b)]
                })
                .collect();
            let new = self.eval_batch(&us)?;
            for (p, pair) in level.into_iter().zip(new.chunks(2)) {
                let (flm, frm) = (pair[0].clone(), pair[1].clone());
                let [fa, fm, fb] = p.f;
                let m = 0.5 * (p.a + p.b);
                let w = (p.b - p.a) / 12.0;
                let n = p.whole.len();
                let left: Vec<f64> = (0..n).map(|j| w * (fa[j] + 4.0 * flm[j] + fm[j])).collect();
                let right: Vec<f64> = (0..n).map(|j| w * (fm[j] + 4.0 * frm[j] + fb[j])).collect();
                // |S_left + S_right − S_whole| ≈ 15 × error; the allowance is
                // proportional to the panel's share of the u range, but not
                // below that of a panel `floor_depth` levels down (see
                // `integrate`).
                let share = ((p.b - p.a) / (self.u_max - self.u_min)).max(self.share_floor);
                let ok = (0..n).all(|j| {
                    let d = (left[j] + right[j] - p.whole[j]).abs();
                    d <= 15.0 * self.rel_tol * share * self.scale[j]
                });
                if ok || p.depth >= MAX_DEPTH {
                    if !ok {
                        self.unresolved += 1;
                    }
                    self.panels.push((p.a, p.b));
                    for j in 0..n {
                        let d = left[j] + right[j] - p.whole[j];
                        self.err[j] += d.abs() / 15.0;
                        total[j] += left[j] + right[j] + d / 15.0;
                    }
                    continue;
                }
                open.push(Panel {
                    a: p.a,
                    b: m,
                    f: [fa, flm, fm.clone()],
                    whole: left,
                    depth: p.depth + 1,
                });
                open.push(Panel {
                    a: m,
                    b: p.b,
                    f: [fm, frm, fb],
                    whole: right,
                    depth: p.depth + 1,
                });
            }
        }
        Ok(())
    }

    pub(super) fn finish(&self, t: &[f64]) -> BulkOptics {
        let (c_ext, c_sca) = (t[0], t[1]);
        let (c_abs, albedo) = if self.m.im == 0.0 {
            (0.0, 1.0)
        } else {
            (t[2], (c_sca / c_ext).min(1.0))
        };
        let p: Vec<[f64; 4]> = (0..self.mu.len())
            .map(|i| {
                let b = N_BULK + 4 * i;
                [t[b], t[b + 1], t[b + 2], t[b + 3]]
            })
            .collect();
        let c = 4.0 * PI / (self.k * self.k * c_sca);
        let rel_error_estimate = self.rel_error_estimate();
        BulkOptics {
            c_ext_um2: c_ext,
            c_sca_um2: c_sca,
            c_abs_um2: c_abs,
            albedo,
            g: t[3] / c_sca,
            matrix: mie::matrix_from_products(self.mu, &p, c),
            radius_min_um: self.r_min,
            radius_max_um: self.r_max,
            size_parameter_max: self.k * self.r_max,
            n_radius_nodes: self.evals,
            rel_error_estimate,
            unresolved_panels: self.unresolved,
        }
    }
}

/// Series length an [`AmplitudeTable`] needs for spheres up to `x_max`
/// (two terms of margin for the rounding of `k r` at the upper cut).
pub(super) fn table_terms(x_max: f64) -> usize {
    mie::series_length(x_max.min(mie::SIZE_PARAMETER_MAX)) + 2
}

fn sum_vecs<'v>(n: usize, vs: impl Iterator<Item = &'v Vec<f64>>) -> Vec<f64> {
    let mut s = vec![0.0; n];
    for v in vs {
        for (a, b) in s.iter_mut().zip(v) {
            *a += b;
        }
    }
    s
}
