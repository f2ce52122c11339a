//! What the cache listing (`GET /v1/brdfs`), its filters and the console
//! show of a result: read off its row and its canonical spec (docs/spec.md),
//! without opening its blob.
//!
//! Pure functions of the canonical JSON; the listing's filter
//! ([`Filter::matches`]) compares against these same fields, so what a page
//! shows is what a filter finds.

use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

/// The name of a material in any form of docs/spec.md, "Materials": a
/// built-in name as written (`"TiO2"`), `{"name"}` by its name, `{"n","k"}`
/// as `n=…,k=…`, a dispersive `{"table"}` as `table`, a bare number (a
/// host index) as `n=…`.
pub fn material_name(m: &Value) -> String {
    match m {
        Value::String(s) => s.clone(),
        Value::Number(n) => format!("n={n}"),
        Value::Object(o) => {
            if let Some(Value::String(name)) = o.get("name") {
                name.clone()
            } else if o.contains_key("table") {
                "table".into()
            } else {
                let part = |k: &str| o.get(k).map_or("0".into(), Value::to_string);
                format!("n={},k={}", part("n"), part("k"))
            }
        }
        other => other.to_string(),
    }
}

/// One layer of a result, as the listing shows it.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct LayerSummary {
    /// The scattering populations: each Mie scatterer's or film pigment's
    /// material ([`material_name`]), or the scatterer's kind (`rayleigh`,
    /// `expansion`, `henyey_greenstein`).
    pub materials: Vec<String>,
    /// The optical form's `optical_thickness`: a number or `"infinite"`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub optical_thickness: Option<Value>,
    /// The film form's geometric thickness (µm).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub thickness_um: Option<f64>,
}

/// A layer's summary from its canonical JSON.
pub fn layer_summary(layer: &Value) -> LayerSummary {
    let mut materials = Vec::new();
    if let Some(pigments) = layer.get("pigments").and_then(Value::as_array) {
        for p in pigments {
            materials.extend(p.get("material").map(material_name));
        }
    }
    if let Some(Value::Object(s)) = layer.get("scatterer") {
        for (kind, body) in s {
            match body.get("material") {
                Some(m) if kind == "mie" => materials.push(material_name(m)),
                _ => materials.push(kind.clone()),
            }
        }
    }
    LayerSummary {
        materials,
        optical_thickness: layer.get("optical_thickness").cloned(),
        thickness_um: layer.get("thickness_um").and_then(Value::as_f64),
    }
}

/// The base as `kind` (`black`, `lambertian`) or `kind:material`
/// (`fresnel:Al`, `rough_fresnel:Ag`).
pub fn base_name(spec: &Value) -> String {
    match spec.get("base") {
        None => "black".into(),
        Some(Value::String(s)) => s.clone(),
        Some(Value::Object(o)) => o
            .iter()
            .next()
            .map(|(kind, body)| match body.get("material") {
                Some(m) => format!("{kind}:{}", material_name(m)),
                None => kind.clone(),
            })
            .unwrap_or_default(),
        Some(other) => other.to_string(),
    }
}

/// What the listing says of a spec.
#[derive(Clone, Debug, PartialEq)]
pub struct SpecSummary {
    /// The layers, top to bottom.
    pub layers: Vec<LayerSummary>,
    /// [`base_name`].
    pub base: String,
    /// `wavelengths_nm` (empty: a wavelength-free result).
    pub wavelengths_nm: Vec<f64>,
    /// `solver.streams`, when the spec fixes them.
    pub streams: Option<i64>,
    /// `solver.tolerance`, when the spec sets one.
    pub tolerance: Option<f64>,
    /// The top interface's kind (`smooth`, `rough`), when there is one.
    pub top_interface: Option<String>,
}

impl SpecSummary {
    /// The summary of a canonical spec.
    pub fn of(spec: &Value) -> Self {
        let layers = spec
            .get("layers")
            .and_then(Value::as_array)
            .map(|ls| ls.iter().map(layer_summary).collect())
            .unwrap_or_default();
        let solver = spec.get("solver");
        let top_interface = match spec.get("top_interface") {
            Some(Value::Object(o)) => o.keys().next().cloned(),
            Some(Value::String(s)) if s != "none" => Some(s.clone()),
            _ => None,
        };
        Self {
            layers,
            base: base_name(spec),
            wavelengths_nm: spec
                .get("wavelengths_nm")
                .and_then(Value::as_array)
                .map(|w| w.iter().filter_map(Value::as_f64).collect())
                .unwrap_or_default(),
            streams: solver
                .and_then(|s| s.get("streams"))
                .and_then(Value::as_i64),
            tolerance: solver
                .and_then(|s| s.get("tolerance"))
                .and_then(Value::as_f64),
            top_interface,
        }
    }

    /// Every population's material, in layer order, each once.
    pub fn materials(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for m in self.layers.iter().flat_map(|l| &l.materials) {
            if !out.contains(m) {
                out.push(m.clone());
            }
        }
        out
    }
}

/// Status filter values (`?status=`).
pub const STATUSES: [&str; 4] = ["queued", "running", "done", "failed"];

/// The filters of `GET /v1/brdfs`; each one given must match.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Filter {
    /// Any of these states (`status=done,failed`).
    pub status: Vec<String>,
    /// A population's material or kind, case-insensitively (`TiO2`,
    /// `rayleigh`).
    pub material: Option<String>,
    /// The base: its kind (`fresnel`) or its material (`Al`) or both
    /// (`fresnel:Al`), case-insensitively.
    pub base: Option<String>,
    /// One of the spec's wavelengths (nm), to 1e-6 nm.
    pub wavelength_nm: Option<f64>,
    /// A layer's optical thickness or film thickness (µm), to 1e-9
    /// relative, or `infinite`.
    pub thickness: Option<Thickness>,
    /// Free text: a case-insensitive substring of the id, a material, the
    /// base or the top interface.
    pub q: Option<String>,
}

/// A thickness to look for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Thickness {
    /// A number (optical thickness or µm).
    Value(f64),
    /// `optical_thickness: "infinite"`.
    Infinite,
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()).max(f64::MIN_POSITIVE)
}

impl Filter {
    /// Does a row of state `status` with this spec summary and id pass?
    pub fn matches(&self, id: &str, status: &str, s: &SpecSummary) -> bool {
        let lower = |x: &str| x.to_ascii_lowercase();
        if !self.status.is_empty() && !self.status.iter().any(|w| w == status) {
            return false;
        }
        let materials = s.materials();
        if let Some(m) = &self.material
            && !materials.iter().any(|x| lower(x) == lower(m))
        {
            return false;
        }
        if let Some(b) = &self.base {
            let b = lower(b);
            let base = lower(&s.base);
            let (kind, material) = base.split_once(':').unwrap_or((&base, ""));
            if b != base && b != kind && b != material {
                return false;
            }
        }
        if let Some(w) = self.wavelength_nm
            && !s.wavelengths_nm.iter().any(|&x| (x - w).abs() <= 1e-6)
        {
            return false;
        }
        if let Some(t) = self.thickness {
            let hit = s.layers.iter().any(|l| match t {
                Thickness::Infinite => {
                    l.optical_thickness.as_ref().and_then(Value::as_str) == Some("infinite")
                }
                Thickness::Value(v) => {
                    l.optical_thickness
                        .as_ref()
                        .and_then(Value::as_f64)
                        .is_some_and(|x| close(x, v, 1e-9))
                        || l.thickness_um.is_some_and(|x| close(x, v, 1e-9))
                }
            });
            if !hit {
                return false;
            }
        }
        if let Some(q) = &self.q {
            let q = lower(q);
            let hit = id.starts_with(&q)
                || materials.iter().any(|m| lower(m).contains(&q))
                || lower(&s.base).contains(&q)
                || s.top_interface.as_deref().is_some_and(|t| t.contains(&q));
            if !hit {
                return false;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn materials_are_named_in_every_form() {
        assert_eq!(material_name(&json!("TiO2")), "TiO2");
        assert_eq!(material_name(&json!({"n": 1.5, "k": 0.01})), "n=1.5,k=0.01");
        assert_eq!(material_name(&json!({"name": "Ag", "source": "x"})), "Ag");
        assert_eq!(material_name(&json!({"table": [[400, 1.5, 0]]})), "table");
        assert_eq!(material_name(&json!(1.5)), "n=1.5");
    }

    fn paint() -> Value {
        json!({
            "layers": [
                {"thickness_um": 25.0, "binder": "acrylic", "pigments": [
                    {"material": "TiO2", "radius_um": 0.2, "volume_fraction": 0.1},
                    {"material": {"n": 1.6, "k": 0}, "radius_um": 1.0, "volume_fraction": 0.05}]},
                {"optical_thickness": "infinite", "scatterer": {"rayleigh": {"albedo": 0.9}}}
            ],
            "base": {"rough_fresnel": {"material": "Al", "alpha": 0.3}},
            "top_interface": {"smooth": {}},
            "wavelengths_nm": [450.0, 550.0],
            "solver": {"tolerance": 1e-3, "polarized": true}
        })
    }

    #[test]
    fn a_film_over_rough_metal_is_summarised() {
        let s = SpecSummary::of(&paint());
        assert_eq!(s.base, "rough_fresnel:Al");
        assert_eq!(s.materials(), ["TiO2", "n=1.6,k=0", "rayleigh"]);
        assert_eq!(s.layers[0].thickness_um, Some(25.0));
        assert_eq!(s.layers[1].optical_thickness, Some(json!("infinite")));
        assert_eq!(s.wavelengths_nm, [450.0, 550.0]);
        assert_eq!((s.streams, s.tolerance), (None, Some(1e-3)));
        assert_eq!(s.top_interface.as_deref(), Some("smooth"));
        let black = SpecSummary::of(&json!({"layers": [], "base": "black"}));
        assert_eq!((black.base.as_str(), black.top_interface), ("black", None));
    }

    #[test]
    fn each_filter_must_match() {
        let s = SpecSummary::of(&paint());
        let id = "ab12";
        let pass = |f: Filter| f.matches(id, "done", &s);
        assert!(pass(Filter::default()));
        let f = |g: fn(&mut Filter)| {
            let mut x = Filter::default();
            g(&mut x);
            x
        };
        assert!(pass(f(|x| x.status = vec!["failed".into(), "done".into()])));
        assert!(!pass(f(|x| x.status = vec!["queued".into()])));
        assert!(pass(f(|x| x.material = Some("tio2".into()))));
        assert!(!pass(f(|x| x.material = Some("TiO".into()))));
        for b in ["rough_fresnel", "al", "Rough_Fresnel:Al"] {
            assert!(pass(f_base(b)), "{b}");
        }
        assert!(!pass(f_base("fresnel")));
        assert!(pass(f(|x| x.wavelength_nm = Some(550.0000001))));
        assert!(!pass(f(|x| x.wavelength_nm = Some(551.0))));
        assert!(pass(f(|x| x.thickness = Some(Thickness::Value(25.0)))));
        assert!(pass(f(|x| x.thickness = Some(Thickness::Infinite))));
        assert!(!pass(f(|x| x.thickness = Some(Thickness::Value(1.0)))));
        assert!(pass(f(|x| x.q = Some("AB1".into()))));
        assert!(pass(f(|x| x.q = Some("rough".into()))));
        assert!(!pass(f(|x| x.q = Some("silver".into()))));
    }

    fn f_base(b: &str) -> Filter {
        Filter {
            base: Some(b.into()),
            ..Filter::default()
        }
    }
}
