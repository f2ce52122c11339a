//! Exports of a table (docs/table-format.md, "Exports"): a dense regular
//! grid as NumPy `.npy`, small point sets as JSON, one slice as CSV.
//!
//! All values are the diffuse Mueller BRDF in 1/sr in the meridian frames of
//! conventions §5, evaluated with [`Table::eval`]'s scheme (interpolation in
//! the polar cosines, exact Fourier sum in azimuth). The specular term of a
//! mirror base is a delta and never part of the dense or CSV exports; the
//! JSON export reports it per point when the point is a mirror pair.

use super::BrdfError;
use super::angles::dphi_prop_rad;
use super::coverage;
use super::table::{Directions, Table, fourier_synthesis};
use crate::physics::stokes::Mueller;
use rayon::prelude::*;
use serde_json::{Value, json};

/// A regular dense grid: incident and outgoing polar angles and the
/// azimuth `φ = φ_o − φ_i` (graphics convention, degrees; `φ_i = 0`, so
/// `φ = 180°` is the mirror side).
#[derive(Clone, Debug, PartialEq)]
pub struct DenseGrid {
    /// Incident polar angles (deg).
    pub theta_i_deg: Vec<f64>,
    /// Outgoing polar angles (deg).
    pub theta_o_deg: Vec<f64>,
    /// Outgoing azimuths with `φ_i = 0` (deg).
    pub phi_deg: Vec<f64>,
}

impl Default for DenseGrid {
    /// The seed's 51 × 51 × 61 grid (as `polbrdf bench table`): θ at the
    /// midpoints of 51 equal steps of 0..90° (0.88°..89.12°), φ at 0, 6, …,
    /// 360°.
    fn default() -> Self {
        Self::regular(51, 61).expect("the seed's grid")
    }
}

impl DenseGrid {
    /// `thetas` polar angles at the midpoints of equal steps of 0..90° (for
    /// both directions) and `phis ≥ 2` azimuths from 0 to 360° inclusive.
    pub fn regular(thetas: usize, phis: usize) -> Result<Self, BrdfError> {
        if thetas == 0 || phis < 2 {
            return Err(BrdfError::Query(format!(
                "a dense grid needs at least 1 polar angle and 2 azimuths (got {thetas} and {phis})"
            )));
        }
        let theta: Vec<f64> = (0..thetas)
            .map(|k| 90.0 * (k as f64 + 0.5) / thetas as f64)
            .collect();
        Ok(Self {
            theta_i_deg: theta.clone(),
            theta_o_deg: theta,
            phi_deg: (0..phis)
                .map(|k| 360.0 * k as f64 / (phis - 1) as f64)
                .collect(),
        })
    }

    /// Values per wavelength (`Ti · To · P · 16`).
    pub fn values_per_wavelength(&self) -> usize {
        self.theta_i_deg.len() * self.theta_o_deg.len() * self.phi_deg.len() * 16
    }
}

/// A dense export: `data` has shape `(W, Ti, To, P, R, C)`, C order, with
/// `R × C` the table's [`Table::shape`] (4 × 4, or the part `needs.stokes`
/// kept: 4 × 1, 1 × 1).
#[derive(Clone, Debug, PartialEq)]
pub struct Dense {
    /// Wavelengths of the table (nm; `None` for a wavelength-free table).
    pub wavelength_nm: Vec<Option<f64>>,
    /// The grid.
    pub grid: DenseGrid,
    /// Mueller BRDF values (1/sr).
    pub data: Vec<f64>,
    /// Rows and columns of each matrix ([`Table::shape`]).
    pub elements: (usize, usize),
}

impl Dense {
    /// `(W, Ti, To, P, R, C)`.
    pub fn shape(&self) -> [usize; 6] {
        [
            self.wavelength_nm.len(),
            self.grid.theta_i_deg.len(),
            self.grid.theta_o_deg.len(),
            self.grid.phi_deg.len(),
            self.elements.0,
            self.elements.1,
        ]
    }
}

/// Evaluate every wavelength of the table on a dense grid (the Fourier
/// coefficients are interpolated once per polar pair, then summed at every
/// azimuth). A grid incident angle outside the table's `needs.theta_i_deg`
/// is a query error ([`Table::incident_theta`]), never extrapolated.
pub fn dense(table: &Table, grid: &DenseGrid) -> Result<Dense, BrdfError> {
    let theta_i: Vec<f64> = grid
        .theta_i_deg
        .iter()
        .map(|&t| table.incident_theta(t))
        .collect::<Result<_, _>>()?;
    let elements = table.shape();
    let dphi: Vec<f64> = grid
        .phi_deg
        .iter()
        .map(|&p| dphi_prop_rad(0.0, p))
        .collect();
    let per_pair = grid.phi_deg.len() * elements.0 * elements.1;
    let mut data = Vec::with_capacity(
        table.wavelengths.len() * grid.theta_i_deg.len() * grid.theta_o_deg.len() * per_pair,
    );
    for wt in &table.wavelengths {
        let rows: Vec<Vec<f64>> = theta_i
            .par_iter()
            .map(|&ti| {
                let mut row = Vec::with_capacity(grid.theta_o_deg.len() * per_pair);
                for &to in &grid.theta_o_deg {
                    let c = wt.coefficients(&table.grid, to, ti);
                    for &d in &dphi {
                        let mut m = fourier_synthesis(&c, wt.ns, d);
                        wt.complete(&mut m, ti, to, d);
                        for r in &m[..elements.0] {
                            row.extend(&r[..elements.1]);
                        }
                    }
                }
                row
            })
            .collect();
        for r in rows {
            data.extend(r);
        }
    }
    Ok(Dense {
        wavelength_nm: table.wavelengths.iter().map(|w| w.wavelength_nm).collect(),
        grid: grid.clone(),
        data,
        elements,
    })
}

/// Element type of a `.npy` file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NpyType {
    /// `<f4`.
    F32,
    /// `<f8`.
    F64,
}

/// A NumPy `.npy` file, format version 1.0: the magic `\x93NUMPY`, version
/// bytes `1, 0`, a little-endian `u16` header length, the header (a Python
/// dict literal with `descr`, `fortran_order`, `shape`, padded with spaces
/// and ended by `\n` so that the data start at a multiple of 64 bytes), then
/// the little-endian data in C order.
pub fn npy_bytes(shape: &[usize], data: &[f64], ty: NpyType) -> Result<Vec<u8>, BrdfError> {
    let count: usize = shape.iter().product();
    if count != data.len() {
        return Err(BrdfError::Query(format!(
            "npy: shape {shape:?} holds {count} values, got {}",
            data.len()
        )));
    }
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_txt = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let descr = match ty {
        NpyType::F32 => "<f4",
        NpyType::F64 => "<f8",
    };
    let mut header =
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_txt}, }}");
    // 6 magic + 2 version + 2 length bytes precede the header.
    let total = 10 + header.len() + 1;
    let pad = (64 - total % 64) % 64;
    header.push_str(&" ".repeat(pad));
    header.push('\n');
    let hlen =
        u16::try_from(header.len()).map_err(|_| BrdfError::Query("npy header too long".into()))?;
    let size = match ty {
        NpyType::F32 => 4,
        NpyType::F64 => 8,
    };
    let mut out = Vec::with_capacity(10 + header.len() + size * data.len());
    out.extend_from_slice(b"\x93NUMPY");
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&hlen.to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for &x in data {
        match ty {
            NpyType::F32 => out.extend_from_slice(&(x as f32).to_le_bytes()),
            NpyType::F64 => out.extend_from_slice(&x.to_le_bytes()),
        }
    }
    Ok(out)
}

/// A matrix as JSON nested rows, in the table's shape ([`Table::shape`]:
/// `[[m00], [m10], [m20], [m30]]` for column 0, `[[m00]]` for f11).
pub fn mueller_json(table: &Table, m: &Mueller) -> Value {
    json!(coverage::nested(m, table.shape()))
}

/// JSON for a small point set: per wavelength (all of the table's, or the
/// one given), per point the angles, the diffuse `mueller` (1/sr) and the
/// `specular` matrix when the point is a mirror pair of a mirror base
/// (else `null`).
pub fn points_json(
    table: &Table,
    points: &[Directions],
    wavelength_nm: Option<f64>,
) -> Result<Value, BrdfError> {
    let wls: Vec<Option<f64>> = match wavelength_nm {
        Some(w) => vec![Some(w)],
        None => table.wavelengths.iter().map(|w| w.wavelength_nm).collect(),
    };
    let mut results = Vec::new();
    for wl in wls {
        let mut pts = Vec::with_capacity(points.len());
        for d in points {
            let m = table.eval(d, wl)?;
            let s = table.specular(d, wl)?;
            pts.push(json!({
                "theta_i_deg": d.theta_i_deg, "phi_i_deg": d.phi_i_deg,
                "theta_o_deg": d.theta_o_deg, "phi_o_deg": d.phi_o_deg,
                "mueller": mueller_json(table, &m),
                "specular": s.map(|s| mueller_json(table, &s)),
            }));
        }
        results.push(json!({"wavelength_nm": wl, "points": pts}));
    }
    Ok(json!({"frames": FRAMES, "units": "1/sr", "results": results}))
}

/// Description of the Stokes frames of every export and of `polbrdf eval`.
pub const FRAMES: &str = "meridian frames of docs/conventions.md §5: incident ray k = -w_i with x = e_theta = (cos th_i cos ph_i, cos th_i sin ph_i, -sin th_i), y = (sin ph_i, -cos ph_i, 0); outgoing ray k = w_o with x = (cos th_o cos ph_o, cos th_o sin ph_o, -sin th_o), y = (-sin ph_o, cos ph_o, 0); row = outgoing Stokes component, column = incident";

/// Header of the CSV slice.
pub const CSV_HEADER: &str = "wavelength_nm,theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,theta_o_signed_deg,m00,m01,m02,m03,m10,m11,m12,m13,m20,m21,m22,m23,m30,m31,m32,m33";

/// CSV of one slice: the **plane of incidence** for one incident polar
/// angle `θ_i` (with `φ_i = 0`): outgoing directions at the seed's polar
/// angles on the backscattering side (`φ_o = 0`, signed angle `−θ_o`) and on
/// the mirror side (`φ_o = 180°`, signed angle `+θ_o`), ordered by the signed
/// angle, for every wavelength of the table. Columns: [`CSV_HEADER`]
/// (`mPQ` = Mueller element row P, column Q, 1/sr; an empty wavelength for
/// a wavelength-free table).
pub fn csv_slice(table: &Table, theta_i_deg: f64) -> Result<String, BrdfError> {
    if !(theta_i_deg.is_finite() && (0.0..=90.0).contains(&theta_i_deg)) {
        return Err(BrdfError::Query(format!(
            "theta_i_deg = {theta_i_deg} is outside [0, 90]"
        )));
    }
    let theta = DenseGrid::default().theta_o_deg;
    let mut rows: Vec<(f64, f64, f64)> = Vec::new(); // (signed, θ_o, φ_o)
    for &t in theta.iter().rev() {
        rows.push((-t, t, 0.0));
    }
    for &t in &theta {
        rows.push((t, t, 180.0));
    }
    let elements = table.shape();
    let mut out = if elements == (4, 4) {
        CSV_HEADER.to_string()
    } else {
        let names = coverage::element_names(elements).join(",");
        format!(
            "{},{names}",
            CSV_HEADER.split(",m00").next().unwrap_or(CSV_HEADER)
        )
    };
    out.push('\n');
    for wt in &table.wavelengths {
        let wl = wt.wavelength_nm;
        for &(signed, to, po) in &rows {
            let d = Directions {
                theta_i_deg,
                phi_i_deg: 0.0,
                theta_o_deg: to,
                phi_o_deg: po,
            };
            let m = table.eval(&d, wl)?;
            let mut line = format!(
                "{},{theta_i_deg},0,{to},{po},{signed}",
                wl.map_or(String::new(), |w| w.to_string())
            );
            for r in &m[..elements.0] {
                for x in &r[..elements.1] {
                    line.push_str(&format!(",{x:e}"));
                }
            }
            out.push_str(&line);
            out.push('\n');
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::grid::PolarGrid;

    fn small_table() -> Table {
        let spec = crate::material::parse(
            r#"{"layers": [{"optical_thickness": 0.5,
                 "scatterer": {"henyey_greenstein": {"albedo": 0.8, "g": 0.3}}}],
                "base": {"lambertian": {"albedo": 0.4}}, "solver": {"streams": 4}}"#,
        )
        .unwrap();
        Table::from_spec(&spec, PolarGrid::graded(9).unwrap()).unwrap()
    }

    /// The .npy header as NumPy's `read_array_header_1_0` reads it: magic,
    /// version 1.0, u16 length, a dict literal ending in a newline, data
    /// aligned to 64 bytes; then the values in C order.
    #[test]
    fn npy_layout() {
        let data: Vec<f64> = (0..24).map(|k| k as f64 * 0.5 - 3.0).collect();
        for (ty, descr, size) in [(NpyType::F32, "<f4", 4), (NpyType::F64, "<f8", 8)] {
            let b = npy_bytes(&[2, 3, 4], &data, ty).unwrap();
            assert_eq!(&b[..8], b"\x93NUMPY\x01\x00");
            let hlen = u16::from_le_bytes([b[8], b[9]]) as usize;
            assert_eq!((10 + hlen) % 64, 0);
            let h = std::str::from_utf8(&b[10..10 + hlen]).unwrap();
            assert!(h.ends_with('\n'));
            assert!(h.starts_with(&format!(
                "{{'descr': '{descr}', 'fortran_order': False, 'shape': (2, 3, 4), }}"
            )));
            assert_eq!(b.len(), 10 + hlen + 24 * size);
            let last = &b[b.len() - size..];
            let v = if size == 4 {
                f32::from_le_bytes(last.try_into().unwrap()) as f64
            } else {
                f64::from_le_bytes(last.try_into().unwrap())
            };
            assert_eq!(v, data[23]);
        }
        assert!(npy_bytes(&[5], &data, NpyType::F64).is_err());
        let b = npy_bytes(&[24], &data, NpyType::F64).unwrap();
        assert!(
            std::str::from_utf8(&b[10..70])
                .unwrap()
                .contains("'shape': (24,)")
        );
    }

    /// Every dense value is the point evaluation at its direction pair
    /// (`φ_i = 0`, `φ_o = φ`).
    #[test]
    fn dense_is_point_evaluation() {
        let t = small_table();
        let g = DenseGrid {
            theta_i_deg: vec![0.0, 33.0, 89.0],
            theta_o_deg: vec![10.0, 60.0],
            phi_deg: vec![0.0, 90.0, 180.0, 300.0],
        };
        let d = dense(&t, &g).unwrap();
        assert_eq!(d.shape(), [1, 3, 2, 4, 4, 4]);
        for (a, &ti) in g.theta_i_deg.iter().enumerate() {
            for (b, &to) in g.theta_o_deg.iter().enumerate() {
                for (c, &p) in g.phi_deg.iter().enumerate() {
                    let m = t
                        .eval(
                            &Directions {
                                theta_i_deg: ti,
                                phi_i_deg: 0.0,
                                theta_o_deg: to,
                                phi_o_deg: p,
                            },
                            None,
                        )
                        .unwrap();
                    let base = ((a * 2 + b) * 4 + c) * 16;
                    for k in 0..16 {
                        assert!((d.data[base + k] - m[k / 4][k % 4]).abs() <= 1e-15 * m[0][0]);
                    }
                }
            }
        }
        assert_eq!(DenseGrid::default().theta_i_deg.len(), 51);
        assert_eq!(DenseGrid::default().phi_deg.len(), 61);
    }

    #[test]
    fn csv_is_the_plane_of_incidence() {
        let t = small_table();
        let text = csv_slice(&t, 30.0).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], CSV_HEADER);
        assert_eq!(lines.len(), 1 + 102);
        let mut prev = f64::NEG_INFINITY;
        for l in &lines[1..] {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 22);
            let signed: f64 = f[5].parse().unwrap();
            let (to, po): (f64, f64) = (f[3].parse().unwrap(), f[4].parse().unwrap());
            assert!(signed > prev);
            prev = signed;
            assert_eq!(signed, if po == 180.0 { to } else { -to });
        }
        assert!(csv_slice(&t, 95.0).is_err());
    }
}
