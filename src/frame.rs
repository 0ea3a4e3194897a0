//! What a render gives: the radiance frame, how it is displayed, and the rays and steps it
//! cost. Both tracers fill these; the outputs, metrics and viewer read them.

use std::time::Duration;

/// Linear RGB radiance per pixel, rows from the top. f32 is enough for storage; the CPU
/// reference computes in f64 and rounds once at the end.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

impl Frame {
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            pixels: vec![[0.0; 3]; width as usize * height as usize],
        }
    }

    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[(y * self.width + x) as usize]
    }

    /// The displayed value: radiance clamped to [0, 1] (the seed's framebuffer; no tone mapping).
    pub fn to_rgb8(&self) -> Vec<u8> {
        self.to_display_rgb8(DisplayTransform::default())
    }

    /// The displayed value under `t`: radiance times 2^exposure, clamped to [0, 1],
    /// stored linearly or sRGB-encoded.
    pub(crate) fn to_display_rgb8(&self, t: DisplayTransform) -> Vec<u8> {
        let scale = 2f32.powf(t.exposure as f32);
        self.pixels
            .iter()
            .flat_map(|p| {
                p.map(|c| {
                    let v = (c * scale).clamp(0.0, 1.0);
                    let v = match t.encoding {
                        DisplayEncoding::Linear => v,
                        DisplayEncoding::Srgb => srgb_encode(v),
                    };
                    (v * 255.0).round() as u8
                })
            })
            .collect()
    }

    pub fn all_finite(&self) -> bool {
        self.pixels.iter().all(|p| p.iter().all(|c| c.is_finite()))
    }
}

/// How a PNG stores radiance in 8 bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DisplayEncoding {
    /// The value itself (the seed's framebuffer: no gamma).
    #[default]
    Linear,
    /// The sRGB transfer function (IEC 61966-2-1), what a display expects.
    Srgb,
}

impl DisplayEncoding {
    pub fn name(self) -> &'static str {
        match self {
            DisplayEncoding::Linear => "linear",
            DisplayEncoding::Srgb => "srgb",
        }
    }
}

/// Radiance to a displayed 8-bit value: exposure (stops), clamp, encoding.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DisplayTransform {
    pub encoding: DisplayEncoding,
    /// Radiance is multiplied by 2^exposure first.
    pub exposure: f64,
}

impl DisplayTransform {
    /// The exposures a display takes, in stops either way: 2^32 shows a radiance of
    /// 2.3e-10 as white and 2^-32 one of 4.3e9, and the scale stays an f32's normal
    /// number (`Frame::to_display_rgb8`). The command line's `--exposure`, Python's
    /// `Image.save` and the viewer's control all take this range.
    pub const MAX_EXPOSURE: f64 = 32.0;

    /// `ev` if it is an exposure a display takes ([`Self::MAX_EXPOSURE`]), else what
    /// it must be.
    pub fn check_exposure(ev: f64) -> Result<f64, String> {
        if ev.is_finite() && ev.abs() <= Self::MAX_EXPOSURE {
            Ok(ev)
        } else {
            let m = Self::MAX_EXPOSURE;
            Err(format!(
                "exposure {ev}: must be a number of stops in [-{m}, {m}]"
            ))
        }
    }
}

/// The sRGB transfer function of a linear value in [0, 1] (IEC 61966-2-1).
pub fn srgb_encode(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Rays and voxel steps, counted by the tracer (not estimated).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayStats {
    pub primary: u64,
    /// Reflection and refraction rays.
    pub secondary: u64,
    pub shadow: u64,
    /// DDA steps from one voxel to the next, over all rays.
    pub voxel_steps: u64,
    /// Ray/triangle tests of triangle surfaces (`render.surface`), over all rays:
    /// counted by the CPU reference only (the GPU's counters stop at voxel steps).
    pub triangle_tests: u64,
    /// The secondary rays that start outside the grid heading away from it on some
    /// axis, which hit nothing: the kernel counts them without a pass of its ray-tree
    /// loop (`leaves_grid`, shaders/traversal.wgsl). Among `secondary`; the CPU
    /// reference traces them to nothing and counts them alike (`voxlab bench --lanes`).
    pub untraced: u64,
}

impl RayStats {
    pub fn total_rays(&self) -> u64 {
        self.primary + self.secondary + self.shadow
    }
}

impl std::ops::AddAssign for RayStats {
    fn add_assign(&mut self, o: Self) {
        self.primary += o.primary;
        self.secondary += o.secondary;
        self.shadow += o.shadow;
        self.voxel_steps += o.voxel_steps;
        self.triangle_tests += o.triangle_tests;
        self.untraced += o.untraced;
    }
}

/// One rendered frame with what it cost.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    pub frame: Frame,
    pub stats: RayStats,
    /// Time of the trace alone (uploads and readback excluded where the backend can tell,
    /// and the preparation always: `setup_time`).
    pub trace_time: Duration,
    /// Time spent before the trace preparing what it reads: the walk's own data (sparse
    /// tree, proximity field), triangle surfaces, cone pyramids, a shadow model's data.
    /// Both backends keep it out of `trace_time`, so a frame's time is comparable
    /// whichever backend traced it and however the preparation was cached.
    pub setup_time: Duration,
    /// What the walk's own data holds where the walk chose it within its budget
    /// ([`crate::sparse::Regions::summary`]; the plan's `walk data:` line).
    pub walk_data: Option<String>,
}

/// The luminance of linear RGB (ITU-R BT.709 weights), what the reconstructions' edge
/// stopping and variance read.
pub fn luminance(c: glam::DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// An image's primary hits and its shadow term apart from the rest of its radiance:
/// what a reconstruction filters and what guides it (`crate::technique::Reconstruction`).
/// Following E. Heitz, S. Hill and M. McGuire (I3D 2018), the filtered signal is the
/// visibility ratio `direct / unshadowed` of the primary hit's local light, not the
/// radiance, so texture, falloff and the light's shape stay sharp; the G-buffer (normal,
/// depth, material) stops the filter at geometric edges (Dammertz et al. 2010).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PrimaryLayers {
    pub width: u32,
    pub height: u32,
    /// The frames the means are over.
    pub frames: u32,
    /// The camera the primary rays left (a temporal reconstruction reprojects through
    /// it: `crate::frame::History`).
    pub camera: crate::scene::CameraFrame,
    /// Rows from the top, as [`Frame::pixels`].
    pub pixels: Vec<PrimaryPixel>,
}

/// One pixel of [`PrimaryLayers`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PrimaryPixel {
    /// Whether frame 0's primary ray hit a surface; the G-buffer is that hit's (frames
    /// that move the ray inside the pixel keep frame 0's, so the guide does not blur).
    pub hit: bool,
    /// The shading normal, facing the ray.
    pub normal: glam::DVec3,
    /// The hit's distance along the primary ray (world units).
    pub depth: f64,
    /// The shading material's index.
    pub material: u8,
    /// Mean over the frames of the primary hit's local light as the shadow model
    /// estimates it (albedo included; zero in a frame whose ray missed).
    pub direct: glam::DVec3,
    /// The same estimate, with the same samples, with every shadow segment clear.
    pub unshadowed: glam::DVec3,
    /// Means of the luminance of the frame's visibility ratio (per channel, as
    /// [`PrimaryPixel::visibility`]) and of its square, over the `ratio_frames` frames in
    /// which the unshadowed light's luminance was not zero:
    /// the temporal moments a variance estimate reads (Schied et al. 2017, section 4.2).
    pub ratio_moments: [f64; 2],
    pub ratio_frames: u32,
}

impl PrimaryPixel {
    /// Whether the filter reads this pixel: a hit with some unshadowed light, so its
    /// visibility ratio is defined.
    pub fn filtered(&self) -> bool {
        self.hit && luminance(self.unshadowed) > 0.0
    }

    /// The visibility ratio per channel (0 where a channel has no unshadowed light).
    pub fn visibility(&self) -> glam::DVec3 {
        let ratio = |d: f64, u: f64| if u > 0.0 { d / u } else { 0.0 };
        glam::DVec3::new(
            ratio(self.direct.x, self.unshadowed.x),
            ratio(self.direct.y, self.unshadowed.y),
            ratio(self.direct.z, self.unshadowed.z),
        )
    }
}

impl PrimaryLayers {
    pub fn get(&self, x: u32, y: u32) -> &PrimaryPixel {
        &self.pixels[(y * self.width + x) as usize]
    }

    /// Where pixel (x, y)'s primary hit lies: `depth` along the ray through the pixel
    /// centre (frame 0's ray may have left elsewhere inside the pixel; a reprojection
    /// reads the centre's, on both tracers).
    pub fn position(&self, x: u32, y: u32) -> glam::DVec3 {
        let dir = self.camera.primary_dir(x, y, self.width, self.height);
        self.camera.eye + self.get(x, y).depth * dir
    }
}

/// What a temporal reconstruction keeps of the previous frame of a camera path
/// (`[render] path_frames`) to reproject into the next: the frame's camera, its G-buffer
/// and its accumulated signal, per pixel. The tracers keep one per session
/// (`crate::Session`), emptied where a path starts; an image of another size starts
/// afresh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct History {
    pub width: u32,
    pub height: u32,
    pub camera: crate::scene::CameraFrame,
    /// Rows from the top.
    pub pixels: Vec<HistoryPixel>,
}

/// One pixel of [`History`]; `kept` is false where the frame filtered nothing (a miss,
/// no unshadowed light), and then nothing else is read.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HistoryPixel {
    pub kept: bool,
    pub normal: glam::DVec3,
    pub depth: f64,
    pub material: u8,
    /// The accumulated visibility ratio per channel.
    pub visibility: glam::DVec3,
    /// The accumulated moments of its luminance (mean, mean square).
    pub moments: [f64; 2],
    /// Frames of the path accumulated (real: a reprojection mixes its taps' lengths).
    pub length: f64,
}
