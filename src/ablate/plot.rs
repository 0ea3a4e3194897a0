//! The log-log plot of error against time: RMSE and FLIP panels, one curve per model,
//! each point with the spread of its timed runs, the Pareto front of each panel, the
//! reference's own noise (the floor no point can be shown to beat), and the legend in a
//! band of its own below the panels, so it never covers data. Point labels are placed
//! where they collide with no other label or point.

use std::collections::BTreeMap;
use std::sync::Once;

use anyhow::{Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Row, ms_spread, pareto_front};
use crisp::CrispText;

const SIZE: (u32, u32) = (1400, 700);
const FONT: &str = "sans-serif";
/// Height of the legend band under the panels.
const LEGEND_H: u32 = 92;
const LABEL_SIZE: f32 = 12.0;
const FRONT_COLOUR: RGBColor = RGBColor(90, 90, 90);

/// An error column of a row.
type Metric = fn(&Row) -> f64;

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

/// The plot as a PNG image and as SVG text. `noise_rmse`: the reference's own RMSE
/// against the converged image, drawn as the RMSE panel's floor.
pub fn plot(
    rows: &[Row],
    title: &str,
    noise_rmse: Option<f64>,
) -> Result<(image::RgbImage, String)> {
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
/// area; else the place with the fewest overlaps. Greedy, in the order given.
fn place_labels(
    points: &[(f32, f32)],
    labels: &[(usize, String)],
    area: PixelBox,
) -> Vec<(i32, i32)> {
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
        let score = |&(dx, dy): &(f32, f32)| {
            let b = (x + dx, y + dy, x + dx + w, y + dy + h);
            let outside = b.0 < area.0 || b.1 < area.1 || b.2 > area.2 || b.3 > area.3;
            let hits = placed.iter().filter(|p| overlaps(**p, b)).count()
                + obstacles.iter().filter(|o| overlaps(**o, b)).count();
            hits + if outside { 100 } else { 0 }
        };
        let best = candidates
            .iter()
            .min_by_key(|c| score(c))
            .copied()
            .expect("candidates are not empty");
        placed.push((x + best.0, y + best.1, x + best.0 + w, y + best.1 + h));
        out.push((best.0.round() as i32, best.1.round() as i32));
    }
    out
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    rows: &[Row],
    title: &str,
    noise_rmse: Option<f64>,
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
    let colour = |model: &str| {
        let i = order.iter().position(|m| *m == model).unwrap_or(0);
        Palette99::pick(i).to_rgba()
    };
    let mixed = rows.iter().any(|r| r.backend != rows[0].backend);
    let x_range = range(rows.iter().flat_map(|r| {
        let (lo, hi) = ms_spread(r);
        [lo, hi]
    }));
    let metrics: [(&str, Metric, Option<f64>); 2] = [
        ("RMSE (linear radiance)", |r| r.rmse, noise_rmse),
        ("FLIP mean (sRGB display)", |r| r.flip_mean, None),
    ];
    for (panel, (name, metric, floor)) in panels.iter().zip(metrics) {
        let y_range = range(rows.iter().map(metric).chain(floor));
        let mut chart = ChartBuilder::on(panel)
            .margin(16)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .caption(format!("{name} against time"), (FONT, 18))
            .build_cartesian_2d(x_range.clone().log_scale(), y_range.clone().log_scale())?;
        chart
            .configure_mesh()
            .x_desc("ms per image (median of trace + cone pyramid build; bars: the runs' range)")
            .y_desc(name)
            .x_labels(12)
            .y_labels(12)
            .x_label_formatter(&|v| format!("{v}"))
            .y_label_formatter(&|v| format!("{v:.1e}"))
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 15))
            .light_line_style(RGBColor(238, 238, 238))
            .max_light_lines(4)
            .draw()?;

        // The reference's noise: no point can be shown to be closer than this.
        if let Some(f) = floor {
            let dashes = dashed(x_range.start, x_range.end, f);
            for d in dashes {
                chart.draw_series(LineSeries::new(d, RGBColor(200, 40, 40).stroke_width(1)))?;
            }
            chart.draw_series(std::iter::once(
                EmptyElement::at((x_range.start, f))
                    + Text::new(
                        format!("reference noise {f:.1e}"),
                        (4, -16),
                        (FONT, 12).into_font().color(&RGBColor(200, 40, 40)),
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

        for model in &order {
            let c = colour(model);
            let idx = &curves[model];
            let pts: Vec<(f64, f64)> = idx
                .iter()
                .map(|&i| (rows[i].ms_median.max(1e-9), metric(&rows[i]).max(1e-12)))
                .collect();
            // The spread of the timed runs, as a horizontal bar with end ticks.
            for &i in idx {
                let (lo, hi) = ms_spread(&rows[i]);
                let y = metric(&rows[i]).max(1e-12);
                if hi > lo {
                    chart.draw_series(std::iter::once(PathElement::new(
                        vec![(lo, y), (hi, y)],
                        c.stroke_width(1),
                    )))?;
                    for x in [lo, hi] {
                        chart.draw_series(std::iter::once(
                            EmptyElement::at((x, y))
                                + PathElement::new(vec![(0, -4), (0, 4)], c.stroke_width(1)),
                        ))?;
                    }
                }
            }
            if pts.len() > 1 {
                chart.draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))?;
                chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, c.filled())))?;
            } else {
                chart.draw_series(pts.iter().map(|&p| TriangleMarker::new(p, 7, c.filled())))?;
            }
        }

        // The knob's value beside each point of a curve, where it collides least.
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
        for ((i, label), (dx, dy)) in labels.iter().zip(offsets) {
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
    let mut entries: Vec<(String, RGBAColor, bool)> = order
        .iter()
        .map(|m| {
            let backend = rows[curves[*m][0]].backend;
            let label = if mixed {
                format!("{m} [{backend}]")
            } else {
                m.to_string()
            };
            (label, colour(m), curves[*m].len() > 1)
        })
        .collect();
    entries.push((
        "Pareto front (each panel's)".into(),
        FRONT_COLOUR.mix(0.35),
        true,
    ));
    if noise_rmse.is_some() {
        entries.push((
            "reference noise (RMSE floor)".into(),
            RGBColor(200, 40, 40).to_rgba(),
            true,
        ));
    }
    let columns = 4;
    let (lw, _) = legend_area.dim_in_pixel();
    let cell_w = (lw as i32 - 40) / columns;
    for (k, (label, c, line)) in entries.iter().enumerate() {
        let (col, row) = (k as i32 % columns, k as i32 / columns);
        let (x, y) = (20 + col * cell_w, 10 + row * 20);
        if *line {
            legend_area.draw(&PathElement::new(
                vec![(x, y + 7), (x + 22, y + 7)],
                c.stroke_width(2),
            ))?;
            legend_area.draw(&Circle::new((x + 11, y + 7), 4, c.filled()))?;
        } else {
            legend_area.draw(&TriangleMarker::new((x + 11, y + 7), 6, c.filled()))?;
        }
        legend_area.draw(&Text::new(label.clone(), (x + 30, y), (FONT, 13)))?;
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

    /// Labels of a dense cluster of points find places that overlap nothing when there
    /// is room, and stay inside the area.
    #[test]
    fn labels_avoid_each_other_and_the_points() {
        let points: Vec<(f32, f32)> = (0..6).map(|k| (200.0 + 9.0 * k as f32, 200.0)).collect();
        let labels: Vec<(usize, String)> = (0..6).map(|k| (k, format!("{}", 1 << k))).collect();
        let area = (0.0, 0.0, 600.0, 400.0);
        let offsets = place_labels(&points, &labels, area);
        let boxes: Vec<PixelBox> = labels
            .iter()
            .zip(&offsets)
            .map(|((i, l), (dx, dy))| {
                let (w, h) = super::super::text::measure(l, LABEL_SIZE);
                let (x, y) = (points[*i].0 + *dx as f32, points[*i].1 + *dy as f32);
                (x, y, x + w, y + h)
            })
            .collect();
        for (a, ba) in boxes.iter().enumerate() {
            assert!(ba.0 >= 0.0 && ba.3 <= 400.0);
            for bb in &boxes[a + 1..] {
                assert!(!overlaps(*ba, *bb), "{ba:?} {bb:?}");
            }
            for &(x, y) in &points {
                assert!(
                    !overlaps(*ba, (x - 4.0, y - 4.0, x + 4.0, y + 4.0)),
                    "{ba:?} on ({x}, {y})"
                );
            }
        }
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
