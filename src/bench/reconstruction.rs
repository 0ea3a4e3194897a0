//! `voxlab bench --reconstruction`: what a reconstruction's passes cost per frame on the
//! device, at each image size: the frame without a reconstruction, the frame with it
//! (the same trace plus the primary layers and the filter), and the filter's passes
//! alone (their wall time around synchronised submissions), medians of interleaved runs.

use std::time::Duration;

use anyhow::{Result, bail};

use crate::experiment::Experiment;
use crate::gpu::GpuTracer;
use crate::render::RenderSettings;
use crate::technique::Reconstruction;

/// One reconstruction at one image size.
#[derive(Clone, Debug)]
pub struct FilterRow {
    pub experiment: String,
    pub reconstruction: &'static str,
    pub size: u32,
    /// Median frame time without a reconstruction, with one, and of its passes alone.
    pub plain_ms: f64,
    pub filtered_ms: f64,
    pub filter_ms: f64,
    /// The filtered frame's time over the plain one's, round by round (interleaved).
    pub time_ratio: super::Ratio,
}

impl FilterRow {
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "experiment": self.experiment,
            "reconstruction": self.reconstruction,
            "image_side": self.size,
            "plain_ms_per_frame": self.plain_ms,
            "filtered_ms_per_frame": self.filtered_ms,
            "filter_ms_per_frame": self.filter_ms,
            "time_filtered_over_none": self.time_ratio.json(),
        })
    }
}

/// `e` at each of `sizes` (square, one frame) without a reconstruction and with each of
/// `reconstructions`, `runs` rounds with the variants interleaved after one untimed
/// render each (pipelines, buffers). Refused where the plan leaves a reconstruction out
/// (a shadow model that samples no shadow rays).
pub fn bench_reconstructions(
    gpu: &mut GpuTracer,
    e: &Experiment,
    reconstructions: &[&'static Reconstruction],
    sizes: &[u32],
    runs: usize,
) -> Result<Vec<FilterRow>> {
    let mut rows = Vec::new();
    for &size in sizes {
        let plain = RenderSettings {
            width: size,
            height: size,
            spp: 1,
            ..e.settings.clone()
        };
        let variants: Vec<RenderSettings> = std::iter::once(plain.clone())
            .chain(reconstructions.iter().map(|&r| {
                let mut s = plain.clone();
                s.features.reconstruction = r;
                s
            }))
            .collect();
        for s in &variants {
            let plan = crate::plan::Plan::new(&e.scene, s);
            if plan.reconstruction != s.features.reconstruction {
                bail!(
                    "{}: the plan leaves the reconstruction {} out ({}); choose a shadow \
                     model that samples, --set features.shadow_model=ratio",
                    e.name,
                    s.features.reconstruction.name,
                    plan.reasons.join("; ")
                );
            }
            gpu.render(&e.scene, s)?;
        }
        let mut frame: Vec<Vec<Duration>> = vec![Vec::new(); variants.len()];
        let mut filter: Vec<Vec<Duration>> = vec![Vec::new(); variants.len()];
        for _ in 0..runs.max(1) {
            for (i, s) in variants.iter().enumerate() {
                let out = gpu.render(&e.scene, s)?;
                frame[i].push(gpu.last_gpu_time().unwrap_or(out.trace_time));
                filter[i].push(gpu.last_filter_time());
            }
        }
        let ms = |t: &[Duration]| super::median(t.to_vec()).as_secs_f64() * 1e3;
        for (k, r) in reconstructions.iter().enumerate() {
            rows.push(FilterRow {
                experiment: e.name.clone(),
                reconstruction: r.name,
                size,
                plain_ms: ms(&frame[0]),
                filtered_ms: ms(&frame[k + 1]),
                filter_ms: ms(&filter[k + 1]),
                time_ratio: super::Ratio::of_times(&frame[k + 1], &frame[0], true),
            });
        }
    }
    Ok(rows)
}

pub fn filter_table(rows: &[FilterRow]) -> String {
    let mut out = String::from(
        "| experiment | reconstruction | image | frame ms, none | frame ms, filtered | filter passes ms | filtered / none (round by round) |\n\
         |---|---|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        out += &format!(
            "| {} | {} | {}x{} | {:.1} | {:.1} | {:.1} | {} |\n",
            r.experiment,
            r.reconstruction,
            r.size,
            r.size,
            r.plain_ms,
            r.filtered_ms,
            r.filter_ms,
            r.time_ratio.cell()
        );
    }
    out
}
