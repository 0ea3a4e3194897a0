//! Writing frames to image files, and reading them back (tests, golden images).
//!
//! - `.png`: the displayed value, as the seed's framebuffer stored it: radiance clamped
//!   to [0, 1], 8 bits, no tone mapping and no gamma (`Frame::to_rgb8`).
//! - `.exr`: linear f32 RGB radiance, unclamped, for analysis.
//!
//! Files are written to a temporary file in the target directory and renamed into
//! place, so a failed write never leaves a partial image under the requested name.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use image::{ImageFormat, Rgb32FImage, RgbImage};

use crate::render::Frame;

/// The file formats a frame can be written as, chosen by the path's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    /// 8-bit clamped colour.
    Png,
    /// Linear f32 radiance.
    Exr,
}

impl OutputFormat {
    /// The format for `path`'s extension (case-insensitive), or an error naming the path.
    pub fn from_path(path: &Path) -> Result<Self, OutputError> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("png") => Ok(Self::Png),
            Some("exr") => Ok(Self::Exr),
            _ => Err(OutputError::UnknownExtension {
                path: path.to_path_buf(),
            }),
        }
    }

    fn image_format(self) -> ImageFormat {
        match self {
            Self::Png => ImageFormat::Png,
            Self::Exr => ImageFormat::OpenExr,
        }
    }
}

/// Every variant holds its cause in `error`, not `source`: the message already includes
/// it, and a `source` would print it twice through anyhow's `{:#}`.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error(
        "cannot write {}: unknown image extension; use .png (8-bit, clamped) or .exr (linear radiance)",
        path.display()
    )]
    UnknownExtension { path: PathBuf },
    #[error("cannot create directory {} for {}: {error}", dir.display(), path.display())]
    CreateDir {
        dir: PathBuf,
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("cannot write {}: {}", path.display(), encoding_text(error))]
    Write {
        path: PathBuf,
        error: image::ImageError,
    },
    #[error("cannot write {}: {error}", path.display())]
    WriteFile {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("cannot write {}: {error}", path.display())]
    Rename {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("cannot read {}: {error}", path.display())]
    Read {
        path: PathBuf,
        error: image::ImageError,
    },
    #[error("cannot read {}: {error}", path.display())]
    Open {
        path: PathBuf,
        error: std::io::Error,
    },
}

/// An encoder's error as what it is: the image crate reports some failures of its EXR
/// encoder as decoding errors ("Format error decoding OpenExr"), which reads wrongly
/// while writing.
fn encoding_text(e: &image::ImageError) -> String {
    match e {
        image::ImageError::Decoding(d) => match std::error::Error::source(d) {
            Some(inner) => format!("the {:?} encoder failed: {inner}", d.format_hint()),
            None => format!("the {:?} encoder failed", d.format_hint()),
        },
        other => other.to_string(),
    }
}

/// Writes `frame` to `path` in the format its extension names (`.png` or `.exr`),
/// creating missing parent directories. Nothing appears under `path` unless the whole
/// image was written.
pub fn write_frame(frame: &Frame, path: impl AsRef<Path>) -> Result<(), OutputError> {
    let path = path.as_ref();
    let format = OutputFormat::from_path(path)?;
    write_atomically(path, |tmp| {
        let written = match format {
            OutputFormat::Png => {
                let img = RgbImage::from_raw(frame.width, frame.height, frame.to_rgb8())
                    .expect("a Frame holds width * height pixels");
                img.save_with_format(tmp, format.image_format())
            }
            OutputFormat::Exr => {
                let data = frame.pixels.iter().flatten().copied().collect();
                let img = Rgb32FImage::from_raw(frame.width, frame.height, data)
                    .expect("a Frame holds width * height pixels");
                img.save_with_format(tmp, format.image_format())
            }
        };
        written.map_err(|error| OutputError::Write {
            path: path.to_path_buf(),
            error,
        })
    })
}

/// The PNG text chunk (iTXt) that holds a render's provenance record.
pub const PROVENANCE_KEYWORD: &str = "voxlab";

/// [`write_frame`] with the PNG's values under `display` (an EXR stays linear radiance),
/// and the provenance record `json` (what made the image: the resolved
/// experiment, revision, adapter, settings, timings, plan) stored with it: in a PNG as
/// the iTXt chunk [`PROVENANCE_KEYWORD`], and for either format in the sidecar
/// `<path>.json`, written the same way (complete or not at all).
pub fn write_frame_with_provenance(
    frame: &Frame,
    path: impl AsRef<Path>,
    json: &str,
    display: crate::render::DisplayTransform,
) -> Result<(), OutputError> {
    let path = path.as_ref();
    let format = OutputFormat::from_path(path)?;
    match format {
        OutputFormat::Exr => write_frame(frame, path)?,
        OutputFormat::Png => write_atomically(path, |tmp| {
            let io = |error| OutputError::WriteFile {
                path: path.to_path_buf(),
                error,
            };
            let file = File::create(tmp).map_err(io)?;
            let encoding = |e: png::EncodingError| {
                io(std::io::Error::other(format!(
                    "the PNG encoder failed: {e}"
                )))
            };
            let mut encoder =
                png::Encoder::new(std::io::BufWriter::new(file), frame.width, frame.height);
            encoder.set_color(png::ColorType::Rgb);
            encoder.set_depth(png::BitDepth::Eight);
            encoder
                .add_itxt_chunk(PROVENANCE_KEYWORD.to_string(), json.to_string())
                .map_err(encoding)?;
            let mut writer = encoder.write_header().map_err(encoding)?;
            writer
                .write_image_data(&frame.to_display_rgb8(display))
                .map_err(encoding)?;
            writer.finish().map_err(encoding)
        })?,
    }
    let mut sidecar = path.as_os_str().to_os_string();
    sidecar.push(".json");
    write_file(PathBuf::from(sidecar), json.as_bytes())
}

/// The provenance record stored in a PNG written by [`write_frame_with_provenance`].
pub fn read_png_provenance(path: impl AsRef<Path>) -> Result<Option<String>, OutputError> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|error| OutputError::Open {
        path: path.to_path_buf(),
        error,
    })?;
    let decoder = png::Decoder::new(BufReader::new(file));
    let reader = decoder.read_info().map_err(|e| OutputError::Open {
        path: path.to_path_buf(),
        error: std::io::Error::other(e.to_string()),
    })?;
    let text = reader
        .info()
        .utf8_text
        .iter()
        .find(|c| c.keyword == PROVENANCE_KEYWORD)
        .and_then(|c| c.get_text().ok());
    Ok(text)
}

/// Writes `bytes` to `path` the way `write_frame` writes images: parent directories
/// created, a temporary file renamed into place, so a failed write leaves nothing under
/// `path` (the viewer's exported experiment files and window captures).
pub fn write_file(path: impl AsRef<Path>, bytes: &[u8]) -> Result<(), OutputError> {
    let path = path.as_ref();
    write_atomically(path, |tmp| {
        std::fs::write(tmp, bytes).map_err(|error| OutputError::WriteFile {
            path: path.to_path_buf(),
            error,
        })
    })
}

/// Creates `path`'s directory, lets `write` fill a temporary file beside `path`, and
/// renames it into place; on any failure the temporary file is removed.
fn write_atomically(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), OutputError>,
) -> Result<(), OutputError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&dir).map_err(|error| OutputError::CreateDir {
        dir: dir.clone(),
        path: path.to_path_buf(),
        error,
    })?;
    let tmp = temp_path(&dir, path);
    let _pending = Pending::new(&tmp);
    if let Err(e) = write(&tmp) {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    std::fs::rename(&tmp, path).map_err(|error| {
        let _ = std::fs::remove_file(&tmp);
        OutputError::Rename {
            path: path.to_path_buf(),
            error,
        }
    })
}

/// Temporary files being written right now, removed by [`remove_temporaries_on_interrupt`]'s
/// handler if the process is interrupted (Ctrl-C) before they are renamed.
static PENDING: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// A temporary file registered in [`PENDING`] for as long as this lives.
struct Pending(PathBuf);

impl Pending {
    fn new(tmp: &Path) -> Self {
        if let Ok(mut p) = PENDING.lock() {
            p.push(tmp.to_path_buf());
        }
        Self(tmp.to_path_buf())
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if let Ok(mut p) = PENDING.lock() {
            p.retain(|x| x != &self.0);
        }
    }
}

/// Installs a SIGINT/SIGTERM handler (once per process; the binary calls it at start)
/// that removes every temporary output file still being written and exits with status
/// 130: an interrupted write leaves neither a half-written output nor a hidden
/// temporary file. Err when another handler is already installed.
pub fn remove_temporaries_on_interrupt() -> Result<(), String> {
    ctrlc::set_handler(|| {
        if let Ok(p) = PENDING.lock() {
            for tmp in p.iter() {
                let _ = std::fs::remove_file(tmp);
            }
        }
        eprintln!("voxlab: interrupted; no partial output left behind");
        std::process::exit(130);
    })
    .map_err(|e| e.to_string())
}

/// A hidden name in the target's directory (a rename across file systems is not atomic),
/// unique per process and call so concurrent writers never share one.
fn temp_path(dir: &Path, path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "frame".to_string());
    // The format is passed explicitly, so the temporary suffix need not be an image one.
    // Short and fixed in length: an output name of 250-255 bytes (the file-name limit)
    // must not make its temporary name too long. The first characters of the name say
    // whose it is.
    let head: String = name.chars().take(32).collect();
    dir.join(format!(".{head}.{}.{n}.tmp", std::process::id()))
}

fn read(path: &Path, format: ImageFormat) -> Result<image::DynamicImage, OutputError> {
    let file = File::open(path).map_err(|error| OutputError::Open {
        path: path.to_path_buf(),
        error,
    })?;
    image::load(BufReader::new(file), format).map_err(|error| OutputError::Read {
        path: path.to_path_buf(),
        error,
    })
}

/// Reads a PNG into a frame with values `byte / 255` (what `write_frame` stored, so a
/// round trip gives the clamped, 8-bit-quantised frame).
pub fn read_png(path: impl AsRef<Path>) -> Result<Frame, OutputError> {
    let img = read(path.as_ref(), ImageFormat::Png)?.to_rgb8();
    Ok(Frame {
        width: img.width(),
        height: img.height(),
        pixels: img
            .pixels()
            .map(|p| p.0.map(|c| f32::from(c) / 255.0))
            .collect(),
    })
}

/// Reads an EXR's RGB channels as linear radiance (bit-exact for what `write_frame` wrote).
pub fn read_exr(path: impl AsRef<Path>) -> Result<Frame, OutputError> {
    let img = read(path.as_ref(), ImageFormat::OpenExr)?.into_rgb32f();
    Ok(Frame {
        width: img.width(),
        height: img.height(),
        pixels: img.pixels().map(|p| p.0).collect(),
    })
}

/// Reads a `.png` or `.exr` by its extension.
pub fn read_frame(path: impl AsRef<Path>) -> Result<Frame, OutputError> {
    let path = path.as_ref();
    match OutputFormat::from_path(path)? {
        OutputFormat::Png => read_png(path),
        OutputFormat::Exr => read_exr(path),
    }
}
