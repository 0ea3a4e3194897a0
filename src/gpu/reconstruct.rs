//! A reconstruction's passes on the device, generic over the slot's techniques
//! (`crate::technique::Reconstruction::wgsl`): `shaders/reconstruct.wgsl`'s `inputs`
//! decodes the planes the tracer summed, the technique's `prepare_pixel` and
//! `iterate_pixel` (its `gpu_passes` times) filter the visibility between two colour
//! buffers, and `compose` writes the image, which is all that comes back to the host.

use std::borrow::Cow;
use std::collections::HashMap;
use std::time::{Duration, Instant};

use anyhow::{Result, anyhow};
use bytemuck::{Pod, Zeroable};

use super::GpuTracer;
use crate::device::{buffer, buffer_entry, storage_entry, uniform_entry};
use crate::render::RenderSettings;
use crate::technique::Reconstruction;

/// `voxlab::layers`, which every reconstruction's module imports.
const LAYERS_MODULE: (&str, &str) = (
    "shaders/layers.wgsl",
    include_str!("../../shaders/layers.wgsl"),
);

/// The passes' entry points, around the reconstruction's `voxlab::reconstruction`.
const ENTRY: (&str, &str) = (
    "shaders/reconstruct.wgsl",
    include_str!("../../shaders/reconstruct.wgsl"),
);

/// `FilterParams` of `shaders/layers.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FilterParams {
    width: u32,
    height: u32,
    frames: u32,
    accumulated: u32,
    pass_index: u32,
    has_history: u32,
    /// Where this frame's and the history's primary depths count from (world units):
    /// the layers hold the depth less it ([`depth_origin`]).
    depth_origin: f32,
    previous_depth_origin: f32,
    settings: [f32; 8],
    camera: [[f32; 4]; 4],
    previous: [[f32; 4]; 4],
}

/// Where a render's primary layers count their depth from (world units): the primary
/// rays' advance (`crate::plan::primary_origin`), 0 for an eye near the grid. The
/// kernel writes each depth less it (shaders/trace.wgsl), so that a far eye's hits keep
/// their digits: 1e8 voxels out, f32 holds a depth to 8 voxels.
pub(super) fn depth_origin(scene: &crate::scene::Scene, settings: &RenderSettings) -> f64 {
    crate::plan::primary_origin(scene, settings).advance * scene.grid.voxel_size()
}

/// `FilterParams::camera` and `previous`: the current frame's camera and the previous
/// one's as the kernel reprojects with them (shaders/reconstruction_svgf.wgsl), in the
/// cameras' own bases, each hit less its depth origin along `forward`. `camera` holds
/// the offset of that origin (the current eye plus `depth` along its forward) from the
/// previous one's, in the previous camera's basis, and the current `tan_half_vfov`,
/// then the rows of the change of basis (previous axis i . current axis j);
/// `previous` its `tan_half_vfov` and its axes. Taken here in f64: a far eye's narrow
/// view placed in world coordinates in f32 kept a ray's sideways part to a few digits
/// (forward + 2e-5 right at 1e6), and a hit found as `eye + depth d` lost the eye's
/// ulp: `render --check` of an `svgf` path drew 1.6 % of a 24x24 image apart at 3e5,
/// 2 % at 1e6 and 11 % at 1e8, its history read partly from neighbouring pixels.
fn reprojection_rows(
    (current, depth): (&crate::scene::CameraFrame, f64),
    (previous, previous_depth): (&crate::scene::CameraFrame, f64),
) -> ([[f32; 4]; 4], [[f32; 4]; 4]) {
    use glam::DVec3;
    let v = |v: DVec3, w: f64| [v.x as f32, v.y as f32, v.z as f32, w as f32];
    let axes = |c: &crate::scene::CameraFrame| [c.forward, c.right, c.up];
    let (from, to) = (axes(previous), axes(current));
    let in_previous = |u: DVec3| DVec3::from(from.map(|a| a.dot(u)));
    let change = |i: usize| DVec3::from(to.map(|b| from[i].dot(b)));
    let offset = in_previous(current.eye + depth * current.forward - previous.eye)
        - DVec3::X * previous_depth;
    (
        [
            v(offset, current.tan_half_vfov),
            v(change(0), 0.0),
            v(change(1), 0.0),
            v(change(2), 0.0),
        ],
        [
            v(DVec3::ZERO, previous.tan_half_vfov),
            v(previous.forward, 0.0),
            v(previous.right, 0.0),
            v(previous.up, 0.0),
        ],
    )
}

/// A temporal reconstruction's history on the device (`crate::frame::History`): two
/// buffers of three `vec4` per pixel, the latest frame's in `buffers[latest]`, which
/// the next frame reads while it writes the other.
pub(super) struct GpuHistory {
    /// The image's width and height: a history of another shape is not read, however
    /// many pixels it has (the CPU's `svgf::accumulate` drops it alike).
    size: (u32, u32),
    buffers: [wgpu::Buffer; 2],
    latest: usize,
    /// The camera of the latest frame and its depth origin ([`depth_origin`]), `None`
    /// while the history is empty.
    camera: Option<(crate::scene::CameraFrame, f64)>,
}

/// The most settings a reconstruction may declare: `FilterParams::settings`.
pub(crate) const MAX_FILTER_SETTINGS: usize = 8;

/// One reconstruction's pipelines, made on its first use.
pub(super) struct FilterPipelines {
    layout: wgpu::BindGroupLayout,
    inputs: wgpu::ComputePipeline,
    prepare: wgpu::ComputePipeline,
    iterate: wgpu::ComputePipeline,
    compose: wgpu::ComputePipeline,
    /// The parameters the passes last ran with. The driver compiles a kernel at its
    /// first dispatch for the values of its uniforms (lavapipe inlines those its
    /// branches read; docs/benchmarks.md, "A kernel's first dispatch"), so passes
    /// with other parameters first run untimed on one tile.
    warmed: Option<FilterParams>,
}

/// The passes' buffers for an image of `pixels` pixels, kept while renders have that
/// many: a viewer's every refinement would otherwise allocate them anew.
#[derive(Clone)]
pub(super) struct FilterBuffers {
    pixels: u64,
    guide: wgpu::Buffer,
    aux: wgpu::Buffer,
    colors: [wgpu::Buffer; 2],
    params: wgpu::Buffer,
    /// Bound as `compensation` when the planes are one frame's values, and as
    /// `history_in` without a temporal reconstruction.
    no_compensation: wgpu::Buffer,
    /// Bound as `history_out` without a temporal reconstruction (a buffer bound
    /// writable may not be bound again in the group).
    no_history: wgpu::Buffer,
}

/// What the tracer's readback of a filtered render reads.
pub(super) struct Filtered {
    /// The buffer holding the composed image (`vec4` per pixel, the radiance in xyz).
    pub image: wgpu::Buffer,
    /// Bytes of the buffers the passes used.
    pub bytes: u64,
    /// The passes' wall time, from their first submission until the device is done
    /// with the last (a first use's untimed warm-up left out).
    pub time: Duration,
}

impl GpuTracer {
    /// The passes' buffers for `pixels` pixels: the kept ones, or new ones (which are
    /// kept). Made inside the caller's error scopes.
    fn filter_buffers(&mut self, pixels: u64) -> FilterBuffers {
        if let Some(b) = &self.filter_buffers
            && b.pixels == pixels
        {
            return b.clone();
        }
        let storage = wgpu::BufferUsages::STORAGE;
        let color = |label| {
            buffer(
                &self.device,
                label,
                pixels * 16,
                storage | wgpu::BufferUsages::COPY_SRC,
            )
        };
        let b = FilterBuffers {
            pixels,
            guide: buffer(&self.device, "reconstruction guide", pixels * 32, storage),
            aux: buffer(&self.device, "reconstruction aux", pixels * 8, storage),
            colors: [
                color("reconstruction colour a"),
                color("reconstruction colour b"),
            ],
            params: buffer(
                &self.device,
                "reconstruction params",
                std::mem::size_of::<FilterParams>() as u64,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            ),
            no_compensation: buffer(&self.device, "no compensation", 16, storage),
            no_history: buffer(&self.device, "no history", 48, storage),
        };
        self.filter_buffers = Some(b.clone());
        b
    }

    /// Makes `r`'s pipelines unless made already (before the timed trace, so that
    /// their compilation is not timed with the passes).
    pub(super) fn make_filter_pipelines(&mut self, r: &'static Reconstruction) -> Result<()> {
        if !self.filters.contains_key(r.name) {
            let entry = r
                .wgsl
                .ok_or_else(|| anyhow!("reconstruction {} has no WGSL module", r.name))?;
            let mut modules = vec![LAYERS_MODULE];
            modules.extend_from_slice(r.wgsl_imports);
            modules.push(entry);
            let module = super::compose::compose(&modules, ENTRY, HashMap::new())
                .map_err(|e| anyhow!("composing {}: {e}", entry.0))?;
            super::validate(&module).map_err(|e| anyhow!("validating {}: {e}", entry.0))?;
            let shader = self
                .device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(entry.0),
                    source: wgpu::ShaderSource::Naga(Cow::Owned(module)),
                });
            let layout = self
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("voxlab reconstruction"),
                    entries: &[
                        uniform_entry(0),
                        storage_entry(1, true),
                        storage_entry(2, true),
                        storage_entry(3, false),
                        storage_entry(4, true),
                        storage_entry(5, false),
                        storage_entry(6, false),
                        storage_entry(7, true),
                        storage_entry(8, false),
                    ],
                });
            let pipeline_layout =
                self.device
                    .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("voxlab reconstruction"),
                        bind_group_layouts: &[Some(&layout)],
                        immediate_size: 0,
                    });
            let pipeline = |name: &str| {
                self.device
                    .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(name),
                        layout: Some(&pipeline_layout),
                        module: &shader,
                        entry_point: Some(name),
                        compilation_options: Default::default(),
                        cache: None,
                    })
            };
            let pipelines = FilterPipelines {
                inputs: pipeline("inputs"),
                prepare: pipeline("prepare"),
                iterate: pipeline("iterate"),
                compose: pipeline("compose"),
                layout,
                warmed: None,
            };
            self.filters.insert(r.name, pipelines);
        }
        Ok(())
    }

    /// Empties the temporal history: the next frame starts a camera path.
    pub fn reset_history(&mut self) {
        if let Some(h) = &mut self.history {
            h.camera = None;
        }
    }

    /// The history's buffers for an image of `size` (kept, or new and empty), made
    /// inside the caller's error scopes.
    fn history_buffers(&mut self, size: (u32, u32)) -> &mut GpuHistory {
        if self.history.as_ref().is_none_or(|h| h.size != size) {
            let pixels = size.0 as u64 * size.1 as u64;
            let b = |label| {
                buffer(
                    &self.device,
                    label,
                    pixels * 48,
                    wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                )
            };
            self.history = Some(GpuHistory {
                size,
                buffers: [b("reconstruction history a"), b("reconstruction history b")],
                latest: 0,
                camera: None,
            });
        }
        self.history.as_mut().expect("made above")
    }

    /// Runs `r` on the planes the tracer summed (`planes`, with `compensation` when
    /// accumulated) over `frames` frames seen through `camera`, and gives the buffer of
    /// the composed image. A temporal `r` reads and replaces the history.
    pub(super) fn reconstruct(
        &mut self,
        r: &'static Reconstruction,
        settings: &RenderSettings,
        (camera, depth_origin): (&crate::scene::CameraFrame, f64),
        planes: &wgpu::Buffer,
        compensation: Option<&wgpu::Buffer>,
        frames: u32,
    ) -> Result<Filtered> {
        let (w, h) = (settings.width, settings.height);
        let pixels = w as u64 * h as u64;
        // Failures (a buffer larger than the device allows, say) are errors of the
        // render, never wgpu's default handler (a panic).
        let oom_scope = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation_scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let FilterBuffers {
            guide,
            aux,
            colors,
            params,
            no_compensation,
            no_history,
            ..
        } = self.filter_buffers(pixels);
        // A temporal reconstruction reads the latest frame's history and writes the
        // other buffer; the others bind the unread placeholder.
        let (history_in, history_out, previous) = if r.temporal {
            let kept = self.history_buffers((w, h));
            (
                kept.buffers[kept.latest].clone(),
                kept.buffers[1 - kept.latest].clone(),
                kept.camera,
            )
        } else {
            (no_compensation.clone(), no_history.clone(), None)
        };
        let values = r.values(settings);
        debug_assert!(values.len() <= MAX_FILTER_SETTINGS);
        let (previous_camera, previous_depth_origin) = previous.unwrap_or((*camera, depth_origin));
        let reprojection = reprojection_rows(
            (camera, depth_origin),
            (&previous_camera, previous_depth_origin),
        );
        let mut p = FilterParams {
            width: w,
            height: h,
            frames,
            accumulated: compensation.is_some() as u32,
            pass_index: 0,
            has_history: previous.is_some() as u32,
            depth_origin: depth_origin as f32,
            previous_depth_origin: previous_depth_origin as f32,
            settings: [0.0; 8],
            camera: reprojection.0,
            previous: reprojection.1,
        };
        for (o, v) in p.settings.iter_mut().zip(&values) {
            *o = *v as f32;
        }
        let passes = (r.gpu_passes)(&values);
        let compensation = compensation.unwrap_or(&no_compensation);
        if let Err(e) = self.make_filter_pipelines(r) {
            pollster::block_on(validation_scope.pop());
            pollster::block_on(oom_scope.pop());
            return Err(e);
        }
        let pipelines = &self.filters[r.name];
        // Bind group k reads colour k and writes the other.
        let groups: [wgpu::BindGroup; 2] = [0, 1].map(|k| {
            self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("voxlab reconstruction"),
                layout: &pipelines.layout,
                entries: &[
                    buffer_entry(0, &params),
                    buffer_entry(1, planes),
                    buffer_entry(2, compensation),
                    buffer_entry(3, &guide),
                    buffer_entry(4, &colors[k]),
                    buffer_entry(5, &colors[1 - k]),
                    buffer_entry(6, &aux),
                    buffer_entry(7, &history_in),
                    buffer_entry(8, &history_out),
                ],
            })
        });
        let cold = pipelines
            .warmed
            .is_none_or(|w| bytemuck::bytes_of(&w) != bytemuck::bytes_of(&p));
        if cold {
            // The warm-up runs the passes with the filter's own parameters and
            // bindings on the first tile only: the timed passes below write every
            // pixel again from the same inputs (no pass reads what it or a later pass
            // writes).
            self.filter_passes(pipelines, &groups, &params, p, passes, (1, 1));
            self.wait()?;
        }
        let start = Instant::now();
        let groups_xy = (w.div_ceil(8), h.div_ceil(8));
        let reads = self.filter_passes(pipelines, &groups, &params, p, passes, groups_xy);
        self.wait()?;
        let time = start.elapsed();
        let validation = pollster::block_on(validation_scope.pop());
        let oom = pollster::block_on(oom_scope.pop());
        if let Some(e) = oom.or(validation) {
            // Nothing half made is kept.
            self.filter_buffers = None;
            self.history = None;
            return Err(anyhow!("reconstruction {}: {e}", r.name));
        }
        if let Some(f) = self.filters.get_mut(r.name) {
            f.warmed = Some(p);
        }
        if r.temporal
            && let Some(h) = &mut self.history
        {
            h.latest = 1 - h.latest;
            h.camera = Some((*camera, depth_origin));
        }
        Ok(Filtered {
            image: colors[1 - reads].clone(),
            bytes: guide.size()
                + aux.size()
                + colors[0].size()
                + colors[1].size()
                + params.size()
                + if r.temporal {
                    history_in.size() + history_out.size()
                } else {
                    0
                },
            time,
        })
    }

    /// Submits the filter's passes over `groups_xy` workgroups, one submission a pass
    /// (the parameters, the pass's index among them, are written before each, and a
    /// queue's writes and submissions keep their order), and gives the bind group the
    /// last pass read. Bind group k reads colour k and writes the other: `inputs`
    /// writes colour 0, `prepare` reads it, and each pass reads what the last wrote.
    fn filter_passes(
        &self,
        pipelines: &FilterPipelines,
        groups: &[wgpu::BindGroup; 2],
        params: &wgpu::Buffer,
        mut p: FilterParams,
        passes: u32,
        groups_xy: (u32, u32),
    ) -> usize {
        let run = |pipeline: &wgpu::ComputePipeline, reads: usize, p: &FilterParams| {
            self.queue.write_buffer(params, 0, bytemuck::bytes_of(p));
            let mut encoder = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("voxlab reconstruction"),
                });
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("voxlab reconstruction"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, &groups[reads], &[]);
                pass.dispatch_workgroups(groups_xy.0, groups_xy.1, 1);
            }
            self.queue.submit([encoder.finish()]);
        };
        run(&pipelines.inputs, 1, &p);
        run(&pipelines.prepare, 0, &p);
        let mut reads = 1;
        for k in 0..passes {
            p.pass_index = k;
            run(&pipelines.iterate, reads, &p);
            reads = 1 - reads;
        }
        run(&pipelines.compose, reads, &p);
        reads
    }
}
