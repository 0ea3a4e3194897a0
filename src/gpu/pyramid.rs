//! Cone-tracing pyramids on the GPU: built by compute passes (`shaders/inject.wgsl`,
//! `shaders/mip_build.wgsl`) into mip-mapped 3D textures, an R16Float opacity pyramid
//! and, for indirect light, an RGBA16Float radiance pyramid. Layout, filter and
//! injection are those of the f64 reference, `crate::technique::cones::pyramid`, which documents
//! them; the tests hold the two within f16 storage error.
//!
//! The opacity is built level by level in f32 storage buffers and rounded to f16 once,
//! then copied into the texture (R16Float is filterable but not a storage format in
//! WebGPU). The radiance texture is a storage format and is written in place; each of
//! its levels is filtered from the f16 level below. The injection reads the tracer's
//! own material and light buffers (`voxlab::types`), so there is one upload and one
//! layout of each.
//!
//! Also here: the bind group of `shaders/cone.wgsl` (group 1) and a probe kernel
//! (`shaders/cone_probe.wgsl`) that runs single cones for tests.

use std::borrow::Cow;
use std::collections::HashMap;

use anyhow::{Result, anyhow, bail};
use bytemuck::{Pod, Zeroable};
use glam::UVec3;
use naga_oil::compose::ShaderDefValue;

use super::{GpuLight, GpuMaterial, GpuTracer};
use crate::device::{
    buffer, buffer_entry, buffer_init, extent, readback, sampler_entry, storage_entry,
    texture_3d_entry, uniform_entry, view_entry,
};
use crate::render::{ConeSettings, RenderSettings};
use crate::scene::Scene;
use crate::technique::cones::march::hemisphere_tan_half;
use crate::technique::cones::pyramid::{PyramidLayout, alpha_table};

const INJECT: (&str, &str) = (
    "shaders/inject.wgsl",
    include_str!("../../shaders/inject.wgsl"),
);
const MIP_BUILD: &str = include_str!("../../shaders/mip_build.wgsl");
/// `voxlab::cone`, imported by the tracer and the probe.
pub(crate) const CONE_MODULE: (&str, &str) =
    ("shaders/cone.wgsl", include_str!("../../shaders/cone.wgsl"));
const CONE_PROBE: &str = include_str!("../../shaders/cone_probe.wgsl");

/// `@workgroup_size(4, 4, 4)` of the build kernels.
const WG: u32 = 4;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct InjectParams {
    dims: [u32; 3],
    num_lights: u32,
    eps: f32,
    voxel_size: f32,
    falloff_min_dist_sq: f32,
    falloff: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct LevelParams {
    src_dims: [u32; 3],
    pitch_words: u32,
    dst_dims: [u32; 3],
    _pad: u32,
}

/// `ConeParams` of `shaders/cone.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct GpuConeParams {
    pub padded: [f32; 3],
    pub levels: u32,
    pub dims: [f32; 3],
    pub step_factor: f32,
    pub start_offset: f32,
    pub ao_cones: u32,
    pub ao_range: f32,
    pub hemi_tan_half: f32,
    pub indirect_strength: f32,
    pub indirect_range: f32,
    pub point_tan_half: f32,
    // Always 0 (`loop_guard`, shaders/cone.wgsl).
    pub loop_guard: u32,
}
const _: () = assert!(std::mem::size_of::<GpuConeParams>() == 64);

impl GpuConeParams {
    pub fn new(layout: &PyramidLayout, c: &ConeSettings) -> Self {
        let dims = layout.dims.as_vec3().to_array();
        Self {
            padded: layout.padded.as_vec3().to_array(),
            levels: layout.levels,
            dims,
            step_factor: c.step_factor as f32,
            start_offset: c.start_offset as f32,
            ao_cones: c.ao_cones.max(1),
            ao_range: c.ao_range as f32,
            hemi_tan_half: hemisphere_tan_half(c.ao_cones) as f32,
            indirect_strength: c.indirect_strength as f32,
            indirect_range: indirect_range(layout) as f32,
            point_tan_half: (c.aperture_deg.to_radians() / 2.0).tan() as f32,
            loop_guard: 0,
        }
    }
}

pub use crate::technique::cones::march::{indirect_range, light_radius};

/// A pyramid on the device.
pub struct GpuPyramid {
    pub layout: PyramidLayout,
    pub opacity: wgpu::Texture,
    pub opacity_view: wgpu::TextureView,
    /// The RGBA16Float radiance texture, when built.
    pub radiance: Option<wgpu::Texture>,
    /// The radiance texture's view, or a 1x1x1 empty stand-in (the binding must exist).
    pub radiance_view: wgpu::TextureView,
}

impl GpuPyramid {
    /// Device memory of the textures (stand-ins excluded).
    pub fn bytes(&self) -> u64 {
        use crate::technique::cones::pyramid::{OPACITY_TEXEL_BYTES, RADIANCE_TEXEL_BYTES};
        self.layout.texture_bytes(OPACITY_TEXEL_BYTES)
            + if self.radiance.is_some() {
                self.layout.texture_bytes(RADIANCE_TEXEL_BYTES)
            } else {
                0
            }
    }
}

/// The pyramid-build kernels. They depend on no scene, so a tracer makes them once.
pub(super) struct BuildPipelines {
    opacity_base: wgpu::ComputePipeline,
    radiance_base: wgpu::ComputePipeline,
    reduce_r: wgpu::ComputePipeline,
    pack_r: wgpu::ComputePipeline,
    reduce_rgba: wgpu::ComputePipeline,
}

impl BuildPipelines {
    fn new(device: &wgpu::Device) -> Result<Self> {
        let inject = super::compose::compose(
            &[
                super::compose::TYPES_MODULE,
                super::compose::EMISSION_MODULE,
            ],
            INJECT,
            // Made once for every scene: the emitter's cosine is always composed in.
            HashMap::from([(
                "LAMBERTIAN_LIGHTS".to_string(),
                naga_oil::compose::ShaderDefValue::Bool(true),
            )]),
        )
        .map_err(|e| anyhow!("composing {}: {e}", INJECT.0))?;
        super::validate(&inject).map_err(|e| anyhow!("validating {}: {e}", INJECT.0))?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("inject"),
            source: wgpu::ShaderSource::Naga(Cow::Owned(inject)),
        });
        let mip = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("mip_build"),
            source: wgpu::ShaderSource::Wgsl(Cow::Borrowed(MIP_BUILD)),
        });
        Ok(Self {
            opacity_base: pipeline(device, &module, "opacity_base"),
            radiance_base: pipeline(device, &module, "radiance_base"),
            reduce_r: pipeline(device, &mip, "reduce_r"),
            pack_r: pipeline(device, &mip, "pack_r"),
            reduce_rgba: pipeline(device, &mip, "reduce_rgba"),
        })
    }
}

/// Everything a pyramid build reads, so that equal keys mean identical pyramids: the
/// grid upload (its contents and dims), the layout, whether radiance is built, and a
/// hash of the per-material alpha (transmittance model, kt, sigma) and, for radiance
/// only, of what the injection reads of the materials (albedo, kd, kt) and lights
/// (position, radiance), and its parameters (falloff, ray offset...).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct PyramidKey {
    grid: u64,
    layout: PyramidLayout,
    radiance: bool,
    inputs: blake3::Hash,
}

/// What a build uploads besides the tracer's materials and lights.
struct InjectInputs {
    alpha: Vec<f32>,
    params: InjectParams,
}

impl InjectInputs {
    fn new(scene: &Scene, settings: &RenderSettings, dims: UVec3) -> Self {
        let grid = &scene.grid;
        let alpha = alpha_table(scene, settings.features.transmittance)
            .into_iter()
            .map(|a| a as f32)
            .collect();
        let params = InjectParams {
            dims: dims.to_array(),
            num_lights: scene.lights.len() as u32,
            eps: settings.ray_offset as f32,
            voxel_size: grid.voxel_size() as f32,
            falloff_min_dist_sq: (settings.falloff_min_distance * settings.falloff_min_distance)
                as f32,
            falloff: settings.falloff as u32,
        };
        Self { alpha, params }
    }

    /// The opacity reads only the alpha table; the radiance reads the rest too. Fields of
    /// the materials and lights that `shaders/inject.wgsl` does not read stay out, so
    /// that changing them (ks, an area light's size or turn) does not rebuild. A light's
    /// emission and normal are in: `emitted` (shaders/emission.wgsl) weighs a Lambertian
    /// emitter's light by the cosine at its normal (left out, a turned Lambertian light
    /// drew the old light's pyramid).
    fn key(
        &self,
        grid: u64,
        layout: PyramidLayout,
        radiance: bool,
        materials: &[GpuMaterial],
        lights: &[GpuLight],
    ) -> PyramidKey {
        let mut h = blake3::Hasher::new();
        h.update(bytemuck::cast_slice(&self.alpha));
        if radiance {
            for m in materials {
                h.update(bytemuck::cast_slice(&m.albedo));
                h.update(bytemuck::cast_slice(&[m.kd, m.kt]));
            }
            for l in lights {
                h.update(bytemuck::cast_slice(&l.position));
                h.update(bytemuck::cast_slice(&l.radiance));
                h.update(bytemuck::bytes_of(&l.emission));
                h.update(bytemuck::cast_slice(&l.axis_n));
            }
            h.update(bytemuck::bytes_of(&self.params));
        }
        PyramidKey {
            grid,
            layout,
            radiance,
            inputs: h.finalize(),
        }
    }
}

fn groups(d: UVec3) -> (u32, u32, u32) {
    (d.x.div_ceil(WG), d.y.div_ceil(WG), d.z.div_ceil(WG))
}

/// Decodes an IEEE binary16 value.
pub(crate) fn f16_to_f32(h: u16) -> f32 {
    let s = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let e = ((h >> 10) & 0x1f) as i32;
    let m = (h & 0x3ff) as f32;
    s * match e {
        0 => m * 2f32.powi(-24),
        31 => {
            if m == 0.0 {
                f32::INFINITY
            } else {
                f32::NAN
            }
        }
        _ => (1.0 + m / 1024.0) * 2f32.powi(e - 15),
    }
}

fn align256(bytes: u32) -> u32 {
    bytes.div_ceil(256) * 256
}

/// A compute pipeline for one entry point, its layout derived from what it uses.
fn pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: None,
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// The layout of `shaders/cone.wgsl`'s group 1.
pub(crate) fn cone_bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let float = wgpu::TextureSampleType::Float { filterable: true };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("voxlab cones"),
        entries: &[
            uniform_entry(0),
            texture_3d_entry(1, float),
            texture_3d_entry(2, float),
            sampler_entry(3),
            storage_entry(4, true),
        ],
    })
}

/// Linear within a level, nearest between levels (the shader blends levels itself),
/// clamp-to-edge (the shader's border weight makes the border empty).
pub(crate) fn pyramid_sampler(device: &wgpu::Device) -> wgpu::Sampler {
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("pyramid"),
        address_mode_u: wgpu::AddressMode::ClampToEdge,
        address_mode_v: wgpu::AddressMode::ClampToEdge,
        address_mode_w: wgpu::AddressMode::ClampToEdge,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Nearest,
        ..Default::default()
    })
}

/// Composes `voxlab::cone` with an entry module.
pub(crate) fn compose_with_cone(entry: (&str, &str), defs: &[&str]) -> Result<naga::Module> {
    let defs: HashMap<String, ShaderDefValue> = defs
        .iter()
        .map(|d| (d.to_string(), ShaderDefValue::Bool(true)))
        .collect();
    let module = super::compose::compose(&[CONE_MODULE], entry, defs)
        .map_err(|e| anyhow!("composing {}: {e}", entry.0))?;
    super::validate(&module).map_err(|e| anyhow!("validating {}: {e}", entry.0))?;
    Ok(module)
}

/// One query of the cone probe (`Query` of `shaders/cone_probe.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ConeQuery {
    pub origin: [f32; 3],
    /// 0 opacity march, 1 radiance march, 2 AO, 3 indirect, 4 shadow visibility.
    pub mode: u32,
    /// The march direction (modes 0, 1) or the surface normal (2, 3, 4).
    pub dir: [f32; 3],
    pub tan_half: f32,
    pub target: [f32; 3],
    pub max_dist: f32,
}

impl GpuTracer {
    /// Builds the opacity pyramid (and the radiance pyramid when `radiance`) of `scene`
    /// under `settings` (transmittance model, falloff, ray offset) on the device. Always
    /// builds: renders go through the tracer's cache instead (`pyramid_builds`).
    pub fn build_pyramid(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        layout: PyramidLayout,
        radiance: bool,
    ) -> Result<GpuPyramid> {
        scene.validate()?;
        self.upload_grid(scene, true);
        self.upload_scene(scene, &[]);
        let inputs = InjectInputs::new(scene, settings, layout.dims);
        self.build(&inputs, layout, radiance)
    }

    /// The pyramid of a render: the cached one when nothing it was built from changed,
    /// else a new build, which replaces it, left in `self.pyramid`. Expects the grid,
    /// materials and lights of `scene` uploaded.
    pub(super) fn cache_pyramid(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        layout: PyramidLayout,
        radiance: bool,
    ) -> Result<()> {
        let inputs = InjectInputs::new(scene, settings, layout.dims);
        let (materials, lights) = Self::scene_data(scene, &[]);
        let key = inputs.key(
            self.grid_generation(),
            layout,
            radiance,
            &materials,
            &lights,
        );
        if self.pyramid.as_ref().is_none_or(|(k, _)| *k != key) {
            // Freed before the build so two pyramids never share the device's memory.
            self.pyramid = None;
            let pyr = self.build(&inputs, layout, radiance)?;
            self.pyramid = Some((key, pyr));
        }
        Ok(())
    }

    /// Reads the tracer's grid, materials and lights as uploaded.
    ///
    /// One function because the level buffers, uniforms and textures it creates are
    /// recorded into one command encoder, kept until its one submission builds every
    /// level, and then handed to the pyramid.
    fn build(
        &mut self,
        inputs: &InjectInputs,
        layout: PyramidLayout,
        radiance: bool,
    ) -> Result<GpuPyramid> {
        if self.build_pipelines.is_none() {
            self.build_pipelines = Some(BuildPipelines::new(&self.device)?);
        }
        self.pyramid_builds += 1;
        let pipes = self.build_pipelines.as_ref().expect("build pipelines made");
        let device = &self.device;
        let limits = device.limits();
        let dims = layout.dims;
        if layout.padded.max_element() > limits.max_texture_dimension_3d {
            bail!(
                "pyramid texture {}x{}x{} exceeds max_texture_dimension_3d {}",
                layout.padded.x,
                layout.padded.y,
                layout.padded.z,
                limits.max_texture_dimension_3d
            );
        }
        let base_bytes = dims.x as u64 * dims.y as u64 * dims.z as u64 * 4;
        let max_binding = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if base_bytes > max_binding {
            bail!(
                "opacity build buffer of {base_bytes} bytes exceeds the device's storage \
                 binding limit {max_binding}"
            );
        }
        let grid_view = &self.grid.as_ref().expect("grid uploaded").view;
        let (Some((_, mat_buf)), Some((_, light_buf))) = (&self.materials, &self.lights) else {
            unreachable!("materials and lights uploaded before a pyramid build");
        };
        let ip_buf = buffer_init(
            device,
            "inject params",
            bytemuck::bytes_of(&inputs.params),
            wgpu::BufferUsages::UNIFORM,
        );
        let alpha_buf = buffer_init(
            device,
            "inject alpha",
            bytemuck::cast_slice(&inputs.alpha),
            wgpu::BufferUsages::STORAGE,
        );

        let texture = |label: &str, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: extent(layout.padded),
                mip_level_count: layout.levels,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D3,
                format,
                usage,
                view_formats: &[],
            })
        };
        // Textures start zeroed (wgpu guarantees it), so padding is empty.
        let opacity = texture(
            "opacity pyramid",
            wgpu::TextureFormat::R16Float,
            wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_DST
                | wgpu::TextureUsages::COPY_SRC,
        );

        // f32 level buffers and one staging buffer sized for level 0.
        let level_bufs: Vec<wgpu::Buffer> = (0..layout.levels)
            .map(|l| {
                let d = layout.level_dims(l);
                buffer(
                    device,
                    "opacity level",
                    d.x as u64 * d.y as u64 * d.z as u64 * 4,
                    wgpu::BufferUsages::STORAGE,
                )
            })
            .collect();
        let pitch0 = align256(dims.x.div_ceil(2) * 4);
        let staging = buffer(
            device,
            "opacity staging",
            pitch0 as u64 * dims.y as u64 * dims.z as u64,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        );

        let mut enc = device.create_command_encoder(&Default::default());
        let run = |enc: &mut wgpu::CommandEncoder,
                   p: &wgpu::ComputePipeline,
                   entries: &[wgpu::BindGroupEntry],
                   g: (u32, u32, u32)| {
            let bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &p.get_bind_group_layout(0),
                entries,
            });
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(p);
            pass.set_bind_group(0, &bg, &[]);
            pass.dispatch_workgroups(g.0, g.1, g.2);
        };

        run(
            &mut enc,
            &pipes.opacity_base,
            &[
                buffer_entry(0, &ip_buf),
                view_entry(1, grid_view),
                buffer_entry(4, &level_bufs[0]),
                buffer_entry(6, &alpha_buf),
            ],
            groups(dims),
        );
        // Uniforms per level, all alive until the submission.
        let mut level_params = Vec::new();
        for l in 0..layout.levels {
            let d = layout.level_dims(l);
            let next = layout.level_dims(l + 1);
            let pitch = align256(d.x.div_ceil(2) * 4);
            level_params.push(buffer_init(
                device,
                "level params",
                bytemuck::bytes_of(&LevelParams {
                    src_dims: d.to_array(),
                    pitch_words: pitch / 4,
                    dst_dims: next.to_array(),
                    _pad: 0,
                }),
                wgpu::BufferUsages::UNIFORM,
            ));
        }
        for l in 0..layout.levels as usize {
            let d = layout.level_dims(l as u32);
            if l + 1 < layout.levels as usize {
                run(
                    &mut enc,
                    &pipes.reduce_r,
                    &[
                        buffer_entry(0, &level_params[l]),
                        buffer_entry(1, &level_bufs[l]),
                        buffer_entry(2, &level_bufs[l + 1]),
                    ],
                    groups(layout.level_dims(l as u32 + 1)),
                );
            }
            run(
                &mut enc,
                &pipes.pack_r,
                &[
                    buffer_entry(0, &level_params[l]),
                    buffer_entry(1, &level_bufs[l]),
                    buffer_entry(5, &staging),
                ],
                groups(UVec3::new(d.x.div_ceil(2), d.y, d.z)),
            );
            let pitch = align256(d.x.div_ceil(2) * 4);
            enc.copy_buffer_to_texture(
                wgpu::TexelCopyBufferInfo {
                    buffer: &staging,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(pitch),
                        rows_per_image: Some(d.y),
                    },
                },
                wgpu::TexelCopyTextureInfo {
                    texture: &opacity,
                    mip_level: l as u32,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                extent(d),
            );
        }

        let radiance_tex = if radiance {
            let tex = texture(
                "radiance pyramid",
                wgpu::TextureFormat::Rgba16Float,
                wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::STORAGE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
            );
            let mip_view = |l: u32| {
                tex.create_view(&wgpu::TextureViewDescriptor {
                    base_mip_level: l,
                    mip_level_count: Some(1),
                    ..Default::default()
                })
            };
            let v0 = mip_view(0);
            run(
                &mut enc,
                &pipes.radiance_base,
                &[
                    buffer_entry(0, &ip_buf),
                    view_entry(1, grid_view),
                    buffer_entry(2, mat_buf),
                    buffer_entry(3, light_buf),
                    view_entry(5, &v0),
                    buffer_entry(6, &alpha_buf),
                ],
                groups(dims),
            );
            for l in 0..layout.levels.saturating_sub(1) {
                let src = mip_view(l);
                let dst = mip_view(l + 1);
                run(
                    &mut enc,
                    &pipes.reduce_rgba,
                    &[
                        buffer_entry(0, &level_params[l as usize]),
                        view_entry(3, &src),
                        view_entry(4, &dst),
                    ],
                    groups(layout.level_dims(l + 1)),
                );
            }
            Some(tex)
        } else {
            None
        };
        self.queue.submit([enc.finish()]);
        self.wait()?;

        let opacity_view = opacity.create_view(&Default::default());
        let radiance_view = match &radiance_tex {
            Some(t) => t.create_view(&Default::default()),
            None => device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some("radiance stand-in"),
                    size: extent(UVec3::ONE),
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D3,
                    format: wgpu::TextureFormat::Rgba16Float,
                    usage: wgpu::TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                })
                .create_view(&Default::default()),
        };
        Ok(GpuPyramid {
            layout,
            opacity,
            opacity_view,
            radiance: radiance_tex,
            radiance_view,
        })
    }

    /// Reads mip `level` of the opacity (`radiance = false`, 1 channel) or radiance
    /// (4 channels) texture back, at the texture's padded dims, x-fastest, decoded to f32.
    pub fn read_pyramid_level(
        &self,
        pyr: &GpuPyramid,
        radiance: bool,
        level: u32,
    ) -> Result<Vec<f32>> {
        let (tex, texel) = if radiance {
            (
                pyr.radiance
                    .as_ref()
                    .ok_or_else(|| anyhow!("no radiance pyramid"))?,
                8u32,
            )
        } else {
            (&pyr.opacity, 2u32)
        };
        let d = pyr.layout.texture_dims(level);
        let pitch = align256(d.x * texel);
        let bytes = pitch as u64 * d.y as u64 * d.z as u64;
        let buf = readback(&self.device, "pyramid readback", bytes);
        let mut enc = self.device.create_command_encoder(&Default::default());
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: tex,
                mip_level: level,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &buf,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(pitch),
                    rows_per_image: Some(d.y),
                },
            },
            extent(d),
        );
        self.queue.submit([enc.finish()]);
        let raw: Vec<u16> = self.read(&buf, bytes)?;
        let ch = (texel / 2) as usize;
        let row_halves = (pitch / 2) as usize;
        let mut out = Vec::with_capacity(d.x as usize * d.y as usize * d.z as usize * ch);
        for row in 0..(d.y * d.z) as usize {
            let r = &raw[row * row_halves..row * row_halves + d.x as usize * ch];
            out.extend(r.iter().map(|&h| f16_to_f32(h)));
        }
        Ok(out)
    }

    /// Runs cone queries through `shaders/cone.wgsl` (the probe kernel), one result per
    /// query (see [`ConeQuery`]).
    pub fn cone_probe(
        &self,
        pyr: &GpuPyramid,
        cones: &ConeSettings,
        queries: &[ConeQuery],
    ) -> Result<Vec<[f32; 4]>> {
        let device = &self.device;
        let indirect = pyr.radiance.is_some();
        let module = compose_with_cone(
            ("shaders/cone_probe.wgsl", CONE_PROBE),
            if indirect { &["RADIANCE_PYRAMID"] } else { &[] },
        )?;
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("cone probe"),
            source: wgpu::ShaderSource::Naga(Cow::Owned(module)),
        });
        let g0 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("cone probe"),
            entries: &[storage_entry(0, true), storage_entry(1, false)],
        });
        let g1 = cone_bind_group_layout(device);
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("cone probe"),
            bind_group_layouts: &[Some(&g0), Some(&g1)],
            immediate_size: 0,
        });
        let p = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("cone probe"),
            layout: Some(&pl),
            module: &shader,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let q = buffer_init(
            device,
            "queries",
            bytemuck::cast_slice(queries),
            wgpu::BufferUsages::STORAGE,
        );
        let out_bytes = queries.len() as u64 * 16;
        let out = buffer(
            device,
            "probe results",
            out_bytes,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        );
        let results = readback(device, "probe readback", out_bytes);
        let bg0 = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &g0,
            entries: &[buffer_entry(0, &q), buffer_entry(1, &out)],
        });
        let bg1 = self.cone_bind_group(pyr, cones, &g1, &[0.0]);
        let mut enc = device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&p);
            pass.set_bind_group(0, &bg0, &[]);
            pass.set_bind_group(1, &bg1, &[]);
            pass.dispatch_workgroups((queries.len() as u32).div_ceil(64), 1, 1);
        }
        enc.copy_buffer_to_buffer(&out, 0, &results, 0, out_bytes);
        self.queue.submit([enc.finish()]);
        self.read(&results, out_bytes)
    }

    /// The group-1 bind group of `shaders/cone.wgsl` for `pyr`, with each light's
    /// radius in voxels (`light_radius`; 0 for point lights).
    pub(crate) fn cone_bind_group(
        &self,
        pyr: &GpuPyramid,
        cones: &ConeSettings,
        layout: &wgpu::BindGroupLayout,
        light_radius: &[f32],
    ) -> wgpu::BindGroup {
        let device = &self.device;
        let params = GpuConeParams::new(&pyr.layout, cones);
        let pbuf = buffer_init(
            device,
            "cone params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let one = [0.0f32];
        let lt = if light_radius.is_empty() {
            &one[..]
        } else {
            light_radius
        };
        let lbuf = buffer_init(
            device,
            "cone lights",
            bytemuck::cast_slice(lt),
            wgpu::BufferUsages::STORAGE,
        );
        let sampler = pyramid_sampler(device);
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("voxlab cones"),
            layout,
            entries: &[
                buffer_entry(0, &pbuf),
                view_entry(1, &pyr.opacity_view),
                view_entry(2, &pyr.radiance_view),
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
                buffer_entry(4, &lbuf),
            ],
        })
    }
}
