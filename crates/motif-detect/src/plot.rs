//! Pictures of the 5.5.2 evaluation (like the thesis's Fig. 5.9): the PR curve (precision
//! against recall as detected classes are removed, largest first) and the stress curve (F
//! against the minimum overlap ratio τ), side by side in one PNG, with a third panel beyond the
//! thesis: per annotated class, the shares of its instances the recall credits, that are located
//! but sit in other classes, and that no detected box locates.
//!
//! Drawn like `motif-retarget`'s pictures: plotters into an RGB buffer, written with `motif_core::io::write_png_rgb`, text
//! in DejaVu Sans embedded from the `dejavu` crate (no system fonts needed).

use std::path::Path;
use std::sync::Once;

use motif_core::plotting::TextFix;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{FontStyle, register_font};

use crate::error::{DetectError, Result};
use crate::eval::{AnnotatedClassTotals, EvalReport, EvalSummary};

const FONT: &str = "sans-serif";
static FONT_ONCE: Once = Once::new();

fn register_fonts() {
    FONT_ONCE.call_once(|| {
        // Valid TrueType bytes from the `dejavu` crate; a failure would only lose the text.
        let _ = register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
    });
}

fn plot_err(path: &Path, e: impl std::fmt::Display) -> DetectError {
    DetectError::Plot { path: path.to_path_buf(), message: e.to_string() }
}

/// What [`plot_pr_and_stress`] draws: implemented by one scene's [`EvalReport`] and by the
/// mean curves of an [`EvalSummary`].
pub trait EvalCurves {
    /// The picture's title.
    fn title(&self) -> String;
    /// PR curve points as `(label, recall, precision)`, all classes first, without the point
    /// with no class left (its precision is undefined). The label, if any, is drawn beside
    /// the point.
    fn pr_points(&self) -> Vec<(Option<String>, f64, f64)>;
    /// The overlap threshold τ the figures are for (marked on the stress curve).
    fn tau(&self) -> f64;
    /// Stress curve points as `(τ, F)`.
    fn stress_points(&self) -> Vec<(f64, f64)>;
    /// Per annotated class: instances, located, credited (summed over the scenes).
    fn annotated(&self) -> Vec<AnnotatedClassTotals>;
    /// The precision side: per detected class (one scene) or per scene (several), a label, the
    /// instances counted and those the precision credits.
    fn precision_rows(&self) -> (&'static str, Vec<(String, usize, usize)>);
}

fn detected_rows(r: &EvalReport) -> Vec<(String, usize, usize)> {
    let names: Vec<&str> = r.annotated.iter().map(|a| a.name.as_str()).collect();
    r.detected
        .iter()
        .map(|d| {
            let against =
                d.best_annotated.and_then(|i| names.get(i).copied()).unwrap_or("no annotated class");
            (
                format!("{}: {} of {} credited, as {against}", d.name, d.credited, d.instances),
                d.instances,
                d.credited,
            )
        })
        .collect()
}

impl EvalCurves for EvalReport {
    fn title(&self) -> String {
        format!(
            "{}: P {:.3}, R {:.3}, F {:.3} at τ = {}",
            self.scene, self.precision, self.recall, self.f, self.tau
        )
    }
    fn pr_points(&self) -> Vec<(Option<String>, f64, f64)> {
        // Labelled with the number of classes kept.
        self.pr_curve
            .iter()
            .filter(|&&(kept, _, _)| kept > 0)
            .map(|&(kept, p, r)| (Some(kept.to_string()), r, p))
            .collect()
    }
    fn tau(&self) -> f64 {
        self.tau
    }
    fn stress_points(&self) -> Vec<(f64, f64)> {
        self.stress.clone()
    }
    fn annotated(&self) -> Vec<AnnotatedClassTotals> {
        self.annotated.iter().map(AnnotatedClassTotals::from).collect()
    }
    fn precision_rows(&self) -> (&'static str, Vec<(String, usize, usize)>) {
        ("(d) detected classes: what the precision credits", detected_rows(self))
    }
}

impl EvalCurves for EvalSummary {
    fn title(&self) -> String {
        if let [scene] = self.scenes.as_slice() {
            return scene.title();
        }
        format!(
            "mean of {} scenes: P {:.3}, R {:.3}, F {:.3} at τ = {}",
            self.scenes.len(),
            self.precision,
            self.recall,
            self.f,
            self.options.tau
        )
    }
    fn pr_points(&self) -> Vec<(Option<String>, f64, f64)> {
        if let [scene] = self.scenes.as_slice() {
            return scene.pr_points();
        }
        // Labelled with the number of classes removed (scenes differ in how many they have); a
        // point past the end of some scenes' curves is the mean of the others, and says of how
        // many (the mean of one scene read as the mean of all).
        let n = self.scenes.len();
        self.mean_pr_curve
            .iter()
            .map(|&(removed, p, r)| {
                let k = self.scenes.iter().filter(|s| removed < s.detected_classes).count();
                let label = match (removed, k < n) {
                    (0, _) => "all".to_string(),
                    (_, false) => format!("−{removed}"),
                    (_, true) => format!("−{removed} ({k} of {n} scenes)"),
                };
                (Some(label), r, p)
            })
            .collect()
    }
    fn tau(&self) -> f64 {
        self.options.tau
    }
    fn stress_points(&self) -> Vec<(f64, f64)> {
        self.mean_stress.clone()
    }
    fn annotated(&self) -> Vec<AnnotatedClassTotals> {
        self.annotated.clone()
    }
    fn precision_rows(&self) -> (&'static str, Vec<(String, usize, usize)>) {
        if let [scene] = self.scenes.as_slice() {
            return scene.precision_rows();
        }
        // Detected classes are not comparable across scenes: one row per scene.
        let rows = self
            .scenes
            .iter()
            .map(|s| {
                let n: usize = s.detected.iter().map(|d| d.instances).sum();
                let c: usize = s.detected.iter().map(|d| d.credited).sum();
                (format!("{}: {c} of {n} credited (P {:.3}, R {:.3})", s.scene, s.precision, s.recall), n, c)
            })
            .collect();
        ("(d) scenes: what the precision credits", rows)
    }
}

/// Draws the PR curve, the stress curve, the per-annotated-class shares (the recall's side) and
/// the per-detected-class (or per-scene) credited shares (the precision's side) of `curves` to
/// `path`, left to right (PNG, 2400 × 560 pixels).
pub fn plot_pr_and_stress(curves: &impl EvalCurves, path: &Path) -> Result<()> {
    plot_pr_and_stress_titled(curves, &curves.title(), path)
}

/// [`plot_pr_and_stress`] under another title (what was run, for a benchmark's picture).
pub fn plot_pr_and_stress_titled(curves: &impl EvalCurves, title: &str, path: &Path) -> Result<()> {
    register_fonts();
    // Four panels in a 2 × 2 grid: a 2400 × 560 strip of four came out at about 6 pt when shown
    // at a page's width.
    let size = (1800u32, 1200u32);
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = TextFix(BitMapBackend::with_buffer(&mut buf, size)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let root = root.titled(title, (FONT, 22)).map_err(|e| plot_err(path, e))?;
        let panels = root.split_evenly((2, 2));
        let [left, right, classes, detected] = &panels[..] else {
            return Err(plot_err(path, "four panels"));
        };
        let pr_colour = RGBColor(214, 39, 40);
        let pr = curves.pr_points();
        let pr_caption = if pr.iter().any(|(l, _, _)| l.as_deref().is_some_and(|l| l.starts_with('−'))) {
            "(a) PR curve: largest classes removed one by one (−k: k removed)"
        } else {
            "(a) PR curve: largest classes removed one by one (k: classes kept)"
        };
        let points: Vec<(f64, f64)> = pr.iter().map(|&(_, r, p)| (r, p)).collect();
        let labels: Vec<Option<String>> = pr.iter().map(|(l, _, _)| l.clone()).collect();
        let note = points.is_empty().then_some("no detected class");
        draw_curve(
            left,
            &points,
            &labels,
            pr_caption,
            "recall",
            "precision",
            (0.0, 1.0),
            pr_colour,
            None,
            note,
            path,
        )?;
        let stress = curves.stress_points();
        let tau_max = stress.iter().map(|p| p.0).fold(0.0, f64::max).max(1e-6);
        let stress_colour = RGBColor(31, 119, 180);
        let none: Vec<Option<String>> = vec![None; stress.len()];
        let all_zero = stress.iter().all(|p| p.1 == 0.0);
        draw_curve(
            right,
            &stress,
            &none,
            "(b) stress test: F as the overlap required rises",
            "τ (least overlap of a detected and an annotated box)",
            "F",
            (0.0, tau_max),
            stress_colour,
            Some(curves.tau()),
            all_zero.then_some("F = 0 at every τ"),
            path,
        )?;
        draw_class_shares(classes, &curves.annotated(), path)?;
        let (caption, rows) = curves.precision_rows();
        draw_precision_rows(detected, caption, &rows, path)?;
        root.present().map_err(|e| plot_err(path, e))?;
    }
    motif_core::io::write_png_rgb(path, size.0, size.1, &buf).map_err(|e| plot_err(path, e))
}

/// One curve with its points; `labels[i]` beside point i; the first point (the operating point:
/// every class kept) drawn larger; `mark` a dashed vertical line with the curve's value there
/// (the τ the figures are for); `note` a message in the middle (an empty or all-zero curve).
#[allow(clippy::too_many_arguments)]
fn draw_curve(
    area: &DrawingArea<TextFix<BitMapBackend<'_>>, Shift>,
    points: &[(f64, f64)],
    labels: &[Option<String>],
    caption: &str,
    x_desc: &str,
    y_desc: &str,
    x_range: (f64, f64),
    colour: RGBColor,
    mark: Option<f64>,
    note: Option<&str>,
    path: &Path,
) -> Result<()> {
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 18).into_font())
        .margin(16)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x_range.0..x_range.1, 0.0..1.02)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    chart
        .draw_series(LineSeries::new(points.iter().copied(), colour.stroke_width(2)))
        .map_err(|e| plot_err(path, e))?;
    chart
        .draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))
        .map_err(|e| plot_err(path, e))?;
    let dx = 0.012 * (x_range.1 - x_range.0);
    // Labels sit right of their point, except in the last tenth of the axis, where they would
    // be cut off at the plot's edge (a PR curve ends at recall 1): there they sit left of it.
    let right_edge = x_range.0 + 0.9 * (x_range.1 - x_range.0);
    chart
        .draw_series(points.iter().zip(labels).filter_map(|(&(x, y), l)| {
            l.as_ref().map(|l| {
                let font = (FONT, 12).into_font().color(&colour);
                if x > right_edge {
                    let style = font.pos(Pos::new(HPos::Right, VPos::Top));
                    Text::new(l.clone(), (x - dx, y + 0.035), style)
                } else {
                    Text::new(l.clone(), (x + dx, y + 0.035), font)
                }
            })
        }))
        .map_err(|e| plot_err(path, e))?;
    if mark.is_none()
        && let Some(&first) = points.first()
    {
        chart
            .draw_series(std::iter::once(Circle::new(first, 7, colour.stroke_width(2))))
            .map_err(|e| plot_err(path, e))?;
    }
    if let Some(at) = mark {
        let grey = RGBColor(90, 90, 90);
        chart
            .draw_series(DashedLineSeries::new(vec![(at, 0.0), (at, 1.02)], 6, 4, grey.stroke_width(1)))
            .map_err(|e| plot_err(path, e))?;
        // The curve's value at `at`, interpolated between its points.
        let value = points.windows(2).find(|w| w[0].0 <= at && at <= w[1].0).map(|w| {
            let t = if w[1].0 > w[0].0 { (at - w[0].0) / (w[1].0 - w[0].0) } else { 0.0 };
            w[0].1 + t * (w[1].1 - w[0].1)
        });
        let text = match value {
            Some(v) => format!("τ = {at} (F {v:.3})"),
            None => format!("τ = {at}"),
        };
        chart
            .draw_series(std::iter::once(Text::new(
                text,
                (at + dx, 0.08),
                (FONT, 13).into_font().color(&grey),
            )))
            .map_err(|e| plot_err(path, e))?;
    }
    if let Some(note) = note {
        let mid = (x_range.0 + 0.3 * (x_range.1 - x_range.0), 0.55);
        chart
            .draw_series(std::iter::once(Text::new(note.to_string(), mid, (FONT, 16).into_font())))
            .map_err(|e| plot_err(path, e))?;
    }
    Ok(())
}

/// Height of the band below the bars that holds the legend, in rows.
const LEGEND_BAND: f64 = 0.6;

/// One bar per annotated class, split into the shares of its instances that the recall credits
/// (green), that are located but sit in other classes (orange) and that are missed (grey),
/// labelled with the counts.
fn draw_class_shares(
    area: &DrawingArea<TextFix<BitMapBackend<'_>>, Shift>,
    classes: &[AnnotatedClassTotals],
    path: &Path,
) -> Result<()> {
    let rows: Vec<(String, Vec<usize>)> = classes
        .iter()
        .map(|c| {
            let text = format!(
                "{}: {} of {} credited, {} elsewhere, {} missed",
                c.name,
                c.recalled,
                c.instances,
                c.elsewhere(),
                c.missed()
            );
            (text, vec![c.recalled, c.elsewhere(), c.missed()])
        })
        .collect();
    draw_share_rows(
        area,
        "(c) annotated classes: what the recall credits",
        "share of the class's instances",
        &rows,
        &[
            (RGBColor(44, 160, 44), "credited"),
            (RGBColor(255, 127, 14), "elsewhere (in other classes)"),
            (RGBColor(160, 160, 160), "missed"),
        ],
        path,
    )
}

/// One labelled bar per row, split into `rows[i].1`'s parts (as shares of their sum) in the
/// colours of `legend`, top row first; the legend on one line in the band below the bars (a
/// legend box would hide bars).
fn draw_share_rows(
    area: &DrawingArea<TextFix<BitMapBackend<'_>>, Shift>,
    caption: &str,
    x_desc: &str,
    rows: &[(String, Vec<usize>)],
    legend: &[(RGBColor, &str)],
    path: &Path,
) -> Result<()> {
    let n = rows.len().max(1) as f64;
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 18).into_font())
        .margin(16)
        .x_label_area_size(40)
        .y_label_area_size(10)
        .build_cartesian_2d(0.0..1.0, -LEGEND_BAND..n)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_labels(0)
        .disable_y_mesh()
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    for (k, &(colour, name)) in legend.iter().enumerate() {
        let bars = rows.iter().enumerate().filter_map(move |(row, (_, parts))| {
            let total = parts.iter().sum::<usize>().max(1) as f64;
            let from = parts[..k.min(parts.len())].iter().sum::<usize>() as f64 / total;
            let to = from + parts.get(k).copied().unwrap_or(0) as f64 / total;
            // The bar fills the lower half of its row, the label the upper half.
            let y = n - row as f64 - 1.0;
            (to > from).then(|| Rectangle::new([(from, y + 0.1), (to, y + 0.5)], colour.filled()))
        });
        chart.draw_series(bars).map_err(|e| plot_err(path, e))?;
        let (x, y) = (k as f64 / legend.len().max(3) as f64, -LEGEND_BAND / 2.0);
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((x, y))
                    + Rectangle::new([(0, -6), (14, 6)], colour.filled())
                    + Text::new(name.to_string(), (20, -7), (FONT, 13).into_font()),
            ))
            .map_err(|e| plot_err(path, e))?;
    }
    let label_size = if rows.len() > 12 { 11 } else { 14 };
    chart
        .draw_series(rows.iter().enumerate().map(|(row, (text, _))| {
            Text::new(text.clone(), (0.005, n - row as f64 - 0.12), (FONT, label_size).into_font())
        }))
        .map_err(|e| plot_err(path, e))?;
    Ok(())
}

/// One bar per row: the share the precision credits (green) and the rest (red), with its label.
fn draw_precision_rows(
    area: &DrawingArea<TextFix<BitMapBackend<'_>>, Shift>,
    caption: &str,
    rows: &[(String, usize, usize)],
    path: &Path,
) -> Result<()> {
    let rows: Vec<(String, Vec<usize>)> = rows
        .iter()
        .map(|(text, instances, credited)| {
            (text.clone(), vec![*credited, instances.saturating_sub(*credited)])
        })
        .collect();
    draw_share_rows(
        area,
        caption,
        "share of the instances",
        &rows,
        &[
            (RGBColor(44, 160, 44), "credited"),
            (RGBColor(214, 39, 40), "not credited (other blocks, clutter)"),
        ],
        path,
    )
}

/// One row of `motif bench detect`: a method on the scenes of one difficulty.
#[derive(Debug, Clone)]
pub struct BenchRow {
    /// "easy", "medium" or "hard".
    pub difficulty: String,
    /// "EM + SC", "SC (no EM)" or "rigid ICP (supervised)".
    pub method: String,
    /// Mean F over the scenes.
    pub f: f64,
    /// Its standard error (`None` for one scene).
    pub f_se: Option<f64>,
    /// Mean stress curve `(τ, F)`.
    pub stress: Vec<(f64, f64)>,
}

/// The benchmark's picture (`motif bench detect --plot PNG`, 1800 × 620 pixels): (a) mean F per
/// difficulty and method as grouped bars with ±1 standard error, with the thesis's street-scan
/// figures and the target as lines; (b) the stress curves, one colour per method, one
/// dash per difficulty; (c) the PR and class panels of `detail` (EM + SC on the medium scenes)
/// are left to `plot_pr_and_stress`, since one picture per level would repeat them.
pub fn plot_bench(rows: &[BenchRow], title: &str, tau: f64, path: &Path) -> Result<()> {
    register_fonts();
    let size = (1600u32, 620u32);
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    let methods: Vec<&str> = unique(rows.iter().map(|r| r.method.as_str()));
    let levels: Vec<&str> = unique(rows.iter().map(|r| r.difficulty.as_str()));
    let colours = [RGBColor(214, 39, 40), RGBColor(31, 119, 180), RGBColor(120, 120, 120)];
    let colour = |m: &str| colours[methods.iter().position(|x| *x == m).unwrap_or(0) % colours.len()];
    {
        let root = TextFix(BitMapBackend::with_buffer(&mut buf, size)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let root = root.titled(title, (FONT, 20)).map_err(|e| plot_err(path, e))?;
        let (left, right) = root.split_horizontally(size.0 / 2);

        // (a) grouped bars.
        let groups = levels.len().max(1) as f64;
        let width = 0.8 / methods.len().max(1) as f64;
        let mut chart = ChartBuilder::on(&left)
            .caption(
                if rows.iter().all(|r| r.f_se.is_none()) {
                    format!("(a) F at τ = {tau} (one scene: no standard error)")
                } else {
                    format!("(a) mean F at τ = {tau}, ±1 standard error over the scenes")
                },
                (FONT, 18).into_font(),
            )
            .margin(16)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(-0.5..groups - 0.5, 0.0..TOP)
            .map_err(|e| plot_err(path, e))?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(levels.len().max(1))
            .x_label_formatter(&|x| {
                let k = x.round();
                if (x - k).abs() < 1e-6 && k >= 0.0 {
                    levels.get(k as usize).unwrap_or(&"").to_string()
                } else {
                    String::new()
                }
            })
            .y_desc("F")
            // The band above 1 holds the legend.
            .y_label_formatter(&|y| if *y <= 1.0 + 1e-9 { format!("{y:.1}") } else { String::new() })
            .label_style((FONT, 14))
            .axis_desc_style((FONT, 14))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(|e| plot_err(path, e))?;
        // Reference lines (the thesis's EM + SC on street scans, and the target), named in the
        // legend band above the bars.
        let references = [
            (0.74, "thesis EM + SC, street scans (0.74)", RGBColor(110, 110, 110)),
            (0.80, "target (0.80)", RGBColor(40, 140, 60)),
        ];
        for (k, (y, text, c)) in references.into_iter().enumerate() {
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(-0.5, y), (groups - 0.5, y)],
                    6,
                    4,
                    c.stroke_width(2),
                ))
                .map_err(|e| plot_err(path, e))?;
            let (x, ly) = (-0.45 + k as f64 * 0.45 * groups, TOP - 0.13);
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((x, ly))
                        + PathElement::new(vec![(0, 0), (8, 0)], c.stroke_width(2))
                        + PathElement::new(vec![(12, 0), (20, 0)], c.stroke_width(2))
                        + Text::new(text, (26, -8), (FONT, 13).into_font()),
                ))
                .map_err(|e| plot_err(path, e))?;
        }
        for r in rows {
            let (Some(g), Some(m)) =
                (levels.iter().position(|l| *l == r.difficulty), methods.iter().position(|x| *x == r.method))
            else {
                continue;
            };
            let x0 = g as f64 - 0.4 + m as f64 * width;
            let c = colour(&r.method);
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(x0 + 0.02, 0.0), (x0 + width - 0.02, r.f)],
                    c.filled(),
                )))
                .map_err(|e| plot_err(path, e))?;
            if let Some(se) = r.f_se {
                let xm = x0 + 0.5 * width;
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(xm, (r.f - se).max(0.0)), (xm, (r.f + se).min(1.0))],
                        BLACK.stroke_width(2),
                    )))
                    .map_err(|e| plot_err(path, e))?;
            }
            chart
                .draw_series(std::iter::once(Text::new(
                    format!("{:.2}", r.f),
                    (x0 + 0.03, r.f + r.f_se.unwrap_or(0.0) + 0.045),
                    (FONT, 12).into_font(),
                )))
                .map_err(|e| plot_err(path, e))?;
        }
        for (m, name) in methods.iter().enumerate() {
            let c = colour(name);
            let (x, y) = (-0.45 + m as f64 * 0.3 * groups, TOP - 0.05);
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((x, y)) + Rectangle::new([(0, -6), (14, 6)], c.filled()),
                ))
                .map_err(|e| plot_err(path, e))?;
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at((x, y)) + Text::new(name.to_string(), (20, -8), (FONT, 13).into_font()),
                ))
                .map_err(|e| plot_err(path, e))?;
        }

        // (b) stress curves.
        let tau_max = rows.iter().flat_map(|r| r.stress.iter().map(|p| p.0)).fold(0.0, f64::max).max(1e-6);
        let mut chart = ChartBuilder::on(&right)
            .caption("(b) stress test: F as the overlap required rises", (FONT, 18).into_font())
            .margin(16)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..tau_max, 0.0..1.02)
            .map_err(|e| plot_err(path, e))?;
        chart
            .configure_mesh()
            .x_desc("τ (least overlap of a detected and an annotated box)")
            .y_desc("F")
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 14))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(|e| plot_err(path, e))?;
        let dashes = [(1, 0), (10, 5), (3, 4)];
        for r in rows {
            let c = colour(&r.method);
            let l = levels.iter().position(|x| *x == r.difficulty).unwrap_or(0);
            let (dash, gap) = dashes[l % dashes.len()];
            let label = format!("{}, {}", r.method, r.difficulty);
            let style = c.stroke_width(2);
            let series = if gap == 0 {
                chart.draw_series(LineSeries::new(r.stress.iter().copied(), style))
            } else {
                chart.draw_series(DashedLineSeries::new(r.stress.iter().copied(), dash, gap, style))
            };
            // A solid line's legend is drawn as one "dash" of the full width.
            let (dash, gap) = if gap == 0 { (20, 0) } else { (dash, gap) };
            series.map_err(|e| plot_err(path, e))?.label(label).legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (dash.min(20), 0)], style)
                    + PathElement::new(vec![((dash + gap).min(20), 0), (20, 0)], style)
            });
        }
        chart
            .draw_series(DashedLineSeries::new(
                vec![(tau, 0.0), (tau, 1.02)],
                6,
                4,
                RGBColor(90, 90, 90).stroke_width(1),
            ))
            .map_err(|e| plot_err(path, e))?;
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(200, 200, 200))
            .label_font((FONT, 12))
            .draw()
            .map_err(|e| plot_err(path, e))?;
        root.present().map_err(|e| plot_err(path, e))?;
    }
    motif_core::io::write_png_rgb(path, size.0, size.1, &buf).map_err(|e| plot_err(path, e))
}

/// Top of the bar chart's F axis: the band above 1 holds the legend.
const TOP: f64 = 1.28;

/// The distinct values of `items`, in order of first appearance.
fn unique<'a>(items: impl Iterator<Item = &'a str>) -> Vec<&'a str> {
    let mut out: Vec<&str> = Vec::new();
    for i in items {
        if !out.contains(&i) {
            out.push(i);
        }
    }
    out
}

/// Distinct colours for detected classes (Tableau 10), in class order; `motif detect --labels`
/// colours its points with them too.
pub const CLASS_COLOURS: [[u8; 3]; 10] = [
    [214, 39, 40],
    [31, 119, 180],
    [44, 160, 44],
    [255, 127, 14],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [188, 189, 34],
    [23, 190, 207],
    [127, 127, 127],
];

/// Most points drawn per panel of [`plot_detections`] (evenly strided), so that a 5-million
/// point scan draws in about a second.
const MAX_DRAWN: usize = 400_000;

/// A picture of a detection (`motif detect --plot PNG`, 1800 × 900 pixels): the points seen
/// along two world axes, coloured by class with the background light grey, each instance's box
/// outlined in its class's colour, and a legend of the classes with their instance counts.
/// `labels[i]` is point i's `(class, instance)`.
///
/// The first view looks along the axis in which the instance boxes, projected, overlap each other
/// least (the summed areas of their pairwise intersections over their summed areas), so that
/// each block is seen apart: a facade or a street from the front, parts standing on the ground
/// from above. The points' thinnest extent, which this view used
/// to follow, picks the ground view of a street whose depth (pavement, parked cars, the far
/// side) is a little less than its height, where every window collapses onto one line. The
/// second view looks along the axis of the next least overlap. Without instances, the points'
/// extents order the axes.
/// Both views are drawn to scale (one model unit spans as many pixels across as up), so a
/// window keeps its shape.
pub fn plot_detections(
    positions: &[motif_core::Point3],
    labels: &[Option<(u32, u32)>],
    result: &crate::DetectionResult,
    title: &str,
    path: &Path,
) -> Result<()> {
    register_fonts();
    let size = (1800u32, 900u32);
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    let bounds = motif_core::geometry::Aabb::from_points(positions)
        .ok_or_else(|| plot_err(path, "no points to draw"))?;
    let (lo, hi) = (bounds.min, bounds.max);
    let axes = view_axes(result, lo, hi);
    // The boxes order the views when there are two or more to see apart (as `view_axes`).
    let spread_named = result.classes.iter().map(|c| c.instances.len()).sum::<usize>() >= 2;
    // Each panel drops one axis and keeps the other two in x, y, z order.
    let panels: Vec<(usize, usize, usize)> = axes[..2]
        .iter()
        .map(|&drop| {
            let kept: Vec<usize> = (0..3).filter(|&k| k != drop).collect();
            (drop, kept[0], kept[1])
        })
        .collect();
    let stride = positions.len().div_ceil(MAX_DRAWN).max(1);
    let colour_of = |c: u32| {
        let k = CLASS_COLOURS[c as usize % CLASS_COLOURS.len()];
        RGBColor(k[0], k[1], k[2])
    };
    {
        let root = TextFix(BitMapBackend::with_buffer(&mut buf, size)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let root = root.titled(title, (FONT, 20)).map_err(|e| plot_err(path, e))?;
        let (views, legend) = root.split_horizontally(size.0 - 300);
        // Stacked or side by side, whichever draws both views larger (to scale, the smaller
        // of the two scales counts): a long street stacks, a tall facade stands side by side.
        let (vw, vh) = views.dim_in_pixel();
        let scale_in = |pw: f64, ph: f64| {
            panels
                .iter()
                .map(|&(_, a, b)| {
                    // Label areas, margins and caption, roughly as laid out below.
                    let (w, h) = ((pw - 80.0).max(1.0), (ph - 90.0).max(1.0));
                    (w / (1.04 * (hi[a] - lo[a])).max(1e-12)).min(h / (1.04 * (hi[b] - lo[b])).max(1e-12))
                })
                .fold(f64::INFINITY, f64::min)
        };
        let stacked = scale_in(vw as f64, vh as f64 / 2.0) >= scale_in(vw as f64 / 2.0, vh as f64);
        let areas = views.split_evenly(if stacked { (2, 1) } else { (1, 2) });
        let name = ["x", "y", "z"];
        for (k, (area, &(drop, a, b))) in areas.iter().zip(&panels).enumerate() {
            let caption = match (k, spread_named) {
                (0, true) => format!("seen along {} (where the instance boxes overlap least)", name[drop]),
                (_, true) => format!("seen along {} (the next least overlap)", name[drop]),
                (0, false) => format!("seen along {} (the points' thinnest extent)", name[drop]),
                (_, false) => format!("seen along {} (the points' middle extent)", name[drop]),
            };
            let pad = |k: usize| 0.02 * (hi[k] - lo[k]).max(1e-9);
            let (xr, yr) = ((lo[a] - pad(a))..(hi[a] + pad(a)), (lo[b] - pad(b))..(hi[b] + pad(b)));
            // The plotting area's size in pixels, from a chart laid out the same way on a
            // scratch canvas, sets ranges of equal scale.
            let (w, h) = area.dim_in_pixel();
            let mut scratch = vec![0u8; w as usize * h as usize * 3];
            let plot_px = {
                let probe = BitMapBackend::with_buffer(&mut scratch, (w, h)).into_drawing_area();
                let chart =
                    view_chart(&probe, &caption, xr.clone(), yr.clone()).map_err(|e| plot_err(path, e))?;
                chart.plotting_area().dim_in_pixel()
            };
            let (xr, yr) = equal_scale(xr, yr, plot_px);
            let mut chart = view_chart(area, &caption, xr, yr).map_err(|e| plot_err(path, e))?;
            chart
                .configure_mesh()
                .x_desc(format!("{} (model units)", name[a]))
                .y_desc(format!("{} (model units)", name[b]))
                .disable_mesh()
                .label_style((FONT, 12))
                .axis_desc_style((FONT, 13))
                .draw()
                .map_err(|e| plot_err(path, e))?;
            // Background first, then the classes over it.
            let grey = RGBColor(200, 200, 200);
            chart
                .draw_series(
                    positions
                        .iter()
                        .zip(labels)
                        .step_by(stride)
                        .filter(|(_, l)| l.is_none())
                        .map(|(p, _)| Pixel::new((p[a], p[b]), grey)),
                )
                .map_err(|e| plot_err(path, e))?;
            chart
                .draw_series(
                    positions
                        .iter()
                        .zip(labels)
                        .step_by(stride)
                        .filter_map(|(p, l)| l.map(|(c, _)| Pixel::new((p[a], p[b]), colour_of(c)))),
                )
                .map_err(|e| plot_err(path, e))?;
            for (c, class) in result.classes.iter().enumerate() {
                let colour = colour_of(c as u32);
                chart
                    .draw_series(class.instances.iter().map(|i| {
                        Rectangle::new(
                            [(i.bbox_min[a], i.bbox_min[b]), (i.bbox_max[a], i.bbox_max[b])],
                            colour.stroke_width(2),
                        )
                    }))
                    .map_err(|e| plot_err(path, e))?;
            }
        }
        // Legend.
        let mut y = 20;
        legend
            .draw(&Text::new(
                format!(
                    "{} {}",
                    result.classes.len(),
                    if result.classes.len() == 1 { "class" } else { "classes" }
                ),
                (10, y),
                (FONT, 16).into_font(),
            ))
            .map_err(|e| plot_err(path, e))?;
        y += 28;
        for (c, class) in result.classes.iter().enumerate().take(30) {
            let colour = colour_of(c as u32);
            legend
                .draw(&Rectangle::new([(10, y + 2), (26, y + 14)], colour.filled()))
                .map_err(|e| plot_err(path, e))?;
            let n = class.instances.len();
            let label = format!(
                "{}: {n} {}",
                class.name.clone().unwrap_or_else(|| format!("class {c}")),
                if n == 1 { "instance" } else { "instances" }
            );
            legend.draw(&Text::new(label, (34, y), (FONT, 14).into_font())).map_err(|e| plot_err(path, e))?;
            y += 22;
        }
        if result.classes.len() > 30 {
            legend
                .draw(&Text::new(
                    format!("… {} more", result.classes.len() - 30),
                    (10, y),
                    (FONT, 14).into_font(),
                ))
                .map_err(|e| plot_err(path, e))?;
            y += 22;
        }
        legend
            .draw(&Rectangle::new([(10, y + 2), (26, y + 14)], RGBColor(200, 200, 200).filled()))
            .map_err(|e| plot_err(path, e))?;
        legend
            .draw(&Text::new("background", (34, y), (FONT, 14).into_font()))
            .map_err(|e| plot_err(path, e))?;
        root.present().map_err(|e| plot_err(path, e))?;
    }
    motif_core::io::write_png_rgb(path, size.0, size.1, &buf).map_err(|e| plot_err(path, e))
}

/// The view axes of [`plot_detections`], best first: the axis along which the instance boxes,
/// projected, overlap each other least (the summed areas of the pairwise intersections over the
/// summed areas of the boxes), so that each box is seen apart from the others; by the points'
/// extents (thinnest first) when there are fewer than two instances, and to break ties.
fn view_axes(result: &crate::DetectionResult, lo: motif_core::Point3, hi: motif_core::Point3) -> [usize; 3] {
    // Enough boxes to judge the views; evenly strided beyond that, as quadratic work.
    const MAX_BOXES: usize = 1500;
    let boxes: Vec<([f64; 3], [f64; 3])> =
        result.classes.iter().flat_map(|c| &c.instances).map(|i| (i.bbox_min, i.bbox_max)).collect();
    let stride = boxes.len().div_ceil(MAX_BOXES).max(1);
    let boxes: Vec<_> = boxes.into_iter().step_by(stride).collect();
    let extent = |k: usize| hi[k] - lo[k];
    let overlap = |drop: usize| {
        if boxes.len() < 2 {
            return 0.0;
        }
        let kept: Vec<usize> = (0..3).filter(|&k| k != drop).collect();
        let side = |b: &([f64; 3], [f64; 3]), k: usize| (b.1[k] - b.0[k]).max(1e-3 * extent(k).max(1e-12));
        let area = |b: &([f64; 3], [f64; 3])| side(b, kept[0]) * side(b, kept[1]);
        let total: f64 = boxes.iter().map(area).sum();
        let mut shared = 0.0;
        for (n, p) in boxes.iter().enumerate() {
            for q in &boxes[n + 1..] {
                let len = |k: usize| (p.1[k].min(q.1[k]) - p.0[k].max(q.0[k])).max(0.0);
                shared += len(kept[0]) * len(kept[1]);
            }
        }
        shared / total.max(f64::MIN_POSITIVE)
    };
    let score: Vec<f64> = (0..3).map(overlap).collect();
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|&a, &b| score[a].total_cmp(&score[b]).then(extent(a).total_cmp(&extent(b))));
    axes
}

/// Widens the shorter of two ranges about its centre so that one unit spans as many pixels along
/// x as along y on a plotting area of `px` pixels.
fn equal_scale(
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
    px: (u32, u32),
) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let (w, h) = (px.0.max(1) as f64, px.1.max(1) as f64);
    let (dx, dy) = (x.end - x.start, y.end - y.start);
    // Units per pixel: the larger of the two keeps both ranges in view.
    let u = (dx / w).max(dy / h);
    let widen = |r: std::ops::Range<f64>, span: f64| {
        let c = 0.5 * (r.start + r.end);
        (c - 0.5 * span)..(c + 0.5 * span)
    };
    (widen(x, u * w), widen(y, u * h))
}

/// One view of [`plot_detections`], laid out alike on the picture and on the scratch canvas that
/// measures its plotting area.
type ViewChart<'a, DB> = ChartContext<
    'a,
    DB,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

fn view_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    caption: &str,
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
) -> std::result::Result<ViewChart<'a, DB>, DrawingAreaErrorKind<DB::ErrorType>> {
    ChartBuilder::on(area)
        .caption(caption, (FONT, 16).into_font())
        .margin(10)
        .x_label_area_size(32)
        .y_label_area_size(50)
        .build_cartesian_2d(x, y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DetectedClass, DetectedInstance, DetectionResult};

    fn boxes(b: &[([f64; 3], [f64; 3])]) -> DetectedClass {
        DetectedClass {
            name: None,
            instances: b.iter().map(|&(lo, hi)| DetectedInstance::from_box(lo, hi)).collect(),
        }
    }

    /// A street: windows on the wall (z near 0) in a 6 × 4 grid, and parked cars spread over a
    /// deep street (z 2–14) more than the windows spread in height. The view along z sees every
    /// box apart; the points' thinnest extent (y, 13 against z's 14) and the spread of the boxes'
    /// centres (z, with the cars) both chose another.
    #[test]
    fn the_first_view_sees_the_boxes_apart() {
        let mut windows = Vec::new();
        for i in 0..6 {
            for j in 0..4 {
                let (x, y) = (3.0 * i as f64, 3.0 * j as f64 + 1.0);
                windows.push(([x, y, -0.2], [x + 1.5, y + 2.0, 0.2]));
            }
        }
        let cars: Vec<_> = (0..8)
            .map(|k| {
                let (x, z) = (2.5 * k as f64, 2.0 + 12.0 * (k % 2) as f64);
                ([x, 0.0, z - 1.0], [x + 2.0, 1.5, z + 1.0])
            })
            .collect();
        let result = DetectionResult { scene: String::new(), classes: vec![boxes(&windows), boxes(&cars)] };
        let (lo, hi) = ([0.0, 0.0, -1.0], [20.0, 13.0, 15.0]);
        assert_eq!(view_axes(&result, lo, hi)[0], 2);
        // Without instances the points' extents decide, thinnest first.
        let empty = DetectionResult { scene: String::new(), classes: vec![] };
        assert_eq!(view_axes(&empty, lo, hi), [1, 2, 0]);
    }

    #[test]
    fn views_are_drawn_to_scale() {
        // A 20 × 5 range on 1000 × 500 pixels: y widens to 10 about its centre.
        let (x, y) = equal_scale(0.0..20.0, 0.0..5.0, (1000, 500));
        assert_eq!((x.start, x.end), (0.0, 20.0));
        assert!((y.start + 2.5).abs() < 1e-12 && (y.end - 7.5).abs() < 1e-12, "{y:?}");
        // A tall range widens x instead.
        let (x, y) = equal_scale(0.0..1.0, 0.0..10.0, (1000, 500));
        assert!(((x.end - x.start) / 1000.0 - (y.end - y.start) / 500.0).abs() < 1e-12);
        assert_eq!((y.start, y.end), (0.0, 10.0));
    }
}
