//! Dispatch and accumulation: one range of frames traced (uploads, error scopes, pyramid
//! builds, dispatches split to the device's limits, accumulation, timestamps, readback),
//! and the reduction of the ray counters.

use super::*;

impl GpuTracer {
    /// `plan` for this device: its DDA unrolling, and under `traversal = "auto"` a walk
    /// whose data the device can bind when the planned one's is too large.
    fn fit_plan(&self, scene: &Scene, settings: &RenderSettings, plan: Plan) -> Plan {
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
        plan.warnings
            .extend(crate::plan::check_ray_offset(scene, settings).err());
        plan
    }

    /// Forgets everything on the device after a failed upload: the next render starts
    /// over rather than trusting what was half made.
    fn forget_device_state(&mut self) {
        self.grid = None;
        self.buffers = None;
        self.compensation = None;
        self.frame_slices = None;
        self.pyramid = None;
        self.technique_data = None;
        self.walk_data = None;
        self.surfaces = None;
        self.filter_buffers = None;
    }

    /// Frames per submission: a whole accumulating render in as few dispatches as the
    /// device's limits allow (`frames_per_dispatch`), one frame otherwise.
    fn frames_per_submission(&self, accumulate: bool, pixels: u64, todo: u32) -> u32 {
        if accumulate {
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
        }
    }

    /// Accumulating, the tracer writes each frame of a dispatch to its own slice and
    /// the accumulation kernel adds them to the sums in `output` and `compensation`:
    /// those two buffers (grown as needed), or none (and none kept) otherwise.
    fn accumulation_buffers(
        &mut self,
        accumulate: bool,
        pixels: u64,
        per_dispatch: u32,
    ) -> Option<(wgpu::Buffer, wgpu::Buffer)> {
        if accumulate {
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
        }
    }

    /// The trace's bindings: parameters, the walk's voxels, materials, lights, the
    /// radiance output (or the frame slices when accumulating), counters, a technique's
    /// data, the walk's data and the surfaces (a placeholder for what the plan lacks).
    fn trace_bind_group(
        &self,
        output: &wgpu::Buffer,
        mat_buf: &wgpu::Buffer,
        light_buf: &wgpu::Buffer,
        slices: Option<&wgpu::Buffer>,
        technique_bytes: u64,
    ) -> wgpu::BindGroup {
        let technique_data = match (&self.technique_data, technique_bytes) {
            (Some((_, b)), 1..) => b,
            _ => &self.no_technique_data,
        };
        let voxels = self
            .grid
            .as_ref()
            .and_then(|g| g.voxels.as_ref().map(|v| &v.1))
            .unwrap_or(&self.no_technique_data);
        let placeholder = &self.no_technique_data;
        let walk = self.walk_data.as_ref().map(|w| &w.1);
        let walk_more = |i: usize| walk.and_then(|w| w.more.get(i)).unwrap_or(placeholder);
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("voxlab tracer"),
            layout: &self.layout,
            entries: &[
                buffer_entry(0, &self.params),
                buffer_entry(1, voxels),
                buffer_entry(2, mat_buf),
                buffer_entry(3, light_buf),
                buffer_entry(4, slices.unwrap_or(output)),
                buffer_entry(5, &self.counters),
                buffer_entry(6, technique_data),
                buffer_entry(7, walk.map_or(placeholder, |w| &w.main)),
                buffer_entry(8, self.surfaces.as_ref().map_or(placeholder, |u| &u.buffer)),
                buffer_entry(9, walk_more(0)),
                buffer_entry(10, walk_more(1)),
                buffer_entry(11, walk_more(2)),
            ],
        })
    }

    /// The error of a render the driver's loop limit cut short: which driver, why, and
    /// what to lower (the image would be wrong, so none is returned).
    fn loops_cut_error(
        &self,
        cut: u32,
        pixel_frames: u64,
        scene: &Scene,
        settings: &RenderSettings,
        plan: &Plan,
    ) -> anyhow::Error {
        let info = self.adapter.get_info();
        let techniques = plan.technique_settings();
        let techniques = if techniques.is_empty() {
            String::new()
        } else {
            format!(
                ", the settings of its techniques ({})",
                techniques.join(", ")
            )
        };
        anyhow::Error::new(LoopsCut).context(format!(
            "{} of {} pixel-frames of this image were cut short by the driver ({}, {}): \
             Mesa's software driver (llvmpipe, lavapipe) ends every loop of an \
             invocation after 65535 loop iterations in all (LP_MAX_TGSI_LOOP_ITERATIONS, \
             counted over the 8 or 16 SIMD lanes that run together), and one frame of \
             these pixels needs more (depth limits {}/{}, {} light sample(s), {} \
             light(s), grid {}x{}x{}; {} voxel steps per loop iteration). The image \
             would be wrong, so none is returned: lower light_samples, the depth limits \
             (or max_depth) or the grid size{}, or render with --backend cpu or on a \
             hardware GPU",
            cut,
            pixel_frames,
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
            techniques,
        ))
    }

    /// Renders `frames` of `plan`: uploads under error scopes, bindings, pyramids, the
    /// timed dispatches, readback, counters and memory. Still one function of about 330
    /// lines because the error scopes, the buffers it binds and the query set live from
    /// the first upload to the readback; the pieces that stand alone are the methods
    /// above and `ray_stats`, `resolve_frame` below.
    pub(super) fn render_range_once(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        plan: Plan,
        frames: Range<u32>,
        continuable: bool,
    ) -> Result<RenderOutput> {
        let mut plan = self.fit_plan(scene, settings, plan);
        let count = plan.count_rays;
        self.check(scene, settings, &plan)?;
        plan.check_frames(settings, &frames)
            .map_err(anyhow::Error::msg)?;
        if plan.layer_slices() > 1 {
            self.make_filter_pipelines(plan.reconstruction)?;
        }
        // Device allocations fail as errors of the render, never through wgpu's default
        // handler (a panic): a grid texture or buffer the device cannot hold is reported
        // with its size. Popped (in reverse order) once everything is uploaded.
        if frames.start > 0 {
            // Before any upload: a grid uploaded for a continuation that is then refused
            // would end the accumulation it refused to continue.
            self.check_continued_voxels(scene, &frames)?;
        }
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
                self.upload_walk_data(
                    plan.traversal,
                    walk_grid,
                    walk_hash,
                    crate::technique::walk_budget(settings, self.walk_budget()),
                )?,
                start.elapsed(),
            )
        } else {
            // Dropped while renders walk the grid: nothing holds it on the device.
            self.walk_data = None;
            (0, Duration::ZERO)
        };
        // The kernel reads the bindings the walk's data takes, and what that data holds,
        // known once it is built.
        if let Some((_, walk)) = &self.walk_data {
            plan.walk_more_bindings = walk.more.len() as u32;
            plan.walk_variant = walk.variant;
            plan.walk_data = walk.summary.clone();
        }
        self.pipeline(&plan)?;
        let key = continuable.then(|| {
            let surface = self.surfaces.as_ref().map(|u| u.key);
            AccumulationKey::new(scene, settings, &plan, surface)
        });
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
        // The kernel writes this many vec4 per frame: the image's pixels, times the
        // planes of the primary layers when a reconstruction reads them.
        let image_pixels = settings.width as u64 * settings.height as u64;
        let pixels = image_pixels * plan.layer_slices() as u64;
        let todo = frames.end - frames.start;
        let per_dispatch = self.frames_per_submission(plan.accumulate, pixels, todo);
        let mut params = Self::params(scene, settings);
        params.technique = plan.shadow_model.gpu_settings(settings);
        params.frame_begin = frames.start;
        params.frame_count = per_dispatch;
        params.walk_part_words = self.walk_data.as_ref().map_or(0, |(k, _)| {
            crate::technique::walk_part_words(k.budget()) as u32
        });
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
        let accumulation = self.accumulation_buffers(plan.accumulate, pixels, per_dispatch);
        let compensation = accumulation.as_ref().map(|a| a.0.clone());
        let reduce = accumulation
            .as_ref()
            .map(|(compensation, slices)| self.reduce_bind_group(&output, compensation, slices));
        let technique_bytes = self.upload_technique_data(scene, settings, &plan)?;
        let bind_group = self.trace_bind_group(
            &output,
            &mat_buf,
            &light_buf,
            accumulation.as_ref().map(|a| &a.1),
            technique_bytes,
        );

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

        self.warm_up(&plan, &bind_group, cone_group.as_ref(), reduce.as_ref());
        // Finish the uploads first so the timed submission holds the trace alone.
        self.queue.submit([]);
        self.wait()?;
        let validation = pollster::block_on(validation_scope.pop());
        let oom = pollster::block_on(oom_scope.pop());
        if let Some(e) = oom.or(validation) {
            self.forget_device_state();
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
        // A reconstruction filters on the device what the trace summed; only the image
        // it composes comes back.
        let filtered = if plan.layer_slices() > 1 {
            let f = self.reconstruct(
                plan.reconstruction,
                settings,
                (
                    &scene.camera.frame(),
                    reconstruct::depth_origin(scene, settings),
                ),
                &output,
                compensation.as_ref(),
                frames.end,
            )?;
            self.last_filter_time = f.time;
            Some(f)
        } else {
            self.last_filter_time = Duration::ZERO;
            None
        };
        let trace_time = start.elapsed();
        self.last_gpu_time = match &queries {
            Some(q) => Some(self.pass_time(q, passes)? + self.last_filter_time),
            None => None,
        };

        let copy = |from: &wgpu::Buffer, bytes: u64| {
            let mut encoder = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("voxlab readback"),
                });
            encoder.copy_buffer_to_buffer(from, 0, &readback, 0, bytes);
            encoder.copy_buffer_to_buffer(
                &self.counters,
                0,
                &self.counters_readback,
                0,
                COUNTER_BYTES,
            );
            self.queue.submit([encoder.finish()]);
        };
        let (radiance, compensation): (Vec<[f32; 4]>, Option<Vec<[f32; 4]>>) = match &filtered {
            // The composed image, already divided by the frames.
            Some(f) => {
                copy(&f.image, image_pixels * 16);
                (self.read(&readback, image_pixels * 16)?, None)
            }
            None => {
                copy(&output, pixels * 16);
                let radiance = self.read(&readback, pixels * 16)?;
                // With ACCUMULATE the buffers hold the sum of the frames and its
                // compensation: the image is (sum + compensation) / frames, in f64,
                // rounded once.
                let compensation = match &compensation {
                    Some(b) => {
                        copy(b, pixels * 16);
                        Some(self.read(&readback, pixels * 16)?)
                    }
                    None => None,
                };
                (radiance, compensation)
            }
        };
        let counts: Vec<u32> = self.read(&self.counters_readback, COUNTER_BYTES)?;
        if counts[LOOPS_CUT] > 0 {
            return Err(self.loops_cut_error(
                counts[LOOPS_CUT],
                image_pixels * todo as u64,
                scene,
                settings,
                &plan,
            ));
        }
        let stats = if count {
            ray_stats(&counts)
        } else {
            RayStats::default()
        };
        let frame = resolve_frame(
            settings.width,
            settings.height,
            &radiance,
            compensation.as_deref(),
            frames.end,
        );
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
            reconstruction: filtered.as_ref().map_or(0, |f| f.bytes),
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
            walk_data: self.walk_data.as_ref().and_then(|w| w.1.summary.clone()),
        })
    }

    /// The first dispatch of a kernel made for this render, and of the accumulation
    /// kernel, untimed. Mesa's software driver compiles a kernel for the bound state
    /// (the values of the uniforms its branches read included) at its first
    /// dispatch, not when the pipeline is made, and where Mesa's shader cache does
    /// not hold it yet that takes longer than a frame: the first 64x64
    /// frame of `experiments/seed_rules.toml` timed 231 ms against 7 ms for the next,
    /// inside the timestamps (docs/benchmarks.md, "A kernel's first dispatch"). One
    /// workgroup of the trace runs with the render's own bindings, whose pixels the
    /// timed dispatch writes again, and the ray counters it adds to are cleared after
    /// it; the accumulation kernel runs with no pixels, so it adds nothing.
    fn warm_up(
        &mut self,
        plan: &Plan,
        trace: &wgpu::BindGroup,
        cones: Option<&wgpu::BindGroup>,
        reduce: Option<&wgpu::BindGroup>,
    ) {
        let key = plan.shader_defs();
        let trace_cold = self.cold_kernels.remove(&key);
        let reduce_cold = reduce.is_some() && std::mem::take(&mut self.cold_reduce);
        if !trace_cold && !reduce_cold {
            return;
        }
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("voxlab warm-up"),
            });
        if trace_cold {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("voxlab trace warm-up"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipelines[&key]);
            pass.set_bind_group(0, trace, &[]);
            if let Some(g) = cones {
                pass.set_bind_group(1, g, &[]);
            }
            pass.dispatch_workgroups(1, 1, 1);
        }
        if let (true, Some(group), Some((_, pipeline, params))) =
            (reduce_cold, reduce, &self.reduce)
        {
            let none = ReduceParams {
                pixels: 0,
                row: 0,
                frame_begin: 0,
                frame_count: 0,
            };
            self.queue
                .write_buffer(params, 0, bytemuck::bytes_of(&none));
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("voxlab accumulate warm-up"),
                timestamp_writes: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(1, 1, 1);
        }
        self.queue.submit([encoder.finish()]);
        // Applied after the warm-up's submission and before the render's.
        self.queue
            .write_buffer(&self.counters, 0, &[0u8; COUNTER_BYTES as usize]);
    }

    /// The accumulation kernel's dispatch grid for `pixels`: 64-wide workgroups along x
    /// up to the per-dimension limit, then rows of them along y.
    pub(super) fn reduce_grid(pixels: u64) -> (u32, u32) {
        let groups = pixels.div_ceil(REDUCE_WORKGROUP as u64);
        let x = groups.min(32768) as u32;
        (x, groups.div_ceil(x as u64) as u32)
    }

    /// The accumulation kernel's bind group (made with the kernel on first use): frame
    /// slices in, running sums and compensation in and out.
    pub(super) fn reduce_bind_group(
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
            self.cold_reduce = true;
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
}

/// The ray counters as [`RayStats`]: each a u64 in two u32 words (shaders/counters.wgsl).
fn ray_stats(counts: &[u32]) -> RayStats {
    let c = |i: usize| counts[2 * i] as u64 | (counts[2 * i + 1] as u64) << 32;
    RayStats {
        primary: c(0),
        secondary: c(1),
        shadow: c(2),
        voxel_steps: c(3),
        triangle_tests: 0,
        untraced: c(5),
    }
}

/// The image from the read-back radiance: as it is, or with ACCUMULATE the sum of
/// `frames` frames and its compensation, (sum + compensation) / frames in f64, rounded
/// once.
fn resolve_frame(
    width: u32,
    height: u32,
    radiance: &[[f32; 4]],
    compensation: Option<&[[f32; 4]]>,
    frames: u32,
) -> Frame {
    let mut frame = Frame::new(width, height);
    match compensation {
        None => {
            for (dst, src) in frame.pixels.iter_mut().zip(radiance) {
                *dst = [src[0], src[1], src[2]];
            }
        }
        Some(comp) => {
            let n = frames as f64;
            for ((dst, sum), c) in frame.pixels.iter_mut().zip(radiance).zip(comp) {
                *dst = std::array::from_fn(|k| ((sum[k] as f64 + c[k] as f64) / n) as f32);
            }
        }
    }
    frame
}
