//! `voxlab bench --cutoffs`: what the ray cutoff (`crate::ray_cutoff`) saves and costs on
//! each experiment, against its exact tree, so the default can be chosen by
//! measurement: rays traced, time per frame (exact and cut frames interleaved, medians),
//! and the error in display values (the 8-bit image a viewer sees).

use std::time::Duration;

use anyhow::Result;

use crate::experiment::Experiment;
use crate::gpu::GpuTracer;
use crate::render::RenderSettings;

/// One experiment at one cutoff (the exact tree is the cutoff-0 row).
#[derive(Clone, Debug)]
pub struct CutoffRow {
    pub experiment: String,
    pub cutoff: f64,
    pub rays: u64,
    pub shadow_rays: u64,
    pub exact_rays: u64,
    pub ms: f64,
    pub exact_ms: f64,
    /// The cut frame's time over the exact one's, round by round (interleaved).
    pub time_ratio: super::Ratio,
    /// Largest and mean difference from the exact tree's image, display levels (of 255,
    /// any channel).
    pub max_levels: u8,
    pub mean_levels: f64,
}

impl CutoffRow {
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "experiment": self.experiment,
            "ray_cutoff": self.cutoff,
            "rays": self.rays,
            "shadow_rays": self.shadow_rays,
            "exact_rays": self.exact_rays,
            "ms_per_frame": self.ms,
            "exact_ms_per_frame": self.exact_ms,
            "time_cut_over_exact": self.time_ratio.json(),
            "max_error_levels": self.max_levels,
            "mean_error_levels": self.mean_levels,
        })
    }
}

/// Each experiment at `size` x `size`, one frame (the sampled models' samples are the
/// same in every variant, so the difference is the cut alone), at cutoff 0 and each of
/// `cutoffs`: a counted frame each for the rays and the image, then `runs` timed rounds
/// with the variants interleaved.
pub fn bench_cutoffs(
    gpu: &mut GpuTracer,
    experiments: &[Experiment],
    cutoffs: &[f64],
    size: u32,
    runs: usize,
    mut progress: impl FnMut(&CutoffRow),
) -> Result<Vec<CutoffRow>> {
    let mut rows = Vec::new();
    for e in experiments {
        let variants: Vec<RenderSettings> = std::iter::once(0.0)
            .chain(cutoffs.iter().copied())
            .map(|c| RenderSettings {
                width: size,
                height: size,
                spp: 1,
                ray_cutoff: c,
                ..e.settings.clone()
            })
            .collect();
        let mut counted = Vec::new();
        for s in &variants {
            let out = gpu.render_counted(&e.scene, s)?;
            // The plain pipeline, built before the timed rounds.
            gpu.render(&e.scene, s)?;
            counted.push(out);
        }
        let mut times: Vec<Vec<Duration>> = vec![Vec::new(); variants.len()];
        for _ in 0..runs.max(1) {
            for (s, t) in variants.iter().zip(&mut times) {
                let out = gpu.render(&e.scene, s)?;
                t.push(gpu.last_gpu_time().unwrap_or(out.trace_time));
            }
        }
        let ms: Vec<f64> = times
            .iter()
            .map(|t| super::median(t.clone()).as_secs_f64() * 1e3)
            .collect();
        let exact = counted[0].frame.to_rgb8();
        for (i, (out, s)) in counted.iter().zip(&variants).enumerate().skip(1) {
            let cut = out.frame.to_rgb8();
            let diffs = exact.iter().zip(&cut).map(|(a, b)| a.abs_diff(*b));
            let max_levels = diffs.clone().max().unwrap_or(0);
            let mean_levels = diffs.map(f64::from).sum::<f64>() / exact.len().max(1) as f64;
            let row = CutoffRow {
                experiment: e.name.clone(),
                cutoff: s.ray_cutoff,
                rays: out.stats.total_rays(),
                shadow_rays: out.stats.shadow,
                exact_rays: counted[0].stats.total_rays(),
                ms: ms[i],
                exact_ms: ms[0],
                time_ratio: super::Ratio::of_times(&times[i], &times[0], true),
                max_levels,
                mean_levels,
            };
            progress(&row);
            rows.push(row);
        }
    }
    Ok(rows)
}

/// The largest cutoff at which every experiment stays within `levels` display levels of
/// its exact tree, and every smaller cutoff measured does too.
pub fn largest_within(rows: &[CutoffRow], cutoffs: &[f64], levels: u8) -> Option<f64> {
    let mut sorted = cutoffs.to_vec();
    sorted.sort_by(f64::total_cmp);
    let mut best = None;
    for c in sorted {
        let ok = rows
            .iter()
            .filter(|r| r.cutoff == c)
            .all(|r| r.max_levels <= levels);
        if !ok {
            break;
        }
        best = Some(c);
    }
    best
}

pub fn cutoff_table(rows: &[CutoffRow]) -> String {
    let mut out = String::from(
        "| experiment | ray_cutoff | rays | of exact | shadow rays | ms/frame | exact ms | time saved (round by round) | max error (levels) | mean error (levels) |\n\
         |---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        out += &format!(
            "| {} | {} | {} | {:.1} % | {} | {:.1} | {:.1} | {} | {} | {:.4} |\n",
            r.experiment,
            r.cutoff,
            r.rays,
            100.0 * r.rays as f64 / r.exact_rays.max(1) as f64,
            r.shadow_rays,
            r.ms,
            r.exact_ms,
            saved(&r.time_ratio),
            r.max_levels,
            r.mean_levels
        );
    }
    out
}

/// The time a cut saves, as a percentage of the exact frame's, with its range over the
/// rounds: `12 % (8 to 15 %)`, and `, noise` where the range holds none saved.
fn saved(r: &super::Ratio) -> String {
    let pct = |x: f64| 100.0 * (1.0 - x);
    format!(
        "{:.0} % ({:.0} to {:.0} %{})",
        pct(r.median),
        pct(r.hi),
        pct(r.lo),
        if r.within_noise() { ", noise" } else { "" }
    )
}
