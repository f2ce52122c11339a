//! The numbers behind every plot as CSV (RFC 4180): one header line, one
//! line per plotted sample. Numbers are written in Rust's shortest
//! round-trip form (they read back bit-exactly), plain for
//! `1e-4 ≤ |x| < 1e15`, else in exponent form (`1.5e-7`); `inf` for a
//! semi-infinite layer. Text cells are quoted when they hold a comma, quote
//! or newline.

/// One CSV cell.
#[derive(Clone, Debug, PartialEq)]
pub enum Cell {
    /// A number (written exactly).
    Num(f64),
    /// Text (a label).
    Text(String),
}

impl From<f64> for Cell {
    fn from(x: f64) -> Self {
        Cell::Num(x)
    }
}

impl From<&str> for Cell {
    fn from(s: &str) -> Self {
        Cell::Text(s.to_string())
    }
}

impl From<String> for Cell {
    fn from(s: String) -> Self {
        Cell::Text(s)
    }
}

/// A number in the shortest form that reads back exactly.
pub fn number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e15).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

fn text_cell(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// A table of cells under a header; every row has the header's length.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Csv {
    /// Column names (units in the names, conventions §1).
    pub header: Vec<String>,
    /// Rows.
    pub rows: Vec<Vec<Cell>>,
}

impl Csv {
    /// An empty table with these columns.
    pub fn new(header: &[&str]) -> Self {
        Self {
            header: header.iter().map(|s| s.to_string()).collect(),
            rows: Vec::new(),
        }
    }

    /// Append a row (panics on a length mismatch: a programming error).
    pub fn push(&mut self, row: Vec<Cell>) {
        assert_eq!(row.len(), self.header.len(), "CSV row length");
        self.rows.push(row);
    }

    /// The CSV text, `\n` line ends.
    pub fn text(&self) -> String {
        let mut out = self
            .header
            .iter()
            .map(|h| text_cell(h))
            .collect::<Vec<_>>()
            .join(",");
        out.push('\n');
        for row in &self.rows {
            let line: Vec<String> = row
                .iter()
                .map(|c| match c {
                    Cell::Num(x) => number(*x),
                    Cell::Text(s) => text_cell(s),
                })
                .collect();
            out.push_str(&line.join(","));
            out.push('\n');
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_round_trip_and_text_is_quoted() {
        let mut c = Csv::new(&["label", "tau", "dop"]);
        c.push(vec![
            "TiO2, r = 0.2 µm".into(),
            0.1.into(),
            (1.0 / 3.0).into(),
        ]);
        c.push(vec![
            "say \"hi\"".into(),
            f64::INFINITY.into(),
            1e-300.into(),
        ]);
        let t = c.text();
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines[0], "label,tau,dop");
        assert_eq!(lines[1], "\"TiO2, r = 0.2 µm\",0.1,0.3333333333333333");
        assert_eq!(lines[2], "\"say \"\"hi\"\"\",inf,1e-300");
        let back: f64 = lines[1].rsplit(',').next().unwrap().parse().unwrap();
        assert_eq!(back, 1.0 / 3.0);
        let inf: f64 = "inf".parse().unwrap();
        assert_eq!(inf, f64::INFINITY);
        for x in [
            1.234e-7,
            -2.5e-5,
            0.0,
            1e-4,
            7.0,
            123456.789,
            3e20,
            f64::MIN_POSITIVE,
        ] {
            assert_eq!(number(x).parse::<f64>().unwrap(), x, "{}", number(x));
        }
        assert_eq!(number(1.5e-7), "1.5e-7");
        assert_eq!(number(0.25), "0.25");
    }

    #[test]
    #[should_panic(expected = "CSV row length")]
    fn rows_must_match_the_header() {
        Csv::new(&["a", "b"]).push(vec![1.0.into()]);
    }
}
