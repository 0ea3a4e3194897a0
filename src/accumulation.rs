//! What a tracer's accumulation of frames was made from, and the rule by which a
//! `Session::render_frames` call may continue it: the GPU tracer keeps its sums in
//! device buffers, a CPU session its per-pixel sums in f64; both continue only their
//! own accumulation, where it left off, and say why not otherwise.

use std::ops::Range;

use crate::plan::Plan;
use crate::render::RenderSettings;
use crate::scene::Scene;

/// What an accumulation was made from, so that a call that continues it can tell
/// whether the sums it holds are its own: each input by name with a hash of its Debug
/// text (f64 prints exactly, so equal text is equal input). The voxels are a tracer's
/// to add ([`Self::with`]): the GPU tracer's grid upload has a generation that stands
/// for them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct AccumulationKey {
    parts: Vec<(&'static str, blake3::Hash)>,
}

impl AccumulationKey {
    /// `surface`: the key of the triangle surface the render traces (what its cells
    /// were listed from, a mesh's triangles say), `None` for voxels.
    pub(crate) fn new(
        scene: &Scene,
        settings: &RenderSettings,
        plan: &Plan,
        surface: Option<blake3::Hash>,
    ) -> Self {
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
                // The triangles a surface traces (a mesh's) change no voxel.
                (
                    "surface (the triangles it traces)",
                    surface.unwrap_or_else(|| hash("voxels".to_string())),
                ),
            ],
        }
    }

    /// The key with one more input.
    pub(crate) fn with(mut self, name: &'static str, hash: blake3::Hash) -> Self {
        self.parts.push((name, hash));
        self
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

/// Whether `frames` continues the accumulation a tracer holds: `held` is its key, the
/// frames it holds (0..n) and the inputs the tracer itself knows changed since; `None`
/// where it holds none. The error says why not and where to start.
pub(crate) fn check_continuation(
    held: Option<(&AccumulationKey, u32, Vec<&'static str>)>,
    key: &AccumulationKey,
    frames: &Range<u32>,
) -> Result<(), String> {
    let f = format!("frames {}..{}", frames.start, frames.end);
    let Some((held, n, mut differs)) = held else {
        return Err(format!(
            "{f}: no accumulation to continue: this tracer's previous render was not a \
             render_frames call of an accumulating plan (any other render, or a failed \
             one, ends the accumulation); start again at frame 0"
        ));
    };
    differs.splice(0..0, key.differences(held));
    if !differs.is_empty() {
        return Err(format!(
            "{f}: cannot continue the accumulation of frames 0..{n}, which was made \
             from other inputs (changed: {}); start again at frame 0",
            differs.join(", ")
        ));
    }
    if frames.start > n {
        return Err(format!(
            "{f}: would skip frames {n}..{}: the accumulation holds frames 0..{n}, so \
             the next range must start at {n}",
            frames.start
        ));
    }
    if frames.start < n {
        return Err(format!(
            "{f}: frames {}..{n} are already accumulated (it holds frames 0..{n}), so \
             the next range must start at {n}",
            frames.start
        ));
    }
    Ok(())
}
