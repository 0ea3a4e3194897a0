//! `voxlab bench --adaptive`: does the viewer's adaptive resolution keep a moving view
//! within its frame budget? For each experiment, a full-size frame is timed, the
//! controller (`state::AdaptiveScale`) picks the scale it would use while both sides
//! move, and frames at that scale are timed and fed back to it until its choice repeats
//! (as in the viewer), on the tracer the viewer uses, in one run.

use std::time::Duration;

use anyhow::Result;

use super::state::{AdaptiveScale, scaled_size};
use crate::experiment::Experiment;
use crate::gpu::GpuTracer;

/// Frames of a drag over which the controller's choice is followed.
const SETTLE_FRAMES: usize = 8;

/// One experiment's figures.
#[derive(Clone, Debug)]
pub struct AdaptiveRow {
    pub name: String,
    pub full: (u32, u32),
    pub full_ms: f64,
    pub scale: f32,
    pub scaled: (u32, u32),
    pub scaled_ms: f64,
    pub budget_ms: f64,
}

impl AdaptiveRow {
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "experiment": self.name,
            "full": [self.full.0, self.full.1],
            "full_ms": self.full_ms,
            "scale": self.scale,
            "scaled": [self.scaled.0, self.scaled.1],
            "scaled_ms": self.scaled_ms,
            "budget_ms": self.budget_ms,
        })
    }
}

/// Median device time (wall where there is no device timer) of `runs` one-frame renders.
fn frame_ms(gpu: &mut GpuTracer, e: &Experiment, size: (u32, u32), runs: usize) -> Result<f64> {
    let settings = crate::render::RenderSettings {
        width: size.0,
        height: size.1,
        spp: 1,
        ..e.settings.clone()
    };
    // Warm-up: compiles the kernel variant, builds pyramids, sizes buffers.
    gpu.render_frames(&e.scene, &settings, 0..1)?;
    let mut times: Vec<Duration> = (0..runs.max(1))
        .map(|_| {
            let out = gpu.render_frames(&e.scene, &settings, 0..1)?;
            Ok(gpu.last_gpu_time().unwrap_or(out.trace_time))
        })
        .collect::<Result<_>>()?;
    times.sort();
    Ok(times[times.len() / 2].as_secs_f64() * 1e3)
}

pub fn bench_adaptive(
    gpu: &mut GpuTracer,
    experiments: &[Experiment],
    runs: usize,
) -> Result<Vec<AdaptiveRow>> {
    let mut rows = Vec::new();
    for e in experiments {
        let full = (e.settings.width, e.settings.height);
        let full_ms = frame_ms(gpu, e, full, runs)?;
        let mut controller = AdaptiveScale::default();
        let pixels = full.0 as u64 * full.1 as u64;
        controller.observe(pixels, full_ms);
        // Both sides moving (an orbit): the budget covers the two together. The viewer
        // learns from every frame (small images cost more per pixel than large ones,
        // the dispatch and readback being fixed costs), so its scale settles over a
        // few frames: followed here for the frames of a short drag.
        let mut scale = controller.scale(2 * pixels, true);
        let mut scaled = scaled_size(full.0, full.1, scale);
        let mut scaled_ms = frame_ms(gpu, e, scaled, runs)?;
        for _ in 0..SETTLE_FRAMES {
            controller.observe(scaled.0 as u64 * scaled.1 as u64, scaled_ms);
            let next = controller.scale(2 * pixels, true);
            if next != scale {
                scale = next;
                scaled = scaled_size(full.0, full.1, scale);
                scaled_ms = frame_ms(gpu, e, scaled, runs)?;
            }
        }
        rows.push(AdaptiveRow {
            name: e.name.clone(),
            full,
            full_ms,
            scale,
            scaled,
            scaled_ms,
            budget_ms: controller.budget_ms,
        });
    }
    Ok(rows)
}

pub fn adaptive_table(rows: &[AdaptiveRow]) -> String {
    let mut t = String::from(
        "| experiment | full size | ms/frame | scale while moving | traced | ms/frame | both sides, ms | budget, ms |\n\
         |---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        t += &format!(
            "| {} | {}x{} | {:.1} | {} | {}x{} | {:.1} | {:.1} | {:.0} |\n",
            r.name,
            r.full.0,
            r.full.1,
            r.full_ms,
            r.scale,
            r.scaled.0,
            r.scaled.1,
            r.scaled_ms,
            2.0 * r.scaled_ms,
            r.budget_ms
        );
    }
    t
}
