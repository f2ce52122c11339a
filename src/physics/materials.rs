//! Built-in complex refractive-index tables of particle and substrate
//! materials, looked up by name and interpolated in wavelength.
//!
//! Indices follow conventions §2 (`m = n + i k`, `k ≥ 0` absorbs); wavelengths
//! are in nm in vacuum (conventions §1).
//!
//! # Measured tables (a plain name)
//!
//! The data files `data/materials/*.csv` (compiled in by `build.rs`; written
//! once by `data/materials/extract.py` from the refractiveindex.info
//! database, CC0) carry each material's source and citation:
//!
//! | material (canonical name) | aliases | range (nm) | source |
//! |---|---|---|---|
//! | `TiO2` | rutile, titanium dioxide, titania | 430–1530 | DeVore 1951, rutile, `n = √((2n_o² + n_e²)/3)`, `k = 0` |
//! | `TiO2 anatase` | anatase | 206.64–826.56 | Jolivet et al. 2023, ALD film |
//! | `gold` | Au | 247.97–2630.4 | Rakić et al. 1998 (Brendel–Bormann) |
//! | `iron oxide` | hematite, rust, Fe2O3, red iron oxide | 210–2604.2 | Querry 1985, α-Fe2O3, ordinary ray |
//! | `silver` | Ag | 247.97–2623.6 | Rakić et al. 1998 |
//! | `aluminium` | aluminum, Al | 177.12–2755.2 | Rakić 1995 |
//! | `chromium` | Cr | 247.97–2622.1 | Rakić et al. 1998 |
//! | `copper` | Cu | 206.64–2649.8 | Rakić et al. 1998 |
//! | `ZnO` | zinc oxide, zinc white | 300–2600 | Aguilar et al. 2019, film |
//! | `SiO2` | silica, fused silica | 210–2600 | Malitson 1965 (Sellmeier, every 10 nm) |
//! | `AlGaAs` | aluminium/aluminum gallium arsenide, Al0.804Ga0.196As | 206.6–826.6 | Aspnes et al. 1986, x = 0.804 (the composition of the seed's Table 2, below) |
//!
//! Between rows, `n` and `k` are each interpolated by the **monotone
//! piecewise-cubic Hermite** interpolant (Fritsch & Carlson, SIAM J. Numer.
//! Anal. 17, 238 (1980), with the slopes of Fritsch & Butland, SIAM J. Sci.
//! Stat. Comput. 5, 300 (1984), MATLAB's `pchip`): exact at the rows,
//! continuous with a continuous first derivative (linear interpolation has a
//! kink at every row, a step in dn/dλ that the spectra of a table inherit),
//! and never outside the two neighbouring row values, so `k ≥ 0` holds and
//! no spline overshoot appears next to an absorption edge.
//!
//! # The seed's values (`"source": "seed"`)
//!
//! The seed's Table 2 (TiO2, gold, iron oxide, AlGaAs, silver at 450, 550 and
//! 650 nm) stays available exactly as printed, interpolated **linearly** in
//! wavelength, so that the seed's figures reproduce ([`find_seed`]). Its
//! iron oxide (`0.260 + 0.383i` at 550 nm) is not hematite: `n < 1` is
//! unphysical for a dielectric oxide in the visible, where measured hematite
//! is `3.32 + 0.50i` (Querry 1985, ordinary ray); a plain `"iron oxide"` is
//! the measured hematite. Its AlGaAs is Al₀.₈₀₄Ga₀.₁₉₆As: Aspnes et al.'s
//! rows for x = 0.804 give `3.831 + 0.184i` (450 nm, interpolated), `3.410`
//! and `3.239` where the seed prints `3.832 + 0.183i`, `3.411` and `3.239`
//! (no other tabulated composition comes within 0.05), so a plain
//! `"AlGaAs"` is that composition, measured over 207–827 nm.
//!
//! # Lookup
//!
//! Names are matched case-insensitively ignoring everything but letters and
//! digits (`"Iron-Oxide"`, `"iron_oxide"`, `"IRON OXIDE"` are the same name).
//! At a row the tabulated value is returned exactly. Outside
//! `[λ_first, λ_last]` the lookup fails with [`PhysicsError::OutOfRange`]
//! (no extrapolation). A table with a single wavelength `λ_0` accepts only
//! `|λ − λ_0| ≤ 0.5 nm` ([`SINGLE_WAVELENGTH_TOLERANCE_NM`]) and returns its
//! value there. A user's table (`"material": {"table": …}`, docs/spec.md) is
//! interpolated like a measured one ([`table_index`]).

// Measured values such as TiO2 n = 3.141 (450 nm) are data, not
// approximations of π.
#![allow(clippy::approx_constant)]

use super::{PhysicsError, RefractiveIndex};

/// Half-width of the wavelength window accepted by a single-wavelength table.
pub const SINGLE_WAVELENGTH_TOLERANCE_NM: f64 = 0.5;

/// One built-in material: names, source and `[wavelength_nm, n, k]` rows
/// (wavelengths strictly increasing).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Canonical name, as listed by [`known_materials`].
    pub name: &'static str,
    /// Other accepted names.
    pub aliases: &'static [&'static str],
    /// Bibliographic source of the table.
    pub source: &'static str,
    /// How `n` and `k` are interpolated between rows.
    pub interpolation: Interpolation,
    /// Rows `[wavelength_nm, n, k]`, wavelengths strictly increasing.
    pub table: &'static [[f64; 3]],
}

/// Interpolation of `n` and `k` between the rows of a table (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// Linear in wavelength (the seed's Table 2).
    Linear,
    /// Monotone piecewise-cubic Hermite (Fritsch–Carlson–Butland, `pchip`).
    MonotoneCubic,
}

// `MEASURED`: the tables of data/materials/*.csv (build.rs).
include!(concat!(env!("OUT_DIR"), "/materials_data.rs"));

const SEED_SOURCE: &str = "Collin et al., seed Table 2 (SOPRA/Filmetrics)";

const fn seed(name: &'static str, table: &'static [[f64; 3]]) -> Material {
    Material {
        name,
        aliases: &[],
        source: SEED_SOURCE,
        interpolation: Interpolation::Linear,
        table,
    }
}

/// The seed's Table 2, exactly as printed (canonical names of [`MEASURED`]).
static SEED: [Material; 5] = [
    seed(
        "TiO2",
        &[
            [450.0, 3.141, 0.000],
            [550.0, 2.954, 0.000],
            [650.0, 2.860, 0.000],
        ],
    ),
    seed(
        "gold",
        &[
            [450.0, 1.509, 1.879],
            [550.0, 0.350, 2.714],
            [650.0, 0.168, 3.118],
        ],
    ),
    seed(
        "iron oxide",
        &[
            [450.0, 0.253, 0.692],
            [550.0, 0.260, 0.383],
            [650.0, 0.023, 0.218],
        ],
    ),
    seed(
        "AlGaAs",
        &[
            [450.0, 3.832, 0.183],
            [550.0, 3.411, 0.000],
            [650.0, 3.239, 0.000],
        ],
    ),
    seed(
        "silver",
        &[
            [450.0, 0.151, 2.470],
            [550.0, 0.125, 3.339],
            [650.0, 0.139, 4.129],
        ],
    ),
];

/// Every material a plain name can mean, in listing order.
fn plain() -> impl Iterator<Item = &'static Material> {
    MEASURED.iter()
}

/// All built-in materials of a plain name (the measured tables).
pub fn materials() -> Vec<&'static Material> {
    plain().collect()
}

/// Canonical names of the built-in materials, in table order.
pub fn known_materials() -> Vec<&'static str> {
    plain().map(|m| m.name).collect()
}

/// The material called `name` (canonical name or alias; case and
/// non-alphanumeric characters ignored).
///
/// # Errors
/// [`PhysicsError::UnknownMaterial`] listing the known canonical names.
pub fn find(name: &str) -> Result<&'static Material, PhysicsError> {
    let key = normalize(name);
    plain()
        .find(|m| {
            !key.is_empty()
                && (normalize(m.name) == key || m.aliases.iter().any(|a| normalize(a) == key))
        })
        .ok_or_else(|| PhysicsError::UnknownMaterial {
            name: name.to_string(),
            known: known_materials().join(", "),
        })
}

/// Canonical names of the materials of the seed's Table 2.
pub fn seed_materials() -> Vec<&'static str> {
    SEED.iter().map(|m| m.name).collect()
}

/// The seed's Table 2 values of the material called `name` (any name
/// [`find`] accepts), linearly interpolated over 450–650 nm.
///
/// # Errors
/// As [`find`]; [`PhysicsError::Invalid`] for a material the seed's table
/// does not have.
pub fn find_seed(name: &str) -> Result<&'static Material, PhysicsError> {
    let canonical = find(name)?.name;
    SEED.iter().find(|m| m.name == canonical).ok_or_else(|| {
        PhysicsError::Invalid(format!(
            "the seed's Table 2 has no values for '{canonical}' (it has {})",
            seed_materials().join(", ")
        ))
    })
}

/// Bibliographic source string of the material called `name`.
///
/// # Errors
/// As [`find`].
pub fn source(name: &str) -> Result<&'static str, PhysicsError> {
    Ok(find(name)?.source)
}

/// Complex refractive index of the material called `name` at
/// `wavelength_nm` (vacuum), interpolated between rows (module doc); exact
/// at a row.
///
/// # Errors
/// [`PhysicsError::UnknownMaterial`] for an unknown name;
/// [`PhysicsError::OutOfRange`] (`wavelength_nm`) outside the tabulated range
/// (±0.5 nm around a single-wavelength table) or for a non-finite wavelength.
pub fn refractive_index(name: &str, wavelength_nm: f64) -> Result<RefractiveIndex, PhysicsError> {
    find(name)?.index_at(wavelength_nm)
}

impl Material {
    /// Tabulated wavelength range `(first, last)` in nm.
    pub fn wavelength_range_nm(&self) -> (f64, f64) {
        (self.table[0][0], self.table[self.table.len() - 1][0])
    }

    /// Index at `wavelength_nm`; see [`refractive_index`].
    ///
    /// # Errors
    /// As [`refractive_index`] (without the unknown-name case).
    pub fn index_at(&self, wavelength_nm: f64) -> Result<RefractiveIndex, PhysicsError> {
        interpolate(self.table, self.interpolation, wavelength_nm, self.name)
    }
}

/// Index at `wavelength_nm` from a user's rows `[wavelength_nm, n, k]`
/// (wavelengths strictly increasing, validated by the caller), interpolated
/// as a measured table (monotone cubic; module doc).
///
/// # Errors
/// [`PhysicsError::OutOfRange`] outside the rows' range.
pub fn table_index(
    table: &[[f64; 3]],
    wavelength_nm: f64,
) -> Result<RefractiveIndex, PhysicsError> {
    interpolate(
        table,
        Interpolation::MonotoneCubic,
        wavelength_nm,
        "the material table",
    )
}

fn interpolate(
    t: &[[f64; 3]],
    how: Interpolation,
    wavelength_nm: f64,
    name: &str,
) -> Result<RefractiveIndex, PhysicsError> {
    let (lo, hi) = (t[0][0], t[t.len() - 1][0]);
    if t.len() == 1 {
        let tol = SINGLE_WAVELENGTH_TOLERANCE_NM;
        if wavelength_nm.is_finite() && (wavelength_nm - lo).abs() <= tol {
            return Ok(RefractiveIndex::new(t[0][1], t[0][2]));
        }
        return Err(PhysicsError::OutOfRange {
            name: "wavelength_nm",
            value: wavelength_nm,
            range: format!(
                "[{}, {}] nm (single-wavelength table of {name} at {lo} nm ± {tol} nm)",
                lo - tol,
                lo + tol,
            ),
        });
    }
    if !(wavelength_nm.is_finite() && (lo..=hi).contains(&wavelength_nm)) {
        return Err(PhysicsError::OutOfRange {
            name: "wavelength_nm",
            value: wavelength_nm,
            range: format!("[{lo}, {hi}] nm (table of {name})"),
        });
    }
    // First row with wavelength >= λ (exists since λ <= hi).
    let j = t.partition_point(|row| row[0] < wavelength_nm);
    if t[j][0] == wavelength_nm || j == 0 {
        return Ok(RefractiveIndex::new(t[j][1], t[j][2]));
    }
    let at = |c: usize| match how {
        Interpolation::Linear => {
            let (a, b) = (t[j - 1], t[j]);
            let s = (wavelength_nm - a[0]) / (b[0] - a[0]);
            (1.0 - s) * a[c] + s * b[c]
        }
        Interpolation::MonotoneCubic => pchip(t, c, j - 1, wavelength_nm),
    };
    Ok(RefractiveIndex::new(at(1), at(2)))
}

/// The monotone cubic Hermite interpolant of column `c` of `t` on the
/// interval `[x_i, x_{i+1}]` at `x` (Fritsch & Carlson 1980; slopes of
/// Fritsch & Butland 1984: zero at a local extremum, else a weighted
/// harmonic mean of the neighbouring secants; at the ends the one-sided
/// three-point slope, limited to keep the shape).
fn pchip(t: &[[f64; 3]], c: usize, i: usize, x: f64) -> f64 {
    let last = t.len() - 1;
    let h = |k: usize| t[k + 1][0] - t[k][0];
    let delta = |k: usize| (t[k + 1][c] - t[k][c]) / h(k);
    let slope = |k: usize| -> f64 {
        if last == 1 {
            return delta(0);
        }
        if k == 0 || k == last {
            // One-sided, shape preserving (Moler, Numerical Computing with
            // MATLAB, §3.4).
            let (a, b) = if k == 0 { (0, 1) } else { (last - 1, last - 2) };
            let (h0, h1, d0, d1) = (h(a), h(b), delta(a), delta(b));
            let d = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
            if d.signum() != d0.signum() {
                0.0
            } else if d0.signum() != d1.signum() && d.abs() > (3.0 * d0).abs() {
                3.0 * d0
            } else {
                d
            }
        } else {
            let (d0, d1) = (delta(k - 1), delta(k));
            if d0 * d1 <= 0.0 {
                return 0.0;
            }
            let (h0, h1) = (h(k - 1), h(k));
            let (w1, w2) = (2.0 * h1 + h0, h1 + 2.0 * h0);
            (w1 + w2) / (w1 / d0 + w2 / d1)
        }
    };
    let hi = h(i);
    let s = (x - t[i][0]) / hi;
    let (y0, y1) = (t[i][c], t[i + 1][c]);
    let (m0, m1) = (slope(i) * hi, slope(i + 1) * hi);
    let s2 = s * s;
    let s3 = s2 * s;
    (2.0 * s3 - 3.0 * s2 + 1.0) * y0
        + (s3 - 2.0 * s2 + s) * m0
        + (-2.0 * s3 + 3.0 * s2) * y1
        + (s3 - s2) * m1
}

fn normalize(name: &str) -> String {
    name.chars()
        .filter(|c| c.is_alphanumeric())
        .flat_map(char::to_lowercase)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_index(name: &str, wl: f64, n: f64, k: f64, tol: f64) {
        let m = refractive_index(name, wl).unwrap();
        assert!(
            (m.n - n).abs() <= tol && (m.k - k).abs() <= tol,
            "{name} at {wl} nm: got {m:?}, expected ({n}, {k})"
        );
    }

    #[test]
    fn seed_table_2_values_at_nodes() {
        // Seed Table 2, exactly as printed: (material, [(n, k) at 450, 550, 650 nm]).
        let table: [(&str, [(f64, f64); 3]); 5] = [
            ("TiO2", [(3.141, 0.000), (2.954, 0.000), (2.860, 0.000)]),
            ("Gold", [(1.509, 1.879), (0.350, 2.714), (0.168, 3.118)]),
            (
                "Iron oxide",
                [(0.253, 0.692), (0.260, 0.383), (0.023, 0.218)],
            ),
            ("AlGaAs", [(3.832, 0.183), (3.411, 0.000), (3.239, 0.000)]),
            ("Silver", [(0.151, 2.470), (0.125, 3.339), (0.139, 4.129)]),
        ];
        for (name, vals) in table {
            let seed = find_seed(name).unwrap();
            for (wl, (n, k)) in [450.0, 550.0, 650.0].into_iter().zip(vals) {
                let m = seed.index_at(wl).unwrap();
                assert_eq!((m.n, m.k), (n, k), "{name} at {wl}");
            }
            assert_eq!(seed.source, SEED_SOURCE);
            // Linear between the seed's wavelengths, as the seed did.
            let mid = seed.index_at(500.0).unwrap();
            assert!((mid.n - 0.5 * (vals[0].0 + vals[1].0)).abs() < 1e-15);
        }
        // The seed's AlGaAs is Aspnes et al.'s x = 0.804 (module doc): the
        // measured table agrees with Table 2 to 0.004 at its wavelengths.
        let (measured, printed) = (find("AlGaAs").unwrap(), find_seed("algaas").unwrap());
        for wl in [450.0, 550.0, 650.0] {
            let (a, b) = (
                measured.index_at(wl).unwrap(),
                printed.index_at(wl).unwrap(),
            );
            assert!(
                (a.n - b.n).abs() < 4e-3 && (a.k - b.k).abs() < 4e-3,
                "{wl}: {a:?} {b:?}"
            );
        }
        assert!(matches!(
            find_seed("chromium"),
            Err(PhysicsError::Invalid(_))
        ));
        assert_eq!(find_seed("rust").unwrap().name, "iron oxide");
    }

    /// Rows of the measured tables against the values their sources print.
    #[test]
    fn measured_rows_match_their_sources() {
        // Rakić (1995) aluminium, rows as printed (0.61993 and 0.65225 µm).
        assert_index("Al", 619.93, 1.3660, 7.4052, 0.0);
        assert_index("Al", 652.25, 1.5724, 7.7354, 0.0);
        // Malitson (1965) fused silica: his Sellmeier formula with his
        // printed coefficients, at rows and between them (n_d at the
        // helium d line, 587.56 nm, is 1.45846 in his Table).
        let malitson = |wl_nm: f64| {
            let l2 = (wl_nm / 1000.0).powi(2);
            let terms = [
                (0.6961663, 0.0684043),
                (0.4079426, 0.1162414),
                (0.8974794, 9.896161),
            ];
            (1.0 + terms
                .iter()
                .map(|(b, c)| b * l2 / (l2 - c * c))
                .sum::<f64>())
            .sqrt()
        };
        for wl in [300.0, 550.0, 1000.0, 2500.0] {
            assert_index("silica", wl, malitson(wl), 0.0, 1e-6);
        }
        assert_index("SiO2", 587.56, malitson(587.56), 0.0, 2e-6);
        assert_index("SiO2", 587.56, 1.45846, 0.0, 1e-5);
        // DeVore (1951) rutile: n_o² = 5.913 + 0.2441/(λ² − 0.0803),
        // n_e² = 7.197 + 0.3322/(λ² − 0.0843) (λ in µm); his Table gives
        // the isotropic mean of module doc from them.
        let devore = |wl_nm: f64| {
            let l2 = (wl_nm / 1000.0).powi(2);
            let o = 5.913 + 0.2441 / (l2 - 0.0803);
            let e = 7.197 + 0.3322 / (l2 - 0.0843);
            ((2.0 * o + e) / 3.0).sqrt()
        };
        for wl in [430.0, 550.0, 632.8, 1000.0, 1530.0] {
            assert_index("rutile", wl, devore(wl), 0.0, 2e-6);
        }
        // Aspnes et al. (1986) Al(0.804)Ga(0.196)As, Table as printed: at
        // 2.0 eV n 3.277, k 0; at 3.0 eV n 4.050, k 0.353; at 4.0 eV
        // n 3.962, k 2.119 (λ = 1239.84/E nm, the database's rows).
        assert_index("AlGaAs", 619.9, 3.277, 0.0, 0.0);
        assert_index("AlGaAs", 413.3, 4.050, 0.353, 0.0);
        assert_index("AlGaAs", 310.0, 3.962, 2.119, 0.0);
        // Hale & Querry (1973) water, Table 1 as printed: 0.500 µm
        // n 1.335, k 1.00e-9; 1.000 µm n 1.327, k 2.89e-6.
        assert_index("water", 500.0, 1.335, 1.00e-9, 0.0);
        assert_index("water", 1000.0, 1.327, 2.89e-6, 0.0);
        // Ghosh (1999) calcite: n² = 1 + A + B1 λ²/(λ² − C1) + B2 λ²/(λ² − C2)
        // with his printed coefficients (Table 1), ordinary and extraordinary;
        // the isotropic mean of the module doc.
        let ghosh = |wl_nm: f64, [a, b1, c1, b2, c2]: [f64; 5]| {
            let l2 = (wl_nm / 1000.0).powi(2);
            1.0 + a + b1 * l2 / (l2 - c1) + b2 * l2 / (l2 - c2)
        };
        let o = [0.73358749, 0.96464345, 1.94325203e-2, 1.82831454, 120.0];
        let e = [0.35859695, 0.82427830, 1.06689543e-2, 0.14429128, 120.0];
        for wl in [300.0, 589.3, 1000.0, 2000.0] {
            let mean = ((2.0 * ghosh(wl, o) + ghosh(wl, e)) / 3.0).sqrt();
            assert_index("calcite", wl, mean, 0.0, 2e-6);
        }
    }

    /// Every measured material covers the wavelengths a renderer samples,
    /// 300–2500 nm, except those whose public data stop short (module doc:
    /// rutile 430–1530 nm, anatase and AlGaAs to 827 nm,
    /// calcite 210–2170 nm, the polymer binders from 400 nm).
    #[test]
    fn measured_materials_cover_300_to_2500_nm() {
        let partial = [
            "TiO2",
            "TiO2 anatase",
            "AlGaAs",
            "CaCO3",
            "acrylic",
            "polystyrene",
            "polycarbonate",
        ];
        for m in materials() {
            if partial.contains(&m.name) {
                continue;
            }
            for wl in [300.0, 360.0, 550.0, 830.0, 1000.0, 2500.0] {
                let x = m
                    .index_at(wl)
                    .unwrap_or_else(|e| panic!("{} at {wl}: {e}", m.name));
                assert!(x.n > 0.0 && x.k >= 0.0, "{}: {x:?}", m.name);
            }
        }
        let range = |name: &str| find(name).unwrap().wavelength_range_nm();
        assert_eq!(range("TiO2"), (430.0, 1530.0));
        assert_eq!(range("anatase"), (206.64, 826.56));
        assert_eq!(range("AlGaAs"), (206.6, 826.6));
        assert_eq!(range("calcite"), (210.0, 2170.0));
        assert_eq!(range("acrylic"), (400.0, 2608.1));
    }

    /// The interpolant is exact at rows, stays between the two neighbouring
    /// row values (so `k ≥ 0`), and is C¹: at every interior row of every
    /// measured table the one-sided derivatives agree to 1e-5 relative,
    /// where linear interpolation's differ by the change of secant.
    #[test]
    fn measured_interpolation_is_smooth_and_bounded() {
        for m in MEASURED.iter() {
            let t = m.table;
            for w in t.windows(2) {
                for s in [0.1, 0.37, 0.5, 0.9] {
                    let wl = w[0][0] + s * (w[1][0] - w[0][0]);
                    let x = m.index_at(wl).unwrap();
                    for (c, v) in [(1, x.n), (2, x.k)] {
                        let (lo, hi) = (w[0][c].min(w[1][c]), w[0][c].max(w[1][c]));
                        // (to round-off: equal rows give the row value ± 1 ulp)
                        let eps = 4.0 * f64::EPSILON * hi.abs();
                        assert!(
                            v >= lo - eps && v <= hi + eps,
                            "{} at {wl}: {v} outside [{lo}, {hi}]",
                            m.name
                        );
                    }
                }
            }
            for i in 1..t.len() - 1 {
                let x = t[i][0];
                let h = 1e-6 * (t[i + 1][0] - t[i - 1][0]);
                let f = |wl: f64| m.index_at(wl).unwrap();
                let (l, c, r) = (f(x - h), f(x), f(x + h));
                assert_eq!((c.n, c.k), (t[i][1], t[i][2]), "{} row {i}", m.name);
                for (a, b, d, scale) in [
                    (l.n, r.n, c.n, t.iter().map(|r| r[1]).fold(0.0, f64::max)),
                    (l.k, r.k, c.k, t.iter().map(|r| r[2]).fold(0.0, f64::max)),
                ] {
                    let (left, right) = ((d - a) / h, (b - d) / h);
                    let typical = scale / (t[i + 1][0] - t[i - 1][0]);
                    assert!(
                        (left - right).abs() <= 1e-3 * typical.max(left.abs()) + 1e-12,
                        "{} at row {i} ({x} nm): slopes {left:e}, {right:e}",
                        m.name
                    );
                }
            }
        }
    }

    /// Collinear rows are reproduced exactly (the secants are equal, so the
    /// slopes are the secant), and a user's table is interpolated the same
    /// way as a built-in one.
    #[test]
    fn user_tables_interpolate_like_measured_ones() {
        let linear = [
            [400.0, 1.5, 0.0],
            [500.0, 1.6, 0.1],
            [600.0, 1.7, 0.2],
            [700.0, 1.8, 0.3],
        ];
        for wl in [400.0, 433.3, 512.0, 650.0, 700.0] {
            let x = table_index(&linear, wl).unwrap();
            let s = (wl - 400.0) / 100.0;
            assert!((x.n - (1.5 + 0.1 * s)).abs() < 1e-14 && (x.k - 0.1 * s).abs() < 1e-14);
        }
        let gold = find("gold").unwrap();
        for wl in [333.3, 550.0, 1234.5] {
            assert_eq!(
                table_index(gold.table, wl).unwrap(),
                gold.index_at(wl).unwrap()
            );
        }
        assert!(matches!(
            table_index(&linear, 399.0),
            Err(PhysicsError::OutOfRange { .. })
        ));
    }

    #[test]
    fn names_and_aliases() {
        let cases = [
            ("TiO2", "TiO2"),
            ("tio2", "TiO2"),
            ("Titanium Dioxide", "TiO2"),
            ("rutile", "TiO2"),
            ("anatase", "TiO2 anatase"),
            ("gold", "gold"),
            ("AU", "gold"),
            ("iron oxide", "iron oxide"),
            ("Iron-Oxide", "iron oxide"),
            ("rust", "iron oxide"),
            ("hematite", "iron oxide"),
            ("Fe2O3", "iron oxide"),
            ("algaas", "AlGaAs"),
            ("Al0.804Ga0.196As", "AlGaAs"),
            ("silver", "silver"),
            ("Ag", "silver"),
            ("Aluminium", "aluminium"),
            ("aluminum", "aluminium"),
            ("Al", "aluminium"),
            ("chromium", "chromium"),
            ("cr", "chromium"),
            ("Cu", "copper"),
            ("zinc oxide", "ZnO"),
            ("fused silica", "SiO2"),
            ("calcite", "CaCO3"),
            ("PMMA", "acrylic"),
            ("H2O", "water"),
            ("soot", "carbon black"),
        ];
        for (q, canon) in cases {
            assert_eq!(find(q).unwrap().name, canon, "{q}");
        }
        assert_eq!(
            known_materials(),
            vec![
                "TiO2",
                "TiO2 anatase",
                "gold",
                "iron oxide",
                "silver",
                "aluminium",
                "chromium",
                "copper",
                "ZnO",
                "SiO2",
                "CaCO3",
                "carbon black",
                "acrylic",
                "polystyrene",
                "polycarbonate",
                "water",
                "AlGaAs"
            ]
        );
    }

    #[test]
    fn errors() {
        match refractive_index("unobtainium", 550.0) {
            Err(PhysicsError::UnknownMaterial { name, known }) => {
                assert_eq!(name, "unobtainium");
                for k in known_materials() {
                    assert!(known.contains(k), "{known}");
                }
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            find(""),
            Err(PhysicsError::UnknownMaterial { .. })
        ));
        assert!(matches!(
            find("Al2O3"),
            Err(PhysicsError::UnknownMaterial { .. })
        ));
        for (name, wl) in [
            ("gold", 200.0),
            ("gold", 2700.0),
            ("TiO2", 400.0),
            ("Al", 170.0),
            ("Al", 2800.0),
            ("Cr", 187.0),
            ("silver", f64::NAN),
            ("silver", f64::INFINITY),
        ] {
            match refractive_index(name, wl) {
                Err(PhysicsError::OutOfRange { name: p, .. }) => assert_eq!(p, "wavelength_nm"),
                other => panic!("{name} {wl}: {other:?}"),
            }
        }
    }

    #[test]
    fn single_wavelength_table() {
        static ONE: [[f64; 3]; 1] = [[632.8, 1.5, 0.25]];
        let m = Material {
            name: "test",
            aliases: &[],
            source: "test",
            interpolation: Interpolation::MonotoneCubic,
            table: &ONE,
        };
        for wl in [632.8, 632.3, 633.3] {
            assert_eq!(m.index_at(wl).unwrap(), RefractiveIndex::new(1.5, 0.25));
        }
        for wl in [632.2, 633.4, f64::NAN] {
            assert!(matches!(
                m.index_at(wl),
                Err(PhysicsError::OutOfRange { .. })
            ));
        }
    }

    #[test]
    fn tables_are_well_formed() {
        for m in materials().into_iter().chain(SEED.iter()) {
            assert!(!m.table.is_empty(), "{}", m.name);
            assert!(!m.source.is_empty());
            for w in m.table.windows(2) {
                assert!(w[0][0] < w[1][0], "{}: wavelengths not increasing", m.name);
            }
            for row in m.table {
                assert!(row[1] > 0.0 && row[2] >= 0.0, "{}: {row:?}", m.name);
            }
        }
        for m in materials() {
            // Every name resolves to itself.
            assert_eq!(find(m.name).unwrap().name, m.name);
            for a in m.aliases {
                assert_eq!(find(a).unwrap().name, m.name);
            }
        }
    }
}
