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

use plotters::coord::Shift;
use plotters::prelude::*;
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
    /// PR curve points as `(recall, precision)`, all classes first.
    fn pr_points(&self) -> Vec<(f64, f64)>;
    /// Stress curve points as `(τ, F)`.
    fn stress_points(&self) -> Vec<(f64, f64)>;
    /// Per annotated class: instances, located, credited (summed over the scenes).
    fn annotated(&self) -> Vec<AnnotatedClassTotals>;
}

impl EvalCurves for EvalReport {
    fn title(&self) -> String {
        format!(
            "{}: P {:.3}, R {:.3}, F {:.3} at tau {}",
            self.scene, self.precision, self.recall, self.f, self.tau
        )
    }
    fn pr_points(&self) -> Vec<(f64, f64)> {
        self.pr_curve.iter().map(|&(_, p, r)| (r, p)).collect()
    }
    fn stress_points(&self) -> Vec<(f64, f64)> {
        self.stress.clone()
    }
    fn annotated(&self) -> Vec<AnnotatedClassTotals> {
        self.annotated.iter().map(AnnotatedClassTotals::from).collect()
    }
}

impl EvalCurves for EvalSummary {
    fn title(&self) -> String {
        if let [scene] = self.scenes.as_slice() {
            return scene.title();
        }
        format!(
            "mean of {} scenes: P {:.3}, R {:.3}, F {:.3} at tau {}",
            self.scenes.len(),
            self.precision,
            self.recall,
            self.f,
            self.options.tau
        )
    }
    fn pr_points(&self) -> Vec<(f64, f64)> {
        self.mean_pr_curve.iter().map(|&(_, p, r)| (r, p)).collect()
    }
    fn stress_points(&self) -> Vec<(f64, f64)> {
        self.mean_stress.clone()
    }
    fn annotated(&self) -> Vec<AnnotatedClassTotals> {
        self.annotated.clone()
    }
}

/// Draws the PR curve (left), the stress curve (middle) and the per-class shares (right) of
/// `curves` to `path` (PNG, 1800 × 560 pixels).
pub fn plot_pr_and_stress(curves: &impl EvalCurves, path: &Path) -> Result<()> {
    register_fonts();
    let size = (1800u32, 560u32);
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let root = root.titled(&curves.title(), (FONT, 20)).map_err(|e| plot_err(path, e))?;
        let (left, rest) = root.split_horizontally(size.0 / 3);
        let (right, classes) = rest.split_horizontally(size.0 / 3);
        let pr_colour = RGBColor(214, 39, 40);
        draw_curve(
            &left,
            &curves.pr_points(),
            "(a) PR curve",
            "recall",
            "precision",
            (0.0, 1.0),
            pr_colour,
            path,
        )?;
        let stress = curves.stress_points();
        let tau_max = stress.iter().map(|p| p.0).fold(0.0, f64::max).max(1e-6);
        let stress_colour = RGBColor(31, 119, 180);
        draw_curve(
            &right,
            &stress,
            "(b) stress test",
            "tau (min. overlap)",
            "F",
            (0.0, tau_max),
            stress_colour,
            path,
        )?;
        draw_class_shares(&classes, &curves.annotated(), path)?;
        root.present().map_err(|e| plot_err(path, e))?;
    }
    motif_core::io::write_png_rgb(path, size.0, size.1, &buf).map_err(|e| plot_err(path, e))
}

fn draw_curve(
    area: &DrawingArea<BitMapBackend, Shift>,
    points: &[(f64, f64)],
    caption: &str,
    x_desc: &str,
    y_desc: &str,
    x_range: (f64, f64),
    colour: RGBColor,
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
    Ok(())
}

/// Height of the band below the bars that holds the legend, in rows.
const LEGEND_BAND: f64 = 0.6;

/// One bar per annotated class, split into the shares of its instances that the recall credits
/// (green), that are located but sit in other classes (orange) and that are missed (grey),
/// labelled with the counts.
fn draw_class_shares(
    area: &DrawingArea<BitMapBackend, Shift>,
    classes: &[AnnotatedClassTotals],
    path: &Path,
) -> Result<()> {
    let rows = classes.len().max(1) as f64;
    let mut chart = ChartBuilder::on(area)
        .caption("(c) annotated classes", (FONT, 18).into_font())
        .margin(16)
        .x_label_area_size(40)
        .y_label_area_size(10)
        .build_cartesian_2d(0.0..1.0, -LEGEND_BAND..rows)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("share of the class's instances")
        .y_labels(0)
        .disable_y_mesh()
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    let colours = [RGBColor(44, 160, 44), RGBColor(255, 127, 14), RGBColor(160, 160, 160)];
    let names = ["credited", "elsewhere (in other classes)", "missed"];
    for (k, (&colour, name)) in colours.iter().zip(names).enumerate() {
        let bars = classes.iter().enumerate().filter_map(move |(row, c)| {
            let n = c.instances.max(1) as f64;
            let parts = [c.recalled, c.elsewhere(), c.missed()];
            let from = parts[..k].iter().sum::<usize>() as f64 / n;
            let to = from + parts[k] as f64 / n;
            // Top row first; the bar fills the lower half of its row, the label the upper half.
            let y = rows - row as f64 - 1.0;
            (to > from).then(|| Rectangle::new([(from, y + 0.1), (to, y + 0.5)], colour.filled()))
        });
        chart.draw_series(bars).map_err(|e| plot_err(path, e))?;
        // The legend, one line in the band below the bars (a legend box would hide bars).
        let x = k as f64 / 3.0;
        let y = -LEGEND_BAND / 2.0;
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((x, y)) + Rectangle::new([(0, -6), (14, 6)], colour.filled()),
            ))
            .map_err(|e| plot_err(path, e))?;
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((x, y)) + Text::new(name, (20, -7), (FONT, 13).into_font()),
            ))
            .map_err(|e| plot_err(path, e))?;
    }
    let label_size = if classes.len() > 12 { 11 } else { 14 };
    chart
        .draw_series(classes.iter().enumerate().map(|(row, c)| {
            let text = format!(
                "{}: {} of {} credited, {} elsewhere, {} missed",
                c.name,
                c.recalled,
                c.instances,
                c.elsewhere(),
                c.missed()
            );
            Text::new(text, (0.005, rows - row as f64 - 0.12), (FONT, label_size).into_font())
        }))
        .map_err(|e| plot_err(path, e))?;
    Ok(())
}
