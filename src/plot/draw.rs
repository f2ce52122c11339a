//! Drawing a [`Figure`] as SVG or PNG with plotters: the only module of
//! `plot` that knows about pixels, fonts and files.
//!
//! **Text.** plotters lays out text (label widths, centring) with a
//! TrueType font in both backends, read at run time through its `ab_glyph`
//! feature (pure Rust: no fontconfig/freetype to build or link): the file
//! given with `--font`, else the first of [`FONT_CANDIDATES`] that exists
//! (DejaVu Sans on Debian/Ubuntu, where `fonts-dejavu-core` provides it).
//! plotters keeps registered fonts in a process-wide table (its API takes
//! `&'static` bytes), so the font is read and registered once per process.
//!
//! **PNG.** Drawn into an RGB buffer (plotters' bitmap backend) and encoded
//! with the `png` crate; SVG text stays text (`font-family: sans-serif`).

use super::figure::{
    Dash, Figure, Legend, LinePanel, LobePanel, MapPanel, Panel, cell_polygon, decade_label,
    linear_label, lobe_xy, map_xy, nice_ceil, split_at_sharp_turns, thin_out, wrap_words,
};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;
use plotters::style::text_anchor;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Font family name the figures use (registered by [`register_font`]).
const FONT: &str = "sans-serif";

/// TrueType fonts tried, in order, when no `--font` is given.
pub const FONT_CANDIDATES: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/liberation-sans/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/freefont/FreeSans.ttf",
    "/Library/Fonts/Arial Unicode.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// Colour-blind safe line colours (Okabe & Ito 2008), then grey.
const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(140, 140, 140),
];

/// Turns sharper than this (degrees, in pixels) end a polyline piece
/// ([`split_at_sharp_turns`]).
const SHARP_TURN_DEG: f64 = 135.0;

const GRID: RGBColor = RGBColor(225, 225, 225);
const GUIDE: RGBColor = RGBColor(120, 120, 120);

/// The palette colour of index `i` (cycling).
fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

fn err<E: std::fmt::Display>(e: E) -> String {
    format!("drawing: {e}")
}

/// The font file to use: `explicit` if given (it must exist), else the
/// first existing [`FONT_CANDIDATES`] entry.
pub fn font_path(explicit: Option<&Path>) -> Result<PathBuf, String> {
    if let Some(p) = explicit {
        return if p.is_file() {
            Ok(p.to_path_buf())
        } else {
            Err(format!("--font {}: no such file", p.display()))
        };
    }
    FONT_CANDIDATES
        .iter()
        .map(PathBuf::from)
        .find(|p| p.is_file())
        .ok_or_else(|| {
            format!(
                "plot labels need a TrueType font and none of {} exists; pass --font FILE.ttf \
                 (on Debian/Ubuntu: apt-get install fonts-dejavu-core)",
                FONT_CANDIDATES.join(", ")
            )
        })
}

static REGISTERED: OnceLock<Result<PathBuf, String>> = OnceLock::new();

/// Read the font ([`font_path`]) and register it with plotters, once per
/// process; later calls return the first call's outcome.
pub fn register_font(explicit: Option<&Path>) -> Result<PathBuf, String> {
    REGISTERED
        .get_or_init(|| {
            let path = font_path(explicit)?;
            let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            // plotters keeps `&'static` font bytes: one font per process.
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            plotters::style::register_font(FONT, FontStyle::Normal, bytes)
                .map_err(|_| format!("{}: not a usable TrueType font", path.display()))?;
            Ok(path)
        })
        .clone()
}

/// Image format, from the file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// `.svg`
    Svg,
    /// `.png`
    Png,
}

/// The format of an output path (`.svg` or `.png`, any case).
pub fn format_of(path: &Path) -> Result<Format, String> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("svg") => Ok(Format::Svg),
        Some("png") => Ok(Format::Png),
        _ => Err(format!(
            "{}: the output must end in .svg or .png",
            path.display()
        )),
    }
}

/// Draw `fig` into `path` (SVG or PNG by extension). The font must have been
/// registered ([`register_font`]).
pub fn write(fig: &Figure, path: &Path) -> Result<(), String> {
    let (w, h) = fig.size;
    match format_of(path)? {
        Format::Svg => {
            let root = SVGBackend::new(path, (w, h)).into_drawing_area();
            draw_figure(&root, fig)?;
            root.present()
                .map_err(|e| format!("{}: {e}", path.display()))
        }
        Format::Png => {
            let mut buf = vec![255u8; w as usize * h as usize * 3];
            {
                let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
                draw_figure(&root, fig)?;
                root.present().map_err(err)?;
            }
            write_png(path, &buf, w, h)
        }
    }
}

/// `fig` as SVG text (the service's plots, `GET /v1/brdfs/{id}/plot`).
/// The font must have been registered ([`register_font`]).
pub fn svg_string(fig: &Figure) -> Result<String, String> {
    let (w, h) = fig.size;
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (w, h)).into_drawing_area();
        draw_figure(&root, fig)?;
        root.present().map_err(err)?;
    }
    Ok(out)
}

/// Encode an RGB buffer as an 8-bit PNG.
fn write_png(path: &Path, rgb: &[u8], w: u32, h: u32) -> Result<(), String> {
    let io = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let file = std::fs::File::create(path).map_err(|e| io(&e))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::High);
    let mut writer = enc.write_header().map_err(|e| io(&e))?;
    writer.write_image_data(rgb).map_err(|e| io(&e))?;
    writer.finish().map_err(|e| io(&e))
}

fn draw_figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    fig: &Figure,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(err)?;
    let (w, h) = root.dim_in_pixel();
    // Small print, wrapped at about 6.6 px per character of the 12 px font.
    let lines = wrap_words(&fig.footnote, (w.saturating_sub(20) as usize * 10) / 66);
    let foot_h = if lines.is_empty() {
        0
    } else {
        15 * lines.len() as u32 + 8
    };
    let (body, foot) = root.split_vertically(h.saturating_sub(foot_h));
    let small = (FONT, 12).into_font().color(&GUIDE);
    for (k, line) in lines.iter().enumerate() {
        foot.draw_text(line, &small, (10, 3 + 15 * k as i32))
            .map_err(err)?;
    }
    let areas = body.split_evenly((fig.rows.max(1), fig.cols.max(1)));
    for (area, panel) in areas.iter().zip(&fig.panels) {
        match panel {
            Panel::Line(p) => line_panel(area, p)?,
            Panel::Lobe(p) => lobe_panel(area, p)?,
            Panel::Map(p) => map_panel(area, p)?,
        }
    }
    Ok(())
}

fn legend_position(l: Legend) -> SeriesLabelPosition {
    match l {
        Legend::UpperRight => SeriesLabelPosition::UpperRight,
        Legend::UpperLeft => SeriesLabelPosition::UpperLeft,
        Legend::LowerRight => SeriesLabelPosition::LowerRight,
        Legend::LowerLeft => SeriesLabelPosition::LowerLeft,
    }
}

fn line_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    p: &LinePanel,
) -> Result<(), String> {
    let log = p.x.log;
    let ylog = p.y.log;
    let tx = move |x: f64| if log { x.log10() } else { x };
    let ty = move |y: f64| if ylog { y.log10() } else { y };
    let (x0, x1) = (tx(p.x.lo), tx(p.x.hi));
    let (y0, y1) = (ty(p.y.lo), ty(p.y.hi));
    let mut chart = ChartBuilder::on(area)
        .caption(&p.title, (FONT, 17))
        .margin(12)
        .x_label_area_size(46)
        .y_label_area_size(64)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    let x_fmt = move |v: &f64| {
        if log {
            decade_label(*v)
        } else {
            linear_label(*v)
        }
    };
    let y_fmt = move |v: &f64| {
        if ylog {
            decade_label(*v)
        } else {
            linear_label(*v)
        }
    };
    let x_labels = if log {
        ((x1 - x0).round() as usize + 1).max(2)
    } else {
        11
    };
    let y_labels = if ylog {
        ((y1 - y0).round() as usize + 1).max(2)
    } else {
        11
    };
    chart
        .configure_mesh()
        .x_desc(p.x.label.as_str())
        .y_desc(p.y.label.as_str())
        .x_labels(x_labels)
        .y_labels(y_labels)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .bold_line_style(GRID)
        .light_line_style(RGBColor(245, 245, 245))
        .draw()
        .map_err(err)?;
    let (pw, ph) = chart.plotting_area().dim_in_pixel();
    let px = 1.5 * (x1 - x0) / pw.max(1) as f64;
    let py = 1.5 * (y1 - y0) / ph.max(1) as f64;
    for s in &p.series {
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter(|(x, y)| {
                x.is_finite() && y.is_finite() && (!log || *x > 0.0) && (!ylog || *y > 0.0)
            })
            .map(|&(x, y)| (tx(x), ty(y)))
            .collect();
        let pts = thin_out(&pts, px, py);
        let style = color(s.color).stroke_width(2);
        let pieces = split_at_sharp_turns(&pts, 1.0 / px, 1.0 / py, SHARP_TURN_DEG);
        let anno = match s.dash {
            Dash::Solid => chart.draw_series(
                pieces
                    .into_iter()
                    .map(|piece| PathElement::new(piece, style)),
            ),
            Dash::Dashed => chart.draw_series(
                pieces
                    .into_iter()
                    .flat_map(|piece| DashedLineSeries::new(piece, 9, 6, style)),
            ),
        }
        .map_err(err)?;
        let dash = s.dash;
        // Two segments: joined for a solid line, with a gap for a dashed one.
        let gap = if dash == Dash::Dashed { 6 } else { 0 };
        anno.label(s.label.as_str()).legend(move |(x, y)| {
            EmptyElement::at((x, y))
                + PathElement::new(vec![(0, 0), (8, 0)], style)
                + PathElement::new(vec![(8 + gap, 0), (22, 0)], style)
        });
        if s.markers {
            chart
                .draw_series(
                    pts.iter()
                        .map(|&p| Circle::new(p, 3, color(s.color).filled())),
                )
                .map_err(err)?;
        }
    }
    if p.series.iter().any(|s| !s.label.is_empty()) {
        chart
            .configure_series_labels()
            .position(legend_position(p.legend))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(190, 190, 190))
            .label_font((FONT, 13))
            .draw()
            .map_err(err)?;
    }
    Ok(())
}

/// Data ranges `[−xr, xr] × [y0, y0 + yr]` enlarged so that one data unit
/// has the same length in pixels on both axes of a `w × h` plotting area.
fn equal_aspect(half_width: f64, height: f64, (w, h): (u32, u32)) -> (f64, f64) {
    let (w, h) = (w.max(1) as f64, h.max(1) as f64);
    let unit = (2.0 * half_width / w).max(height / h);
    (unit * w / 2.0, unit * h)
}

fn lobe_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    p: &LobePanel,
) -> Result<(), String> {
    let area = area.titled(&p.title, (FONT, 17)).map_err(err)?;
    let r = p.r_max;
    let build = |xr: f64, ymax: f64| {
        ChartBuilder::on(&area)
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(58)
            // A little below the surface: plotters' bitmap lines misbehave
            // for points exactly on the plotting area's bottom edge.
            .build_cartesian_2d(-xr..xr, -0.02 * ymax..ymax)
    };
    let dims = build(1.08 * r, 1.1 * r)
        .map_err(err)?
        .plotting_area()
        .dim_in_pixel();
    let (xr, ymax) = equal_aspect(1.08 * r, 1.1 * r, dims);
    let mut chart = build(xr, ymax).map_err(err)?;
    let fmt = |v: &f64| linear_label(v.abs());
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(format!("{}: lobe radius along the surface", p.radius_label))
        .y_desc("along the normal")
        .x_label_formatter(&fmt)
        .y_label_formatter(&fmt)
        .x_labels(9)
        .y_labels(5)
        .label_style((FONT, 12))
        .axis_desc_style((FONT, 13))
        .draw()
        .map_err(err)?;
    // Polar grid: rings at nice radii, spokes every 30°.
    let step = nice_ceil(r / 4.0);
    let mut ring = step;
    let label = (FONT, 11).into_font().color(&GUIDE);
    while ring <= r * (1.0 + 1e-9) {
        let arc: Vec<(f64, f64)> = (-90..=90).map(|t| lobe_xy(t as f64, ring)).collect();
        chart
            .draw_series(LineSeries::new(arc, GRID.stroke_width(1)))
            .map_err(err)?;
        ring += step;
    }
    for t in (-90i32..=90).step_by(30) {
        let end = lobe_xy(t as f64, r);
        chart
            .draw_series(LineSeries::new(vec![(0.0, 0.0), end], GRID.stroke_width(1)))
            .map_err(err)?;
        let at = lobe_xy(t as f64, 1.04 * r);
        chart
            .draw_series(std::iter::once(Text::new(
                format!("{}°", t.abs()),
                at,
                label.clone().pos(text_anchor::Pos::new(
                    text_anchor::HPos::Center,
                    text_anchor::VPos::Bottom,
                )),
            )))
            .map_err(err)?;
    }
    // Incident and mirror directions.
    for (sign, name) in [(-1.0, "incident"), (1.0, "mirror")] {
        let end = lobe_xy(sign * p.theta_i_deg, r);
        chart
            .draw_series(DashedLineSeries::new(
                vec![(0.0, 0.0), end],
                6,
                5,
                GUIDE.stroke_width(1),
            ))
            .map_err(err)?;
        let at = lobe_xy(sign * p.theta_i_deg, 0.9 * r);
        let hpos = if sign < 0.0 {
            text_anchor::HPos::Right
        } else {
            text_anchor::HPos::Left
        };
        chart
            .draw_series(std::iter::once(Text::new(
                format!("  {name}  "),
                at,
                label
                    .clone()
                    .pos(text_anchor::Pos::new(hpos, text_anchor::VPos::Bottom)),
            )))
            .map_err(err)?;
    }
    let (pw, _) = chart.plotting_area().dim_in_pixel();
    let px = 1.5 * 2.0 * xr / pw.max(1) as f64;
    for s in &p.series {
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .collect();
        let pts = thin_out(&pts, px, px);
        let style = color(s.color).stroke_width(2);
        let pieces = split_at_sharp_turns(&pts, 1.0, 1.0, SHARP_TURN_DEG);
        chart
            .draw_series(
                pieces
                    .into_iter()
                    .map(|piece| PathElement::new(piece, style)),
            )
            .map_err(err)?
            .label(s.label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], style));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(190, 190, 190))
        .label_font((FONT, 12))
        .draw()
        .map_err(err)?;
    Ok(())
}

fn map_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    p: &MapPanel,
) -> Result<(), String> {
    let area = area.titled(&p.title, (FONT, 15)).map_err(err)?;
    let (w, _) = area.dim_in_pixel();
    let (disk, bar) = area.split_horizontally(w.saturating_sub(86));
    let build = |xr: f64, yr: f64| {
        ChartBuilder::on(&disk)
            .margin(6)
            .build_cartesian_2d(-xr..xr, -yr / 2.0..yr / 2.0)
    };
    let dims = build(1.12, 2.24)
        .map_err(err)?
        .plotting_area()
        .dim_in_pixel();
    let (xr, yr) = equal_aspect(1.12, 2.24, dims);
    let mut chart = build(xr, yr).map_err(err)?;
    let span = (p.hi - p.lo).max(f64::MIN_POSITIVE);
    let cells = (0..p.n_theta).flat_map(|j| (0..p.n_phi).map(move |k| (j, k)));
    chart
        .draw_series(cells.filter_map(|(j, k)| {
            let v = p.values[j * p.n_phi + k];
            v.is_finite().then(|| {
                let t = ((v - p.lo) / span).clamp(0.0, 1.0);
                let c: RGBColor = ViridisRGB.get_color_normalized(t, 0.0, 1.0);
                Polygon::new(cell_polygon(j, k, p.n_theta, p.n_phi, 2), c.filled())
            })
        }))
        .map_err(err)?;
    let label = (FONT, 11).into_font().color(&WHITE);
    for t in [30.0, 60.0, 90.0] {
        let circle: Vec<(f64, f64)> = (0..=120).map(|k| map_xy(t, 3.0 * k as f64)).collect();
        chart
            .draw_series(LineSeries::new(circle, WHITE.mix(0.7).stroke_width(1)))
            .map_err(err)?;
        chart
            .draw_series(std::iter::once(Text::new(
                format!("{t}°"),
                map_xy(t, 270.0 - 8.0),
                label.clone(),
            )))
            .map_err(err)?;
    }
    for (phi, name) in [(0.0, "incident"), (180.0, "mirror")] {
        let at = map_xy(p.theta_i_deg, phi);
        chart
            .draw_series([
                Circle::new(at, 4, WHITE.filled()),
                Circle::new(at, 4, BLACK.stroke_width(1)),
            ])
            .map_err(err)?;
        chart
            .draw_series(std::iter::once(Text::new(
                name.to_string(),
                (at.0, at.1 - 0.06),
                label.clone().pos(text_anchor::Pos::new(
                    text_anchor::HPos::Center,
                    text_anchor::VPos::Top,
                )),
            )))
            .map_err(err)?;
    }
    // Colour bar.
    let mut cb = ChartBuilder::on(&bar)
        .margin_top(14)
        .margin_bottom(14)
        .margin_right(4)
        .y_label_area_size(52)
        .build_cartesian_2d(0.0..1.0, p.lo..p.hi)
        .map_err(err)?;
    cb.configure_mesh()
        .disable_mesh()
        .x_labels(0)
        .y_labels(6)
        .y_desc(p.colorbar_label.as_str())
        .y_label_formatter(&|v| linear_label(*v))
        .label_style((FONT, 11))
        .axis_desc_style((FONT, 12))
        .draw()
        .map_err(err)?;
    let bands = 64;
    cb.draw_series((0..bands).map(|b| {
        let (a, z) = (b as f64 / bands as f64, (b + 1) as f64 / bands as f64);
        let c: RGBColor = ViridisRGB.get_color_normalized(0.5 * (a + z), 0.0, 1.0);
        Rectangle::new([(0.0, p.lo + a * span), (1.0, p.lo + z * span)], c.filled())
    }))
    .map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_format_from_the_extension() {
        assert_eq!(format_of(Path::new("a/fig8.svg")), Ok(Format::Svg));
        assert_eq!(format_of(Path::new("FIG.PNG")), Ok(Format::Png));
        assert!(
            format_of(Path::new("fig.pdf"))
                .unwrap_err()
                .contains(".svg or .png")
        );
        assert!(format_of(Path::new("fig")).is_err());
    }

    #[test]
    fn a_missing_font_is_named() {
        let e = font_path(Some(Path::new("/nonexistent/font.ttf"))).unwrap_err();
        assert!(e.contains("/nonexistent/font.ttf"), "{e}");
    }

    #[test]
    fn equal_aspect_keeps_the_data_inside() {
        let (xr, yr) = equal_aspect(1.0, 1.0, (400, 100));
        assert!(xr >= 1.0 && yr >= 1.0);
        assert!(((2.0 * xr / 400.0) - (yr / 100.0)).abs() < 1e-12);
    }
}
