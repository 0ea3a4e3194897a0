//! The GPU tracer: a wgpu compute kernel (WGSL under `shaders/`, composed per [`Plan`])
//! that implements `src/trace_contract.md` in f32, in grid-local coordinates.

mod compose;
pub mod pyramid;

pub use compose::{ENTRY_POINT, ShaderError, compose_shader, validate};

use std::borrow::Cow;
use std::collections::HashMap;
use std::ops::Range;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use bytemuck::{Pod, Zeroable};
use glam::DVec3;

use crate::device::{buffer, buffer_entry, extent, readback, storage_entry, uniform_entry};
use crate::plan::{Plan, ShaderDefs};
use crate::render::{
    Frame, MAX_DEPTH_LIMIT, MAX_IMAGE_SIDE, RayStats, RenderOutput, RenderSettings,
};
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
    _pad_e: f32,
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

/// Ray counters (4 x 64 bit), the invocations whose loops the driver cut, one unused word.
const COUNTER_WORDS: usize = 10;
const COUNTER_BYTES: u64 = COUNTER_WORDS as u64 * 4;
/// Word of `counters` that counts invocations whose loops the driver cut short.
const LOOPS_CUT: usize = 8;

/// `@workgroup_size(64, 1, 1)` of `shaders/accumulate.wgsl`.
const REDUCE_WORKGROUP: u32 = 64;

// The WGSL uniform struct is 144 bytes (9 rows of 16).
const _: () = assert!(std::mem::size_of::<GpuParams>() == 144);
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

/// What a [`GpuTracer::render_frames`] accumulation was made from, so that a call that
/// continues it can tell whether the sums in the output and compensation buffers are
/// its own: each input by name with a hash of its Debug text (f64 prints exactly, so
/// equal text is equal input). The voxels are not hashed: the grid upload's generation
/// stands for them.
#[derive(Clone, Debug, PartialEq, Eq)]
struct AccumulationKey {
    parts: Vec<(&'static str, blake3::Hash)>,
}

impl AccumulationKey {
    fn new(scene: &Scene, settings: &RenderSettings, plan: &Plan) -> Self {
        let grid = &scene.grid;
        let hash = |s: String| blake3::hash(s.as_bytes());
        Self {
            parts: vec![
                ("render settings", hash(format!("{settings:?}"))),
                (
                    "plan (kernel variant)",
                    hash(format!("{:?} {:?}", plan.shader_defs(), plan.pyramid)),
                ),
                (
                    "grid's size or placement",
                    hash(format!(
                        "{:?} {:?} {:?}",
                        grid.dims(),
                        grid.voxel_size(),
                        grid.origin()
                    )),
                ),
                ("materials", hash(format!("{:?}", scene.materials))),
                ("lights", hash(format!("{:?}", scene.lights))),
                ("camera", hash(format!("{:?}", scene.camera))),
                ("ambient colour", hash(format!("{:?}", scene.ambient))),
            ],
        }
    }

    /// The names of the inputs that differ from `other`'s.
    fn differences(&self, other: &Self) -> Vec<&'static str> {
        self.parts
            .iter()
            .zip(&other.parts)
            .filter(|(a, b)| a.1 != b.1)
            .map(|(a, _)| a.0)
            .collect()
    }
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
    /// Bound as `technique_data` when the plan needs none (a binding needs a buffer),
    /// and as `walk_data` when the plan walks the voxel buffer.
    no_technique_data: wgpu::Buffer,
    /// The planned traversal's own data of the voxels the walks read (which traversal,
    /// the voxels' hash, the buffer: the sparse tree, say), while renders walk it.
    walk_data: Option<(
        &'static crate::technique::TraversalModel,
        blake3::Hash,
        wgpu::Buffer,
    )>,
    /// The triangle surfaces of the latest render that traced them: what they were made
    /// from (a hash), the cells, the hash of their tagged grid and their buffer
    /// (`surface` of shaders/bindings.wgsl).
    surfaces: Option<SurfaceUpload>,
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
    }
}

impl std::fmt::Display for GpuMemory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mib = |b: u64| b as f64 / 1048576.0;
        write!(
            f,
            "{:.2} MiB (grid {:.2}, walk data {:.2}, surfaces {:.2}, scene {:.3}, image {:.2}, \
             accumulation {:.2}, pyramids {:.2}, technique data {:.2})",
            mib(self.total()),
            mib(self.grid),
            mib(self.walk_data),
            mib(self.surfaces),
            mib(self.scene),
            mib(self.image),
            mib(self.accumulation),
            mib(self.pyramids),
            mib(self.technique)
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
        write!(f, "the driver's loop limit cut the walk")
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
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("voxlab tracer"),
            entries: &[
                uniform_entry(0),
                storage_entry(1, true),
                uniform_entry(2),
                storage_entry(3, true),
                storage_entry(4, false),
                storage_entry(5, false),
                storage_entry(6, true),
                storage_entry(7, true),
                storage_entry(8, true),
            ],
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
            params,
            counters,
            counters_readback,
            materials: None,
            lights: None,
            compensation: None,
            frame_slices: None,
            reduce: None,
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
            no_technique_data,
            walk_data: None,
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
        let out_bytes = w as u64 * h as u64 * 16;
        let max_out = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if out_bytes > max_out {
            bail!(
                "image {w}x{h} needs a {out_bytes}-byte radiance buffer; the device allows \
                 {max_out} (max_storage_buffer_binding_size / max_buffer_size)"
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
            // 4 % of a frame of the seed scene on lavapipe. Bounds checks stay.
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
        }
        Ok(&self.pipelines[&key])
    }

    /// Whether a render of `plan` reads the grid texture: the builds of the cone pyramids
    /// and of device-built technique data do. The walks do not: the dense walk reads the
    /// voxel buffer, the sparse one the tree.
    fn reads_grid_texture(plan: &Plan) -> bool {
        plan.pyramid.is_some()
            || matches!(
                plan.shadow_model.gpu_data,
                Some(crate::technique::GpuData::Device(_))
            )
    }

    /// Whether a render of `plan` reads the voxel buffer: a walk without data of its
    /// own (the dense walk) does.
    fn reads_voxel_buffer(plan: &Plan) -> bool {
        plan.traversal.data.is_none()
    }

    /// The largest storage buffer this device binds: the largest dense grid's voxel
    /// buffer, and the largest sparse tree.
    pub fn max_voxel_buffer_bytes(&self) -> u64 {
        let limits = self.device.limits();
        limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size)
    }

    /// Makes the voxel buffer of `grid` (the uploaded grid, or its copy with the cells
    /// tagged), whose voxels hash to `hash`, unless the upload holds it.
    fn upload_voxel_buffer(&mut self, grid: &crate::scene::Grid, hash: blake3::Hash) {
        let Some(g) = self.grid.as_mut() else {
            return;
        };
        if g.voxels.as_ref().is_some_and(|v| v.0 == hash) {
            return;
        }
        let bytes = crate::technique::dense::voxel_buffer_bytes(g.dims);
        let buf = buffer(
            &self.device,
            "voxels",
            bytes,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        );
        // The plan walks a grid held sparse through its tree, never this buffer.
        let dense = grid
            .to_dense()
            .expect("the plan walks sparse grids through the tree");
        let data = dense.data();
        let whole = data.len() / 4 * 4;
        self.queue.write_buffer(&buf, 0, &data[..whole]);
        if whole < data.len() || (whole as u64) < bytes {
            let mut tail = data[whole..].to_vec();
            tail.resize((bytes - whole as u64) as usize, 0);
            self.queue.write_buffer(&buf, whole as u64, &tail);
        }
        g.voxels = Some((hash, buf));
    }

    /// Uploads the grid unless the device already holds exactly this one; without
    /// `texture` a one-voxel stand-in is bound (a hash of the voxels tells a change).
    fn upload_grid(&mut self, scene: &Scene, texture: bool) {
        let dims = scene.grid.dims();
        let hash = scene.grid.content_hash();
        let same = self
            .grid
            .as_ref()
            .is_some_and(|g| g.dims == dims && g.hash == hash);
        if same && self.grid.as_ref().is_some_and(|g| g.texture || !texture) {
            return;
        }
        // The same voxels keep their generation: what was built from them stays valid.
        let generation = self.grid_generation() + u64::from(!same);
        // Only the cone pyramids and the distance field read the texture, and the plan
        // builds them for dense grids (and small ones) only.
        let dense = texture.then(|| scene.grid.to_dense().expect("planned for dense grids"));
        let (size, data, bytes_per_row, rows) = if let Some(d) = &dense {
            (extent(dims), d.data(), dims.x, dims.y)
        } else {
            (extent(glam::UVec3::ONE), &[0u8][..], 1, 1)
        };
        let gpu_texture = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("voxel grid"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D3,
            format: wgpu::TextureFormat::R8Uint,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        // write_texture takes tightly packed rows (no 256-byte row alignment, which only
        // buffer-to-texture copies need): x-fastest, as the grid stores them.
        self.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &gpu_texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            data,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(bytes_per_row),
                rows_per_image: Some(rows),
            },
            size,
        );
        let view = gpu_texture.create_view(&wgpu::TextureViewDescriptor::default());
        // The voxel buffer of the same voxels stays.
        let voxels = self.grid.take().filter(|_| same).and_then(|g| g.voxels);
        self.grid = Some(GridUpload {
            voxels,
            generation,
            dims,
            hash,
            texture,
            view,
        });
    }

    /// Builds and uploads the data `traversal` walks in `grid` (whose voxels hash to
    /// `hash`: the sparse tree, say) unless the device holds it already; returns its
    /// bytes.
    fn upload_walk_data(
        &mut self,
        traversal: &'static crate::technique::TraversalModel,
        grid: &crate::scene::Grid,
        hash: blake3::Hash,
    ) -> Result<u64> {
        let build = traversal
            .data
            .expect("only a traversal with data of its own uploads it");
        if let Some((t, h, b)) = &self.walk_data
            && *h == hash
            && std::ptr::eq(*t, traversal)
        {
            return Ok(b.size());
        }
        self.walk_data = None;
        let data = build(grid);
        let words = data.device_words();
        let bytes = (words.len() * 4).next_multiple_of(16) as u64;
        let max = self.max_voxel_buffer_bytes();
        if bytes > max {
            bail!(
                "the {} traversal's data of grid {}x{}x{} needs {bytes} bytes; the device \
                 allows {max} (max_storage_buffer_binding_size); render.traversal = \"dense\" \
                 walks the voxel buffer instead",
                traversal.name,
                grid.dims().x,
                grid.dims().y,
                grid.dims().z
            );
        }
        let buf = buffer(
            &self.device,
            traversal.label,
            bytes,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        );
        self.queue
            .write_buffer(&buf, 0, bytemuck::cast_slice(words));
        self.walk_data = Some((traversal, hash, buf));
        Ok(bytes)
    }

    /// Lists the plan's triangle surfaces in the grid and uploads them, unless the
    /// device holds those already (the same grid, mesh and kind). `None` for voxels.
    fn upload_surfaces(
        &mut self,
        scene: &Scene,
        plan: &Plan,
    ) -> Result<Option<std::sync::Arc<crate::triangles::SurfaceTrace>>> {
        if !plan.surface.traces_triangles() {
            self.surfaces = None;
            return Ok(None);
        }
        // What the cells were listed from: the kind, the grid's placement, its voxels
        // (the hash upload_grid has just taken, not taken again) and the mesh.
        let mut h = blake3::Hasher::new();
        h.update(plan.surface.name().as_bytes());
        let g = &scene.grid;
        h.update(format!("{:?}", (g.dims(), g.voxel_size(), g.origin())).as_bytes());
        match &self.grid {
            Some(u) => h.update(u.hash.as_bytes()),
            None => h.update(g.content_hash().as_bytes()),
        };
        (plan.surface.hash_inputs)(scene, &mut h);
        let key = h.finalize();
        if let Some(u) = self.surfaces.as_ref().filter(|u| u.key == key) {
            return Ok(Some(u.trace.clone()));
        }
        self.surfaces = None;
        let trace = crate::triangles::surface_trace(scene, plan.surface)?
            .context("the plan traces triangles the scene does not have")?;
        let words = trace.gpu_words();
        let bytes = (words.len() * 4) as u64;
        let max = self.max_voxel_buffer_bytes();
        if bytes > max {
            bail!(
                "the triangle surfaces need {bytes} bytes; the device binds at most {max} \
                 (max_storage_buffer_binding_size); render.surface = \"voxels\" draws the \
                 voxels instead"
            );
        }
        let buffer = buffer(
            &self.device,
            "triangle surfaces",
            bytes,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        );
        self.queue
            .write_buffer(&buffer, 0, bytemuck::cast_slice(&words));
        let trace = std::sync::Arc::new(trace);
        self.surfaces = Some(SurfaceUpload {
            key,
            tagged_hash: blake3::hash(trace.tagged.data()),
            trace: trace.clone(),
            buffer,
        });
        Ok(Some(trace))
    }

    /// A buffer of at least `bytes` in `slot`, kept while large enough.
    fn grow(
        device: &wgpu::Device,
        slot: &mut Option<(u64, wgpu::Buffer)>,
        bytes: u64,
        label: &str,
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        if let Some((cap, b)) = slot
            && *cap >= bytes
        {
            return b.clone();
        }
        let b = buffer(device, label, bytes, usage);
        *slot = Some((bytes, b.clone()));
        b
    }

    /// The materials and lights as `shaders/types.wgsl` lays them out: the tracer's
    /// and the pyramid injection's; the lights' ray-cutoff bounds from `bounds` (0
    /// where it has none: the injection reads none).
    fn scene_data(scene: &Scene, bounds: &[f32]) -> (Vec<GpuMaterial>, Vec<GpuLight>) {
        let materials = scene
            .materials
            .iter()
            .map(|m| GpuMaterial {
                albedo: f3(m.albedo),
                kd: m.kd as f32,
                ks: m.ks as f32,
                shininess: m.shininess as f32,
                kr: m.kr as f32,
                kt: m.kt as f32,
                ior: m.ior as f32,
                // Per world unit times world units per voxel: per voxel unit.
                sigma: f3(m.absorption(scene.grid.voxel_size()) * scene.grid.voxel_size()),
                emission: f3(m.emission),
                _pad_e: 0.0,
            })
            .collect();
        let mut lights: Vec<GpuLight> = scene
            .lights
            .iter()
            .enumerate()
            .map(|(j, l)| GpuLight {
                bound: bounds.get(j).copied().unwrap_or(0.0),
                ..Self::light(scene, l)
            })
            .collect();
        // A binding cannot be empty: a scene without lights binds one unused entry.
        if lights.is_empty() {
            lights.push(GpuLight::zeroed());
        }
        (materials, lights)
    }

    /// Writes the materials and lights into their buffers (grown when too small) and
    /// returns those.
    fn upload_scene(&mut self, scene: &Scene, bounds: &[f32]) -> (wgpu::Buffer, wgpu::Buffer) {
        let (mut materials, lights) = Self::scene_data(scene, bounds);
        // The tracer declares the whole table (`shaders/bindings.wgsl`): a uniform array
        // has a fixed length. The cone injection binds the same buffer as storage.
        materials.resize(
            materials.len().max(crate::scene::MAX_MATERIALS),
            GpuMaterial::zeroed(),
        );
        let usage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::UNIFORM
            | wgpu::BufferUsages::COPY_DST;
        let upload = |slot: &mut Option<(u64, wgpu::Buffer)>, bytes: &[u8], label| {
            let b = Self::grow(&self.device, slot, bytes.len() as u64, label, usage);
            self.queue.write_buffer(&b, 0, bytes);
            b
        };
        let mat_buf = upload(
            &mut self.materials,
            bytemuck::cast_slice(&materials),
            "materials",
        );
        let light_buf = upload(&mut self.lights, bytemuck::cast_slice(&lights), "lights");
        (mat_buf, light_buf)
    }

    fn output_buffers(&mut self, pixels: u64) -> (wgpu::Buffer, wgpu::Buffer) {
        if let Some(b) = &self.buffers
            && b.pixels == pixels
        {
            return (b.output.clone(), b.readback.clone());
        }
        let output = buffer(
            &self.device,
            "radiance",
            pixels * 16,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        );
        let readback = readback(&self.device, "radiance readback", pixels * 16);
        self.buffers = Some(Buffers {
            pixels,
            output: output.clone(),
            readback: readback.clone(),
        });
        (output, readback)
    }

    fn params(scene: &Scene, settings: &RenderSettings) -> GpuParams {
        let grid = &scene.grid;
        let vs = grid.voxel_size();
        let cam = scene.camera.frame();
        let aspect = settings.width as f64 / settings.height as f64;
        // Directions keep their length in local coordinates (a uniform scale), so only
        // the eye is transformed; everything in f64 before the one rounding to f32.
        GpuParams {
            eye: f3(grid.to_local(cam.eye)),
            width: settings.width,
            forward: f3(cam.forward),
            height: settings.height,
            right_scaled: f3(cam.right * (cam.tan_half_vfov * aspect)),
            num_lights: scene.lights.len() as u32,
            up_scaled: f3(cam.up * cam.tan_half_vfov),
            max_reflection_depth: settings.max_reflection_depth,
            dims: grid.dims().to_array(),
            max_refraction_depth: settings.max_refraction_depth,
            ambient: f3(scene.ambient),
            eye_medium: scene.medium_at(cam.eye) as u32,
            // eps = ray_offset * voxel_size in world units is ray_offset voxels.
            eps: settings.ray_offset as f32,
            voxel_size: vs as f32,
            falloff_min_dist_sq: (settings.falloff_min_distance * settings.falloff_min_distance)
                as f32,
            falloff: settings.falloff as u32,
            light_samples: settings.light_samples.max(1),
            seed: settings.seed,
            frame_begin: 0,
            frame_count: 1,
            max_total_depth: settings.total_depth_limit(),
            ray_cutoff: crate::ray_cutoff::cutoff(settings),
            pixel_filter: settings.pixel_filter.code(),
            filter_width: settings.filter_width as f32,
        }
    }

    /// A light as the kernel sees it. Point lights and area lights of size 0 are points
    /// at their centres; other area lights carry their kind and their axes scaled by
    /// their size, from AreaLight::frame in f64, divided by the voxel size into voxel
    /// units. Only the shadow model reads the shape: hard shadows take the centre alone.
    fn light(scene: &Scene, light: &Light) -> GpuLight {
        let grid = &scene.grid;
        let mut g = GpuLight {
            position: f3(grid.to_local(light.position())),
            kind: LIGHT_POINT,
            radiance: f3(light.color() * light.intensity()),
            ..GpuLight::zeroed()
        };
        // Every area light of non-zero size goes with its shape: the shadow model decides
        // whether to read it (hard shadows take its centre). A Lambertian light carries
        // its normal whatever its size, for the emitter's cosine.
        let Light::Area(a) = light else { return g };
        let local = |v: DVec3| f3(v / grid.voxel_size());
        let (u, v, n) = a.frame();
        if a.emission == Emission::Lambertian {
            g.emission = EMISSION_LAMBERTIAN;
            g.axis_n = local(n);
        }
        if !light.is_area() {
            return g;
        }
        let (kind, axes) = match a.shape {
            AreaShape::Rect { width, height } => (LIGHT_RECT, [u * width, v * height, n]),
            AreaShape::Disk { radius } => (LIGHT_DISK, [u * radius, v * radius, n]),
            // The sphere is sampled in world axes.
            AreaShape::Sphere { radius } => (
                LIGHT_SPHERE,
                [DVec3::X * radius, DVec3::Y * radius, DVec3::Z * radius],
            ),
        };
        g.kind = kind;
        g.axis_u = local(axes[0]);
        g.axis_v = local(axes[1]);
        g.axis_n = local(axes[2]);
        g
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

    /// Frames the accumulation a `render_frames` call may continue holds (it continues
    /// at this frame): 0 when there is none, after any other render, a failed one, or
    /// a plan that does not accumulate.
    pub fn accumulated_frames(&self) -> u32 {
        self.accumulation.as_ref().map_or(0, |a| a.frames)
    }

    /// Whether `frames` is a range `plan` can render: non-empty and within its frames.
    fn check_frames(settings: &RenderSettings, plan: &Plan, frames: &Range<u32>) -> Result<()> {
        let (a, b) = (frames.start, frames.end);
        if a >= b {
            bail!("frames {a}..{b}: an empty range; render at least one frame");
        }
        let cap = plan.frames(settings);
        if b <= cap {
            return Ok(());
        }
        if plan.accumulate {
            bail!(
                "frames {a}..{b}: past the end of the accumulation, {cap} frames \
                 (settings.spp = {} caps it)",
                settings.spp
            );
        }
        let why = if settings.spp <= 1 {
            "settings.spp is 1".to_string()
        } else {
            format!(
                "nothing is sampled (shadow model {} draws no samples here and there is no \
                 pixel filter), so every frame is the same image",
                plan.shadow_model.name
            )
        };
        bail!(
            "frames {a}..{b}: this plan does not accumulate ({why}); it renders one frame, \
             frames 0..1"
        )
    }

    /// Whether the accumulation this tracer holds is the one `frames` continues.
    fn check_continuation(&self, key: &AccumulationKey, frames: &Range<u32>) -> Result<()> {
        let f = format!("frames {}..{}", frames.start, frames.end);
        let Some(acc) = &self.accumulation else {
            bail!(
                "{f}: no accumulation to continue: this tracer's previous render was not a \
                 render_frames call of an accumulating plan (any other render, or a failed \
                 one, ends the accumulation); start again at frame 0"
            );
        };
        let n = acc.frames;
        let mut differs = key.differences(&acc.key);
        if acc.grid_generation != self.grid_generation() {
            differs.push("voxel grid (another was uploaded since)");
        }
        if acc.pyramid_builds != self.pyramid_builds {
            differs.push("cone pyramids (rebuilt since)");
        }
        if !differs.is_empty() {
            bail!(
                "{f}: cannot continue the accumulation of frames 0..{n}, which was made \
                 from other inputs (changed: {}); start again at frame 0",
                differs.join(", ")
            );
        }
        if frames.start > n {
            bail!(
                "{f}: would skip frames {n}..{}: the accumulation holds frames 0..{n}, so \
                 the next range must start at {n}",
                frames.start
            );
        }
        if frames.start < n {
            bail!(
                "{f}: frames {}..{n} are already accumulated (it holds frames 0..{n}), so \
                 the next range must start at {n}",
                frames.start
            );
        }
        Ok(())
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

    /// Makes (or keeps) the `technique_data` of the plan's plug-in shadow model and
    /// returns its size in bytes; 0, with any held data dropped, when the plan needs none.
    fn upload_technique_data(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        plan: &Plan,
    ) -> Result<u64> {
        let model = plan.shadow_model;
        let Some(make) = model.gpu_data else {
            self.technique_data = None;
            return Ok(0);
        };
        // Its inputs: the technique, its settings, the voxels (by upload generation) and
        // everything else of the scene but the camera.
        let key = blake3::hash(
            format!(
                "{} {:?} {} {:?} {:?} {:?} {:?}",
                model.name,
                settings.technique_params,
                self.grid_generation(),
                scene.grid.voxel_size(),
                scene.grid.origin(),
                scene.materials,
                scene.lights
            )
            .as_bytes(),
        );
        if let Some((k, b)) = &self.technique_data
            && *k == key
        {
            return Ok(b.size());
        }
        // Dropped first: a failed build leaves nothing that looks current.
        self.technique_data = None;
        let buf = match make {
            crate::technique::GpuData::Host(make) => {
                let mut data = make(scene, settings);
                if data.is_empty() {
                    data.push(0.0);
                }
                let buf = buffer(
                    &self.device,
                    model.name,
                    (data.len() * 4) as u64,
                    wgpu::BufferUsages::STORAGE
                        | wgpu::BufferUsages::COPY_DST
                        | wgpu::BufferUsages::COPY_SRC,
                );
                self.queue
                    .write_buffer(&buf, 0, bytemuck::cast_slice(&data));
                buf
            }
            crate::technique::GpuData::Device(build) => {
                let grid = &self.grid.as_ref().expect("grid uploaded").view;
                build(&crate::technique::GpuBuild {
                    device: &self.device,
                    queue: &self.queue,
                    grid,
                    scene,
                    settings,
                })
                .with_context(|| format!("building the data of shadow model {}", model.name))?
            }
        };
        let size = buf.size();
        self.technique_data = Some((key, buf));
        Ok(size)
    }

    fn render_range_once(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        plan: Plan,
        frames: Range<u32>,
        continuable: bool,
    ) -> Result<RenderOutput> {
        let mut plan = plan;
        plan.dda_unroll = self.dda_unroll;
        let dims = scene.grid.dims();
        let max_bytes = self.max_voxel_buffer_bytes();
        let fits = |t: &crate::technique::TraversalModel| t.binds_within(dims, max_bytes);
        if settings.traversal == crate::render::Traversal::Auto && !fits(plan.traversal) {
            // The device cannot bind what the planned walk reads (the dense grid, the
            // traversal's own data): the auto choice among the walks it can bind (the
            // tree walk binds any grid).
            let (walk, why) = crate::plan::auto_traversal_within(scene, settings, fits);
            plan.traversal_reason = format!(
                "auto: the {} walk's {} bytes are more than this device binds ({}, \
                 max_storage_buffer_binding_size); {why}",
                plan.traversal.name,
                plan.traversal.device_bytes.map_or(0, |b| b(dims)),
                max_bytes
            );
            plan.traversal = walk;
            plan.tree_levels = crate::plan::tree_levels(walk, dims);
        }
        let count = plan.count_rays;
        self.check(scene, settings, &plan)?;
        Self::check_frames(settings, &plan, &frames)?;
        self.pipeline(&plan)?;
        // Device allocations fail as errors of the render, never through wgpu's default
        // handler (a panic): a grid texture or buffer the device cannot hold is reported
        // with its size. Popped (in reverse order) once everything is uploaded.
        let oom_scope = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation_scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        self.upload_grid(scene, Self::reads_grid_texture(&plan));
        // The walks read the grid, or with triangle surfaces its copy with the cells
        // tagged (the texture the cone and sdf builds read stays the grid's own).
        let setup_start = Instant::now();
        let trace = self.upload_surfaces(scene, &plan)?;
        // Nothing is set up for voxels: their setup time stays exactly zero.
        let surface_time = if trace.is_some() {
            setup_start.elapsed()
        } else {
            Duration::ZERO
        };
        let walk_grid = trace.as_ref().map_or(&scene.grid, |t| &t.tagged);
        let walk_hash = match (&self.surfaces, &self.grid) {
            (Some(u), _) => u.tagged_hash,
            (None, Some(g)) => g.hash,
            (None, None) => scene.grid.content_hash(),
        };
        if Self::reads_voxel_buffer(&plan) {
            self.upload_voxel_buffer(walk_grid, walk_hash);
        } else if let Some(g) = self.grid.as_mut() {
            // Dropped while renders walk the tree.
            g.voxels = None;
        }
        let (walk_bytes, walk_time) = if plan.traversal.data.is_some() {
            let start = Instant::now();
            (
                self.upload_walk_data(plan.traversal, walk_grid, walk_hash)?,
                start.elapsed(),
            )
        } else {
            // Dropped while renders walk the grid: nothing holds it on the device.
            self.walk_data = None;
            (0, Duration::ZERO)
        };
        let key = continuable.then(|| AccumulationKey::new(scene, settings, &plan));
        if frames.start > 0 {
            // Only render_frames asks for a start above 0.
            let key = key
                .as_ref()
                .expect("a continuation comes from render_frames");
            self.check_continuation(key, &frames)?;
        }
        // From here on the buffers change: no accumulation survives a failure.
        self.accumulation = None;

        // Frames in dispatches of whole frames; the first dispatch's params are written
        // with the uploads, the others' before their own submissions.
        let pixels = settings.width as u64 * settings.height as u64;
        let todo = frames.end - frames.start;
        let per_dispatch = if plan.accumulate {
            let most = frames_per_dispatch(pixels, todo);
            // A render that may be stopped checks between dispatches: smaller ones let it
            // stop within a fraction of the whole (a 64x64 image's 256 frames are one
            // dispatch otherwise). The frames are summed in the same order either way.
            if self.progress.as_ref().is_some_and(|p| p.can_stop()) {
                most.div_ceil(WATCHED_SPLIT).max(1)
            } else {
                most
            }
        } else {
            1
        };
        let mut params = Self::params(scene, settings);
        params.frame_begin = frames.start;
        params.frame_count = per_dispatch;
        self.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));

        let bounds = if plan.ray_cutoff {
            crate::ray_cutoff::light_bounds(scene, settings)
        } else {
            Vec::new()
        };
        let (mat_buf, light_buf) = self.upload_scene(scene, &bounds);
        self.queue
            .write_buffer(&self.counters, 0, &[0u8; COUNTER_BYTES as usize]);

        let (output, readback) = self.output_buffers(pixels);
        // Accumulating, the tracer writes each frame of a dispatch to its own slice and
        // the accumulation kernel adds them to the sums in `output` and `compensation`.
        let accumulation = if plan.accumulate {
            let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
            let compensation = Self::grow(
                &self.device,
                &mut self.compensation,
                pixels * 16,
                "compensation",
                storage,
            );
            let slices = Self::grow(
                &self.device,
                &mut self.frame_slices,
                pixels * 16 * per_dispatch as u64,
                "frame slices",
                wgpu::BufferUsages::STORAGE,
            );
            Some((compensation, slices))
        } else {
            // Only accumulating renders hold them.
            self.compensation = None;
            self.frame_slices = None;
            None
        };
        let compensation = accumulation.as_ref().map(|a| a.0.clone());
        let reduce = accumulation
            .as_ref()
            .map(|(compensation, slices)| self.reduce_bind_group(&output, compensation, slices));
        let technique_bytes = self.upload_technique_data(scene, settings, &plan)?;
        let technique_data = match (&self.technique_data, technique_bytes) {
            (Some((_, b)), 1..) => b,
            _ => &self.no_technique_data,
        };
        let voxels = self
            .grid
            .as_ref()
            .and_then(|g| g.voxels.as_ref().map(|v| &v.1))
            .unwrap_or(&self.no_technique_data);
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("voxlab tracer"),
            layout: &self.layout,
            entries: &[
                buffer_entry(0, &self.params),
                buffer_entry(1, voxels),
                buffer_entry(2, &mat_buf),
                buffer_entry(3, &light_buf),
                buffer_entry(4, accumulation.as_ref().map_or(&output, |a| &a.1)),
                buffer_entry(5, &self.counters),
                buffer_entry(6, technique_data),
                buffer_entry(
                    7,
                    self.walk_data
                        .as_ref()
                        .map_or(&self.no_technique_data, |t| &t.2),
                ),
                buffer_entry(
                    8,
                    self.surfaces
                        .as_ref()
                        .map_or(&self.no_technique_data, |u| &u.buffer),
                ),
            ],
        });

        // The pyramids, built on the device before the timed trace (their build is
        // not part of the trace time), only when the plan has a cone feature.
        let setup = Instant::now();
        let cone_group = match plan.pyramid {
            Some(layout) => {
                self.cache_pyramid(scene, settings, layout, plan.radiance_pyramid())?;
                let pyr = &self.pyramid.as_ref().expect("pyramid cached").1;
                let grid = &scene.grid;
                let radii: Vec<f32> = scene
                    .lights
                    .iter()
                    .map(|l| (pyramid::light_radius(l) / grid.voxel_size()) as f32)
                    .collect();
                Some(self.cone_bind_group(pyr, &settings.cones, &self.cone_layout, &radii))
            }
            None => None,
        };
        self.last_setup_time = walk_time
            + surface_time
            + if plan.pyramid.is_some() {
                setup.elapsed()
            } else {
                Duration::ZERO
            };

        // Finish the uploads first so the timed submission holds the trace alone.
        self.queue.submit([]);
        self.wait()?;
        let validation = pollster::block_on(validation_scope.pop());
        let oom = pollster::block_on(oom_scope.pop());
        if let Some(e) = oom.or(validation) {
            // Whatever was made is not to be trusted: the next render starts over.
            self.grid = None;
            self.buffers = None;
            self.compensation = None;
            self.frame_slices = None;
            self.pyramid = None;
            self.technique_data = None;
            self.walk_data = None;
            self.surfaces = None;
            let d = scene.grid.dims();
            bail!(
                "the device could not hold this render (grid {}x{}x{}: {} bytes of texture; \
                 image {}x{}: {} bytes of radiance buffers): {e}",
                d.x,
                d.y,
                d.z,
                scene.grid.voxel_count(),
                settings.width,
                settings.height,
                settings.width as u64 * settings.height as u64 * 16 * 2
            );
        }

        let pipeline = &self.pipelines[&plan.shader_defs()];
        // Two timestamps per pass (its start and end): the trace's, and with
        // accumulation the accumulation kernel's.
        let dispatches = todo.div_ceil(per_dispatch);
        let passes = dispatches * if reduce.is_some() { 2 } else { 1 };
        // A query set holds at most QUERY_SET_MAX_QUERIES: a render of more passes (many
        // frames of a large image, one dispatch each) is timed by the wall clock.
        let timed = self.timestamps && 2 * passes <= wgpu::QUERY_SET_MAX_QUERIES;
        let queries = timed.then(|| {
            self.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("voxlab trace timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * passes,
            })
        });
        let (reduce_x, reduce_y) = Self::reduce_grid(pixels);
        let mut pass_index = 0u32;
        let start = Instant::now();
        let mut begin = frames.start;
        while begin < frames.end {
            let count = per_dispatch.min(frames.end - begin);
            if begin > frames.start {
                params.frame_begin = begin;
                params.frame_count = count;
                self.queue
                    .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
            }
            if let Some((_, _, reduce_params)) = &self.reduce
                && reduce.is_some()
            {
                let rp = ReduceParams {
                    pixels: pixels as u32,
                    row: reduce_x * REDUCE_WORKGROUP,
                    frame_begin: begin,
                    frame_count: count,
                };
                self.queue
                    .write_buffer(reduce_params, 0, bytemuck::bytes_of(&rp));
            }
            let mut encoder = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("voxlab trace"),
                });
            {
                let mut pass = timed_pass(
                    &mut encoder,
                    "voxlab trace",
                    queries.as_ref(),
                    &mut pass_index,
                );
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, &bind_group, &[]);
                if let Some(g) = &cone_group {
                    pass.set_bind_group(1, g, &[]);
                }
                // One invocation per pixel and frame (frames along z), the tiles in
                // stripes (DISPATCH_STRIPES).
                let (stripes, per_stripe) = trace_workgroups(settings.width, settings.height);
                pass.dispatch_workgroups(
                    stripes,
                    per_stripe,
                    if plan.accumulate { count } else { 1 },
                );
            }
            if let (Some(group), Some((_, reduce_pipeline, _))) = (&reduce, &self.reduce) {
                let mut pass = timed_pass(
                    &mut encoder,
                    "voxlab accumulate",
                    queries.as_ref(),
                    &mut pass_index,
                );
                pass.set_pipeline(reduce_pipeline);
                pass.set_bind_group(0, group, &[]);
                pass.dispatch_workgroups(reduce_x, reduce_y, 1);
            }
            self.queue.submit([encoder.finish()]);
            begin += count;
            // Waiting between dispatches only when someone watches: the frames done.
            if let Some(p) = &self.progress {
                self.wait()?;
                p.update(u64::from(begin - frames.start), u64::from(todo));
                if p.stopped() && begin < frames.end {
                    anyhow::bail!("stopped after {} of {todo} frames", begin - frames.start);
                }
            }
        }
        self.wait()?;
        let trace_time = start.elapsed();
        self.last_gpu_time = match &queries {
            Some(q) => Some(self.pass_time(q, passes)?),
            None => None,
        };

        let copy = |from: &wgpu::Buffer| {
            let mut encoder = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("voxlab readback"),
                });
            encoder.copy_buffer_to_buffer(from, 0, &readback, 0, pixels * 16);
            encoder.copy_buffer_to_buffer(
                &self.counters,
                0,
                &self.counters_readback,
                0,
                COUNTER_BYTES,
            );
            self.queue.submit([encoder.finish()]);
        };
        copy(&output);
        let radiance: Vec<[f32; 4]> = self.read(&readback, pixels * 16)?;
        // With ACCUMULATE the buffers hold the sum of the frames and its compensation:
        // the image is (sum + compensation) / frames, in f64, rounded once.
        let compensation: Option<Vec<[f32; 4]>> = match &compensation {
            Some(b) => {
                copy(b);
                Some(self.read(&readback, pixels * 16)?)
            }
            None => None,
        };
        let counts: Vec<u32> = self.read(&self.counters_readback, COUNTER_BYTES)?;
        if counts[LOOPS_CUT] > 0 {
            let info = self.adapter.get_info();
            return Err(anyhow::Error::new(LoopsCut).context(format!(
                "{} of {} pixel-frames of this image were cut short by the driver ({}, {}): \
                 Mesa's software driver (llvmpipe, lavapipe) ends every loop of an \
                 invocation after 65535 loop iterations in all (LP_MAX_TGSI_LOOP_ITERATIONS, \
                 counted over the 8 or 16 SIMD lanes that run together), and one frame of \
                 these pixels needs more (depth limits {}/{}, {} light sample(s), {} \
                 light(s), grid {}x{}x{}; {} voxel steps per loop iteration). The image \
                 would be wrong, so none is returned: lower light_samples, the depth limits \
                 (or max_depth) or the grid size, or render with --backend cpu or on a \
                 hardware GPU",
                counts[LOOPS_CUT],
                pixels * todo as u64,
                info.name,
                info.driver_info,
                settings.max_reflection_depth,
                settings.max_refraction_depth,
                settings.light_samples,
                scene.lights.len(),
                scene.grid.dims().x,
                scene.grid.dims().y,
                scene.grid.dims().z,
                plan.dda_unroll,
            )));
        }
        let c = |i: usize| counts[2 * i] as u64 | (counts[2 * i + 1] as u64) << 32;
        let stats = if count {
            RayStats {
                primary: c(0),
                secondary: c(1),
                shadow: c(2),
                voxel_steps: c(3),
                triangle_tests: 0,
            }
        } else {
            RayStats::default()
        };

        let mut frame = Frame::new(settings.width, settings.height);
        match &compensation {
            None => {
                for (dst, src) in frame.pixels.iter_mut().zip(&radiance) {
                    *dst = [src[0], src[1], src[2]];
                }
            }
            Some(comp) => {
                let n = frames.end as f64;
                for ((dst, sum), c) in frame.pixels.iter_mut().zip(&radiance).zip(comp) {
                    *dst = std::array::from_fn(|k| ((sum[k] as f64 + c[k] as f64) / n) as f32);
                }
            }
        }
        let pyramids = plan.pyramid.map_or(0, |layout| {
            layout.texture_bytes(crate::technique::cones::pyramid::OPACITY_TEXEL_BYTES)
                + if plan.radiance_pyramid() {
                    layout.texture_bytes(crate::technique::cones::pyramid::RADIANCE_TEXEL_BYTES)
                } else {
                    0
                }
        });
        self.last_memory = Some(GpuMemory {
            grid: if Self::reads_grid_texture(&plan) {
                scene.grid.voxel_count() as u64
            } else {
                0
            } + if Self::reads_voxel_buffer(&plan) {
                crate::technique::dense::voxel_buffer_bytes(scene.grid.dims())
            } else {
                0
            },
            walk_data: walk_bytes,
            surfaces: self.surfaces.as_ref().map_or(0, |u| u.buffer.size()),
            scene: mat_buf.size() + light_buf.size() + self.params.size() + 2 * COUNTER_BYTES,
            image: output.size() + readback.size(),
            accumulation: accumulation
                .as_ref()
                .map_or(0, |(c, slices)| c.size() + slices.size()),
            pyramids,
            technique: technique_bytes,
        });
        if let Some(key) = key
            && plan.accumulate
        {
            self.accumulation = Some(Accumulation {
                key,
                grid_generation: self.grid_generation(),
                pyramid_builds: self.pyramid_builds,
                frames: frames.end,
            });
        }
        self.last_plan = Some(plan);
        Ok(RenderOutput {
            frame,
            stats,
            trace_time,
            setup_time: self.last_setup_time,
        })
    }

    /// The accumulation kernel's dispatch grid for `pixels`: 64-wide workgroups along x
    /// up to the per-dimension limit, then rows of them along y.
    fn reduce_grid(pixels: u64) -> (u32, u32) {
        let groups = pixels.div_ceil(REDUCE_WORKGROUP as u64);
        let x = groups.min(32768) as u32;
        (x, groups.div_ceil(x as u64) as u32)
    }

    /// The accumulation kernel's bind group (made with the kernel on first use): frame
    /// slices in, running sums and compensation in and out.
    fn reduce_bind_group(
        &mut self,
        sums: &wgpu::Buffer,
        compensation: &wgpu::Buffer,
        slices: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        if self.reduce.is_none() {
            let layout = self
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("voxlab accumulate"),
                    entries: &[
                        uniform_entry(0),
                        storage_entry(1, true),
                        storage_entry(2, false),
                        storage_entry(3, false),
                    ],
                });
            let pipeline_layout =
                self.device
                    .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("voxlab accumulate"),
                        bind_group_layouts: &[Some(&layout)],
                        immediate_size: 0,
                    });
            let module = compose::compose(&[], compose::ACCUMULATE, HashMap::new())
                .expect("shaders/accumulate.wgsl composes: it imports nothing");
            let shader = self
                .device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("voxlab accumulate"),
                    source: wgpu::ShaderSource::Naga(Cow::Owned(module)),
                });
            let pipeline = self
                .device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("voxlab accumulate"),
                    layout: Some(&pipeline_layout),
                    module: &shader,
                    entry_point: Some(ENTRY_POINT),
                    compilation_options: Default::default(),
                    cache: None,
                });
            let params = buffer(
                &self.device,
                "accumulate params",
                std::mem::size_of::<ReduceParams>() as u64,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            );
            self.reduce = Some((layout, pipeline, params));
        }
        let (layout, _, params) = self.reduce.as_ref().expect("made above");
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("voxlab accumulate"),
            layout,
            entries: &[
                buffer_entry(0, params),
                buffer_entry(1, slices),
                buffer_entry(2, sums),
                buffer_entry(3, compensation),
            ],
        })
    }

    fn wait(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| anyhow!("waiting for the GPU: {e}"))?;
        Ok(())
    }

    /// Maps `buffer` (already copied into), reads `bytes` as `T`s, unmaps.
    /// The summed durations of `passes` compute passes whose start and end timestamps
    /// are queries 2i and 2i + 1 of `q`.
    fn pass_time(&self, q: &wgpu::QuerySet, passes: u32) -> Result<Duration> {
        let bytes = 16 * passes as u64;
        let resolve = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("voxlab timestamps"),
            size: bytes,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("voxlab timestamps readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("voxlab timestamps"),
            });
        encoder.resolve_query_set(q, 0..2 * passes, &resolve, 0);
        encoder.copy_buffer_to_buffer(&resolve, 0, &readback, 0, bytes);
        self.queue.submit([encoder.finish()]);
        let ticks: Vec<u64> = self.read(&readback, bytes)?;
        // Ticks to nanoseconds; a pass whose end precedes its start (a driver that
        // resets its counter) counts as zero rather than wrapping.
        let period = self.queue.get_timestamp_period() as f64;
        let ns: f64 = ticks
            .chunks_exact(2)
            .map(|p| p[1].saturating_sub(p[0]) as f64 * period)
            .sum();
        Ok(Duration::from_nanos(ns.round() as u64))
    }

    /// The `technique_data` of the latest render whose plan had a plug-in shadow model
    /// with data (`None` otherwise), read back: for tests that hold the device's build to
    /// the CPU's.
    pub fn read_technique_data(&self) -> Result<Option<Vec<f32>>> {
        let Some((_, buf)) = &self.technique_data else {
            return Ok(None);
        };
        let copy = readback(&self.device, "technique data readback", buf.size());
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buf, 0, &copy, 0, buf.size());
        self.queue.submit([encoder.finish()]);
        self.read(&copy, buf.size()).map(Some)
    }

    fn read<T: Pod>(&self, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<T>> {
        let slice = buffer.slice(..bytes);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait()?;
        rx.recv()
            .context("buffer mapping was dropped")?
            .map_err(|e| anyhow!("mapping a readback buffer: {e}"))?;
        let out = {
            let view = slice
                .get_mapped_range()
                .map_err(|e| anyhow!("reading a mapped buffer: {e:?}"))?;
            bytemuck::cast_slice(&view).to_vec()
        };
        buffer.unmap();
        Ok(out)
    }
}
