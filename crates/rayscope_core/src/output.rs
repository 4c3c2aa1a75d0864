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

/// Checks, before any work is done, that `path` can be written: known format, existing folder,
/// folder writable. Returns the format.
pub fn check_writable(path: &Path) -> Result<Format, OutputError> {
    if path.is_dir() {
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
    // Probe with a real temporary file: permission bits alone do not tell (root, ACLs, read-only mounts).
    let probe = temp_path(path);
    match fs::File::create(&probe) {
        Ok(_) => {
            let _ = fs::remove_file(&probe);
            Ok(format)
        }
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

/// The temporary file `path` is first written to: hidden, beside it, unique to this process.
#[must_use]
pub fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    parent_dir(path).join(format!(".{name}.rayscope-{}.tmp", std::process::id()))
}

/// Writes `film` to `path` in the format its extension names, atomically.
pub fn write_film(film: &Film, path: &Path) -> Result<(), OutputError> {
    let format = Format::from_path(path)?;
    let tmp = temp_path(path);
    let io_err = |source: io::Error| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let result = (|| -> io::Result<()> {
        let file = fs::File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        match format {
            Format::Png => {
                let enc = image::codecs::png::PngEncoder::new(&mut w);
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
                let (fw, px) = (film.width as usize, &film.pixels);
                exr::prelude::write_rgb_file(&tmp, film.width as usize, film.height as usize, |x, y| {
                    let p = px[y * fw + x];
                    (p.x, p.y, p.z)
                })
                .map_err(io::Error::other)?;
            }
        }
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        Ok(())
    })();
    match result.and_then(|()| fs::rename(&tmp, path)) {
        Ok(()) => Ok(()),
        Err(e) => {
            let _ = fs::remove_file(&tmp);
            Err(io_err(e))
        }
    }
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
