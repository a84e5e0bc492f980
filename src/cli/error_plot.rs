//! The plot of `nimbus bench error`: relMSE against render time, log-log, one line per
//! tracker (mean over seeds, a vertical bar from the smallest to the largest seed), as
//! PNG and SVG, drawn with `plotters`.
//!
//! Text needs a TrueType font. `plotters`' own font loader links fontconfig and
//! FreeType, so Nimbus uses its pure-Rust `ab_glyph` backend instead and hands it a font
//! file found at run time: `$NIMBUS_FONT`, else a common sans-serif font under the system
//! font folders. Without any font the plot is drawn without text (axes, grid, lines) and
//! a warning says so.

use crate::output::write_atomically;
use anyhow::{anyhow, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// One tracker's line: (seconds, mean relMSE, min relMSE, max relMSE) per budget.
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64, f64, f64)>,
}

const SIZE: (u32, u32) = (800, 560);
const FAMILY: &str = "sans-serif";
/// Line colours (matplotlib's tab10): distinct on white, none too light.
const COLORS: [(u8, u8, u8); 8] = [
    (31, 119, 180),
    (214, 39, 40),
    (44, 160, 44),
    (255, 127, 14),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
];

/// Writes `PREFIX.png` and `PREFIX.svg` (each atomically) and returns their paths.
pub fn write_plots(prefix: &Path, title: &str, series: &[Series]) -> Result<[PathBuf; 2]> {
    let [png_path, svg_path] = plot_paths(prefix);
    let text = font_registered();
    if !text {
        eprintln!(
            "nimbus: warning: no TrueType font found (set NIMBUS_FONT to a .ttf file); the plot has no text"
        );
    }

    let mut svg = String::new();
    draw(
        SVGBackend::with_string(&mut svg, SIZE).into_drawing_area(),
        title,
        series,
        text,
    )?;
    write_atomically(&svg_path, |f| {
        use std::io::Write;
        f.write_all(svg.as_bytes()).map_err(|e| e.to_string())
    })?;

    let mut rgb = vec![0u8; SIZE.0 as usize * SIZE.1 as usize * 3];
    draw(
        BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area(),
        title,
        series,
        text,
    )?;
    write_atomically(&png_path, |f| {
        let mut enc = png::Encoder::new(std::io::BufWriter::new(f), SIZE.0, SIZE.1);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        // A chart is mostly flat colour: the best compression keeps the file small.
        enc.set_compression(png::Compression::Best);
        enc.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        let mut w = enc.write_header().map_err(|e| e.to_string())?;
        w.write_image_data(&rgb).map_err(|e| e.to_string())
    })?;
    Ok([png_path, svg_path])
}

/// `PREFIX.png` and `PREFIX.svg`.
pub fn plot_paths(prefix: &Path) -> [PathBuf; 2] {
    let with = |ext: &str| {
        let mut s = prefix.as_os_str().to_owned();
        s.push(ext);
        PathBuf::from(s)
    };
    [with(".png"), with(".svg")]
}

/// Draws the chart on `root`; with `text` false nothing asks the font backend for
/// anything (no caption, labels or legend).
fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    series: &[Series],
    text: bool,
) -> Result<()> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("cannot draw the plot: {e}");
    root.fill(&WHITE).map_err(err)?;
    let (x0, x1, y0, y1) = bounds(series);
    let mut builder = ChartBuilder::on(&root);
    builder.margin(16);
    if text {
        builder
            .caption(title, (FAMILY, 18))
            .x_label_area_size(40)
            .y_label_area_size(70);
    }
    let mut chart = builder
        // Budgets usually double: ticks at powers of two on the time axis.
        .build_cartesian_2d((x0..x1).log_scale().base(2.0), (y0..y1).log_scale())
        .map_err(err)?;
    let mut mesh = chart.configure_mesh();
    if text {
        mesh.x_desc("render time (s)")
            .y_desc("relMSE")
            .label_style((FAMILY, 13))
            .axis_desc_style((FAMILY, 15))
            .x_label_formatter(&|v| format!("{v}"))
            .y_label_formatter(&|v| format!("{v:.0e}"));
    } else {
        mesh.x_labels(0).y_labels(0);
    }
    mesh.draw().map_err(err)?;
    for (i, s) in series.iter().enumerate() {
        let (r, g, b) = COLORS[i % COLORS.len()];
        let color = RGBColor(r, g, b).to_rgba();
        let style = color.stroke_width(2);
        let line = chart
            .draw_series(LineSeries::new(s.points.iter().map(|p| (p.0, p.1)), style))
            .map_err(err)?;
        if text {
            line.label(s.label.as_str()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        }
        chart
            .draw_series(
                s.points
                    .iter()
                    .map(|p| Circle::new((p.0, p.1), 3, color.filled())),
            )
            .map_err(err)?;
        chart
            .draw_series(
                s.points
                    .iter()
                    .map(|p| PathElement::new(vec![(p.0, p.2), (p.0, p.3)], color)),
            )
            .map_err(err)?;
    }
    if text {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FAMILY, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

/// Axis ranges over every positive finite value: time with a margin of a third of an
/// octave, relMSE widened to whole decades so the axis has labelled ticks.
fn bounds(series: &[Series]) -> (f64, f64, f64, f64) {
    let mut b = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in series.iter().flat_map(|s| &s.points) {
        if p.0 > 0.0 && p.0.is_finite() {
            b.0 = b.0.min(p.0);
            b.1 = b.1.max(p.0);
        }
        for y in [p.1, p.2, p.3] {
            if y > 0.0 && y.is_finite() {
                b.2 = b.2.min(y);
                b.3 = b.3.max(y);
            }
        }
    }
    if b.0 > b.1 || b.2 > b.3 {
        return (0.1, 10.0, 0.1, 10.0); // nothing to show: any range will do
    }
    let (x0, x1) = (b.0 / 1.26, b.1 * 1.26);
    let y0 = 10f64.powf(b.2.log10().floor());
    let y1 = 10f64.powf(b.3.log10().ceil()).max(10.0 * y0);
    (x0, x1, y0, y1)
}

/// Registers a font with plotters' `ab_glyph` backend once; false when none was found.
fn font_registered() -> bool {
    static DONE: OnceLock<bool> = OnceLock::new();
    *DONE.get_or_init(|| {
        for path in font_candidates() {
            let Ok(bytes) = std::fs::read(&path) else {
                continue;
            };
            // plotters keeps fonts for the life of the process.
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            if plotters::style::register_font(FAMILY, FontStyle::Normal, bytes).is_ok() {
                return true;
            }
        }
        false
    })
}

/// `$NIMBUS_FONT`, then well-known sans-serif fonts, then any .ttf in the font folders.
fn font_candidates() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::env::var_os("NIMBUS_FONT")
        .filter(|p| !p.is_empty())
        .map(PathBuf::from)
        .into_iter()
        .collect();
    v.extend(
        [
            "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/TTF/DejaVuSans.ttf",
            "/usr/share/fonts/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
            "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
            "/usr/share/fonts/liberation-sans/LiberationSans-Regular.ttf",
            "/System/Library/Fonts/Supplemental/Arial.ttf",
            "/Library/Fonts/Arial.ttf",
            "C:\\Windows\\Fonts\\arial.ttf",
        ]
        .map(PathBuf::from),
    );
    for dir in ["/usr/share/fonts", "/usr/local/share/fonts"] {
        collect_ttf(Path::new(dir), 3, &mut v);
    }
    v
}

fn collect_ttf(dir: &Path, depth: u32, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<_> = entries.filter_map(|e| e.ok()).map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() && depth > 0 {
            collect_ttf(&p, depth - 1, out);
        } else if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("ttf")) {
            out.push(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_lines() -> Vec<Series> {
        vec![
            Series {
                label: "a".into(),
                points: vec![(0.5, 1e-2, 8e-3, 1.2e-2), (1.0, 5e-3, 4e-3, 6e-3)],
            },
            Series {
                label: "b".into(),
                points: vec![(0.5, 3e-2, 2e-2, 4e-2), (1.0, 1.5e-2, 1e-2, 2e-2)],
            },
        ]
    }

    /// Without text the chart must not touch the font backend: no font is registered in
    /// this test, so any text request would fail with "font unavailable".
    #[test]
    fn draws_without_a_font() {
        let mut svg = String::new();
        draw(
            SVGBackend::with_string(&mut svg, SIZE).into_drawing_area(),
            "t",
            &two_lines(),
            false,
        )
        .unwrap();
        assert!(svg.contains("<polyline") || svg.contains("<path"), "{svg}");
        assert!(!svg.contains("<text"));
        let mut rgb = vec![0u8; SIZE.0 as usize * SIZE.1 as usize * 3];
        draw(
            BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area(),
            "t",
            &two_lines(),
            false,
        )
        .unwrap();
        // Some pixels are neither white (background) nor black: the coloured lines.
        assert!(rgb.chunks(3).any(|p| p[0] != p[1] || p[1] != p[2]));
    }

    #[test]
    fn bounds_cover_all_points_with_margin() {
        let (x0, x1, y0, y1) = bounds(&two_lines());
        assert!(x0 < 0.5 && x1 > 1.0);
        assert_eq!((y0, y1), (1e-3, 1e-1));
        assert_eq!(bounds(&[]), (0.1, 10.0, 0.1, 10.0));
    }
}
