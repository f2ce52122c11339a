//! What a figure shows, as plain data (pure): panels of curves, polar lobes
//! and hemisphere maps, and the small geometric helpers they need. The
//! drawing itself is [`super::draw`].
//!
//! **Lobe coordinates** (plane of incidence). A sample at signed outgoing
//! angle `θ_s` (`+` mirror side, `−` backscattering side, as
//! [`super::curves::signed_theta_deg`]) with radius `r` (f11 or DOP) sits at
//! `(x, y) = (r sin θ_s, r cos θ_s)`: the surface normal points up, the light
//! comes in from the upper left and the mirror direction is upper right.
//!
//! **Map coordinates** (hemisphere seen from above). An outgoing direction
//! `(θ_o, φ_o)` (graphics convention, `φ_i = 0`) sits at
//! `(x, y) = −(θ_o/90°)(cos φ_o, sin φ_o)`: azimuthal equidistant (the polar
//! angle is the distance from the centre, so the horizon is the unit circle),
//! turned by 180° so that the incident direction is on the left, as in the
//! lobe plot.

/// Line style of a curve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dash {
    /// Continuous.
    Solid,
    /// Long dashes.
    Dashed,
}

/// One curve.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Data coordinates (non-finite points are skipped).
    pub points: Vec<(f64, f64)>,
    /// Index into the palette.
    pub color: usize,
    /// Line style.
    pub dash: Dash,
    /// Draw a marker at every point.
    pub markers: bool,
}

/// Where a panel's legend goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Legend {
    /// Upper right corner.
    UpperRight,
    /// Upper left corner.
    UpperLeft,
    /// Lower right corner.
    LowerRight,
    /// Lower left corner.
    LowerLeft,
}

/// An axis: label (with units) and range.
#[derive(Clone, Debug, PartialEq)]
pub struct Axis {
    /// Description with units, e.g. "optical thickness τ".
    pub label: String,
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
    /// Logarithmic (decades labelled).
    pub log: bool,
}

/// Curves on Cartesian axes.
#[derive(Clone, Debug, PartialEq)]
pub struct LinePanel {
    /// Title above the panel.
    pub title: String,
    /// Horizontal axis.
    pub x: Axis,
    /// Vertical axis.
    pub y: Axis,
    /// Curves.
    pub series: Vec<Series>,
    /// Legend position.
    pub legend: Legend,
}

/// Lobes in the plane of incidence (see the module doc for coordinates).
#[derive(Clone, Debug, PartialEq)]
pub struct LobePanel {
    /// Title above the panel.
    pub title: String,
    /// What the radius is, with units (e.g. "f11 (1/sr)").
    pub radius_label: String,
    /// Outer radius of the polar grid.
    pub r_max: f64,
    /// Curves in lobe coordinates ([`lobe_xy`]).
    pub series: Vec<Series>,
    /// Incident polar angle (drawn as a ray on the left, the mirror
    /// direction on the right).
    pub theta_i_deg: f64,
}

/// A quantity over the outgoing hemisphere on `n_theta × n_phi` cells
/// (θ-major, cell centres as in [`super::curves::lobe_map`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MapPanel {
    /// Title above the panel.
    pub title: String,
    /// Cells in polar angle (covering `[0, 90°)`).
    pub n_theta: usize,
    /// Cells in azimuth (covering `[0, 360°)`).
    pub n_phi: usize,
    /// One value per cell, θ-major.
    pub values: Vec<f64>,
    /// Colour scale range.
    pub lo: f64,
    /// Colour scale range.
    pub hi: f64,
    /// Colour bar label with units.
    pub colorbar_label: String,
    /// Incident polar angle (marked on the map, with the mirror direction).
    pub theta_i_deg: f64,
}

/// One panel of a figure.
#[derive(Clone, Debug, PartialEq)]
pub enum Panel {
    /// Curves.
    Line(LinePanel),
    /// Polar lobes.
    Lobe(LobePanel),
    /// Hemisphere map.
    Map(MapPanel),
}

/// A figure: panels on a `rows × cols` grid, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    /// Image size in pixels.
    pub size: (u32, u32),
    /// Grid of panels.
    pub rows: usize,
    /// Grid of panels.
    pub cols: usize,
    /// Panels, row-major.
    pub panels: Vec<Panel>,
    /// A line of small print under the panels (settings, provenance).
    pub footnote: String,
}

/// The smallest of `{1, 2, 2.5, 5} × 10^k` that is `≥ x` (`x > 0`); 1 for
/// `x ≤ 0` or non-finite `x`.
pub fn nice_ceil(x: f64) -> f64 {
    if !(x > 0.0 && x.is_finite()) {
        return 1.0;
    }
    let p = 10f64.powf(x.log10().floor());
    for m in [1.0, 2.0, 2.5, 5.0, 10.0] {
        if m * p >= x * (1.0 - 1e-12) {
            return m * p;
        }
    }
    10.0 * p
}

/// The largest finite value of the series' `y` (0 if none).
pub fn max_y(series: &[Series]) -> f64 {
    series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .filter(|y| y.is_finite())
        .fold(0.0, f64::max)
}

/// Lobe coordinates of radius `r` at signed outgoing angle `theta_signed_deg`.
pub fn lobe_xy(theta_signed_deg: f64, r: f64) -> (f64, f64) {
    let (s, c) = theta_signed_deg.to_radians().sin_cos();
    (r * s, r * c)
}

/// Map coordinates of the outgoing direction `(θ_o, φ_o)`.
pub fn map_xy(theta_o_deg: f64, phi_o_deg: f64) -> (f64, f64) {
    let r = theta_o_deg / 90.0;
    let (s, c) = phi_o_deg.to_radians().sin_cos();
    (-r * c, -r * s)
}

/// Outline of map cell `(j, k)` (polar ring `j`, azimuth sector `k`) as a
/// polygon in map coordinates, each arc cut into `arc_steps` segments.
pub fn cell_polygon(
    j: usize,
    k: usize,
    n_theta: usize,
    n_phi: usize,
    arc_steps: usize,
) -> Vec<(f64, f64)> {
    let (dt, dp) = (90.0 / n_theta as f64, 360.0 / n_phi as f64);
    let (t0, t1) = (j as f64 * dt, (j + 1) as f64 * dt);
    let (p0, p1) = (k as f64 * dp, (k + 1) as f64 * dp);
    let steps = arc_steps.max(1);
    let mut v = Vec::with_capacity(2 * steps + 2);
    for s in 0..=steps {
        v.push(map_xy(t1, p0 + (p1 - p0) * s as f64 / steps as f64));
    }
    for s in (0..=steps).rev() {
        v.push(map_xy(t0, p0 + (p1 - p0) * s as f64 / steps as f64));
    }
    v
}

/// Tick label of a decade exponent on a log axis (`v = log10 x`): plain
/// numbers from 0.001 to 1000, `1e-4` style beyond; empty between decades.
pub fn decade_label(v: f64) -> String {
    let k = v.round();
    if (v - k).abs() > 1e-6 {
        return String::new();
    }
    let k = k as i32;
    if (-3..=3).contains(&k) {
        format!("{}", 10f64.powi(k))
    } else {
        format!("1e{k}")
    }
}

/// Tick label of a linear axis value (no `-0`, no float noise).
pub fn linear_label(v: f64) -> String {
    let r = (v * 1e6).round() / 1e6;
    if r == 0.0 { "0".into() } else { format!("{r}") }
}

/// The points of a polyline without those closer than `(dx, dy)` (data
/// units, per axis) to the last point kept; the first point is always kept.
/// With `(dx, dy)` of 1.5 pixels, consecutive points never fall on the same
/// pixel, where plotters' thick-line joins divide by a zero segment length
/// (stray spikes in the PNG).
pub fn thin_out(points: &[(f64, f64)], dx: f64, dy: f64) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::with_capacity(points.len());
    for &p in points {
        match out.last() {
            Some(&q) if (p.0 - q.0).abs() < dx && (p.1 - q.1).abs() < dy => {}
            _ => out.push(p),
        }
    }
    out
}

/// A polyline cut into pieces at its sharp turns: where the direction turns
/// by more than `max_turn_deg` (measured after scaling by `(sx, sy)`, e.g.
/// pixels per data unit), one piece ends at the vertex and the next starts
/// there. plotters joins thick bitmap lines with an uncapped inner miter,
/// which for a near reversal (the petals of a DOP lobe) lands far away.
pub fn split_at_sharp_turns(
    points: &[(f64, f64)],
    sx: f64,
    sy: f64,
    max_turn_deg: f64,
) -> Vec<Vec<(f64, f64)>> {
    let cos_max = max_turn_deg.to_radians().cos();
    let mut pieces = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    for (k, &p) in points.iter().enumerate() {
        cur.push(p);
        if k == 0 || k + 1 == points.len() {
            continue;
        }
        let (a, b) = (points[k - 1], points[k + 1]);
        let u = ((p.0 - a.0) * sx, (p.1 - a.1) * sy);
        let v = ((b.0 - p.0) * sx, (b.1 - p.1) * sy);
        let (lu, lv) = (u.0.hypot(u.1), v.0.hypot(v.1));
        if lu > 0.0 && lv > 0.0 && (u.0 * v.0 + u.1 * v.1) / (lu * lv) < cos_max {
            pieces.push(std::mem::replace(&mut cur, vec![p]));
        }
    }
    if cur.len() > 1 || (pieces.is_empty() && !cur.is_empty()) {
        pieces.push(cur);
    }
    pieces
}

/// Greedy word wrap into lines of at most `max_chars` characters (a longer
/// word gets a line of its own).
pub fn wrap_words(text: &str, max_chars: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        let fits = line.chars().count() + 1 + word.chars().count() <= max_chars.max(1);
        if !line.is_empty() && !fits {
            lines.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_ceil_rounds_up_to_1_2_2_5_5() {
        assert_eq!(nice_ceil(0.37), 0.5);
        assert_eq!(nice_ceil(0.2), 0.2);
        assert_eq!(nice_ceil(2.2), 2.5);
        assert_eq!(nice_ceil(7.0), 10.0);
        assert!((nice_ceil(0.0123) - 0.02).abs() < 1e-15);
        assert_eq!(nice_ceil(0.0), 1.0);
        assert_eq!(nice_ceil(f64::NAN), 1.0);
    }

    #[test]
    fn lobe_and_map_geometry() {
        let (x, y) = lobe_xy(0.0, 2.0);
        assert!(x.abs() < 1e-15 && (y - 2.0).abs() < 1e-15);
        let (x, y) = lobe_xy(-90.0, 1.0);
        assert!((x + 1.0).abs() < 1e-15 && y.abs() < 1e-15);
        // Incident side (φ_o = 0) on the left, mirror side on the right,
        // horizon on the unit circle, normal at the centre.
        let (x, y) = map_xy(45.0, 0.0);
        assert!((x + 0.5).abs() < 1e-15 && y.abs() < 1e-15);
        let (x, _) = map_xy(90.0, 180.0);
        assert!((x - 1.0).abs() < 1e-15);
        assert_eq!(map_xy(0.0, 123.0).0.abs(), 0.0);
        let poly = cell_polygon(0, 0, 3, 4, 2);
        assert_eq!(poly.len(), 6);
        let r = |p: (f64, f64)| p.0.hypot(p.1);
        assert!((r(poly[0]) - 1.0 / 3.0).abs() < 1e-12);
        assert!(r(poly[5]).abs() < 1e-12);
    }

    #[test]
    fn thinning_keeps_points_a_pixel_apart() {
        let pts = [(0.0, 0.0), (0.1, 0.1), (2.0, 0.0), (2.0, 0.5), (2.0, 3.0)];
        assert_eq!(
            thin_out(&pts, 1.0, 1.0),
            vec![(0.0, 0.0), (2.0, 0.0), (2.0, 3.0)]
        );
        assert!(thin_out(&[], 1.0, 1.0).is_empty());
    }

    #[test]
    fn polylines_split_at_reversals_only() {
        // Out and back: a 180° turn at (1, 0).
        let pts = [(0.0, 0.0), (1.0, 0.0), (0.0, 0.01), (0.0, 1.0)];
        let pieces = split_at_sharp_turns(&pts, 1.0, 1.0, 150.0);
        assert_eq!(pieces.len(), 2);
        assert_eq!(pieces[0], vec![(0.0, 0.0), (1.0, 0.0)]);
        assert_eq!(pieces[1][0], (1.0, 0.0));
        assert_eq!(pieces[1].len(), 3);
        // A right angle stays one piece.
        let l = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)];
        assert_eq!(split_at_sharp_turns(&l, 1.0, 1.0, 150.0), vec![l.to_vec()]);
        // The angle is measured in scaled units.
        let v = [(0.0, 0.0), (1.0, 100.0), (2.0, 0.0)];
        assert_eq!(split_at_sharp_turns(&v, 1.0, 1.0, 150.0).len(), 2);
        assert_eq!(split_at_sharp_turns(&v, 1.0, 0.001, 150.0).len(), 1);
    }

    #[test]
    fn words_wrap_greedily() {
        assert_eq!(wrap_words("a bb ccc dd", 6), vec!["a bb", "ccc dd"]);
        assert_eq!(wrap_words("averylongword x", 4), vec!["averylongword", "x"]);
        assert!(wrap_words("  ", 10).is_empty());
        assert_eq!(wrap_words("λ = 550 nm", 10), vec!["λ = 550 nm"]);
    }

    #[test]
    fn tick_labels() {
        assert_eq!(decade_label(-3.0), "0.001");
        assert_eq!(decade_label(0.0), "1");
        assert_eq!(decade_label(2.0), "100");
        assert_eq!(decade_label(-4.0), "1e-4");
        assert_eq!(decade_label(0.5), "");
        assert_eq!(linear_label(0.30000000000000004), "0.3");
        assert_eq!(linear_label(-0.0), "0");
    }
}
