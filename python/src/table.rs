//! `polbrdf._native.NativeTable`: a loaded BRDF table and its vectorized
//! point evaluation (docs/python.md; the Python class `polbrdf.Table` wraps
//! it and does the broadcasting).
//!
//! Directions are graphics-convention unit vectors pointing away from the
//! surface (conventions §5): `ω = (sinθ cosφ, sinθ sinφ, cosθ)`, light
//! arriving along `−ω_i`, leaving along `ω_o`. Each pair is turned into
//! angles once ([`angles::angles_of`]) and evaluated by [`Table::eval`], the
//! code behind `polbrdf eval` and the service's point queries, so Python
//! answers exactly what they answer.

use crate::{QueryError, brdf_error};
use numpy::ndarray::{Array3, Array4};
use numpy::{
    IntoPyArray, PyArray3, PyArray4, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use polbrdf::brdf::format::{self, DataType};
use polbrdf::brdf::{BrdfError, Directions, Table, angles};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rayon::prelude::*;

type Mueller = [[f64; 4]; 4];

/// A polbrdf table (docs/table-format.md) held in Rust.
#[pyclass(module = "polbrdf._native", frozen)]
pub struct NativeTable {
    table: Table,
}

impl NativeTable {
    pub fn new(table: Table) -> Self {
        Self { table }
    }

    /// The table's wavelengths that are known (nm), increasing.
    fn known_wavelengths(&self) -> Vec<f64> {
        self.table
            .wavelengths
            .iter()
            .filter_map(|w| w.wavelength_nm)
            .collect()
    }

    /// Per pair: the wavelength to evaluate at (`None` for a one-wavelength
    /// or wavelength-free table when none is given), clamped to the table's
    /// range when asked.
    fn wavelengths_for(
        &self,
        n: usize,
        wavelength_nm: Option<PyReadonlyArray1<'_, f64>>,
        clamp: bool,
    ) -> PyResult<Vec<Option<f64>>> {
        let Some(wl) = wavelength_nm else {
            return Ok(vec![None; n]);
        };
        let wl = wl.as_array();
        if wl.len() != n {
            return Err(QueryError::new_err(format!(
                "wavelength_nm has {} values for {n} direction pairs",
                wl.len()
            )));
        }
        Ok(self.clamped(wl.iter().copied().collect(), clamp))
    }

    /// Wavelengths as queries, clamped to the table's range when asked.
    fn clamped(&self, wl: Vec<f64>, clamp: bool) -> Vec<Option<f64>> {
        let known = self.known_wavelengths();
        let range = known.first().zip(known.last());
        wl.into_iter()
            .map(|x| match (clamp, range) {
                (true, Some((&lo, &hi))) if x.is_finite() => Some(x.clamp(lo, hi)),
                _ => Some(x),
            })
            .collect()
    }
}

/// `(n, 3)` directions as rows, refusing another shape or a direction below
/// the surface.
fn directions(name: &str, a: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<[f64; 3]>> {
    if a.shape()[1] != 3 {
        return Err(QueryError::new_err(format!(
            "{name} must have shape (n, 3), got {:?}",
            a.shape()
        )));
    }
    let v = a.as_array();
    let mut out = Vec::with_capacity(v.nrows());
    for (k, r) in v.rows().into_iter().enumerate() {
        let w = [r[0], r[1], r[2]];
        if !w.iter().all(|x| x.is_finite()) || w == [0.0; 3] {
            return Err(QueryError::new_err(format!(
                "{name}[{k}] = {w:?} is not a direction"
            )));
        }
        if w[2] < 0.0 {
            return Err(QueryError::new_err(format!(
                "{name}[{k}] = {w:?} points into the surface (z < 0); directions point away from it (conventions §5)"
            )));
        }
        out.push(w);
    }
    Ok(out)
}

/// The graphics angles of a direction pair.
fn pair(wi: [f64; 3], wo: [f64; 3]) -> Directions {
    let (theta_i_deg, phi_i_deg) = angles::angles_of(wi);
    let (theta_o_deg, phi_o_deg) = angles::angles_of(wo);
    Directions {
        theta_i_deg: theta_i_deg.min(90.0),
        phi_i_deg,
        theta_o_deg: theta_o_deg.min(90.0),
        phi_o_deg,
    }
}

/// `n` Mueller matrices as an `(n, 4, 4)` array.
fn to_array<'py>(py: Python<'py>, m: Vec<Mueller>) -> Bound<'py, PyArray3<f64>> {
    let n = m.len();
    let flat: Vec<f64> = m.into_iter().flatten().flatten().collect();
    Array3::from_shape_vec((n, 4, 4), flat)
        .expect("n 4x4 matrices")
        .into_pyarray(py)
}

/// Evaluate `f` for every pair in parallel; the first error (by index) wins.
fn par_eval<F>(n: usize, f: F) -> Result<Vec<Mueller>, (usize, BrdfError)>
where
    F: Fn(usize) -> Result<Mueller, BrdfError> + Sync,
{
    (0..n)
        .into_par_iter()
        .map(|k| f(k).map_err(|e| (k, e)))
        .collect()
}

fn indexed(py: Python<'_>, (k, e): (usize, BrdfError)) -> PyErr {
    match e {
        BrdfError::Query(q) => QueryError::new_err(format!("pair {k}: {q}")),
        other => brdf_error(py, other),
    }
}

#[pymethods]
impl NativeTable {
    /// The diffuse Mueller BRDF (1/sr) at `n` direction pairs: `wi`, `wo`
    /// of shape `(n, 3)`, `wavelength_nm` of shape `(n,)` or `None`; an
    /// `(n, 4, 4)` array in the meridian frames of conventions §5.
    #[pyo3(signature = (wi, wo, wavelength_nm=None, clamp_wavelength=false))]
    fn eval_flat<'py>(
        &self,
        py: Python<'py>,
        wi: PyReadonlyArray2<'py, f64>,
        wo: PyReadonlyArray2<'py, f64>,
        wavelength_nm: Option<PyReadonlyArray1<'py, f64>>,
        clamp_wavelength: bool,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let wi = directions("wi", &wi)?;
        let wo = directions("wo", &wo)?;
        if wi.len() != wo.len() {
            return Err(QueryError::new_err(format!(
                "wi has {} directions and wo {}",
                wi.len(),
                wo.len()
            )));
        }
        let wl = self.wavelengths_for(wi.len(), wavelength_nm, clamp_wavelength)?;
        let table = &self.table;
        let m = py
            .detach(|| par_eval(wi.len(), |k| table.eval(&pair(wi[k], wo[k]), wl[k])))
            .map_err(|e| indexed(py, e))?;
        Ok(to_array(py, m))
    }

    /// For the Mitsuba plugin (`polbrdf.mitsuba`): `D f D · cos` at `n`
    /// lanes (light `wi`, viewer `wo`, `(n, 3)`) and `c` wavelengths each
    /// (`wavelength_nm` `(n, c)`, clamped to the table's range; `None` for a
    /// wavelength-free table), with `D = diag(1, 1, 1, −1)` (Mitsuba's sign
    /// of V, conventions §9) and `cos` `(n,)` the cosine Mitsuba's BSDFs
    /// multiply by; float32 in `mi.Spectrum`'s layout `(4, 4, c, n)` (row,
    /// column, wavelength, lane), still in the meridian frames of §5. Lanes
    /// not `ok` are 0 and are not looked at (their directions may be NaN).
    #[pyo3(signature = (wi, wo, wavelength_nm, cos, ok, wavelengths=4))]
    #[allow(clippy::too_many_arguments)]
    fn eval_mitsuba<'py>(
        &self,
        py: Python<'py>,
        wi: PyReadonlyArray2<'py, f64>,
        wo: PyReadonlyArray2<'py, f64>,
        wavelength_nm: Option<PyReadonlyArray2<'py, f64>>,
        cos: PyReadonlyArray1<'py, f64>,
        ok: PyReadonlyArray1<'py, bool>,
        wavelengths: usize,
    ) -> PyResult<Bound<'py, PyArray4<f32>>> {
        let (wi, wo, cos, ok) = (wi.as_array(), wo.as_array(), cos.as_array(), ok.as_array());
        let n = ok.len();
        let c = wavelength_nm.as_ref().map_or(wavelengths, |w| w.shape()[1]);
        if wi.dim() != (n, 3) || wo.dim() != (n, 3) || cos.len() != n {
            return Err(QueryError::new_err(format!(
                "eval_mitsuba: wi {:?}, wo {:?}, cos {} for {n} lanes",
                wi.dim(),
                wo.dim(),
                cos.len()
            )));
        }
        let wl: Vec<Option<f64>> = match &wavelength_nm {
            Some(w) if w.shape()[0] == n => {
                self.clamped(w.as_array().iter().copied().collect(), true)
            }
            Some(w) => {
                return Err(QueryError::new_err(format!(
                    "wavelength_nm has {} rows for {n} lanes",
                    w.shape()[0]
                )));
            }
            None => vec![None; n * c],
        };
        let lanes: Vec<usize> = (0..n).filter(|&k| ok[k]).collect();
        let dirs: Vec<([f64; 3], [f64; 3])> = lanes
            .iter()
            .map(|&k| {
                let a = [wi[(k, 0)], wi[(k, 1)], wi[(k, 2)]];
                let b = [wo[(k, 0)], wo[(k, 1)], wo[(k, 2)]];
                (a, b)
            })
            .collect();
        let table = &self.table;
        let evaluated: Result<Vec<Vec<Mueller>>, (usize, BrdfError)> = py.detach(|| {
            lanes
                .par_iter()
                .zip(&dirs)
                .map(|(&k, &(a, b))| {
                    table
                        .eval_wavelengths(&pair(a, b), &wl[k * c..(k + 1) * c])
                        .map_err(|e| (k, e))
                })
                .collect()
        });
        let evaluated = evaluated.map_err(|e| indexed(py, e))?;
        let mut out = vec![0f32; 16 * c * n];
        let sign = |p: usize| if p == 3 { -1.0 } else { 1.0 };
        for (&k, ms) in lanes.iter().zip(&evaluated) {
            for (w, m) in ms.iter().enumerate() {
                for (p, row) in m.iter().enumerate() {
                    for (q, &x) in row.iter().enumerate() {
                        let v = x * sign(p) * sign(q) * cos[k];
                        out[((p * 4 + q) * c + w) * n + k] = v as f32;
                    }
                }
            }
        }
        Ok(Array4::from_shape_vec((4, 4, c, n), out)
            .expect("4 x 4 x c x n values")
            .into_pyarray(py))
    }

    /// The same at `n` pairs of graphics angles: `angles_deg` of shape
    /// `(n, 4)`, columns `theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg`.
    #[pyo3(signature = (angles_deg, wavelength_nm=None, clamp_wavelength=false))]
    fn eval_angles_flat<'py>(
        &self,
        py: Python<'py>,
        angles_deg: PyReadonlyArray2<'py, f64>,
        wavelength_nm: Option<PyReadonlyArray1<'py, f64>>,
        clamp_wavelength: bool,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        if angles_deg.shape()[1] != 4 {
            return Err(QueryError::new_err(format!(
                "angles must have shape (n, 4) (theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg), got {:?}",
                angles_deg.shape()
            )));
        }
        let d: Vec<Directions> = angles_deg
            .as_array()
            .rows()
            .into_iter()
            .map(|r| Directions {
                theta_i_deg: r[0],
                phi_i_deg: r[1],
                theta_o_deg: r[2],
                phi_o_deg: r[3],
            })
            .collect();
        let wl = self.wavelengths_for(d.len(), wavelength_nm, clamp_wavelength)?;
        let table = &self.table;
        let m = py
            .detach(|| par_eval(d.len(), |k| table.eval(&d[k], wl[k])))
            .map_err(|e| indexed(py, e))?;
        Ok(to_array(py, m))
    }

    /// The specular matrix `S` of a mirror base (conventions §6:
    /// `∫ L_out dΩ = S F_beam` around the mirror direction) for `n` incident
    /// directions `wi` `(n, 3)`, in the meridian frames of `ω_i` and its
    /// mirror direction `(θ_i, φ_i + 180°)`; `None` when the table has no
    /// specular term.
    #[pyo3(signature = (wi, wavelength_nm=None, clamp_wavelength=false))]
    fn specular_flat<'py>(
        &self,
        py: Python<'py>,
        wi: PyReadonlyArray2<'py, f64>,
        wavelength_nm: Option<PyReadonlyArray1<'py, f64>>,
        clamp_wavelength: bool,
    ) -> PyResult<Option<Bound<'py, PyArray3<f64>>>> {
        if !self.has_specular() {
            return Ok(None);
        }
        let wi = directions("wi", &wi)?;
        let wl = self.wavelengths_for(wi.len(), wavelength_nm, clamp_wavelength)?;
        let table = &self.table;
        let m = py
            .detach(|| {
                par_eval(wi.len(), |k| {
                    let (theta, phi) = angles::angles_of(wi[k]);
                    let d = Directions {
                        theta_i_deg: theta.min(90.0),
                        phi_i_deg: phi,
                        theta_o_deg: theta.min(90.0),
                        phi_o_deg: phi + 180.0,
                    };
                    Ok(table.specular(&d, wl[k])?.unwrap_or([[0.0; 4]; 4]))
                })
            })
            .map_err(|e| indexed(py, e))?;
        Ok(Some(to_array(py, m)))
    }

    /// Does the table hold the specular term of a mirror base?
    fn has_specular(&self) -> bool {
        self.table.wavelengths.iter().any(|w| w.specular.is_some())
    }

    /// The table's metadata (docs/table-format.md) as JSON text.
    fn metadata_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.table.metadata)
            .map_err(|e| crate::PolbrdfError::new_err(e.to_string()))
    }

    /// The wavelengths (nm), increasing; empty for a wavelength-free table.
    fn wavelengths_nm(&self) -> Vec<f64> {
        self.known_wavelengths()
    }

    /// The polar nodes (degrees) of the table's grid.
    fn theta_deg(&self) -> Vec<f64> {
        self.table.grid.theta_deg.clone()
    }

    /// Rows and columns of the matrices the table answers with (4 × 4,
    /// 4 × 1 for `needs.stokes: "unpolarized_in"`, 1 × 1 for `"intensity"`).
    fn shape(&self) -> (usize, usize) {
        self.table.shape()
    }

    /// The table file's bytes (docs/table-format.md, f64: lossless).
    fn to_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let b = format::to_bytes(&self.table, DataType::F64).map_err(|e| brdf_error(py, e))?;
        Ok(PyBytes::new(py, &b))
    }

    /// Write the table file (f64) to `path`, atomically.
    fn save(&self, py: Python<'_>, path: &str) -> PyResult<()> {
        let table = &self.table;
        py.detach(|| format::write_file(table, path, DataType::F64))
            .map_err(|e| brdf_error(py, e))
    }

    /// A table from a table file's bytes.
    #[staticmethod]
    fn from_bytes(py: Python<'_>, data: &[u8]) -> PyResult<Self> {
        let table = format::from_bytes(data).map_err(|e| brdf_error(py, e))?;
        Ok(Self::new(table))
    }
}
