//! Pictures of offset statistics (`motif offsets --plot PNG`) and of the sparsity study
//! (`motif sparsity --plot PNG`), drawn with plotters into an RGB buffer and written as PNG.
//!
//! Text uses DejaVu Sans embedded from the `dejavu` crate (registered with plotters' `ab_glyph`
//! backend), so pictures render the same on any machine without system fonts or fontconfig.
//!
//! The offset picture shows why the principal offsets were chosen:
//! - three projections of the 3-D offset histogram (onto the XY, XZ and YZ planes; the bin masses
//!   summed along the dropped axis, log colour scale shared by the three and shown as a colour
//!   bar beside the text), drawn point-symmetric (each bin also at `−v`, since `v` and `−v` are
//!   one repetition), with the dominant offsets circled (accepted ones in blue, rejected ones
//!   grey) and the principal offsets as arrows from the origin labelled `p0 …` (numbered by
//!   model axis, as `--steps` counts them) and their support; when every offset lies along one
//!   axis (a fence), one profile of the counts along it instead ([`line_axis`]), and when they
//!   lie in one axis plane (a shelf, a facade), that plane's projection alone, large, with the
//!   bar chart and text beside it ([`plane_axes`]);
//! - a bar chart of the dominant offsets' support, principal ones highlighted, with the verdict and
//!   the principal offsets in model units below.

use std::path::Path;
use std::sync::Once;

use motif_core::plotting::TextFix;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use crate::offsets::{DominantStatus, OffsetAnalysis, OffsetsError, Result};
use crate::sparsity::{Category, SparsityReport};

const FONT: &str = "sans-serif";
static FONT_ONCE: Once = Once::new();

fn register_fonts() {
    FONT_ONCE.call_once(|| {
        // The bytes are a valid TrueType font shipped by the `dejavu` crate; a failure here would
        // only mean missing text, never a wrong picture.
        let _ = register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
        let _ = register_font(FONT, FontStyle::Bold, dejavu::sans::bold());
    });
}

fn plot_err(path: &Path, e: impl std::fmt::Display) -> OffsetsError {
    OffsetsError::Plot { path: path.to_path_buf(), message: e.to_string() }
}

/// Renders into an RGB buffer with `draw`, then writes it to `path` as PNG.
fn render_png(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<TextFix<BitMapBackend<'_>>, Shift>) -> Result<()>,
) -> Result<()> {
    register_fonts();
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = TextFix(BitMapBackend::with_buffer(&mut buf, size)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        draw(&root)?;
        root.present().map_err(|e| plot_err(path, e))?;
    }
    motif_core::io::write_png_rgb(path, size.0, size.1, &buf).map_err(|e| plot_err(path, e))
}

/// A light-to-dark heat colour for `t` in [0, 1] (pale yellow → orange → red → dark purple).
fn heat(t: f64) -> RGBColor {
    const STOPS: [(f64, [f64; 3]); 5] = [
        (0.0, [255.0, 245.0, 200.0]),
        (0.3, [253.0, 190.0, 90.0]),
        (0.6, [235.0, 90.0, 40.0]),
        (0.85, [170.0, 20.0, 60.0]),
        (1.0, [60.0, 10.0, 70.0]),
    ];
    let t = t.clamp(0.0, 1.0);
    let mut k = 0;
    while k + 2 < STOPS.len() && t > STOPS[k + 1].0 {
        k += 1;
    }
    let (t0, c0) = STOPS[k];
    let (t1, c1) = STOPS[k + 1];
    let s = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    let c = [0, 1, 2].map(|i| (c0[i] + s * (c1[i] - c0[i])).round() as u8);
    RGBColor(c[0], c[1], c[2])
}

/// The principal offsets in the order the CLI lists them and `motif retarget --steps U,V,W`
/// counts them (by model axis, [`OffsetAnalysis::axis_order`]): `(number, index into
/// analysis.principal)`. The picture numbers them the same way (`p0`, `p1`, `p2`), so a step
/// count read off the picture grows the axis it names.
pub fn principal_numbering(analysis: &OffsetAnalysis) -> Vec<(usize, usize)> {
    let n = analysis.principal.len();
    let valid = analysis.axis_order.len() == n && {
        let mut seen = analysis.axis_order.clone();
        seen.sort_unstable();
        seen.iter().copied().eq(0..n)
    };
    if valid {
        analysis.axis_order.iter().copied().enumerate().collect()
    } else {
        (0..n).map(|k| (k, k)).collect()
    }
}

/// Colour of principal offset number `i` (grey when the verdict is "no repetition": the offsets
/// were found but rejected).
fn principal_colour(analysis: &OffsetAnalysis, i: usize) -> RGBColor {
    if no_repetition(analysis) {
        RGBColor(150, 150, 150)
    } else {
        PRINCIPAL_COLOURS[i % PRINCIPAL_COLOURS.len()]
    }
}

/// Splits `text` into lines of at most `width` characters at spaces.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > width {
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

/// Colours of the principal offsets' arrows.
const PRINCIPAL_COLOURS: [RGBColor; 3] =
    [RGBColor(0, 110, 200), RGBColor(0, 150, 60), RGBColor(150, 60, 200)];

/// Draws the offset picture of `analysis` to `path` (PNG, 1500 × 1000 pixels; 1500 × 820 when
/// the offsets lie in one plane).
pub fn plot_offsets(analysis: &OffsetAnalysis, title: &str, path: &Path) -> Result<()> {
    let line = line_axis(analysis);
    let plane = if line.is_none() { plane_axes(analysis) } else { None };
    let size = if plane.is_some() { (1500, 820) } else { (1500, 1000) };
    render_png(path, size, |root| {
        let (top, bottom) = root.split_vertically(560);
        let h = analysis.bin_size;
        // Symmetric extent covering every bin and principal offset, at least 0.5.
        let mut extent: f64 = 0.5;
        for b in &analysis.histogram {
            for c in b.index {
                extent = extent.max((c.abs() as f64 + 0.5) * h);
            }
        }
        for p in &analysis.principal {
            for c in p.offset {
                extent = extent.max(c.abs());
            }
        }
        let extent = extent * 1.05;
        // Offsets along one line (a fence, a row of columns): the three projections would show
        // that line twice and a dot, so one profile along it is drawn instead.
        if let Some(a) = line {
            draw_profile(&top, analysis, a, extent, path)?;
            // The profile's heights are its counts: no colour bar.
            return draw_summary(&bottom, analysis, title, None, path);
        }
        // Offsets in one plane (a shelf, a facade): the two projections across the plane would
        // each show a line, so the plane alone is drawn, large, with the bars and the text beside.
        if let Some((a, b)) = plane {
            // 813 pixels high leaves a square of 730 pixels for the plot under the caption.
            let (left, right) = root.split_horizontally(800);
            let (square, _) = left.split_vertically(813);
            let name = ["X", "Y", "Z"];
            let flat = 3 - a - b;
            let within = 100.0 * (1.0 - off_axis_shares(analysis)[flat]);
            let within = if within > 99.95 { "all".to_string() } else { format!("{within:.1}%") };
            let caption = format!(
                "offsets on the {}{} plane ({within} within a bin of it; bin {}, log colour)",
                name[a], name[b], analysis.bin_size
            );
            let cells = projected_cells(analysis, a, b);
            let heat_max = cells.values().copied().fold(1.0, f64::max);
            draw_projection(&square, analysis, a, b, &cells, heat_max, &caption, extent, None, path)?;
            let (bars, text) = right.split_vertically(400);
            draw_bars(&bars, analysis, path)?;
            return draw_text(&text, analysis, title, Some(heat_max), path);
        }
        let panels = top.split_evenly((1, 3));
        let axes = [(0usize, 1usize, "XY"), (0, 2, "XZ"), (1, 2, "YZ")];
        // One colour scale for the three, so that a colour reads the same count in each.
        let cells = axes.map(|(a, b, _)| projected_cells(analysis, a, b));
        let heat_max = cells.iter().flat_map(|c| c.values().copied()).fold(1.0, f64::max);
        for ((panel, &(a, b, name)), cells) in panels.iter().zip(axes.iter()).zip(&cells) {
            let caption = format!("offsets projected on {name} (bin {}, log colour)", analysis.bin_size);
            let tau = analysis.parameters.tau;
            draw_projection(panel, analysis, a, b, cells, heat_max, &caption, extent, Some(tau), path)?;
        }
        draw_summary(&bottom, analysis, title, Some(heat_max), path)
    })
}

/// Colour of a dominant offset's circle: blue when it refined to a repetition, grey otherwise;
/// a darker grey for those that refined when the verdict is "no repetition", since nothing was
/// kept then (blue circles suggested a structure the verdict denies).
fn dominant_colour(analysis: &OffsetAnalysis, status: DominantStatus) -> RGBColor {
    match status {
        DominantStatus::Accepted if no_repetition(analysis) => RGBColor(90, 90, 90),
        DominantStatus::Accepted => RGBColor(0, 90, 200),
        _ => REJECTED_PEAK,
    }
}

/// A rejected peak's ring; its number is drawn darker ([`peak_marks`]).
const REJECTED_PEAK: RGBColor = RGBColor(140, 140, 140);

/// Secondary text: the colour bar's caption and the text panel's notes.
const NOTE_GREY: RGBColor = RGBColor(80, 80, 80);

fn no_repetition(analysis: &OffsetAnalysis) -> bool {
    analysis.repetition.kind == crate::offsets::Repetition::NoRepetition
}

/// The dominant offsets' rings, at `at(d, ±1)` (both signs: `v` and `−v` are one repetition),
/// and each one's number (as the bar chart numbers it) beside its positive ring (`label_at` of
/// its position), unless a stronger peak's number is already there: `apart(p, q)` says whether
/// numbers at `p` and `q` leave each other readable. (Only the first eight were numbered
/// before, and the bars past 7 had no ring to point to.) Each number stands on a white ground,
/// `ground(p, chars)` (the corners of a number of `chars` characters whose top left is at `p`),
/// so that dense heat does not hide it (the bunny's grey numbers were unreadable over it), and
/// is drawn darker than a grey ring.
#[allow(clippy::type_complexity)]
fn peak_marks(
    analysis: &OffsetAnalysis,
    at: impl Fn(&crate::offsets::DominantOffset, f64) -> (f64, f64),
    label_at: impl Fn((f64, f64)) -> (f64, f64),
    keep: impl Fn(&crate::offsets::DominantOffset) -> bool,
    apart: impl Fn((f64, f64), (f64, f64)) -> bool,
    ground: impl Fn((f64, f64), usize) -> [(f64, f64); 2],
) -> (Vec<Circle<(f64, f64), i32>>, Vec<Rectangle<(f64, f64)>>, Vec<Text<'static, (f64, f64), String>>) {
    let mut rings = Vec::new();
    let mut grounds = Vec::new();
    let mut labels = Vec::new();
    let mut placed: Vec<(f64, f64)> = Vec::new();
    for (k, d) in analysis.dominant.iter().enumerate().filter(|(_, d)| keep(d)) {
        let colour = dominant_colour(analysis, d.status);
        for s in [1.0, -1.0] {
            rings.push(Circle::new(at(d, s), 9, colour.stroke_width(2)));
        }
        let p = label_at(at(d, 1.0));
        if placed.iter().all(|&q| apart(p, q)) {
            placed.push(p);
            let text = format!("{k}");
            grounds.push(Rectangle::new(ground(p, text.len()), WHITE.mix(0.85).filled()));
            let ink = if colour == REJECTED_PEAK { RGBColor(90, 90, 90) } else { colour };
            labels.push(Text::new(text, p, (FONT, 12).into_font().color(&ink)));
        }
    }
    (rings, grounds, labels)
}

/// Where a peak's number starts (its top left), in pixels right of and above its ring's centre:
/// right of the ring (radius 9), centred on it, so that the ring does not strike through it.
const PEAK_NUMBER_AT_PX: (f64, f64) = (12.0, 6.0);

/// Pixels of a peak number's white ground per character, and its height (12-pixel text).
const PEAK_GROUND_PX: (f64, f64) = (7.5, 13.0);

/// The corners of the white ground of a peak number of `chars` characters, in pixels from the
/// number's top left (x right, y up): one pixel of margin left of and above the text.
fn peak_ground_px(chars: usize) -> [(f64, f64); 2] {
    [(-1.0, 1.0), (PEAK_GROUND_PX.0 * chars as f64 + 2.0, -PEAK_GROUND_PX.1)]
}

/// Room a peak's number needs, in pixels: two digits of 12-pixel text, with a margin.
const PEAK_LABEL_PX: (f64, f64) = (18.0, 13.0);

/// A principal offset's shaft: solid, or dashed when the verdict rejected it (solid is one dash
/// longer than any picture).
fn shaft<C: Clone>(
    points: Vec<C>,
    rejected: bool,
    colour: RGBColor,
) -> plotters::element::DashedPathElement<std::vec::IntoIter<C>, i32> {
    let dash = if rejected { 8 } else { 100_000 };
    plotters::element::DashedPathElement::new(points, dash, 6, colour.stroke_width(3))
}

/// The axis the offsets lie along when all but 2% of their mass lies within one bin of it on
/// both other axes, and every principal offset runs along it (as close); `None` otherwise.
pub fn line_axis(analysis: &OffsetAnalysis) -> Option<usize> {
    let flat = flat_axes(analysis)?;
    let a = (0..3).find(|&k| !flat[k])?;
    let along = (0..3).filter(|&k| k != a).all(|k| flat[k]);
    (along && principal_within(analysis, &flat)).then_some(a)
}

/// The two axes of the plane the offsets lie in (in axis order) when all but 2% of their mass
/// lies within one bin of it on the third axis, the offsets do not also lie along a line
/// ([`line_axis`]), and every principal offset lies in the plane (as close); `None` otherwise.
/// Off the plane of their cells: the generated shelf 0.35% (14% one bin off, its depth), the
/// facade 0%, the OpenSCAD fence 0% across and 18% along its posts' height (drawn as the XZ
/// plane); the gridbeam shelf, heat sink, cheese and Kiva pod are not flat on any axis.
pub fn plane_axes(analysis: &OffsetAnalysis) -> Option<(usize, usize)> {
    let flat = flat_axes(analysis)?;
    if flat.iter().filter(|&&f| f).count() != 1 || !principal_within(analysis, &flat) {
        return None;
    }
    let mut free = (0..3).filter(|&k| !flat[k]);
    Some((free.next()?, free.next()?))
}

/// Per axis, the share of the offsets' mass more than one bin off 0 along that axis (bin
/// index 2 or more away; all zeros for an empty histogram).
fn off_axis_shares(analysis: &OffsetAnalysis) -> [f64; 3] {
    let total: f64 = analysis.histogram.iter().map(|b| b.count as f64).sum();
    if total <= 0.0 {
        return [0.0; 3];
    }
    [0, 1, 2].map(|k| {
        analysis.histogram.iter().filter(|b| b.index[k].abs() >= 2).map(|b| b.count as f64).sum::<f64>()
            / total
    })
}

/// Which axes the offsets are flat along (all but [`FLAT_SPREAD`] of their mass within one bin
/// of 0); `None` for an empty histogram.
fn flat_axes(analysis: &OffsetAnalysis) -> Option<[bool; 3]> {
    if analysis.histogram.iter().all(|b| b.count == 0) {
        return None;
    }
    Some(off_axis_shares(analysis).map(|s| s <= FLAT_SPREAD))
}

/// Whether every principal offset is within 1.5 bins (the reach of bin index ±1) of 0 along
/// each flat axis.
fn principal_within(analysis: &OffsetAnalysis, flat: &[bool; 3]) -> bool {
    analysis
        .principal
        .iter()
        .all(|p| (0..3).filter(|&k| flat[k]).all(|k| p.offset[k].abs() < 1.5 * analysis.bin_size))
}

/// Share of the offsets that may lie off a line or plane for [`line_axis`] and [`plane_axes`]
/// to call it one (the generated fence: none of its offsets is more than a bin off its length;
/// the shelf 0.35% off its plane).
const FLAT_SPREAD: f64 = 0.02;

/// The histogram of offsets along axis `a` (counts per bin, summed over the other axes, log
/// scale), with the τ band, the histogram peaks and the principal offsets: the picture for
/// offsets that all lie along one line.
fn draw_profile(
    area: &DrawingArea<TextFix<BitMapBackend<'_>>, Shift>,
    analysis: &OffsetAnalysis,
    a: usize,
    extent: f64,
    path: &Path,
) -> Result<()> {
    let axis = ["x", "y", "z"];
    let h = analysis.bin_size;
    let mut counts: std::collections::BTreeMap<i32, f64> = std::collections::BTreeMap::new();
    for bin in &analysis.histogram {
        *counts.entry(bin.index[a]).or_default() += bin.count as f64;
        if analysis.parameters.sign == crate::offsets::SignConvention::Canonical && bin.index[a] != 0 {
            *counts.entry(-bin.index[a]).or_default() += bin.count as f64;
        }
    }
    let max = counts.values().copied().fold(1.0, f64::max);
    let top = max * 4.0;
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!(
                "offsets along {} (every offset lies on this line; bin {h}, count per bin, log scale)",
                axis[a]
            ),
            (FONT, 18).into_font(),
        )
        .margin(16)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(-extent..extent, (0.8f64..top).log_scale())
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc(format!("{} (normalised)", axis[a]))
        .y_desc("offsets in the bin")
        .y_label_formatter(&|v| format!("{v:.0}"))
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    // The τ band: offsets shorter than τ are left out by eq. 4.1.
    let tau = analysis.parameters.tau;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(-tau, 0.8), (tau, top)],
            RGBColor(236, 236, 236).filled(),
        )))
        .map_err(|e| plot_err(path, e))?;
    chart
        .draw_series(std::iter::once(Text::new(
            "|v| < τ: ignored".to_string(),
            (-tau + 0.01 * extent, top / 1.6),
            (FONT, 13).into_font().color(&RGBColor(110, 110, 110)),
        )))
        .map_err(|e| plot_err(path, e))?;
    chart
        .draw_series(counts.iter().map(|(&i, &m)| {
            let x = i as f64 * h;
            Rectangle::new([(x - 0.45 * h, 0.8), (x + 0.45 * h, m)], heat(heat_level(m, max)).filled())
        }))
        .map_err(|e| plot_err(path, e))?;
    // Histogram peaks at their support's height, both signs.
    // Pixels to chart units: x linear, y logarithmic from 0.8 to `top`.
    let (pw, ph) = chart.plotting_area().dim_in_pixel();
    let (x_px, log_px) = (2.0 * extent / pw.max(1) as f64, (top / 0.8).ln() / ph.max(1) as f64);
    let (x_gap, log_gap) = (PEAK_LABEL_PX.0 * x_px, PEAK_LABEL_PX.1 * log_px);
    let (rings, grounds, labels) = peak_marks(
        analysis,
        |d, s| (s * d.offset[a], (d.peak.support as f64).max(1.0)),
        |p| (p.0 + PEAK_NUMBER_AT_PX.0 * x_px, p.1 * (PEAK_NUMBER_AT_PX.1 * log_px).exp()),
        |_| true,
        |p, q| (p.0 - q.0).abs() >= x_gap || (p.1 / q.1).ln().abs() >= log_gap,
        |p, chars| peak_ground_px(chars).map(|(dx, dy)| (p.0 + dx * x_px, p.1 * (dy * log_px).exp())),
    );
    chart.draw_series(grounds).map_err(|e| plot_err(path, e))?;
    chart.draw_series(rings).map_err(|e| plot_err(path, e))?;
    chart.draw_series(labels).map_err(|e| plot_err(path, e))?;
    // Principal offsets: a line from the origin to each, at the top, labelled.
    let rejected = no_repetition(analysis);
    for (row, (i, k)) in principal_numbering(analysis).into_iter().enumerate() {
        let p = &analysis.principal[k];
        let colour = principal_colour(analysis, i);
        let x = p.offset[a];
        let y = top / (1.5 * 1.4f64.powi(row as i32));
        chart
            .draw_series(std::iter::once(shaft(vec![(0.0, y), (x, y)], rejected, colour)))
            .map_err(|e| plot_err(path, e))?;
        chart
            .draw_series(std::iter::once(Circle::new((x, y), 5, colour.filled())))
            .map_err(|e| plot_err(path, e))?;
        chart
            .draw_series(std::iter::once(Text::new(
                format!("p{i}{} ({})", if rejected { " rejected" } else { "" }, p.support),
                (x + 0.015 * extent * x.signum(), y * 1.12),
                (FONT, 15).into_font().style(FontStyle::Bold).color(&colour),
            )))
            .map_err(|e| plot_err(path, e))?;
    }
    Ok(())
}

/// The (point-symmetric) histogram projected on the plane of axes `a` and `b`: offsets per
/// projected bin, summed along the third axis.
fn projected_cells(
    analysis: &OffsetAnalysis,
    a: usize,
    b: usize,
) -> std::collections::HashMap<(i32, i32), f64> {
    let mut cells = std::collections::HashMap::new();
    for bin in &analysis.histogram {
        let (i, j) = (bin.index[a], bin.index[b]);
        *cells.entry((i, j)).or_default() += bin.count as f64;
        if analysis.parameters.sign == crate::offsets::SignConvention::Canonical {
            *cells.entry((-i, -j)).or_default() += bin.count as f64;
        }
    }
    cells
}

/// Where `count` falls on the heat scale whose darkest colour is `max` offsets: log(1 + count) /
/// log(1 + max), so that one offset is already visible and the peaks do not wash out the rest.
fn heat_level(count: f64, max: f64) -> f64 {
    (1.0 + count).ln() / (1.0 + max.max(1.0)).ln()
}

/// Width of the colour bar, in pixels.
const COLOUR_BAR_WIDTH: i32 = 260;
/// Height of the colour bar with its tick labels, in pixels.
const COLOUR_BAR_HEIGHT: i32 = 36;

/// A horizontal colour bar of the heat scale whose top is `max` offsets per bin, with its
/// top-left corner at `at`, ticks at 1, 10, 100, … and at `max`, and a caption on its right or,
/// with `caption_above`, above it.
fn draw_colour_bar(
    area: &DrawingArea<TextFix<BitMapBackend<'_>>, Shift>,
    max: f64,
    at: (i32, i32),
    caption_above: bool,
    path: &Path,
) -> Result<()> {
    let (x0, y0) = at;
    let (width, height) = (COLOUR_BAR_WIDTH, 12);
    // Pixel column k shows the colour of the count whose level is k / (width − 1).
    for k in 0..width {
        let t = k as f64 / (width - 1).max(1) as f64;
        area.draw(&Rectangle::new([(x0 + k, y0), (x0 + k + 1, y0 + height)], heat(t).filled()))
            .map_err(|e| plot_err(path, e))?;
    }
    // The frame one pixel outside the colours, so that both ends' colours stay visible.
    area.draw(&Rectangle::new([(x0 - 1, y0 - 1), (x0 + width, y0 + height)], NOTE_GREY.stroke_width(1)))
        .map_err(|e| plot_err(path, e))?;
    let x_of = |count: f64| x0 + (heat_level(count, max) * (width - 1) as f64).round() as i32;
    let label = |count: f64| format!("{count:.0}");
    let label_width = |count: f64| motif_core::plotting::text_width(&label(count), 12.0, FontStyle::Normal);
    let mut ticks: Vec<f64> =
        std::iter::successors(Some(1.0), |t| Some(t * 10.0)).take_while(|&t| t < max).collect();
    // The top's own tick, in place of the last power of ten's when their labels would touch.
    if let Some(&t) = ticks.last()
        && f64::from(x_of(max) - x_of(t)) < 0.5 * (label_width(t) + label_width(max)) + 8.0
    {
        ticks.pop();
    }
    ticks.push(max);
    let font = (FONT, 12).into_font().color(&NOTE_GREY);
    for t in ticks {
        let x = x_of(t);
        area.draw(&PathElement::new(vec![(x, y0 + height), (x, y0 + height + 4)], NOTE_GREY.stroke_width(1)))
            .map_err(|e| plot_err(path, e))?;
        let w = label_width(t).round() as i32;
        area.draw(&Text::new(label(t), (x - w / 2, y0 + height + 6), font.clone()))
            .map_err(|e| plot_err(path, e))?;
    }
    let caption_at = if caption_above { (x0, y0 - 17) } else { (x0 + width + 12, y0 - 1) };
    area.draw(&Text::new("offsets per projected bin (log colour scale)".to_string(), caption_at, font))
        .map_err(|e| plot_err(path, e))?;
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn draw_projection(
    area: &DrawingArea<TextFix<BitMapBackend<'_>>, Shift>,
    analysis: &OffsetAnalysis,
    a: usize,
    b: usize,
    cells: &std::collections::HashMap<(i32, i32), f64>,
    heat_max: f64,
    caption: &str,
    extent: f64,
    ring_slab: Option<f64>,
    path: &Path,
) -> Result<()> {
    let axis = ["x", "y", "z"];
    let h = analysis.bin_size;
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 18).into_font())
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(46)
        .build_cartesian_2d(-extent..extent, -extent..extent)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc(format!("{} (normalised)", axis[a]))
        .y_desc(format!("{} (normalised)", axis[b]))
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    chart
        .draw_series(cells.iter().map(|(&(i, j), &m)| {
            let t = heat_level(m, heat_max);
            let (x, y) = (i as f64 * h, j as f64 * h);
            Rectangle::new([(x - 0.5 * h, y - 0.5 * h), (x + 0.5 * h, y + 0.5 * h)], heat(t).filled())
        }))
        .map_err(|e| plot_err(path, e))?;
    // τ circle: offsets inside it are excluded by eq. 4.1.
    let tau = analysis.parameters.tau;
    let circle: Vec<(f64, f64)> = (0..=72)
        .map(|k| {
            let t = k as f64 / 72.0 * std::f64::consts::TAU;
            (tau * t.cos(), tau * t.sin())
        })
        .collect();
    chart
        .draw_series(std::iter::once(PathElement::new(circle, RGBColor(150, 150, 150).stroke_width(1))))
        .map_err(|e| plot_err(path, e))?;
    // Dominant offsets.
    let (pw, ph) = chart.plotting_area().dim_in_pixel();
    let per = (2.0 * extent / pw.max(1) as f64, 2.0 * extent / ph.max(1) as f64);
    let gap = (PEAK_LABEL_PX.0 * per.0, PEAK_LABEL_PX.1 * per.1);
    let (rings, grounds, labels) = peak_marks(
        analysis,
        |d, s| (s * d.offset[a], s * d.offset[b]),
        |p| (p.0 + PEAK_NUMBER_AT_PX.0 * per.0, p.1 + PEAK_NUMBER_AT_PX.1 * per.1),
        // In the three projections, a peak is circled in those whose plane it lies near: the
        // heat sink's XZ and YZ views showed a chain of 25 rings, the XY view's peaks projected.
        |d| ring_slab.is_none_or(|slab| d.offset[3 - a - b].abs() <= slab),
        |p, q| (p.0 - q.0).abs() >= gap.0 || (p.1 - q.1).abs() >= gap.1,
        |p, chars| peak_ground_px(chars).map(|(dx, dy)| (p.0 + dx * per.0, p.1 + dy * per.1)),
    );
    chart.draw_series(grounds).map_err(|e| plot_err(path, e))?;
    chart.draw_series(rings).map_err(|e| plot_err(path, e))?;
    chart.draw_series(labels).map_err(|e| plot_err(path, e))?;
    // Principal offsets as arrows (dashed when the verdict rejected them).
    let rejected = no_repetition(analysis);
    // Label boxes placed so far ([x0, y0, x1, y1] in chart units), so that no label covers
    // another (the shelf's p1 label, left of its arrow, covered the start of p0's above its).
    let mut placed: Vec<[f64; 4]> = Vec::new();
    for (i, k) in principal_numbering(analysis) {
        let p = &analysis.principal[k];
        let colour = principal_colour(analysis, i);
        let (x, y) = (p.offset[a], p.offset[b]);
        let len = (x * x + y * y).sqrt();
        if len < 1e-3 * extent {
            // Perpendicular to this view: a dot.
            chart
                .draw_series(std::iter::once(Circle::new((0.0, 0.0), 5, colour.filled())))
                .map_err(|e| plot_err(path, e))?;
            continue;
        }
        let head = 0.06 * extent;
        let (ux, uy) = (x / len, y / len);
        let back = (x - head * ux, y - head * uy);
        let left = (back.0 - 0.45 * head * uy, back.1 + 0.45 * head * ux);
        let right = (back.0 + 0.45 * head * uy, back.1 - 0.45 * head * ux);
        chart
            .draw_series(std::iter::once(shaft(vec![(0.0, 0.0), (x, y)], rejected, colour)))
            .map_err(|e| plot_err(path, e))?;
        chart
            .draw_series(std::iter::once(Polygon::new(vec![(x, y), left, right], colour.filled())))
            .map_err(|e| plot_err(path, e))?;
        // The label beside the arrow's middle, on its left (between the origin and the first
        // peak, where no peak circle is), on a white ground so that bins do not strike through;
        // further along the arrow, or on its right, where that box would cover an earlier label.
        let label = format!("p{i}{} ({})", if rejected { " rejected" } else { "" }, p.support);
        let (pw, ph) = chart.plotting_area().dim_in_pixel();
        let per_px = (2.0 * extent / pw as f64, 2.0 * extent / ph as f64);
        let (tw, th) = (
            motif_core::plotting::text_width(&label, 15.0, plotters::style::FontStyle::Bold) * per_px.0,
            16.0 * per_px.1,
        );
        let pad = (3.0 * per_px.0, 2.0 * per_px.1);
        let candidate = |t: f64, side: f64| {
            // `side` 1: left of the arrow's direction, far enough that the box clears the shaft.
            let (nx, ny) = (-uy * side, ux * side);
            let (mx, my) = (
                t * x + nx * (0.03 * extent + 0.5 * tw.max(th) * nx.abs()),
                t * y + ny * (0.03 * extent + 0.5 * th),
            );
            [mx - 0.5 * tw - pad.0, my - 0.5 * th - pad.1, mx + 0.5 * tw + pad.0, my + 0.5 * th + pad.1]
        };
        let overlaps =
            |r: &[f64; 4]| placed.iter().any(|q| r[0] < q[2] && q[0] < r[2] && r[1] < q[3] && q[1] < r[3]);
        // Beside the shaft first; beyond the head only when a short arrow leaves no room there
        // (the stadium's p1, a quarter of p0's label long, covered that label).
        let spots = [
            (0.5, 1.0),
            (0.75, 1.0),
            (0.5, -1.0),
            (0.75, -1.0),
            (0.25, 1.0),
            (0.25, -1.0),
            (1.0, 1.0),
            (1.0, -1.0),
            (1.4, 1.0),
            (1.4, -1.0),
            (1.8, 1.0),
            (1.8, -1.0),
        ];
        let chosen = spots
            .iter()
            .map(|&(t, side)| candidate(t, side))
            .find(|r| !overlaps(r))
            .unwrap_or(candidate(0.5, 1.0));
        placed.push(chosen);
        let (lx, ly) = (chosen[0] + pad.0, chosen[3] - pad.1);
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(chosen[0], chosen[3]), (chosen[2], chosen[1])],
                RGBColor(255, 255, 255).filled(),
            )))
            .map_err(|e| plot_err(path, e))?;
        chart
            .draw_series(std::iter::once(Text::new(
                label,
                (lx, ly),
                (FONT, 15).into_font().style(FontStyle::Bold).color(&colour),
            )))
            .map_err(|e| plot_err(path, e))?;
    }
    Ok(())
}

/// The bar chart of the dominant offsets' support (left) and the verdict with the principal
/// offsets in model units and, given the heat scale's top, its colour bar (right), side by side
/// in `area`.
fn draw_summary(
    area: &DrawingArea<TextFix<BitMapBackend<'_>>, Shift>,
    analysis: &OffsetAnalysis,
    title: &str,
    heat_max: Option<f64>,
    path: &Path,
) -> Result<()> {
    let (bars, text) = area.split_horizontally(820);
    draw_bars(&bars, analysis, path)?;
    draw_text(&text, analysis, title, heat_max, path)
}

/// The bar chart of the dominant offsets' support, principal ones highlighted and rejected ones
/// marked with the reason.
fn draw_bars(
    bars: &DrawingArea<TextFix<BitMapBackend<'_>>, Shift>,
    analysis: &OffsetAnalysis,
    path: &Path,
) -> Result<()> {
    let n = analysis.dominant.len().max(1);
    let max = analysis.dominant.iter().map(|d| d.peak.support).max().unwrap_or(1).max(1) as f64;
    let mut chart = ChartBuilder::on(bars)
        .caption("support of the dominant offsets (histogram peaks, strongest first)", (FONT, 18).into_font())
        .margin(14)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(-0.5..(n as f64 - 0.5), 0.0..max * 1.15)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_desc("dominant offset #")
        .y_desc("offsets in the peak's 3×3×3 bins")
        .x_labels(n.min(20))
        .x_label_formatter(&|x| format!("{:.0}", x))
        .y_label_formatter(&|y| format!("{:.0}", y))
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    let numbered = principal_numbering(analysis);
    for (k, d) in analysis.dominant.iter().enumerate() {
        let principal = numbered.iter().find(|&&(_, j)| analysis.principal[j].dominant == k).map(|&(i, _)| i);
        // The peak a principal offset was selected on, when the period reduction replaced it by
        // its generator (p = peak / multiple): labelled as that multiple of p.
        let multiple_of = numbered
            .iter()
            .find(|&&(_, j)| {
                let q = &analysis.principal[j];
                q.selected == k && q.dominant != k && q.multiple > 1
            })
            .map(|&(i, j)| (i, analysis.principal[j].multiple));
        let colour = match (principal, d.status) {
            (Some(p), _) => principal_colour(analysis, p),
            (None, DominantStatus::Accepted) if no_repetition(analysis) => RGBColor(170, 170, 170),
            (None, DominantStatus::Accepted) => RGBColor(150, 180, 220),
            _ => RGBColor(200, 200, 200),
        };
        let x = k as f64;
        let y = d.peak.support as f64;
        chart
            .draw_series(std::iter::once(Rectangle::new([(x - 0.38, 0.0), (x + 0.38, y)], colour.filled())))
            .map_err(|e| plot_err(path, e))?;
        let label = match (principal, d.status) {
            // A pitch below τ is the peak divided: the peak is that many pitches long.
            (Some(p), _) => {
                match numbered.iter().find(|&&(i, _)| i == p).map(|&(_, j)| analysis.principal[j].divisor) {
                    Some(n) if n > 1 => format!("{n}·p{p}"),
                    _ => format!("p{p}"),
                }
            }
            (None, _) if multiple_of.is_some() => {
                let (p, m) = multiple_of.unwrap_or_default();
                format!("{m}·p{p}")
            }
            (None, DominantStatus::Accepted) => String::new(),
            (None, DominantStatus::Collapsed) => "col".into(),
            (None, DominantStatus::Drifted) => "dri".into(),
            (None, DominantStatus::LowOverlap) => "low".into(),
            (None, DominantStatus::NoOverlap) => "none".into(),
            (None, DominantStatus::Duplicate { .. }) => "dup".into(),
        };
        if !label.is_empty() {
            chart
                .draw_series(std::iter::once(Text::new(
                    label,
                    (x - 0.35, y + 0.035 * max),
                    (FONT, 13).into_font().color(&match (principal, multiple_of) {
                        (Some(_), _) => colour,
                        (None, Some((p, _))) => principal_colour(analysis, p),
                        (None, None) => RGBColor(90, 90, 90),
                    }),
                )))
                .map_err(|e| plot_err(path, e))?;
        }
    }

    Ok(())
}

/// The verdict, the principal offsets in model units, how to read the picture and the timings.
fn draw_text(
    text: &DrawingArea<TextFix<BitMapBackend<'_>>, Shift>,
    analysis: &OffsetAnalysis,
    title: &str,
    heat_max: Option<f64>,
    path: &Path,
) -> Result<()> {
    let total = analysis.counts.offsets.max(1) as f64;
    let font = |s: u32| (FONT, s).into_font();
    let mut lines: Vec<(String, u32, RGBColor)> = vec![(title.to_string(), 20, BLACK)];
    let rep = &analysis.repetition;
    let verdict = match rep.kind {
        crate::offsets::Repetition::Repetitive => ("REPETITIVE", RGBColor(0, 130, 60)),
        crate::offsets::Repetition::NoRepetition => ("NO REPETITION", RGBColor(190, 40, 40)),
    };
    lines.push((verdict.0.to_string(), 20, verdict.1));
    lines.push((
        format!(
            "{} offsets in {} bins; top peak {:.1}% ({:.1}× flat)",
            analysis.counts.offsets,
            analysis.counts.bins,
            100.0 * rep.top_peak_share,
            rep.concentration
        ),
        14,
        BLACK,
    ));
    if rep.kind == crate::offsets::Repetition::NoRepetition {
        for l in wrap(&rep.summary, 88) {
            lines.push((l, 13, verdict.1));
        }
    }
    // Four decimals, as the CLI prints, without "-0.0000".
    let num = |v: f64| format!("{:.4}", if v.abs() < 5e-5 { 0.0 } else { v });
    for (i, k) in principal_numbering(analysis) {
        let p = &analysis.principal[k];
        let m = p.offset_model;
        let mut s = format!(
            "p{i} = ({}, {}, {})  |v| = {}  support {} ({:.1}%)",
            num(m[0]),
            num(m[1]),
            num(m[2]),
            num(p.length_model),
            p.support,
            100.0 * p.support as f64 / total
        );
        if p.multiple > 1 {
            // The greedy selection chose peak `selected`; its generator, peak `dominant`, is p.
            s += &format!("  (peak #{} / {}, at peak #{})", p.selected, p.multiple, p.dominant);
        }
        if p.divisor > 1 {
            s += &format!("  (peak #{} / {}: a pitch shorter than τ)", p.dominant, p.divisor);
        }
        lines.push((s, 14, principal_colour(analysis, i)));
        let mut detail = format!(
            "      shifted by it, {:.0}% of the surface lands on itself; contrast {:+.0} points",
            100.0 * p.overlap,
            100.0 * p.contrast
        );
        // A rejected model's verdict already says why (continuous symmetry or partial match).
        // The contrast compares v with v / 2 and 3v / 2 (see `refine`).
        let finer = (p.contrast < 0.0 && !no_repetition(analysis)).then_some(
            "      (half or 1.5× of it maps more edges and corners: a finer pattern inside the period)",
        );
        if p.length_model * analysis.normalisation.scale < analysis.bin_size {
            detail += " (shorter than a bin: a dot at the centre)";
        }
        lines.push((detail, 13, NOTE_GREY));
        if let Some(f) = finer {
            lines.push((f.into(), 13, NOTE_GREY));
        }
    }
    if analysis.principal.is_empty() {
        lines.push(("no principal offset".into(), 14, BLACK));
    } else if rep.kind == crate::offsets::Repetition::Repetitive {
        lines.push((
            format!(
                "motif retarget --steps counts cells along {}, in that order",
                (0..analysis.principal.len()).map(|i| format!("p{i}")).collect::<Vec<_>>().join(", ")
            ),
            13,
            NOTE_GREY,
        ));
    }
    lines.push((
        if no_repetition(analysis) {
            "How to read it: heat = offsets per bin (log scale); circles = histogram peaks, dark: none kept;"
        } else {
            "How to read it: heat = offsets per bin (log scale); circles = histogram peaks, blue: kept;"
        }
        .into(),
        13,
        NOTE_GREY,
    ));
    lines.push((
        "grey: rejected, marked col (collapsed to 0 under ICP), dri (drifted), dup (a repeat),".into(),
        13,
        NOTE_GREY,
    ));
    let tau_mark =
        if line_axis(analysis).is_some() { "grey band = |v| < τ" } else { "thin circle = |v| = τ" };
    lines.push((
        format!("low / none (too little / no surface overlap); {tau_mark}, offsets inside are ignored"),
        13,
        NOTE_GREY,
    ));
    if line_axis(analysis).is_none() && plane_axes(analysis).is_none() {
        lines.push((
            "each projection circles the peaks within τ of its plane; the bars show them all".into(),
            13,
            NOTE_GREY,
        ));
    }
    let t = &analysis.timings;
    lines.push((
        format!("model units; normalised = {:.4} x (model - centre)", analysis.normalisation.scale),
        13,
        NOTE_GREY,
    ));
    lines.push((
        format!(
            "{} dense, {} features; {:.2} s (sample {:.2}, SHOT {:.2}, match {:.2}, ICP {:.2})",
            analysis.counts.dense,
            analysis.counts.features,
            t.total_ms / 1e3,
            t.sampling_ms / 1e3,
            t.shot_ms / 1e3,
            t.matching_ms / 1e3,
            t.refinement_ms / 1e3
        ),
        13,
        NOTE_GREY,
    ));
    let mut y = 20;
    for (s, size, colour) in lines {
        text.draw(&Text::new(s, (10, y), font(size).color(&colour))).map_err(|e| plot_err(path, e))?;
        y += size as i32 + 7;
    }
    if let Some(max) = heat_max {
        // Under the text, captioned on its right; when the text leaves no room there (three
        // principal offsets with notes under a wrapped verdict), at the top right under the
        // title, captioned above, where the verdict and the counts are short.
        let (w, h) = text.dim_in_pixel();
        let (w, h) = (w as i32, h as i32);
        if y + 6 + COLOUR_BAR_HEIGHT <= h {
            draw_colour_bar(text, max, (10, y + 6), false, path)?;
        } else {
            draw_colour_bar(text, max, (w - COLOUR_BAR_WIDTH - 20, 62), true, path)?;
        }
    }
    Ok(())
}

/// Draws the sparsity study's cumulative curves to `path` (PNG, 1400 × 620 pixels): offsets
/// share against bin share per category (solid man-made, dashed natural, dotted unknown) and τ
/// (colour), with the uniform diagonal, in full and zoomed to the first 20% of the bins (like the
/// thesis's Fig. 4.5).
pub fn plot_sparsity(report: &SparsityReport, path: &Path) -> Result<()> {
    render_png(path, (1400, 620), |root| {
        let (left, right) = root.split_horizontally(700);
        draw_curves(
            &left,
            report,
            1.0,
            "(a) offsets in the largest bins, category means (×: thesis, τ = 0.15)",
            path,
        )?;
        draw_curves(&right, report, 0.2, "(b) zoom-in: the first 20% of the bins (legend in (a))", path)
    })
}

const TAU_COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(120, 120, 120),
];

fn draw_curves(
    area: &DrawingArea<TextFix<BitMapBackend<'_>>, Shift>,
    report: &SparsityReport,
    xmax: f64,
    caption: &str,
    path: &Path,
) -> Result<()> {
    // The zoom reaches a little past its last bin share, so the thesis's marker at 20% is drawn
    // whole.
    let xhi = if xmax < 1.0 { xmax * 105.0 } else { 100.0 };
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 18).into_font())
        .margin(14)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..xhi, 0.0..100.0)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("bins, largest first (% of non-empty bins)")
        .y_desc("offsets (%)")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.0}"))
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    chart
        .draw_series(LineSeries::new(vec![(0.0, 0.0), (xhi, xhi)], RGBColor(170, 170, 170).stroke_width(2)))
        .map_err(|e| plot_err(path, e))?
        .label("uniform")
        .legend(|(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], RGBColor(170, 170, 170).stroke_width(2))
        });
    let n = report.options.curve_points;
    for c in &report.categories {
        for (k, t) in c.per_tau.iter().enumerate() {
            let colour = TAU_COLOURS[k % TAU_COLOURS.len()];
            let pts: Vec<(f64, f64)> = t
                .curve
                .iter()
                .enumerate()
                .map(|(i, &y)| (100.0 * i as f64 / (n - 1) as f64, 100.0 * y))
                .filter(|&(x, _)| x <= xmax * 100.0 + 1e-9)
                .collect();
            let label = format!("{} ({}), τ = {}", c.category.as_str(), c.models, t.tau);
            let width = if (t.tau - 0.15).abs() < 1e-9 { 4 } else { 2 };
            let style = colour.stroke_width(width);
            match c.category {
                Category::ManMade => {
                    chart
                        .draw_series(LineSeries::new(pts, style))
                        .map_err(|e| plot_err(path, e))?
                        .label(label)
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
                }
                Category::Natural | Category::Unknown => {
                    let (dash, gap): (i32, i32) =
                        if c.category == Category::Natural { (8, 5) } else { (2, 4) };
                    chart
                        .draw_series(DashedLineSeries::new(pts, dash, gap, style))
                        .map_err(|e| plot_err(path, e))?
                        .label(label)
                        .legend(move |(x, y)| {
                            EmptyElement::at((x, y))
                                + PathElement::new(vec![(0, 0), (dash, 0)], style)
                                + PathElement::new(vec![(dash + gap, 0), (20, 0)], style)
                        });
                }
            }
        }
    }
    // The thesis's numbers as black crosses and, in the zoom, Motif's at the same τ and bin
    // share as dots, each labelled with its share, so the comparison reads off the picture.
    let zoom = xmax < 1.0;
    for r in &report.thesis {
        if r.bins > xmax + 1e-9 {
            continue;
        }
        let at = (100.0 * r.bins, 100.0 * r.offsets);
        chart
            .draw_series(std::iter::once(Cross::new(at, 6, BLACK.stroke_width(2))))
            .map_err(|e| plot_err(path, e))?;
        if !zoom {
            continue;
        }
        let name = if r.category == Category::ManMade { "man-made" } else { "natural" };
        // Labels right of their marker, or left of it near the right edge, on a white box so
        // that the curves do not run through them: the thesis's below its cross, Motif's above
        // its dot (the two are a few points apart for the natural models).
        let right_edge = at.0 > 0.7 * xhi;
        let (pw, ph) = chart.plotting_area().dim_in_pixel();
        let per_px = (xhi / pw as f64, 100.0 / ph as f64);
        let mut boxed = |text: String, corner: (f64, f64), below: bool, colour: RGBColor| -> Result<()> {
            let w =
                motif_core::plotting::text_width(&text, 12.0, plotters::style::FontStyle::Normal) * per_px.0;
            let h = 12.0 * per_px.1;
            let x0 = if right_edge { corner.0 - 0.4 - w } else { corner.0 + 0.4 };
            let top = if below { corner.1 - 1.0 } else { corner.1 + 1.5 + h };
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [
                        (x0 - 2.0 * per_px.0, top + 2.0 * per_px.1),
                        (x0 + w + 2.0 * per_px.0, top - h - 2.0 * per_px.1),
                    ],
                    WHITE.filled(),
                )))
                .map_err(|e| plot_err(path, e))?;
            chart
                .draw_series(std::iter::once(Text::new(
                    text,
                    (x0, top),
                    (FONT, 12).into_font().color(&colour),
                )))
                .map_err(|e| plot_err(path, e))?;
            Ok(())
        };
        boxed(format!("thesis {name} {:.1}%", 100.0 * r.offsets), at, true, BLACK)?;
        let measured = report.categories.iter().find(|c| c.category == r.category).and_then(|c| {
            let k = c.per_tau.iter().position(|t| (t.tau - r.tau).abs() < 1e-9)?;
            let i = report.options.read_at.iter().position(|&b| (b - r.bins).abs() < 1e-9)?;
            Some((k, *c.per_tau[k].shares.get(i)?))
        });
        if let Some((k, share)) = measured {
            let colour = TAU_COLOURS[k % TAU_COLOURS.len()];
            let dot = (100.0 * r.bins, 100.0 * share);
            boxed(format!("Motif {name} {:.1}%", 100.0 * share), dot, false, colour)?;
            chart
                .draw_series(std::iter::once(Circle::new(dot, 5, colour.filled())))
                .map_err(|e| plot_err(path, e))?;
        }
    }
    // The zoom's uniform line runs along its lower edge, under a legend there; the zoom draws
    // the same series, named by panel (a)'s legend.
    if xmax < 1.0 {
        return Ok(());
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(200, 200, 200))
        .label_font((FONT, 12))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    Ok(())
}

/// A scatter of points projected on two axes (`a`, `b` ∈ {0, 1, 2}), for looking at a model or a
/// cloud: `points` normalised or not, drawn as small dots.
pub fn plot_points(points: &[[f64; 3]], a: usize, b: usize, title: &str, path: &Path) -> Result<()> {
    render_png(path, (900, 900), |root| {
        let lo = |i: usize| points.iter().map(|p| p[i]).fold(f64::INFINITY, f64::min);
        let hi = |i: usize| points.iter().map(|p| p[i]).fold(f64::NEG_INFINITY, f64::max);
        let (xa, xb, ya, yb) = (lo(a), hi(a), lo(b), hi(b));
        let span = (xb - xa).max(yb - ya).max(1e-12) * 0.52;
        let (cx, cy) = (0.5 * (xa + xb), 0.5 * (ya + yb));
        let mut chart = ChartBuilder::on(root)
            .caption(title, (FONT, 18).into_font())
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(cx - span..cx + span, cy - span..cy + span)
            .map_err(|e| plot_err(path, e))?;
        chart.configure_mesh().label_style((FONT, 12)).draw().map_err(|e| plot_err(path, e))?;
        chart
            .draw_series(points.iter().map(|p| Circle::new((p[a], p[b]), 1, RGBColor(40, 40, 40).filled())))
            .map_err(|e| plot_err(path, e))?;
        Ok(())
    })
}

/// What [`plot_retarget_preview`] writes besides the two meshes.
#[derive(Debug, Clone, Default)]
pub struct PreviewText {
    /// First line: the model and what was asked.
    pub title: String,
    /// Lines under the title (method, nodes, labels, energy); `true` marks a warning, drawn
    /// in red (a stitching with seams of infinite cost must not look like a success).
    pub notes: Vec<(String, bool)>,
    /// Per output triangle, the copy it came from (0: copied in place); the output is coloured
    /// by copy, as thesis Fig. 4.4 c colours voxels by label, so inserted copies and seams show.
    pub output_groups: Option<Vec<u32>>,
    /// Points drawn over the meshes (the handles of a deformation: where a handle was, where
    /// it was dragged), so a reader sees what moved without reading the caption.
    pub marks: Vec<PreviewMark>,
    /// The names of the two panels in their size lines; `None`: "input" and "output".
    pub panel_names: Option<[String; 2]>,
    /// A line that replaces a panel's size line (the right panel of `motif symmetry detect
    /// --plot` holds the model and drawn elements, whose box and triangles mean nothing).
    pub panel_captions: [Option<String>; 2],
    /// Both panels framed alike (centred on the union of both), so that what did not move is
    /// drawn at the same place in each (a deformation); otherwise each panel is centred on its
    /// own mesh (a resized model is larger).
    pub shared_frame: bool,
}

/// A point drawn over one panel of [`plot_retarget_preview`]: a ring at `at` with a label, and
/// an arrow to it from `from` when given (a handle dragged from its rest position).
#[derive(Debug, Clone)]
pub struct PreviewMark {
    /// 0: the input's panel (left), 1: the output's (right).
    pub panel: usize,
    /// Position in model units.
    pub at: [f64; 3],
    /// Start of an arrow ending at `at`, in model units.
    pub from: Option<[f64; 3]>,
    /// Text beside the ring.
    pub label: String,
    /// Colour of the ring, arrow and label (RGB).
    pub colour: [u8; 3],
}

/// Colours of the copies in the preview (group 0, copied in place, is the first).
const COPY_COLOURS: [[f64; 3]; 8] = [
    [150.0, 175.0, 210.0],
    [235.0, 160.0, 90.0],
    [120.0, 195.0, 130.0],
    [215.0, 120.0, 140.0],
    [175.0, 145.0, 215.0],
    [220.0, 200.0, 100.0],
    [110.0, 190.0, 200.0],
    [190.0, 150.0, 120.0],
];

/// The camera's screen right, screen up and viewing direction for a camera looking along `view`
/// with `up` towards the top of the screen (made orthogonal to `view`). Looking along d with v
/// up, right is d × v: v × d, used until 2026-11-30, drew every model mirrored.
fn screen_axes(view: [f64; 3], up: [f64; 3]) -> Option<[[f64; 3]; 3]> {
    use motif_core::geometry::{cross, dot, normalize, sub};
    let d = normalize(view)?;
    let up = sub(up, d.map(|c| c * dot(up, d)));
    let v = normalize(up).or_else(|| normalize(cross(d, [1.0, 0.0, 0.0]))).unwrap_or([0.0, 1.0, 0.0]);
    Some([cross(d, v), v, d])
}

/// A side-by-side picture of a model before and after retargeting (`motif retarget --preview
/// PNG`): both meshes rendered with the same orthographic camera and scale by a small z-buffer
/// rasteriser (flat shading, two-sided, lit from the upper left in front, with dark outlines
/// where depth or the surface's direction jumps, so recessed frames read against their wall),
/// input on the left, output on the right coloured by the copy each part came from, each with
/// its size in model units.
///
/// `view` is the direction the camera looks along (any length), `up` the screen's up direction
/// (made orthogonal to `view`); for a facade or a shelf, look along the normal of the plane of
/// its principal offsets.
pub fn plot_retarget_preview(
    input: &motif_core::TriMesh,
    output: &motif_core::TriMesh,
    view: [f64; 3],
    up: [f64; 3],
    preview: &PreviewText,
    path: &Path,
) -> Result<()> {
    use motif_core::geometry::{cross, dot, normalize, sub};
    let [u, v, d] = screen_axes(view, up).ok_or_else(|| plot_err(path, "zero view direction"))?;
    let project = |p: [f64; 3]| (dot(p, u), dot(p, v), dot(p, d));
    // Common scale: the larger of the two meshes' screen extents fits its panel.
    let extent = |m: &motif_core::TriMesh| {
        m.positions.iter().fold(
            [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY],
            |b, &p| {
                let (x, y, _) = project(p);
                [b[0].min(x), b[1].max(x), b[2].min(y), b[3].max(y)]
            },
        )
    };
    // Each panel frames its mesh and the marks drawn on it (a handle's target off the mesh);
    // with `shared_frame` both panels frame the union, so what did not move stays in place.
    let with_marks = |mut e: [f64; 4], k: usize| {
        for m in preview.marks.iter().filter(|m| m.panel == k) {
            for p in std::iter::once(m.at).chain(m.from) {
                let (x, y, _) = project(p);
                e = [e[0].min(x), e[1].max(x), e[2].min(y), e[3].max(y)];
            }
        }
        e
    };
    let (mut ei, mut eo) = (with_marks(extent(input), 0), with_marks(extent(output), 1));
    if preview.shared_frame {
        let u = [ei[0].min(eo[0]), ei[1].max(eo[1]), ei[2].min(eo[2]), ei[3].max(eo[3])];
        (ei, eo) = (u, u);
    }
    let (panel_w, panel_h) = (700usize, 620usize);
    let top = 60 + 20 * preview.notes.len();
    let span = (ei[1] - ei[0]).max(eo[1] - eo[0]).max((ei[3] - ei[2]).max(eo[3] - eo[2]) * 700.0 / 620.0);
    if !(span.is_finite() && span > 0.0) {
        return Err(plot_err(path, "nothing to draw: the meshes are empty or degenerate"));
    }
    let scale = 0.9 * panel_w as f64 / span;
    let (w, h) = (2 * panel_w, panel_h + top);
    let mut rgb = vec![255u8; w * h * 3];
    let mut depth = vec![f64::INFINITY; w * h];
    // Unit normal (facing the camera) of the surface at each pixel, for the outlines.
    let mut normal = vec![[0.0f64; 3]; w * h];
    let light = normalize([
        -d[0] + 0.6 * v[0] - 0.4 * u[0],
        -d[1] + 0.6 * v[1] - 0.4 * u[1],
        -d[2] + 0.6 * v[2] - 0.4 * u[2],
    ])
    .unwrap_or(d.map(|c| -c));
    // Screen position of a model point in panel k (each panel centred on its own mesh).
    let panel_px = |k: usize, p: [f64; 3]| {
        let ext = if k == 0 { ei } else { eo };
        let (cx, cy) = (0.5 * (ext[0] + ext[1]), 0.5 * (ext[2] + ext[3]));
        let x0 = (k * panel_w) as f64 + 0.5 * panel_w as f64;
        let y0 = top as f64 + 0.5 * panel_h as f64;
        let (x, y, z) = project(p);
        (x0 + (x - cx) * scale, y0 - (y - cy) * scale, z)
    };
    for (k, mesh) in [input, output].into_iter().enumerate() {
        let groups = if k == 1 {
            preview.output_groups.as_deref().filter(|g| g.len() == mesh.triangles.len())
        } else {
            None
        };
        let to_px = |p: [f64; 3]| panel_px(k, p);
        for (f, t) in mesh.triangles.iter().enumerate() {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            let Some(n) = normalize(cross(sub(b, a), sub(c, a))) else { continue };
            // Two-sided: the side facing the camera (which looks along +d).
            let n = if dot(n, d) > 0.0 { n.map(|c| -c) } else { n };
            let shade = 0.35 + 0.65 * dot(n, light).max(0.0);
            let base = COPY_COLOURS[groups.map_or(0, |g| g[f] as usize) % COPY_COLOURS.len()];
            let col = base.map(|c| (c * (0.45 + 0.6 * shade)).min(255.0) as u8);
            let (pa, pb, pc) = (to_px(a), to_px(b), to_px(c));
            let area = (pb.0 - pa.0) * (pc.1 - pa.1) - (pc.0 - pa.0) * (pb.1 - pa.1);
            if area.abs() < 1e-12 {
                continue;
            }
            let xmin = pa.0.min(pb.0).min(pc.0).floor().max((k * panel_w) as f64) as usize;
            let xmax = pa.0.max(pb.0).max(pc.0).ceil().min(((k + 1) * panel_w - 1) as f64);
            let ymin = pa.1.min(pb.1).min(pc.1).floor().max(top as f64) as usize;
            let ymax = pa.1.max(pb.1).max(pc.1).ceil().min((h - 1) as f64);
            if xmax < xmin as f64 || ymax < ymin as f64 {
                continue;
            }
            for py in ymin..=ymax as usize {
                for px in xmin..=xmax as usize {
                    let (sx, sy) = (px as f64 + 0.5, py as f64 + 0.5);
                    let w0 = ((pb.0 - sx) * (pc.1 - sy) - (pc.0 - sx) * (pb.1 - sy)) / area;
                    let w1 = ((pc.0 - sx) * (pa.1 - sy) - (pa.0 - sx) * (pc.1 - sy)) / area;
                    let w2 = 1.0 - w0 - w1;
                    if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                        continue;
                    }
                    let z = w0 * pa.2 + w1 * pb.2 + w2 * pc.2;
                    let i = py * w + px;
                    if z < depth[i] {
                        depth[i] = z;
                        normal[i] = n;
                        rgb[3 * i..3 * i + 3].copy_from_slice(&col);
                    }
                }
            }
        }
    }
    // Outlines: a covered pixel whose right or lower neighbour is empty, lies deeper or nearer
    // by more than 1% of the picture's span, or faces another way (more than about 35°).
    let jump = 0.01 * span;
    let mut edge = vec![false; w * h];
    for py in top..h {
        for px in 0..w {
            let i = py * w + px;
            for j in [(px + 1 < w).then(|| i + 1), (py + 1 < h).then(|| i + w)].into_iter().flatten() {
                let (zi, zj) = (depth[i], depth[j]);
                let differs = match (zi.is_finite(), zj.is_finite()) {
                    (false, false) => false,
                    (true, true) => (zi - zj).abs() > jump || dot(normal[i], normal[j]) < 0.82,
                    _ => true,
                };
                if differs {
                    // Darken the nearer of the two (the one in front draws the line).
                    edge[if zi <= zj { i } else { j }] = true;
                }
            }
        }
    }
    for (i, &e) in edge.iter().enumerate() {
        if e {
            for c in &mut rgb[3 * i..3 * i + 3] {
                *c = (*c as f64 * 0.35) as u8;
            }
        }
    }
    register_fonts();
    {
        let root = TextFix(BitMapBackend::with_buffer(&mut rgb, (w as u32, h as u32))).into_drawing_area();
        let text = |s: &str, x: i32, y: i32, size: u32| {
            root.draw(&Text::new(s.to_string(), (x, y), (FONT, size).into_font().color(&BLACK)))
                .map_err(|e| plot_err(path, e))
        };
        text(&preview.title, 12, 8, 20)?;
        for (k, (line, warning)) in preview.notes.iter().enumerate() {
            let colour = if *warning { RGBColor(190, 30, 30) } else { RGBColor(60, 60, 60) };
            root.draw(&Text::new(
                line.clone(),
                (12, 36 + 20 * k as i32),
                (FONT, 15).into_font().color(&colour),
            ))
            .map_err(|e| plot_err(path, e))?;
        }
        // The bounding box's sides, not the on-screen extents (the view is tilted, so those
        // mixed the axes: the shelf's 1.7 × 1.13 read 1.704 × 1.317).
        let names = preview.panel_names.clone().unwrap_or_else(|| ["input".into(), "output".into()]);
        for (k, (name, mesh)) in [(&names[0], input), (&names[1], output)].into_iter().enumerate() {
            let e = mesh.aabb().map(|b| b.extent()).unwrap_or([0.0; 3]);
            let line = preview.panel_captions[k].clone().unwrap_or_else(|| {
                format!(
                    "{name}: {:.3} × {:.3} × {:.3} (bounding box, model units), {} triangles",
                    e[0],
                    e[1],
                    e[2],
                    mesh.triangles.len()
                )
            });
            text(&line, (k * panel_w) as i32 + 12, top as i32 - 26, 15)?;
        }
        root.draw(&PathElement::new(
            vec![(panel_w as i32, top as i32), (panel_w as i32, h as i32)],
            RGBColor(200, 200, 200),
        ))
        .map_err(|e| plot_err(path, e))?;
        // Marks: rings and arrows first, then every label, so that no label's box hides an
        // arrow drawn after it.
        let placed: Vec<(&PreviewMark, (i32, i32), Option<(i32, i32)>)> = preview
            .marks
            .iter()
            .filter(|m| m.panel < 2)
            .filter_map(|m| {
                let px = |p: [f64; 3]| {
                    let (x, y, _) = panel_px(m.panel, p);
                    (x.round() as i32, y.round() as i32)
                };
                let inside = |p: &(i32, i32)| {
                    p.0 >= (m.panel * panel_w) as i32
                        && p.0 < ((m.panel + 1) * panel_w) as i32
                        && p.1 >= top as i32
                };
                let at = Some(px(m.at)).filter(inside)?;
                Some((m, at, m.from.map(px).filter(|f| *f != at && inside(f))))
            })
            .collect();
        for &(m, at, from) in &placed {
            let colour = RGBColor(m.colour[0], m.colour[1], m.colour[2]);
            if let Some(from) = from {
                let (dx, dy) = ((at.0 - from.0) as f64, (at.1 - from.1) as f64);
                let len = dx.hypot(dy);
                let (ux, uy) = (dx / len, dy / len);
                // The head ends on the ring, not in its centre.
                let tip = (at.0 - (ux * 9.0).round() as i32, at.1 - (uy * 9.0).round() as i32);
                let head = |side: f64| {
                    let (hx, hy) = (-ux * 14.0 - side * uy * 7.0, -uy * 14.0 + side * ux * 7.0);
                    (tip.0 + hx.round() as i32, tip.1 + hy.round() as i32)
                };
                root.draw(&PathElement::new(vec![from, tip], colour.stroke_width(3)))
                    .map_err(|e| plot_err(path, e))?;
                root.draw(&Polygon::new(vec![tip, head(1.0), head(-1.0)], colour.filled()))
                    .map_err(|e| plot_err(path, e))?;
                root.draw(&Circle::new(from, 5, colour.stroke_width(2))).map_err(|e| plot_err(path, e))?;
            }
            root.draw(&Circle::new(at, 9, colour.stroke_width(3))).map_err(|e| plot_err(path, e))?;
        }
        // Each label on a white box beside its ring: right of it, else left of it, moved up or
        // down in steps of a line until it covers no other label and no ring, and inside its
        // panel below the captions (first free place; the nearest if none is free).
        let size = 15;
        let rings: Vec<(i32, i32)> = placed.iter().map(|p| p.1).collect();
        let mut boxes: Vec<[i32; 4]> = Vec::new();
        for &(m, at, _) in &placed {
            let colour = RGBColor(m.colour[0], m.colour[1], m.colour[2]);
            let width =
                motif_core::plotting::text_width(&m.label, size as f64, FontStyle::Normal).ceil() as i32 + 6;
            let (x_lo, x_hi) = ((m.panel * panel_w) as i32 + 4, ((m.panel + 1) * panel_w) as i32 - 4);
            let (y_lo, y_hi) = (top as i32 + 2, h as i32 - size - 6);
            let fits = |b: [i32; 4]| b[0] >= x_lo && b[2] <= x_hi && b[1] >= y_lo && b[3] <= y_hi + size + 4;
            let clear = |b: [i32; 4]| {
                boxes.iter().all(|o| b[2] < o[0] || b[0] > o[2] || b[3] < o[1] || b[1] > o[3])
                    && rings
                        .iter()
                        .all(|r| r.0 + 10 < b[0] || r.0 - 10 > b[2] || r.1 + 10 < b[1] || r.1 - 10 > b[3])
            };
            let candidate = |dx: i32, dy: i32| {
                let lx = if dx >= 0 { at.0 + 14 } else { at.0 - 14 - width };
                let ly = at.1 - 10 + dy;
                [lx - 3, ly - 2, lx + width, ly + size + 4]
            };
            let mut choice = None;
            'search: for step in 0..8 {
                for dy in if step == 0 { vec![0] } else { vec![-(size + 8) * step, (size + 8) * step] } {
                    for dx in [1, -1] {
                        let b = candidate(dx, dy);
                        if fits(b) && clear(b) {
                            choice = Some(b);
                            break 'search;
                        }
                    }
                }
            }
            let b = choice.unwrap_or_else(|| {
                // No free place: right of the ring if it fits, else left, kept in the panel.
                let b = candidate(if candidate(1, 0)[2] <= x_hi { 1 } else { -1 }, 0);
                let sx = (x_lo - b[0]).max(0) - (b[2] - x_hi).max(0);
                let sy = (y_lo - b[1]).max(0);
                [b[0] + sx, b[1] + sy, b[2] + sx, b[3] + sy]
            });
            boxes.push(b);
            let (lx, ly) = (b[0] + 3, b[1] + 2);
            root.draw(&Rectangle::new(
                [(lx - 3, ly - 2), (lx + width, ly + size + 4)],
                WHITE.mix(0.85).filled(),
            ))
            .map_err(|e| plot_err(path, e))?;
            root.draw(&Text::new(m.label.clone(), (lx, ly), (FONT, size).into_font().color(&colour)))
                .map_err(|e| plot_err(path, e))?;
        }
        root.present().map_err(|e| plot_err(path, e))?;
    }
    motif_core::io::write_png_rgb(path, w as u32, h as u32, &rgb).map_err(|e| plot_err(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every dominant offset gets its number unless a stronger one's is in the way: all of the
    /// shelf's when nothing is, only the strongest when every spot is taken.
    #[test]
    fn every_peak_is_numbered_unless_a_stronger_ones_number_is_there() {
        let shelf = motif_core::procedural::generate("shelf", 0).expect("shelf");
        let options = crate::offsets::OffsetOptions { seed: 1, ..Default::default() };
        let a = crate::offsets::analyze_offsets(&shelf.mesh, &options, &motif_core::progress::NoProgress)
            .expect("offsets");
        assert!(a.dominant.len() > 8, "{} peaks", a.dominant.len());
        let at = |d: &crate::offsets::DominantOffset, s: f64| (s * d.offset[0], s * d.offset[1]);
        let no_ground = |p: (f64, f64), _| [p, p];
        let (rings, grounds, labels) = peak_marks(&a, at, |p| p, |_| true, |_, _| true, no_ground);
        assert_eq!((rings.len(), labels.len()), (2 * a.dominant.len(), a.dominant.len()));
        // One white ground under each number, none under a number left out.
        assert_eq!(grounds.len(), labels.len());
        let (_, grounds, labels) = peak_marks(&a, at, |p| p, |_| true, |_, _| false, no_ground);
        assert_eq!((grounds.len(), labels.len()), (1, 1));
        // Numbers need 0.3 across or up (in the picture's normalised units): the shelf's peaks lie
        // on a lattice of 0.42 × 0.37 model units, 0.494 × 0.435 normalised (× 1.1765), so all
        // fit; at 0.5 across, neighbours along a row collide.
        let room =
            |w: f64| move |p: (f64, f64), q: (f64, f64)| (p.0 - q.0).abs() >= w || (p.1 - q.1).abs() >= 0.3;
        assert_eq!(peak_marks(&a, at, |p| p, |_| true, room(0.3), no_ground).2.len(), a.dominant.len());
        let fewer = peak_marks(&a, at, |p| p, |_| true, room(0.5), no_ground).2.len();
        assert!(1 < fewer && fewer < a.dominant.len(), "{fewer} of {}", a.dominant.len());
    }

    /// A camera looking down −z with y up sees +x on the right (as OpenGL's default camera and
    /// Blender's front view do), and the screen frame is right-handed for any view: right × up
    /// points back at the viewer. (The preview drew mirror images before.)
    #[test]
    fn the_preview_camera_keeps_handedness() {
        let [u, v, d] = screen_axes([0.0, 0.0, -1.0], [0.0, 1.0, 0.0]).unwrap();
        assert_eq!((u, v, d), ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]));
        for (view, up) in [([-0.4, -0.25, -1.0], [0.0, 1.0, 0.0]), ([1.0, 2.0, 0.5], [0.0, 0.0, 1.0])] {
            let [u, v, d] = screen_axes(view, up).unwrap();
            let back = motif_core::geometry::cross(u, v);
            assert!((0..3).all(|k| (back[k] + d[k]).abs() < 1e-12), "{back:?} vs {d:?}");
        }
        assert!(screen_axes([0.0; 3], [0.0, 1.0, 0.0]).is_none());
    }
}
