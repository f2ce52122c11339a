//! Built-in complex refractive-index tables of particle and substrate
//! materials, looked up by name and interpolated in wavelength.
//!
//! Indices follow conventions §2 (`m = n + i k`, `k ≥ 0` absorbs); wavelengths
//! are in nm in vacuum (conventions §1).
//!
//! # Tables and sources
//!
//! | material (canonical name) | aliases | nodes | source |
//! |---|---|---|---|
//! | `TiO2` | titanium dioxide, titania | 450, 550, 650 nm | Collin et al., seed Table 2 (SOPRA/Filmetrics) |
//! | `gold` | Au | 450, 550, 650 nm | Collin et al., seed Table 2 (SOPRA/Filmetrics) |
//! | `iron oxide` | rust, Fe2O3 | 450, 550, 650 nm | Collin et al., seed Table 2 (SOPRA/Filmetrics) |
//! | `AlGaAs` | aluminium/aluminum gallium arsenide | 450, 550, 650 nm | Collin et al., seed Table 2 (SOPRA/Filmetrics) |
//! | `silver` | Ag | 450, 550, 650 nm | Collin et al., seed Table 2 (SOPRA/Filmetrics) |
//! | `aluminium` | aluminum, Al | 30 nodes, 206.64–2066.4 nm | Rakić, Appl. Opt. 34, 4755 (1995) |
//! | `chromium` | Cr | 49 nodes, 188–1937 nm | Johnson & Christy, Phys. Rev. B 9, 5056 (1974) |
//!
//! The seed's Table 2 values are copied exactly as printed (e.g. silver
//! `n = 0.151` at 450 nm) and are the only data for those five materials, so
//! they are the values at 450/550/650 nm. Aluminium and chromium are the
//! experiment of seed Table 1 (aluminium particles on chromium, He-Ne
//! 632.8 nm); at 632.8 nm the tables give (linear interpolation)
//! aluminium `1.44819 + 7.53669 i` and chromium `3.13990 + 3.31505 i`.
//!
//! # Lookup and interpolation
//!
//! Names are matched case-insensitively ignoring everything but letters and
//! digits (`"Iron-Oxide"`, `"iron_oxide"`, `"IRON OXIDE"` are the same name).
//! Between two tabulated wavelengths `λ_a ≤ λ ≤ λ_b`, `n` and `k` are each
//! interpolated **linearly in wavelength**:
//! `n(λ) = (1 − t) n_a + t n_b`, `t = (λ − λ_a)/(λ_b − λ_a)` (same for `k`);
//! at a node the tabulated value is returned exactly. Outside
//! `[λ_first, λ_last]` the lookup fails with [`PhysicsError::OutOfRange`]
//! (no extrapolation). A table with a single wavelength `λ_0` accepts only
//! `|λ − λ_0| ≤ 0.5 nm` ([`SINGLE_WAVELENGTH_TOLERANCE_NM`]) and returns its
//! value there.

// Measured values such as TiO2 n = 3.141 (450 nm) or Cr k = 3.14 (451 nm) are
// data, not approximations of π.
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
    /// Rows `[wavelength_nm, n, k]`, wavelengths strictly increasing.
    pub table: &'static [[f64; 3]],
}

const SEED_SOURCE: &str = "Collin et al., seed Table 2 (SOPRA/Filmetrics)";

const TIO2: [[f64; 3]; 3] = [
    [450.0, 3.141, 0.000],
    [550.0, 2.954, 0.000],
    [650.0, 2.860, 0.000],
];
const GOLD: [[f64; 3]; 3] = [
    [450.0, 1.509, 1.879],
    [550.0, 0.350, 2.714],
    [650.0, 0.168, 3.118],
];
const IRON_OXIDE: [[f64; 3]; 3] = [
    [450.0, 0.253, 0.692],
    [550.0, 0.260, 0.383],
    [650.0, 0.023, 0.218],
];
const ALGAAS: [[f64; 3]; 3] = [
    [450.0, 3.832, 0.183],
    [550.0, 3.411, 0.000],
    [650.0, 3.239, 0.000],
];
const SILVER: [[f64; 3]; 3] = [
    [450.0, 0.151, 2.470],
    [550.0, 0.125, 3.339],
    [650.0, 0.139, 4.129],
];

/// Rakić (1995) evaporated-aluminium n, k, rows 0.20664–2.0664 µm of
/// refractiveindex.info `database/data-nk/main/Al/Rakic.yml` (µm × 1000).
const ALUMINIUM: [[f64; 3]; 30] = [
    [206.64, 0.12677, 2.3563],
    [247.97, 0.18137, 2.9029],
    [309.96, 0.28003, 3.7081],
    [326.28, 0.31474, 3.9165],
    [364.66, 0.39877, 4.3957],
    [413.28, 0.52135, 5.0008],
    [442.8, 0.6079, 5.3676],
    [476.87, 0.7278, 5.7781],
    [516.6, 0.8734, 6.2418],
    [563.57, 1.0728, 6.7839],
    [619.93, 1.366, 7.4052],
    [652.25, 1.5724, 7.7354],
    [688.81, 1.8301, 8.0601],
    [729.32, 2.1606, 8.3565],
    [774.91, 2.6154, 8.4914],
    [794.78, 2.7675, 8.3866],
    [815.69, 2.7668, 8.2573],
    [837.74, 2.6945, 8.1878],
    [885.61, 2.2802, 8.1134],
    [911.66, 1.9739, 8.3058],
    [939.28, 1.6784, 8.597],
    [968.63, 1.4867, 9.0655],
    [999.88, 1.4359, 9.4939],
    [1033.2, 1.3998, 9.8914],
    [1127.1, 1.3281, 10.969],
    [1239.9, 1.3157, 12.245],
    [1377.6, 1.3899, 13.784],
    [1549.8, 1.5782, 15.656],
    [1771.2, 1.9205, 17.991],
    [2066.4, 2.4738, 20.982],
];

/// Johnson & Christy (1974) chromium n, k, all rows of refractiveindex.info
/// `database/data-nk/main/Cr/Johnson.yml` (µm × 1000).
const CHROMIUM: [[f64; 3]; 49] = [
    [188.0, 1.28, 1.64],
    [192.0, 1.31, 1.65],
    [195.0, 1.35, 1.68],
    [199.0, 1.39, 1.7],
    [203.0, 1.43, 1.7],
    [207.0, 1.46, 1.71],
    [212.0, 1.46, 1.72],
    [216.0, 1.47, 1.72],
    [221.0, 1.45, 1.73],
    [226.0, 1.43, 1.74],
    [231.0, 1.4, 1.77],
    [237.0, 1.38, 1.8],
    [243.0, 1.36, 1.85],
    [249.0, 1.36, 1.91],
    [255.0, 1.37, 1.97],
    [262.0, 1.38, 2.03],
    [269.0, 1.39, 2.08],
    [276.0, 1.43, 2.15],
    [284.0, 1.45, 2.21],
    [292.0, 1.48, 2.28],
    [301.0, 1.53, 2.34],
    [311.0, 1.58, 2.4],
    [320.0, 1.65, 2.47],
    [332.0, 1.69, 2.53],
    [342.0, 1.76, 2.58],
    [354.0, 1.84, 2.64],
    [368.0, 1.87, 2.69],
    [381.0, 1.92, 2.74],
    [397.0, 2.0, 2.83],
    [413.0, 2.08, 2.93],
    [431.0, 2.19, 3.04],
    [451.0, 2.33, 3.14],
    [471.0, 2.51, 3.24],
    [496.0, 2.75, 3.3],
    [521.0, 2.94, 3.33],
    [549.0, 3.18, 3.33],
    [582.0, 3.22, 3.3],
    [617.0, 3.17, 3.3],
    [659.0, 3.09, 3.34],
    [704.0, 3.05, 3.39],
    [756.0, 3.08, 3.42],
    [821.0, 3.2, 3.48],
    [892.0, 3.3, 3.52],
    [984.0, 3.41, 3.57],
    [1088.0, 3.58, 3.58],
    [1216.0, 3.67, 3.6],
    [1393.0, 3.69, 3.84],
    [1610.0, 3.66, 4.31],
    [1937.0, 3.71, 5.04],
];

static MATERIALS: [Material; 7] = [
    Material {
        name: "TiO2",
        aliases: &["titanium dioxide", "titania"],
        source: SEED_SOURCE,
        table: &TIO2,
    },
    Material {
        name: "gold",
        aliases: &["Au"],
        source: SEED_SOURCE,
        table: &GOLD,
    },
    Material {
        name: "iron oxide",
        aliases: &["rust", "Fe2O3"],
        source: SEED_SOURCE,
        table: &IRON_OXIDE,
    },
    Material {
        name: "AlGaAs",
        aliases: &["aluminium gallium arsenide", "aluminum gallium arsenide"],
        source: SEED_SOURCE,
        table: &ALGAAS,
    },
    Material {
        name: "silver",
        aliases: &["Ag"],
        source: SEED_SOURCE,
        table: &SILVER,
    },
    Material {
        name: "aluminium",
        aliases: &["aluminum", "Al"],
        source: "A. D. Rakić, \"Algorithm for the determination of intrinsic optical constants \
                 of metal films: application to aluminum\", Appl. Opt. 34, 4755-4767 (1995), \
                 doi:10.1364/AO.34.004755; n, k rows 206.64-2066.4 nm as tabulated in the \
                 refractiveindex.info database (database/data-nk/main/Al/Rakic.yml, CC0)",
        table: &ALUMINIUM,
    },
    Material {
        name: "chromium",
        aliases: &["Cr"],
        source: "P. B. Johnson and R. W. Christy, \"Optical constants of transition metals: \
                 Ti, V, Cr, Mn, Fe, Co, Ni, and Pd\", Phys. Rev. B 9, 5056-5070 (1974), \
                 doi:10.1103/PhysRevB.9.5056; n, k 188-1937 nm as tabulated in the \
                 refractiveindex.info database (database/data-nk/main/Cr/Johnson.yml, CC0; \
                 wavelengths converted from the paper's photon energies)",
        table: &CHROMIUM,
    },
];

/// All built-in materials.
pub fn materials() -> &'static [Material] {
    &MATERIALS
}

/// Canonical names of the built-in materials, in table order.
pub fn known_materials() -> Vec<&'static str> {
    MATERIALS.iter().map(|m| m.name).collect()
}

/// The material called `name` (canonical name or alias; case and
/// non-alphanumeric characters ignored).
///
/// # Errors
/// [`PhysicsError::UnknownMaterial`] listing the known canonical names.
pub fn find(name: &str) -> Result<&'static Material, PhysicsError> {
    let key = normalize(name);
    MATERIALS
        .iter()
        .find(|m| {
            !key.is_empty()
                && (normalize(m.name) == key || m.aliases.iter().any(|a| normalize(a) == key))
        })
        .ok_or_else(|| PhysicsError::UnknownMaterial {
            name: name.to_string(),
            known: known_materials().join(", "),
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
/// `wavelength_nm` (vacuum), linearly interpolated in wavelength between
/// tabulated nodes (module doc); exact at a node.
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
        let t = self.table;
        let (lo, hi) = self.wavelength_range_nm();
        if t.len() == 1 {
            let tol = SINGLE_WAVELENGTH_TOLERANCE_NM;
            if wavelength_nm.is_finite() && (wavelength_nm - lo).abs() <= tol {
                return Ok(RefractiveIndex::new(t[0][1], t[0][2]));
            }
            return Err(PhysicsError::OutOfRange {
                name: "wavelength_nm",
                value: wavelength_nm,
                range: format!(
                    "[{}, {}] nm (single-wavelength table of {} at {lo} nm ± {tol} nm)",
                    lo - tol,
                    lo + tol,
                    self.name
                ),
            });
        }
        if !(wavelength_nm.is_finite() && (lo..=hi).contains(&wavelength_nm)) {
            return Err(PhysicsError::OutOfRange {
                name: "wavelength_nm",
                value: wavelength_nm,
                range: format!("[{lo}, {hi}] nm (table of {})", self.name),
            });
        }
        // First row with wavelength >= λ (exists since λ <= hi).
        let j = t.partition_point(|row| row[0] < wavelength_nm);
        if t[j][0] == wavelength_nm || j == 0 {
            return Ok(RefractiveIndex::new(t[j][1], t[j][2]));
        }
        let (a, b) = (t[j - 1], t[j]);
        let s = (wavelength_nm - a[0]) / (b[0] - a[0]);
        Ok(RefractiveIndex::new(
            (1.0 - s) * a[1] + s * b[1],
            (1.0 - s) * a[2] + s * b[2],
        ))
    }
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
            for (wl, (n, k)) in [450.0, 550.0, 650.0].into_iter().zip(vals) {
                let m = refractive_index(name, wl).unwrap();
                assert_eq!((m.n, m.k), (n, k), "{name} at {wl}");
            }
            assert_eq!(source(name).unwrap(), SEED_SOURCE);
        }
    }

    #[test]
    fn aluminium_and_chromium_nodes_and_hene() {
        // Nodes, exactly.
        assert_index("Al", 619.93, 1.3660, 7.4052, 0.0);
        assert_index("Al", 652.25, 1.5724, 7.7354, 0.0);
        assert_index("Cr", 617.0, 3.17, 3.30, 0.0);
        assert_index("Cr", 659.0, 3.09, 3.34, 0.0);
        // He-Ne 632.8 nm (seed Table 1 experiment), linear interpolation.
        assert_index("aluminium", 632.8, 1.448_190, 7.536_687, 2e-6);
        assert_index("chromium", 632.8, 3.139_905, 3.315_048, 2e-6);
        // refractiveindex.info forum (M. Polyanskiy), Al at 0.6 µm from the
        // same Rakić table, linear interpolation: n = 1.26232, k = 7.1855.
        assert_index("aluminum", 600.0, 1.26232, 7.1855, 6e-5);
    }

    #[test]
    fn interpolation_midpoint_and_node_exactness() {
        // Linear in n and k between 450 and 550 nm.
        assert_index(
            "gold",
            500.0,
            0.5 * (1.509 + 0.350),
            0.5 * (1.879 + 2.714),
            1e-15,
        );
        assert_index(
            "silver",
            600.0,
            0.5 * (0.125 + 0.139),
            0.5 * (3.339 + 4.129),
            1e-15,
        );
        // A quarter of the way, chromium 0.617 -> 0.659 µm.
        let wl = 617.0 + 0.25 * 42.0;
        assert_index("Cr", wl, 3.17 - 0.25 * 0.08, 3.30 + 0.25 * 0.04, 1e-14);
        // Range ends are exact nodes.
        assert_index("TiO2", 450.0, 3.141, 0.0, 0.0);
        assert_index("TiO2", 650.0, 2.860, 0.0, 0.0);
        // Continuity across a node.
        let below = refractive_index("Al", 652.25 - 1e-9).unwrap();
        assert!((below.n - 1.5724).abs() < 1e-9 && (below.k - 7.7354).abs() < 1e-9);
    }

    #[test]
    fn names_and_aliases() {
        let cases = [
            ("TiO2", "TiO2"),
            ("tio2", "TiO2"),
            ("Titanium Dioxide", "TiO2"),
            ("titanium_dioxide", "TiO2"),
            ("gold", "gold"),
            ("AU", "gold"),
            ("iron oxide", "iron oxide"),
            ("Iron-Oxide", "iron oxide"),
            ("rust", "iron oxide"),
            ("Fe2O3", "iron oxide"),
            ("algaas", "AlGaAs"),
            ("silver", "silver"),
            ("Ag", "silver"),
            ("Aluminium", "aluminium"),
            ("aluminum", "aluminium"),
            ("Al", "aluminium"),
            ("chromium", "chromium"),
            ("cr", "chromium"),
        ];
        for (q, canon) in cases {
            assert_eq!(find(q).unwrap().name, canon, "{q}");
        }
        assert_eq!(
            known_materials(),
            vec![
                "TiO2",
                "gold",
                "iron oxide",
                "AlGaAs",
                "silver",
                "aluminium",
                "chromium"
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
            ("gold", 449.9),
            ("gold", 650.1),
            ("TiO2", 632.8 + 100.0),
            ("Al", 200.0),
            ("Al", 2100.0),
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
        for m in materials() {
            assert!(!m.table.is_empty(), "{}", m.name);
            assert!(!m.source.is_empty());
            for w in m.table.windows(2) {
                assert!(w[0][0] < w[1][0], "{}: wavelengths not increasing", m.name);
            }
            for row in m.table {
                assert!(row[1] > 0.0 && row[2] >= 0.0, "{}: {row:?}", m.name);
            }
            // Every name resolves to itself.
            assert_eq!(find(m.name).unwrap().name, m.name);
            for a in m.aliases {
                assert_eq!(find(a).unwrap().name, m.name);
            }
        }
    }
}
