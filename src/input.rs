//! Reading untrusted input: only regular files, never more than a stated size, and
//! third-party parsers run where their panics cannot take the process down.
//!
//! Every loader (experiment TOML, MagicaVoxel `.vox`, OBJ and its `.mtl`, glTF and its
//! buffers) reads through [`read_file`], so `/dev/zero`, a FIFO or a directory (directly
//! or through a link) is an error at once rather than a read that never ends, and a
//! file larger than its kind allows is refused before it is read. Parsers written by
//! others (tobj, gltf, dot_vox) run inside [`guarded`]: a panic in one becomes an error
//! that names the file, and nothing is printed on the way.

use std::cell::Cell;
use std::io::Read;
use std::path::Path;
use std::sync::Once;

/// Largest experiment file read, bytes.
pub const MAX_EXPERIMENT_BYTES: u64 = 16 << 20;
/// Largest `.vox` file read, bytes.
pub(crate) const MAX_VOX_BYTES: u64 = 512 << 20;
/// Largest mesh file (OBJ, MTL, glTF, GLB or a glTF buffer) read, bytes.
pub(crate) const MAX_MESH_BYTES: u64 = 1 << 30;

/// Why an input file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The OS error alone: it already says what went wrong.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    #[error("not a regular file ({0}): only regular files are read")]
    NotRegular(&'static str),
    #[error("{size} bytes: larger than the {limit} bytes a {what} may have")]
    TooLarge {
        size: u64,
        limit: u64,
        what: &'static str,
    },
}

/// The bytes of the regular file `path` (links followed), of at most `limit` bytes;
/// `what` names the kind of file in the error.
pub fn read_file(path: &Path, limit: u64, what: &'static str) -> Result<Vec<u8>, ReadError> {
    let meta = std::fs::metadata(path)?;
    let ft = meta.file_type();
    if !ft.is_file() {
        return Err(ReadError::NotRegular(kind_of(&ft)));
    }
    if meta.len() > limit {
        return Err(ReadError::TooLarge {
            size: meta.len(),
            limit,
            what,
        });
    }
    let file = std::fs::File::open(path)?;
    // The file may grow between the check and the read: never read past the limit.
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(ReadError::TooLarge {
            size: bytes.len() as u64,
            limit,
            what,
        });
    }
    Ok(bytes)
}

fn kind_of(ft: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if ft.is_char_device() {
            return "a character device";
        }
        if ft.is_block_device() {
            return "a block device";
        }
        if ft.is_fifo() {
            return "a FIFO";
        }
        if ft.is_socket() {
            return "a socket";
        }
    }
    if ft.is_dir() {
        "a directory"
    } else {
        "not a plain file"
    }
}

thread_local! {
    /// Set while this thread runs a guarded parser: its panics are not printed.
    static QUIET: Cell<bool> = const { Cell::new(false) };
    /// The message of the last panic a guarded parser raised on this thread.
    static LAST_PANIC: Cell<Option<String>> = const { Cell::new(None) };
}

/// Installs, once, a panic hook that stays quiet on threads running [`guarded`] (and
/// keeps the message for the error) and defers to the previous hook everywhere else.
fn install_hook() {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if QUIET.with(Cell::get) {
                let message = info
                    .payload()
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| info.payload().downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "a panic without a message".to_string());
                let at = info
                    .location()
                    .map(|l| format!(" at {}:{}", l.file(), l.line()))
                    .unwrap_or_default();
                LAST_PANIC.with(|p| p.set(Some(format!("{message}{at}"))));
            } else {
                previous(info);
            }
        }));
    });
}

/// Runs a third-party parser `f`; a panic inside it becomes `Err` with its message
/// (where in the parser it happened), printed nowhere.
pub fn guarded<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    install_hook();
    let was = QUIET.with(|q| q.replace(true));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    QUIET.with(|q| q.set(was));
    result.map_err(|_| {
        LAST_PANIC
            .with(Cell::take)
            .unwrap_or_else(|| "a panic".to_string())
    })
}

/// How many more bytes this process may allocate, by the limits it actually runs
/// under: its address-space limit (RLIMIT_AS, `ulimit -v`) less what it has mapped, and
/// its cgroup's memory limit (v2 `memory.max`, v1 `memory.limit_in_bytes`) less the
/// cgroup's use. `None` where neither limits it (or the platform cannot say). A work
/// that needs more is refused before it starts, rather than aborting half-way on a
/// failed allocation.
pub fn memory_headroom() -> Option<(u64, &'static str)> {
    let mut best: Option<(u64, &'static str)> = None;
    let mut consider = |bytes: u64, what: &'static str| {
        if best.is_none_or(|(b, _)| bytes < b) {
            best = Some((bytes, what));
        }
    };
    #[cfg(unix)]
    {
        let mut lim = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: getrlimit writes the struct it is given.
        if unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut lim) } == 0
            && lim.rlim_cur != libc::RLIM_INFINITY
        {
            let mapped = std::fs::read_to_string("/proc/self/statm")
                .ok()
                .and_then(|s| s.split_whitespace().next()?.parse::<u64>().ok())
                .map_or(0, |pages| pages * page_size());
            // rlim_t is u64 on Linux, not on every unix.
            #[allow(clippy::unnecessary_cast)]
            let limit = lim.rlim_cur as u64;
            consider(
                limit.saturating_sub(mapped),
                "the address-space limit (RLIMIT_AS)",
            );
        }
    }
    let read = |p: &str| std::fs::read_to_string(p).ok();
    let number = |s: Option<String>| s.and_then(|s| s.trim().parse::<u64>().ok());
    if let Some(max) = number(read("/sys/fs/cgroup/memory.max")) {
        let used = number(read("/sys/fs/cgroup/memory.current")).unwrap_or(0);
        consider(max.saturating_sub(used), "the cgroup's memory.max");
    } else if let Some(max) = number(read("/sys/fs/cgroup/memory/memory.limit_in_bytes")) {
        // v1 says "no limit" with a number near 2^63.
        if max < 1 << 60 {
            let used = number(read("/sys/fs/cgroup/memory/memory.usage_in_bytes")).unwrap_or(0);
            consider(
                max.saturating_sub(used),
                "the cgroup's memory.limit_in_bytes",
            );
        }
    }
    best
}

#[cfg(unix)]
fn page_size() -> u64 {
    // SAFETY: sysconf has no preconditions.
    let n = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    if n > 0 { n as u64 } else { 4096 }
}

/// Refuses a work that needs `bytes` more than [`memory_headroom`] allows, with what
/// it is and which limit stops it.
pub fn check_memory(bytes: u64, what: &str) -> Result<(), String> {
    match memory_headroom() {
        Some((room, limit)) if bytes > room => Err(format!(
            "{what} needs about {bytes} bytes, and {limit} leaves this process {room}"
        )),
        _ => Ok(()),
    }
}

/// A vector of `n` copies of `v`, or an error instead of the abort a failed allocation
/// would be.
pub(crate) fn try_filled<T: Clone>(n: usize, v: T, what: &str) -> Result<Vec<T>, String> {
    let mut out = Vec::new();
    out.try_reserve_exact(n).map_err(|_| {
        format!(
            "{what}: cannot allocate {} bytes",
            n as u64 * std::mem::size_of::<T>() as u64
        )
    })?;
    out.resize(n, v);
    Ok(out)
}

/// `text` cut to at most `max` characters for an error message, with how much was cut.
pub(crate) fn excerpt(text: &str, max: usize) -> String {
    let n = text.chars().count();
    if n <= max {
        return text.to_string();
    }
    let head: String = text.chars().take(max).collect();
    format!("{head}... ({} more characters)", n - max)
}

/// A number as a message quotes it: as written where that is short (`22.4`), else in
/// exponent form (`1e300`, not the 301 digits Rust's `Display` writes).
pub fn short_number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..1e9).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// [`short_number`] of each component, as `[x, y, z]`.
pub fn short_vector(v: glam::DVec3) -> String {
    let [x, y, z] = v.to_array().map(short_number);
    format!("[{x}, {y}, {z}]")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_fifos_and_directories_are_refused_at_once() {
        for p in ["/dev/zero", "/dev/null", "/"] {
            let e = read_file(Path::new(p), 1 << 20, "test file").unwrap_err();
            assert!(matches!(e, ReadError::NotRegular(_)), "{p}: {e}");
        }
    }

    #[test]
    fn files_over_the_limit_are_refused_before_reading() {
        let dir = std::env::temp_dir().join(format!("voxlab-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("big.txt");
        std::fs::write(&p, vec![b'x'; 100]).unwrap();
        assert_eq!(read_file(&p, 100, "t").unwrap().len(), 100);
        let e = read_file(&p, 99, "test file").unwrap_err().to_string();
        assert!(e.contains("100 bytes") && e.contains("99 bytes"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_panic_in_a_guarded_parser_is_an_error_with_its_message() {
        let r: Result<(), String> = guarded(|| panic!("index out of bounds: 7"));
        let e = r.unwrap_err();
        assert!(e.contains("index out of bounds: 7"), "{e}");
        assert_eq!(guarded(|| 5).unwrap(), 5);
    }

    #[test]
    fn excerpts_are_cut() {
        assert_eq!(excerpt("abc", 5), "abc");
        assert_eq!(excerpt("abcdef", 3), "abc... (3 more characters)");
    }

    #[test]
    fn numbers_are_quoted_short() {
        assert_eq!(super::short_number(22.4), "22.4");
        assert_eq!(super::short_number(0.0), "0");
        assert_eq!(super::short_number(-1e308), "-1e308");
        assert_eq!(super::short_number(1e-300), "1e-300");
        assert_eq!(super::short_number(f64::NAN), "NaN");
        assert_eq!(
            super::short_vector(glam::DVec3::new(1e300, 0.5, f64::INFINITY)),
            "[1e300, 0.5, inf]"
        );
    }
}
