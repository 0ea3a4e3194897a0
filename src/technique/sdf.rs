//! Distance-field soft shadows: the penumbra estimate of I. Quilez, "Rendering Worlds
//! with Two Triangles" (NVSCENE 2008) and his soft-shadow note (2010), `min k h / t`
//! along the ray to the light, over an exact Euclidean distance transform of the
//! grid's occluders (P. Felzenszwalb and D. Huttenlocher, "Distance Transforms of
//! Sampled Functions", Theory of Computing 8, 2012).
//!
//! Contract (both tracers):
//! - Occluders are the voxels whose material is opaque (kt <= 0). The field `D(v)` of a
//!   voxel is the exact Euclidean distance between its centre and the nearest
//!   occluder's centre, minus half a voxel (the distance from a centre to the face of a
//!   face-adjacent voxel), in voxels; 0 on occluders. Off the axes it overestimates the
//!   distance to the occluder's box by at most `(sqrt 3 - 1) / 2` voxel. Built once per
//!   scene by each backend on its own: in f64 here, in f32 on the device
//!   (`shaders/sdf_edt.wgsl`, read by the kernel from `technique_data`, x fastest).
//!   Squared distances are integers, exact in f32 below 2^24, so both are exact.
//! - A light is shaded at its centre `x`: `T P E (kd diffuse + ks specular)`, with `T`
//!   the shadow transmittance of the segment from `q` to `x` under the experiment's
//!   transmittance model, and, when `T` is not zero, `P = clamp(min_v D(v) len / (s R
//!   t_v), 0, 1)` over the voxels `v` the segment crosses inside the grid, `t_v` the
//!   distance from `q` to the middle of its crossing of `v`, `len` the segment's length,
//!   `R` the light's radius (`cpu::cone::light_radius`: a rectangle's half-diagonal)
//!   and `s` the setting `softness`. `len / (s R)` is Quilez's `k`: the penumbra a light
//!   of angular radius `R / len` casts. A Lambertian light's `E` takes the emitter's
//!   cosine at the centre (`Light::radiance_towards`): the model approximates its
//!   unshadowed light by the centre's and its penumbra by a uniform disk's.
//! - A point light (`R = 0`) or `softness = 0` is the hard shadow exactly (`P = 1`,
//!   no walk), and `P -> 1` as `R -> 0` since `D >= 1/2` on every voxel a lit segment
//!   crosses: a vanishing light reaches the baseline.
//!
//! The estimate only darkens the lit side of a shadow's edge (the umbra is the hard
//! shadow's): the classic single-ray soft shadow, noise-free and biased. It walks the
//! segment voxel by voxel (a second walk after the transmittance's), so it costs two
//! hard shadow rays per light; the sparse traversal of issue 16 would let it leap.

use glam::{DVec3, IVec3, UVec3};

use super::{
    AblateCurve, CpuShadow, GpuBuild, GpuData, Kind, Knob, LightQuery, Setting, ShadowModel,
};
use crate::dda::Dda;
use crate::frame::RayStats;
use crate::render::RenderSettings;
use crate::scene::{Scene, VOID};
use crate::technique::shading::{shadow_transmittance, unshadowed};

/// Largest grid (voxels) the field is built for: 64 MiB of f32 on the device (and
/// twice that of scratch while it is built), 128 MiB of f64 for the CPU reference.
pub(crate) const MAX_FIELD_VOXELS: u64 = 1 << 24;

const SETTINGS: &[Setting] = &[Setting {
    key: "softness",
    kind: Kind::Float {
        min: 0.0,
        max: 16.0,
        min_open: false,
        max_open: false,
    },
    default: 1.0,
    unit: "",
    doc: "scale of the light's radius in the penumbra estimate (0: hard shadows)",
    sweep: &[0.25, 0.5, 1.0, 2.0, 4.0],
}];

pub const MODEL: ShadowModel = ShadowModel {
    name: "sdf",
    summary: "penumbra min k h / t along one ray to each light over an exact Euclidean \
              distance transform of the occluders (Quilez 2010; Felzenszwalb and \
              Huttenlocher 2012)",
    title: "distance-field penumbra",
    settings: SETTINGS,
    stochastic: false,
    plan,
    wgsl: (
        "shaders/shadow_sdf.wgsl",
        include_str!("../../shaders/shadow_sdf.wgsl"),
    ),
    // The field, built on the device from the occluders alone: `softness` reaches the
    // kernel with every model's settings (ShadowModel::gpu_settings), so a softness
    // sweep keeps the field.
    gpu_data: Some(GpuData::Device(build_on_device)),
    data_settings: &[],
    cpu: |scene, settings| {
        Box::new(Sdf {
            field: distance_field(scene),
            softness: MODEL.value(settings, "softness"),
        })
    },
    ablate: &[AblateCurve {
        label: "sdf",
        knob: Knob::Own("softness"),
        lights_as_points: false,
        about: "",
    }],
    describe: None,
    label: "SHADOW_MODEL(sdf)",
    switch: None,
    shared_settings: &[],
    shadow_rays: true,
    pyramid: false,
};

fn plan(scene: &Scene, _: &RenderSettings) -> Result<(), String> {
    let n = scene.grid.voxel_count() as u64;
    if n > MAX_FIELD_VOXELS {
        return Err(format!(
            "the grid has {n} voxels; the distance field is built for at most \
             {MAX_FIELD_VOXELS} (sdf::MAX_FIELD_VOXELS)"
        ));
    }
    Ok(())
}

/// `D(v)` of every voxel, x fastest (module documentation); a grid without occluders
/// is `f64::MAX` everywhere.
pub fn distance_field(scene: &Scene) -> Vec<f64> {
    let grid = scene
        .grid
        .to_dense()
        .expect("the plan bounds the field to MAX_FIELD_VOXELS");
    let grid = grid.as_ref();
    let opaque: Vec<bool> = scene
        .materials
        .iter()
        .enumerate()
        .map(|(i, m)| i != VOID as usize && m.kt <= 0.0)
        .collect();
    let mut d2: Vec<f64> = grid
        .data()
        .iter()
        .map(|&m| {
            if opaque[m as usize] {
                0.0
            } else {
                f64::INFINITY
            }
        })
        .collect();
    squared_edt(&mut d2, grid.dims());
    d2.into_iter()
        .map(|s| match s {
            0.0 => 0.0,
            s if s.is_finite() => s.sqrt() - 0.5,
            _ => f64::MAX,
        })
        .collect()
}

/// The squared Euclidean distance transform of `f` (0 on sites, infinity elsewhere) in
/// place, one axis after the other (Felzenszwalb and Huttenlocher, section 2.1 and 3).
pub fn squared_edt(f: &mut [f64], dims: UVec3) {
    let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
    let longest = nx.max(ny).max(nz);
    let mut line = vec![0.0; longest];
    let mut out = vec![0.0; longest];
    let mut v = vec![0usize; longest];
    let mut z = vec![0.0; longest + 1];
    // (length, stride) of the lines along x, y and z, and how many there are.
    let axes = [(nx, 1, ny * nz), (ny, nx, nx * nz), (nz, nx * ny, nx * ny)];
    for (axis, &(n, stride, count)) in axes.iter().enumerate() {
        for k in 0..count {
            let start = match axis {
                0 => k * nx,
                1 => (k / nx) * nx * ny + k % nx,
                _ => k,
            };
            for i in 0..n {
                line[i] = f[start + i * stride];
            }
            lower_envelope(&line[..n], &mut out[..n], &mut v, &mut z);
            for i in 0..n {
                f[start + i * stride] = out[i];
            }
        }
    }
}

/// `d(p) = min_q (p - q)^2 + f(q)`: the lower envelope of the parabolas rooted at the
/// finite samples (Felzenszwalb and Huttenlocher, algorithm DT(f)).
fn lower_envelope(f: &[f64], d: &mut [f64], v: &mut [usize], z: &mut [f64]) {
    let n = f.len();
    let Some(first) = f.iter().position(|x| x.is_finite()) else {
        d.fill(f64::INFINITY);
        return;
    };
    let mut k = 0;
    v[0] = first;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in first + 1..n {
        if !f[q].is_finite() {
            continue;
        }
        // Drop the parabolas the new one hides (z[0] is -infinity, so k stays >= 0).
        let s = loop {
            let p = v[k];
            let s = ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q - p) as f64);
            if k > 0 && s <= z[k] {
                k -= 1;
            } else {
                break s;
            }
        };
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    k = 0;
    for (q, out) in d.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        let dq = q as f64 - p as f64;
        *out = dq * dq + f[p];
    }
}

struct Sdf {
    field: Vec<f64>,
    softness: f64,
}

impl Sdf {
    fn at(&self, scene: &Scene, v: IVec3) -> f64 {
        let d = scene.grid.dims();
        self.field[v.x as usize + d.x as usize * (v.y as usize + d.y as usize * v.z as usize)]
    }

    /// `P` of the segment from `q` along unit `dir` of length `len` (world units), for
    /// `k = len / (s R)` in voxels.
    fn penumbra(
        &self,
        scene: &Scene,
        q: DVec3,
        dir: DVec3,
        len: f64,
        k: f64,
        stats: &mut RayStats,
    ) -> f64 {
        let h = scene.grid.voxel_size();
        let mut dda = Dda::new(&scene.grid, q, dir, len);
        let mut p = 1.0f64;
        let mut last: Option<(IVec3, f64)> = None;
        let term = |v: IVec3, t0: f64, t1: f64, p: &mut f64| {
            let t = 0.5 * (t0 + t1.min(len)) / h;
            if t > 0.0 {
                *p = p.min(self.at(scene, v) * k / t);
            }
        };
        for visit in dda.by_ref() {
            if let Some((v, t0)) = last {
                term(v, t0, visit.t_enter, &mut p);
            }
            last = Some((visit.voxel, visit.t_enter));
        }
        if let Some((v, t0)) = last {
            term(v, t0, dda.t_end, &mut p);
        }
        stats.voxel_steps += dda.steps;
        p.clamp(0.0, 1.0)
    }
}

impl CpuShadow for Sdf {
    fn light_term(&self, at: &LightQuery, stats: &mut RayStats) -> DVec3 {
        let (scene, s) = (at.scene, at.settings);
        let x = at.light.position();
        let radiance = at.light.radiance_towards(x, at.p);
        stats.shadow += 1;
        let t = shadow_transmittance(scene, &at.walk, s.features.transmittance, at.q, x, stats);
        if t == DVec3::ZERO {
            return DVec3::ZERO;
        }
        let to = x - at.q;
        let len = to.length();
        let r = self.softness * crate::technique::cones::march::light_radius(at.light);
        let p = if r > 0.0 && len > 0.0 {
            // k in voxels: len / r is a ratio of world lengths.
            self.penumbra(scene, at.q, to / len, len, len / r, stats)
        } else {
            1.0
        };
        if p == 0.0 {
            return DVec3::ZERO;
        }
        t * p * unshadowed(s, at.material, at.p, at.n, at.d, x, radiance)
    }
}

/// `shaders/sdf_edt.wgsl`: the field on the device.
const EDT: &str = include_str!("../../shaders/sdf_edt.wgsl");

/// Builds `D` on the device (one envelope pass per axis, then the finishing pass) into a
/// buffer of `voxels` floats; an error when the driver's
/// loop limit cut a line short.
fn build_on_device(b: &GpuBuild) -> anyhow::Result<wgpu::Buffer> {
    use wgpu::util::DeviceExt;
    let (device, queue) = (b.device, b.queue);
    let dims = b.scene.grid.dims();
    let voxels = dims.as_u64vec3().element_product();
    let opaque: Vec<u32> = b
        .scene
        .materials
        .iter()
        .enumerate()
        .map(|(i, m)| u32::from(i != VOID as usize && m.kt <= 0.0))
        .collect();
    use crate::device::{buffer_entry, storage_entry, texture_3d_entry, uniform_entry, view_entry};
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("sdf field"),
        entries: &[
            uniform_entry(0),
            texture_3d_entry(1, wgpu::TextureSampleType::Uint),
            storage_entry(2, true),
            storage_entry(3, true),
            storage_entry(4, false),
            storage_entry(5, false),
            storage_entry(6, false),
            storage_entry(7, false),
        ],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("sdf field"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("shaders/sdf_edt.wgsl"),
        source: wgpu::ShaderSource::Wgsl(EDT.into()),
    });
    let pipeline = |entry: &str| {
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
    };
    let (envelope, finish) = (pipeline("envelope"), pipeline("finish"));
    let buffer = |label, size: u64, usage| crate::device::buffer(device, label, size.max(4), usage);
    let storage_usage = wgpu::BufferUsages::STORAGE;
    let field = buffer(
        "sdf field",
        voxels * 4,
        storage_usage | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
    );
    let other = buffer("sdf field (pass)", voxels * 4, storage_usage);
    let roots = buffer("sdf envelope roots", voxels * 4, storage_usage);
    let lines = [dims.y * dims.z, dims.x * dims.z, dims.x * dims.y].map(u64::from);
    let most_lines = lines.into_iter().max().unwrap_or(1);
    let bounds = buffer(
        "sdf envelope bounds",
        (voxels + most_lines) * 4,
        storage_usage,
    );
    let cut = buffer(
        "sdf loop cut",
        4,
        storage_usage | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
    );
    let cut_read = crate::device::readback(device, "sdf loop cut readback", 4);
    let opaque = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("sdf opaque materials"),
        contents: bytemuck::cast_slice(&opaque),
        usage: storage_usage,
    });
    queue.write_buffer(&cut, 0, &[0; 4]);
    let mut encoder = device.create_command_encoder(&Default::default());
    // x: grid -> field; y: field -> other; z: other -> field; finish: field in place.
    for (axis, src, dst) in [
        (0u32, &other, &field),
        (1, &field, &other),
        (2, &other, &field),
        (3, &other, &field),
    ] {
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("sdf field params"),
            contents: bytemuck::cast_slice(&[dims.x, dims.y, dims.z, axis]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("sdf field"),
            layout: &layout,
            entries: &[
                buffer_entry(0, &params),
                view_entry(1, b.grid),
                buffer_entry(2, &opaque),
                buffer_entry(3, src),
                buffer_entry(4, dst),
                buffer_entry(5, &roots),
                buffer_entry(6, &bounds),
                buffer_entry(7, &cut),
            ],
        });
        let items = if axis < 3 {
            lines[axis as usize]
        } else {
            voxels
        };
        let groups = items.div_ceil(64).max(1);
        let gx = groups.min(65535) as u32;
        let gy = groups.div_ceil(u64::from(gx)) as u32;
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(if axis < 3 { &envelope } else { &finish });
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(gx, gy, 1);
    }
    encoder.copy_buffer_to_buffer(&cut, 0, &cut_read, 0, 4);
    queue.submit([encoder.finish()]);
    let slice = cut_read.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| anyhow::anyhow!("waiting for the GPU: {e}"))?;
    rx.recv()??;
    let was_cut = {
        let view = slice
            .get_mapped_range()
            .map_err(|e| anyhow::anyhow!("reading a mapped buffer: {e:?}"))?;
        bytemuck::cast_slice::<u8, u32>(&view)[0] != 0
    };
    cut_read.unmap();
    if was_cut {
        anyhow::bail!(
            "the driver's loop limit cut the distance transform of a {}x{}x{} grid short \
             (shaders/counters.wgsl); render with --backend cpu or on a hardware GPU",
            dims.x,
            dims.y,
            dims.z
        );
    }
    Ok(field)
}
