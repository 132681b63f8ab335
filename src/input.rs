//! Reading input files within a size cap, so that no input costs more than the limit that names
//! it (the `# Limits` table of the crate documentation).
//!
//! Files whose whole content is loaded into memory to be decoded (OBJ meshes, MPU point clouds,
//! images) must be **regular files**: a device such as `/dev/zero` or a FIFO could feed forever.
//! The text files rayproof is configured by (scenes, suite files, tolerance tables, manifests) may
//! also come from a pipe; they are read up to their cap and refused beyond it. A regular file is
//! refused by its size before a byte of it is read.

use std::io::Read;
use std::path::Path;

/// The largest magnitude of any number in a scene file, and of an MPU point's coordinates:
/// squared distances between such points stay below f64's range (3·(2·1e150)² ≈ 1.2e301). Five
/// MPU points at ±1e153 fit in 0.05 s; at ±1e154 the squared distances overflow to ∞ and the
/// fit's search for the nearest points had not ended after 10 s (it cannot: no distance is below
/// ∞).
pub const MAX_MAGNITUDE: f64 = 1e150;

/// The largest scene file, suite file, tolerance table or manifest: 16 MiB (the reference
/// scenes are below 5 KB; fan30's 30 spheres take 3.9 KB).
pub const MAX_TEXT_BYTES: u64 = 16 << 20;
/// The largest OBJ mesh or MPU point file: 64 MiB (the bunny's OBJ is 110 KB, its points 160 KB;
/// a 64 MiB OBJ holds about 1.5 million triangles).
pub const MAX_MESH_BYTES: u64 = 64 << 20;

/// The largest `score` cases or answers file and `merge` shard file: 256 MiB (read up to that
/// from a pipe). The default cases file of the largest shape (sphere, 360,000 cases) is 68 MB and
/// takes 213 MB to score; a shard of every shape at 2,000 cases is 7 MB. `/dev/zero` given as
/// `score --cases` was read until the kernel killed rayproof at 22 GB.
pub const MAX_DATA_BYTES: u64 = 256 << 20;

/// Whether the file may be a device or a FIFO.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A regular file only.
    Regular,
    /// Anything that can be read; at most the cap is read from it.
    Stream,
}

/// Reads at most `cap` bytes of `path`; one line (without the path, which the caller names) if
/// it cannot be opened, is a directory, is not a regular file when `kind` asks for one (checked
/// before it is opened), or holds more than `cap` bytes.
pub fn read_capped(path: &Path, cap: u64, kind: Kind) -> Result<Vec<u8>, String> {
    // Looked at before it is opened: opening a FIFO waits for a writer (a mesh or an image that
    // is a FIFO hung the run)
    let meta = std::fs::metadata(path).map_err(|e| e.to_string())?;
    if meta.is_dir() {
        return Err("is a directory".into());
    }
    if kind == Kind::Regular && !meta.is_file() {
        return Err("is not a regular file (a device, a FIFO or a socket is not read)".into());
    }
    if meta.is_file() && meta.len() > cap {
        return Err(format!(
            "has {} bytes; at most {} are read",
            meta.len(),
            size(cap)
        ));
    }
    let file = open_without_waiting(path).map_err(|e| e.to_string())?;
    let mut bytes = Vec::new();
    file.take(cap + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > cap {
        // A stream, or a file that grew while it was read
        return Err(format!(
            "holds more than {}, the most that is read",
            size(cap)
        ));
    }
    Ok(bytes)
}

/// Opens `path` for reading without waiting for a writer: a FIFO nobody writes to reads as
/// empty instead of blocking in `open` (where no signal ends the run), and reads then block as
/// usual (a pipe with a writer, `<(…)`, is read whole).
fn open_without_waiting(path: &Path) -> std::io::Result<std::fs::File> {
    use std::os::unix::fs::OpenOptionsExt;
    use std::os::unix::io::AsRawFd;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)?;
    // SAFETY: fcntl on a descriptor this function owns, with integer arguments
    let fd = file.as_raw_fd();
    let flags = unsafe { libc::fcntl(fd, libc::F_GETFL) };
    if flags < 0 || unsafe { libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) } < 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(file)
}

/// [`read_capped`] as UTF-8 text.
pub fn read_text(path: &Path, cap: u64, kind: Kind) -> Result<String, String> {
    String::from_utf8(read_capped(path, cap, kind)?)
        .map_err(|_| "stream did not contain valid UTF-8".to_string())
}

/// `n` bytes, in MiB too when it is a whole number of them (as the limits are written).
pub fn size(n: u64) -> String {
    if n >= 1 << 20 && n.is_multiple_of(1 << 20) {
        format!("{} MiB ({n} bytes)", n >> 20)
    } else {
        format!("{n} bytes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn caps_devices_and_sizes() {
        let d = std::env::temp_dir().join(format!("rayproof-input-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let f = d.join("f.txt");
        std::fs::write(&f, "hello").unwrap();
        assert_eq!(read_text(&f, 5, Kind::Regular).unwrap(), "hello");
        let e = read_capped(&f, 4, Kind::Regular).unwrap_err();
        assert!(
            e.contains("has 5 bytes") && e.contains("at most 4 bytes"),
            "{e}"
        );
        assert!(read_capped(&d, 100, Kind::Stream)
            .unwrap_err()
            .contains("directory"));
        let zero = Path::new("/dev/zero");
        assert!(read_capped(zero, 100, Kind::Regular)
            .unwrap_err()
            .contains("not a regular file"));
        assert!(read_capped(zero, 100, Kind::Stream)
            .unwrap_err()
            .contains("more than 100 bytes"));
        std::fs::remove_dir_all(&d).unwrap();
    }
}
