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

use image::{ImageFormat, RgbImage};

use crate::frame::Frame;

/// A size in bytes as printed output gives it (a walk's data, a stress case's grid): B, KiB or MiB, one decimal.
pub fn bytes_text(b: u64) -> String {
    if b >= 1 << 20 {
        format!("{:.1} MiB", b as f64 / (1u64 << 20) as f64)
    } else if b >= 1 << 10 {
        format!("{:.1} KiB", b as f64 / 1024.0)
    } else {
        format!("{b} B")
    }
}

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
    #[error(
        "cannot write {}: its file name is {len} bytes, and this file system allows at most {max}",
        path.display()
    )]
    NameTooLong {
        path: PathBuf,
        len: usize,
        max: usize,
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

impl OutputError {
    /// Why, without the path: for a caller whose own message names the file.
    pub fn cause(&self) -> String {
        match self {
            Self::CreateDir { dir, error, .. } => {
                format!("cannot create directory {}: {error}", dir.display())
            }
            Self::WriteFile { error, .. }
            | Self::Rename { error, .. }
            | Self::Open { error, .. } => error.to_string(),
            Self::Write { error, .. } => encoding_text(error),
            Self::Read { error, .. } => error.to_string(),
            Self::NameTooLong { len, max, .. } => {
                format!("its file name is {len} bytes, and this file system allows at most {max}")
            }
            Self::UnknownExtension { .. } => self.to_string(),
        }
    }
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
    write_together(vec![(path.to_path_buf(), frame_fill(frame, path)?)])
}

/// The [`Fill`] of [`write_frame`]: `frame` in the format `path`'s extension names.
pub(crate) fn frame_fill<'a>(frame: &'a Frame, path: &Path) -> Result<Fill<'a>, OutputError> {
    let format = OutputFormat::from_path(path)?;
    let path = path.to_path_buf();
    Ok(Box::new(move |tmp: &Path| match format {
        OutputFormat::Png => {
            let img = RgbImage::from_raw(frame.width, frame.height, frame.to_rgb8())
                .expect("a Frame holds width * height pixels");
            img.save_with_format(tmp, format.image_format())
                .map_err(|error| OutputError::Write { path, error })
        }
        OutputFormat::Exr => write_exr(frame, &path, tmp),
    }))
}

/// Linear RGB f32 as a scanline EXR (ZIP, 16 lines a block, increasing Y): the layout
/// every reader takes. The image crate's encoder writes 64x64 RLE tiles, which some
/// readers (NVIDIA's flip-evaluator 1.7, through tinyexr) crash on.
fn write_exr(frame: &Frame, path: &Path, tmp: &Path) -> Result<(), OutputError> {
    use exr::prelude::{Encoding, Image, SpecificChannels, Vec2, WritableImage};
    let (w, h) = (frame.width as usize, frame.height as usize);
    let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
        let [r, g, b] = frame.pixels[p.y() * w + p.x()];
        (r, g, b)
    });
    Image::from_encoded_channels((w, h), Encoding::SMALL_LOSSLESS, channels)
        .write()
        .to_file(tmp)
        .map_err(|e| OutputError::WriteFile {
            path: path.to_path_buf(),
            error: std::io::Error::other(format!("the EXR encoder failed: {e}")),
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
    display: crate::frame::DisplayTransform,
) -> Result<(), OutputError> {
    // The image and its record appear together or not at all.
    write_together(frame_with_provenance_fills(
        frame,
        path.as_ref(),
        json,
        display,
    )?)
}

/// The [`Fill`]s of [`write_frame_with_provenance`]: the image, then its sidecar, for a
/// caller that writes them with other files as one output.
pub(crate) fn frame_with_provenance_fills<'a>(
    frame: &'a Frame,
    path: &Path,
    json: &'a str,
    display: crate::frame::DisplayTransform,
) -> Result<Vec<(PathBuf, Fill<'a>)>, OutputError> {
    let format = OutputFormat::from_path(path)?;
    let sidecar = sidecar_path(path);
    let at = path.to_path_buf();
    let image = move |tmp: &Path| match format {
        OutputFormat::Exr => write_exr(frame, &at, tmp),
        OutputFormat::Png => {
            let io = |error| OutputError::WriteFile {
                path: at.clone(),
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
        }
    };
    Ok(vec![
        (path.to_path_buf(), Box::new(image) as Fill),
        (sidecar.clone(), bytes_fill(&sidecar, json.as_bytes())),
    ])
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

/// Refuses a command's output directory that is an existing file, before the command
/// does any work (a stress run takes minutes): `option` names the option that gave it
/// (as [`given`] writes it), `writes` what the command writes there.
pub fn check_directory_output(option: &str, dir: &Path, writes: &str) -> Result<(), String> {
    if dir.exists() && !dir.is_dir() {
        return Err(format!(
            "{}: {writes}, and this is a file",
            given(option, dir)
        ));
    }
    Ok(())
}

/// An option and its value as the user wrote them, for messages: `--out DIR` on the
/// command line, `out=DIR` for a keyword argument (an option not starting with `-`),
/// `DIR` alone for a positional argument (no option).
pub fn given(option: &str, value: &Path) -> String {
    if option.is_empty() {
        value.display().to_string()
    } else if option.starts_with('-') {
        format!("{option} {}", value.display())
    } else {
        format!("{option}={}", value.display())
    }
}

/// `<path>.json`: where the provenance record of the output `path` goes.
pub fn sidecar_path(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(".json");
    PathBuf::from(s)
}

/// A file an output was made from, as its record names it: the path and the blake3
/// hash of the bytes; `None` when it cannot be read.
pub(crate) fn file_record(path: &Path) -> Option<serde_json::Value> {
    let file = File::open(path).ok()?;
    let mut h = blake3::Hasher::new();
    h.update_reader(file).ok()?;
    Some(
        serde_json::json!({"path": path.display().to_string(), "blake3": h.finalize().to_hex().to_string()}),
    )
}

/// The record of an output made by `made_by` (`"voxlab voxelize"`) from `inputs`: the
/// build's revision, each input's path and hash, and the command's own `fields` (an
/// object, merged in).
pub fn record(made_by: &str, inputs: &[&Path], fields: serde_json::Value) -> serde_json::Value {
    let mut r = serde_json::json!({
        "made_by": made_by,
        "revision": crate::revision::revision(),
        "inputs": inputs.iter().filter_map(|p| file_record(p)).collect::<Vec<_>>(),
    });
    if let (Some(map), serde_json::Value::Object(extra)) = (r.as_object_mut(), fields) {
        map.extend(extra);
    }
    r
}

/// Writes `record` beside the output `path`, which was just written (`<path>.json`),
/// complete or not at all; when it cannot be written `path` is removed as well, so no
/// output is left without its record.
pub fn write_sidecar(path: &Path, record: &serde_json::Value) -> Result<(), OutputError> {
    let text = serde_json::to_string_pretty(record).expect("a JSON value serialises");
    let result = write_file(sidecar_path(path), text.as_bytes());
    if result.is_err() {
        let _ = std::fs::remove_file(path);
    }
    result
}

/// Writes `bytes` to `path` the way `write_frame` writes images: parent directories
/// created, a temporary file renamed into place, so a failed write leaves nothing under
/// `path` (the viewer's exported experiment files and window captures).
pub(crate) fn write_file(path: impl AsRef<Path>, bytes: &[u8]) -> Result<(), OutputError> {
    let path = path.as_ref();
    write_together(vec![(path.to_path_buf(), bytes_fill(path, bytes))])
}

/// What fills one temporary file of [`write_together`].
pub type Fill<'a> = Box<dyn FnOnce(&Path) -> Result<(), OutputError> + 'a>;

/// A [`Fill`] that writes `bytes`, blaming `path` for a failure.
pub fn bytes_fill<'a>(path: &Path, bytes: &'a [u8]) -> Fill<'a> {
    let path = path.to_path_buf();
    Box::new(move |tmp: &Path| {
        std::fs::write(tmp, bytes).map_err(|error| OutputError::WriteFile { path, error })
    })
}

/// Writes several files as one output (an image and its record, an OBJ and its MTL):
/// every name is checked first, each file is filled under a temporary name beside its
/// own, and only when all are complete are they renamed into place. Missing parent
/// directories are created. A failure at any point, or an interrupt (the handler of
/// [`remove_temporaries_on_interrupt`] waits for the renames), leaves none of them:
/// those already renamed are removed again, and so are the directories this call
/// created, where they are still empty.
pub fn write_together(files: Vec<(PathBuf, Fill<'_>)>) -> Result<(), OutputError> {
    for (path, _) in &files {
        check_name(path)?;
    }
    let mut written = Vec::with_capacity(files.len());
    let mut guards = Vec::with_capacity(files.len());
    // Deepest first, so they can be removed in order.
    let mut made_dirs: Vec<PathBuf> = Vec::new();
    let clean = |written: &[(PathBuf, PathBuf)], made_dirs: &[PathBuf]| {
        for (_, tmp) in written {
            let _ = std::fs::remove_file(tmp);
        }
        remove_empty_dirs(made_dirs);
    };
    for (path, fill) in files {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let missing = missing_dirs(&dir);
        let created = std::fs::create_dir_all(&dir);
        // Registered before the error is looked at: a failed create_dir_all may have made
        // the upper ones.
        for d in missing.into_iter().rev() {
            guards.push(Pending::new_dir(&d));
            made_dirs.insert(0, d);
        }
        if let Err(error) = created {
            clean(&written, &made_dirs);
            return Err(OutputError::CreateDir { dir, path, error });
        }
        let tmp = temp_path(&dir, &path);
        guards.push(Pending::new(&tmp));
        let filled = fill(&tmp);
        written.push((path, tmp));
        if let Err(e) = filled {
            clean(&written, &made_dirs);
            return Err(e);
        }
    }
    // The interrupt handler takes this lock before it removes the temporaries: it never
    // runs between two renames.
    let _renaming = PENDING.lock();
    for (k, (path, tmp)) in written.iter().enumerate() {
        if let Err(error) = std::fs::rename(tmp, path) {
            for (done, _) in &written[..k] {
                let _ = std::fs::remove_file(done);
            }
            clean(&written[k..], &made_dirs);
            return Err(OutputError::Rename {
                path: path.clone(),
                error,
            });
        }
    }
    drop(_renaming);
    drop(guards);
    Ok(())
}

/// The directories `dir` and its ancestors that do not exist, deepest first: what
/// `create_dir_all(dir)` would make.
fn missing_dirs(dir: &Path) -> Vec<PathBuf> {
    let mut missing = Vec::new();
    let mut d = Some(dir);
    while let Some(p) = d.filter(|p| !p.as_os_str().is_empty()) {
        if p.symlink_metadata().is_ok() {
            break;
        }
        missing.push(p.to_path_buf());
        d = p.parent();
    }
    missing
}

/// Removes `dirs` in order (deepest first), each only where it is empty: another
/// writer's files in a directory keep it.
fn remove_empty_dirs(dirs: &[PathBuf]) {
    for d in dirs {
        let _ = std::fs::remove_dir(d);
    }
}

/// Refuses a file name longer than its directory's file system allows, before anything
/// is written (the temporary names are short, so only the final rename would fail).
fn check_name(path: &Path) -> Result<(), OutputError> {
    let len = path.file_name().map_or(0, |n| n.len());
    let max = name_max(path.parent().filter(|d| !d.as_os_str().is_empty()));
    if len > max {
        return Err(OutputError::NameTooLong {
            path: path.to_path_buf(),
            len,
            max,
        });
    }
    Ok(())
}

/// The longest file name the directory's file system takes (`pathconf(_PC_NAME_MAX)`,
/// asked of the nearest directory that exists); 255 (Linux's NAME_MAX) where it cannot
/// say.
fn name_max(dir: Option<&Path>) -> usize {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let mut d = dir.unwrap_or(Path::new("."));
        while !d.is_dir() {
            match d.parent() {
                Some(p) if !p.as_os_str().is_empty() => d = p,
                _ => {
                    d = Path::new(".");
                    break;
                }
            }
        }
        if let Ok(c) = std::ffi::CString::new(d.as_os_str().as_bytes()) {
            // SAFETY: a valid NUL-terminated path; pathconf only reads it.
            let n = unsafe { libc::pathconf(c.as_ptr(), libc::_PC_NAME_MAX) };
            if n > 0 {
                return n as usize;
            }
        }
    }
    let _ = dir;
    255
}

/// Temporary files being written right now, and the directories made for them (`true`),
/// removed by [`remove_temporaries_on_interrupt`]'s handler if the process is
/// interrupted (Ctrl-C) before they are renamed.
static PENDING: std::sync::Mutex<Vec<(PathBuf, bool)>> = std::sync::Mutex::new(Vec::new());

/// A temporary file or a directory made for one, registered in [`PENDING`] for as long
/// as this lives.
struct Pending((PathBuf, bool));

impl Pending {
    fn register(entry: (PathBuf, bool)) -> Self {
        if let Ok(mut p) = PENDING.lock() {
            p.push(entry.clone());
        }
        Self(entry)
    }

    fn new(tmp: &Path) -> Self {
        Self::register((tmp.to_path_buf(), false))
    }

    fn new_dir(dir: &Path) -> Self {
        Self::register((dir.to_path_buf(), true))
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if let Ok(mut p) = PENDING.lock() {
            // One entry: two writers may have registered the same directory.
            if let Some(k) = p.iter().rposition(|x| x == &self.0) {
                p.remove(k);
            }
        }
    }
}

/// Installs a SIGINT/SIGTERM handler (once per process; the binary calls it at start)
/// that removes every temporary output file still being written, and the directories
/// made for them where they are empty, and exits with status 130: an interrupted write
/// leaves neither a half-written output, nor a hidden temporary file, nor a new empty
/// directory. Err when another handler is already installed.
pub fn remove_temporaries_on_interrupt() -> Result<(), String> {
    ctrlc::set_handler(|| {
        if let Ok(p) = PENDING.lock() {
            for (tmp, _) in p.iter().filter(|(_, dir)| !dir) {
                let _ = std::fs::remove_file(tmp);
            }
            // Registered from the top down: the deepest go first.
            for (dir, _) in p.iter().rev().filter(|(_, dir)| *dir) {
                let _ = std::fs::remove_dir(dir);
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
