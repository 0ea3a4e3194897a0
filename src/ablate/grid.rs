//! The image grid of an ablation: the reference, then every point, each tile at least
//! 256 pixels wide, with a magnified inset of the region where the models disagree most
//! with the reference (the penumbrae, on a soft-shadow scene) and a label band.

use super::{Reference, Row, text};
use crate::frame::Frame;

/// Tiles are magnified (nearest neighbour, whole factors) to at least this width.
const TILE_MIN: u32 = 256;
const BACKGROUND: [u8; 3] = [24, 24, 24];
const INK: [u8; 3] = [235, 235, 235];
const MARK: [u8; 3] = [255, 210, 0];
const TEXT_SIZE: f32 = 13.0;

/// The inset: a square of the source image, (x, y, side) in its pixels.
type Region = (u32, u32, u32);

/// The square (a sixth of the image's smaller side, at least 8 pixels) where the rows
/// differ most from the reference, summed over rows: where the models disagree.
pub(crate) fn inset_region<'a>(
    reference: &Frame,
    frames: impl Iterator<Item = &'a Frame>,
) -> Region {
    let (w, h) = (reference.width, reference.height);
    let side = (w.min(h) / 6).max(8).min(w.min(h));
    let mut err = vec![0.0f64; (w * h) as usize];
    for frame in frames {
        for (e, (a, b)) in err
            .iter_mut()
            .zip(frame.pixels.iter().zip(&reference.pixels))
        {
            let d: f32 = (0..3)
                .map(|k| (a[k].clamp(0.0, 1.0) - b[k].clamp(0.0, 1.0)).abs())
                .sum();
            if d.is_finite() {
                *e += f64::from(d);
            }
        }
    }
    // Summed-area table, then the best window.
    let (w, h) = (w as usize, h as usize);
    let mut sat = vec![0.0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        for x in 0..w {
            sat[(y + 1) * (w + 1) + x + 1] =
                err[y * w + x] + sat[y * (w + 1) + x + 1] + sat[(y + 1) * (w + 1) + x]
                    - sat[y * (w + 1) + x];
        }
    }
    let s = side as usize;
    let mut best = (0usize, 0usize, f64::MIN);
    for y in 0..=h - s {
        for x in 0..=w - s {
            let sum = sat[(y + s) * (w + 1) + x + s]
                - sat[y * (w + 1) + x + s]
                - sat[(y + s) * (w + 1) + x]
                + sat[y * (w + 1) + x];
            if sum > best.2 {
                best = (x, y, sum);
            }
        }
    }
    (best.0 as u32, best.1 as u32, side)
}

/// Every image in a grid, the reference first: the image with the inset's square
/// outlined, under it the label (model and value, RMSE, FLIP, time and backend) and the
/// inset magnified.
pub(crate) fn grid_image(r: &Reference, rows: &[Row]) -> image::RgbImage {
    let zoom = TILE_MIN.div_ceil(r.frame.width).max(1);
    let (w, h) = (r.frame.width * zoom, r.frame.height * zoom);
    let line = TEXT_SIZE + 4.0;
    // Two title lines across the tile, then the figures at the left of the inset.
    let inset_side = w / 2 - 8;
    let title_h = (2.0 * line) as u32 + 4;
    let band = title_h + inset_side.max((3.0 * line) as u32) + 6;
    let region = inset_region(&r.frame, rows.iter().map(|row| &row.frame));
    let mut tiles: Vec<(&Frame, String, [String; 3])> = vec![(
        &r.frame,
        format!("reference, {} spp", r.spp),
        [
            format!("noise {:.1e}", r.noise_rmse),
            r.backend.split(' ').take(2).collect::<Vec<_>>().join(" "),
            String::new(),
        ],
    )];
    for row in rows {
        let title = if row.knob == "-" || row.model.contains(&row.value) {
            row.model.clone()
        } else {
            format!("{} {}={}", row.model, row.knob, row.value)
        };
        tiles.push((
            &row.frame,
            title,
            [
                format!("RMSE {:.2e}", row.rmse),
                format!("FLIP {:.4}", row.flip_mean),
                format!("{:.1} ms {}", row.ms_median, row.backend),
            ],
        ));
    }
    let cols = (tiles.len() as f64).sqrt().ceil() as u32;
    let rows_n = (tiles.len() as u32).div_ceil(cols);
    let gap = 4;
    let (tw, th) = (w + gap, h + band + gap);
    let mut img = image::RgbImage::from_pixel(cols * tw, rows_n * th, image::Rgb(BACKGROUND));
    for (i, (frame, title, figures)) in tiles.iter().enumerate() {
        let (x0, y0) = ((i as u32 % cols) * tw, (i as u32 / cols) * th);
        let rgb = frame.to_rgb8();
        let at = |x: u32, y: u32| {
            let k = 3 * (y * frame.width + x) as usize;
            image::Rgb([rgb[k], rgb[k + 1], rgb[k + 2]])
        };
        for y in 0..h {
            for x in 0..w {
                img.put_pixel(x0 + x, y0 + y, at(x / zoom, y / zoom));
            }
        }
        let top = (y0 + h + 3) as f32;
        for (l, part) in wrap(title, TEXT_SIZE, (w - 6) as f32)
            .iter()
            .take(2)
            .enumerate()
        {
            let y = top + l as f32 * line;
            text::draw_on(
                &mut img,
                part,
                TEXT_SIZE,
                (x0 as f32 + 3.0, y),
                INK,
                (w - 6) as f32,
            );
        }
        // The inset's square on the image, and the inset itself under it, at the right.
        let (rx, ry, rs) = region;
        outline(&mut img, x0 + rx * zoom, y0 + ry * zoom, rs * zoom, MARK);
        let (ix, iy) = (x0 + w - inset_side - 2, y0 + h + title_h);
        for y in 0..inset_side {
            for x in 0..inset_side {
                let (sx, sy) = (rx + x * rs / inset_side, ry + y * rs / inset_side);
                img.put_pixel(ix + x, iy + y, at(sx, sy));
            }
        }
        outline(&mut img, ix, iy, inset_side, MARK);
        let text_w = (w - inset_side - 10) as f32;
        for (l, part) in figures.iter().enumerate() {
            let y = (y0 + h + title_h) as f32 + l as f32 * line;
            text::draw_on(&mut img, part, TEXT_SIZE, (x0 as f32 + 3.0, y), INK, text_w);
        }
    }
    img
}

/// `s` in lines no wider than `max_w` pixels, broken at spaces (a word wider than a line
/// is cut when drawn).
fn wrap(s: &str, size: f32, max_w: f32) -> Vec<String> {
    let mut lines: Vec<String> = vec![String::new()];
    for word in s.split(' ') {
        let last = lines.last_mut().expect("one line at least");
        let candidate = if last.is_empty() {
            word.to_string()
        } else {
            format!("{last} {word}")
        };
        if text::measure(&candidate, size).0 <= max_w || last.is_empty() {
            *last = candidate;
        } else {
            lines.push(word.to_string());
        }
    }
    lines
}

/// A one-pixel square outline of side `s` at (x, y), clipped to the image.
fn outline(img: &mut image::RgbImage, x: u32, y: u32, s: u32, c: [u8; 3]) {
    let (w, h) = img.dimensions();
    let mut put = |px: u32, py: u32| {
        if px < w && py < h {
            img.put_pixel(px, py, image::Rgb(c));
        }
    };
    for k in 0..s {
        put(x + k, y);
        put(x + k, y + s - 1);
        put(x, y + k);
        put(x + s - 1, y + k);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inset_is_where_the_images_disagree() {
        let mut reference = Frame::new(60, 48);
        reference.pixels.iter_mut().for_each(|p| *p = [0.5; 3]);
        let mut other = reference.clone();
        // A 6x6 patch that differs, away from the corners.
        for y in 30..36 {
            for x in 40..46 {
                other.pixels[y * 60 + x] = [0.9; 3];
            }
        }
        let (x, y, side) = inset_region(&reference, [&other, &other].into_iter());
        assert_eq!(side, 8, "a sixth of 48, at least 8");
        assert!(
            (38..=40).contains(&x) && (28..=30).contains(&y),
            "({x}, {y})"
        );
        // Equal images: some square inside the image.
        let (x, y, side) = inset_region(&reference, std::iter::once(&reference));
        assert!(x + side <= 60 && y + side <= 48);
    }

    #[test]
    fn titles_wrap_at_spaces() {
        let lines = wrap(
            "cone at light's aperture (beer-lambert) step_factor=0.5",
            13.0,
            200.0,
        );
        assert!(lines.len() >= 2, "{lines:?}");
        for l in &lines {
            assert!(text::measure(l, 13.0).0 <= 200.0 || !l.contains(' '), "{l}");
        }
        assert_eq!(
            lines.join(" "),
            "cone at light's aperture (beer-lambert) step_factor=0.5"
        );
    }
}
