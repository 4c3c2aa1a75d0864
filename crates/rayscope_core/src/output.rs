//! Writing films to disk: PNG (8-bit, the course's conversion), OpenEXR (linear float) and PPM,
//! always through a temporary file renamed into place so a failure never damages what was there.

use std::fs;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::film::Film;

/// An output file format, chosen by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// 8-bit RGBA PNG with the course's clamp-and-truncate conversion.
    Png,
    /// Linear 32-bit float RGB OpenEXR.
    Exr,
    /// Binary 8-bit PPM (P6) with the course's conversion.
    Ppm,
}

/// Why an image could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The extension names no format rayscope writes.
    #[error("cannot write '{}': unsupported output format '{ext}' (expected .png, .exr or .ppm)", path.display())]
    UnsupportedFormat {
        /// The path.
        path: PathBuf,
        /// Its extension.
        ext: String,
    },
    /// The folder the file would go in does not exist or is not a folder.
    #[error("cannot write '{}': the folder '{}' does not exist", path.display(), dir.display())]
    MissingFolder {
        /// The path.
        path: PathBuf,
        /// Its folder.
        dir: PathBuf,
    },
    /// The output path is an existing folder.
    #[error("cannot write '{}': it is a folder", .0.display())]
    IsFolder(PathBuf),
    /// An I/O error while writing.
    #[error("cannot write '{}': {source}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: io::Error,
    },
}

impl Format {
    /// The format for `path`'s extension.
    pub fn from_path(path: &Path) -> Result<Format, OutputError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        match ext.as_str() {
            "png" => Ok(Format::Png),
            "exr" => Ok(Format::Exr),
            "ppm" => Ok(Format::Ppm),
            _ => Err(OutputError::UnsupportedFormat {
                path: path.to_path_buf(),
                ext: if ext.is_empty() {
                    "(none)".into()
                } else {
                    format!(".{ext}")
                },
            }),
        }
    }
}

/// Checks, before any work is done, that `path` can be written: a file name (not a folder, no
/// trailing `/`), a known format, an existing folder that is writable. Returns the format.
pub fn check_writable(path: &Path) -> Result<Format, OutputError> {
    if path.is_dir() || path.as_os_str().to_string_lossy().ends_with('/') {
        return Err(OutputError::IsFolder(path.to_path_buf()));
    }
    let format = Format::from_path(path)?;
    let dir = parent_dir(path);
    if !dir.is_dir() {
        return Err(OutputError::MissingFolder {
            path: path.to_path_buf(),
            dir,
        });
    }
    // Probe with a real temporary file: permission bits alone do not tell (root, ACLs, read-only
    // mounts). It is created the way the real one will be, and removed when dropped.
    match create_temp(path) {
        Ok(_) => Ok(format),
        Err(source) => Err(OutputError::Io {
            path: path.to_path_buf(),
            source,
        }),
    }
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A new temporary file beside `path`: hidden, with a random name, created exclusively (an
/// existing file or a planted symbolic link of that name makes creation fail rather than be
/// followed), with the permissions a new file at `path` would get, or `path`'s own if it exists.
/// The name does not contain `path`'s, so any file name the folder accepts can be written.
fn create_temp(path: &Path) -> io::Result<tempfile::NamedTempFile> {
    let mut b = tempfile::Builder::new();
    b.prefix(".rayscope-").suffix(".tmp").rand_bytes(12);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // 0o666 goes through the umask, as `File::create` does.
        b.permissions(fs::Permissions::from_mode(0o666));
    }
    let tmp = b.tempfile_in(parent_dir(path))?;
    // `metadata` follows a link at `path`: the rename replaces the link, and the new file takes
    // the permissions of what the user saw there.
    if let Ok(m) = fs::metadata(path) {
        if m.is_file() {
            tmp.as_file().set_permissions(m.permissions())?;
        }
    }
    Ok(tmp)
}

/// Writes a file at `path` atomically: `write` fills a temporary file beside it (see
/// [`check_writable`] for how it is created), which is flushed to disk and renamed into place
/// only when everything succeeded; on any error it is removed and `path` is untouched.
pub fn write_atomic(path: &Path, write: impl FnOnce(&mut BufWriter<&fs::File>) -> io::Result<()>) -> io::Result<()> {
    if path.as_os_str().to_string_lossy().ends_with('/') {
        return Err(io::Error::new(io::ErrorKind::IsADirectory, "the path names a folder"));
    }
    let tmp = create_temp(path)?;
    {
        let mut w = BufWriter::new(tmp.as_file());
        write(&mut w)?;
        w.flush()?;
    }
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

/// Writes `film` to `path` in the format its extension names, atomically, and byte for byte the
/// same for the same film.
pub fn write_film(film: &Film, path: &Path) -> Result<(), OutputError> {
    let format = Format::from_path(path)?;
    write_atomic(path, |w| {
        match format {
            Format::Png => {
                // Paeth on every row: the same pixels and, on the course's renders, a file within
                // 2 % of the adaptive filter's, which tries five filters a row and took 1.5×
                // (scene 2) to 2× (scene 1) as long to encode.
                use image::codecs::png::{CompressionType, FilterType, PngEncoder};
                let enc = PngEncoder::new_with_quality(w, CompressionType::Fast, FilterType::Paeth);
                image::ImageEncoder::write_image(
                    enc,
                    &film.to_rgba8(),
                    film.width,
                    film.height,
                    image::ExtendedColorType::Rgba8,
                )
                .map_err(io::Error::other)?;
            }
            Format::Ppm => {
                write!(w, "P6\n{} {}\n255\n", film.width, film.height)?;
                w.write_all(&film.to_rgb8())?;
            }
            Format::Exr => {
                use exr::prelude::*;
                let (fw, px) = (film.width as usize, &film.pixels);
                let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
                    let p = px[y * fw + x];
                    (p.x, p.y, p.z)
                });
                // Serial compression: the parallel writer stores blocks in the order they finish.
                Image::from_channels((film.width as usize, film.height as usize), channels)
                    .write()
                    .non_parallel()
                    .to_buffered(&mut *w)
                    .map_err(io::Error::other)?;
            }
        }
        Ok(())
    })
    .map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_each_format_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let mut film = Film::new(3, 2);
        film.pixels[0] = glam::Vec3::new(1.0, 0.5, 0.0);
        for name in ["a.png", "a.exr", "a.ppm"] {
            let p = dir.path().join(name);
            write_film(&film, &p).unwrap();
            assert!(p.metadata().unwrap().len() > 0);
        }
        let png = image::open(dir.path().join("a.png")).unwrap().to_rgba8();
        assert_eq!(png.get_pixel(0, 0).0, [255, 127, 0, 255]);
        let ppm = fs::read(dir.path().join("a.ppm")).unwrap();
        assert!(ppm.starts_with(b"P6\n3 2\n255\n"));
        assert_eq!(
            fs::read_dir(dir.path()).unwrap().count(),
            3,
            "no temporary files left behind"
        );
    }

    #[test]
    fn rejects_unknown_format_and_missing_folder() {
        assert!(matches!(
            check_writable(Path::new("x.jpg")),
            Err(OutputError::UnsupportedFormat { .. })
        ));
        assert!(matches!(
            check_writable(Path::new("/nonexistent-folder-rayscope/x.png")),
            Err(OutputError::MissingFolder { .. })
        ));
    }
}
