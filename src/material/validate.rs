//! Validation: every field of a parsed spec inside its allowed range, the
//! error naming its JSON path and the range (docs/spec.md). The range texts
//! are also what [`super::parse`] reports for a value that does not even
//! parse at a numeric field.

use super::{
    BaseSpec, HostSpec, LayerForm, LayerSpec, MaterialSpec, PigmentSpec, ScattererSpec,
    SizeDistributionSpec, Spec, SpecError, ThicknessSpec, TopInterfaceSpec,
};
use crate::physics::materials;

/// Hard limits of the spec (the service adds its own, lower, caps).
pub const MAX_STREAMS: usize = 512;

// Allowed ranges, one text per field: `validate` reports them, and so does
// a value that does not even parse there (`NaN`, `1e999`, a string).
const R_THICKNESS: &str = "[0, 1e12] (or \"infinite\")";
const R_UNIT: &str = "[0, 1]";
const R_INDEX_REAL: &str = "[1, 10]";
const R_RADIUS: &str = "[1e-6, 1e4] µm";
const R_SIGMA_G: &str = "[1.0001, 5]";
const R_V_EFF: &str = "[1e-4, 0.49]";
const R_DEPOLARIZATION: &str = "[0, 0.99]";
const R_G: &str = "[-0.999, 0.999]";
const R_N: &str = "(0, 100]";
const R_K: &str = "[0, 100]";
/// Smallest GGX roughness of a rough base: below it the lobe needs more
/// azimuthal orders than it is worth (docs/solver.md, Rough bases); a
/// smoother surface is the `fresnel` base.
pub const ALPHA_MIN: f64 = 0.05;
const R_ALPHA: &str = "[0.05, 1] (a smoother surface is the `fresnel` base)";
const R_WAVELENGTH: &str = "[100, 100000] nm";
const R_STREAMS: &str = "[1, 512] (integer)";
const R_TOLERANCE: &str = "[1e-10, 0.5]";
const R_COEFFICIENT: &str = "finite numbers with |x| ≤ 1e6";
const R_FILM_THICKNESS: &str = "[1e-6, 1e6] µm";
const R_VOLUME_FRACTION: &str = "(0, 1)";

/// A JSON path with its array indices left out: `layers[3].scatterer` →
/// `layers[].scatterer`.
pub(super) fn without_indices(path: &str) -> String {
    let mut p = String::with_capacity(path.len());
    let mut in_index = false;
    for c in path.chars() {
        match c {
            '[' => {
                in_index = true;
                p.push('[');
            }
            ']' => {
                in_index = false;
                p.push(']');
            }
            _ if in_index => {}
            _ => p.push(c),
        }
    }
    p
}

/// The allowed range of the numeric field at a JSON path, if it is one.
fn allowed_range(path: &str) -> Option<&'static str> {
    let p = without_indices(path);
    let p = p.as_str();
    let tail = |suffix: &str| p.ends_with(suffix);
    Some(match p {
        "layers[].optical_thickness" => R_THICKNESS,
        "wavelengths_nm[]" => R_WAVELENGTH,
        "solver.streams" => R_STREAMS,
        "solver.tolerance" => R_TOLERANCE,
        "base.lambertian.albedo" => R_UNIT,
        "base.fresnel.ambient_index" => R_INDEX_REAL,
        _ if tail(".mie.host_index") || tail("].binder") => R_INDEX_REAL,
        "layers[].thickness_um" => R_FILM_THICKNESS,
        _ if tail(".volume_fraction") => R_VOLUME_FRACTION,
        _ if tail(".mie.radius_um")
            || tail("].radius_um")
            || tail(".r_g_um")
            || tail(".r_eff_um") =>
        {
            R_RADIUS
        }
        _ if tail(".sigma_g") => R_SIGMA_G,
        _ if tail(".v_eff") => R_V_EFF,
        _ if tail("material.n") => R_N,
        _ if tail("material.k") => R_K,
        _ if tail(".rayleigh.depolarization") => R_DEPOLARIZATION,
        _ if tail(".henyey_greenstein.g") => R_G,
        _ if tail(".albedo") => R_UNIT,
        _ if p.starts_with("layers[].scatterer.expansion.") && tail("[]") => R_COEFFICIENT,
        _ => return None,
    })
}

/// A value that did not parse at a numeric field: name what is allowed
/// there (`NaN`, `Infinity` and numbers beyond ±1.8e308 are not JSON numbers).
pub(super) fn with_allowed_range(e: SpecError) -> SpecError {
    let Some(range) = allowed_range(&e.path) else {
        return e;
    };
    let not_a_number =
        e.message.starts_with("expected value") || e.message.starts_with("number out of range");
    let message = if not_a_number {
        format!(
            "not a finite JSON number ({}; NaN, Infinity and numbers beyond ±1.8e308 are not JSON); allowed: {range}",
            e.message
        )
    } else {
        format!("{}; allowed: {range}", e.message)
    };
    SpecError::new(e.path, message)
}

fn finite_in(path: &str, v: f64, lo: f64, hi: f64, what: &str) -> Result<(), SpecError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(SpecError::new(
            path,
            format!("{v} is outside the allowed range {what}"),
        ))
    }
}

fn needs_wavelength(spec: &Spec) -> bool {
    let named = |m: &MaterialSpec| !m.is_constant();
    spec.layers.iter().any(|l| {
        matches!(l.optical_scatterer(), Some(ScattererSpec::Mie(_))) || l.pigments.is_some()
    }) || spec
        .base
        .surface()
        .is_some_and(|(_, material, _)| named(material))
        || spec.top_interface.index().is_some_and(|h| !h.is_constant())
}

/// Check every range; the error names the JSON path.
pub fn validate(spec: &Spec) -> Result<(), SpecError> {
    if spec.layers.is_empty() {
        return Err(SpecError::new("layers", "at least one layer is required"));
    }
    let n_layers = spec.layers.len();
    for (i, layer) in spec.layers.iter().enumerate() {
        let p = format!("layers[{i}]");
        let form = layer.form().map_err(|(field, message)| {
            let path = if field.is_empty() {
                p.clone()
            } else {
                format!("{p}.{field}")
            };
            SpecError::new(path, message)
        })?;
        match form {
            LayerForm::Optical {
                thickness,
                scatterer,
            } => {
                validate_optical_thickness(&p, thickness, i + 1 == n_layers)?;
                validate_scatterer(&format!("{p}.scatterer"), scatterer)?;
            }
            LayerForm::Film {
                thickness_um,
                pigments,
                binder,
            } => validate_film(&p, thickness_um, pigments, binder)?,
        }
    }
    match &spec.base {
        BaseSpec::Black => {}
        BaseSpec::Lambertian { albedo } => {
            finite_in("base.lambertian.albedo", *albedo, 0.0, 1.0, R_UNIT)?
        }
        BaseSpec::Fresnel { .. } | BaseSpec::RoughFresnel { .. } => {
            let (key, material, ambient_index) = spec.base.surface().expect("a surface base");
            validate_material(&format!("base.{key}.material"), material)?;
            if let Some(a) = ambient_index {
                finite_in(
                    &format!("base.{key}.ambient_index"),
                    a,
                    1.0,
                    10.0,
                    R_INDEX_REAL,
                )?;
            }
            if let BaseSpec::RoughFresnel { alpha, .. } = &spec.base {
                finite_in("base.rough_fresnel.alpha", *alpha, ALPHA_MIN, 1.0, R_ALPHA)?;
            }
        }
    }
    validate_top_interface(spec)?;
    match &spec.wavelengths_nm {
        Some(w) => {
            if w.is_empty() || w.len() > 1000 {
                return Err(SpecError::new(
                    "wavelengths_nm",
                    "give between 1 and 1000 wavelengths",
                ));
            }
            for (i, x) in w.iter().enumerate() {
                finite_in(
                    &format!("wavelengths_nm[{i}]"),
                    *x,
                    100.0,
                    100_000.0,
                    R_WAVELENGTH,
                )?;
            }
        }
        None => {
            if needs_wavelength(spec) {
                return Err(SpecError::new(
                    "wavelengths_nm",
                    "missing field: required because a layer or the base depends on wavelength",
                ));
            }
        }
    }
    if let Some(n) = spec.solver.streams
        && (n == 0 || n > MAX_STREAMS)
    {
        return Err(SpecError::new(
            "solver.streams",
            format!("{n} is outside the allowed range [1, {MAX_STREAMS}]"),
        ));
    }
    if let Some(t) = spec.solver.tolerance {
        finite_in("solver.tolerance", t, 1e-10, 0.5, R_TOLERANCE)?;
    }
    // A tolerance next to explicit streams is ignored (docs/spec.md).
    let tolerance = spec
        .solver
        .tolerance
        .filter(|_| spec.solver.streams.is_none());
    spec.needs.validate(tolerance, spec.solver.polarized)
}

/// The JSON path of a layer's host medium (`None`: the layer has none).
fn host_path(i: usize, layer: &LayerSpec) -> Option<String> {
    match layer.form() {
        Ok(LayerForm::Optical {
            scatterer: ScattererSpec::Mie(_),
            ..
        }) => Some(format!("layers[{i}].scatterer.mie.host_index")),
        Ok(LayerForm::Film { .. }) => Some(format!("layers[{i}].binder")),
        _ => None,
    }
}

/// The binder index of a spec's `top_interface` (canonical host form),
/// `None` without an interface: the one given, or the layers' host medium
/// (`host_index` of Mie layers, `binder` of films, defaults included) when
/// the stack has one. Every layer with a host must sit in that binder.
///
/// # Errors
/// A host that differs from the interface's index or from another layer's
/// (naming both paths), or no index to default to.
pub fn interface_index(spec: &Spec) -> Result<Option<HostSpec>, SpecError> {
    let key = match &spec.top_interface {
        TopInterfaceSpec::None => return Ok(None),
        TopInterfaceSpec::Smooth { .. } => "smooth",
        TopInterfaceSpec::Rough { .. } => "rough",
    };
    let canonical = |h: &HostSpec| {
        let mut h = h.clone();
        super::canonical::canonical_host(&mut h);
        h
    };
    let index_path = format!("top_interface.{key}.index");
    let mut chosen: Option<(String, HostSpec)> = spec
        .top_interface
        .index()
        .map(|h| (index_path.clone(), canonical(h)));
    for (i, layer) in spec.layers.iter().enumerate() {
        let (Some(path), Some(host)) = (host_path(i, layer), layer.host()) else {
            continue;
        };
        let host = canonical(host);
        match &chosen {
            None => chosen = Some((path, host)),
            Some((p, h)) if *h != host => {
                return Err(SpecError::new(
                    path,
                    format!(
                        "{} differs from {p} = {}: the layers under a top_interface sit in its \
                         binder (give them the same medium, or leave top_interface.{key}.index \
                         out to take the layers')",
                        host.label(),
                        h.label()
                    ),
                ));
            }
            Some(_) => {}
        }
    }
    match chosen {
        Some((_, h)) => Ok(Some(h)),
        None => Err(SpecError::new(
            index_path,
            "missing field: no layer has a host_index or binder to take it from",
        )),
    }
}

/// `top_interface`: its index (a host medium, [`interface_index`]) and a
/// rough one's `alpha` in [`ALPHA_MIN`], 1]. A smooth (`fresnel`) base is
/// refused under a rough interface: its mirror beam would need a beam
/// through the surface, and no beam crosses a rough one (docs/solver.md,
/// "A rough top interface").
fn validate_top_interface(spec: &Spec) -> Result<(), SpecError> {
    let key = match &spec.top_interface {
        TopInterfaceSpec::None => return Ok(()),
        TopInterfaceSpec::Smooth { .. } => "smooth",
        TopInterfaceSpec::Rough { alpha, .. } => {
            finite_in(
                "top_interface.rough.alpha",
                *alpha,
                ALPHA_MIN,
                1.0,
                "[0.05, 1] (a smoother surface is `smooth`)",
            )?;
            if matches!(spec.base, BaseSpec::Fresnel { .. }) {
                return Err(SpecError::new(
                    "base.fresnel",
                    "a smooth (mirror) base under a rough top interface is not supported: \
                     no beam crosses a rough surface to carry the mirror's delta term; \
                     use {\"rough_fresnel\": {…, \"alpha\": …}} for the base",
                ));
            }
            "rough"
        }
    };
    if let Some(h) = spec.top_interface.index() {
        let path = format!("top_interface.{key}.index");
        validate_host(&path, h)?;
        if let (TopInterfaceSpec::Rough { .. }, HostSpec::Index(n)) = (&spec.top_interface, h) {
            finite_in(
                &path,
                *n,
                crate::solver::ROUGH_INTERFACE_MIN_INDEX,
                10.0,
                "[1.1, 10] (a rough interface's refracted lobe, α(1 − 1/n) wide, \
                 becomes a delta as n → 1; a binder this close to air needs no interface)",
            )?;
        }
    }
    interface_index(spec).map(|_| ())
}

/// Most rows a material table may have.
pub const MAX_TABLE_ROWS: usize = 10_000;

/// An optical layer's `optical_thickness` (`last`: the stack's last layer,
/// the only one that may be infinite).
fn validate_optical_thickness(
    p: &str,
    thickness: &ThicknessSpec,
    last: bool,
) -> Result<(), SpecError> {
    match thickness {
        ThicknessSpec::Number(t) => finite_in(
            &format!("{p}.optical_thickness"),
            *t,
            0.0,
            1e12,
            R_THICKNESS,
        )?,
        ThicknessSpec::Word(w) => {
            if w != "infinite" {
                return Err(SpecError::new(
                    format!("{p}.optical_thickness"),
                    format!("\"{w}\" is not allowed: give a number ≥ 0 or \"infinite\""),
                ));
            }
            if !last {
                return Err(SpecError::new(
                    format!("{p}.optical_thickness"),
                    "only the last layer may be \"infinite\"",
                ));
            }
        }
    }
    Ok(())
}

/// A scatterer at JSON path `sp`.
fn validate_scatterer(sp: &str, scatterer: &ScattererSpec) -> Result<(), SpecError> {
    match scatterer {
        ScattererSpec::Mie(m) => {
            let mp = format!("{sp}.mie");
            validate_material(&format!("{mp}.material"), &m.material)?;
            validate_host(&format!("{mp}.host_index"), &m.host_index)?;
            validate_particles(&mp, m.radius_um, m.size_distribution.as_ref())?;
        }
        ScattererSpec::Expansion(e) => {
            let ep = format!("{sp}.expansion");
            finite_in(&format!("{ep}.albedo"), e.albedo, 0.0, 1.0, R_UNIT)?;
            if e.beta.is_empty() {
                return Err(SpecError::new(
                    format!("{ep}.beta"),
                    "at least beta_0 = 1 is required",
                ));
            }
            if (e.beta[0] - 1.0).abs() > 1e-6 {
                return Err(SpecError::new(
                    format!("{ep}.beta[0]"),
                    format!("{} must be 1 (normalised phase function)", e.beta[0]),
                ));
            }
            for (name, v) in [
                ("beta", &e.beta),
                ("alpha", &e.alpha),
                ("zeta", &e.zeta),
                ("delta", &e.delta),
                ("gamma", &e.gamma),
                ("epsilon", &e.epsilon),
            ] {
                if v.len() > 100_000 {
                    return Err(SpecError::new(
                        format!("{ep}.{name}"),
                        "at most 100000 terms",
                    ));
                }
                for (l, x) in v.iter().enumerate() {
                    if !x.is_finite() || x.abs() > 1e6 {
                        return Err(SpecError::new(
                            format!("{ep}.{name}[{l}]"),
                            format!("{x} is outside the allowed range: {R_COEFFICIENT}"),
                        ));
                    }
                }
            }
        }
        ScattererSpec::Rayleigh {
            albedo,
            depolarization,
        } => {
            finite_in(&format!("{sp}.rayleigh.albedo"), *albedo, 0.0, 1.0, R_UNIT)?;
            finite_in(
                &format!("{sp}.rayleigh.depolarization"),
                *depolarization,
                0.0,
                0.99,
                R_DEPOLARIZATION,
            )?;
        }
        ScattererSpec::HenyeyGreenstein { albedo, g } => {
            finite_in(
                &format!("{sp}.henyey_greenstein.albedo"),
                *albedo,
                0.0,
                1.0,
                R_UNIT,
            )?;
            finite_in(&format!("{sp}.henyey_greenstein.g"), *g, -0.999, 0.999, R_G)?;
        }
    }
    Ok(())
}

/// The size of a particle population at `mp` (a Mie scatterer or a
/// pigment): `radius_um` or one `size_distribution`.
fn validate_particles(
    mp: &str,
    radius_um: Option<f64>,
    size_distribution: Option<&SizeDistributionSpec>,
) -> Result<(), SpecError> {
    match (radius_um, size_distribution) {
        (Some(r), None) => finite_in(&format!("{mp}.radius_um"), r, 1e-6, 1e4, R_RADIUS)?,
        (
            None,
            Some(
                d @ SizeDistributionSpec::Lognormal {
                    r_g_um, sigma_g, ..
                },
            ),
        ) => {
            let q = format!("{mp}.size_distribution.lognormal");
            validate_radius_limits(&q, d)?;
            finite_in(&format!("{q}.r_g_um"), *r_g_um, 1e-6, 1e4, R_RADIUS)?;
            finite_in(&format!("{q}.sigma_g"), *sigma_g, 1.0001, 5.0, R_SIGMA_G)?;
        }
        (
            None,
            Some(
                d @ SizeDistributionSpec::Gamma {
                    r_eff_um, v_eff, ..
                },
            ),
        ) => {
            let q = format!("{mp}.size_distribution.gamma");
            validate_radius_limits(&q, d)?;
            finite_in(&format!("{q}.r_eff_um"), *r_eff_um, 1e-6, 1e4, R_RADIUS)?;
            finite_in(&format!("{q}.v_eff"), *v_eff, 1e-4, 0.49, R_V_EFF)?;
        }
        (Some(_), Some(_)) => {
            return Err(SpecError::new(
                mp.to_string(),
                "give either radius_um or size_distribution, not both",
            ));
        }
        (None, None) => {
            return Err(SpecError::new(
                mp.to_string(),
                "missing field: radius_um or size_distribution is required",
            ));
        }
    }
    Ok(())
}

/// A host medium (`host_index`, `binder`) at `path`: a real index in
/// [`R_INDEX_REAL`] or a material; a material's real part ≥ 1 at the spec's
/// wavelengths is checked by `crate::plan::check_solvable`.
fn validate_host(path: &str, host: &HostSpec) -> Result<(), SpecError> {
    match host {
        HostSpec::Index(n) => finite_in(path, *n, 1.0, 10.0, R_INDEX_REAL),
        HostSpec::Material(m) => validate_material(path, m),
    }
}

/// Most pigments one film may mix.
pub const MAX_PIGMENTS: usize = 16;

/// A paint film at layer path `p`: its thickness, each pigment (material,
/// size, volume fraction) and the binder; the volume fractions sum to less
/// than 1 (the binder fills the rest).
fn validate_film(
    p: &str,
    thickness_um: f64,
    pigments: &[PigmentSpec],
    binder: &HostSpec,
) -> Result<(), SpecError> {
    finite_in(
        &format!("{p}.thickness_um"),
        thickness_um,
        1e-6,
        1e6,
        R_FILM_THICKNESS,
    )?;
    if pigments.is_empty() || pigments.len() > MAX_PIGMENTS {
        return Err(SpecError::new(
            format!("{p}.pigments"),
            format!("give between 1 and {MAX_PIGMENTS} pigments"),
        ));
    }
    let mut pvc = 0.0;
    for (j, pigment) in pigments.iter().enumerate() {
        let q = format!("{p}.pigments[{j}]");
        validate_material(&format!("{q}.material"), &pigment.material)?;
        validate_particles(&q, pigment.radius_um, pigment.size_distribution.as_ref())?;
        let f = pigment.volume_fraction;
        if !(f.is_finite() && f > 0.0 && f < 1.0) {
            return Err(SpecError::new(
                format!("{q}.volume_fraction"),
                format!("{f} is outside the allowed range {R_VOLUME_FRACTION}"),
            ));
        }
        pvc += f;
    }
    if pvc >= 1.0 {
        return Err(SpecError::new(
            format!("{p}.pigments"),
            format!(
                "the volume fractions sum to {pvc}: the pigments must leave room for the binder (sum < 1)"
            ),
        ));
    }
    validate_host(&format!("{p}.binder"), binder)
}

fn validate_material(path: &str, m: &MaterialSpec) -> Result<(), SpecError> {
    let known_name = |path: &str, name: &str| -> Result<(), SpecError> {
        materials::find(name).map(|_| ()).map_err(|_| {
            SpecError::new(
                path,
                format!(
                    "unknown material '{name}' (known: {})",
                    materials::known_materials().join(", ")
                ),
            )
        })
    };
    match m {
        MaterialSpec::Name(name) => known_name(path, name),
        MaterialSpec::Named { name, source } => {
            known_name(&format!("{path}.name"), name)?;
            match source.as_deref() {
                None | Some("measured") => Ok(()),
                Some("seed") => materials::find_seed(name)
                    .map(|_| ())
                    .map_err(|e| SpecError::new(format!("{path}.source"), e.to_string())),
                Some(other) => Err(SpecError::new(
                    format!("{path}.source"),
                    format!(
                        "'{other}' is not a material source (one of: {})",
                        super::schema::MATERIAL_SOURCES.join(", ")
                    ),
                )),
            }
        }
        MaterialSpec::Index { n, k } => {
            finite_in(&format!("{path}.n"), *n, 1e-6, 100.0, R_N)?;
            finite_in(&format!("{path}.k"), *k, 0.0, 100.0, R_K)
        }
        MaterialSpec::Table { table } => validate_table(&format!("{path}.table"), table),
    }
}

/// The rows of a `{"table"}` material (docs/spec.md), errors naming
/// `q[i][j]`.
fn validate_table(q: &str, table: &[[f64; 3]]) -> Result<(), SpecError> {
    if table.is_empty() || table.len() > MAX_TABLE_ROWS {
        return Err(SpecError::new(
            q,
            format!(
                "{} rows: a table has 1 to {MAX_TABLE_ROWS} rows [wavelength_nm, n, k]",
                table.len()
            ),
        ));
    }
    for (i, row) in table.iter().enumerate() {
        finite_in(&format!("{q}[{i}][0]"), row[0], 1.0, 1e6, "[1, 1e6] nm")?;
        finite_in(&format!("{q}[{i}][1]"), row[1], 1e-6, 100.0, R_N)?;
        finite_in(&format!("{q}[{i}][2]"), row[2], 0.0, 100.0, R_K)?;
        if i > 0 && row[0] <= table[i - 1][0] {
            return Err(SpecError::new(
                format!("{q}[{i}][0]"),
                format!(
                    "wavelengths must increase strictly: {} nm follows {} nm",
                    row[0],
                    table[i - 1][0]
                ),
            ));
        }
    }
    Ok(())
}

/// [`validate_table`] for a table read elsewhere (the CLI's
/// `--material-table`): the message names `what` and the row.
pub fn validate_material_table(what: &str, table: &[[f64; 3]]) -> Result<(), String> {
    validate_table("table", table).map_err(|e| format!("{what}: {}: {}", e.path, e.message))
}

/// `radius_min_um` / `radius_max_um` of a size distribution: both or
/// neither, each in `[1e-6, 1e4]` µm, `min < max`.
fn validate_radius_limits(q: &str, d: &SizeDistributionSpec) -> Result<(), SpecError> {
    match d.radius_limits_um() {
        (None, None) => Ok(()),
        (Some(lo), Some(hi)) => {
            finite_in(
                &format!("{q}.radius_min_um"),
                lo,
                1e-6,
                1e4,
                "[1e-6, 1e4] µm",
            )?;
            finite_in(
                &format!("{q}.radius_max_um"),
                hi,
                1e-6,
                1e4,
                "[1e-6, 1e4] µm",
            )?;
            if lo < hi {
                Ok(())
            } else {
                Err(SpecError::new(
                    format!("{q}.radius_max_um"),
                    format!("must be greater than radius_min_um = {lo}"),
                ))
            }
        }
        (Some(_), None) => Err(SpecError::new(
            format!("{q}.radius_max_um"),
            "missing field: radius_min_um requires radius_max_um",
        )),
        (None, Some(_)) => Err(SpecError::new(
            format!("{q}.radius_min_um"),
            "missing field: radius_max_um requires radius_min_um",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::parse;

    #[test]
    fn out_of_range_names_path_and_range() {
        let e =
            parse(r#"{"layers":[{"optical_thickness":-1,"scatterer":{"rayleigh":{"albedo":1}}}]}"#)
                .unwrap_err();
        assert_eq!(e.path, "layers[0].optical_thickness");
        assert!(e.message.contains("[0, 1e12]"), "{e}");
        let e = parse(r#"{"layers":[{"optical_thickness":1,"scatterer":{"henyey_greenstein":{"albedo":1.5,"g":0.5}}}]}"#)
            .unwrap_err();
        assert_eq!(e.path, "layers[0].scatterer.henyey_greenstein.albedo");
    }

    #[test]
    fn infinite_only_last_and_wavelength_required() {
        let e = parse(
            r#"{"layers":[{"optical_thickness":"infinite","scatterer":{"rayleigh":{"albedo":1}}},
                          {"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}]}"#,
        )
        .unwrap_err();
        assert_eq!(e.path, "layers[0].optical_thickness");
        let e = parse(
            r#"{"layers":[{"optical_thickness":1,"scatterer":{"mie":{"material":"TiO2","radius_um":0.2}}}]}"#,
        )
        .unwrap_err();
        assert_eq!(e.path, "wavelengths_nm");
    }

    #[test]
    fn unparsable_numbers_name_the_allowed_range() {
        for (text, path, range) in [
            (
                r#"{"layers":[{"optical_thickness":NaN,"scatterer":{"rayleigh":{"albedo":1}}}]}"#,
                "layers[0].optical_thickness",
                R_THICKNESS,
            ),
            (
                r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1e999}}}]}"#,
                "layers[0].scatterer.rayleigh.albedo",
                "[0, 1]",
            ),
            (
                r#"{"layers":[{"optical_thickness":1,"scatterer":{"henyey_greenstein":{"albedo":1,"g":"x"}}}]}"#,
                "layers[0].scatterer.henyey_greenstein.g",
                "[-0.999, 0.999]",
            ),
            (
                r#"{"layers":[{"optical_thickness":1,"scatterer":{"rayleigh":{"albedo":1}}}],"wavelengths_nm":[Infinity]}"#,
                "wavelengths_nm[0]",
                "[100, 100000] nm",
            ),
        ] {
            let e = parse(text).unwrap_err();
            assert_eq!(e.path, path, "{e}");
            assert!(e.message.ends_with(&format!("allowed: {range}")), "{e}");
        }
    }
}
