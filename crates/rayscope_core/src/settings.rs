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

/// One render setting, as the command line and the debugger name it: the unit that
/// [`RenderSettings::flags_only`] writes and that [`Ranges`] bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Setting {
    /// Image width (`-w`).
    Width,
    /// Image height (`-h`).
    Height,
    /// Stage (`--stage`).
    Stage,
    /// Anti-aliasing multiplier (`-x`).
    Aa,
    /// Ambient lighting (`-l`).
    Ambient,
    /// Quality (`-q`).
    Quality,
    /// Which hits the recursion limit turns black (`--depth-limit`).
    DepthLimit,
    /// Recursion limit (`--max-depth`).
    MaxDepth,
    /// Course edition (`--edition`).
    Edition,
    /// Camera position (`-p`).
    CamPos,
    /// Camera rotation axis (`-a`).
    CamAxis,
    /// Camera rotation angle (`-n`).
    CamAngle,
    /// Field of view (`--fov`).
    Fov,
    /// Which image side the field of view spans (`--fov-axis`).
    FovAxis,
    /// Lens radius (`-r`).
    Aperture,
    /// Distance in focus (`-t`).
    FocalLength,
    /// Seed (`--seed`).
    Seed,
    /// Mistakes to make (`--mistake`).
    Mistakes,
    /// What pixels show (`--aov`).
    Channel,
}

impl Setting {
    /// Every setting, in the order [`RenderSettings::flags_only`] writes them.
    pub const ALL: [Setting; 19] = [
        Setting::Width,
        Setting::Height,
        Setting::Stage,
        Setting::Aa,
        Setting::Ambient,
        Setting::Quality,
        Setting::DepthLimit,
        Setting::MaxDepth,
        Setting::Edition,
        Setting::CamPos,
        Setting::CamAxis,
        Setting::CamAngle,
        Setting::Fov,
        Setting::FovAxis,
        Setting::Aperture,
        Setting::FocalLength,
        Setting::Seed,
        Setting::Mistakes,
        Setting::Channel,
    ];

    /// The setting as an error message names it: its flag, then what it is (the debugger's
    /// form shows both).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Setting::Width => "-w (image width)",
            Setting::Height => "-h (image height)",
            Setting::Stage => "--stage",
            Setting::Aa => "-x (anti-aliasing multiplier)",
            Setting::Ambient => "-l (ambient lighting)",
            Setting::Quality => "-q (quality)",
            Setting::DepthLimit => "--depth-limit",
            Setting::MaxDepth => "--max-depth (recursion limit)",
            Setting::Edition => "--edition",
            Setting::CamPos => "-p (camera position)",
            Setting::CamAxis => "-a (camera axis)",
            Setting::CamAngle => "-n (camera angle)",
            Setting::Fov => "--fov (field of view)",
            Setting::FovAxis => "--fov-axis",
            Setting::Aperture => "-r (aperture radius)",
            Setting::FocalLength => "-t (focal length)",
            Setting::Seed => "--seed",
            Setting::Mistakes => "--mistake",
            Setting::Channel => "--aov",
        }
    }
}

impl FovAxis {
    /// The flag's value: `horizontal` or `vertical`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            FovAxis::Horizontal => "horizontal",
            FovAxis::Vertical => "vertical",
        }
    }
}

impl RenderSettings {
    /// The command-line flags that give these settings: the size, then each setting that is not
    /// the default.
    #[must_use]
    pub fn flags(&self) -> String {
        self.flags_only(&Setting::ALL)
    }

    /// The flags of the settings `which` only, in [`Setting::ALL`]'s order: the width and the
    /// height when listed, and each other listed setting that is not the default. The settings
    /// left out are to be read as their defaults, or as flags given beside these.
    #[must_use]
    pub fn flags_only(&self, which: &[Setting]) -> String {
        let d = RenderSettings::default();
        let always = |s: Setting| matches!(s, Setting::Width | Setting::Height);
        Setting::ALL
            .into_iter()
            .filter(|s| which.contains(s) && (always(*s) || self.differs(&d, *s)))
            .filter_map(|s| self.flag(s))
            .collect::<Vec<_>>()
            .join(" ")
    }

    /// True when `self` and `other` give `setting` different values.
    #[must_use]
    pub fn differs(&self, other: &RenderSettings, setting: Setting) -> bool {
        let (c, o) = (&self.camera, &other.camera);
        match setting {
            Setting::Width => self.width != other.width,
            Setting::Height => self.height != other.height,
            Setting::Stage => self.stage != other.stage,
            Setting::Aa => self.aa != other.aa,
            Setting::Ambient => self.ambient != other.ambient,
            Setting::Quality => self.quality != other.quality,
            Setting::DepthLimit => self.depth_limit != other.depth_limit,
            Setting::MaxDepth => self.max_depth != other.max_depth,
            Setting::Edition => self.edition != other.edition,
            Setting::CamPos => c.position != o.position,
            Setting::CamAxis => c.axis != o.axis,
            Setting::CamAngle => c.angle_deg != o.angle_deg,
            Setting::Fov => c.fov_deg != o.fov_deg,
            Setting::FovAxis => c.fov_axis != o.fov_axis,
            Setting::Aperture => c.aperture_radius != o.aperture_radius,
            Setting::FocalLength => c.focal_length != o.focal_length,
            Setting::Seed => self.seed != other.seed,
            Setting::Mistakes => self.mistakes != other.mistakes,
            Setting::Channel => self.channel != other.channel,
        }
    }

    /// The flag that gives `setting` its value here; none where no flag is needed for it (no
    /// ambient lighting, no mistakes).
    fn flag(&self, setting: Setting) -> Option<String> {
        let v = |v: glam::Vec3| format!("{},{},{}", v.x, v.y, v.z);
        let c = &self.camera;
        Some(match setting {
            Setting::Width => format!("-w {}", self.width),
            Setting::Height => format!("-h {}", self.height),
            Setting::Stage => match self.stage {
                Stage::One => "--stage 1",
                Stage::Two => "--stage 2",
                Stage::Full => "--stage 3",
            }
            .into(),
            Setting::Aa => format!("-x {}", self.aa),
            Setting::Ambient if self.ambient => "-l".into(),
            Setting::Ambient => return None,
            Setting::Quality => format!("-q {}", self.quality),
            Setting::DepthLimit => format!("--depth-limit {}", self.depth_limit.name()),
            Setting::MaxDepth => format!("--max-depth {}", self.max_depth),
            Setting::Edition => format!("--edition {}", self.edition.year()),
            Setting::CamPos => format!("-p {}", v(c.position)),
            Setting::CamAxis => format!("-a {}", v(c.axis)),
            Setting::CamAngle => format!("-n {}", c.angle_deg),
            Setting::Fov => format!("--fov {}", c.fov_deg),
            Setting::FovAxis => format!("--fov-axis {}", c.fov_axis.name()),
            Setting::Aperture => format!("-r {}", c.aperture_radius),
            Setting::FocalLength => format!("-t {}", c.focal_length),
            Setting::Seed => format!("--seed {}", self.seed),
            Setting::Mistakes if self.mistakes.is_empty() => return None,
            Setting::Mistakes => format!("--mistake {}", self.mistakes),
            Setting::Channel => format!("--aov {}", self.channel.name()),
        })
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

/// Most `-q` a render takes: 2^16 paths a grid position, the most `MAX_SAMPLES_PER_PIXEL`
/// leaves room for beside `-x`.
pub const MAX_QUALITY: u32 = 16;

/// The ranges a front end accepts for each numeric render setting. [`RenderSettings::check`]
/// holds settings to them; the command line's value parsers read single values through
/// [`Ranges::whole`] and [`Ranges::real`], so both report a value out of range in the same words.
/// The field of view (0° to 360°, both excluded, and not 180°) and `-q` (0 to [`MAX_QUALITY`])
/// are the same everywhere. Above 180° the image plane's half-width, tan(fov/2), is negative and
/// the picture is turned half a turn: what a tracer computes that takes the tangent of an angle
/// in degrees as radians, which `diagnose` names.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ranges {
    /// Most pixels on an image side (`-w`, `-h`; at least 1).
    pub max_side: u32,
    /// Largest `-x` (at least 1).
    pub max_aa: u32,
    /// Largest `--max-depth`.
    pub max_depth: u32,
    /// Largest magnitude of a coordinate of the camera's position and axis (`f32::MAX`: any
    /// finite value).
    pub max_coordinate: f32,
    /// Largest magnitude of the camera angle in degrees (`f32::MAX`: any finite value).
    pub max_angle: f32,
    /// Largest aperture radius (`f32::MAX`: any finite value; at least 0).
    pub max_aperture: f32,
    /// Largest focal length (`f32::MAX`: any finite value; over 0).
    pub max_focal_length: f32,
    /// Said after a bound that is this front end's own (e.g. " in the debugger").
    pub scope: &'static str,
}

impl Ranges {
    /// The command line's ranges: the widest, for a render that runs as long as it takes. An
    /// image side up to 2^20 pixels (the pixel budget of [`Limits`] bounds the area), `-x` up to
    /// 64, `--max-depth` up to 1000, and any finite camera.
    pub const COMMAND_LINE: Ranges = Ranges {
        max_side: 1 << 20,
        max_aa: 64,
        max_depth: 1000,
        max_coordinate: f32::MAX,
        max_angle: f32::MAX,
        max_aperture: f32::MAX,
        max_focal_length: f32::MAX,
        scope: "",
    };

    /// The debugger's ranges, narrower than the command line's because one local server renders
    /// for every request interactively and a new request cancels the render before: an image
    /// side up to 2048 pixels, `-x` up to 16 (256 samples a pixel), `--max-depth` up to 64, and
    /// a camera within ±10^6 (angle within ±10^5°, aperture up to 100, focal length up to 10^6)
    /// so the 3D view's orbit and the frustum it draws stay within single precision.
    pub const DEBUGGER: Ranges = Ranges {
        max_side: 2048,
        max_aa: 16,
        max_depth: 64,
        max_coordinate: 1e6,
        max_angle: 1e5,
        max_aperture: 100.0,
        max_focal_length: 1e6,
        scope: " in the debugger",
    };

    /// The whole numbers `setting` may take here (`-w`, `-h`, `-x`, `-q`, `--max-depth`), both
    /// ends included.
    #[must_use]
    pub fn whole_range(&self, setting: Setting) -> Option<(u32, u32)> {
        match setting {
            Setting::Width | Setting::Height => Some((1, self.max_side)),
            Setting::Aa => Some((1, self.max_aa)),
            Setting::Quality => Some((0, MAX_QUALITY)),
            Setting::MaxDepth => Some((0, self.max_depth)),
            _ => None,
        }
    }

    /// Checks a whole-number setting's value `v` (read wider than `u32`, so a negative value is
    /// named as given).
    ///
    /// # Errors
    /// A message naming the setting, its range and `v`.
    pub fn whole(&self, setting: Setting, v: i64) -> Result<u32, String> {
        let Some((lo, hi)) = self.whole_range(setting) else {
            return Err(format!("{} is not a whole-number setting", setting.name()));
        };
        if (i64::from(lo)..=i64::from(hi)).contains(&v) {
            Ok(v as u32)
        } else {
            let scope = if hi == Ranges::COMMAND_LINE.whole_range(setting).map_or(hi, |r| r.1) {
                ""
            } else {
                self.scope
            };
            Err(format!(
                "{} must be from {lo} to {hi}{scope}, found {v}",
                setting.name()
            ))
        }
    }

    /// Checks a real-number setting's value `v` (`-n`, `--fov`, `-r`, `-t`).
    ///
    /// # Errors
    /// A message naming the setting, its range and `v`.
    pub fn real(&self, setting: Setting, v: f32) -> Result<f32, String> {
        // (lowest, lowest included, highest, highest included)
        let (lo, lo_in, hi, hi_in) = match setting {
            Setting::CamAngle => (-self.max_angle, true, self.max_angle, true),
            Setting::Fov if v == 180.0 => {
                return Err(format!(
                    "{} cannot be 180: the image plane's half-width, tan(90°), is infinite",
                    setting.name()
                ))
            }
            Setting::Fov => (0.0, false, 360.0, false),
            Setting::Aperture => (0.0, true, self.max_aperture, true),
            Setting::FocalLength => (0.0, false, self.max_focal_length, true),
            _ => return Err(format!("{} is not a real-number setting", setting.name())),
        };
        let above = if lo_in { v >= lo } else { v > lo };
        let below = if hi_in { v <= hi } else { v < hi };
        if v.is_finite() && above && below {
            return Ok(v);
        }
        let name = setting.name();
        Err(match (lo == -f32::MAX, hi == f32::MAX) {
            (true, true) => format!("{name} must be a finite number, found {v}"),
            (false, true) if lo_in => format!("{name} must be a finite number of {lo} or more, found {v}"),
            (false, true) => format!("{name} must be a finite number greater than {lo}, found {v}"),
            _ => {
                let ends = match (lo_in, hi_in) {
                    (true, true) => "both included".to_string(),
                    (false, false) => "both excluded".to_string(),
                    (true, false) => format!("{hi} excluded"),
                    (false, true) => format!("{lo} excluded"),
                };
                format!(
                    "{name} must be from {lo} to {hi} ({ends}){}, found {v}",
                    self.scope_of(setting)
                )
            }
        })
    }

    /// Checks a camera vector (`-p`, `-a`): finite, each coordinate within `max_coordinate`.
    ///
    /// # Errors
    /// A message naming the setting, its range and `v`.
    pub fn coordinates(&self, setting: Setting, v: glam::Vec3) -> Result<glam::Vec3, String> {
        let name = setting.name();
        if !v.is_finite() {
            return Err(format!("{name} must be finite, found ({}, {}, {})", v.x, v.y, v.z));
        }
        if v.abs().max_element() > self.max_coordinate {
            return Err(format!(
                "{name} must lie within ±{:e} on each axis{}, found ({}, {}, {})",
                self.max_coordinate, self.scope, v.x, v.y, v.z
            ));
        }
        Ok(v)
    }

    /// This front end's scope for `setting`'s bound: empty where the bound is the command line's.
    fn scope_of(&self, setting: Setting) -> &'static str {
        let mine = (self.max_angle, self.max_aperture, self.max_focal_length);
        let cli = Ranges::COMMAND_LINE;
        let wide = match setting {
            Setting::CamAngle => mine.0 == cli.max_angle,
            Setting::Aperture => mine.1 == cli.max_aperture,
            Setting::FocalLength => mine.2 == cli.max_focal_length,
            _ => true,
        };
        if wide {
            ""
        } else {
            self.scope
        }
    }

    /// Checks every ranged setting of `s`, and the camera-axis rule ([`check_camera_axis`]).
    ///
    /// # Errors
    /// The first setting out of its range, as [`Ranges::whole`], [`Ranges::real`] and
    /// [`Ranges::coordinates`] name it.
    pub fn check(&self, s: &RenderSettings) -> Result<(), String> {
        self.whole(Setting::Width, s.width.into())?;
        self.whole(Setting::Height, s.height.into())?;
        self.whole(Setting::Aa, s.aa.into())?;
        self.whole(Setting::Quality, s.quality.into())?;
        self.whole(Setting::MaxDepth, s.max_depth.into())?;
        let c = &s.camera;
        self.real(Setting::Fov, c.fov_deg)?;
        self.coordinates(Setting::CamPos, c.position)?;
        self.coordinates(Setting::CamAxis, c.axis)?;
        self.real(Setting::CamAngle, c.angle_deg)?;
        check_camera_axis(c.axis, c.angle_deg)?;
        self.real(Setting::Aperture, c.aperture_radius)?;
        self.real(Setting::FocalLength, c.focal_length)?;
        Ok(())
    }
}

/// The camera axis as a render takes it: `axis` normalised in f64, so that a tiny but non-zero
/// axis is a direction even where its squared length underflows in f32; a zero axis is kept as
/// given (it means no rotation, which [`check_camera_axis`] allows only with a zero angle).
#[must_use]
pub fn unit_camera_axis(axis: glam::Vec3) -> glam::Vec3 {
    let unit = axis.as_dvec3().normalize_or_zero();
    if unit == glam::DVec3::ZERO {
        axis
    } else {
        unit.as_vec3()
    }
}

/// The camera-axis rule: a rotation by a non-zero angle needs a non-zero axis (judged in f64, as
/// [`unit_camera_axis`] normalises it).
///
/// # Errors
/// A message naming both settings.
pub fn check_camera_axis(axis: glam::Vec3, angle_deg: f32) -> Result<(), String> {
    if angle_deg != 0.0 && axis.as_dvec3().normalize_or_zero() == glam::DVec3::ZERO {
        return Err(format!(
            "{} must not be (0, 0, 0) when {} is not 0: a rotation needs an axis",
            Setting::CamAxis.name(),
            Setting::CamAngle.name()
        ));
    }
    Ok(())
}

/// What a front end lets one render use; [`RenderSettings::check`] holds settings to it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// The range of each setting.
    pub ranges: Ranges,
    /// Most pixels in the image.
    pub max_pixels: u64,
    /// Most bytes the image buffers may take ([`BYTES_PER_PIXEL`] a pixel).
    pub memory_bytes: u64,
    /// Most grid samples in the whole image, `-x` N² a pixel, whatever `-q` (`None`: no bound).
    pub max_grid_samples: Option<u64>,
    /// Most samples in the whole image, counting every `-q` path (`None`: no bound).
    pub max_samples: Option<u64>,
    /// What to tell a user who goes over `max_pixels` (e.g. the flag that lifts it).
    pub pixel_hint: &'static str,
    /// Where `memory_bytes` comes from, for the message.
    pub memory_hint: &'static str,
}

impl Limits {
    /// The command line's limits: [`Ranges::COMMAND_LINE`]; unless `allow_large`, 64 megapixels
    /// and 16 grid samples a pixel at that size (2^30 in all); and in either case image buffers
    /// that fit in three quarters of the memory available now.
    #[must_use]
    pub fn command_line(allow_large: bool) -> Limits {
        const PIXEL_BUDGET: u64 = 8192 * 8192;
        let available = available_memory().map_or(u64::MAX, |m| m / 4 * 3);
        if allow_large {
            Limits {
                ranges: Ranges::COMMAND_LINE,
                max_pixels: 1 << 30,
                memory_bytes: available,
                max_grid_samples: None,
                max_samples: None,
                pixel_hint: " (2^30), the most rayscope renders even with --allow-large",
                memory_hint: " (three quarters of the memory available now)",
            }
        } else {
            Limits {
                ranges: Ranges::COMMAND_LINE,
                max_pixels: PIXEL_BUDGET,
                memory_bytes: available.min(PIXEL_BUDGET * BYTES_PER_PIXEL),
                max_grid_samples: Some(16 * PIXEL_BUDGET),
                max_samples: None,
                pixel_hint: " (8192×8192); pass --allow-large to render it anyway",
                memory_hint: " (2 GiB, or three quarters of the memory available now if less)",
            }
        }
    }

    /// The debugger's limits: [`Ranges::DEBUGGER`], images up to its side squared, and at most
    /// 2^28 samples counting every `-q` path (about a minute of path tracing on two cores), so
    /// no request to the shared server can start a render that outlives the user's patience; a
    /// new request cancels it in any case.
    #[must_use]
    pub const fn debugger() -> Limits {
        let side = Ranges::DEBUGGER.max_side as u64;
        Limits {
            ranges: Ranges::DEBUGGER,
            max_pixels: side * side,
            memory_bytes: side * side * BYTES_PER_PIXEL,
            max_grid_samples: None,
            max_samples: Some(1 << 28),
            pixel_hint: "",
            memory_hint: "",
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

    /// Checks that a render with these settings fits `limits`, before any work starts: each
    /// setting within its range ([`Ranges::check`]), then the image's size, memory and samples.
    ///
    /// # Errors
    /// A message that names the settings at fault and the bound they break.
    pub fn check(&self, limits: &Limits) -> Result<(), String> {
        limits.ranges.check(self)?;
        let (w, h) = (self.width, self.height);
        let pixels = w as u64 * h as u64;
        if let Some(max) = limits.max_grid_samples {
            let samples = pixels * u64::from(self.aa).pow(2);
            if samples > max {
                return Err(format!(
                    "{samples} samples ({w}×{h} pixels at -x {}) is over the budget; pass --allow-large",
                    self.aa
                ));
            }
        }
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

/// A change to some render settings, by the names the debugger's settings API takes: every
/// field is optional, and one given replaces that setting. [`SettingsPatch::of`] is every setting
/// (the API's answer); a diagnosis names its settings changes as one.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SettingsPatch {
    /// Image width.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<u32>,
    /// Image height.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height: Option<u32>,
    /// `-x`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aa: Option<u32>,
    /// Stage: "1", "2", or "full" (also read as "3").
    #[serde(default, skip_serializing_if = "Option::is_none", with = "stage_key")]
    pub stage: Option<Stage>,
    /// `-l`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ambient: Option<bool>,
    /// `-q`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quality: Option<u32>,
    /// `--max-depth`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_depth: Option<u32>,
    /// `--depth-limit`: "mirror-glass" or "all".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_limit: Option<DepthLimit>,
    /// `--seed`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// `--fov` in degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov: Option<f32>,
    /// `--fov-axis`: "horizontal" or "vertical".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov_axis: Option<FovAxis>,
    /// `-p`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cam_pos: Option<[f32; 3]>,
    /// `-a`, normalised as [`unit_camera_axis`] does when applied.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cam_axis: Option<[f32; 3]>,
    /// `-n` in degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cam_angle: Option<f32>,
    /// `-r`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aperture: Option<f32>,
    /// `-t`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub focal_length: Option<f32>,
}

impl SettingsPatch {
    /// Every setting the patch names, taken from `s`.
    #[must_use]
    pub fn of(s: &RenderSettings) -> SettingsPatch {
        let c = &s.camera;
        SettingsPatch {
            width: Some(s.width),
            height: Some(s.height),
            aa: Some(s.aa),
            stage: Some(s.stage),
            ambient: Some(s.ambient),
            quality: Some(s.quality),
            max_depth: Some(s.max_depth),
            depth_limit: Some(s.depth_limit),
            seed: Some(s.seed),
            fov: Some(c.fov_deg),
            fov_axis: Some(c.fov_axis),
            cam_pos: Some(c.position.to_array()),
            cam_axis: Some(c.axis.to_array()),
            cam_angle: Some(c.angle_deg),
            aperture: Some(c.aperture_radius),
            focal_length: Some(c.focal_length),
        }
    }

    /// `s` with the patch's settings in place of its own (to be checked against a front end's
    /// [`Limits`] before a render).
    #[must_use]
    pub fn apply(&self, s: &RenderSettings) -> RenderSettings {
        let mut s = *s;
        let c = &mut s.camera;
        let set = |slot: &mut u32, v: Option<u32>| *slot = v.unwrap_or(*slot);
        set(&mut s.width, self.width);
        set(&mut s.height, self.height);
        set(&mut s.aa, self.aa);
        set(&mut s.quality, self.quality);
        set(&mut s.max_depth, self.max_depth);
        s.stage = self.stage.unwrap_or(s.stage);
        s.ambient = self.ambient.unwrap_or(s.ambient);
        s.depth_limit = self.depth_limit.unwrap_or(s.depth_limit);
        s.seed = self.seed.unwrap_or(s.seed);
        c.fov_deg = self.fov.unwrap_or(c.fov_deg);
        c.fov_axis = self.fov_axis.unwrap_or(c.fov_axis);
        c.position = self.cam_pos.map_or(c.position, glam::Vec3::from);
        c.axis = self.cam_axis.map_or(c.axis, |a| unit_camera_axis(glam::Vec3::from(a)));
        c.angle_deg = self.cam_angle.unwrap_or(c.angle_deg);
        c.aperture_radius = self.aperture.unwrap_or(c.aperture_radius);
        c.focal_length = self.focal_length.unwrap_or(c.focal_length);
        s
    }

    /// The settings the patch names, in [`Setting::ALL`]'s order.
    #[must_use]
    pub fn settings(&self) -> Vec<Setting> {
        let named = [
            (Setting::Width, self.width.is_some()),
            (Setting::Height, self.height.is_some()),
            (Setting::Stage, self.stage.is_some()),
            (Setting::Aa, self.aa.is_some()),
            (Setting::Ambient, self.ambient.is_some()),
            (Setting::Quality, self.quality.is_some()),
            (Setting::DepthLimit, self.depth_limit.is_some()),
            (Setting::MaxDepth, self.max_depth.is_some()),
            (Setting::CamPos, self.cam_pos.is_some()),
            (Setting::CamAxis, self.cam_axis.is_some()),
            (Setting::CamAngle, self.cam_angle.is_some()),
            (Setting::Fov, self.fov.is_some()),
            (Setting::FovAxis, self.fov_axis.is_some()),
            (Setting::Aperture, self.aperture.is_some()),
            (Setting::FocalLength, self.focal_length.is_some()),
            (Setting::Seed, self.seed.is_some()),
        ];
        named.into_iter().filter(|n| n.1).map(|n| n.0).collect()
    }
}

/// A patch's stage as the debugger's API writes it: "1", "2" or "full" ("3" is read as "full").
mod stage_key {
    use serde::de::Error;
    use serde::{Deserialize, Deserializer, Serializer};

    use super::Stage;

    pub(super) fn serialize<S: Serializer>(v: &Option<Stage>, s: S) -> Result<S::Ok, S::Error> {
        match v {
            Some(Stage::One) => s.serialize_str("1"),
            Some(Stage::Two) => s.serialize_str("2"),
            Some(Stage::Full) => s.serialize_str("full"),
            None => s.serialize_none(),
        }
    }

    pub(super) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Stage>, D::Error> {
        Ok(match Option::<String>::deserialize(d)?.as_deref() {
            None => None,
            Some("1") => Some(Stage::One),
            Some("2") => Some(Stage::Two),
            Some("3" | "full") => Some(Stage::Full),
            Some(other) => return Err(D::Error::custom(format!("stage must be 1, 2 or full, not '{other}'"))),
        })
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
            ranges: Ranges::COMMAND_LINE,
            max_grid_samples: None,
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
            ranges: Ranges::COMMAND_LINE,
            max_grid_samples: None,
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
