//! The GPU tracer: a wgpu compute kernel (WGSL under `shaders/`, composed per [`Plan`])
//! that implements `src/trace_contract.md` in f32, in grid-local coordinates.

mod compose;
mod dispatch;
pub mod pyramid;
mod readback;
mod reconstruct;
mod upload;

pub use compose::{ENTRY_POINT, ShaderError, compose_shader, validate};

use std::borrow::Cow;
use std::collections::{HashMap, HashSet};
use std::ops::Range;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use bytemuck::{Pod, Zeroable};
use glam::DVec3;

use crate::accumulation::AccumulationKey;
use crate::device::{buffer, buffer_entry, extent, readback, storage_entry, uniform_entry};
use crate::frame::{Frame, RayStats, RenderOutput};
use crate::plan::{Plan, ShaderDefs};
use crate::render::{MAX_DEPTH_LIMIT, MAX_IMAGE_SIDE, RenderSettings};
use crate::scene::{AreaShape, Emission, Light, Scene};

/// Side of the square workgroup (`@workgroup_size(8, 8, 1)` in `shaders/trace.wgsl`).
const WORKGROUP: u32 = 8;

/// Stripes of the trace dispatch: its x. Mesa's software driver hands each of its
/// threads one contiguous run of a dispatch's workgroups (`lp_cs_tpool_queue_task`:
/// `iter_per_thread = num_iters / num_threads`, in x-fastest order), so with the image's
/// tiles in raster order one core traced the top half and the other the bottom, and the
/// cheaper half's core sat idle (1.61 of 2 cores busy on the seed scene). The kernel
/// reads workgroup (x, y) as tile x * groups.y + y of the image's raster order, so a
/// run of workgroups is a run of y within every one of these stripes: each thread gets
/// the same share of each 1/STRIPES band of the image. Hardware schedules workgroups
/// dynamically and sees only another order.
const DISPATCH_STRIPES: u32 = 128;

/// The trace dispatch's workgroups per frame for a `width` x `height` image (see
/// `DISPATCH_STRIPES`; `shaders/trace.wgsl`'s `main` maps them back to tiles). Some
/// workgroups of the last stripe may lie past the image's tiles: they return at once.
fn trace_workgroups(width: u32, height: u32) -> (u32, u32) {
    let tiles = width.div_ceil(WORKGROUP) * height.div_ceil(WORKGROUP);
    let stripes = tiles.clamp(1, DISPATCH_STRIPES);
    (stripes, tiles.div_ceil(stripes))
}

/// `Params` of `shaders/types.wgsl`, in WGSL uniform layout (vec3 aligned to 16 bytes,
/// a scalar filling its fourth lane).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuParams {
    eye: [f32; 3],
    width: u32,
    forward: [f32; 3],
    height: u32,
    right_scaled: [f32; 3],
    num_lights: u32,
    up_scaled: [f32; 3],
    max_reflection_depth: u32,
    dims: [u32; 3],
    max_refraction_depth: u32,
    ambient: [f32; 3],
    eye_medium: u32,
    eps: f32,
    voxel_size: f32,
    falloff_min_dist_sq: f32,
    falloff: u32,
    light_samples: u32,
    seed: u32,
    frame_begin: u32,
    frame_count: u32,
    max_total_depth: u32,
    // `crate::ray_cutoff::cutoff` (read only when the plan has `RAY_CUTOFF`).
    ray_cutoff: f32,
    pixel_filter: u32,
    filter_width: f32,
    // Words of each binding of a walk's further words (`technique::walk_part_words`).
    walk_part_words: u32,
    // `plan::primary_origin`: 0 unless the eye is far out.
    primary_advance: f32,
    // Always 0 (`loop_guard`, shaders/counters.wgsl).
    loop_guard: u32,
    _pad: u32,
    // The plan's shadow model's settings (`ShadowModel::gpu_settings`).
    technique: [f32; crate::technique::MAX_GPU_SETTINGS],
}

/// `ReduceParams` of `shaders/accumulate.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ReduceParams {
    pixels: u32,
    row: u32,
    frame_begin: u32,
    frame_count: u32,
}

/// `Material` of `shaders/types.wgsl` (64-byte array stride).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuMaterial {
    albedo: [f32; 3],
    kd: f32,
    ks: f32,
    shininess: f32,
    kr: f32,
    kt: f32,
    ior: f32,
    /// Beer-Lambert absorption per voxel unit (per world unit times voxel_size).
    sigma: [f32; 3],
    emission: [f32; 3],
    /// `crate::scene::Dielectric::code`.
    dielectric: u32,
}

/// `Light` of `shaders/types.wgsl`: the centre, colour times intensity, and for a
/// sampled area light its kind and axes scaled by its size, in voxel units.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuLight {
    position: [f32; 3],
    kind: u32,
    radiance: [f32; 3],
    // `crate::ray_cutoff::light_bounds` (0 when the plan has no `RAY_CUTOFF`).
    bound: f32,
    axis_u: [f32; 3],
    emission: u32,
    axis_v: [f32; 3],
    _pad2: f32,
    axis_n: [f32; 3],
    _pad3: f32,
}

/// `LIGHT_*` of `shaders/types.wgsl`.
const LIGHT_POINT: u32 = 0;
const LIGHT_RECT: u32 = 1;
const LIGHT_DISK: u32 = 2;
const LIGHT_SPHERE: u32 = 3;
/// `EMISSION_LAMBERTIAN` of `shaders/types.wgsl`.
const EMISSION_LAMBERTIAN: u32 = 1;

/// Pixel-frames traced by one dispatch at most: a render of many frames is split into
/// dispatches of whole frames (the sums carry over in the buffers), so no single
/// dispatch runs long enough to trip a driver's watchdog, and the frame slices stay
/// at most 16 MiB.
const PIXEL_FRAMES_PER_DISPATCH: u64 = 1 << 20;
/// Into how many dispatches a render that may be stopped splits each one.
const WATCHED_SPLIT: u32 = 16;

/// Frames of one dispatch at most: each is one invocation per pixel along the
/// dispatch's z (at most 65535 workgroups), and the accumulation kernel loops over them
/// in every invocation alike, so this also keeps that loop far below the 65535 loop
/// iterations Mesa's software driver allows an invocation (shaders/counters.wgsl).
const MAX_FRAMES_PER_DISPATCH: u32 = 4096;

pub use crate::technique::WALK_BUILDS_KEPT;

/// Ray counters (4 x 64 bit), the invocations whose loops the driver cut, one unused word,
/// the untraced secondary rays (64 bit).
const COUNTER_WORDS: usize = 12;
const COUNTER_BYTES: u64 = COUNTER_WORDS as u64 * 4;
/// Word of `counters` that counts invocations whose loops the driver cut short.
const LOOPS_CUT: usize = 8;

/// `@workgroup_size(64, 1, 1)` of `shaders/accumulate.wgsl`.
const REDUCE_WORKGROUP: u32 = 64;

// The WGSL uniform struct is 176 bytes (11 rows of 16).
const _: () = assert!(std::mem::size_of::<GpuParams>() == 176);
const _: () = assert!(std::mem::size_of::<GpuMaterial>() == 64);
const _: () = assert!(std::mem::size_of::<GpuLight>() == 80);

fn f3(v: DVec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// The grid as it sits on the device, with a hash of the voxels it was made from so a
/// render can tell whether it changed (a hash, not a copy: a 1024^3 grid is 1 GiB).
struct GridUpload {
    /// Counts uploads, so a pyramid can tell whether the grid it was built from is
    /// still the one on the device without comparing the voxels again.
    generation: u64,
    dims: glam::UVec3,
    /// blake3 of the voxels.
    hash: blake3::Hash,
    /// Whether `view` is the grid itself; a plan that reads no texture gets a one-voxel
    /// stand-in, so a sparse render does not hold the dense grid on the device.
    texture: bool,
    view: wgpu::TextureView,
    /// The voxels the walks read packed four to a word, x-fastest (`voxels` of
    /// shaders/bindings.wgsl), with the hash of those voxels (the grid's, or its copy with
    /// the triangle cells tagged); only while a plan walks the dense grid.
    voxels: Option<(blake3::Hash, wgpu::Buffer)>,
}

/// The accumulation the output and compensation buffers hold after a
/// [`GpuTracer::render_frames`] call of an accumulating plan.
struct Accumulation {
    key: AccumulationKey,
    /// The grid upload it was traced against.
    grid_generation: u64,
    /// `pyramid_builds` after its latest call: a build since then ends it.
    pyramid_builds: u64,
    /// Frames 0..frames are summed in the buffers.
    frames: u32,
}

/// Buffers sized by the image or the scene, reused while they are large enough.
struct Buffers {
    pixels: u64,
    output: wgpu::Buffer,
    readback: wgpu::Buffer,
}

pub struct GpuTracer {
    adapter: wgpu::Adapter,
    device: wgpu::Device,
    queue: wgpu::Queue,
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    /// Group 1 of `shaders/cone.wgsl`, and the layout of kernels with a cone feature.
    cone_layout: wgpu::BindGroupLayout,
    cone_pipeline_layout: wgpu::PipelineLayout,
    pipelines: HashMap<ShaderDefs, wgpu::ComputePipeline>,
    /// Kernels made and not yet dispatched, and whether the accumulation kernel is one:
    /// their first dispatch is an untimed warm-up (`dispatch.rs`, `warm_up`).
    cold_kernels: HashSet<ShaderDefs>,
    cold_reduce: bool,
    params: wgpu::Buffer,
    counters: wgpu::Buffer,
    counters_readback: wgpu::Buffer,
    materials: Option<(u64, wgpu::Buffer)>,
    lights: Option<(u64, wgpu::Buffer)>,
    /// Kahan compensation per pixel, only while a plan accumulates (`ACCUMULATE`).
    compensation: Option<(u64, wgpu::Buffer)>,
    /// The radiance of each frame of a dispatch, only while a plan accumulates.
    frame_slices: Option<(u64, wgpu::Buffer)>,
    /// The accumulation kernel, its bind group layout and parameters, made on the
    /// first accumulating render.
    reduce: Option<(wgpu::BindGroupLayout, wgpu::ComputePipeline, wgpu::Buffer)>,
    /// Each reconstruction's pipelines, made on its first render (`reconstruct.rs`).
    filters: HashMap<&'static str, reconstruct::FilterPipelines>,
    /// The reconstruction passes' buffers, kept while images keep their size.
    filter_buffers: Option<reconstruct::FilterBuffers>,
    /// A temporal reconstruction's history, kept from frame to frame of a camera path.
    history: Option<reconstruct::GpuHistory>,
    /// Wall time of the latest render's reconstruction passes (synchronised), included
    /// in its trace time and device time; zero without a reconstruction.
    last_filter_time: Duration,
    grid: Option<GridUpload>,
    buffers: Option<Buffers>,
    /// The pyramid-build kernels, made on the first build.
    build_pipelines: Option<pyramid::BuildPipelines>,
    /// The pyramids of the latest cone render and what they were built from: a render
    /// whose key is equal reuses them. Kept across renders without cones, so ablations
    /// that toggle cone features do not rebuild.
    pyramid: Option<(pyramid::PyramidKey, pyramid::GpuPyramid)>,
    pyramid_builds: u64,
    /// Time the latest render spent on its sparse tree and pyramids, outside the trace
    /// time.
    last_setup_time: Duration,
    /// Told of each finished dispatch (frames) of a render, when set.
    progress: Option<std::sync::Arc<crate::progress::Progress>>,
    /// The plan of the latest render, for printing and reports.
    last_plan: Option<Plan>,
    /// Device memory the latest render bound, by resource.
    last_memory: Option<GpuMemory>,
    /// Whether the device was opened with `TIMESTAMP_QUERY` (the adapter has it).
    timestamps: bool,
    /// Device time of the latest render's trace passes, from timestamp queries.
    last_gpu_time: Option<Duration>,
    /// The accumulation a `render_frames` call may continue; any other render, or a
    /// failed one, clears it.
    accumulation: Option<Accumulation>,
    /// Voxel steps per loop iteration in the walks (`Plan::dda_unroll`) on this device.
    dda_unroll: u32,
    /// The device's own choice of `dda_unroll` (`dda_unroll_for`).
    device_dda_unroll: u32,
    /// The grid's dims and the walk for which a cut render raised `dda_unroll`: renders
    /// of others start again from the device's choice, so that a small scene after a
    /// large one does not pay for the large one's walks (seed_rules at 16^3: 112 ms per
    /// frame alone, 172 ms after the seed scene at 256^3, on lavapipe).
    raised_for: Option<(glam::UVec3, &'static str)>,
    /// `technique_data` of a plug-in technique (`crate::technique::ShadowModel::gpu_data`)
    /// and what it was made from; kept while renders need the same.
    technique_data: Option<(blake3::Hash, wgpu::Buffer)>,
    /// Builds of `technique_data` since the tracer was made.
    technique_data_builds: u64,
    /// Bound as `technique_data` when the plan needs none (a binding needs a buffer),
    /// and as `walk_data` when the plan walks the voxel buffer.
    no_technique_data: wgpu::Buffer,
    /// The planned traversal's own data of the voxels the walks read (which traversal,
    /// the voxels' hash, the budget; the buffers: the sparse tree, say), while renders
    /// walk it.
    walk_data: Option<(crate::technique::WalkKey, WalkBuffers)>,
    /// The latest walks' data as built on the host (what each was built from, the
    /// data), at most [`WALK_BUILDS_KEPT`]: switching between walks of one grid (the
    /// benchmark's interleaved frames, the viewer's menu) uploads again but does not
    /// build again (the sparse octant walk's codes take seconds at 1024^3). Only the
    /// `walk_data` buffer is on the device.
    walk_builds: crate::technique::WalkBuilds,
    /// The triangle surfaces of the latest render that traced them: what they were made
    /// from (a hash), the cells, the hash of their tagged grid and their buffer
    /// (`surface` of shaders/bindings.wgsl).
    surfaces: Option<SurfaceUpload>,
}

/// A walk's data on the device: `walk_data`, and its further words over up to
/// [`crate::technique::WALK_MORE_BINDINGS`] buffers of
/// `crate::technique::walk_part_words(budget)` words each (`walk_more_0` ... of
/// shaders/bindings.wgsl; the budget is its [`crate::technique::WalkKey`]'s).
struct WalkBuffers {
    main: wgpu::Buffer,
    more: Vec<wgpu::Buffer>,
    /// The data's `Regions::kernel_variant`.
    variant: u32,
    /// The data's `Regions::summary`, for the plan.
    summary: Option<String>,
}

impl WalkBuffers {
    fn bytes(&self) -> u64 {
        self.main.size() + self.more.iter().map(|b| b.size()).sum::<u64>()
    }
}

/// Triangle surfaces on the device (`crate::triangles`).
struct SurfaceUpload {
    key: blake3::Hash,
    trace: std::sync::Arc<crate::triangles::SurfaceTrace>,
    tagged_hash: blake3::Hash,
    buffer: wgpu::Buffer,
}

/// Device memory bound by one render, in bytes: what a plan's leaving out saves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuMemory {
    /// The voxel grid texture (1 byte per voxel), when the plan reads it.
    pub grid: u64,
    /// The traversal's own data (the sparse tree, say), when the plan
    /// walks it.
    pub walk_data: u64,
    /// Triangles, cells and their references, when the plan traces triangle surfaces.
    pub surfaces: u64,
    /// Materials, lights, parameters and ray counters.
    pub scene: u64,
    /// Radiance output and its readback copy.
    pub image: u64,
    /// Kahan compensation, only while accumulating frames.
    pub accumulation: u64,
    /// Opacity and radiance pyramids, only with a cone feature.
    pub pyramids: u64,
    /// A plug-in technique's data (`technique_data`), only when the plan uses it.
    pub technique: u64,
    /// A reconstruction's guide and colour buffers, only when the plan filters.
    pub reconstruction: u64,
}

impl GpuMemory {
    pub fn total(&self) -> u64 {
        self.grid
            + self.walk_data
            + self.surfaces
            + self.scene
            + self.image
            + self.accumulation
            + self.pyramids
            + self.technique
            + self.reconstruction
    }
}

impl std::fmt::Display for GpuMemory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mib = |b: u64| b as f64 / 1048576.0;
        write!(
            f,
            "{:.2} MiB (grid {:.2}, walk data {:.2}, surfaces {:.2}, scene {:.3}, image {:.2}, \
             accumulation {:.2}, pyramids {:.2}, technique data {:.2}, reconstruction {:.2})",
            mib(self.total()),
            mib(self.grid),
            mib(self.walk_data),
            mib(self.surfaces),
            mib(self.scene),
            mib(self.image),
            mib(self.accumulation),
            mib(self.pyramids),
            mib(self.technique),
            mib(self.reconstruction)
        )
    }
}

/// Voxel steps per loop iteration for a device: Mesa's software driver ends every loop
/// of an invocation after 65535 back edges in all (shaders/counters.wgsl), so on a CPU
/// device the walks take several steps per back edge; hardware has no such limit, and
/// there every step written out but not needed costs. `VOXLAB_DDA_UNROLL` (1, 2, 4 or
/// 8) overrides it, for measuring.
fn dda_unroll_for(info: &wgpu::AdapterInfo) -> u32 {
    if let Some(n) = std::env::var("VOXLAB_DDA_UNROLL")
        .ok()
        .and_then(|v| v.parse::<u32>().ok())
        .filter(|n| [1, 2, 4, 8].contains(n))
    {
        return n;
    }
    if info.device_type == wgpu::DeviceType::Cpu {
        SOFTWARE_FIRST_DDA_UNROLL
    } else {
        1
    }
}

/// Steps per loop iteration a software device falls back to when a render runs into
/// the driver's loop limit (`GpuTracer::render_range`).
const SOFTWARE_DDA_UNROLL: u32 = 8;

/// Steps per loop iteration a software device starts with: short walks (small grids)
/// pay least for steps written out but not needed (1305 ms per seed frame at 16^3 and
/// 512x512 against 1802 ms with 8, on lavapipe), and one step per back edge is what the
/// limit allows least of, so a render that needs more is retried with
/// `SOFTWARE_DDA_UNROLL` (587 ms against 216 ms per 32x32 frame of the seed scene at
/// 256^3 with 4 and 8).
const SOFTWARE_FIRST_DDA_UNROLL: u32 = 1;

/// A render some invocation of which the driver's loop limit cut short.
#[derive(Debug)]
struct LoopsCut;

impl std::fmt::Display for LoopsCut {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "the driver's loop limit cut a loop of the kernel short")
    }
}

impl std::error::Error for LoopsCut {}

/// A compute pass whose start and end are timestamps 2i and 2i + 1 of `queries` (when
/// the device has them), i the running pass index, which this advances.
fn timed_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    queries: Option<&wgpu::QuerySet>,
    index: &mut u32,
) -> wgpu::ComputePass<'e> {
    let i = *index;
    *index += 1;
    encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: queries.map(|q| wgpu::ComputePassTimestampWrites {
            query_set: q,
            beginning_of_pass_write_index: Some(2 * i),
            end_of_pass_write_index: Some(2 * i + 1),
        }),
    })
}

/// Frames one dispatch of an accumulating render traces, for an image of `pixels` and
/// `frames` frames to go: at most 2^20 pixel-frames and 4096 frames, at least one.
pub fn frames_per_dispatch(pixels: u64, frames: u32) -> u32 {
    let most = frames.clamp(1, MAX_FRAMES_PER_DISPATCH) as u64;
    (PIXEL_FRAMES_PER_DISPATCH / pixels.max(1)).clamp(1, most) as u32
}

/// Hardware before software, and the primary backends before GL.
fn adapter_rank(info: &wgpu::AdapterInfo) -> (u32, u32) {
    let backend = match info.backend {
        wgpu::Backend::Vulkan => 0,
        wgpu::Backend::Metal | wgpu::Backend::Dx12 => 1,
        _ => 2,
    };
    let kind = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    };
    (backend, kind)
}

impl GpuTracer {
    /// Finds an adapter (any backend, Vulkan preferred; software adapters such as
    /// lavapipe allowed) that runs compute shaders. An error if there is none.
    pub fn new() -> Result<Self> {
        // WGPU_BACKEND (e.g. "vulkan", "gl") narrows the search; otherwise the primary
        // backends first, and GL only when they have nothing (probing GL needs a display
        // connection and complains loudly on headless machines).
        let searches = match wgpu::Backends::from_env() {
            Some(b) => vec![b],
            None => vec![wgpu::Backends::PRIMARY, wgpu::Backends::SECONDARY],
        };
        let mut adapters = Vec::new();
        for backends in searches {
            let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
                backends,
                ..wgpu::InstanceDescriptor::new_without_display_handle()
            });
            adapters = pollster::block_on(instance.enumerate_adapters(backends))
                .into_iter()
                .filter(|a| {
                    a.get_downlevel_capabilities()
                        .flags
                        .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS)
                })
                .collect();
            if !adapters.is_empty() {
                break;
            }
        }
        adapters.sort_by_key(|a| adapter_rank(&a.get_info()));
        let adapter = adapters.into_iter().next().ok_or_else(|| {
            anyhow!(
                "no GPU adapter with compute shaders found (wgpu, all backends{}). On Linux \
                 install a Vulkan driver; Mesa's software lavapipe is the Debian package \
                 `mesa-vulkan-drivers`",
                if std::env::var_os("WGPU_BACKEND").is_some() {
                    ", narrowed by WGPU_BACKEND"
                } else {
                    ""
                }
            )
        })?;
        // The adapter's own limits, so the largest grid and image the device allows can
        // be used (the defaults would cap 3D textures at 2048).
        let limits = adapter.limits();
        // Timestamp queries time the trace on the device itself, where the adapter has
        // them (lavapipe does); without them the trace is timed on the host.
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("voxlab"),
            required_limits: limits,
            required_features: if timestamps {
                wgpu::Features::TIMESTAMP_QUERY
            } else {
                wgpu::Features::empty()
            },
            ..Default::default()
        }))
        .with_context(|| format!("opening a device on {}", adapter.get_info().name))?;

        let dda_unroll = dda_unroll_for(&adapter.get_info());
        // shaders/bindings.wgsl: the params and materials uniform, the output and the
        // counters written, every other binding a storage buffer read.
        let entries: Vec<_> = (0..12)
            .map(|b| match b {
                0 | 2 => uniform_entry(b),
                4 | 5 => storage_entry(b, false),
                _ => storage_entry(b, true),
            })
            .collect();
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("voxlab tracer"),
            entries: &entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("voxlab tracer"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let cone_layout = pyramid::cone_bind_group_layout(&device);
        let cone_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("voxlab tracer with cones"),
            bind_group_layouts: &[Some(&layout), Some(&cone_layout)],
            immediate_size: 0,
        });
        let params = buffer(
            &device,
            "params",
            std::mem::size_of::<GpuParams>() as u64,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        let counters = buffer(
            &device,
            "ray counters",
            COUNTER_BYTES,
            wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
        );
        let counters_readback = readback(&device, "ray counters readback", COUNTER_BYTES);
        let no_technique_data = buffer(
            &device,
            "no technique data",
            16,
            wgpu::BufferUsages::STORAGE,
        );
        Ok(Self {
            adapter,
            device,
            queue,
            layout,
            pipeline_layout,
            cone_layout,
            cone_pipeline_layout,
            pipelines: HashMap::new(),
            cold_kernels: HashSet::new(),
            cold_reduce: false,
            params,
            counters,
            counters_readback,
            materials: None,
            lights: None,
            compensation: None,
            frame_slices: None,
            reduce: None,
            filters: HashMap::new(),
            filter_buffers: None,
            history: None,
            last_filter_time: Duration::ZERO,
            grid: None,
            buffers: None,
            build_pipelines: None,
            pyramid: None,
            pyramid_builds: 0,
            last_setup_time: Duration::ZERO,
            progress: None,
            timestamps,
            last_gpu_time: None,
            last_plan: None,
            last_memory: None,
            accumulation: None,
            dda_unroll,
            device_dda_unroll: dda_unroll,
            raised_for: None,
            technique_data: None,
            technique_data_builds: 0,
            no_technique_data,
            walk_data: None,
            walk_builds: crate::technique::WalkBuilds::new(WALK_BUILDS_KEPT),
            surfaces: None,
        })
    }

    pub fn adapter_info(&self) -> wgpu::AdapterInfo {
        self.adapter.get_info()
    }

    /// One line naming the adapter, its type, backend and driver.
    pub fn adapter_summary(&self) -> String {
        let i = self.adapter.get_info();
        format!(
            "{} ({:?}, {:?}, driver {} {})",
            i.name, i.device_type, i.backend, i.driver, i.driver_info
        )
    }

    /// Largest 3D texture side this device allows: the largest grid side the cone
    /// features (their pyramids) and device-built technique data accept. The walks read
    /// storage buffers instead, limited by [`Self::max_voxel_buffer_bytes`].
    pub fn max_grid_side(&self) -> u32 {
        self.device.limits().max_texture_dimension_3d
    }

    /// Voxel steps per loop iteration of the walks on this tracer (`Plan::dda_unroll`).
    pub fn dda_unroll(&self) -> u32 {
        self.dda_unroll
    }

    /// Sets the voxel steps per loop iteration (1, 2, 4 or 8) for the next renders: for
    /// benchmarks and the tests that hold that it changes no image.
    pub fn set_dda_unroll(&mut self, n: u32) -> Result<()> {
        if ![1, 2, 4, 8].contains(&n) {
            bail!("dda_unroll {n}: must be 1, 2, 4 or 8");
        }
        self.dda_unroll = n;
        self.raised_for = None;
        Ok(())
    }

    /// The plan of the latest render.
    pub fn last_plan(&self) -> Option<&Plan> {
        self.last_plan.as_ref()
    }

    /// Device memory the latest render bound.
    pub fn last_memory(&self) -> Option<GpuMemory> {
        self.last_memory
    }

    /// Diagnostics counter: pyramid builds since the tracer was made, each render's
    /// that missed the cache and each `build_pyramid` call. A render whose pyramids'
    /// inputs did not change does not add one.
    pub fn pyramid_builds(&self) -> u64 {
        self.pyramid_builds
    }

    /// Diagnostics counter: builds of a shadow model's data (`ShadowModel::gpu_data`)
    /// since the tracer was made. A render whose model and data inputs (the scene, the
    /// model's `data_settings`) did not change does not add one.
    pub fn technique_data_builds(&self) -> u64 {
        self.technique_data_builds
    }

    /// Diagnostics counter: builds of a walk's own data (`TraversalModel::data`: the
    /// sparse tree's words, the octant codes) since the tracer was made. A render of a
    /// grid and walk among the latest [`WALK_BUILDS_KEPT`] built does not add one.
    pub fn walk_data_builds(&self) -> u64 {
        self.walk_builds.built()
    }

    /// The bindings the walk's data on the device takes: `walk_data` and those of its
    /// further words (`crate::sparse::Regions::device_more_words`); 0 while renders
    /// walk the voxel buffer.
    pub fn walk_data_bindings(&self) -> usize {
        self.walk_data.as_ref().map_or(0, |w| 1 + w.1.more.len())
    }

    /// Device time of the latest render's trace (the sum of its compute passes, from
    /// timestamp queries), or `None` when the adapter has no timestamp queries; then
    /// `RenderOutput::trace_time`, wall time around a synchronised submit, is the timer.
    pub fn last_gpu_time(&self) -> Option<Duration> {
        self.last_gpu_time
    }

    /// Which timer `last_gpu_time` / `trace_time` come from, for reports.
    pub fn timer_name(&self) -> &'static str {
        if self.timestamps {
            "timestamp queries"
        } else {
            "wall time around a synchronised submit"
        }
    }

    /// Time the latest render spent building (or finding in the cache) its walk's data
    /// (the sparse tree, a proximity or octant field) and cone pyramids: zero when it
    /// has neither, and not part of its `trace_time`.
    pub fn last_setup_time(&self) -> Duration {
        self.last_setup_time
    }

    fn grid_generation(&self) -> u64 {
        self.grid.as_ref().map_or(0, |g| g.generation)
    }

    /// Reports the frames of each later render to `progress` (`None`: no reports, and
    /// no waits between dispatches).
    pub fn set_progress(&mut self, progress: Option<std::sync::Arc<crate::progress::Progress>>) {
        self.progress = progress;
    }

    /// Wall time of the latest render's reconstruction passes (around their
    /// synchronised submissions; included in its trace time and device time), zero
    /// without a reconstruction.
    pub fn last_filter_time(&self) -> Duration {
        self.last_filter_time
    }

    /// Renders without ray counting; `stats` are zero.
    pub fn render(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<RenderOutput> {
        self.render_with(scene, settings, false)
    }

    /// Renders with ray counting compiled in (`COUNT_RAYS`), so `stats` are filled.
    pub fn render_counted(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
    ) -> Result<RenderOutput> {
        self.render_with(scene, settings, true)
    }

    fn check(&self, scene: &Scene, settings: &RenderSettings, plan: &Plan) -> Result<()> {
        scene.validate()?;
        crate::plan::check_primary_origin(scene, settings).map_err(anyhow::Error::msg)?;
        crate::plan::check_lights_f32(scene, settings).map_err(anyhow::Error::msg)?;
        crate::plan::check_iors_f32(scene).map_err(anyhow::Error::msg)?;
        let (w, h) = (settings.width, settings.height);
        if w == 0 || h == 0 || w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
            bail!("image size {w}x{h}: each side must be in 1..={MAX_IMAGE_SIDE}");
        }
        for (name, d) in [
            ("max_reflection_depth", settings.max_reflection_depth),
            ("max_refraction_depth", settings.max_refraction_depth),
        ] {
            if d > MAX_DEPTH_LIMIT {
                bail!("{name} {d}: at most {MAX_DEPTH_LIMIT}");
            }
        }
        let own = self.walk_budget() >> 20;
        if settings.walk_budget_mib as usize > own {
            bail!(
                "render.walk_budget_mib = {}: {} binds at most {own} MiB of a walk's data \
                 a binding (max_storage_buffer_binding_size); allowed 0..={own} (0: all of \
                 it)",
                settings.walk_budget_mib,
                self.adapter.get_info().name,
            );
        }
        let limits = self.device.limits();
        let dims = scene.grid.dims();
        if !plan
            .traversal
            .binds_within(dims, self.max_voxel_buffer_bytes())
            && let Some(bytes) = plan.traversal.device_bytes.map(|b| b(dims))
        {
            bail!(
                "grid {}x{}x{} needs {bytes} bytes for the {} walk; {} binds at most {} \
                 (max_storage_buffer_binding_size); render.traversal = \"sparse\" walks \
                 the tree instead",
                dims.x,
                dims.y,
                dims.z,
                plan.traversal.name,
                self.adapter.get_info().name,
                self.max_voxel_buffer_bytes()
            );
        }
        if Self::reads_grid_texture(plan) && self.adapter.get_info().backend == wgpu::Backend::Gl {
            // Measured with WGPU_BACKEND=gl on Mesa's llvmpipe: the main kernel agrees
            // with the reference, but the device builds that read the grid texture do
            // not (tests/cone_pyramid.rs and tests/sdf_shadows.rs fail: empty pyramids,
            // a different field). Refused rather than rendered wrong.
            bail!(
                "{} builds its data on the device from the grid's 3D texture, which \
                 wgpu's OpenGL backend ({}) does not read as the reference does; install a \
                 Vulkan driver (Mesa's lavapipe: Debian package mesa-vulkan-drivers) or \
                 render with --backend cpu",
                if plan.pyramid.is_some() {
                    "cone tracing"
                } else {
                    "the shadow model"
                },
                self.adapter.get_info().name
            );
        }
        let side = self.max_grid_side();
        if Self::reads_grid_texture(plan) && dims.max_element() > side {
            bail!(
                "grid {}x{}x{} does not fit this device: max_texture_dimension_3d is {side} \
                 on {}",
                dims.x,
                dims.y,
                dims.z,
                self.adapter.get_info().name
            );
        }
        let (stripes, per_stripe) = trace_workgroups(w, h);
        let groups = stripes.max(per_stripe);
        if groups > limits.max_compute_workgroups_per_dimension {
            bail!(
                "image {w}x{h} needs {groups} workgroups per dimension; the device allows {} \
                 (max_compute_workgroups_per_dimension)",
                limits.max_compute_workgroups_per_dimension
            );
        }
        // The radiance, and the primary layers' planes when a reconstruction reads them.
        let out_bytes = w as u64 * h as u64 * 16 * plan.layer_slices() as u64;
        let max_out = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if out_bytes > max_out {
            let planes = if plan.layer_slices() > 1 {
                format!(
                    " (the radiance and the {} planes of the primary layers a reconstruction \
                     reads)",
                    plan.layer_slices() - 1
                )
            } else {
                String::new()
            };
            bail!(
                "image {w}x{h} needs a {out_bytes}-byte radiance buffer{planes}; the device \
                 allows {max_out} (max_storage_buffer_binding_size / max_buffer_size)"
            );
        }
        Ok(())
    }

    fn pipeline(&mut self, plan: &Plan) -> Result<&wgpu::ComputePipeline> {
        let key = plan.shader_defs();
        if !self.pipelines.contains_key(&key) {
            let module = compose_shader(plan)?;
            // wgpu adds a 64-bit counter to every loop, which breaks out of a loop that
            // would never end, so that a driver may not assume it ends. Every loop of
            // the tracer has its own bound (the walks' max_steps, the stack's depth
            // limits, the light and sample counts), so the counter is only cost: 3 to
            // 4 % of a frame of the seed scene on lavapipe. Bounds checks stay. Without
            // it each loop's exit carries `loop_guard()` (shaders/counters.wgsl), or the
            // driver's compiler drops the checks that report its loop limit.
            let mut checks = wgpu::ShaderRuntimeChecks::checked();
            checks.force_loop_bounding = false;
            // SAFETY: the module is the tracer's own WGSL, composed and validated by
            // naga; wgpu's documented requirement for dropping the loop counter is that
            // no loop runs forever, which the bounds above give.
            let shader = unsafe {
                self.device.create_shader_module_trusted(
                    wgpu::ShaderModuleDescriptor {
                        label: Some("voxlab trace"),
                        source: wgpu::ShaderSource::Naga(Cow::Owned(module)),
                    },
                    checks,
                )
            };
            let pipeline = self
                .device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("voxlab trace"),
                    layout: Some(if plan.pyramid.is_some() {
                        &self.cone_pipeline_layout
                    } else {
                        &self.pipeline_layout
                    }),
                    module: &shader,
                    entry_point: Some(ENTRY_POINT),
                    compilation_options: Default::default(),
                    cache: None,
                });
            self.pipelines.insert(key.clone(), pipeline);
            self.cold_kernels.insert(key.clone());
        }
        Ok(&self.pipelines[&key])
    }

    fn render_with(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        count: bool,
    ) -> Result<RenderOutput> {
        let plan = Plan::new(scene, settings).with_counting(count);
        self.render_plan(scene, settings, plan)
    }

    /// Renders with a given kernel variant instead of the scene's own plan: for
    /// ablations, and for tests that check that leaving code out changes nothing. A plan
    /// that leaves out code the scene needs gives a wrong image, not an error; a stack
    /// smaller than the depth limits need drops rays.
    pub fn render_plan(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        plan: Plan,
    ) -> Result<RenderOutput> {
        let frames = 0..plan.frames(settings);
        self.render_range(scene, settings, plan, frames, false)
    }

    /// Renders frames `frames` (a range of frame indices) of `settings`' accumulation
    /// with the scene's own plan (no ray counting) and returns the image averaged over
    /// frames `0..frames.end`: bit for bit the image of a render with `spp =
    /// frames.end`. `frames.start == 0` starts a new accumulation; `frames.start > 0`
    /// continues the one this tracer's previous call left, which must have been a
    /// `render_frames` call with the same scene, settings and plan that ended at
    /// `frames.start` (else an error that says which differs). `frames.end` must be at
    /// most `Plan::frames(settings)` (`settings.spp` is the cap); a plan that does not
    /// accumulate (nothing sampled, or `spp` 1) has only `0..1`. Any other render ends
    /// the accumulation. `trace_time` and `last_gpu_time` cover this call's frames only.
    pub fn render_frames(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        frames: Range<u32>,
    ) -> Result<RenderOutput> {
        let plan = Plan::new(scene, settings);
        self.render_range(scene, settings, plan, frames, true)
    }

    /// The walk data this tracer keeps built for `key`, if it keeps it (its latest
    /// builds): what the CPU reference walks instead of building the same again
    /// (`crate::cpu::render_region_reusing`).
    pub fn kept_walk_data(
        &self,
        key: &crate::technique::WalkKey,
    ) -> Option<std::sync::Arc<dyn crate::sparse::Regions>> {
        self.walk_builds.find(key)
    }

    /// Frames the accumulation a `render_frames` call may continue holds (it continues
    /// at this frame): 0 when there is none, after any other render, a failed one, or
    /// a plan that does not accumulate.
    pub fn accumulated_frames(&self) -> u32 {
        self.accumulation.as_ref().map_or(0, |a| a.frames)
    }

    /// Whether the accumulation this tracer holds is the one `frames` continues.
    fn check_continuation(&self, key: &AccumulationKey, frames: &Range<u32>) -> Result<()> {
        let held = self.accumulation.as_ref().map(|acc| {
            let mut also = Vec::new();
            if acc.grid_generation != self.grid_generation() {
                also.push("voxel grid (another was uploaded since)");
            }
            if acc.pyramid_builds != self.pyramid_builds {
                also.push("cone pyramids (rebuilt since)");
            }
            (&acc.key, acc.frames, also)
        });
        crate::accumulation::check_continuation(held, key, frames).map_err(anyhow::Error::msg)
    }

    /// Whether `scene`'s voxels are those the held accumulation was traced against,
    /// asked before the render uploads anything; the rest of the key is checked once
    /// the plan is final ([`Self::check_continuation`]).
    fn check_continued_voxels(&self, scene: &Scene, frames: &Range<u32>) -> Result<()> {
        let (Some(acc), Some(grid)) = (&self.accumulation, &self.grid) else {
            return Ok(());
        };
        let held = acc.grid_generation == grid.generation;
        if !held || (grid.dims == scene.grid.dims() && grid.hash == scene.grid.content_hash()) {
            return Ok(());
        }
        let changed = vec!["voxel grid (other voxels than it was traced against)"];
        crate::accumulation::check_continuation(
            Some((&acc.key, acc.frames, changed)),
            &acc.key,
            frames,
        )
        .map_err(anyhow::Error::msg)
    }

    /// Renders frames `frames` of `plan`'s accumulation and returns the image averaged
    /// over `0..frames.end`; a start above 0 continues the sums in the buffers. With
    /// `continuable` (render_frames) an accumulating render is recorded so the next
    /// call may continue it; otherwise the record is cleared.
    ///
    /// On a software device the walks start with few steps per loop iteration (fast for
    /// short walks); a render the driver's loop limit cut is rendered again with
    /// [`SOFTWARE_DDA_UNROLL`], which this tracer then keeps for renders of grids of the
    /// same dims on the same walk. A continued accumulation cannot be rendered again
    /// (its sums were overwritten): that is the error.
    fn render_range(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        plan: Plan,
        frames: Range<u32>,
        continuable: bool,
    ) -> Result<RenderOutput> {
        let walk = (scene.grid.dims(), plan.traversal.name);
        if frames.start == 0 && self.raised_for.is_some_and(|raised| raised != walk) {
            self.dda_unroll = self.device_dda_unroll;
            self.raised_for = None;
        }
        let first =
            self.render_range_once(scene, settings, plan.clone(), frames.clone(), continuable);
        match first {
            Err(e)
                if e.downcast_ref::<LoopsCut>().is_some()
                    && frames.start == 0
                    && self.dda_unroll < SOFTWARE_DDA_UNROLL =>
            {
                self.dda_unroll = SOFTWARE_DDA_UNROLL;
                self.raised_for = Some(walk);
                self.render_range_once(scene, settings, plan, frames, continuable)
            }
            other => other,
        }
    }
}
