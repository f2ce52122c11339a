//! `polbrdf mie`, run as the real binary: published Mie values, the Rayleigh
//! limit, normalisation of the printed matrix, size distributions, material
//! lookup and the errors for bad input (each names its flag).

use serde_json::Value;
use std::f64::consts::PI;
use std::process::Command;

/// Runs `polbrdf mie ARGS`: (exit code, stdout, stderr).
fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_polbrdf"))
        .arg("mie")
        .args(args)
        .output()
        .expect("run polbrdf");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8(out.stdout).expect("utf-8"),
        String::from_utf8(out.stderr).expect("utf-8"),
    )
}

/// Runs `polbrdf mie ARGS`, expecting success; the printed JSON.
fn ok(args: &[&str]) -> Value {
    let (code, out, err) = run(args);
    assert_eq!(code, 0, "polbrdf mie {args:?} failed: {err}");
    serde_json::from_str(&out).expect("JSON on stdout")
}

fn num(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} missing in {v}"))
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

/// Comma-separated angles `0, step, …, 180`.
fn angle_list(step_deg: f64) -> String {
    let n = (180.0 / step_deg).round() as usize;
    (0..=n)
        .map(|i| format!("{}", step_deg * i as f64))
        .collect::<Vec<_>>()
        .join(",")
}

/// Half a unit in the last of `digits` significant digits of `printed`.
fn half_ulp(printed: f64, digits: i32) -> f64 {
    if printed == 0.0 {
        return 0.5 * 10f64.powi(-digits);
    }
    let e = printed.abs().log10().floor() as i32;
    0.5 * 10f64.powi(e - digits + 1)
}

/// Radius (µm) giving size parameter `x` at 1000 nm in a host of index 1.
fn radius_for_x(x: f64) -> String {
    format!("{:.17}", x / (2.0 * PI))
}

/// ½ ∫ f(Θ) sin Θ dΘ by the trapezoid rule on the angle grid (degrees).
fn half_integral(theta_deg: &[f64], f: &[f64]) -> f64 {
    let mut s = 0.0;
    for i in 1..theta_deg.len() {
        let (t0, t1) = (theta_deg[i - 1].to_radians(), theta_deg[i].to_radians());
        s += 0.5 * (t1 - t0) * (f[i - 1] * t0.sin() + f[i] * t1.sin());
    }
    0.5 * s
}

/// Checks β0 = 1, g = β1/3, equal lengths, and round trip within tolerance.
fn check_expansion(v: &Value) {
    let e = &v["expansion"];
    let beta = floats(&e["beta"]);
    for key in ["alpha", "zeta", "delta", "gamma", "epsilon"] {
        assert_eq!(floats(&e[key]).len(), beta.len(), "{key} length");
    }
    let rep = &v["expansion_report"];
    assert_eq!(num(rep, "n_terms") as usize, beta.len());
    assert!(num(rep, "n_nodes") >= 1.0);
    assert!((beta[0] - 1.0).abs() < 1e-9, "beta_0 = {}", beta[0]);
    let tol = num(rep, "tolerance");
    assert!(
        num(rep, "round_trip_error") <= tol,
        "round trip {} > tolerance {tol}",
        num(rep, "round_trip_error")
    );
    if beta.len() > 1 {
        assert!(
            (beta[1] / 3.0 - num(v, "g")).abs() < 1e-6,
            "g {} vs beta_1/3 {}",
            num(v, "g"),
            beta[1] / 3.0
        );
    }
}

// ------------------------------------------------------ published Mie values

/// Bohren & Huffman (1983), Appendix A (p. 482), the BHMIE worked example:
/// sphere of radius 0.525 µm, m = 1.55, λ = 0.6328 µm (x = 5.213):
/// QSCA = QEXT = 3.10543, QBACK = 2.92534, and S11 (normalised to its forward
/// value), POL = −S12/S11, S33/S11, S34/S11 every 9°. The same published
/// table as src/physics/mie.rs (bohren_huffman_appendix_a_example), read
/// here through the CLI: POL = −b1/a1, S33/S11 = a3/a1, S34/S11 = b2/a1
/// (conventions §3). BHMIE ran in single precision: ≤ 2 units of the 6th
/// printed digit for the table, half a unit for the efficiencies.
#[test]
fn bhmie_worked_example() {
    let angles = angle_list(9.0);
    let v = ok(&[
        "--n",
        "1.55",
        "--k",
        "0",
        "--wavelength-nm",
        "632.8",
        "--radius-um",
        "0.525",
        "--host-index",
        "1",
        "--angles-deg",
        &angles,
    ]);
    let x = 2.0 * PI * 0.525 / 0.6328;
    assert!((num(&v, "size_parameter") - x).abs() < 1e-12 * x);
    assert!((num(&v, "size_parameter") - 5.213).abs() < 5e-4); // BH's printed x
    assert_eq!(num(&v["relative_index"], "n"), 1.55);
    assert_eq!(num(&v["relative_index"], "k"), 0.0);
    for (key, want) in [("qext", 3.10543), ("qsca", 3.10543), ("qback", 2.92534)] {
        let got = num(&v, key);
        assert!(
            (got - want).abs() <= half_ulp(want, 6),
            "{key}: {got} vs BH {want}"
        );
    }
    assert_eq!(num(&v, "qabs"), 0.0);
    assert_eq!(num(&v, "albedo"), 1.0);

    #[rustfmt::skip]
    // Published table values (0.785390 happens to be close to π/4).
    #[allow(clippy::approx_constant)]
    let s11 = [
        0.100000e01, 0.785390e00, 0.356897e00, 0.766119e-01, 0.355355e-01, 0.701845e-01,
        0.574313e-01, 0.219660e-01, 0.125959e-01, 0.173750e-01, 0.124601e-01, 0.679093e-02,
        0.954239e-02, 0.863419e-02, 0.227421e-02, 0.543998e-02, 0.160243e-01, 0.188852e-01,
        0.195254e-01, 0.301676e-01, 0.383189e-01,
    ];
    #[rustfmt::skip]
    let pol = [
        0.000000e00, -0.459811e-02, -0.458541e-01, -0.364744e00, -0.534997e00, 0.959953e-02,
        0.477927e-01, -0.440604e00, -0.831996e00, 0.341670e-01, 0.230462e00, -0.713472e00,
        -0.756255e00, -0.281215e00, -0.239612e00, -0.850804e00, -0.706334e00, -0.891081e00,
        -0.783319e00, -0.196194e00, 0.000000e00,
    ];
    #[rustfmt::skip]
    let s33 = [
        0.100000e01, 0.999400e00, 0.986022e00, 0.843603e00, 0.686967e00, 0.959825e00,
        0.985371e00, 0.648043e00, 0.203255e00, 0.795354e00, 0.937497e00, -0.717397e-02,
        -0.394748e-01, 0.536251e00, 0.967602e00, 0.187531e00, 0.495254e00, 0.453277e00,
        -0.391613e00, -0.962069e00, -0.100000e01,
    ];
    #[rustfmt::skip]
    let s34 = [
        0.000000e00, 0.343261e-01, 0.160184e00, 0.394076e00, -0.491787e00, -0.280434e00,
        0.163584e00, 0.621216e00, -0.516208e00, -0.605182e00, 0.260742e00, 0.700647e00,
        -0.653085e00, -0.795835e00, 0.795798e-01, -0.490882e00, -0.505781e00, -0.226817e-01,
        0.482752e00, 0.189556e00, 0.000000e00,
    ];
    let f = &v["phase_matrix"];
    let theta = floats(&f["theta_deg"]);
    assert_eq!(theta.len(), 21);
    let [a1, a2, a3, a4, b1, b2] = ["a1", "a2", "a3", "a4", "b1", "b2"].map(|k| floats(&f[k]));
    for i in 0..21 {
        assert_eq!(theta[i], 9.0 * i as f64);
        // Spheres: a1 = a2, a3 = a4 (conventions §3).
        assert_eq!(a1[i], a2[i]);
        assert_eq!(a3[i], a4[i]);
        let got = [a1[i] / a1[0], -b1[i] / a1[i], a3[i] / a1[i], b2[i] / a1[i]];
        let want = [s11[i], pol[i], s33[i], s34[i]];
        for j in 0..4 {
            let units = (got[j] - want[j]).abs() / (2.0 * half_ulp(want[j], 6));
            assert!(
                units <= 2.0,
                "{}°, column {j}: {} vs BH {}",
                theta[i],
                got[j],
                want[j]
            );
        }
    }
    check_expansion(&v);
}

/// W. J. Wiscombe, NCAR/TN-140+STR (1979), Appendix test output (p. A22):
/// x = 10, m = 1.5 (QEXT = QSCA = 2.881999, G = 0.742913) and m = 1.5 − 0.1i
/// in MIEV0's sign, 1.5 + 0.1i here (QEXT = 2.459791, QSCA = 1.235144,
/// G = 0.922350), printed with six decimals; the values cited in
/// src/physics/mie.rs (wiscombe_1979_appendix_tables). Checks the absorbing
/// path and that `--k` is the conventions-§2 absorbing sign.
#[test]
fn wiscombe_x10_cases() {
    let r = radius_for_x(10.0);
    for (k, qext, qsca, g) in [
        ("0", 2.881999, 2.881999, 0.742913),
        ("0.1", 2.459791, 1.235144, 0.922350),
    ] {
        let v = ok(&[
            "--n",
            "1.5",
            "--k",
            k,
            "--wavelength-nm",
            "1000",
            "--radius-um",
            &r,
        ]);
        assert!((num(&v, "size_parameter") - 10.0).abs() < 1e-12);
        for (key, want) in [("qext", qext), ("qsca", qsca), ("g", g)] {
            let got = num(&v, key);
            assert!(
                (got - want).abs() <= 1e-6,
                "k={k} {key}: {got} vs Wiscombe {want}"
            );
        }
        let want_albedo = qsca / qext;
        assert!((num(&v, "albedo") - want_albedo).abs() < 1e-6);
        assert!((num(&v, "qabs") - (qext - qsca)).abs() <= 2e-6);
        check_expansion(&v);
    }
}

// ---------------------------------------------------------------- Rayleigh

/// Dipole (Rayleigh) limit, conventions §4: β0 = 1, β2 = 1/2, α2 = 3,
/// δ1 = 3/2, γ2 = −√6/2, all other coefficients 0 (Hansen & Travis 1974,
/// Siewert's convention); a1 = ¾(1+cos²Θ), b1 = −¾ sin²Θ (BH §5.2). At
/// x ≈ 1.1e-4 the corrections are O(x²) ≈ 1e-8.
#[test]
fn rayleigh_limit_expansion() {
    let v = ok(&[
        "--n",
        "1.5",
        "--k",
        "0",
        "--wavelength-nm",
        "550",
        "--radius-um",
        "1e-5",
        "--angles-deg",
        "0,45,90,135,180",
    ]);
    assert!((num(&v, "size_parameter") - 2.0 * PI * 1e-5 / 0.55).abs() < 1e-15);
    assert_eq!(num(&v, "albedo"), 1.0);
    let e = &v["expansion"];
    let want: [(&str, &[(usize, f64)]); 6] = [
        ("beta", &[(0, 1.0), (2, 0.5)]),
        ("alpha", &[(2, 3.0)]),
        ("zeta", &[]),
        ("delta", &[(1, 1.5)]),
        ("gamma", &[(2, -(6f64.sqrt()) / 2.0)]),
        ("epsilon", &[]),
    ];
    for (key, nonzero) in want {
        let c = floats(&e[key]);
        for (l, &got) in c.iter().enumerate() {
            let w = nonzero.iter().find(|(ll, _)| *ll == l).map_or(0.0, |p| p.1);
            assert!((got - w).abs() < 1e-6, "{key}_{l} = {got}, Rayleigh {w}");
        }
        for &(l, w) in nonzero {
            assert!(l < c.len(), "{key}_{l} (= {w}) missing");
        }
    }
    let f = &v["phase_matrix"];
    let theta = floats(&f["theta_deg"]);
    let (a1, b1) = (floats(&f["a1"]), floats(&f["b1"]));
    for i in 0..theta.len() {
        let mu = theta[i].to_radians().cos();
        assert!((a1[i] - 0.75 * (1.0 + mu * mu)).abs() < 1e-6);
        assert!((b1[i] + 0.75 * (1.0 - mu * mu)).abs() < 1e-6);
    }
    check_expansion(&v);
}

/// Absorbing dipole: albedo = Q_sca / (Q_sca + Q_abs) with
/// Q_sca = (8/3) x⁴ |K|², Q_abs = 4 x Im K, K = (m² − 1)/(m² + 2) (BH eqs.
/// 5.8, 5.11); relative corrections O(x²) ≈ 1e-6 at x = 1e-3.
#[test]
fn rayleigh_limit_albedo() {
    let (n, k) = (1.5, 0.01);
    let x: f64 = 1e-3;
    let r = format!("{:.17}", x * 0.55 / (2.0 * PI));
    let v = ok(&[
        "--n",
        "1.5",
        "--k",
        "0.01",
        "--wavelength-nm",
        "550",
        "--radius-um",
        &r,
    ]);
    // K = (m² − 1)/(m² + 2) in real arithmetic.
    let (m2r, m2i) = (n * n - k * k, 2.0 * n * k);
    let (nr, ni, dr, di) = (m2r - 1.0, m2i, m2r + 2.0, m2i);
    let d2 = dr * dr + di * di;
    let (kr, ki) = ((nr * dr + ni * di) / d2, (ni * dr - nr * di) / d2);
    let qsca = 8.0 / 3.0 * x.powi(4) * (kr * kr + ki * ki);
    let qabs = 4.0 * x * ki;
    let want = qsca / (qsca + qabs);
    let got = num(&v, "albedo");
    assert!(
        ((got - want) / want).abs() < 1e-4,
        "albedo {got} vs dipole {want}"
    );
    assert!(((num(&v, "qabs") - qabs) / qabs).abs() < 1e-4);
    check_expansion(&v);
}

// ------------------------------------------------------------ normalisation

/// The printed a1 integrates to one, ½ ∫ a1 sinΘ dΘ = 1 (conventions §3),
/// and ½ ∫ a1 cosΘ sinΘ dΘ = g, by the trapezoid rule on a 0.05° grid, for a
/// sphere and for a log-normal population (averaged matrix).
#[test]
fn printed_a1_is_normalised() {
    let angles = angle_list(0.05);
    let sphere = [
        "--n",
        "1.55",
        "--k",
        "0.02",
        "--wavelength-nm",
        "632.8",
        "--radius-um",
        "0.525",
    ];
    let population = [
        "--material",
        "TiO2",
        "--wavelength-nm",
        "550",
        "--host-index",
        "1.5",
        "--lognormal-rg-um",
        "0.2",
        "--lognormal-sigma",
        "1.3",
    ];
    for base in [&sphere[..], &population[..]] {
        let mut args = base.to_vec();
        args.extend(["--angles-deg", &angles]);
        let v = ok(&args);
        let f = &v["phase_matrix"];
        let theta = floats(&f["theta_deg"]);
        assert_eq!(theta.len(), 3601);
        let a1 = floats(&f["a1"]);
        let norm = half_integral(&theta, &a1);
        assert!((norm - 1.0).abs() < 1e-5, "{base:?}: ½∫a1 = {norm}");
        let a1mu: Vec<f64> = a1
            .iter()
            .zip(&theta)
            .map(|(a, t)| a * t.to_radians().cos())
            .collect();
        let g = half_integral(&theta, &a1mu);
        assert!((g - num(&v, "g")).abs() < 1e-5, "{base:?}: g {g}");
        check_expansion(&v);
    }
}

// ------------------------------------------------------- size distributions

/// A very narrow log-normal (σ_g = 1.0001) around BH's sphere has the
/// sphere's cross sections: ⟨C_ext⟩ = ⟨C_sca⟩ ≈ QEXT π r² with BH's
/// QEXT = 3.10543; the bulk keys replace the efficiencies.
#[test]
fn narrow_distribution_matches_bhmie_sphere() {
    let v = ok(&[
        "--n",
        "1.55",
        "--k",
        "0",
        "--wavelength-nm",
        "632.8",
        "--lognormal-rg-um",
        "0.525",
        "--lognormal-sigma",
        "1.0001",
    ]);
    for key in ["qext", "qsca", "qabs", "qback", "radius_um"] {
        assert!(v.get(key).is_none(), "{key} printed for a distribution");
    }
    let want = 3.10543 * PI * 0.525 * 0.525;
    for key in ["c_ext_um2", "c_sca_um2"] {
        let got = num(&v, key);
        assert!(((got - want) / want).abs() < 1e-4, "{key} {got} vs {want}");
    }
    assert_eq!(num(&v, "c_abs_um2"), 0.0);
    let c_back = num(&v, "c_back_um2");
    let want_back = 2.92534 * PI * 0.525 * 0.525;
    assert!(
        ((c_back - want_back) / want_back).abs() < 1e-3,
        "c_back {c_back}"
    );
    // The largest size parameter is at the upper cut, above x(r_g).
    let x_g = 2.0 * PI * 0.525 / 0.6328;
    let x_max = num(&v, "size_parameter");
    assert!(x_max > x_g && x_max < 1.01 * x_g, "size_parameter {x_max}");
    assert_eq!(v["size_distribution"]["kind"], "log_normal");
    check_expansion(&v);
}

/// Gamma distribution of absorbing particles: c_abs = c_ext − c_sca,
/// albedo = c_sca / c_ext, size_parameter = x at radius_max_um.
#[test]
fn gamma_distribution_bulk_quantities() {
    let v = ok(&[
        "--n",
        "1.5",
        "--k",
        "0.01",
        "--wavelength-nm",
        "550",
        "--host-index",
        "1.3",
        "--gamma-reff-um",
        "0.3",
        "--gamma-veff",
        "0.1",
    ]);
    let (ce, cs, ca) = (
        num(&v, "c_ext_um2"),
        num(&v, "c_sca_um2"),
        num(&v, "c_abs_um2"),
    );
    assert!(ce > 0.0 && cs > 0.0 && ca > 0.0);
    assert!((ca - (ce - cs)).abs() < 1e-6 * ce);
    assert!((num(&v, "albedo") - cs / ce).abs() < 1e-12);
    let x_max = 2.0 * PI * 1.3 * num(&v, "radius_max_um") / 0.55;
    assert!((num(&v, "size_parameter") - x_max).abs() < 1e-9 * x_max);
    assert!((num(&v["relative_index"], "n") - 1.5 / 1.3).abs() < 1e-15);
    assert_eq!(v["size_distribution"]["kind"], "gamma");
    check_expansion(&v);
}

// ------------------------------------------------------ materials, TiO2 case

/// Material names are case-insensitive; the seed's TiO2 at 550 nm is
/// 2.954 + 0i (seed Table 2, as tabulated in src/physics/materials.rs).
#[test]
fn material_lookup_is_case_insensitive() {
    let base = [
        "--material-source",
        "seed",
        "--wavelength-nm",
        "550",
        "--radius-um",
        "0.2",
    ];
    let mut outputs = Vec::new();
    for name in ["TiO2", "tio2", "TIO2", "titania"] {
        let mut args = vec!["--material", name];
        args.extend(base);
        let v = ok(&args);
        assert_eq!(v["material"], "TiO2", "{name}");
        assert_eq!(num(&v["particle_index"], "n"), 2.954);
        assert_eq!(num(&v["particle_index"], "k"), 0.0);
        outputs.push(v);
    }
    assert!(outputs.iter().all(|v| *v == outputs[0]));
    // Same as the index given explicitly.
    let mut args = vec!["--n", "2.954", "--k", "0"];
    args.extend(&base[2..]);
    let v = ok(&args);
    assert_eq!(v["expansion"], outputs[0]["expansion"]);
    assert_eq!(v["qext"], outputs[0]["qext"]);
}

/// The seed's TiO2 particle (550 nm, r = 0.2 µm, air): β0 = 1 and the round
/// trip within the reported tolerance (default 1e-10 for x < 20); in a binder
/// the relative index is m / n_host.
#[test]
fn tio2_expansion_meets_its_tolerance() {
    let v = ok(&[
        "--material",
        "TiO2",
        "--material-source",
        "seed",
        "--wavelength-nm",
        "550",
        "--radius-um",
        "0.2",
    ]);
    let x = 2.0 * PI * 0.2 / 0.55;
    assert!((num(&v, "size_parameter") - x).abs() < 1e-12);
    assert_eq!(num(&v["expansion_report"], "tolerance"), 1e-10);
    check_expansion(&v);
    assert!(v.get("phase_matrix").is_none());

    let v = ok(&[
        "--material",
        "TiO2",
        "--material-source",
        "seed",
        "--wavelength-nm",
        "550",
        "--radius-um",
        "0.2",
        "--host-index",
        "1.5",
        "--expansion-tolerance",
        "1e-8",
    ]);
    assert!((num(&v["relative_index"], "n") - 2.954 / 1.5).abs() < 1e-15);
    assert!((num(&v, "size_parameter") - 1.5 * x).abs() < 1e-12);
    assert_eq!(num(&v["expansion_report"], "tolerance"), 1e-8);
    check_expansion(&v);
}

// --------------------------------------------------------------- bad input

/// Runs with bad `args`: non-zero exit, nothing on stdout, and the first line
/// of stderr names every flag in `flags`. `own` errors (not clap's parse
/// errors) are exactly one line.
fn rejects(args: &[&str], flags: &[&str], own: bool) {
    let (code, out, err) = run(args);
    assert_ne!(code, 0, "{args:?} accepted: {out}");
    assert!(out.is_empty(), "{args:?} printed {out}");
    let first = err.lines().next().unwrap_or("");
    for f in flags {
        assert!(first.contains(f), "{args:?}: message '{first}' lacks {f}");
    }
    if own {
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    }
}

#[test]
fn bad_input_names_the_argument() {
    let idx = ["--material", "TiO2", "--wavelength-nm", "550"];
    let with = |extra: &[&'static str]| -> Vec<&'static str> {
        let mut v = idx.to_vec();
        v.extend_from_slice(extra);
        v
    };
    // Negative, zero or non-finite radius.
    rejects(&with(&["--radius-um", "-0.2"]), &["--radius-um"], true);
    rejects(&with(&["--radius-um=-0.2"]), &["--radius-um"], true);
    rejects(&with(&["--radius-um", "0"]), &["--radius-um"], true);
    rejects(&with(&["--radius-um", "nan"]), &["--radius-um"], true);
    // Unknown material.
    rejects(
        &[
            "--material",
            "unobtainium",
            "--wavelength-nm",
            "550",
            "--radius-um",
            "0.2",
        ],
        &["--material", "unobtainium"],
        true,
    );
    // Wavelength outside the material's table (430–1530 nm for measured
    // rutile, 450–650 nm for the seed's TiO2).
    for (source, wl) in [("measured", "1600"), ("measured", "400"), ("seed", "700")] {
        rejects(
            &[
                "--material",
                "TiO2",
                "--material-source",
                source,
                "--wavelength-nm",
                wl,
                "--radius-um",
                "0.2",
            ],
            &["--wavelength-nm"],
            true,
        );
    }
    rejects(
        &[
            "--n",
            "1.5",
            "--k",
            "0",
            "--wavelength-nm",
            "-550",
            "--radius-um",
            "0.2",
        ],
        &["--wavelength-nm"],
        true,
    );
    // Malformed numbers (clap's parse errors).
    rejects(
        &[
            "--material",
            "TiO2",
            "--wavelength-nm",
            "abc",
            "--radius-um",
            "0.2",
        ],
        &["--wavelength-nm"],
        false,
    );
    rejects(&with(&["--radius-um", "0.2.3"]), &["--radius-um"], false);
    rejects(
        &with(&["--radius-um", "0.2", "--angles-deg", "0,x,10"]),
        &["--angles-deg"],
        false,
    );
    rejects(
        &with(&["--radius-um", "0.2", "--host-index", "1,5"]),
        &["--host-index"],
        false,
    );
    // A flag without its value.
    rejects(
        &[
            "--material",
            "TiO2",
            "--wavelength-nm",
            "550",
            "--radius-um",
        ],
        &["--radius-um"],
        false,
    );
    // Missing options.
    rejects(
        &["--wavelength-nm", "550", "--radius-um", "0.2"],
        &["--material", "--n"],
        true,
    );
    rejects(
        &["--material", "TiO2", "--radius-um", "0.2"],
        &["--wavelength-nm"],
        true,
    );
    rejects(&idx, &["--radius-um"], true);
    rejects(
        &["--n", "1.5", "--wavelength-nm", "550", "--radius-um", "0.2"],
        &["--k"],
        true,
    );
    rejects(
        &["--k", "0", "--wavelength-nm", "550", "--radius-um", "0.2"],
        &["--n"],
        true,
    );
    rejects(
        &with(&["--lognormal-rg-um", "0.2"]),
        &["--lognormal-sigma"],
        true,
    );
    rejects(&with(&["--gamma-veff", "0.1"]), &["--gamma-reff-um"], true);
    // Conflicting options.
    rejects(
        &with(&["--n", "2", "--k", "0", "--radius-um", "0.2"]),
        &["--material", "--n"],
        true,
    );
    rejects(
        &with(&[
            "--radius-um",
            "0.2",
            "--lognormal-rg-um",
            "0.2",
            "--lognormal-sigma",
            "1.3",
        ]),
        &["--radius-um", "--lognormal"],
        true,
    );
    rejects(
        &with(&[
            "--gamma-reff-um",
            "0.2",
            "--gamma-veff",
            "0.1",
            "--lognormal-rg-um",
            "0.2",
            "--lognormal-sigma",
            "1.3",
        ]),
        &["--lognormal", "--gamma"],
        true,
    );
    // Angles outside [0, 180].
    for a in ["0,190", "-1,10", "0,inf"] {
        rejects(
            &with(&["--radius-um", "0.2", "--angles-deg", a]),
            &["--angles-deg"],
            true,
        );
    }
    // Other out-of-range values.
    rejects(
        &with(&["--radius-um", "0.2", "--host-index", "0.9"]),
        &["--host-index"],
        true,
    );
    rejects(
        &[
            "--n",
            "1.5",
            "--k",
            "-0.1",
            "--wavelength-nm",
            "550",
            "--radius-um",
            "0.2",
        ],
        &["--k"],
        true,
    );
    rejects(
        &[
            "--n",
            "0",
            "--k",
            "0",
            "--wavelength-nm",
            "550",
            "--radius-um",
            "0.2",
        ],
        &["--n"],
        true,
    );
    for t in ["0", "1", "-0.1", "nan"] {
        rejects(
            &with(&["--radius-um", "0.2", "--expansion-tolerance", t]),
            &["--expansion-tolerance"],
            true,
        );
    }
    rejects(
        &with(&["--lognormal-rg-um", "0.2", "--lognormal-sigma", "0.9"]),
        &["--lognormal-sigma"],
        true,
    );
    rejects(
        &with(&["--lognormal-rg-um", "-0.2", "--lognormal-sigma", "1.3"]),
        &["--lognormal-rg-um"],
        true,
    );
    rejects(
        &with(&["--gamma-reff-um", "0.2", "--gamma-veff", "0.6"]),
        &["--gamma-veff"],
        true,
    );
    // Size parameter beyond the validated range (x ≈ 2.3e4 > 2e4).
    rejects(&with(&["--radius-um", "2000"]), &["--radius-um"], true);
}
