//! The CPU reference tracer: the model of `src/trace_contract.md`, implemented independently
//! of the WGSL kernel, in f64, parallel over rows with rayon. It is the oracle of the
//! tests and the fallback renderer when no GPU adapter exists. It follows
//! `src/trace_contract.md` to the letter.

use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;

pub use crate::sampling::SampleKey;
use crate::technique::shading::ShadowWalk;

use crate::dda::cast_through;
use crate::frame::{Frame, PrimaryLayers, PrimaryPixel, RayStats, RenderOutput, luminance};
use crate::plan::Plan;
use crate::ray_cutoff::{light_shaded, spawned, traced};
use crate::render::{RenderSettings, Rules};
use crate::scene::{Dielectric, Scene, fresnel_dielectric_at};
use crate::sparse::Regions;
use crate::triangles::SurfaceTrace;

/// What the CPU backend is, for printing next to a GPU adapter's name.
pub fn backend_summary() -> String {
    format!(
        "CPU reference (f64, rayon, {} threads)",
        rayon::current_num_threads()
    )
}

/// The machine's processor, for benchmark headers: a software GPU (lavapipe) runs on it
/// too, and the code its LLVM makes differs with the vector extensions it finds, so
/// figures from two hosts compare only with this beside them.
pub fn host_summary() -> String {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let field = |key: &str| {
        cpuinfo.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            (k.trim() == key).then(|| v.trim().to_string())
        })
    };
    let model = field("model name").unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let id = match (field("cpu family"), field("model")) {
        (Some(f), Some(m)) => format!(" (family {f}, model {m})"),
        _ => String::new(),
    };
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{model}{id}, {threads} hardware threads{}", simd_summary())
}

#[cfg(target_arch = "x86_64")]
fn simd_summary() -> &'static str {
    if std::arch::is_x86_feature_detected!("avx512f") {
        ", AVX-512"
    } else if std::arch::is_x86_feature_detected!("avx2") {
        ", AVX2"
    } else {
        ""
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn simd_summary() -> &'static str {
    ""
}

/// Renders the scene: `settings.spp` frames, each tracing every pixel independently
/// (so the image does not depend on the thread count), averaged in f64 so accumulation
/// never drifts. When nothing is sampled every frame is the same image, so one is
/// rendered ([`Plan::frames`], as the GPU does).
pub fn render(scene: &Scene, settings: &RenderSettings) -> RenderOutput {
    render_region(scene, settings, 0..settings.width, 0..settings.height)
}

/// The pixels `columns` x `rows` of [`render`]'s image (bit for bit the same values, so
/// a crop of a large GPU image can be checked against the reference cheaply); the
/// frame returned is the crop's size.
pub fn render_region(
    scene: &Scene,
    settings: &RenderSettings,
    columns: std::ops::Range<u32>,
    rows: std::ops::Range<u32>,
) -> RenderOutput {
    render_region_with_progress(
        scene,
        settings,
        (columns, rows),
        None,
        &mut None,
        Walks::Build,
    )
}

/// What holds walk data already built: the build of a key where it holds one (a GPU
/// tracer's latest builds, `crate::gpu::GpuTracer::kept_walk_data`).
pub type KeptWalkData<'a> =
    &'a dyn Fn(&crate::technique::WalkKey) -> Option<std::sync::Arc<dyn Regions>>;

/// [`render_region`], walking the data `kept` holds for the render's walk instead of
/// building it again where it holds the same (the same traversal, dims, voxels and
/// budget): `render --check` of a GPU render at 2048^3 built the 30 s of walk data a
/// second time. The image is the same bit for bit; `setup_time` then leaves out the
/// build.
pub fn render_region_reusing(
    scene: &Scene,
    settings: &RenderSettings,
    columns: std::ops::Range<u32>,
    rows: std::ops::Range<u32>,
    kept: KeptWalkData,
) -> RenderOutput {
    render_region_with_progress(
        scene,
        settings,
        (columns, rows),
        None,
        &mut None,
        Walks::Kept(kept),
    )
}

/// [`render`], telling `progress` of each finished row.
pub fn render_with_progress(
    scene: &Scene,
    settings: &RenderSettings,
    progress: Option<&crate::progress::Progress>,
) -> RenderOutput {
    render_with_history(scene, settings, progress, &mut None)
}

/// [`render_with_progress`], with a temporal reconstruction accumulating onto
/// `history` (a camera path's previous frame, `None` where it starts), which becomes
/// this frame's.
pub fn render_with_history(
    scene: &Scene,
    settings: &RenderSettings,
    progress: Option<&crate::progress::Progress>,
    history: &mut Option<crate::frame::History>,
) -> RenderOutput {
    let whole = (0..settings.width, 0..settings.height);
    render_region_with_progress(scene, settings, whole, progress, history, Walks::Build)
}

/// [`render_with_history`], taking the walk's data from `builds` where it keeps the
/// render's and keeping it there where it does not, and summing the frames from those
/// `prior` holds (of the same scene, settings and plan: the caller's to check): a CPU
/// [`crate::Session`]'s renders. With the image, the sums of its frames.
pub(crate) fn render_keeping(
    scene: &Scene,
    settings: &RenderSettings,
    progress: Option<&crate::progress::Progress>,
    history: &mut Option<crate::frame::History>,
    (builds, surface): (&mut crate::technique::WalkBuilds, &mut KeptSurface),
    prior: Option<&FrameSums>,
) -> (RenderOutput, FrameSums) {
    let setup = Instant::now();
    let plan = Plan::new(scene, settings);
    let prepared = Prepared::prepare(scene, settings, &plan, Walks::Keep(builds, surface));
    let setup_time = setup.elapsed();
    let whole = (0..settings.width, 0..settings.height);
    let (out, sums) = trace_region(
        scene, settings, &plan, &prepared, whole, progress, history, prior,
    );
    (RenderOutput { setup_time, ..out }, sums)
}

/// Where a render's walk data comes from.
enum Walks<'a> {
    /// Built for the render.
    Build,
    /// From what another tracer holds where it holds the same, else built.
    Kept(KeptWalkData<'a>),
    /// From builds kept across renders, and kept there; likewise the triangle surface.
    Keep(&'a mut crate::technique::WalkBuilds, &'a mut KeptSurface),
}

/// The triangle surface a CPU session traced last, by [`crate::render::Surface::trace_key`]:
/// a render of the same grid and mesh lists it again from there (the glass bunny's
/// mesh took 150 ms a render to list, before a trace of milliseconds at 16x16).
pub(crate) type KeptSurface = Option<(blake3::Hash, Arc<SurfaceTrace>)>;

fn render_region_with_progress(
    scene: &Scene,
    settings: &RenderSettings,
    region: (std::ops::Range<u32>, std::ops::Range<u32>),
    progress: Option<&crate::progress::Progress>,
    history: &mut Option<crate::frame::History>,
    walks: Walks,
) -> RenderOutput {
    let setup = Instant::now();
    let plan = Plan::new(scene, settings);
    // Pyramids (and a plug-in model's data) once per render, only when planned.
    let prepared = Prepared::prepare(scene, settings, &plan, walks);
    let setup_time = setup.elapsed();
    let (out, _) = trace_region(
        scene, settings, &plan, &prepared, region, progress, history, None,
    );
    RenderOutput { setup_time, ..out }
}

/// [`render`] with what it reads prepared already (`Prepared::new` for the same scene,
/// settings and plan): what a caller that renders one scene many times calls, so that
/// its walk's data and pyramids are built once. `setup_time` is zero.
pub(crate) fn render_prepared(
    scene: &Scene,
    settings: &RenderSettings,
    plan: &Plan,
    prepared: &Prepared,
) -> RenderOutput {
    trace_region(
        scene,
        settings,
        plan,
        prepared,
        (0..settings.width, 0..settings.height),
        None,
        &mut None,
        None,
    )
    .0
}

/// The pixels `columns` x `rows` of the image; a temporal reconstruction accumulates
/// onto `history`; the frames `prior` holds (the region's first) are summed from there.
#[allow(clippy::too_many_arguments)]
fn trace_region(
    scene: &Scene,
    settings: &RenderSettings,
    plan: &Plan,
    prepared: &Prepared,
    (columns, rows): (std::ops::Range<u32>, std::ops::Range<u32>),
    progress: Option<&crate::progress::Progress>,
    history: &mut Option<crate::frame::History>,
    prior: Option<&FrameSums>,
) -> (RenderOutput, FrameSums) {
    let start = Instant::now();
    let reconstruction = plan.reconstruction;
    if reconstruction.cpu.is_none() {
        let (means, _, stats, sums) = trace_means(
            scene,
            settings,
            plan,
            prepared,
            (columns.clone(), rows.clone()),
            false,
            progress,
            prior,
        );
        let out = RenderOutput {
            frame: frame_of(&means, columns.len() as u32, rows.len() as u32),
            stats,
            trace_time: start.elapsed(),
            setup_time: Duration::ZERO,
            walk_data: prepared.regions.as_ref().and_then(|r| r.summary()),
        };
        return (out, sums);
    }
    // A filter reads around each pixel: the region is traced as far wider as it reads,
    // so a crop is filtered as the whole image is (clamped at the image's edges, as
    // there), then cut back.
    let reach = (reconstruction.reach)(&reconstruction.values(settings));
    let wide = |r: &std::ops::Range<u32>, side: u32| {
        r.start.saturating_sub(reach)..r.end.saturating_add(reach).min(side)
    };
    let (wide_columns, wide_rows) = (wide(&columns, settings.width), wide(&rows, settings.height));
    let (means, layers, stats, sums) = trace_means(
        scene,
        settings,
        plan,
        prepared,
        (wide_columns.clone(), wide_rows.clone()),
        true,
        progress,
        prior,
    );
    let layers = layers.expect("asked for");
    let filtered = reconstruction.apply(&layers, &means, settings, history);
    let wide_width = wide_columns.len();
    let (x0, y0) = (
        (columns.start - wide_columns.start) as usize,
        (rows.start - wide_rows.start) as usize,
    );
    let crop: Vec<DVec3> = (0..rows.len())
        .flat_map(|j| {
            let at = (y0 + j) * wide_width + x0;
            filtered[at..at + columns.len()].to_vec()
        })
        .collect();
    let out = RenderOutput {
        frame: frame_of(&crop, columns.len() as u32, rows.len() as u32),
        stats,
        trace_time: start.elapsed(),
        setup_time: Duration::ZERO,
        walk_data: prepared.regions.as_ref().and_then(|r| r.summary()),
    };
    (out, sums)
}

/// A frame of `width` x `height` pixels from their f64 values, each rounded once.
fn frame_of(means: &[DVec3], width: u32, height: u32) -> Frame {
    let mut frame = Frame::new(width, height);
    for (p, c) in frame.pixels.iter_mut().zip(means) {
        *p = [c.x as f32, c.y as f32, c.z as f32];
    }
    frame
}

/// Per-pixel sums in f64 of a region's frames `0..frames`, rows from the top (and,
/// where a reconstruction reads them, of its primary layers): what a CPU session keeps
/// to continue an accumulation, as the GPU tracer keeps its sums in its buffers. The
/// sums of frames `0..n` continued over `n..m` are, bit for bit, those of `0..m`: each
/// pixel's frames are added in order either way.
#[derive(Clone, Default)]
pub(crate) struct FrameSums {
    frames: u32,
    radiance: Vec<DVec3>,
    /// Empty where the render read no layers.
    layers: Vec<PrimaryPixel>,
}

impl FrameSums {
    /// The frames summed: `0..frames`.
    pub(crate) fn frames(&self) -> u32 {
        self.frames
    }
}

/// Every pixel of the region, the mean of its frames in f64, rows from the top; with
/// `layers`, also the primary layers a reconstruction reads (`crate::frame::PrimaryLayers`);
/// and the sums of which they are the means. The frames `prior` holds (0..n of the same
/// region) are not traced again: they are summed from there.
#[allow(clippy::too_many_arguments)]
fn trace_means(
    scene: &Scene,
    settings: &RenderSettings,
    plan: &Plan,
    prepared: &Prepared,
    (columns, rows): (std::ops::Range<u32>, std::ops::Range<u32>),
    layers: bool,
    progress: Option<&crate::progress::Progress>,
    prior: Option<&FrameSums>,
) -> (Vec<DVec3>, Option<PrimaryLayers>, RayStats, FrameSums) {
    let rows_done = std::sync::atomic::AtomicU64::new(0);
    let row_count = rows.len() as u64;
    let frame_cam = scene.camera.frame();
    let (w, h) = (settings.width, settings.height);
    let frames = plan.frames(settings);
    let first = prior.map_or(0, |p| p.frames);
    if let Some(p) = prior {
        assert!(
            p.radiance.len() == columns.len() * rows.len()
                && p.layers.len() == if layers { p.radiance.len() } else { 0 }
                && first <= frames,
            "a continued accumulation is of the same region, layers and fewer frames"
        );
    }
    type Row = (Vec<DVec3>, Vec<PrimaryPixel>, RayStats);
    let out: Vec<Row> = rows
        .clone()
        .into_par_iter()
        .map(|j| {
            let mut stats = RayStats::default();
            // A stopped render skips its remaining rows; the caller discards the image.
            if progress.is_some_and(|p| p.stopped()) {
                let n = columns.len();
                let kept = if layers { n } else { 0 };
                return (
                    vec![DVec3::ZERO; n],
                    vec![PrimaryPixel::default(); kept],
                    stats,
                );
            }
            let mut row_layers = Vec::new();
            let row = columns
                .clone()
                .map(|i| {
                    let at =
                        (j - rows.start) as usize * columns.len() + (i - columns.start) as usize;
                    let mut sum = prior.map_or(DVec3::ZERO, |p| p.radiance[at]);
                    let mut layer = prior
                        .filter(|_| layers)
                        .map_or_else(PrimaryPixel::default, |p| p.layers[at]);
                    for frame in first..frames {
                        let key = SampleKey {
                            pixel: j * w + i,
                            frame,
                        };
                        let offset = settings.pixel_filter.offset(
                            settings.filter_width,
                            settings.seed,
                            key.pixel,
                            frame,
                        );
                        let dir = frame_cam.primary_dir_offset(i, j, w, h, offset);
                        let mut primary = PrimarySample::default();
                        sum += trace_tree(
                            scene,
                            settings,
                            prepared,
                            key,
                            frame_cam.eye,
                            dir,
                            &mut stats,
                            layers.then_some(&mut primary),
                        );
                        if layers {
                            primary.add_to(&mut layer, frame == 0);
                        }
                    }
                    if layers {
                        row_layers.push(layer);
                    }
                    sum
                })
                .collect();
            if let Some(p) = progress {
                let done = rows_done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                p.update(done, row_count);
            }
            (row, row_layers, stats)
        })
        .collect();
    let mut sums = FrameSums {
        frames,
        radiance: Vec::with_capacity(columns.len() * rows.len()),
        layers: Vec::new(),
    };
    let mut stats = RayStats::default();
    for (row, row_layers, s) in out {
        sums.radiance.extend(row);
        sums.layers.extend(row_layers);
        stats += s;
    }
    let means = sums.radiance.iter().map(|s| s / frames as f64).collect();
    let layers = layers.then(|| PrimaryLayers {
        width: columns.len() as u32,
        height: rows.len() as u32,
        frames,
        camera: frame_cam,
        pixels: sums.layers.iter().map(|l| l.mean_over(frames)).collect(),
    });
    (means, layers, stats, sums)
}

/// What one frame's primary ray found, for a reconstruction's layers.
#[derive(Clone, Copy, Default)]
struct PrimarySample {
    hit: bool,
    normal: DVec3,
    depth: f64,
    material: u8,
    /// The primary hit's local light, as shaded, and with every shadow segment clear.
    direct: DVec3,
    unshadowed: DVec3,
}

impl PrimarySample {
    /// Adds this frame to the sums in `layer` (the G-buffer taken from the first frame).
    fn add_to(&self, layer: &mut PrimaryPixel, first: bool) {
        if first {
            layer.hit = self.hit;
            layer.normal = self.normal;
            layer.depth = self.depth;
            layer.material = self.material;
        }
        layer.direct += self.direct;
        layer.unshadowed += self.unshadowed;
        let frame = PrimaryPixel {
            direct: self.direct,
            unshadowed: self.unshadowed,
            ..PrimaryPixel::default()
        };
        if luminance(self.unshadowed) > 0.0 {
            let l = luminance(frame.visibility());
            layer.ratio_moments[0] += l;
            layer.ratio_moments[1] += l * l;
            layer.ratio_frames += 1;
        }
    }
}

impl PrimaryPixel {
    /// Sums over `frames` frames (`PrimarySample::add_to`) to means.
    fn mean_over(mut self, frames: u32) -> Self {
        self.direct /= frames as f64;
        self.unshadowed /= frames as f64;
        if self.ratio_frames > 0 {
            let n = self.ratio_frames as f64;
            self.ratio_moments = self.ratio_moments.map(|m| m / n);
        }
        self
    }
}

/// One entry of the explicit ray stack (the recursion of Whitted's model unrolled).
struct StackRay {
    origin: DVec3,
    dir: DVec3,
    throughput: DVec3,
    reflection_depth: u32,
    refraction_depth: u32,
    medium: u8,
    /// The weight the ray cutoff compares, in f32 as the kernel's throughput
    /// (`crate::ray_cutoff`).
    weight: f32,
}

/// What a render builds once from the scene before tracing, as its plan asks: the cone
/// pyramids, the shadow model's own data, the triangle surfaces and the sparse tree.
pub struct Prepared {
    pub cones: Option<crate::technique::cones::march::ConeScene>,
    pub shadow_model: Box<dyn crate::technique::CpuShadow>,
    /// The plan's lighting terms.
    pub terms: Vec<&'static crate::technique::LightingTerm>,
    /// The planned traversal's regions of the grid the walks read (its `data`), when it
    /// has any (the dense walk reads the grid's voxels).
    pub regions: Option<std::sync::Arc<dyn Regions>>,
    /// The triangle surfaces, when the plan traces them.
    pub surfaces: Option<Arc<SurfaceTrace>>,
    /// The ray cutoff in force (0 when the plan has none) and the lights' bounds it
    /// compares (`crate::ray_cutoff`).
    pub cutoff: f32,
    pub light_bounds: Vec<f32>,
    /// How far short of its light a shadow segment ends (world units).
    pub shadow_end_offset: f64,
}

impl Prepared {
    pub fn new(scene: &Scene, settings: &RenderSettings, plan: &Plan) -> Self {
        Self::prepare(scene, settings, plan, Walks::Build)
    }

    /// [`Self::new`], taking the walk's data from `kept` where it holds the same build
    /// ([`render_region_reusing`]).
    pub fn reusing(
        scene: &Scene,
        settings: &RenderSettings,
        plan: &Plan,
        kept: KeptWalkData,
    ) -> Self {
        Self::prepare(scene, settings, plan, Walks::Kept(kept))
    }

    /// Takes a key only where `walks` keeps builds: the key hashes the voxels the walk
    /// reads (a surface's tagged grid is hashed anew each render).
    fn prepare(scene: &Scene, settings: &RenderSettings, plan: &Plan, mut walks: Walks) -> Self {
        let trace = || match plan.surface.trace(scene) {
            Ok(s) => s.map(Arc::new),
            // Past the plan's checks only a surface overlapping more voxels than are
            // kept fails; it is drawn as voxels, and said so.
            Err(e) => {
                eprintln!("warning: {e}; the scene is drawn as voxels");
                None
            }
        };
        let surfaces = match &mut walks {
            Walks::Keep(_, kept) if plan.surface.traces_triangles() => {
                let key = plan.surface.trace_key(scene, scene.grid.content_hash());
                match kept.as_ref().filter(|(k, _)| *k == key) {
                    Some((_, t)) => Some(t.clone()),
                    None => {
                        let t = trace();
                        **kept = t.clone().map(|t| (key, t));
                        t
                    }
                }
            }
            _ => trace(),
        };
        let grid = surfaces.as_ref().map_or(&scene.grid, |s| &s.tagged);
        Self {
            cones: crate::technique::cones::march::ConeScene::new(scene, settings, plan),
            shadow_model: (plan.shadow_model.cpu)(scene, settings),
            terms: plan.terms.clone(),
            regions: plan.traversal.data.map(|data| {
                let own = crate::technique::HOST_WALK_BYTES;
                let budget = crate::technique::walk_budget(settings, own);
                let key = || crate::technique::WalkKey::new(plan.traversal, grid, budget);
                match walks {
                    Walks::Build => data(grid, budget),
                    Walks::Kept(kept) => kept(&key()).unwrap_or_else(|| data(grid, budget)),
                    Walks::Keep(builds, _) => builds.get_or_build(key(), || data(grid, budget)),
                }
            }),
            surfaces,
            cutoff: if plan.ray_cutoff {
                crate::ray_cutoff::cutoff(settings)
            } else {
                0.0
            },
            light_bounds: if plan.ray_cutoff {
                crate::ray_cutoff::light_bounds(scene, settings)
            } else {
                Vec::new()
            },
            shadow_end_offset: settings.ray_offset * scene.grid.voxel_size(),
        }
    }

    /// How shadow segments from a point in `medium` walk this preparation's structures.
    pub(crate) fn shadow_walk(&self, medium: u8) -> ShadowWalk<'_> {
        ShadowWalk {
            regions: self.regions.as_deref(),
            surfaces: self.surfaces.as_deref(),
            medium,
            end_offset: self.shadow_end_offset,
            clear: false,
        }
    }

    /// The grid the walks read: the scene's, or its copy with the cells tagged.
    pub fn grid<'a>(&'a self, scene: &'a Scene) -> &'a crate::scene::Grid {
        self.surfaces.as_ref().map_or(&scene.grid, |s| &s.tagged)
    }
}

/// Radiance seen along a primary ray from `eye` in direction `dir` (unit), ambient included.
/// This plans and prepares the scene for the one ray; [`render`] does it once and calls
/// [`trace_ray_with`].
pub fn trace_ray(
    scene: &Scene,
    settings: &RenderSettings,
    key: SampleKey,
    eye: DVec3,
    dir: DVec3,
    stats: &mut RayStats,
) -> DVec3 {
    let prepared = Prepared::new(scene, settings, &Plan::new(scene, settings));
    trace_ray_with(scene, settings, &prepared, key, eye, dir, stats)
}

/// [`trace_ray`] with the scene prepared by the caller.
pub fn trace_ray_with(
    scene: &Scene,
    settings: &RenderSettings,
    prepared: &Prepared,
    key: SampleKey,
    eye: DVec3,
    dir: DVec3,
    stats: &mut RayStats,
) -> DVec3 {
    trace_tree(scene, settings, prepared, key, eye, dir, stats, None)
}

/// [`trace_ray_with`], telling `primary` what the primary ray found: its hit and the
/// local light there, as shaded and unshadowed.
#[allow(clippy::too_many_arguments)]
fn trace_tree(
    scene: &Scene,
    settings: &RenderSettings,
    prepared: &Prepared,
    key: SampleKey,
    eye: DVec3,
    dir: DVec3,
    stats: &mut RayStats,
    mut primary: Option<&mut PrimarySample>,
) -> DVec3 {
    let grid = &scene.grid;
    let walk_grid = prepared.grid(scene);
    let eps = settings.ray_offset * grid.voxel_size();
    let mut color = scene.ambient;
    let mut stack = Vec::with_capacity(settings.ray_stack_size() as usize);
    stack.push(StackRay {
        origin: eye,
        dir,
        throughput: DVec3::ONE,
        reflection_depth: 0,
        refraction_depth: 0,
        medium: scene.medium_at(eye),
        weight: 1.0,
    });
    stats.primary += 1;

    let mut first = true;
    while let Some(ray) = stack.pop() {
        if !std::mem::take(&mut first) && leaves_grid(walk_grid, ray.origin, ray.dir) {
            stats.untraced += 1;
        }
        let exit_hits = settings.rules == Rules::Consistent;
        let (hit, steps) = cast_through(
            walk_grid,
            prepared.regions.as_deref(),
            prepared.surfaces.as_deref(),
            ray.origin,
            ray.dir,
            ray.medium,
            exit_hits,
            &mut stats.triangle_tests,
        );
        stats.voxel_steps += steps;
        // Only the first ray popped is the primary ray.
        let mut primary = primary.take();
        let Some(hit) = hit else { continue };

        let p = ray.origin + hit.t * ray.dir;
        let n = hit.normal;
        let ng = hit.geometric;
        let shade_id = if hit.material == crate::scene::VOID {
            ray.medium
        } else {
            hit.material
        };
        let m = &scene.materials[shade_id as usize];

        // Emission is seen, not cast: emissive voxels light nothing else.
        color += ray.throughput * m.emission;
        if m.is_lit() {
            let at = Surface {
                p,
                n,
                q: p + eps * ng,
                medium: ray.medium,
            };
            let local = direct_light(
                scene, settings, prepared, key, &at, ray.dir, shade_id, ray.weight, false, stats,
            );
            color += ray.throughput * local;
            if let Some(primary) = primary.as_deref_mut() {
                // The same estimate with the same samples and nothing in the way; its rays
                // are not traced, so they are not counted.
                let mut uncounted = RayStats::default();
                primary.direct = local;
                primary.unshadowed = direct_light(
                    scene,
                    settings,
                    prepared,
                    key,
                    &at,
                    ray.dir,
                    shade_id,
                    ray.weight,
                    true,
                    &mut uncounted,
                );
            }
        }
        if let Some(primary) = primary {
            (primary.hit, primary.normal, primary.depth) = (true, n, hit.t);
            primary.material = shade_id;
        }
        // The plan's lighting terms (crate::technique).
        for term in &prepared.terms {
            let at = crate::technique::TermQuery {
                scene,
                settings,
                material: m,
                p,
                n,
                cones: prepared.cones.as_ref(),
            };
            color += ray.throughput * (term.cpu)(&at);
        }

        spawn(
            scene,
            settings,
            prepared,
            &ray,
            (p, n, ng),
            (hit.material, m),
            eps,
            &mut stack,
            stats,
        );
    }
    color
}

/// Whether a ray from `origin` along `dir` starts outside the grid and does not move
/// towards it on some axis, so that it hits nothing: the f64 twin of the kernel's
/// `leaves_grid` (shaders/traversal.wgsl), which counts such a secondary ray without
/// tracing it. The reference traces it (to nothing) and counts it as `untraced`.
fn leaves_grid(grid: &crate::scene::Grid, origin: DVec3, dir: DVec3) -> bool {
    let local = grid.to_local(origin);
    let dims = grid.dims().as_dvec3();
    (0..3).any(|a| (local[a] < 0.0 && dir[a] <= 0.0) || (local[a] > dims[a] && dir[a] >= 0.0))
}

/// Pushes the refraction ray, then the reflection ray (the contract's order), of `ray`'s
/// hit at `p` with shading normal `n` and the surface's own normal `ng` (the rays start
/// off the surface along it) on material `material`, shaded as `m` (void's hit: the
/// medium's), as the kernel's `spawn` (shaders/trace.wgsl).
#[allow(clippy::too_many_arguments)]
fn spawn(
    scene: &Scene,
    settings: &RenderSettings,
    prepared: &Prepared,
    ray: &StackRay,
    (p, n, ng): (DVec3, DVec3, DVec3),
    (material, m): (u8, &crate::scene::Material),
    eps: f64,
    stack: &mut Vec<StackRay>,
    stats: &mut RayStats,
) {
    let mut reflection_weight = m.kr;
    // The same weight in f32, as the kernel sums it, for the ray cutoff.
    let mut reflection_factor = m.kr as f32;
    let mut refraction = m.kt;
    let mut refraction_factor = m.kt as f32;
    let (a, b) = (ray.reflection_depth, ray.refraction_depth);
    if m.kt > 0.0 {
        let eta = scene.materials[ray.medium as usize].ior / scene.materials[material as usize].ior;
        let refracted = refract(ray.dir, n, eta);
        if m.dielectric == Dielectric::Fresnel {
            // The interface's own split, 1 under total internal reflection
            // (shaders/dielectric.wgsl is its f32 twin).
            let c = -n.dot(ray.dir);
            let f = fresnel_dielectric_at(c, eta * scaled_length(ray.dir + c * n), eta);
            reflection_weight = m.kr * f;
            refraction = m.kt * (1.0 - f);
            // The cutoff's weights as the kernel multiplies them, so a weight at the
            // cutoff falls the same side of it.
            reflection_factor = m.kr as f32 * f as f32;
            refraction_factor = m.kt as f32 * (1.0 - f as f32);
        }
        let refraction_weight = spawned(ray.weight, refraction_factor);
        match refracted {
            // Total internal reflection: the refracted share goes to the reflection,
            // except under the seed's rules, where it is lost (GLSL's refract gives
            // the zero vector, a ray that hits nothing), and under Fresnel, whose
            // reflectance is already 1.
            None if settings.rules == Rules::Seed || m.dielectric == Dielectric::Fresnel => {}
            None => {
                reflection_weight += m.kt;
                reflection_factor += m.kt as f32;
            }
            Some(_) if refraction <= 0.0 => {}
            Some(_) if !settings.may_spawn(a, b, false) => {}
            Some(_) if !traced(refraction_weight, prepared.cutoff) => {}
            Some(refracted) => {
                stats.secondary += 1;
                stack.push(StackRay {
                    origin: p - eps * ng,
                    dir: refracted,
                    throughput: ray.throughput * refraction,
                    reflection_depth: a,
                    refraction_depth: b + 1,
                    medium: material,
                    weight: refraction_weight,
                });
            }
        }
    }
    let reflected_weight = spawned(ray.weight, reflection_factor);
    if reflection_weight > 0.0
        && settings.may_spawn(a, b, true)
        && traced(reflected_weight, prepared.cutoff)
    {
        stats.secondary += 1;
        stack.push(StackRay {
            origin: p + eps * ng,
            dir: ray.dir - 2.0 * ray.dir.dot(n) * n,
            throughput: ray.throughput * reflection_weight,
            reflection_depth: a + 1,
            refraction_depth: b,
            medium: ray.medium,
            weight: reflected_weight,
        });
    }
}

/// `|v|` without squaring `v`'s components: from its largest one, so that the part
/// along the surface of a ray that entered a medium of a far larger index (its
/// components' squares past f64's smallest number) keeps its length (shaders/trace.wgsl
/// `scaled_length` is the f32 twin).
pub fn scaled_length(v: DVec3) -> f64 {
    let m = v.abs().max_element();
    if m > 0.0 { m * (v / m).length() } else { 0.0 }
}

/// Snell's law in vector form (`sin t1 / sin t2 = n2 / n1`, `eta = n1 / n2`) for a unit
/// direction `d` and a unit normal `n` facing against it; `None` under total internal
/// reflection. `eta d + (eta c - sqrt(k)) n` with `k = 1 - eta^2 (1 - c^2)` (the
/// contract's form), evaluated as the f32 kernel does: `sin_i` from the ray's part
/// along the surface, `d + c n` ([`scaled_length`]), and `eta sin_i` squared after the
/// product. `1 - c^2`
/// has no digits left for a near-normal ray's `sin^2` below about 1e-16, where the
/// critical angle of an `eta` past 1e8 lies: the reference drew a quarter of the seed
/// scene's pixels apart from the kernel's at a glass ior of 1e8, itself the wrong one.
pub fn refract(d: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let c = -n.dot(d);
    let along = d + c * n;
    let sin_t = eta * scaled_length(along);
    let k = 1.0 - sin_t * sin_t;
    (k >= 0.0).then(|| (eta * along - k.sqrt() * n).normalize())
}

/// A shaded point: the hit, its shading normal (facing the ray), where shadow rays
/// start (off the surface along its own normal) and the medium there.
struct Surface {
    p: DVec3,
    n: DVec3,
    q: DVec3,
    medium: u8,
}

/// Phong with inverse-square falloff, summed over the lights as the plan's shadow model
/// shades each, times the albedo; `clear`: with every shadow segment clear.
#[allow(clippy::too_many_arguments)]
fn direct_light(
    scene: &Scene,
    settings: &RenderSettings,
    prepared: &Prepared,
    key: SampleKey,
    at: &Surface,
    d: DVec3,
    shade_id: u8,
    weight: f32,
    clear: bool,
    stats: &mut RayStats,
) -> DVec3 {
    let m = &scene.materials[shade_id as usize];
    let Surface { p, n, q, medium } = *at;
    let walk = ShadowWalk {
        clear,
        ..prepared.shadow_walk(medium)
    };
    let mut sum = DVec3::ZERO;
    for (j, light) in scene.lights.iter().enumerate() {
        // The ray cutoff: a light that cannot add what the pixel would show is not
        // shaded.
        if prepared.cutoff > 0.0 && !light_shaded(weight, prepared.light_bounds[j], prepared.cutoff)
        {
            continue;
        }
        // The plan's shadow model shades the whole light (crate::technique).
        let at = crate::technique::LightQuery {
            scene,
            settings,
            material: m,
            p,
            n,
            d,
            q,
            key,
            index: j as u32,
            light,
            walk,
            cones: prepared.cones.as_ref(),
        };
        sum += prepared.shadow_model.light_term(&at, stats);
    }
    m.albedo * sum
}

// The two models' own entry points, where tests and the cone injection call them.
pub use crate::technique::beer_lambert::{shadow_beer_lambert, shadow_beer_lambert_over};
pub use crate::technique::min_kt::{shadow_min_kt, shadow_min_kt_over};

#[cfg(test)]
mod tests {
    use super::*;

    /// A CPU session's kept surface is listed again only when what it was listed from
    /// changes: the same grid and mesh give the same trace (not a copy), a changed voxel
    /// or another surface kind a new one, whose images are the renders' own.
    #[test]
    fn a_kept_surface_is_reused_only_for_its_own_inputs() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
        let e = crate::experiment::Experiment::load(dir.join("bunny_mesh.toml")).unwrap();
        let settings = RenderSettings {
            width: 8,
            height: 8,
            ..e.settings.clone()
        };
        let mut builds = crate::technique::WalkBuilds::new(crate::technique::WALK_BUILDS_KEPT);
        let mut kept: KeptSurface = None;
        let mut prepare = |scene: &Scene, settings: &RenderSettings| {
            let plan = Plan::new(scene, settings);
            Prepared::prepare(scene, settings, &plan, Walks::Keep(&mut builds, &mut kept))
                .surfaces
                .expect("a triangle surface")
        };
        let first = prepare(&e.scene, &settings);
        assert!(
            Arc::ptr_eq(&first, &prepare(&e.scene, &settings)),
            "listed again"
        );
        let mut carved = e.scene.clone();
        let v = carved.grid.dims().as_ivec3() / 2;
        carved
            .grid
            .set(v, if carved.grid.get(v) == 0 { 1 } else { 0 });
        let other = prepare(&carved, &settings);
        assert!(
            !Arc::ptr_eq(&first, &other),
            "a changed voxel kept the old surface"
        );
        let smooth = RenderSettings {
            surface: crate::render::Surface::named("smooth").unwrap(),
            ..settings.clone()
        };
        let smoothed = prepare(&carved, &smooth);
        assert!(
            !Arc::ptr_eq(&other, &smoothed),
            "another kind kept the mesh"
        );
        assert!(Arc::ptr_eq(&smoothed, &prepare(&carved, &smooth)));
    }
}
