//! `voxlab bench --lanes`: how evenly a software driver's SIMD lanes share the ray
//! tree. The kernel traces one pixel per invocation (shaders/trace.wgsl, `main`), and
//! Mesa's software driver runs 8 invocations as one vector, a 4x2 block of pixels, whose
//! loops run until their slowest lane is done. The lanes' efficiency is what the
//! pixels of a vector trace over what the vector runs: the sum of its lanes' counts
//! over 8 times the largest. Its inverse bounds what any rebalancing of the tree across
//! lanes (a wavefront, a shared ray queue) could save on that loop.
//!
//! The counts are the CPU reference's (frame 0, every pixel its own tree, as the
//! kernel's rays): the passes of the ray-tree loop (the tree's primary and secondary
//! rays, as both tracers count them, less those the kernel counts without tracing,
//! `RayStats::untraced`) and the shadow rays each pixel casts.

use rayon::prelude::*;

use crate::cpu::{Prepared, trace_ray_with};
use crate::experiment::Experiment;
use crate::frame::RayStats;
use crate::plan::Plan;
use crate::sampling::SampleKey;

/// The pixels one SIMD vector of the kernel traces: `main`'s 4x2 blocks of its 8x8 tile.
pub const VECTOR_BLOCK: (u32, u32) = (4, 2);

/// One experiment's lanes at one image size.
#[derive(Clone, Debug)]
pub struct LaneRow {
    pub experiment: String,
    pub side: u32,
    /// Ray-tree rays (primary and secondary), the ray-tree loop's passes (those rays
    /// less the untraced) and shadow rays per pixel, means.
    pub tree_rays_per_pixel: f64,
    pub tree_passes_per_pixel: f64,
    pub shadow_rays_per_pixel: f64,
    /// [`efficiency`] of the passes and of the shadow rays.
    pub tree_efficiency: f64,
    pub shadow_efficiency: f64,
    /// Voxel steps per pixel (every walk of its tree, shadow walks included), and their
    /// [`efficiency`]: a coarser bound than the rays', as the kernel runs each walk's
    /// steps in step with the vector's other lanes' same walk, not a pixel's whole
    /// tree's; where it falls as a grid grows, the vectors run more idle steps a step.
    pub steps_per_pixel: f64,
    pub steps_efficiency: f64,
}

impl LaneRow {
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "experiment": self.experiment,
            "side": self.side,
            "tree_rays_per_pixel": self.tree_rays_per_pixel,
            "tree_passes_per_pixel": self.tree_passes_per_pixel,
            "shadow_rays_per_pixel": self.shadow_rays_per_pixel,
            "tree_lane_efficiency": self.tree_efficiency,
            "shadow_lane_efficiency": self.shadow_efficiency,
            "voxel_steps_per_pixel": self.steps_per_pixel,
            "voxel_steps_lane_efficiency": self.steps_efficiency,
        })
    }
}

/// What each pixel of `rows` of frame 0 traces (rows from the top, of a `width` x
/// `height` image), on the CPU reference: the same pixels, samples and trees as
/// `crate::cpu::render`, whose total these sum to.
pub fn pixel_stats(
    e: &Experiment,
    width: u32,
    height: u32,
    rows: std::ops::Range<u32>,
) -> Vec<RayStats> {
    let (settings, prepared) = prepare(e, width, height);
    pixels_of(e, &settings, &prepared, rows)
}

/// The experiment's settings at `width` x `height` and what its trees read, prepared once.
fn prepare(e: &Experiment, width: u32, height: u32) -> (crate::RenderSettings, Prepared) {
    let settings = crate::RenderSettings {
        width,
        height,
        ..e.settings.clone()
    };
    let prepared = Prepared::new(&e.scene, &settings, &Plan::new(&e.scene, &settings));
    (settings, prepared)
}

fn pixels_of(
    e: &Experiment,
    settings: &crate::RenderSettings,
    prepared: &Prepared,
    rows: std::ops::Range<u32>,
) -> Vec<RayStats> {
    let scene = &e.scene;
    let camera = scene.camera.frame();
    let (width, height) = (settings.width, settings.height);
    rows.into_par_iter()
        .flat_map_iter(|j| {
            (0..width).map(move |i| {
                let key = SampleKey {
                    pixel: j * width + i,
                    frame: 0,
                };
                let offset = settings.pixel_filter.offset(
                    settings.filter_width,
                    settings.seed,
                    key.pixel,
                    0,
                );
                let dir = camera.primary_dir_offset(i, j, width, height, offset);
                let mut stats = RayStats::default();
                trace_ray_with(scene, settings, prepared, key, camera.eye, dir, &mut stats);
                stats
            })
        })
        .collect()
}

/// What the vectors of [`VECTOR_BLOCK`] do and run over whole rows of blocks.
#[derive(Clone, Copy, Debug, Default)]
pub struct Lanes {
    /// The lanes' counts, summed.
    pub done: u64,
    /// 8 lanes times each vector's largest count, summed.
    pub run: u64,
}

impl Lanes {
    /// Adds `counts`, whole rows of blocks of a `width`-wide image (rows from the top;
    /// the last may be cut short by the image's edge), to the sums.
    pub fn add(&mut self, counts: &[u64], width: u32) {
        let (bw, bh) = VECTOR_BLOCK;
        let height = counts.len() as u32 / width.max(1);
        assert_eq!(counts.len(), (width * height) as usize);
        for by in (0..height).step_by(bh as usize) {
            for bx in (0..width).step_by(bw as usize) {
                let mut largest = 0;
                for y in by..(by + bh).min(height) {
                    for x in bx..(bx + bw).min(width) {
                        let c = counts[(y * width + x) as usize];
                        self.done += c;
                        largest = largest.max(c);
                    }
                }
                self.run += u64::from(bw * bh) * largest;
            }
        }
    }

    /// `done / run`: 1 when every lane of a vector does as much as the others (and when
    /// nothing is done).
    pub fn efficiency(&self) -> f64 {
        if self.run == 0 {
            1.0
        } else {
            self.done as f64 / self.run as f64
        }
    }
}

/// Sum of `counts` (a `width` x `height` image, rows from the top) over what the vectors
/// of [`VECTOR_BLOCK`] run: 8 lanes times each block's largest count, a block cut by the
/// image's edge still a whole vector (its lanes outside return at once). 1 when every
/// lane of a vector does as much as the others; 1 for an image of zeros.
pub fn efficiency(counts: &[u64], width: u32, height: u32) -> f64 {
    assert_eq!(counts.len(), (width * height) as usize);
    let mut lanes = Lanes::default();
    lanes.add(counts, width);
    lanes.efficiency()
}

/// Each experiment's lanes at `side` x `side`, traced a band of rows at a time so that
/// what it holds does not grow with the image.
pub fn bench_lanes(experiments: &[Experiment], side: u32) -> Vec<LaneRow> {
    // Whole rows of blocks: an even number of rows.
    const BAND: u32 = 64;
    experiments
        .iter()
        .map(|e| {
            let (settings, prepared) = prepare(e, side, side);
            let (mut tree, mut shadow, mut steps) =
                (Lanes::default(), Lanes::default(), Lanes::default());
            let mut rays = 0;
            for start in (0..side).step_by(BAND as usize) {
                let band = pixels_of(e, &settings, &prepared, start..(start + BAND).min(side));
                let counts = |f: fn(&RayStats) -> u64| band.iter().map(f).collect::<Vec<_>>();
                rays += band.iter().map(|s| s.primary + s.secondary).sum::<u64>();
                tree.add(&counts(passes), side);
                shadow.add(&counts(|s| s.shadow), side);
                steps.add(&counts(|s| s.voxel_steps), side);
            }
            let pixels = f64::from(side) * f64::from(side);
            LaneRow {
                experiment: e.name.clone(),
                side,
                tree_rays_per_pixel: rays as f64 / pixels,
                tree_passes_per_pixel: tree.done as f64 / pixels,
                shadow_rays_per_pixel: shadow.done as f64 / pixels,
                tree_efficiency: tree.efficiency(),
                shadow_efficiency: shadow.efficiency(),
                steps_per_pixel: steps.done as f64 / pixels,
                steps_efficiency: steps.efficiency(),
            }
        })
        .collect()
}

/// The passes of the kernel's ray-tree loop a pixel's tree takes: its rays less those
/// the kernel counts without tracing.
pub fn passes(s: &RayStats) -> u64 {
    s.primary + s.secondary - s.untraced
}

/// The rows as a Markdown table.
pub fn lanes_table(rows: &[LaneRow]) -> String {
    let mut t = String::from(
        "| experiment | image | tree rays a pixel | loop passes a pixel | lane efficiency | shadow rays a pixel | lane efficiency | voxel steps a pixel | lane efficiency |\n\
         |---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        t += &format!(
            "| {} | {}x{} | {:.2} | {:.2} | {:.3} | {:.2} | {:.3} | {:.2} | {:.3} |\n",
            r.experiment,
            r.side,
            r.side,
            r.tree_rays_per_pixel,
            r.tree_passes_per_pixel,
            r.tree_efficiency,
            r.shadow_rays_per_pixel,
            r.shadow_efficiency,
            r.steps_per_pixel,
            r.steps_efficiency
        );
    }
    t
}
