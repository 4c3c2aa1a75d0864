//! Validated render settings: what the core needs to know, independent of any command line.

use serde::{Deserialize, Serialize};

use crate::camera::{CameraSettings, FovAxis};
use crate::mistakes::{Mistake, Mistakes};

/// Which of the course's stages to render.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    /// Stage 1: the closest hit's material colour, one ray per pixel.
    One,
    /// Stage 2: Whitted ray tracing with point lights, mirrors and glass.
    Two,
    /// Everything rayscope supports (stage 2 plus every stage-3 add-on).
    #[default]
    Full,
}

/// Which year's course a scene is read by: the editions differ in what a glass colour means.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
pub enum Edition {
    /// The 2021 course: a Refractive material's colour plays no part (clear glass).
    #[serde(rename = "2021")]
    Y2021,
    /// The 2022 course (the current template): a Refractive material's colour is its Beer's-law
    /// absorbance per channel (stage 3 F).
    #[default]
    #[serde(rename = "2022")]
    Y2022,
}

impl Edition {
    /// The edition's year, as `--edition` takes it.
    #[must_use]
    pub fn year(self) -> u32 {
        match self {
            Edition::Y2021 => 2021,
            Edition::Y2022 => 2022,
        }
    }

    /// True for the default edition (2022).
    #[must_use]
    pub fn is_default(&self) -> bool {
        *self == Edition::default()
    }
}

/// Which hits the recursion limit (`--max-depth N`) turns black.
///
/// The camera ray has depth 0 and every reflected, refracted or bounce ray one more than the ray
/// whose hit sent it (shadow rays have none).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum DepthLimit {
    /// A Reflective or Refractive hit on a ray of depth N or more returns black; other hits are
    /// shaded whatever their depth, and `-l`'s diffuse bounces do not count.
    #[default]
    MirrorGlass,
    /// Any ray of depth over N returns black, whatever it hits: a student's
    /// `if (depth > maxDepth) return black` at the top of `Trace(ray, depth)`, called with depth
    /// 0 for the camera ray and depth + 1 for every ray a hit sends on, `-l`'s bounces included.
    All,
}

impl DepthLimit {
    /// The flag's value: `mirror-glass` or `all`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            DepthLimit::MirrorGlass => "mirror-glass",
            DepthLimit::All => "all",
        }
    }

    /// True when this is the default.
    #[must_use]
    pub fn is_default(&self) -> bool {
        *self == DepthLimit::default()
    }
}

/// What a pixel shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Channel {
    /// The rendered colour.
    #[default]
    Color,
    /// The first hit's shading normal, mapped from [−1, 1] to [0, 1].
    Normal,
    /// Distance to the first hit, mapped to [0, 1] over the scene's depth range.
    Depth,
    /// A distinct colour per entity.
    Entity,
    /// The first hit's material colour (stage 1).
    Albedo,
    /// Number of BVH nodes and primitives tested for the camera ray, as a heat map.
    Cost,
}

impl Channel {
    /// The name `--aov` takes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Channel::Color => "color",
            Channel::Normal => "normal",
            Channel::Depth => "depth",
            Channel::Entity => "entity",
            Channel::Albedo => "albedo",
            Channel::Cost => "cost",
        }
    }
}

/// Everything that decides what a render produces.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RenderSettings {
    /// Image width in pixels (≥ 1).
    pub width: u32,
    /// Image height in pixels (≥ 1).
    pub height: u32,
    /// Anti-aliasing: an `aa` × `aa` grid of samples per pixel (`-x`, ≥ 1).
    pub aa: u32,
    /// Stage to render.
    pub stage: Stage,
    /// Ambient (indirect diffuse) lighting (`-l`).
    pub ambient: bool,
    /// Quality level for stochastic effects (`-q`).
    pub quality: u32,
    /// Most secondary bounces for mirrors and glass (see [`DepthLimit`]).
    pub max_depth: u32,
    /// Which hits the recursion limit turns black.
    #[serde(default, skip_serializing_if = "DepthLimit::is_default")]
    pub depth_limit: DepthLimit,
    /// The course edition the scene is read by (what a glass colour means).
    #[serde(default, skip_serializing_if = "Edition::is_default")]
    pub edition: Edition,
    /// Camera.
    pub camera: CameraSettings,
    /// Seed of every random stream.
    pub seed: u64,
    /// What pixels show.
    pub channel: Channel,
    /// The course's mistakes to make (`--mistake`); none for a correct render.
    #[serde(default, skip_serializing_if = "Mistakes::is_empty")]
    pub mistakes: Mistakes,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 400,
            height: 400,
            aa: 1,
            stage: Stage::Full,
            ambient: false,
            quality: 0,
            max_depth: 8,
            depth_limit: DepthLimit::MirrorGlass,
            edition: Edition::Y2022,
            camera: CameraSettings::default(),
            seed: 0,
            channel: Channel::Color,
            mistakes: Mistakes::NONE,
        }
    }
}

impl RenderSettings {
    /// The command-line flags that give these settings: the size, then each setting that is not
    /// the default.
    #[must_use]
    pub fn flags(&self) -> String {
        let d = RenderSettings::default();
        let v = |v: glam::Vec3| format!("{},{},{}", v.x, v.y, v.z);
        let mut f = format!("-w {} -h {}", self.width, self.height);
        let mut add = |on: bool, flag: String| {
            if on {
                f.push(' ');
                f.push_str(&flag);
            }
        };
        let stage = match self.stage {
            Stage::One => "1",
            Stage::Two => "2",
            Stage::Full => "3",
        };
        add(self.stage != d.stage, format!("--stage {stage}"));
        add(self.aa != d.aa, format!("-x {}", self.aa));
        add(self.ambient, "-l".into());
        add(self.quality != d.quality, format!("-q {}", self.quality));
        add(
            self.depth_limit != d.depth_limit,
            format!("--depth-limit {}", self.depth_limit.name()),
        );
        add(self.max_depth != d.max_depth, format!("--max-depth {}", self.max_depth));
        add(self.edition != d.edition, format!("--edition {}", self.edition.year()));
        let (c, dc) = (&self.camera, &d.camera);
        add(c.position != dc.position, format!("-p {}", v(c.position)));
        add(c.axis != dc.axis, format!("-a {}", v(c.axis)));
        add(c.angle_deg != dc.angle_deg, format!("-n {}", c.angle_deg));
        add(c.fov_deg != dc.fov_deg, format!("--fov {}", c.fov_deg));
        add(c.fov_axis != dc.fov_axis, "--fov-axis vertical".into());
        add(
            c.aperture_radius != dc.aperture_radius,
            format!("-r {}", c.aperture_radius),
        );
        add(c.focal_length != dc.focal_length, format!("-t {}", c.focal_length));
        add(self.seed != d.seed, format!("--seed {}", self.seed));
        add(!self.mistakes.is_empty(), format!("--mistake {}", self.mistakes));
        add(self.channel != d.channel, format!("--aov {}", self.channel.name()));
        f
    }
}

/// Memory a render holds per pixel at its peak: the float film (12 bytes), the tiles' results
/// before they are copied in (12) and the 8-bit image being encoded (4), rounded up to leave room
/// for the encoder's buffers. Path-traced tiles stream their samples in bounded batches, so this
/// does not grow with `-x` or `-q`.
pub const BYTES_PER_PIXEL: u64 = 32;

/// Most samples a pixel may take (`-x` N² grid positions × 2^q paths): each pixel's sum is kept
/// in f32, which cannot resolve one more sample past 2^24 of them.
pub(crate) const MAX_SAMPLES_PER_PIXEL: u64 = 1 << 24;

/// What a front end lets one render use; [`RenderSettings::check`] holds settings to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Most pixels in the image.
    pub max_pixels: u64,
    /// Most bytes the image buffers may take ([`BYTES_PER_PIXEL`] a pixel).
    pub memory_bytes: u64,
    /// Most samples in the whole image, counting every `-q` path (`None`: no bound).
    pub max_samples: Option<u64>,
    /// What to tell a user who goes over `max_pixels` (e.g. the flag that lifts it).
    pub pixel_hint: &'static str,
    /// Where `memory_bytes` comes from, for the message.
    pub memory_hint: &'static str,
}

impl Limits {
    /// The command line's limits: 64 megapixels unless `allow_large`, and in either case image
    /// buffers that fit in three quarters of the memory available now.
    #[must_use]
    pub fn command_line(allow_large: bool) -> Limits {
        const PIXEL_BUDGET: u64 = 8192 * 8192;
        let available = available_memory().map_or(u64::MAX, |m| m / 4 * 3);
        if allow_large {
            Limits {
                max_pixels: 1 << 30,
                memory_bytes: available,
                max_samples: None,
                pixel_hint: " (2^30), the most rayscope renders even with --allow-large",
                memory_hint: " (three quarters of the memory available now)",
            }
        } else {
            Limits {
                max_pixels: PIXEL_BUDGET,
                memory_bytes: available.min(PIXEL_BUDGET * BYTES_PER_PIXEL),
                max_samples: None,
                pixel_hint: " (8192×8192); pass --allow-large to render it anyway",
                memory_hint: " (2 GiB, or three quarters of the memory available now if less)",
            }
        }
    }
}

/// Memory the system could give this process now (`MemAvailable` on Linux), if known.
#[must_use]
pub(crate) fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

impl RenderSettings {
    /// These settings as a render with the mistakes `m` runs under: those mistakes that are
    /// settings of rayscope's too (the field of view's axis, the recursion limit) applied.
    #[must_use]
    pub(crate) fn mistaken(&self, m: Mistakes) -> RenderSettings {
        let mut s = *self;
        if m.has(Mistake::FovVertical) {
            s.camera.fov_axis = FovAxis::Vertical;
        }
        if m.has(Mistake::RecursionLimit3) {
            s.max_depth = 3;
        }
        s
    }

    /// Most samples a pixel can take with these settings, in any scene: N² grid positions, times
    /// 2^q paths when the scene turns out to have a stochastic effect.
    #[must_use]
    pub(crate) fn max_samples_per_pixel(&self) -> u64 {
        if self.stage == Stage::One || self.channel != Channel::Color {
            return 1;
        }
        let grid = (self.aa as u64).pow(2);
        if self.stage == Stage::Full {
            grid << self.quality.min(16)
        } else {
            grid
        }
    }

    /// Checks that a render with these settings fits `limits`, before any work starts.
    ///
    /// # Errors
    /// A message that names the settings at fault and the bound they break.
    pub fn check(&self, limits: &Limits) -> Result<(), String> {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return Err(format!("a {w}×{h} image has no pixels"));
        }
        let pixels = w as u64 * h as u64;
        if pixels > limits.max_pixels {
            return Err(format!(
                "a {w}×{h} image is {pixels} pixels, over the budget of {}{}",
                limits.max_pixels, limits.pixel_hint
            ));
        }
        let bytes = pixels.saturating_mul(BYTES_PER_PIXEL);
        if bytes > limits.memory_bytes {
            return Err(format!(
                "a {w}×{h} image needs about {} MiB for its buffers ({BYTES_PER_PIXEL} bytes a pixel), more than the {} MiB a render may use{}",
                bytes >> 20,
                limits.memory_bytes >> 20,
                limits.memory_hint
            ));
        }
        let spp = self.max_samples_per_pixel();
        if spp > MAX_SAMPLES_PER_PIXEL {
            return Err(format!(
                "-x {} -q {} asks for up to {spp} samples per pixel; at most {MAX_SAMPLES_PER_PIXEL} (2^24) can be averaged in single precision: lower -x or -q",
                self.aa, self.quality
            ));
        }
        if let Some(max) = limits.max_samples {
            let samples = pixels.saturating_mul(spp);
            if samples > max {
                return Err(format!(
                    "{samples} samples ({w}×{h} pixels, up to {spp} a pixel) is more than {max}; lower the size, -x or -q"
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(width: u32, height: u32, aa: u32, quality: u32) -> RenderSettings {
        RenderSettings {
            width,
            height,
            aa,
            quality,
            ..RenderSettings::default()
        }
    }

    #[test]
    fn samples_count_every_path_in_64_bits() {
        let s = settings(16, 16, 16, 16);
        assert_eq!(s.max_samples_per_pixel(), 1 << 24);
        let limits = Limits {
            max_pixels: u64::MAX,
            memory_bytes: u64::MAX,
            max_samples: Some(1 << 28),
            pixel_hint: "",
            memory_hint: "",
        };
        // 256 pixels × 2^24 is 2^32: it wraps to 0 in u32, and must not pass.
        let err = s.check(&limits).unwrap_err();
        assert!(err.contains("4294967296 samples"), "{err}");
        assert!(settings(64, 64, 64, 16).check(&limits).unwrap_err().contains("2^24"));
        assert!(settings(16, 16, 4, 2).check(&limits).is_ok());
    }

    #[test]
    fn memory_bounds_the_image_not_the_samples() {
        let limits = Limits {
            max_pixels: u64::MAX,
            memory_bytes: 1 << 30,
            max_samples: None,
            pixel_hint: "",
            memory_hint: "",
        };
        assert!(
            settings(4096, 4096, 1, 0).check(&limits).is_ok(),
            "16 M pixels × 32 B = 512 MiB"
        );
        let err = settings(8192, 8192, 1, 0).check(&limits).unwrap_err();
        assert!(err.contains("2048 MiB"), "{err}");
        assert!(
            settings(1024, 1024, 16, 8).check(&limits).is_ok(),
            "samples cost time, not memory"
        );
    }

    #[test]
    fn command_line_needs_allow_large_past_64_megapixels() {
        let err = settings(8193, 8192, 1, 0)
            .check(&Limits::command_line(false))
            .unwrap_err();
        assert!(err.contains("--allow-large"), "{err}");
    }
}
