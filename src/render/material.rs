//! BRDF tables as sphere materials: the renderer's hot path.
//!
//! [`TableBrdf::eval`] computes exactly what `Table::eval` computes —
//! interpolation of `g^m = (μ_o + μ_i) f^m` on the tensor-product stencil
//! (docs/table-format.md, T2) and the Fourier sum (T1) — for all colour
//! channels of one direction pair at once: the stencils, the
//! `(μ_a + μ_b)/(μ_o + μ_i)` weights and the azimuth factors are computed
//! once per pair instead of once per channel, no per-order vectors are
//! allocated, and `cos mΔφ`, `sin mΔφ` come from the angle-addition
//! recurrence. Agreement with `Table::eval` is a unit test.

use crate::brdf::angles::{Vec3, dphi_prop_rad, mu_of_theta_deg};
use crate::brdf::frames::directions_of_vectors;
use crate::brdf::table::{Directions, Table};
use crate::brdf::{BrdfError, grid::MAX_STENCIL};
use crate::physics::stokes::Mueller;
use std::f64::consts::PI;
use std::sync::Arc;

/// Largest number of colour channels (RGB).
pub const MAX_CHANNELS: usize = 3;

/// One channel: its wavelength (`None`: the table's only one) and the
/// (wavelength block, linear weight) pairs that make it.
type Channel = (Option<f64>, Vec<(usize, f64)>);

/// A BRDF table evaluated at the renderer's channel wavelengths.
#[derive(Clone, Debug)]
pub struct TableBrdf {
    table: Arc<Table>,
    /// Per channel: the channel's wavelength and its (block, weight) pairs.
    channels: Vec<Channel>,
    /// Wavelength blocks used by any channel.
    blocks: Vec<usize>,
    has_specular: bool,
}

impl TableBrdf {
    /// Prepare `table` for the channel wavelengths (`None`: the table's only
    /// wavelength); a wavelength outside the table's range is an error.
    pub fn new(table: Arc<Table>, wavelengths_nm: &[Option<f64>]) -> Result<Self, BrdfError> {
        // Light at any incident direction; polarized light too unless the
        // table is `needs.stokes: "unpolarized_in"`, which the scene planner
        // (`render::scene_plan`) asks for only when no polarized light can
        // reach the sphere: then its columns 1-3 (zero here) meet only zero
        // Stokes components.
        if table.metadata.theta_i_deg.is_some()
            || table.metadata.stokes == crate::material::needs::StokesNeed::Intensity
        {
            table.require_complete("rendering")?;
        }
        if wavelengths_nm.is_empty() || wavelengths_nm.len() > MAX_CHANNELS {
            return Err(BrdfError::Query(format!(
                "1 to {MAX_CHANNELS} channels, got {}",
                wavelengths_nm.len()
            )));
        }
        let mut channels = Vec::new();
        let mut blocks: Vec<usize> = Vec::new();
        for &wl in wavelengths_nm {
            let w = table.wavelength_weights(wl)?;
            for &(b, _) in &w {
                if !blocks.contains(&b) {
                    blocks.push(b);
                }
            }
            channels.push((wl, w));
        }
        let has_specular = table.wavelengths.iter().any(|w| w.specular.is_some());
        Ok(Self {
            table,
            channels,
            blocks,
            has_specular,
        })
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.channels.len()
    }

    /// The table.
    pub fn table(&self) -> &Table {
        &self.table
    }

    /// Whether the table has a mirror base (a specular delta, conventions §6).
    pub fn has_specular(&self) -> bool {
        self.has_specular
    }

    /// The diffuse Mueller BRDF (1/sr) per channel for unit vectors in the
    /// local shading frame (`z` = normal, both away from the surface), in the
    /// meridian frames of conventions §5 — `Table::eval_vectors` for every
    /// channel. Writes `out[0..channels]`.
    pub fn eval(
        &self,
        wi: Vec3,
        wo: Vec3,
        out: &mut [Mueller; MAX_CHANNELS],
    ) -> Result<(), BrdfError> {
        let d = directions_of_vectors(wi, wo)?;
        self.eval_directions(&d, out);
        Ok(())
    }

    /// [`TableBrdf::eval`] at graphics angles (already validated).
    pub fn eval_directions(&self, d: &Directions, out: &mut [Mueller; MAX_CHANNELS]) {
        let t = &*self.table;
        let grid = &t.grid;
        let so = grid.stencil(d.theta_o_deg);
        let si = grid.stencil(d.theta_i_deg);
        let mu_sum = mu_of_theta_deg(d.theta_o_deg) + mu_of_theta_deg(d.theta_i_deg);
        // Step 1: tensor-product weights with (μ_a + μ_b)/(μ_o + μ_i) (T2).
        let mut weights = [(0usize, 0usize, 0.0f64); MAX_STENCIL * MAX_STENCIL];
        let mut nw = 0;
        for a in 0..so.len {
            for b in 0..si.len {
                let w = so.w[a] * si.w[b];
                if w == 0.0 {
                    continue;
                }
                let (o, i) = (so.start + a, si.start + b);
                weights[nw] = (o, i, w * (grid.mu[o] + grid.mu[i]) / mu_sum);
                nw += 1;
            }
        }
        let weights = &weights[..nw];
        // Step 2: per block, interpolate each order and add it to (T1).
        let dphi = dphi_prop_rad(d.phi_i_deg, d.phi_o_deg);
        let (s1, c1) = dphi.sin_cos();
        let mut per_block = [[[0.0; 4]; 4]; MAX_CHANNELS];
        for (slot, &b) in self.blocks.iter().enumerate() {
            let wt = &t.wavelengths[b];
            // Rows × columns stored per node (4 × 1 for `unpolarized_in`).
            let (ns, cols) = (wt.ns, wt.cols);
            let ns2 = ns * cols;
            let mut f = [[0.0; 4]; 4];
            let (mut cm, mut sm) = (1.0f64, 0.0f64);
            for m in 0..wt.orders {
                let mut acc = [0.0; 16];
                for &(o, i, w) in weights {
                    let off = wt.offset(m, o, i);
                    for (x, y) in acc[..ns2].iter_mut().zip(&wt.f[off..off + ns2]) {
                        *x += w * y;
                    }
                }
                let norm = if m == 0 { 1.0 } else { 2.0 } / (2.0 * PI);
                let (wc, ws) = (norm * cm, norm * sm);
                for p in 0..ns {
                    for q in 0..cols {
                        let v = acc[p * cols + q];
                        f[p][q] += match (p < 2, q < 2) {
                            (true, true) | (false, false) => v * wc,
                            (false, true) => v * ws,
                            (true, false) => -v * ws,
                        };
                    }
                }
                (cm, sm) = (cm * c1 - sm * s1, sm * c1 + cm * s1);
            }
            // The single-scattering correction (T3) and realizability, as
            // `WavelengthTable::eval` does.
            wt.complete(&mut f, d.theta_i_deg, d.theta_o_deg, dphi);
            per_block[slot] = f;
        }
        // Step 3: channels are linear combinations of blocks (wavelength).
        for (c, (_, ws)) in self.channels.iter().enumerate() {
            let mut m = [[0.0; 4]; 4];
            for &(b, w) in ws {
                let slot = self.blocks.iter().position(|&x| x == b).expect("block");
                for (r, s) in m.iter_mut().zip(&per_block[slot]) {
                    for (x, y) in r.iter_mut().zip(s) {
                        *x += w * y;
                    }
                }
            }
            out[c] = m;
        }
    }

    /// The specular matrix per channel (conventions §6, `Table::specular`):
    /// `Some` when the base is a mirror and `wo` is the mirror direction of
    /// `wi`; in the meridian frames of the incident and reflected rays.
    pub fn specular(
        &self,
        wi: Vec3,
        wo: Vec3,
        out: &mut [Mueller; MAX_CHANNELS],
    ) -> Result<bool, BrdfError> {
        if !self.has_specular {
            return Ok(false);
        }
        let d = directions_of_vectors(wi, wo)?;
        for (c, (wl, _)) in self.channels.iter().enumerate() {
            match self.table.specular(&d, *wl)? {
                Some(s) => out[c] = s,
                None => return Ok(false),
            }
        }
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::angles::direction;
    use crate::brdf::grid::PolarGrid;

    fn rayleigh_table(base: &str, wavelengths: Option<&[f64]>) -> Table {
        let text = format!(
            r#"{{"layers": [{{"optical_thickness": 0.5,
                 "scatterer": {{"rayleigh": {{"albedo": 0.9}}}}}}],
                "base": {base}, "solver": {{"streams": 6}}}}"#
        );
        let spec = crate::material::parse(&text).unwrap();
        let mut t = Table::from_spec(&spec, PolarGrid::graded(12).unwrap()).unwrap();
        if let Some(wls) = wavelengths {
            // Same optics at several wavelengths, scaled so that they differ.
            let first = t.wavelengths[0].clone();
            t.wavelengths = wls
                .iter()
                .enumerate()
                .map(|(k, &wl)| {
                    let mut b = first.clone();
                    b.wavelength_nm = Some(wl);
                    b.f.iter_mut().for_each(|x| *x *= 1.0 + 0.25 * k as f64);
                    b
                })
                .collect();
        }
        t
    }

    /// The fused evaluation equals `Table::eval` per channel (to 1e-13 of
    /// max |f|: the only difference is the cos/sin recurrence), on and off
    /// the nodes, at the horizon and at normal incidence, with wavelengths
    /// on and between the table's.
    #[test]
    fn equals_table_eval() {
        let t = Arc::new(rayleigh_table(
            r#"{"lambertian": {"albedo": 0.4}}"#,
            Some(&[450.0, 550.0, 650.0]),
        ));
        let wls = [Some(450.0), Some(600.0), Some(650.0)];
        let brdf = TableBrdf::new(t.clone(), &wls).unwrap();
        assert_eq!(brdf.channels(), 3);
        let mut out = [[[0.0; 4]; 4]; MAX_CHANNELS];
        for (ti, pi, to, po) in [
            (30.0, 10.0, 45.0, 200.0),
            (0.0, 0.0, 60.0, 33.0),
            (t.grid.theta_deg[5], 0.0, t.grid.theta_deg[7], 90.0),
            (89.99, -40.0, 90.0, 170.0),
            (71.3, 123.0, 0.0, 0.0),
        ] {
            let (wi, wo) = (direction(ti, pi), direction(to, po));
            brdf.eval(wi, wo, &mut out).unwrap();
            for (c, wl) in wls.iter().enumerate() {
                let expect = t.eval_vectors(wi, wo, *wl).unwrap();
                let scale = expect.iter().flatten().fold(0.0f64, |a, x| a.max(x.abs()));
                for i in 0..4 {
                    for j in 0..4 {
                        assert!(
                            (out[c][i][j] - expect[i][j]).abs() <= 1e-13 * scale,
                            "{ti} {pi} {to} {po} channel {c} [{i}][{j}]: {} vs {}",
                            out[c][i][j],
                            expect[i][j]
                        );
                    }
                }
            }
        }
        assert!(TableBrdf::new(t.clone(), &[Some(700.0)]).is_err());
        assert!(TableBrdf::new(t, &[]).is_err());
    }

    /// Mirror bases report the specular matrix of `Table::specular` at
    /// mirror pairs only.
    #[test]
    fn specular_only_at_mirror_pairs() {
        let t = Arc::new(rayleigh_table(
            r#"{"fresnel": {"material": {"n": 1.5, "k": 0.0}}}"#,
            None,
        ));
        let brdf = TableBrdf::new(t.clone(), &[None]).unwrap();
        assert!(brdf.has_specular());
        let mut out = [[[0.0; 4]; 4]; MAX_CHANNELS];
        let (wi, wo) = (direction(40.0, 20.0), direction(40.0, 200.0));
        assert!(brdf.specular(wi, wo, &mut out).unwrap());
        let expect = t
            .specular(&directions_of_vectors(wi, wo).unwrap(), None)
            .unwrap()
            .unwrap();
        assert_eq!(out[0], expect);
        assert!(!brdf.specular(wi, direction(41.0, 200.0), &mut out).unwrap());
    }
}
