//! A multi-wavelength table assembled from one-wavelength tables (the
//! per-wavelength results of `plan::wavelength_parts`, docs/service.md).
//! A table cut to what a smaller request needs is `brdf::cover`.
//!
//! The parts are tables of the same physical spec, needs and settings at
//! one wavelength each, so the assembled table is the table a solve of the
//! whole request writes ([`super::table::Table::from_plan`]): the parts'
//! blocks in increasing wavelength, their per-wavelength metadata, and the
//! request's canonical spec and id. Parts that disagree in anything but
//! the wavelength (grid, solver settings, interpolation, conventions) are
//! refused: they are not parts of one request.

use super::BrdfError;
use super::table::Table;

impl Table {
    /// The table of the request with canonical spec `spec` and id
    /// `spec_hash`, from its one-wavelength `parts` (any order).
    pub fn assemble(
        spec: serde_json::Value,
        spec_hash: &str,
        mut parts: Vec<Table>,
    ) -> Result<Table, BrdfError> {
        let part_error = |what: String| BrdfError::Query(format!("cannot assemble: {what}"));
        if parts.is_empty() {
            return Err(part_error("no parts".into()));
        }
        if let Some(p) = parts.iter().find(|p| p.wavelengths.len() != 1) {
            return Err(part_error(format!(
                "a part holds {} wavelengths, not 1",
                p.wavelengths.len()
            )));
        }
        parts.sort_by(|a, b| {
            let wl = |t: &Table| t.wavelengths[0].wavelength_nm.unwrap_or(0.0);
            wl(a).total_cmp(&wl(b))
        });
        if parts
            .windows(2)
            .any(|w| w[0].wavelengths[0].wavelength_nm == w[1].wavelengths[0].wavelength_nm)
        {
            return Err(BrdfError::Query("a wavelength is listed twice".into()));
        }
        let first = &parts[0];
        for p in &parts[1..] {
            let (a, b) = (&first.metadata, &p.metadata);
            if p.grid != first.grid
                || a.solver != b.solver
                || a.grid != b.grid
                || a.interpolation != b.interpolation
                || a.conventions != b.conventions
                || a.generator != b.generator
            {
                return Err(part_error(format!(
                    "the parts at {:?} and {:?} nm differ in more than the wavelength",
                    first.wavelengths[0].wavelength_nm, p.wavelengths[0].wavelength_nm
                )));
            }
        }
        let mut metadata = first.metadata.clone();
        metadata.spec = spec;
        metadata.spec_hash = spec_hash.to_string();
        metadata.wavelengths = parts
            .iter()
            .map(|p| p.metadata.wavelengths[0].clone())
            .collect();
        let grid = first.grid.clone();
        Ok(Table {
            metadata,
            grid,
            wavelengths: parts
                .into_iter()
                .map(|p| p.wavelengths.into_iter().next().expect("one block"))
                .collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use crate::brdf::table::{BuildOptions, Table};
    use crate::material::parse;
    use crate::plan;

    fn spec(wavelengths: &str) -> String {
        format!(
            r#"{{"layers":[{{"optical_thickness":1,"scatterer":{{"mie":{{"material":"TiO2","radius_um":0.2}}}}}}],
                "base":{{"fresnel":{{"material":"silver"}}}},"wavelengths_nm":{wavelengths},
                "solver":{{"streams":6}},"needs":{{"error_estimate":false,"grid":{{"polar_nodes":8}}}}}}"#
        )
    }

    fn zero_times(t: &mut Table) {
        for w in &mut t.wavelengths {
            w.wall_time_ms = 0.0;
        }
        for w in &mut t.metadata.wavelengths {
            w.wall_time_ms = 0.0;
        }
    }

    /// The parts of `[650, 450, 550]` assemble into the table solved in one
    /// go: every coefficient, the specular matrices, the corrections and
    /// the metadata (timings aside).
    #[test]
    fn parts_assemble_into_the_whole_table() {
        let whole_spec = parse(&spec("[650, 450, 550]")).unwrap();
        let mut whole = Table::from_spec_needs(&whole_spec, &BuildOptions::default()).unwrap();
        let parts: Vec<Table> = plan::wavelength_parts(&whole_spec)
            .iter()
            .map(|p| Table::from_spec_needs(&p.spec, &BuildOptions::default()).unwrap())
            .collect();
        let (canonical, id) = plan::id_of_spec(&whole_spec);
        let mut assembled =
            Table::assemble(serde_json::from_str(&canonical).unwrap(), &id, parts).unwrap();
        zero_times(&mut whole);
        zero_times(&mut assembled);
        assert_eq!(assembled, whole);
    }

    #[test]
    fn parts_of_different_requests_are_refused() {
        let a = parse(&spec("[450]")).unwrap();
        let mut b = parse(&spec("[550]")).unwrap();
        b.solver.streams = Some(8);
        let tables: Vec<Table> = [a, b]
            .iter()
            .map(|s| Table::from_spec_needs(s, &BuildOptions::default()).unwrap())
            .collect();
        let e = Table::assemble(serde_json::json!({}), "x", tables).unwrap_err();
        assert!(e.to_string().contains("differ"), "{e}");
        let one = Table::from_spec_needs(&parse(&spec("[450]")).unwrap(), &BuildOptions::default())
            .unwrap();
        let e = Table::assemble(serde_json::json!({}), "x", vec![one.clone(), one]).unwrap_err();
        assert!(e.to_string().contains("twice"), "{e}");
    }
}
