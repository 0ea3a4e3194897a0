//! Uploads: the grid, its walk data and surfaces, the scene's materials and lights, the
//! parameters and output buffers, a technique's data; each kept on the device and replaced
//! only when what it holds changed.

use super::*;

impl GpuTracer {
    /// Whether a render of `plan` reads the grid texture: the builds of the cone pyramids
    /// and of device-built technique data do. The walks do not: the dense walk reads the
    /// voxel buffer, the sparse one the tree.
    pub(super) fn reads_grid_texture(plan: &Plan) -> bool {
        plan.pyramid.is_some()
            || matches!(
                plan.shadow_model.gpu_data,
                Some(crate::technique::GpuData::Device(_))
            )
    }

    /// Whether a render of `plan` reads the voxel buffer: a walk without data of its
    /// own (the dense walk) does.
    pub(super) fn reads_voxel_buffer(plan: &Plan) -> bool {
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

    /// The most bytes a binding of a walk's data may take where the walk chooses what to
    /// hold (the sparse octant walk's codes): the largest binding. On lavapipe it is the
    /// CPU reference's [`crate::technique::HOST_WALK_BYTES`], so both walk alike; a
    /// device that binds more holds the codes of larger trees (images the same, fewer
    /// steps).
    pub fn walk_budget(&self) -> usize {
        usize::try_from(self.max_voxel_buffer_bytes()).unwrap_or(usize::MAX)
    }

    /// Makes the voxel buffer of `grid` (the uploaded grid, or its copy with the cells
    /// tagged), whose voxels hash to `hash`, unless the upload holds it.
    pub(super) fn upload_voxel_buffer(&mut self, grid: &crate::scene::Grid, hash: blake3::Hash) {
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
    pub(super) fn upload_grid(&mut self, scene: &Scene, texture: bool) {
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
    /// `hash`: the sparse tree, say) within `budget` bytes where the traversal chooses
    /// what to hold, unless the device holds it already; returns its bytes.
    pub(super) fn upload_walk_data(
        &mut self,
        traversal: &'static crate::technique::TraversalModel,
        grid: &crate::scene::Grid,
        hash: blake3::Hash,
        budget: usize,
    ) -> Result<u64> {
        let build = traversal
            .data
            .expect("only a traversal with data of its own uploads it");
        let key = crate::technique::WalkKey::hashed(traversal, grid, hash, budget);
        if let Some((k, b)) = &self.walk_data
            && k.same(&key)
        {
            return Ok(b.bytes());
        }
        self.walk_data = None;
        let data = self.walk_builds.get_or_build(key, || build(grid, budget));
        let parts = data.device_words();
        let bytes = (parts.iter().map(|p| p.len()).sum::<usize>() * 4).next_multiple_of(16) as u64;
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
        let more = data.device_more_words();
        let part_words = crate::technique::walk_part_words(budget);
        let parts_more = more.len().div_ceil(part_words.max(1));
        // The build keeps within both (it knows the budget); a traversal that does not
        // is refused here rather than bound past the device's limits.
        if parts_more > crate::technique::WALK_MORE_BINDINGS
            || (!more.is_empty() && 4 * part_words as u64 > max)
        {
            bail!(
                "the {} traversal's further data of grid {}x{}x{} needs {} bytes in \
                 bindings of {} bytes; the device binds {} more of at most {max} bytes",
                traversal.name,
                grid.dims().x,
                grid.dims().y,
                grid.dims().z,
                4 * more.len(),
                4 * part_words,
                crate::technique::WALK_MORE_BINDINGS,
            );
        }
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let main = buffer(&self.device, traversal.label, bytes, usage);
        let mut offset = 0;
        for part in parts {
            self.queue
                .write_buffer(&main, offset, bytemuck::cast_slice(part));
            offset += 4 * part.len() as u64;
        }
        let more = more
            .chunks(part_words.max(1))
            .map(|words| {
                let b = buffer(&self.device, traversal.label, 4 * words.len() as u64, usage);
                self.queue.write_buffer(&b, 0, bytemuck::cast_slice(words));
                b
            })
            .collect();
        let walk = super::WalkBuffers {
            main,
            more,
            variant: data.kernel_variant(),
            summary: data.summary(),
        };
        let bytes = walk.bytes();
        self.walk_data = Some((key, walk));
        Ok(bytes)
    }

    /// Lists the plan's triangle surfaces in the grid and uploads them, unless the
    /// device holds those already (the same grid, mesh and kind). `None` for voxels.
    pub(super) fn upload_surfaces(
        &mut self,
        scene: &Scene,
        plan: &Plan,
    ) -> Result<Option<std::sync::Arc<crate::triangles::SurfaceTrace>>> {
        if !plan.surface.traces_triangles() {
            self.surfaces = None;
            return Ok(None);
        }
        // What the cells were listed from, with the voxels' hash upload_grid has just
        // taken (not taken again).
        let voxels = self
            .grid
            .as_ref()
            .map_or_else(|| scene.grid.content_hash(), |u| u.hash);
        let key = plan.surface.trace_key(scene, voxels);
        if let Some(u) = self.surfaces.as_ref().filter(|u| u.key == key) {
            return Ok(Some(u.trace.clone()));
        }
        self.surfaces = None;
        let trace = plan
            .surface
            .trace(scene)?
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
    pub(super) fn grow(
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
    pub(super) fn scene_data(scene: &Scene, bounds: &[f32]) -> (Vec<GpuMaterial>, Vec<GpuLight>) {
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
                dielectric: m.dielectric.code(),
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
    pub(super) fn upload_scene(
        &mut self,
        scene: &Scene,
        bounds: &[f32],
    ) -> (wgpu::Buffer, wgpu::Buffer) {
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

    pub(super) fn output_buffers(&mut self, pixels: u64) -> (wgpu::Buffer, wgpu::Buffer) {
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

    pub(super) fn params(scene: &Scene, settings: &RenderSettings) -> GpuParams {
        let grid = &scene.grid;
        let vs = grid.voxel_size();
        let cam = scene.camera.frame();
        let (right_scaled, up_scaled) = crate::plan::primary_spans(&cam, settings);
        // A far eye's rays start nearer the grid (plan::primary_origin).
        let origin = crate::plan::primary_origin(scene, settings);
        // Directions keep their length in local coordinates (a uniform scale), so only
        // the eye is transformed; everything in f64 before the one rounding to f32.
        GpuParams {
            eye: f3(origin.eye),
            width: settings.width,
            forward: f3(cam.forward),
            height: settings.height,
            right_scaled: f3(right_scaled),
            num_lights: scene.lights.len() as u32,
            up_scaled: f3(up_scaled),
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
            walk_part_words: 0,
            primary_advance: origin.advance as f32,
            loop_guard: 0,
            _pad: 0,
            technique: [0.0; crate::technique::MAX_GPU_SETTINGS],
        }
    }

    /// A light as the kernel sees it. Point lights and area lights of size 0 are points
    /// at their centres; other area lights carry their kind and their axes scaled by
    /// their size, from AreaLight::frame in f64, divided by the voxel size into voxel
    /// units. Only the shadow model reads the shape: hard shadows take the centre alone.
    pub(super) fn light(scene: &Scene, light: &Light) -> GpuLight {
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

    /// Makes (or keeps) the `technique_data` of the plan's plug-in shadow model and
    /// returns its size in bytes; 0, with any held data dropped, when the plan needs none.
    pub(super) fn upload_technique_data(
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
        // Its inputs: the technique, the settings it declares it reads, the voxels (by
        // upload generation) and everything else of the scene but the camera.
        let params: Vec<f64> = model
            .data_settings
            .iter()
            .map(|key| model.value(settings, key))
            .collect();
        let key = blake3::hash(
            format!(
                "{} {:?} {} {:?} {:?} {:?} {:?}",
                model.name,
                params,
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
                let mut data = make(scene, &params);
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
                    params: &params,
                })
                .with_context(|| format!("building the data of shadow model {}", model.name))?
            }
        };
        let size = buf.size();
        self.technique_data = Some((key, buf));
        self.technique_data_builds += 1;
        Ok(size)
    }
}
