//! BRDF tables: per wavelength the Fourier coefficients of the 4×4 Mueller
//! BRDF on a polar grid, their interpolation, and point evaluation
//! (docs/table-format.md).
//!
//! **Stored quantity.** For azimuth order `m`, outgoing node `o` and
//! incident node `i`: `f^m(μ_o, μ_i) = ρ^m(μ_o, μ_i) / μ_i`, with `ρ^m` the
//! solver's response ([`solver::ReflectionFourier::rho`]): all `ns × ns`
//! elements of the "S1" set of conventions §7, so that
//!
//! ```text
//! f(μ_o, μ_i, Δφ) = Σ_m (2 − δ_m0)/(2π) [bd(f^m) cos mΔφ + od(f^m) sin mΔφ]      (T1)
//! ```
//!
//! (`bd` keeps the IQ←IQ and UV←UV blocks, `od` the UV←IQ block with `+` and
//! the IQ←UV block with `−`), `Δφ = Δφ_prop = φ_o − φ_i − 180°`.
//!
//! **Interpolation.** Between nodes the smoother product
//! `g^m = (μ_o + μ_i) f^m` (T2) is interpolated by the tensor product of the
//! same 1-D Lagrange scheme on both axes ([`PolarGrid::stencil`]) and divided
//! back by `(μ_o + μ_i)` at the evaluation point; single scattering gives
//! `g = ω P (1 − e^{−τ(1/μ_o + 1/μ_i)})/(4π)`, free of the `1/(μ_o + μ_i)`
//! divergence at the horizon. Then (T1) is summed exactly at `Δφ`. Between
//! wavelengths the Mueller matrices are interpolated linearly.
//!
//! **Specular term** (conventions §6, mirror bases only): per incident node
//! `S(μ_i) = e^{−2τ/μ_i} M_F(μ_i)`, interpolated with the same 1-D scheme.

use super::BrdfError;
use super::angles::{self, Vec3, dphi_prop_rad, mu_of_theta_deg};
pub use super::build::{BuildOptions, BuiltWavelength, build, build_wavelength, plan_grid};
use super::coverage;
use super::grid::{PolarGrid, STENCIL, Stencil};
pub use super::metadata::{Directions, EstimateMeta, Metadata, SolverMeta, WavelengthMeta};
use crate::material::Spec;
use crate::material::needs::StokesNeed;
use crate::physics::RefractiveIndex;
use crate::physics::microfacet::RoughSurface;
use crate::physics::stokes::{Mueller, mul, rotation};
use crate::plan::{self, Plan};
use crate::solver::truncation::{CorrectionLayer, SingleScatterCorrection};
use crate::solver::{self, Settings};
use std::f64::consts::PI;

/// Angular tolerance (radians) within which an outgoing direction "is" the
/// mirror direction of the incident one, so that the specular term is
/// reported (docs/table-format.md): far above the rounding of degrees to
/// unit vectors (~1e-16 rad), far below any physical resolution.
pub const MIRROR_TOLERANCE_RAD: f64 = 1e-6;

/// Which quantity is interpolated in the polar cosines.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolant {
    /// `g^m = (μ_o + μ_i) f^m` (T2), the default.
    SumOfCosines,
    /// `f^m` itself (for comparison only: worse near the horizon).
    Plain,
}

/// One wavelength of a table.
#[derive(Clone, Debug, PartialEq)]
pub struct WavelengthTable {
    /// Vacuum wavelength (nm); `None` for a wavelength-free spec.
    pub wavelength_nm: Option<f64>,
    /// Rows stored: outgoing Stokes components (4 polarized, 1 scalar or
    /// `needs.stokes: "intensity"`).
    pub ns: usize,
    /// Columns stored: incident Stokes components (`ns`, or 1 for
    /// `needs.stokes` other than full: column 0 only).
    pub cols: usize,
    /// Number of polar nodes `N` of the grid (outgoing axis).
    pub nodes: usize,
    /// Grid nodes held on the incident axis, increasing (`0..N` unless
    /// `needs.theta_i_deg`, [`super::coverage::incident_nodes`]).
    pub incident: Vec<usize>,
    /// Number of Fourier orders `M` (`m = 0..M`).
    pub orders: usize,
    /// `f^m(μ_o, μ_i)` (1/sr), element `(p, q)` at
    /// `(((m·N + o)·K + k)·ns + p)·cols + q` with `k` the position of the
    /// incident node in [`WavelengthTable::incident`] (`K` of them).
    pub f: Vec<f64>,
    /// The delta term (conventions §6) per held incident node:
    /// `e^{−2τ/μ_i} M_F(μ_i)` of a mirror base, or the Fresnel reflection
    /// `M(r_{1→n}(μ_i))` of a smooth top interface (conventions §8), else
    /// `None`; elements outside `ns × cols` are zero unless `cols = ns`.
    pub specular: Option<Vec<Mueller>>,
    /// Solver wall time for this wavelength (ms).
    pub wall_time_ms: f64,
    /// The exact-minus-truncated single-scattering BRDF of a delta-M
    /// truncated solve (`solver::truncation`), evaluated in closed form at
    /// every query direction (T3); `None` when no layer was truncated.
    pub correction: Option<StoredCorrection>,
    /// A rough top interface's own reflection (its gloss lobe), evaluated
    /// in closed form at every query direction (T4) and not in `f`
    /// (`solver::rough_interface`); `None` without one.
    pub surface: Option<RoughSurface>,
}

/// The single-scattering correction a table carries: the solver's
/// [`SingleScatterCorrection`] with the Fresnel indices its mirror paths
/// are rebuilt from when the table is read (the closure itself is not
/// data).
#[derive(Clone, Debug)]
pub struct StoredCorrection {
    /// The correction, ready to evaluate.
    pub correction: SingleScatterCorrection,
    /// Ambient and base indices of a Fresnel base under a finite stack.
    pub mirror_indices: Option<(f64, RefractiveIndex)>,
    /// The binder index of a smooth top interface: the correction is
    /// then evaluated inside the binder and carried across it
    /// (`solver::interface`).
    pub interface_index: Option<f64>,
}

impl PartialEq for StoredCorrection {
    fn eq(&self, other: &Self) -> bool {
        let (a, b) = (&self.correction, &other.correction);
        a.layers == b.layers
            && a.polarized == b.polarized
            && a.mirror.as_ref().map(|m| m.1) == b.mirror.as_ref().map(|m| m.1)
            && a.streams == b.streams
            && self.mirror_indices == other.mirror_indices
            && self.interface_index == other.interface_index
    }
}

impl StoredCorrection {
    /// Rebuild from stored parts (`mirror` = scaled stack thickness and the
    /// Fresnel indices; `interface_index` that of a smooth top interface).
    pub fn from_parts(
        layers: Vec<CorrectionLayer>,
        polarized: bool,
        streams: usize,
        mirror: Option<(f64, f64, RefractiveIndex)>,
        interface_index: Option<f64>,
    ) -> Self {
        let top_interface =
            interface_index.map(|index| solver::TopInterface { index, alpha: None });
        Self {
            correction: SingleScatterCorrection {
                layers,
                polarized,
                mirror: mirror.map(|(depth, n1, n2)| (plan::fresnel_mirror(n1, n2), depth)),
                streams,
                quadrature_split: solver::interface_split(top_interface.as_ref()),
            },
            mirror_indices: mirror.map(|(_, n1, n2)| (n1, n2)),
            interface_index,
        }
    }

    /// The correction's BRDF at external cosines `mu_o`, `mu_i` (in air
    /// under a top interface, [`solver::interface::InterfaceMaps`]).
    pub fn brdf(&self, mu_o: f64, mu_i: f64, dphi_prop: f64) -> Mueller {
        let c = &self.correction;
        match self.interface_index {
            None => c.brdf(mu_o, mu_i, dphi_prop),
            Some(index) => match solver::interface::InterfaceMaps::new(index, &[mu_o, mu_i]) {
                Ok(maps) => {
                    let inside = c.brdf(maps.mu_internal[0], maps.mu_internal[1], dphi_prop);
                    maps.external_brdf(0, 1, mu_i, &inside)
                }
                // Validated indices and cosines in [0, 1]: cannot fail.
                Err(_) => [[0.0; 4]; 4],
            },
        }
    }
}

/// A BRDF table: metadata, the polar grid and one block per wavelength
/// (increasing wavelength).
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// JSON metadata.
    pub metadata: Metadata,
    /// Polar nodes (incident and outgoing).
    pub grid: PolarGrid,
    /// Per wavelength, increasing.
    pub wavelengths: Vec<WavelengthTable>,
}

/// A `rows × cols` row-major block as a 4×4 matrix (zeros outside).
fn unflatten(v: &[f64], rows: usize, cols: usize) -> Mueller {
    let mut c = [[0.0; 4]; 4];
    for (p, row) in c.iter_mut().enumerate().take(rows) {
        row[..cols].copy_from_slice(&v[p * cols..p * cols + cols]);
    }
    c
}

pub(super) fn scale(m: &Mueller, a: f64) -> Mueller {
    m.map(|row| row.map(|x| a * x))
}

fn add_scaled(acc: &mut Mueller, m: &Mueller, a: f64) {
    for (r, s) in acc.iter_mut().zip(m) {
        for (x, y) in r.iter_mut().zip(s) {
            *x += a * y;
        }
    }
}

/// The Fourier sum (T1) of per-order coefficients `c[m]` at `dphi_prop`
/// (radians) over the first `ns` rows and columns; scalar coefficients
/// (`ns = 1`) fill `[0][0]` only. Elements outside those stored are zero
/// in `c` and stay zero.
pub fn fourier_synthesis(c: &[Mueller], ns: usize, dphi_prop: f64) -> Mueller {
    let mut f = [[0.0; 4]; 4];
    for (m, cm) in c.iter().enumerate() {
        let w = if m == 0 { 1.0 } else { 2.0 } / (2.0 * PI);
        let (s, co) = (m as f64 * dphi_prop).sin_cos();
        let (wc, ws) = (w * co, w * s);
        for p in 0..ns {
            for q in 0..ns {
                let v = cm[p][q];
                f[p][q] += match (p < 2, q < 2) {
                    (true, true) | (false, false) => v * wc,
                    (false, true) => v * ws,
                    (true, false) => -v * ws,
                };
            }
        }
    }
    f
}

impl WavelengthTable {
    /// Offset of the `ns × cols` block `f^m(μ_o, μ_i)` in
    /// [`WavelengthTable::f`], `i` a grid node held on the incident axis
    /// (panics for one not held: callers check the coverage first,
    /// [`Table::incident_theta`]).
    pub fn offset(&self, m: usize, o: usize, i: usize) -> usize {
        let k = self.incident_position(i);
        ((m * self.nodes + o) * self.incident.len() + k) * self.ns * self.cols
    }

    /// Position of grid node `i` in [`WavelengthTable::incident`].
    pub fn incident_position(&self, i: usize) -> usize {
        if self.incident.len() == self.nodes {
            return i;
        }
        self.incident
            .binary_search(&i)
            .unwrap_or_else(|_| panic!("incident node {i} is not held by this table"))
    }

    /// Does this block hold every incident node and every element?
    pub fn is_complete(&self) -> bool {
        self.incident.len() == self.nodes && self.cols == self.ns
    }

    /// The shape fields without the data (for a derived block).
    pub(super) fn clone_shape(&self) -> Self {
        Self {
            f: Vec::new(),
            specular: None,
            correction: None,
            surface: None,
            incident: self.incident.clone(),
            ..*self
        }
    }

    /// The stored coefficient `f^m` at nodes `(o, i)` as a 4×4 matrix.
    pub fn node(&self, m: usize, o: usize, i: usize) -> Mueller {
        let len = self.ns * self.cols;
        let b = self.offset(m, o, i);
        unflatten(&self.f[b..b + len], self.ns, self.cols)
    }

    /// Interpolated `f^m(μ_o, μ_i)`, `m = 0..M`, at the polar angles
    /// `theta_o_deg`, `theta_i_deg` (T2).
    pub fn coefficients(
        &self,
        grid: &PolarGrid,
        theta_o_deg: f64,
        theta_i_deg: f64,
    ) -> Vec<Mueller> {
        self.coefficients_with(
            grid,
            theta_o_deg,
            theta_i_deg,
            Interpolant::SumOfCosines,
            STENCIL,
        )
    }

    /// [`WavelengthTable::coefficients`] with a chosen interpolant and
    /// stencil size (for measurements; docs/table-format.md).
    pub fn coefficients_with(
        &self,
        grid: &PolarGrid,
        theta_o_deg: f64,
        theta_i_deg: f64,
        what: Interpolant,
        stencil: usize,
    ) -> Vec<Mueller> {
        let so = grid.stencil_of_size(theta_o_deg, stencil);
        let si = grid.stencil_of_size(theta_i_deg, stencil);
        let (mu_o, mu_i) = (mu_of_theta_deg(theta_o_deg), mu_of_theta_deg(theta_i_deg));
        self.combine(grid, &so, &si, mu_o + mu_i, what)
    }

    fn combine(
        &self,
        grid: &PolarGrid,
        so: &Stencil,
        si: &Stencil,
        mu_sum: f64,
        what: Interpolant,
    ) -> Vec<Mueller> {
        let ns2 = self.ns * self.cols;
        // Tensor-product weights, with (μ_a + μ_b)/(μ_o + μ_i) for (T2).
        let mut weights = Vec::with_capacity(so.len * si.len);
        for a in 0..so.len {
            for b in 0..si.len {
                let (o, i) = (so.start + a, si.start + b);
                let w = so.w[a] * si.w[b];
                if w == 0.0 {
                    continue;
                }
                let w = match what {
                    Interpolant::SumOfCosines => w * (grid.mu[o] + grid.mu[i]) / mu_sum,
                    Interpolant::Plain => w,
                };
                weights.push((o, i, w));
            }
        }
        // Offsets of the stencil's blocks at order 0; order `m` is `m`
        // strides further (`WavelengthTable::offset`). The sums run in the
        // same order for every layout, so a full 4 × 4 block (unrolled, for
        // the renderer's millions of lookups) and a partial one give the
        // same bits as the plain loop.
        let stride = self.nodes * self.incident.len() * ns2;
        let blocks: Vec<(usize, f64)> = weights
            .iter()
            .map(|&(o, i, w)| (self.offset(0, o, i), w))
            .collect();
        (0..self.orders)
            .map(|m| {
                let mut acc = [0.0; 16];
                let at = m * stride;
                if ns2 == 16 {
                    for &(b, w) in &blocks {
                        let y: &[f64; 16] = self.f[at + b..at + b + 16]
                            .try_into()
                            .expect("a 16-value block");
                        for (x, y) in acc.iter_mut().zip(y) {
                            *x += w * y;
                        }
                    }
                } else {
                    for &(b, w) in &blocks {
                        for (x, y) in acc.iter_mut().zip(&self.f[at + b..at + b + ns2]) {
                            *x += w * y;
                        }
                    }
                }
                unflatten(&acc, self.ns, self.cols)
            })
            .collect()
    }

    /// The diffuse Mueller BRDF (1/sr, conventions §6) at graphics polar
    /// angles and propagation azimuth difference `dphi_prop` (radians).
    pub fn eval(
        &self,
        grid: &PolarGrid,
        theta_i_deg: f64,
        theta_o_deg: f64,
        dphi_prop: f64,
    ) -> Mueller {
        let mut f = fourier_synthesis(
            &self.coefficients(grid, theta_o_deg, theta_i_deg),
            self.ns,
            dphi_prop,
        );
        self.complete(&mut f, theta_i_deg, theta_o_deg, dphi_prop);
        f
    }

    /// Add the stored single-scattering correction (T3) and a rough top
    /// interface's own reflection (T4), if any, at the exact directions
    /// (they carry the forward peak and the gloss lobe that no Fourier
    /// series of the table's length could), then make the matrix
    /// realizable (`solver::make_realizable`: the interpolation, like a
    /// coarse solve, need not be).
    pub fn complete(&self, f: &mut Mueller, theta_i_deg: f64, theta_o_deg: f64, dphi_prop: f64) {
        let (mu_o, mu_i) = (mu_of_theta_deg(theta_o_deg), mu_of_theta_deg(theta_i_deg));
        let mut add = |d: &Mueller| {
            for (row, drow) in f.iter_mut().zip(d).take(self.ns) {
                for (x, y) in row.iter_mut().zip(drow).take(self.cols) {
                    *x += y;
                }
            }
        };
        if let Some(c) = &self.correction {
            add(&c.brdf(mu_o, mu_i, dphi_prop));
        }
        if let Some(s) = &self.surface {
            add(&s.mueller(mu_o, mu_i, dphi_prop));
        }
        // Cloude filtering needs all 16 elements: a block of fewer
        // (`needs.stokes`) is returned as interpolated.
        if self.ns == 4 && self.cols == 4 {
            solver::make_realizable(f);
        }
    }

    /// Interpolated specular matrix `e^{−2τ/μ_i} M_F(μ_i)` (conventions §6)
    /// in the meridian frames of the incident and the mirror-reflected ray;
    /// `None` unless the base is a mirror.
    pub fn specular_at(&self, grid: &PolarGrid, theta_i_deg: f64) -> Option<Mueller> {
        let spec = self.specular.as_ref()?;
        let st = grid.stencil(theta_i_deg);
        let mut s = [[0.0; 4]; 4];
        for k in 0..st.len {
            if st.w[k] != 0.0 {
                add_scaled(&mut s, &spec[self.incident_position(st.start + k)], st.w[k]);
            }
        }
        Some(s)
    }
}

impl Table {
    /// Build a table (one [`solver::reflection`] per wavelength, [`build`])
    /// with its metadata.
    pub fn from_spec(spec: &Spec, grid: PolarGrid) -> Result<Self, BrdfError> {
        Self::from_spec_with(spec, grid, &BuildOptions::default())
    }

    /// [`Table::from_spec`] with a stream cap for tolerance specs and a
    /// progress sink.
    pub fn from_spec_with(
        spec: &Spec,
        grid: PolarGrid,
        options: &BuildOptions,
    ) -> Result<Self, BrdfError> {
        let plan = Plan::lower(spec)?;
        let built = (0..plan.wavelengths.len())
            .map(|k| build_wavelength(&plan, k, &grid, options))
            .collect::<Result<Vec<_>, _>>()?;
        Self::from_plan(&plan, grid, built)
    }

    /// The table a spec requests: on the grid of its `needs`
    /// ([`plan_grid`]; the default grid without them), as the service
    /// builds it.
    pub fn from_spec_needs(spec: &Spec, options: &BuildOptions) -> Result<Self, BrdfError> {
        let plan = Plan::lower(spec)?;
        let grid = plan_grid(&plan);
        let built = (0..plan.wavelengths.len())
            .map(|k| build_wavelength(&plan, k, &grid, options))
            .collect::<Result<Vec<_>, _>>()?;
        Self::from_plan(&plan, grid, built)
    }

    /// The table of a plan's solved wavelengths (sorted by wavelength), with
    /// its metadata written once: the canonical spec and its id, the
    /// settings, and per wavelength the orders, time, streams and estimate.
    pub fn from_plan(
        plan: &Plan,
        grid: PolarGrid,
        mut built: Vec<BuiltWavelength>,
    ) -> Result<Self, BrdfError> {
        built.sort_by(|a, b| {
            a.block
                .wavelength_nm
                .unwrap_or(0.0)
                .total_cmp(&b.block.wavelength_nm.unwrap_or(0.0))
        });
        if built
            .windows(2)
            .any(|w| w[0].block.wavelength_nm == w[1].block.wavelength_nm)
        {
            return Err(BrdfError::Query("a wavelength is listed twice".into()));
        }
        let metadata = Metadata {
            generator: format!("polbrdf {}", env!("CARGO_PKG_VERSION")),
            spec: plan.canonical_spec(),
            spec_hash: plan.id.clone(),
            solver: solver_meta(&plan.settings, plan.policy),
            grid: grid_description(&grid),
            interpolation: INTERPOLATION.into(),
            conventions: CONVENTIONS.into(),
            wavelengths: built
                .iter()
                .map(|b| WavelengthMeta {
                    wavelength_nm: b.block.wavelength_nm,
                    fourier_orders: b.block.orders,
                    wall_time_ms: b.block.wall_time_ms,
                    streams: b.streams,
                    error_estimate: b.error_estimate.clone(),
                    interpolation_error: b.interpolation_error,
                })
                .collect(),
            stokes: plan.needs.stokes,
            theta_i_deg: plan.needs.theta_i_deg.clone(),
        };
        Ok(Self {
            metadata,
            grid,
            wavelengths: built.into_iter().map(|b| b.block).collect(),
        })
    }

    /// Wavelength blocks and linear weights for `wavelength_nm`
    /// (docs/table-format.md): `None` is allowed for a one-wavelength table;
    /// a wavelength outside the table's range is an error.
    pub fn wavelength_weights(
        &self,
        wavelength_nm: Option<f64>,
    ) -> Result<Vec<(usize, f64)>, BrdfError> {
        let w = &self.wavelengths;
        let Some(wl) = wavelength_nm else {
            return if w.len() == 1 {
                Ok(vec![(0, 1.0)])
            } else {
                Err(BrdfError::Query(format!(
                    "the table has {} wavelengths ({}); give one",
                    w.len(),
                    self.wavelength_list()
                )))
            };
        };
        if !wl.is_finite() {
            return Err(BrdfError::Query(format!("wavelength {wl} nm")));
        }
        let known: Vec<f64> = w.iter().filter_map(|x| x.wavelength_nm).collect();
        if known.len() != w.len() {
            return Err(BrdfError::Query(
                "the table is wavelength-free; give no wavelength".into(),
            ));
        }
        let tol = 1e-9 * wl.abs().max(1.0);
        if let Some(k) = known.iter().position(|&x| (x - wl).abs() <= tol) {
            return Ok(vec![(k, 1.0)]);
        }
        for k in 0..known.len().saturating_sub(1) {
            let (a, b) = (known[k], known[k + 1]);
            if wl > a && wl < b {
                let t = (wl - a) / (b - a);
                return Ok(vec![(k, 1.0 - t), (k + 1, t)]);
            }
        }
        Err(BrdfError::Query(format!(
            "wavelength {wl} nm is outside the table's range ({})",
            self.wavelength_list()
        )))
    }

    fn wavelength_list(&self) -> String {
        self.wavelengths
            .iter()
            .map(|w| w.wavelength_nm.map_or("none".into(), |x| format!("{x} nm")))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The diffuse Mueller BRDF (1/sr) at a direction pair (graphics
    /// convention, degrees) in the meridian frames of conventions §5
    /// (incident ray `k = −ω_i`, outgoing `k = ω_o`): interpolation in the
    /// polar cosines (T2), exact Fourier sum (T1) at
    /// `Δφ_prop = φ_o − φ_i − 180°`, linear in wavelength.
    ///
    /// A table of part of the incident directions (`needs.theta_i_deg`)
    /// refuses any other ([`Table::incident_theta`]); elements it does not
    /// hold (`needs.stokes`) are zero, [`Table::shape`] says which.
    pub fn eval(&self, d: &Directions, wavelength_nm: Option<f64>) -> Result<Mueller, BrdfError> {
        d.validate()?;
        let theta_i = self.incident_theta(d.theta_i_deg)?;
        let dphi = dphi_prop_rad(d.phi_i_deg, d.phi_o_deg);
        let mut f = [[0.0; 4]; 4];
        for (k, w) in self.wavelength_weights(wavelength_nm)? {
            let m = self.wavelengths[k].eval(&self.grid, theta_i, d.theta_o_deg, dphi);
            add_scaled(&mut f, &m, w);
        }
        Ok(f)
    }

    /// [`Table::eval`] at one direction pair for several wavelengths (a
    /// spectral renderer's lane): each wavelength block the wavelengths
    /// need is evaluated once and shared, and every answer is the same, bit
    /// for bit, as [`Table::eval`] at that wavelength.
    pub fn eval_wavelengths(
        &self,
        d: &Directions,
        wavelengths_nm: &[Option<f64>],
    ) -> Result<Vec<Mueller>, BrdfError> {
        d.validate()?;
        let theta_i = self.incident_theta(d.theta_i_deg)?;
        let dphi = dphi_prop_rad(d.phi_i_deg, d.phi_o_deg);
        let mut blocks: Vec<Option<Mueller>> = vec![None; self.wavelengths.len()];
        wavelengths_nm
            .iter()
            .map(|&wl| {
                let mut f = [[0.0; 4]; 4];
                for (k, w) in self.wavelength_weights(wl)? {
                    let m = blocks[k].get_or_insert_with(|| {
                        self.wavelengths[k].eval(&self.grid, theta_i, d.theta_o_deg, dphi)
                    });
                    add_scaled(&mut f, m, w);
                }
                Ok(f)
            })
            .collect()
    }

    /// The specular matrix `S` (conventions §6: `∫ L_out dΩ = S F_beam`
    /// around the mirror direction) when the base is a mirror **and** `ω_o`
    /// is the mirror direction `(θ_i, φ_i + 180°)` of `ω_i` within
    /// [`MIRROR_TOLERANCE_RAD`]; else `None`. In the meridian frames of the
    /// query: at normal incidence the reflected frame at `φ_o` is turned by
    /// `σ = φ_o − φ_i − 180°` from the mirror frame, `S' = L(σ) S`.
    pub fn specular(
        &self,
        d: &Directions,
        wavelength_nm: Option<f64>,
    ) -> Result<Option<Mueller>, BrdfError> {
        d.validate()?;
        let theta_i = self.incident_theta(d.theta_i_deg)?;
        let weights = self.wavelength_weights(wavelength_nm)?;
        if self.wavelengths.iter().all(|w| w.specular.is_none()) {
            return Ok(None);
        }
        if !is_mirror_pair(d) {
            return Ok(None);
        }
        let mut s = [[0.0; 4]; 4];
        for (k, w) in weights {
            if let Some(m) = self.wavelengths[k].specular_at(&self.grid, theta_i) {
                add_scaled(&mut s, &m, w);
            }
        }
        let sigma = dphi_prop_rad(d.phi_i_deg, d.phi_o_deg);
        Ok(Some(mul(&rotation(sigma), &s)))
    }

    /// The incident polar angle to evaluate a query's `theta_i_deg` at:
    /// itself when the table covers it, else a query error naming
    /// `theta_i_deg` and `needs.theta_i_deg` ([`coverage::incident_theta`]).
    pub fn incident_theta(&self, theta_i_deg: f64) -> Result<f64, BrdfError> {
        coverage::incident_theta(self.metadata.theta_i_deg.as_ref(), theta_i_deg)
    }

    /// Rows and columns of the Mueller matrices this table answers with:
    /// 4 × 4 for the full product (a scalar table's zeros included, as
    /// always), 4 × 1 for `needs.stokes: "unpolarized_in"`, 1 × 1 for
    /// `"intensity"`.
    pub fn shape(&self) -> (usize, usize) {
        match self.metadata.stokes {
            StokesNeed::Full => (4, 4),
            s => s.shape(self.wavelengths.first().map_or(4, |w| w.ns.max(w.cols))),
        }
    }

    /// Does the table hold every element at every incident direction (what
    /// a dense, Mitsuba or render use needs)? Else a query error naming
    /// `what` and what the table lacks.
    pub fn require_complete(&self, what: &str) -> Result<(), BrdfError> {
        coverage::require_complete(self, what)
    }

    /// Total number of stored coefficients.
    pub fn values(&self) -> usize {
        self.wavelengths.iter().map(|w| w.f.len()).sum()
    }
}

/// Is `ω_o` the mirror direction of `ω_i` (within [`MIRROR_TOLERANCE_RAD`])?
pub fn is_mirror_pair(d: &Directions) -> bool {
    let wi = angles::direction(d.theta_i_deg, d.phi_i_deg);
    let wo = angles::direction(d.theta_o_deg, d.phi_o_deg);
    let mirror: Vec3 = [-wi[0], -wi[1], wi[2]];
    angles::angle_between(wo, mirror) <= MIRROR_TOLERANCE_RAD
}

/// The solver metadata of a request with these settings and policy.
pub(super) fn solver_meta(settings: &Settings, policy: plan::StreamPolicy) -> SolverMeta {
    SolverMeta {
        streams: settings.streams,
        tolerance: match policy {
            plan::StreamPolicy::Tolerance(t) => Some(t),
            plan::StreamPolicy::Fixed(_) => None,
        },
        polarized: settings.polarized,
        start_factor: settings.start_factor,
        fourier_tolerance: settings.fourier_tolerance,
        max_order: settings.max_order,
    }
}

pub(super) fn grid_description(grid: &PolarGrid) -> String {
    let uniform_s = grid
        .s
        .iter()
        .enumerate()
        .all(|(k, &s)| (s - k as f64 / (grid.len() - 1) as f64).abs() < 1e-12);
    if uniform_s {
        format!(
            "{} polar nodes theta = 90 deg * sin(pi k / (2 ({} - 1))), k = 0..{}, shared by incident and outgoing directions; theta = 90 deg evaluated at mu = 1e-6",
            grid.len(),
            grid.len(),
            grid.len()
        )
    } else {
        format!(
            "{} polar nodes (listed), shared by incident and outgoing directions",
            grid.len()
        )
    }
}

const INTERPOLATION: &str = "polar: tensor-product Lagrange interpolation of degree 5 (6 nearest nodes) in s = (2/pi) asin(theta / 90 deg) of g^m = (mu_o + mu_i) f^m, divided by (mu_o + mu_i); azimuth: exact Fourier sum at dphi_prop = phi_o - phi_i - 180 deg; wavelength: linear";

const CONVENTIONS: &str = "docs/conventions.md: graphics directions (sec. 5), Mueller BRDF in 1/sr in the meridian frames of the incident ray k = -w_i and the outgoing ray k = w_o (sec. 5, 6), f^m = rho^m / mu_i of the S1 Fourier set (sec. 7)";

#[cfg(test)]
mod tests {
    use super::*;

    fn table(base: &str) -> Table {
        let text = format!(
            r#"{{"layers": [{{"optical_thickness": 0.4,
                 "scatterer": {{"rayleigh": {{"albedo": 0.95}}}}}}],
                "base": {base}, "solver": {{"streams": 4}}}}"#
        );
        let spec = crate::material::parse(&text).unwrap();
        Table::from_spec(&spec, PolarGrid::graded(8).unwrap()).unwrap()
    }

    /// The shared-block evaluation is `eval` at each wavelength, bit for
    /// bit, at nodes, between them and for a one-wavelength table; its
    /// errors are `eval`'s.
    #[test]
    fn eval_wavelengths_is_eval_at_each_wavelength() {
        let text = r#"{"layers": [{"optical_thickness": 0.4,
             "scatterer": {"mie": {"material": {"n": 1.5, "k": 0.01}, "radius_um": 0.1}}}],
             "base": {"lambertian": {"albedo": 0.2}}, "wavelengths_nm": [400, 500, 700],
             "solver": {"streams": 4}}"#;
        let spec = crate::material::parse(text).unwrap();
        let t = Table::from_spec(&spec, PolarGrid::graded(8).unwrap()).unwrap();
        let q = d(33.0, 12.0, 61.0, 250.0);
        let wls = [
            Some(450.0),
            Some(400.0),
            Some(650.0),
            Some(450.0),
            Some(700.0),
        ];
        let all = t.eval_wavelengths(&q, &wls).unwrap();
        for (wl, m) in wls.iter().zip(&all) {
            assert_eq!(*m, t.eval(&q, *wl).unwrap(), "{wl:?}");
        }
        assert!(all[0] != all[2]);
        assert!(t.eval_wavelengths(&q, &[Some(800.0)]).is_err());
        assert!(
            t.eval_wavelengths(&d(95.0, 0.0, 10.0, 0.0), &[Some(450.0)])
                .is_err()
        );
        let one = table("\"black\"");
        assert_eq!(
            one.eval_wavelengths(&q, &[None]).unwrap()[0],
            one.eval(&q, None).unwrap()
        );
    }

    fn d(ti: f64, pi: f64, to: f64, po: f64) -> Directions {
        Directions {
            theta_i_deg: ti,
            phi_i_deg: pi,
            theta_o_deg: to,
            phi_o_deg: po,
        }
    }

    /// A delta-M truncated solve (Mie x ≈ 11, ~25 terms, at 4 streams,
    /// which integrate 8): at the nodes the table's BRDF (T3) equals the
    /// solver's (Fourier part plus the single-scattering correction), over
    /// black and a Fresnel base (mirror paths), and the correction is a
    /// large part of it at the grazing forward pair (so leaving it out, as
    /// format version 1 did, fails this test).
    #[test]
    fn truncated_tables_carry_the_single_scattering_correction() {
        for base in [
            r#""black""#,
            r#"{"fresnel": {"material": {"n": 0.14, "k": 4.1}}}"#,
        ] {
            let text = format!(
                r#"{{"layers": [{{"optical_thickness": 0.5, "scatterer": {{"mie": {{
                     "material": {{"n": 1.5, "k": 0.001}}, "radius_um": 1.0, "host_index": 1.0}}}}}}],
                    "base": {base}, "wavelengths_nm": [550], "solver": {{"streams": 4}}}}"#
            );
            let spec = crate::material::parse(&text).unwrap();
            let grid = PolarGrid::graded(8).unwrap();
            let t = Table::from_spec(&spec, grid.clone()).unwrap();
            let wt = &t.wavelengths[0];
            let stored = wt.correction.as_ref().expect("truncated solve");
            assert_eq!(stored.mirror_indices.is_some(), base != r#""black""#);
            let p = plan::problem(&spec, Some(550.0)).unwrap();
            let r = solver::reflection(&p, &grid.mu).unwrap();
            let (mut worst, mut scale, mut share) = (0.0f64, 0.0f64, 0.0f64);
            for o in 0..grid.len() {
                for i in 0..grid.len() {
                    for k in 0..7 {
                        let dphi = PI * k as f64 / 6.0;
                        let a = wt.eval(&t.grid, grid.theta_deg[i], grid.theta_deg[o], dphi);
                        let b = r.brdf(o, i, dphi);
                        let c = stored.correction.brdf(grid.mu[o], grid.mu[i], dphi);
                        for (x, y) in a.iter().flatten().zip(b.iter().flatten()) {
                            worst = worst.max((x - y).abs());
                        }
                        scale = scale.max(b[0][0]);
                        share = share.max(c[0][0] / b[0][0]);
                    }
                }
            }
            assert!(worst <= 1e-12 * scale, "{base}: {worst:e} of {scale:e}");
            assert!(
                share > 0.1,
                "{base}: the correction is at most {share} of f11"
            );
        }
    }

    /// Two blocks at 500 and 600 nm, the second twice the first: the BRDF at
    /// 575 nm is 1.75 times the first (linear in wavelength); outside the
    /// range and without a wavelength it is an error.
    #[test]
    fn wavelengths_are_interpolated_linearly() {
        let mut t = table(r#""black""#);
        let mut a = t.wavelengths[0].clone();
        a.wavelength_nm = Some(500.0);
        let mut b = a.clone();
        b.wavelength_nm = Some(600.0);
        b.f.iter_mut().for_each(|x| *x *= 2.0);
        t.wavelengths = vec![a, b];
        let q = d(20.0, 0.0, 50.0, 120.0);
        let f0 = t.eval(&q, Some(500.0)).unwrap();
        let f = t.eval(&q, Some(575.0)).unwrap();
        for i in 0..4 {
            for j in 0..4 {
                assert!((f[i][j] - 1.75 * f0[i][j]).abs() <= 1e-14 * f0[0][0]);
            }
        }
        assert!(t.eval(&q, Some(650.0)).is_err());
        assert!(t.eval(&q, None).is_err());
        assert!(t.eval(&d(20.0, 0.0, 95.0, 0.0), Some(550.0)).is_err());
    }

    /// A spec with `solver.tolerance` (and no `solver.streams`) is solved
    /// as `polbrdf solve` does it: the cheapest power-of-two streams meeting
    /// the tolerance, recorded per wavelength with the estimate; a spec
    /// with fixed streams records its estimate too (from `N/2` and `3N/4`).
    #[test]
    fn tolerance_specs_record_streams_and_estimate() {
        let spec = crate::material::parse(
            r#"{"layers": [{"optical_thickness": 0.4,
                 "scatterer": {"rayleigh": {"albedo": 0.95}}}],
                "solver": {"tolerance": 1e-3}}"#,
        )
        .unwrap();
        let t = Table::from_spec(&spec, PolarGrid::graded(8).unwrap()).unwrap();
        assert_eq!(t.metadata.solver.tolerance, Some(1e-3));
        let w = &t.metadata.wavelengths[0];
        let e = w.error_estimate.as_ref().expect("estimate");
        assert_eq!(w.streams, e.streams[2]);
        assert!(e.max_err_f11 <= 1e-3 || w.streams * 2 > crate::material::MAX_STREAMS);
        let fixed = table(r#""black""#);
        assert_eq!(fixed.metadata.wavelengths[0].streams, 4);
        let e = fixed.metadata.wavelengths[0]
            .error_estimate
            .as_ref()
            .expect("estimate");
        assert_eq!(e.streams, [2, 3, 4]);
        assert!(e.max_err_f11 > 0.0 && e.max_err_f11 < 1.0, "{e:?}");
    }

    /// The specular term is reported for mirror pairs only, and at normal
    /// incidence in the query's frames: `L(φ_o − φ_i − 180°) S`.
    #[test]
    fn specular_only_for_mirror_pairs() {
        let t = table(r#"{"fresnel": {"material": {"n": 1.5, "k": 0.0}}}"#);
        let s = t
            .specular(&d(30.0, 10.0, 30.0, 190.0), None)
            .unwrap()
            .unwrap();
        let direct = t.wavelengths[0].specular_at(&t.grid, 30.0).unwrap();
        assert!(
            s.iter()
                .flatten()
                .zip(direct.iter().flatten())
                .all(|(a, b)| (a - b).abs() < 1e-15)
        );
        assert!(
            t.specular(&d(30.0, 10.0, 30.0, 190.01), None)
                .unwrap()
                .is_none()
        );
        assert!(
            t.specular(&d(30.0, 10.0, 31.0, 190.0), None)
                .unwrap()
                .is_none()
        );
        // Normal incidence: every φ_o is the mirror direction.
        let s0 = t.specular(&d(0.0, 0.0, 0.0, 180.0), None).unwrap().unwrap();
        let s1 = t
            .specular(&d(0.0, 0.0, 0.0, 180.0 + 35.0), None)
            .unwrap()
            .unwrap();
        let expect = mul(&rotation(35f64.to_radians()), &s0);
        for i in 0..4 {
            for j in 0..4 {
                assert!((s1[i][j] - expect[i][j]).abs() < 1e-15);
            }
        }
        // No specular term over a black base.
        let b = table(r#""black""#);
        assert!(
            b.specular(&d(30.0, 10.0, 30.0, 190.0), None)
                .unwrap()
                .is_none()
        );
    }

    /// At normal incidence the meridian frame of the incident ray is the
    /// `θ → 0` limit at `φ_i` (conventions §5): turning `φ_i` by `α` at
    /// fixed `ω_o` is the frame rotation `L(−α)` of the incident Stokes
    /// vector (the frame `(cos α, sin α, 0)` is at `σ = −α` from `x` towards
    /// `y = −ẑ × x`), so `f(φ_i = α) = f(φ_i = 0) L(α)`.
    #[test]
    fn normal_incidence_frames_are_continuous() {
        let t = table(r#"{"lambertian": {"albedo": 0.3}}"#);
        let alpha = 0.7f64;
        let f0 = t.eval(&d(0.0, 0.0, 40.0, 100.0), None).unwrap();
        let fa = t
            .eval(&d(0.0, alpha.to_degrees(), 40.0, 100.0), None)
            .unwrap();
        let expect = mul(&f0, &rotation(alpha));
        for i in 0..4 {
            for j in 0..4 {
                assert!((fa[i][j] - expect[i][j]).abs() < 1e-12 * f0[0][0], "{i}{j}");
            }
        }
    }
}
