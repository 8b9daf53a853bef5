//! The comparison plots (plotters): error against run time (the Pareto front), error against
//! DOFs, and per-phase time bars, each written as SVG and PNG. Text is rendered with the bundled
//! DejaVu Sans (`xtask/assets`, licence beside it) through ab_glyph, so no system fonts are read.

use crate::compare::{cut_references, reference_of, tip_error};
use anyhow::{Context, Result, anyhow};
use cleave_testkit::compare::{Problem, Row};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

pub(crate) const FONT: &str = "sans-serif";

pub(crate) fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, include_bytes!("../assets/DejaVuSans.ttf"))
            .unwrap_or_else(|_| panic!("the bundled DejaVuSans.ttf is a valid font"));
    });
}

/// One line of a log–log panel: (run time [s], DOFs, error) per level.
struct Series {
    method: String,
    points: Vec<(f64, f64, f64)>,
}

struct ErrorPanel {
    title: String,
    y_label: String,
    series: Vec<Series>,
}

fn error_panels(rows: &[Row]) -> Vec<ErrorPanel> {
    let reference = reference_of(rows);
    let [(_, _, cut_reference), ..] = cut_references(rows);
    let mut panels = Vec::new();
    let specs: [(Problem, &str, &str); 4] = [
        (Problem::MmsSin111, "MMS sin111: L2 error", "relative L2 error [-]"),
        (Problem::MmsCos123, "MMS cos123: L2 error", "relative L2 error [-]"),
        (Problem::Cantilever, "cantilever: tip error vs extrapolated", "relative tip_uz_avg error [-]"),
        (Problem::CutCantilever, "cut cantilever: tip error vs extrapolated", "relative tip_uz_avg error [-]"),
    ];
    for (problem, title, y_label) in specs {
        let mut series: Vec<Series> = Vec::new();
        for r in rows.iter().filter(|r| r.problem == problem.key()) {
            let error = match problem {
                Problem::Cantilever => reference.as_ref().and_then(|rf| tip_error(r, rf)),
                Problem::CutCantilever => cut_reference.as_ref().and_then(|rf| tip_error(r, rf)),
                _ => r.l2_rel_error,
            };
            let (Some(e), Some(t)) = (error, r.seconds_total) else { continue };
            if !(e > 0.0 && t > 0.0) {
                continue;
            }
            let point = (t, r.dofs as f64, e);
            match series.iter_mut().find(|s| s.method == r.method()) {
                Some(s) => s.points.push(point),
                None => series.push(Series { method: r.method(), points: vec![point] }),
            }
        }
        for s in &mut series {
            s.points.sort_by(|a, b| a.1.total_cmp(&b.1));
        }
        if !series.is_empty() {
            panels.push(ErrorPanel { title: title.into(), y_label: y_label.into(), series });
        }
    }
    panels
}

fn log_bounds(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo > hi { (0.1, 10.0) } else { (lo / 1.6, hi * 1.6) }
}

fn draw_error_panels<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    panels: &[ErrorPanel],
    by_dofs: bool,
) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("{e:?}");
    root.fill(&WHITE).map_err(e)?;
    let areas = root.split_evenly((1, panels.len().max(1)));
    // One colour per method across all panels (the cut cantilever's methods keep their colours).
    let mut methods: Vec<&str> = Vec::new();
    for s in panels.iter().flat_map(|p| &p.series) {
        if !methods.contains(&s.method.as_str()) {
            methods.push(&s.method);
        }
    }
    for (panel, area) in panels.iter().zip(&areas) {
        let x = |p: &(f64, f64, f64)| if by_dofs { p.1 } else { p.0 };
        let (x0, x1) = log_bounds(panel.series.iter().flat_map(|s| s.points.iter().map(x)));
        let (y0, y1) = log_bounds(panel.series.iter().flat_map(|s| s.points.iter().map(|p| p.2)));
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FONT, 20))
            .margin(12)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc(if by_dofs { "degrees of freedom [-]" } else { "run time (wall clock, median) [s]" })
            .y_desc(panel.y_label.as_str())
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 15))
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()
            .map_err(e)?;
        for s in &panel.series {
            let color = Palette99::pick(methods.iter().position(|m| *m == s.method).unwrap_or(0)).to_rgba();
            let points: Vec<(f64, f64)> = s.points.iter().map(|p| (x(p), p.2)).collect();
            chart
                .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))
                .map_err(e)?
                .label(s.method.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, color.filled()))).map_err(e)?;
        }
        chart
            .configure_series_labels()
            .label_font((FONT, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(e)?;
    }
    root.present().map_err(e)
}

struct PhasePanel {
    title: String,
    /// (method, [(phase, seconds)]) at the method's finest level.
    bars: Vec<(String, Vec<(&'static str, f64)>)>,
}

fn phase_panels(rows: &[Row]) -> Vec<PhasePanel> {
    let mut panels = Vec::new();
    for problem in Problem::ALL {
        let mut finest: Vec<&Row> = Vec::new();
        for r in rows.iter().filter(|r| r.problem == problem.key()) {
            match finest.iter_mut().find(|f| f.method() == r.method()) {
                Some(f) if f.n < r.n => *f = r,
                Some(_) => {}
                None => finest.push(r),
            }
        }
        if finest.is_empty() {
            continue;
        }
        let bars = finest
            .iter()
            .map(|r| {
                let setup = r.seconds_setup.unwrap_or(0.0);
                let assemble = r.seconds_assemble.unwrap_or(0.0);
                let solve = r.seconds_solve.unwrap_or(0.0);
                let rotations = r.seconds_rotations.unwrap_or(0.0);
                let other = (r.seconds_total.unwrap_or(0.0) - setup - assemble - solve - rotations).max(0.0);
                (
                    format!("{} n={}", r.method(), r.n),
                    vec![
                        ("setup", setup),
                        ("assemble", assemble),
                        ("solve", solve),
                        ("rotations", rotations),
                        ("other", other),
                    ],
                )
            })
            .collect();
        panels.push(PhasePanel { title: format!("{}: time per phase, finest level", problem.key()), bars });
    }
    panels
}

fn draw_phase_panels<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, panels: &[PhasePanel]) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("{e:?}");
    root.fill(&WHITE).map_err(e)?;
    let areas = root.split_evenly((1, panels.len().max(1)));
    let phases = ["setup", "assemble", "solve", "rotations", "other"];
    for (panel, area) in panels.iter().zip(&areas) {
        let m = panel.bars.len();
        let top =
            panel.bars.iter().map(|(_, p)| p.iter().map(|(_, s)| s).sum::<f64>()).fold(0.0, f64::max).max(1e-6) * 1.25;
        let names: Vec<String> = panel.bars.iter().map(|(n, _)| n.clone()).collect();
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FONT, 18))
            .margin(12)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(-0.5f64..m as f64 - 0.5, 0.0..top)
            .map_err(e)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(m.max(2))
            .x_label_formatter(&|x| {
                let i = x.round();
                if (x - i).abs() < 1e-6 && i >= 0.0 {
                    names.get(i as usize).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            })
            .x_desc("method (finest level)")
            .y_desc("wall-clock time [s]")
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 15))
            .draw()
            .map_err(e)?;
        for (k, phase) in phases.iter().enumerate() {
            let color = Palette99::pick(k + 3).to_rgba();
            let rects: Vec<Rectangle<(f64, f64)>> = panel
                .bars
                .iter()
                .enumerate()
                .map(|(i, (_, p))| {
                    let bottom: f64 = p[..k].iter().map(|(_, s)| s).sum();
                    let height = p[k].1;
                    Rectangle::new([(i as f64 - 0.3, bottom), (i as f64 + 0.3, bottom + height)], color.filled())
                })
                .collect();
            chart
                .draw_series(rects)
                .map_err(e)?
                .label(*phase)
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], color.filled()));
        }
        chart
            .configure_series_labels()
            .label_font((FONT, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(e)?;
    }
    root.present().map_err(e)
}

/// Writes `error_vs_time`, `error_vs_dofs` and `phases` as SVG and PNG into `dir`; returns the
/// file names written.
pub fn compare_plots(rows: &[Row], dir: &Path) -> Result<Vec<String>> {
    register_font();
    let errors = error_panels(rows);
    let phases = phase_panels(rows);
    let mut written = Vec::new();
    let width = |panels: usize| 620 * panels.max(1) as u32;
    for (name, by_dofs) in [("error_vs_time", false), ("error_vs_dofs", true)] {
        if errors.is_empty() {
            continue;
        }
        let size = (width(errors.len()), 560);
        let svg = dir.join(format!("{name}.svg"));
        draw_error_panels(&SVGBackend::new(&svg, size).into_drawing_area(), &errors, by_dofs)
            .map_err(|e| anyhow!(e))
            .with_context(|| format!("drawing {}", svg.display()))?;
        let png = dir.join(format!("{name}.png"));
        draw_error_panels(&BitMapBackend::new(&png, size).into_drawing_area(), &errors, by_dofs)
            .map_err(|e| anyhow!(e))
            .with_context(|| format!("drawing {}", png.display()))?;
        written.extend([svg.display().to_string(), png.display().to_string()]);
    }
    if !phases.is_empty() {
        let size = (width(phases.len()), 560);
        let svg = dir.join("phases.svg");
        draw_phase_panels(&SVGBackend::new(&svg, size).into_drawing_area(), &phases)
            .map_err(|e| anyhow!(e))
            .with_context(|| format!("drawing {}", svg.display()))?;
        let png = dir.join("phases.png");
        draw_phase_panels(&BitMapBackend::new(&png, size).into_drawing_area(), &phases)
            .map_err(|e| anyhow!(e))
            .with_context(|| format!("drawing {}", png.display()))?;
        written.extend([svg.display().to_string(), png.display().to_string()]);
    }
    Ok(written)
}
