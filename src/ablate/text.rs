//! Text for the figures (the plot's PNG and the image grid), rasterized with `ab_glyph`
//! from a TTF bundled in a crate (Ubuntu Light, `epaint_default_fonts`), so no system
//! font is needed.
//!
//! plotters' own ab_glyph text places each glyph's bitmap at the pen position without its
//! bearing and truncates the baseline offset towards zero, so letters drift and jump
//! ("apert\u{1d41}re" at 13 px); here each glyph is positioned at its sub-pixel pen
//! position on one baseline, with kerning.

use ab_glyph::{Font, FontRef, PxScale, ScaleFont, point};

fn font() -> FontRef<'static> {
    FontRef::try_from_slice(epaint_default_fonts::UBUNTU_LIGHT)
        .expect("epaint_default_fonts ships a valid TTF")
}

/// A text's extent at `size` pixels: (width, height), height = ascent - descent.
pub fn measure(text: &str, size: f32) -> (f32, f32) {
    let font = font();
    let f = font.as_scaled(PxScale::from(size));
    let mut x = 0.0;
    let mut prev = None;
    for c in text.chars() {
        let id = f.glyph_id(c);
        if let Some(p) = prev {
            x += f.kern(p, id);
        }
        x += f.h_advance(id);
        prev = Some(id);
    }
    (x, f.ascent() - f.descent())
}

/// Calls `put(x, y, coverage)` for every pixel of `text` at `size` pixels whose box's
/// top-left corner is `(x0, y0)` (the baseline one ascent below it).
pub(crate) fn rasterize(
    text: &str,
    size: f32,
    x0: f32,
    y0: f32,
    mut put: impl FnMut(i32, i32, f32),
) {
    let font = font();
    let f = font.as_scaled(PxScale::from(size));
    let baseline = y0 + f.ascent();
    let mut x = x0;
    let mut prev = None;
    for c in text.chars() {
        let id = f.glyph_id(c);
        if let Some(p) = prev {
            x += f.kern(p, id);
        }
        let glyph = id.with_scale_and_position(PxScale::from(size), point(x, baseline));
        if let Some(outlined) = font.outline_glyph(glyph) {
            let b = outlined.px_bounds();
            outlined.draw(|gx, gy, coverage| {
                put(
                    b.min.x as i32 + gx as i32,
                    b.min.y as i32 + gy as i32,
                    coverage,
                );
            });
        }
        x += f.h_advance(id);
        prev = Some(id);
    }
}

/// Draws `text` onto an RGB image in `colour`, blended by coverage, clipped to the image
/// and to `max_w` pixels of width (whole glyphs past it are left out).
pub(crate) fn draw_on(
    img: &mut image::RgbImage,
    text: &str,
    size: f32,
    (x0, y0): (f32, f32),
    colour: [u8; 3],
    max_w: f32,
) {
    // Cut to whole characters that fit.
    let mut shown = String::new();
    for c in text.chars() {
        shown.push(c);
        if measure(&shown, size).0 > max_w {
            shown.pop();
            break;
        }
    }
    let (w, h) = (img.width() as i32, img.height() as i32);
    rasterize(&shown, size, x0, y0, |x, y, a| {
        if (0..w).contains(&x) && (0..h).contains(&y) {
            let p = img.get_pixel_mut(x as u32, y as u32);
            for k in 0..3 {
                let v = f32::from(p[k]) * (1.0 - a) + f32::from(colour[k]) * a;
                p[k] = v.round().clamp(0.0, 255.0) as u8;
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every glyph of a word sits on one baseline at every size: the coverage-weighted
    /// height of each copy of a repeated letter is the same ("apert\u{1d41}re" was a 'u'
    /// drawn a pixel high by plotters' own text).
    #[test]
    fn repeated_letters_sit_on_one_baseline() {
        for tenth in 100..200 {
            let size = tenth as f32 / 10.0;
            let advance = measure("u", size).0;
            let mut sums = [(0.0f32, 0.0f32); 6];
            rasterize("uuuuuu", size, 0.3, 0.0, |x, y, a| {
                let k = ((x as f32 + 0.5) / advance).floor().clamp(0.0, 5.0) as usize;
                sums[k].0 += a * y as f32;
                sums[k].1 += a;
            });
            let centres: Vec<f32> = sums.iter().map(|(ay, a)| ay / a).collect();
            let spread = centres
                .iter()
                .fold(0.0f32, |m, c| m.max((c - centres[0]).abs()));
            assert!(spread < 0.2, "size {size}: {centres:?}");
        }
    }

    #[test]
    fn measure_grows_with_the_text() {
        let (a, h) = measure("ab", 13.0);
        let (b, h2) = measure("abc", 13.0);
        assert!(b > a && a > 0.0);
        assert_eq!(h, h2);
        assert!((10.0..20.0).contains(&h), "{h}");
    }
}
