//! Reading input files with the checks a user's mistakes and a hostile path call for: only
//! regular files (a folder, a named pipe or a device is named as such instead of blocking or
//! growing without end), and never more bytes than a bound.

use std::fs;
use std::io::{self, Read};
use std::path::Path;

/// The largest scene file rayscope reads: the course's scenes are a few hundred bytes, and a
/// scene of a million `Triangle` lines is about 100 MiB.
pub const MAX_SCENE_BYTES: u64 = 256 << 20;

/// The largest OBJ file rayscope reads: a 4-million-triangle mesh is about 300 MiB.
pub const MAX_OBJ_BYTES: u64 = 4 << 30;

/// What a path names when it is not a regular file, for messages; `None` for a regular file.
#[must_use]
pub fn not_a_file(meta: &fs::Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some("a folder");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some("a named pipe (FIFO)");
        }
        if t.is_socket() {
            return Some("a socket");
        }
        if t.is_char_device() || t.is_block_device() {
            return Some("a device");
        }
    }
    Some("not a regular file")
}

/// Opens `path` for reading with its length, only if it is a regular file.
///
/// # Errors
/// The OS error, or an `InvalidInput` error that says what the path is instead of a file.
pub fn open_regular(path: &Path) -> io::Result<(fs::File, u64)> {
    let wrong = |what: &str| io::Error::new(io::ErrorKind::InvalidInput, format!("it is {what}, not a file"));
    // Looked at before opening: opening a named pipe blocks until a writer appears.
    if let Some(what) = not_a_file(&fs::metadata(path)?) {
        return Err(wrong(what));
    }
    let file = fs::File::open(path)?;
    // The path may have been replaced between the two looks.
    let meta = file.metadata()?;
    if let Some(what) = not_a_file(&meta) {
        return Err(wrong(what));
    }
    Ok((file, meta.len()))
}

/// Reads the regular file at `path`, at most `max_bytes` of it.
///
/// # Errors
/// The OS error, or an `InvalidInput` error that says what the path is instead of a file, or
/// how large the file is against the bound.
pub fn read_bounded(path: &Path, max_bytes: u64) -> io::Result<Vec<u8>> {
    let (file, len) = open_regular(path)?;
    let too_large = |len: u64| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "it is {} MiB, more than the {} MiB rayscope reads",
                len >> 20,
                max_bytes >> 20
            ),
        )
    };
    if len > max_bytes {
        return Err(too_large(len));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(max_bytes + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_folders_and_devices_and_bounds_size() {
        let dir = tempfile::tempdir().unwrap();
        let err = read_bounded(dir.path(), 10).unwrap_err();
        assert!(err.to_string().contains("a folder"), "{err}");
        #[cfg(unix)]
        {
            let err = read_bounded(Path::new("/dev/zero"), 10).unwrap_err();
            assert!(err.to_string().contains("a device"), "{err}");
        }
        let f = dir.path().join("s.txt");
        fs::write(&f, "0123456789x").unwrap();
        let err = read_bounded(&f, 10).unwrap_err();
        assert!(err.to_string().contains("more than"), "{err}");
        assert_eq!(read_bounded(&f, 11).unwrap(), b"0123456789x");
    }
}
