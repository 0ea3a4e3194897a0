//! An external reference (`[ablate] reference = "path.exr"`, `reference_by`): a
//! converged image another renderer made (Mitsuba 3 from `voxlab export`, say). Every
//! point of the experiment's own scene is measured against it too, and the distance of
//! voxlab's own reference to it is reported as that reference's bias: a bias of
//! voxlab's estimator, or of the scene's export, shows there and nowhere else.

use anyhow::{Result, bail};

use super::{ExternalSpec, Reference, Row};
use crate::frame::Frame;
use crate::metrics::{Domain, compare, flip};

/// A checked external reference and voxlab's reference measured against it.
#[derive(Clone, Debug)]
pub struct External {
    pub spec: ExternalSpec,
    pub frame: Frame,
    /// blake3 of the file's bytes, for the records.
    pub blake3: String,
    /// RMSE of voxlab's own reference against it.
    pub bias_rmse: f64,
    /// Mean signed difference, voxlab's reference minus the external one, per channel.
    pub bias_mean: [f64; 3],
    /// FLIP mean of voxlab's reference against it.
    pub bias_flip: f64,
}

impl External {
    /// One line for logs and tables.
    pub(crate) fn bias_line(&self, own: &Reference) -> String {
        format!(
            "voxlab's reference ({} spp, {}) against {}: RMSE {:.3e} (its own noise {:.3e}), \
             mean difference ({:+.3e}, {:+.3e}, {:+.3e}), FLIP {:.4}",
            own.spp,
            own.backend,
            self.spec.by,
            self.bias_rmse,
            own.noise_rmse,
            self.bias_mean[0],
            self.bias_mean[1],
            self.bias_mean[2],
            self.bias_flip
        )
    }
}

/// Reads and checks the external reference: an OpenEXR of the experiment's size whose
/// every value is finite and >= 0 (linear radiance); each refusal names the file and
/// the key.
/// The bias fields stay 0 until [`External::measure`].
pub fn load(spec: &ExternalSpec, width: u32, height: u32) -> Result<External> {
    let path = &spec.path;
    let bytes = crate::input::read_file(path, 1 << 30, "reference image")
        .map_err(|e| anyhow::anyhow!("ablate.reference = {}: {e}", path.display()))?;
    let frame = crate::output::read_exr(path)
        .map_err(|e| anyhow::anyhow!("ablate.reference = {}: {e}", path.display()))?;
    if (frame.width, frame.height) != (width, height) {
        bail!(
            "ablate.reference = {}: {}x{} pixels; the experiment renders {width}x{height}",
            path.display(),
            frame.width,
            frame.height
        );
    }
    if let Some((i, p)) = frame
        .pixels
        .iter()
        .enumerate()
        .find(|(_, p)| p.iter().any(|v| !v.is_finite() || *v < 0.0))
    {
        bail!(
            "ablate.reference = {}: pixel ({}, {}) is {:?}; a reference is linear radiance, \
             every value finite and >= 0",
            path.display(),
            i as u32 % width,
            i as u32 / width,
            p
        );
    }
    Ok(External {
        spec: spec.clone(),
        blake3: blake3::hash(&bytes).to_hex().to_string(),
        frame,
        bias_rmse: 0.0,
        bias_mean: [0.0; 3],
        bias_flip: 0.0,
    })
}

impl External {
    /// Measures voxlab's own reference against this one.
    pub fn measure(&mut self, own: &Reference) {
        let d = compare(&own.frame, &self.frame, Domain::Linear, 0.0).expect("same size");
        let n = self.frame.pixels.len().max(1) as f64;
        let mut mean = [0.0; 3];
        for (a, b) in own.frame.pixels.iter().zip(&self.frame.pixels) {
            for k in 0..3 {
                mean[k] += (f64::from(a[k]) - f64::from(b[k])) / n;
            }
        }
        self.bias_rmse = d.rmse;
        self.bias_mean = mean;
        self.bias_flip = flip(&self.frame, &own.frame).0;
    }
}

/// A point's errors against the external reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Errors {
    pub rmse: f64,
    pub psnr: f64,
    pub flip_mean: f64,
    pub flip8_mean: f64,
}

/// `frame`'s errors against the external reference (as `point_row` measures them
/// against voxlab's).
pub fn errors(ext: &External, frame: &Frame) -> Errors {
    let d =
        compare(&ext.frame, frame, Domain::Linear, 0.0).expect("a point has the reference's size");
    Errors {
        rmse: d.rmse,
        psnr: d.psnr,
        flip_mean: flip(&ext.frame, frame).0,
        flip8_mean: crate::metrics::flip_8bit(&ext.frame, frame),
    }
}

/// The rows measured against the external reference: every row of the experiment's own
/// scene (not the curves with scenes of their own), its errors replaced. The noise of
/// an external reference is unknown, so `rmse_corrected` is the RMSE itself.
pub fn rows(rows: &[Row]) -> Vec<Row> {
    rows.iter()
        .filter_map(|r| {
            let x = r.external?;
            Some(Row {
                rmse: x.rmse,
                rmse_corrected: x.rmse,
                psnr: x.psnr,
                flip_mean: x.flip_mean,
                flip8_mean: x.flip8_mean,
                ..r.clone()
            })
        })
        .collect()
}
