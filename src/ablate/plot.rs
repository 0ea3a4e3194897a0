//! The log-log plot of error against time: RMSE and FLIP panels, one curve per model,
//! each point the mean over its seeds with its 95 % interval on both axes (one seed: the
//! spread of its timed runs in time; an interval through zero open below, an arrowhead at
//! the axis' edge), the Pareto front of each panel, the reference's
//! own noise (each metric's floor, which no point can be shown to beat), and the legend
//! in a band of its own below the panels, so it never covers data. Each technique keeps
//! its colour across runs (Okabe and Ito's colour-blind-safe palette, by the registry's
//! order); point labels go where they collide with no other label or point, or are left
//! out (the table has every value).

use std::collections::BTreeMap;
use std::sync::Once;

use anyhow::{Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Interval, Row, ms_spread, pareto_front};
use crisp::CrispText;

const SIZE: (u32, u32) = (1400, 700);
const FONT: &str = "sans-serif";
/// Height of the legend band under the panels.
const LEGEND_H: u32 = 92;
const LABEL_SIZE: f32 = 12.0;
const FRONT_COLOUR: RGBColor = RGBColor(90, 90, 90);

/// An error column of a row, and its interval's half-width.
type Metric = fn(&Row) -> f64;
type Half = fn(&Interval) -> f64;

/// Okabe and Ito's colour-blind-safe palette without its yellow (too light on white)
/// and black (the floors): a technique's curves take its registry index's colour.
const PALETTE: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(230, 159, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(86, 180, 233),
    RGBColor(213, 94, 0),
];

/// The colour of a row's technique: its shadow model's place in the registry, so the
/// same technique has the same colour in every plot.
pub(crate) fn technique_colour(row: &Row) -> RGBColor {
    let i = crate::technique::SHADOW_MODELS
        .iter()
        .position(|m| m.name == row.shadow_model)
        .unwrap_or(crate::technique::SHADOW_MODELS.len());
    PALETTE[i % PALETTE.len()]
}

/// A tick's label: the fewest digits its value needs (ticks have at most five
/// significant ones), in scientific notation outside 0.01..10000.
fn tick_label(v: f64) -> String {
    let sci = format!("{v:.4e}");
    let (mantissa, exp) = sci.split_once('e').unwrap_or((&sci, "0"));
    let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
    let exp: i32 = exp.parse().unwrap_or(0);
    if (-2..4).contains(&exp) {
        let digits = (mantissa.len().saturating_sub(2) as i32 - exp).max(0) as usize;
        format!("{v:.digits$}")
    } else {
        format!("{mantissa}e{exp}")
    }
}

/// Tick values for a log axis over `lo..hi`: the decades' 1, 2, 5 (or every digit)
/// where those give at least four, else five values evenly spaced in the logarithm,
/// rounded to two significant digits, so a narrow range still gets labels.
pub(crate) fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
        return vec![];
    }
    let within = |mantissas: &[f64]| -> Vec<f64> {
        let mut out = Vec::new();
        let mut decade = 10f64.powf(lo.log10().floor());
        while decade <= hi {
            for m in mantissas {
                let v = m * decade;
                if v >= lo && v <= hi {
                    out.push(v);
                }
            }
            decade *= 10.0;
        }
        out
    };
    for mantissas in [
        &[1.0][..],
        &[1.0, 2.0, 5.0][..],
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0][..],
    ] {
        let t = within(mantissas);
        if t.len() >= 4 && t.len() <= 14 {
            return t;
        }
    }
    // A narrow range: five values evenly spaced in the logarithm, with the fewest
    // significant digits that keep them apart.
    let (a, b) = (lo.ln(), hi.ln());
    let even: Vec<f64> = (1..=5)
        .map(|k| (a + (b - a) * k as f64 / 6.0).exp())
        .collect();
    for significant in 2..=15 {
        let t: Vec<f64> = even
            .iter()
            .map(|&v| {
                let unit = 10f64.powf(v.log10().floor() + 1.0 - significant as f64);
                (v / unit).round() * unit
            })
            .filter(|v| (lo..=hi).contains(v))
            .collect();
        if t.len() == even.len() && t.windows(2).all(|w| w[0] < w[1]) {
            return t;
        }
    }
    even
}

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The SVG names the family; the bytes only give plotters its layout estimates.
        let _ = plotters::style::register_font(
            FONT,
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        );
    });
}

/// The plot as a PNG image and as SVG text. `floors`: the reference's own RMSE and FLIP
/// floor (`super::Reference`), drawn as each panel's floor.
pub fn plot(
    rows: &[Row],
    title: &str,
    floors: Option<(f64, f64)>,
) -> Result<(image::RgbImage, String)> {
    let noise_rmse = floors;
    register_font();
    let mut buf = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let backend = CrispText(BitMapBackend::with_buffer(&mut buf, SIZE));
        let root = backend.into_drawing_area();
        draw(&root, rows, title, noise_rmse).map_err(|e| anyhow!("drawing the plot: {e}"))?;
        root.present()
            .map_err(|e| anyhow!("drawing the plot: {e}"))?;
    }
    let png = image::RgbImage::from_raw(SIZE.0, SIZE.1, buf).expect("buffer is w*h*3");
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        draw(&root, rows, title, noise_rmse).map_err(|e| anyhow!("drawing the plot: {e}"))?;
        root.present()
            .map_err(|e| anyhow!("drawing the plot: {e}"))?;
    }
    Ok((png, svg))
}

/// Log axes need a positive range around the values, with some air.
fn range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo > hi {
        return 1e-3..1.0;
    }
    lo / 1.6..hi * 1.6
}

/// A box in pixels: (x0, y0, x1, y1).
type PixelBox = (f32, f32, f32, f32);

fn overlaps(a: PixelBox, b: PixelBox) -> bool {
    a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3
}

/// Where each label goes, as an offset from its point: the first of several places
/// around the point that overlaps no placed label, no point and stays in the plotting
/// area; `None` where every place collides (the label is left out: the table has the
/// value). Greedy, in the order given.
fn place_labels(
    points: &[(f32, f32)],
    labels: &[(usize, String)],
    area: PixelBox,
) -> Vec<Option<(i32, i32)>> {
    let obstacles: Vec<PixelBox> = points
        .iter()
        .map(|&(x, y)| (x - 4.0, y - 4.0, x + 4.0, y + 4.0))
        .collect();
    let mut placed: Vec<PixelBox> = Vec::new();
    let mut out = Vec::with_capacity(labels.len());
    for (point, label) in labels {
        let (x, y) = points[*point];
        let (w, h) = super::text::measure(label, LABEL_SIZE);
        let candidates = [
            (6.0, -h - 2.0),
            (6.0, 2.0),
            (-w - 6.0, -h - 2.0),
            (-w - 6.0, 2.0),
            (-w / 2.0, -h - 7.0),
            (-w / 2.0, 7.0),
            (8.0, -h / 2.0),
            (-w - 8.0, -h / 2.0),
        ];
        // Scored where they will be drawn: at whole pixels.
        let candidates = candidates.map(|(dx, dy): (f32, f32)| (dx.round(), dy.round()));
        let score = |&(dx, dy): &(f32, f32)| {
            let b = (x + dx, y + dy, x + dx + w, y + dy + h);
            let outside = b.0 < area.0 || b.1 < area.1 || b.2 > area.2 || b.3 > area.3;
            let hits = placed.iter().filter(|p| overlaps(**p, b)).count()
                + obstacles.iter().filter(|o| overlaps(**o, b)).count();
            hits + if outside { 100 } else { 0 }
        };
        let Some(best) = candidates.iter().find(|c| score(c) == 0).copied() else {
            out.push(None);
            continue;
        };
        placed.push((x + best.0, y + best.1, x + best.0 + w, y + best.1 + h));
        out.push(Some((best.0.round() as i32, best.1.round() as i32)));
    }
    out
}

/// An interval on a log axis: its lower end, `None` where the interval reaches zero or
/// below (a Student's t interval over few, spread seeds can), and its upper end. An open
/// lower end is drawn to the axis' edge with an arrowhead and does not stretch the axis:
/// a made-up positive end would claim a bound the data do not give.
type Bar = (Option<f64>, f64);

fn open_below(lo: f64, hi: f64) -> Bar {
    ((lo > 0.0).then_some(lo), hi)
}

/// The time axis: the points and their bars' ends, an open end left out.
fn x_axis(rows: &[Row]) -> std::ops::Range<f64> {
    range(rows.iter().flat_map(|r| {
        let (lo, hi) = x_bar(r);
        [Some(r.ms_median), lo, Some(hi)].into_iter().flatten()
    }))
}

/// A row's time interval: the 95 % interval over seeds, else the runs' spread.
fn x_bar(r: &Row) -> Bar {
    match r.interval {
        Some(i) => open_below(r.ms_median - i.ms, r.ms_median + i.ms),
        None => {
            let (lo, hi) = ms_spread(r);
            open_below(lo, hi)
        }
    }
}

/// A row's error interval under `metric`, where it has one.
fn y_bar(r: &Row, metric: Metric, half: Half) -> Option<Bar> {
    let i = r.interval?;
    let (y, h) = (metric(r), half(&i));
    Some(open_below(y - h, y + h))
}

/// One function because plotters' chart contexts borrow the drawing area: the panels,
/// curves, error bars and legend are drawn through borrows of one root.
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    rows: &[Row],
    title: &str,
    floors: Option<(f64, f64)>,
) -> Result<(), Box<dyn std::error::Error>>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let root = root.titled(title, (FONT, 22))?;
    let (height, _) = (root.dim_in_pixel().1, ());
    let (panels_area, legend_area) = root.split_vertically(height - LEGEND_H);
    let panels = panels_area.split_evenly((1, 2));
    // One curve per model, in the order the sweep gave them.
    let mut order: Vec<&str> = Vec::new();
    let mut curves: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (i, r) in rows.iter().enumerate() {
        if !order.contains(&r.model.as_str()) {
            order.push(&r.model);
        }
        curves.entry(&r.model).or_default().push(i);
    }
    let colour = |model: &str| technique_colour(&rows[curves[model][0]]).to_rgba();
    // The curves of one technique are told apart by their markers.
    let shape = |model: &str| {
        let t = rows[curves[model][0]].shadow_model;
        order
            .iter()
            .filter(|m| rows[curves[**m][0]].shadow_model == t)
            .position(|m| *m == model)
            .unwrap_or(0)
    };
    let mixed = rows.iter().any(|r| r.backend != rows[0].backend);
    let seeds = rows
        .iter()
        .filter_map(|r| r.interval)
        .map(|i| i.seeds)
        .max();
    let x_range = x_axis(rows);
    let metrics: [(&str, Metric, Half, Option<f64>, &str); 2] = [
        (
            "RMSE (linear radiance)",
            |r| r.rmse,
            |i| i.rmse,
            floors.map(|f| f.0),
            "reference noise",
        ),
        (
            "FLIP mean (sRGB display)",
            |r| r.flip_mean,
            |i| i.flip,
            floors.map(|f| f.1),
            "FLIP floor (reference halves)",
        ),
    ];
    let x_desc = match seeds {
        Some(n) => format!(
            "ms per image (trace + cone pyramid build; mean of {n} seeds, bars: 95 % interval)"
        ),
        None => {
            "ms per image (median of trace + cone pyramid build; bars: the runs' range)".to_string()
        }
    };
    let open_bars = rows.iter().any(|r| {
        x_bar(r).0.is_none()
            || metrics
                .iter()
                .any(|m| y_bar(r, m.1, m.2).is_some_and(|b| b.0.is_none()))
    });

    for (panel, (name, metric, half, floor, floor_name)) in panels.iter().zip(metrics) {
        let y_range = range(
            rows.iter()
                .flat_map(|r| {
                    let (lo, hi) = y_bar(r, metric, half).unwrap_or((None, metric(r)));
                    [Some(metric(r)), lo, Some(hi)].into_iter().flatten()
                })
                .chain(floor),
        );
        let (xt, yt) = (
            log_ticks(x_range.start, x_range.end),
            log_ticks(y_range.start, y_range.end),
        );
        let mut chart = ChartBuilder::on(panel)
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .caption(format!("{name} against time"), (FONT, 18))
            .build_cartesian_2d(
                x_range.clone().log_scale().with_key_points(xt),
                y_range.clone().log_scale().with_key_points(yt),
            )?;
        chart
            .configure_mesh()
            .x_desc(x_desc.as_str())
            .y_desc(name)
            .x_label_formatter(&|v| tick_label(*v))
            .y_label_formatter(&|v| tick_label(*v))
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 15))
            .light_line_style(RGBColor(238, 238, 238))
            .draw()?;

        // The reference's noise: no point can be shown to be closer than this.
        if let Some(f) = floor {
            let dashes = dashed(x_range.start, x_range.end, f);
            for d in dashes {
                chart.draw_series(LineSeries::new(d, BLACK.stroke_width(1)))?;
            }
            chart.draw_series(std::iter::once(
                EmptyElement::at((x_range.start, f))
                    + Text::new(
                        format!("{floor_name} {f:.1e}"),
                        (4, -16),
                        (FONT, 12).into_font().color(&BLACK),
                    ),
            ))?;
        }

        // The Pareto front: a staircase through the points no other beats in both.
        let front = pareto_front(rows, metric);
        let mut steps: Vec<(f64, f64)> = rows
            .iter()
            .zip(&front)
            .filter(|(_, on)| **on)
            .map(|(r, _)| (r.ms_median, metric(r)))
            .collect();
        steps.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut stair = Vec::new();
        for (k, &(x, y)) in steps.iter().enumerate() {
            if k > 0 {
                stair.push((x, steps[k - 1].1));
            }
            stair.push((x, y));
        }
        if let Some(&(_, y)) = steps.last() {
            stair.push((x_range.end, y));
        }
        chart.draw_series(LineSeries::new(
            stair,
            ShapeStyle::from(&FRONT_COLOUR.mix(0.35)).stroke_width(4),
        ))?;

        // Curves first, single points (fixed configurations) last, so none hides.
        let mut drawing: Vec<&&str> = order.iter().collect();
        drawing.sort_by_key(|m| curves[**m].len() == 1);
        for model in drawing {
            let c = colour(model);
            let idx = &curves[*model];
            let pts: Vec<(f64, f64)> = idx
                .iter()
                .map(|&i| (rows[i].ms_median.max(1e-9), metric(&rows[i]).max(1e-12)))
                .collect();
            for &i in idx {
                let (x, y) = (rows[i].ms_median.max(1e-9), metric(&rows[i]).max(1e-12));
                // (start, end, horizontal, whether the start is open).
                let mut bars = Vec::new();
                let (lo, hi) = x_bar(&rows[i]);
                if lo.is_none_or(|lo| hi > lo) {
                    bars.push((
                        (lo.unwrap_or(x_range.start), y),
                        (hi, y),
                        true,
                        lo.is_none(),
                    ));
                }
                if let Some((ylo, yhi)) = y_bar(&rows[i], metric, half)
                    && ylo.is_none_or(|ylo| yhi > ylo)
                {
                    let start = ylo.unwrap_or(y_range.start);
                    bars.push(((x, start), (x, yhi), false, ylo.is_none()));
                }
                for (a, b, horizontal, open) in bars {
                    chart.draw_series(std::iter::once(PathElement::new(
                        vec![a, b],
                        c.stroke_width(1),
                    )))?;
                    let (tick, arrow) = if horizontal {
                        (vec![(0, -4), (0, 4)], vec![(6, -4), (0, 0), (6, 4)])
                    } else {
                        (vec![(-4, 0), (4, 0)], vec![(-4, -6), (0, 0), (4, -6)])
                    };
                    let start_mark = if open { arrow } else { tick.clone() };
                    for (end, mark) in [(a, start_mark), (b, tick)] {
                        chart.draw_series(std::iter::once(
                            EmptyElement::at(end) + PathElement::new(mark, c.stroke_width(1)),
                        ))?;
                    }
                }
            }
            if pts.len() > 1 {
                chart.draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))?;
            }
            // Single points start at the triangle, so a technique's fixed points differ
            // from each other as its curves do.
            let k = if pts.len() > 1 {
                shape(model)
            } else {
                shape(model) + 2
            };
            for &p in &pts {
                // A white rim keeps a marker visible on a line or another marker.
                chart.draw_series(std::iter::once(Circle::new(p, 7, WHITE.filled())))?;
                // Marker shapes tell a technique's curves apart (they share its colour).
                match k % 3 {
                    0 => chart.draw_series(std::iter::once(Circle::new(p, 4, c.filled())))?,
                    1 => chart.draw_series(std::iter::once(
                        EmptyElement::at(p) + Rectangle::new([(-4, -4), (4, 4)], c.filled()),
                    ))?,
                    _ => {
                        chart.draw_series(std::iter::once(TriangleMarker::new(p, 6, c.filled())))?
                    }
                };
            }
        }

        // The knob's value beside each point of a curve, where it collides with nothing.
        let area = chart.plotting_area();
        let (xr, yr) = area.get_pixel_range();
        let bounds = (
            xr.start as f32,
            yr.start as f32,
            xr.end as f32,
            yr.end as f32,
        );
        let pixel: Vec<(f32, f32)> = rows
            .iter()
            .map(|r| {
                let (x, y) = area.map_coordinate(&(r.ms_median.max(1e-9), metric(r).max(1e-12)));
                (x as f32, y as f32)
            })
            .collect();
        let labels: Vec<(usize, String)> = order
            .iter()
            .filter(|m| curves[**m].len() > 1)
            .flat_map(|m| curves[*m].iter().map(|&i| (i, rows[i].value.clone())))
            .collect();
        let offsets = place_labels(&pixel, &labels, bounds);
        for ((i, label), offset) in labels.iter().zip(offsets) {
            let Some((dx, dy)) = offset else {
                continue;
            };
            let p = (rows[*i].ms_median.max(1e-9), metric(&rows[*i]).max(1e-12));
            // The curve's colour, darkened so light ones stay legible on white.
            let RGBAColor(r, g, b, _) = colour(&rows[*i].model);
            let dark = RGBColor(r * 3 / 5, g * 3 / 5, b * 3 / 5);
            chart.draw_series(std::iter::once(
                EmptyElement::at(p)
                    + Text::new(
                        label.clone(),
                        (dx, dy),
                        (FONT, f64::from(LABEL_SIZE)).into_font().color(&dark),
                    ),
            ))?;
        }
    }

    // The legend, in its own band: one entry per curve, then the front and the floor.
    legend_area.fill(&WHITE)?;
    let mut entries: Vec<(String, RGBAColor, Option<usize>)> = order
        .iter()
        .map(|m| {
            let backend = rows[curves[*m][0]].backend;
            let label = if mixed {
                format!("{m} [{backend}]")
            } else {
                m.to_string()
            };
            let k = if curves[*m].len() > 1 {
                Some(shape(m))
            } else {
                Some(shape(m) + 2 + 3 * 1000)
            };
            (label, colour(m), k)
        })
        .collect();
    entries.push((
        "Pareto front (each panel's)".into(),
        FRONT_COLOUR.mix(0.35),
        None,
    ));
    if floors.is_some() {
        entries.push((
            "reference noise (each metric's floor)".into(),
            BLACK.to_rgba(),
            None,
        ));
    }
    let columns = 4;
    let (lw, _) = legend_area.dim_in_pixel();
    let cell_w = (lw as i32 - 40) / columns;
    let n_curves = order.len();
    for (k, (label, c, shape)) in entries.iter().enumerate() {
        let (col, row) = (k as i32 % columns, k as i32 / columns);
        let (x, y) = (20 + col * cell_w, 10 + row * 20);
        let curve = k < n_curves;
        // Curves have a line through their marker; single points (shape >= 3000) none.
        let single = shape.is_some_and(|k| k >= 3000);
        if !curve || !single {
            legend_area.draw(&PathElement::new(
                vec![(x, y + 7), (x + 22, y + 7)],
                c.stroke_width(2),
            ))?;
        }
        if curve {
            let p = (x + 11, y + 7);
            match shape.unwrap_or(2) % 3 {
                0 => legend_area.draw(&Circle::new(p, 4, c.filled()))?,
                1 => legend_area.draw(&Rectangle::new(
                    [(p.0 - 4, p.1 - 4), (p.0 + 4, p.1 + 4)],
                    c.filled(),
                ))?,
                _ => legend_area.draw(&TriangleMarker::new(p, 6, c.filled()))?,
            }
        }
        legend_area.draw(&Text::new(label.clone(), (x + 30, y), (FONT, 13)))?;
    }
    if open_bars {
        let k = entries.len() as i32;
        let (x, y) = (20 + (k % columns) * cell_w, 10 + (k / columns) * 20);
        let grey = FRONT_COLOUR.to_rgba();
        legend_area.draw(&PathElement::new(
            vec![(x, y + 7), (x + 22, y + 7)],
            grey.stroke_width(1),
        ))?;
        legend_area.draw(&PathElement::new(
            vec![(x + 6, y + 3), (x, y + 7), (x + 6, y + 11)],
            grey.stroke_width(1),
        ))?;
        legend_area.draw(&Text::new(
            "arrowhead: the interval reaches 0 or below",
            (x + 30, y),
            (FONT, 13),
        ))?;
    }
    Ok(())
}

/// A horizontal dashed line at `y` from `x0` to `x1` (log x), as segments.
fn dashed(x0: f64, x1: f64, y: f64) -> Vec<Vec<(f64, f64)>> {
    let (a, b) = (x0.ln(), x1.ln());
    let n = 60;
    (0..n)
        .step_by(2)
        .map(|k| {
            let t0 = a + (b - a) * k as f64 / n as f64;
            let t1 = a + (b - a) * (k + 1) as f64 / n as f64;
            vec![(t0.exp(), y), (t1.exp(), y)]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A summary row of `ms` ± `half` milliseconds and RMSE 0.02 ± 0.001 over 3 seeds.
    fn row(model: &str, ms: f64, half: f64) -> Row {
        Row {
            model: model.into(),
            knob: "spp".into(),
            value: "1".into(),
            spp: 1,
            light_samples: 1,
            shadow_model: "area",
            model_settings: vec![],
            model_note: None,
            transmittance: "min-kt",
            reconstruction: "none",
            backend: "gpu",
            fallback: None,
            timer: "device",
            ms_median: ms,
            ms_runs: vec![ms],
            trace_ms_median: ms,
            setup_ms_median: 0.0,
            lights_as_points: false,
            rmse: 0.02,
            rmse_corrected: 0.02,
            psnr: 34.0,
            flip_mean: 0.03,
            flip8_mean: 0.03,
            flicker: None,
            seed: 0,
            seed_index: 0,
            interval: Some(Interval {
                seeds: 3,
                ms: half,
                rmse: 0.001,
                rmse_corrected: 0.001,
                flip: 0.001,
                flicker: 0.0,
            }),
            own_reference: None,
            plan: String::new(),
            image: String::new(),
            frame: crate::frame::Frame::new(1, 1),
            external: None,
            adapter: String::new(),
        }
    }

    /// A time interval that reaches below zero (three spread seeds: 3.39 ± 3.46 ms) is
    /// open below: it neither claims a positive bound nor stretches the axis three
    /// decades to the left of every point (as a clamp to a thousandth of the mean did);
    /// the plot still draws.
    #[test]
    fn an_interval_through_zero_is_open_and_keeps_the_axis_on_the_points() {
        let rows = [row("a", 3.39, 3.46), row("b", 100.0, 5.0)];
        assert_eq!(x_bar(&rows[0]), (None, 3.39 + 3.46));
        assert_eq!(x_bar(&rows[1]), (Some(95.0), 105.0));
        let axis = x_axis(&rows);
        assert_eq!(
            axis.start,
            3.39 / 1.6,
            "the axis starts at the leftmost point"
        );
        assert_eq!(axis.end, 105.0 * 1.6);
        let mut wide = row("c", 50.0, 1.0);
        wide.rmse = 0.01;
        wide.interval.as_mut().unwrap().rmse = 0.02;
        let y = y_bar(&wide, |r| r.rmse, |i| i.rmse).unwrap();
        assert_eq!(y, (None, 0.03));
        plot(
            &[rows[0].clone(), rows[1].clone(), wide],
            "open intervals",
            None,
        )
        .expect("a plot with open intervals draws");
    }

    /// Labels of a dense cluster of points find places that overlap nothing when there
    /// is room, and stay inside the area; in a cluster too dense for all of them, those
    /// that would collide are left out, and the rest still overlap nothing.
    #[test]
    fn labels_avoid_each_other_and_the_points() {
        for (spacing, count) in [(9.0, 6), (2.0, 40)] {
            let points: Vec<(f32, f32)> = (0..count)
                .map(|k| (200.0 + spacing * k as f32, 200.0))
                .collect();
            let labels: Vec<(usize, String)> =
                (0..count).map(|k| (k, format!("{}", 1u64 << k))).collect();
            let offsets = place_labels(&points, &labels, (0.0, 0.0, 600.0, 400.0));
            let placed = offsets.iter().flatten().count();
            if count == 6 {
                assert_eq!(placed, 6, "room for every label");
            } else {
                assert!(placed > 0 && placed < count, "{placed} of {count}");
            }
            assert_separate(&points, &labels, &offsets);
        }
    }

    fn assert_separate(
        points: &[(f32, f32)],
        labels: &[(usize, String)],
        offsets: &[Option<(i32, i32)>],
    ) {
        let boxes: Vec<PixelBox> = labels
            .iter()
            .zip(offsets)
            .filter_map(|((i, l), o)| {
                let (dx, dy) = (*o)?;
                let (w, h) = super::super::text::measure(l, LABEL_SIZE);
                let (x, y) = (points[*i].0 + dx as f32, points[*i].1 + dy as f32);
                Some((x, y, x + w, y + h))
            })
            .collect();
        for (a, ba) in boxes.iter().enumerate() {
            assert!(ba.0 >= 0.0 && ba.3 <= 400.0);
            for bb in &boxes[a + 1..] {
                assert!(!overlaps(*ba, *bb), "{ba:?} {bb:?}");
            }
            for &(x, y) in points {
                assert!(
                    !overlaps(*ba, (x - 4.0, y - 4.0, x + 4.0, y + 4.0)),
                    "{ba:?} on ({x}, {y})"
                );
            }
        }
    }

    /// Any range, however narrow, gets at least three tick values inside it, and at most
    /// fourteen.
    #[test]
    fn log_axes_get_enough_ticks() {
        for (lo, hi) in [
            (0.0101, 0.0113),
            (0.0038, 0.0052),
            (1e-4, 1e3),
            (1e-12, 1e12),
            (0.9, 1.1),
            (3.0, 7.0),
            (55.0, 60.0),
            (1e-3, 1.0),
        ] {
            let t = log_ticks(lo, hi);
            assert!((3..=14).contains(&t.len()), "{lo}..{hi}: {t:?}");
            assert!(t.iter().all(|v| (lo..=hi).contains(v)), "{lo}..{hi}: {t:?}");
            assert!(t.windows(2).all(|w| w[0] < w[1]), "{t:?}");
            let labels: Vec<String> = t.iter().map(|&v| tick_label(v)).collect();
            assert!(
                labels.windows(2).all(|w| w[0] != w[1]),
                "{lo}..{hi}: {labels:?}"
            );
        }
        assert_eq!(tick_label(0.01053), "0.01053");
        assert_eq!(tick_label(200.0), "200");
        assert_eq!(tick_label(2e-5), "2e-5");
    }
}

mod crisp {
    //! plotters' bitmap backend with the text drawn by [`super::super::text`] (see its
    //! module comment).

    use plotters::prelude::*;
    use plotters_backend::{
        BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingErrorKind,
    };

    use super::super::text;

    pub(super) struct CrispText<'a>(pub(super) BitMapBackend<'a>);

    impl DrawingBackend for CrispText<'_> {
        type ErrorType = <BitMapBackend<'static> as DrawingBackend>::ErrorType;

        fn get_size(&self) -> (u32, u32) {
            self.0.get_size()
        }
        fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.ensure_prepared()
        }
        fn present(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.present()
        }
        fn draw_pixel(
            &mut self,
            point: BackendCoord,
            color: BackendColor,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.draw_pixel(point, color)
        }
        fn draw_line<S: BackendStyle>(
            &mut self,
            from: BackendCoord,
            to: BackendCoord,
            style: &S,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.draw_line(from, to, style)
        }
        fn draw_rect<S: BackendStyle>(
            &mut self,
            upper_left: BackendCoord,
            bottom_right: BackendCoord,
            style: &S,
            fill: bool,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.draw_rect(upper_left, bottom_right, style, fill)
        }
        fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
            &mut self,
            path: I,
            style: &S,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.draw_path(path, style)
        }
        fn draw_circle<S: BackendStyle>(
            &mut self,
            center: BackendCoord,
            radius: u32,
            style: &S,
            fill: bool,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.draw_circle(center, radius, style, fill)
        }
        fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
            &mut self,
            vert: I,
            style: &S,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.fill_polygon(vert, style)
        }
        fn blit_bitmap(
            &mut self,
            pos: BackendCoord,
            size: (u32, u32),
            src: &[u8],
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            self.0.blit_bitmap(pos, size, src)
        }

        fn draw_text<T: BackendTextStyle>(
            &mut self,
            s: &str,
            style: &T,
            pos: BackendCoord,
        ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
            use plotters::style::text_anchor::{HPos, VPos};
            let color = style.color();
            if color.alpha == 0.0 {
                return Ok(());
            }
            let size = style.size() as f32;
            let (w, h) = text::measure(s, size);
            let dx = match style.anchor().h_pos {
                HPos::Left => 0.0,
                HPos::Right => -w,
                HPos::Center => -w / 2.0,
            };
            let dy = match style.anchor().v_pos {
                VPos::Top => 0.0,
                VPos::Center => -h / 2.0,
                VPos::Bottom => -h,
            };
            let transform = style.transform();
            let mut pixels = Vec::new();
            text::rasterize(s, size, dx, dy, |x, y, a| pixels.push((x, y, a)));
            let (bw, bh) = self.get_size();
            for (x, y, a) in pixels {
                let (tx, ty) = transform.transform(x, y);
                let (px, py) = (pos.0 + tx, pos.1 + ty);
                if px >= 0 && py >= 0 && (px as u32) < bw && (py as u32) < bh && a > 0.0 {
                    let c = BackendColor {
                        alpha: color.alpha * f64::from(a.min(1.0)),
                        rgb: color.rgb,
                    };
                    self.0.draw_pixel((px, py), c)?;
                }
            }
            Ok(())
        }

        fn estimate_text_size<T: BackendTextStyle>(
            &self,
            s: &str,
            style: &T,
        ) -> Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
            let (w, h) = text::measure(s, style.size() as f32);
            Ok((w.ceil() as u32, h.ceil() as u32))
        }
    }
}
