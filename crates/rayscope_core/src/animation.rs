//! Camera paths for animations (`--frames A..B`): keyframed `-p`, `-a` and `-n` values,
//! interpolated linearly between frames, and a turntable that circles a point.
//!
//! A frame's camera depends only on the path and the frame number, never on which other frames a
//! process renders, so each frame (or each part of a frame) can be a task of its own on a cluster.

use glam::{Mat3, Quat, Vec3};

use crate::camera::CameraSettings;

/// A turntable: the camera circles `center` about the vertical (+y) axis, one full turn every
/// `frames` frames, turning with it so that it keeps facing the same way relative to the centre.
/// Frame 0 is the camera as the flags place it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Turntable {
    /// The point circled.
    pub center: Vec3,
    /// Frames per full turn (≥ 1).
    pub frames: u32,
}

/// Keyframes of one value: (frame, value), sorted by frame, frames distinct.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Keys<T>(Vec<(u32, T)>);

impl<T: Copy> Keys<T> {
    /// Keyframes from (frame, value) pairs in any order.
    ///
    /// # Errors
    /// When two keyframes are at the same frame.
    pub fn new(mut keys: Vec<(u32, T)>, what: &str) -> Result<Keys<T>, String> {
        keys.sort_by_key(|k| k.0);
        if let Some(w) = keys.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(format!("two {what} keyframes at frame {}", w[0].0));
        }
        Ok(Keys(keys))
    }

    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The value at `frame`, interpolated with `lerp` between the keyframes around it and held
    /// before the first and after the last; `None` without keyframes.
    fn at(&self, frame: u32, lerp: impl Fn(T, T, f32) -> T) -> Option<T> {
        let k = &self.0;
        let first = k.first()?;
        let next = k.partition_point(|&(f, _)| f <= frame);
        Some(match next {
            0 => first.1,
            n if n == k.len() => k[n - 1].1,
            n => {
                let ((f0, v0), (f1, v1)) = (k[n - 1], k[n]);
                lerp(v0, v1, (f64::from(frame - f0) / f64::from(f1 - f0)) as f32)
            }
        })
    }
}

/// A camera path: keyframes for position, axis and angle, then an optional turntable.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CameraPath {
    /// `-p` keyframes.
    pub position: Keys<Vec3>,
    /// `-a` keyframes (interpolated component by component, then normalised).
    pub axis: Keys<Vec3>,
    /// `-n` keyframes, in degrees.
    pub angle: Keys<f32>,
    /// The turntable, if any.
    pub turntable: Option<Turntable>,
}

impl CameraPath {
    /// The camera at `frame`: `base` (the flags) with the keyframed values interpolated in, then
    /// carried round the turntable.
    #[must_use]
    pub fn camera_at(&self, base: CameraSettings, frame: u32) -> CameraSettings {
        let mut cam = base;
        if let Some(p) = self.position.at(frame, |a, b, t| a.lerp(b, t)) {
            cam.position = p;
        }
        if let Some(a) = self.axis.at(frame, |a, b, t| a.lerp(b, t)) {
            // Normalised in f64, as `--cam-axis` is: a tiny but non-zero axis is a direction even
            // where its squared length underflows in f32. A zero axis (keyframes pointing
            // opposite ways, half way) keeps the flags' axis.
            let axis = a.as_dvec3().normalize_or_zero();
            if axis != glam::DVec3::ZERO {
                cam.axis = axis.as_vec3();
            }
        }
        if let Some(n) = self.angle.at(frame, |a, b, t| a + (b - a) * t) {
            cam.angle_deg = n;
        }
        if let Some(tt) = self.turntable {
            // The turn in f64, then one rounding: frame 120 of 120 lands exactly on a full turn.
            let turn = (f64::from(frame % tt.frames) / f64::from(tt.frames) * std::f64::consts::TAU) as f32;
            if turn != 0.0 {
                let spin = Mat3::from_rotation_y(turn);
                cam.position = tt.center + spin * (cam.position - tt.center);
                let axis = cam.axis.normalize_or_zero();
                let own = if axis == Vec3::ZERO {
                    Mat3::IDENTITY
                } else {
                    Mat3::from_axis_angle(axis, cam.angle_deg.to_radians())
                };
                let (axis, angle) = Quat::from_mat3(&(spin * own)).normalize().to_axis_angle();
                cam.axis = axis;
                cam.angle_deg = angle.to_degrees();
            }
        }
        cam
    }
}

/// `path` with the frame number put in: a run of `#` becomes the number padded with zeros to the
/// run's length (`frame_####.png` → `frame_0007.png`); without `#`, `_NNNN` goes before the
/// extension (`turn.png` → `turn_0007.png`).
#[must_use]
pub fn frame_path(path: &std::path::Path, frame: u32) -> std::path::PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let new = if let Some(start) = name.find('#') {
        let len = name[start..].chars().take_while(|&c| c == '#').count();
        format!("{}{frame:0len$}{}", &name[..start], &name[start + len..])
    } else {
        match name.rsplit_once('.') {
            Some((stem, ext)) => format!("{stem}_{frame:04}.{ext}"),
            None => format!("{name}_{frame:04}"),
        }
    };
    path.with_file_name(new)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn keyframes_interpolate_and_hold() {
        let k = Keys::new(vec![(10, 4.0f32), (0, 0.0), (20, 4.0)], "-n").unwrap();
        let at = |f| k.at(f, |a, b, t| a + (b - a) * t).unwrap();
        assert_eq!(at(0), 0.0);
        assert_eq!(at(5), 2.0);
        assert_eq!(at(10), 4.0);
        assert_eq!(at(15), 4.0);
        assert_eq!(at(99), 4.0);
        assert!(Keys::new(vec![(1, 0.0f32), (1, 2.0)], "-n").is_err());
    }

    #[test]
    fn a_turntable_circles_its_centre_facing_it() {
        let path = CameraPath {
            turntable: Some(Turntable {
                center: Vec3::new(0.0, 0.0, 5.0),
                frames: 4,
            }),
            ..CameraPath::default()
        };
        let base = CameraSettings::default();
        assert_eq!(path.camera_at(base, 0), base);
        assert_eq!(path.camera_at(base, 4), base, "a full turn is frame 0 again");
        let quarter = path.camera_at(base, 1);
        assert!(
            (quarter.position - Vec3::new(-5.0, 0.0, 5.0)).length() < 1e-5,
            "{quarter:?}"
        );
        // It still looks at the centre: its forward (+z) is turned to +x.
        let fwd = Mat3::from_axis_angle(quarter.axis, quarter.angle_deg.to_radians()) * Vec3::Z;
        assert!((fwd - Vec3::X).length() < 1e-5, "{fwd}");
    }

    #[test]
    fn frame_numbers_fill_hashes_or_follow_the_stem() {
        assert_eq!(frame_path(Path::new("out/f_####.png"), 7), Path::new("out/f_0007.png"));
        assert_eq!(frame_path(Path::new("t#.exr"), 12), Path::new("t12.exr"));
        assert_eq!(frame_path(Path::new("out/turn.png"), 3), Path::new("out/turn_0003.png"));
    }
}
