//! How the viewer shows its two images: the view mode (split, either side alone for an
//! A/B flip on the same pixels, their difference, their FLIP error map), the display
//! transform (exposure, sRGB or the seed's linear framebuffer), the zoom (fit, or whole
//! screen pixels per image pixel, sampled nearest so pixels stay pixels) and the pixel
//! probe's geometry. No GPU and no window: the app draws what these functions give.

use eframe::egui::{Color32, ColorImage, Pos2, Rect, Vec2, pos2};

use crate::frame::{DisplayEncoding, DisplayTransform, Frame};

/// What the image area shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewMode {
    /// Left image left of the divider, right image right of it.
    Split,
    /// One side over the whole image: flipping between the two (the B key) compares the
    /// same pixels.
    Left,
    Right,
    /// |left - right| per channel, times the difference gain, displayed.
    Difference,
    /// FLIP's error map of the right side against the left (magma: black = equal).
    Flip,
}

impl ViewMode {
    pub(crate) const ALL: [ViewMode; 5] = [
        ViewMode::Split,
        ViewMode::Left,
        ViewMode::Right,
        ViewMode::Difference,
        ViewMode::Flip,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ViewMode::Split => "split",
            ViewMode::Left => "left only",
            ViewMode::Right => "right only",
            ViewMode::Difference => "difference |L - R|",
            ViewMode::Flip => "FLIP map (R vs L)",
        }
    }

    /// Whether the image is computed from both sides.
    pub fn compares(self) -> bool {
        matches!(self, ViewMode::Difference | ViewMode::Flip)
    }

    /// The A/B flip: split or a comparison goes to one side, one side to the other.
    pub fn flipped(self) -> ViewMode {
        match self {
            ViewMode::Left => ViewMode::Right,
            _ => ViewMode::Left,
        }
    }
}

/// How much of the image area one image pixel takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Zoom {
    /// The whole image, as large as the area allows.
    Fit,
    /// This many physical screen pixels per image pixel.
    Pixels(u32),
}

impl Zoom {
    pub(crate) const ALL: [Zoom; 5] = [
        Zoom::Fit,
        Zoom::Pixels(1),
        Zoom::Pixels(2),
        Zoom::Pixels(4),
        Zoom::Pixels(8),
    ];

    pub fn name(self) -> String {
        match self {
            Zoom::Fit => "fit".into(),
            Zoom::Pixels(n) => format!("{n}:1"),
        }
    }
}

/// The display settings of the image area.
#[derive(Clone, Debug, PartialEq)]
pub struct Display {
    pub mode: ViewMode,
    /// Stops: radiance times 2^exposure before the clamp.
    pub exposure: f64,
    /// sRGB-encode for the screen; off, the seed's linear framebuffer (what `voxlab
    /// render` writes by default).
    pub srgb: bool,
    pub zoom: Zoom,
    /// Gain of the difference view.
    pub difference_gain: f32,
    /// Image pixel at the centre of a zoomed view (`None`: the image's centre).
    pub centre: Option<(f32, f32)>,
}

impl Default for Display {
    fn default() -> Self {
        Self {
            mode: ViewMode::Split,
            exposure: 0.0,
            srgb: false,
            zoom: Zoom::Fit,
            difference_gain: 4.0,
            centre: None,
        }
    }
}

impl Display {
    pub fn transform(&self) -> DisplayTransform {
        DisplayTransform {
            encoding: if self.srgb {
                DisplayEncoding::Srgb
            } else {
                DisplayEncoding::Linear
            },
            exposure: self.exposure,
        }
    }

    /// `frame` as the screen shows it.
    pub fn image(&self, frame: &Frame) -> ColorImage {
        ColorImage::from_rgb(
            [frame.width as usize, frame.height as usize],
            &frame.to_display_rgb8(self.transform()),
        )
    }

    /// Where the image of `size` pixels goes in `area` (points; `pixels_per_point` of
    /// the screen): fitted, or at the zoom's scale around `centre`, clipped by the caller.
    pub(crate) fn image_rect(&self, area: Rect, size: (u32, u32), pixels_per_point: f32) -> Rect {
        let (w, h) = (size.0.max(1) as f32, size.1.max(1) as f32);
        match self.zoom {
            Zoom::Fit => {
                let aspect = w / h;
                let s = if area.width() / area.height().max(1.0) > aspect {
                    Vec2::new(area.height() * aspect, area.height())
                } else {
                    Vec2::new(area.width(), area.width() / aspect)
                };
                Rect::from_center_size(area.center(), s)
            }
            Zoom::Pixels(n) => {
                let scale = n as f32 / pixels_per_point.max(1e-3);
                let (cx, cy) = self.centre.unwrap_or((w / 2.0, h / 2.0));
                let min = area.center() - Vec2::new(cx * scale, cy * scale);
                Rect::from_min_size(min, Vec2::new(w * scale, h * scale))
            }
        }
    }
}

/// The image pixel under `pos`, for an image of `size` drawn over `rect`.
pub(crate) fn pixel_at(rect: Rect, size: (u32, u32), pos: Pos2) -> Option<(u32, u32)> {
    if !rect.contains(pos) || rect.width() <= 0.0 || rect.height() <= 0.0 {
        return None;
    }
    let u = (pos.x - rect.left()) / rect.width();
    let v = (pos.y - rect.top()) / rect.height();
    let x = ((u * size.0 as f32) as u32).min(size.0.saturating_sub(1));
    let y = ((v * size.1 as f32) as u32).min(size.1.saturating_sub(1));
    Some((x, y))
}

/// The centre of image pixel `(x, y)` on screen, for an image of `size` over `rect`.
pub(crate) fn pixel_centre(rect: Rect, size: (u32, u32), (x, y): (u32, u32)) -> Pos2 {
    pos2(
        rect.left() + (x as f32 + 0.5) / size.0 as f32 * rect.width(),
        rect.top() + (y as f32 + 0.5) / size.1 as f32 * rect.height(),
    )
}

/// The absolute difference of two frames of one size, per channel, linear: what the
/// difference view shows and what a save writes as EXR.
pub fn difference(a: &Frame, b: &Frame) -> Option<Frame> {
    if (a.width, a.height) != (b.width, b.height) {
        return None;
    }
    let mut d = Frame::new(a.width, a.height);
    for (o, (p, q)) in d.pixels.iter_mut().zip(a.pixels.iter().zip(&b.pixels)) {
        *o = [
            (p[0] - q[0]).abs(),
            (p[1] - q[1]).abs(),
            (p[2] - q[2]).abs(),
        ];
    }
    Some(d)
}

/// The difference view's image: |a - b| times `gain`, clamped, shown through `display`.
pub fn difference_image(display: &Display, a: &Frame, b: &Frame) -> Option<ColorImage> {
    let mut d = difference(a, b)?;
    for p in &mut d.pixels {
        for c in p.iter_mut() {
            *c *= display.difference_gain;
        }
    }
    Some(display.image(&d))
}

/// FLIP of `b` against `a` (both as an sRGB display shows them, `metrics::flip`): its
/// mean and the magma-coloured map.
pub(crate) fn flip_image(a: &Frame, b: &Frame) -> Option<(f64, ColorImage)> {
    if (a.width, a.height) != (b.width, b.height) {
        return None;
    }
    let (mean, map) = crate::metrics::flip(a, b);
    let image = ColorImage::from_rgb([a.width as usize, a.height as usize], map.as_raw());
    Some((mean, image))
}

/// The colour bar of a comparison view: what its colours mean. `colours` run from `lo`
/// to `hi` of `quantity`, as the view draws them.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ColourBar {
    pub quantity: &'static str,
    pub lo: f64,
    pub hi: f64,
    pub colours: Vec<Color32>,
}

impl ColourBar {
    /// The bar's caption: the quantity and the range its colours span.
    pub fn caption(&self) -> String {
        format!("{} {} .. {}", self.quantity, self.lo, tidy(self.hi))
    }
}

/// A number in few digits, for a caption.
fn tidy(v: f64) -> String {
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "0" && v > 0.0 {
        format!("{v:.2e}")
    } else {
        s.to_string()
    }
}

/// The colour bar of `display`'s comparison view (`None` in the other views): FLIP's
/// magma over 0 to 1; for the difference, grey from 0 to the radiance difference shown
/// as white, `1 / (gain 2^exposure)`, through the display's encoding.
pub(crate) fn colour_bar(display: &Display) -> Option<ColourBar> {
    const STEPS: usize = 64;
    match display.mode {
        ViewMode::Flip => {
            let lut = nv_flip::magma_lut().to_vec();
            let colours = (0..STEPS)
                .map(|k| {
                    let i = (k * 255 / (STEPS - 1)) * 3;
                    Color32::from_rgb(lut[i], lut[i + 1], lut[i + 2])
                })
                .collect();
            Some(ColourBar {
                quantity: "FLIP error",
                lo: 0.0,
                hi: 1.0,
                colours,
            })
        }
        ViewMode::Difference => {
            let white =
                1.0 / (f64::from(display.difference_gain) * 2f64.powf(display.exposure)).max(1e-30);
            let mut ramp = Frame::new(STEPS as u32, 1);
            for (k, p) in ramp.pixels.iter_mut().enumerate() {
                // The view multiplies |L - R| by the gain, then shows it as any image.
                let d = white * k as f64 / (STEPS - 1) as f64;
                *p = [(d * f64::from(display.difference_gain)) as f32; 3];
            }
            let image = display.image(&ramp);
            Some(ColourBar {
                quantity: "|L - R| radiance",
                lo: 0.0,
                hi: white,
                colours: image.pixels,
            })
        }
        _ => None,
    }
}

/// A stale image (of an earlier camera or setting, while the new one renders) is shown
/// dimmed under this tint, never as current.
pub(crate) const STALE_TINT: Color32 = Color32::from_gray(90);

#[cfg(test)]
mod tests {
    use super::*;

    /// The difference bar ends in white exactly at the radiance difference the view
    /// shows as white, at any gain and exposure; the FLIP bar is FLIP's magma map.
    #[test]
    fn colour_bars_say_what_the_colours_mean() {
        for (gain, exposure) in [(4.0, 0.0), (1.0, 2.0), (100.0, -3.0)] {
            let d = Display {
                mode: ViewMode::Difference,
                difference_gain: gain,
                exposure,
                ..Display::default()
            };
            let bar = colour_bar(&d).unwrap();
            assert!((bar.hi - 1.0 / (f64::from(gain) * 2f64.powf(exposure))).abs() < 1e-12);
            assert_eq!(*bar.colours.first().unwrap(), Color32::from_rgb(0, 0, 0));
            assert_eq!(
                *bar.colours.last().unwrap(),
                Color32::from_rgb(255, 255, 255)
            );
            // One step below white is not white: the range is not wider than shown.
            assert_ne!(bar.colours[bar.colours.len() - 2], Color32::WHITE);
        }
        let flip = colour_bar(&Display {
            mode: ViewMode::Flip,
            ..Display::default()
        })
        .unwrap();
        assert_eq!((flip.lo, flip.hi), (0.0, 1.0));
        // FLIP's own map: magma from near black (0, 0, 4) to its pale yellow at 1.
        let lut = nv_flip::magma_lut().to_vec();
        assert_eq!(flip.colours[0], Color32::from_rgb(lut[0], lut[1], lut[2]));
        let end = flip.colours.last().unwrap();
        assert_eq!(*end, Color32::from_rgb(lut[765], lut[766], lut[767]));
        assert!(colour_bar(&Display::default()).is_none());
    }

    #[test]
    fn fit_keeps_the_aspect_and_pixels_map_back() {
        let d = Display::default();
        let area = Rect::from_min_size(pos2(10.0, 20.0), Vec2::new(400.0, 300.0));
        let r = d.image_rect(area, (128, 64), 1.0);
        assert!((r.width() / r.height() - 2.0).abs() < 1e-4);
        assert_eq!(r.width(), 400.0);
        assert_eq!(pixel_at(r, (128, 64), r.min), Some((0, 0)));
        assert_eq!(
            pixel_at(r, (128, 64), r.max - Vec2::splat(0.01)),
            Some((127, 63))
        );
        let c = pixel_centre(r, (128, 64), (5, 7));
        assert_eq!(pixel_at(r, (128, 64), c), Some((5, 7)));
        assert_eq!(pixel_at(r, (128, 64), pos2(0.0, 0.0)), None);
    }

    #[test]
    fn one_to_one_is_one_physical_pixel_per_image_pixel() {
        let d = Display {
            zoom: Zoom::Pixels(1),
            ..Default::default()
        };
        let area = Rect::from_min_size(pos2(0.0, 0.0), Vec2::new(1000.0, 800.0));
        // At 2 physical pixels per point, 128 image pixels take 64 points.
        let r = d.image_rect(area, (128, 128), 2.0);
        assert_eq!(r.width(), 64.0);
        assert_eq!(r.center(), area.center());
        let d4 = Display {
            zoom: Zoom::Pixels(4),
            centre: Some((0.0, 0.0)),
            ..Default::default()
        };
        let r = d4.image_rect(area, (128, 128), 1.0);
        assert_eq!(r.width(), 512.0);
        assert_eq!(r.min, area.center(), "the chosen pixel at the centre");
    }

    #[test]
    fn difference_and_the_display_transform() {
        let mut a = Frame::new(2, 1);
        let mut b = Frame::new(2, 1);
        a.pixels = vec![[0.5, 0.2, 0.1], [0.0; 3]];
        b.pixels = vec![[0.25, 0.2, 0.3], [0.0; 3]];
        let d = difference(&a, &b).unwrap();
        for (got, want) in d.pixels[0].iter().zip([0.25, 0.0, 0.2]) {
            assert!((got - want).abs() < 1e-6, "{:?}", d.pixels[0]);
        }
        assert!(difference(&a, &Frame::new(1, 1)).is_none());
        let display = Display {
            difference_gain: 2.0,
            ..Default::default()
        };
        let img = difference_image(&display, &a, &b).unwrap();
        assert_eq!(img.pixels[0], Color32::from_rgb(128, 0, 102));
        // Exposure and sRGB: one stop up doubles, sRGB brightens a mid value.
        let bright = Display {
            exposure: 1.0,
            ..Default::default()
        };
        assert_eq!(bright.image(&a).pixels[0].r(), 255);
        let srgb = Display {
            srgb: true,
            ..Default::default()
        };
        assert!(srgb.image(&b).pixels[0].r() > 128);
    }

    #[test]
    fn the_ab_flip_alternates_the_sides() {
        assert_eq!(ViewMode::Split.flipped(), ViewMode::Left);
        assert_eq!(ViewMode::Left.flipped(), ViewMode::Right);
        assert_eq!(ViewMode::Right.flipped(), ViewMode::Left);
        assert_eq!(ViewMode::Flip.flipped(), ViewMode::Left);
    }
}
