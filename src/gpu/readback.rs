//! Readback and timing: waiting for the device, timestamp queries, reading buffers back.

use super::*;

impl GpuTracer {
    pub(super) fn wait(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| anyhow!("waiting for the GPU: {e}"))?;
        Ok(())
    }

    /// Maps `buffer` (already copied into), reads `bytes` as `T`s, unmaps.
    /// The summed durations of `passes` compute passes whose start and end timestamps
    /// are queries 2i and 2i + 1 of `q`.
    pub(super) fn pass_time(&self, q: &wgpu::QuerySet, passes: u32) -> Result<Duration> {
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

    pub(super) fn read<T: Pod>(&self, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<T>> {
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
