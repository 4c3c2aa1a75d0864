//! Command-line flags (clap) and their conversion into validated library settings.

use std::ffi::OsStr;
use std::path::PathBuf;

use clap::error::ErrorKind;
use clap::{Args, Parser, Subcommand, ValueEnum};
use glam::Vec3;
use rayscope_core::mistakes::catalogue_text;
use rayscope_core::settings::{unit_camera_axis, Limits, Ranges, Setting};
use rayscope_core::Mistakes;
use rayscope_core::{CameraSettings, Channel, DepthLimit, Edition, FovAxis, RenderSettings, Stage};

/// rayscope: a ray tracer and visual ray debugger for the COMP30019 scene format.
///
/// With no subcommand it renders like the course's program:
///   rayscope -f scene.txt -o out.png -x 4
#[derive(Debug, Parser)]
#[command(
    name = "rayscope",
    version,
    disable_help_flag = true,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    after_help = "Pixel coordinates are 0-based from the top-left. `-h` is the image height; help is `--help`."
)]
pub struct Cli {
    /// Print help.
    #[arg(long, action = clap::ArgAction::Help, global = true)]
    pub help: Option<bool>,
    /// Render flags (the course's command line).
    #[command(flatten)]
    pub render: RenderArgs,
    /// Tools beside rendering.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// Tools beside rendering.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print the ray tree of one pixel sample (text, or JSON with --json).
    Trace(TraceArgs),
    /// Compare two images: PSNR, share of differing pixels, optional heat map.
    Diff(DiffArgs),
    /// Benchmarks: time a render, or closest-hit throughput.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Start the visual debugger in the browser.
    Debug(DebugArgs),
    /// Write the debugger's 3D scene view to an image, headless.
    View(ViewArgs),
    /// Test your own intersector: run it as a child process and send it a battery of rays.
    Probe(ProbeArgs),
    /// Judge every ray your own tracer logged against rayscope's trace of the scene.
    Check(CheckArgs),
    /// List the course's common mistakes that --mistake renders and diagnose looks for.
    Mistakes,
    /// Explain a wrong picture: where it differs from rayscope's, and which mistakes explain it.
    Diagnose(DiagnoseArgs),
    /// Join the parts of a farm render (`--part K/N`) into the image one render would give.
    Merge(MergeArgs),
}

/// `rayscope merge`.
#[derive(Debug, Clone, Args)]
pub struct MergeArgs {
    /// The part files (EXR files written with --part K/N), in any order.
    #[arg(required = true, value_name = "PART")]
    pub parts: Vec<PathBuf>,
    /// The image to write (.png, .exr or .ppm), as the render would have written it.
    #[arg(short = 'o', long = "output", value_name = "IMAGE")]
    pub output: PathBuf,
    /// Write the image even if parts are missing (their tiles black), naming what is absent.
    #[arg(long = "allow-missing")]
    pub allow_missing: bool,
    /// Merge images over the pixel budget (64 megapixels), as a render's --allow-large.
    #[arg(long = "allow-large")]
    pub allow_large: bool,
    /// No summary.
    #[arg(long)]
    pub quiet: bool,
}

/// Which of the course's stages to render.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum StageArg {
    /// Flat material colour, one ray per pixel.
    #[value(name = "1")]
    One,
    /// Whitted: point lights, shadows, mirrors, Fresnel glass.
    #[value(name = "2")]
    Two,
    /// Everything, stage-3 add-ons included (the default).
    #[value(name = "3")]
    Three,
}

/// FOV axis flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FovAxisArg {
    /// The angle spans the image width (the course).
    Horizontal,
    /// The angle spans the image height (the Unity workshop).
    Vertical,
}

/// Course edition flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EditionArg {
    /// The 2021 course: a glass (Refractive) colour plays no part.
    #[value(name = "2021")]
    Y2021,
    /// The 2022 course, the current template: a glass colour is Beer's-law absorbance (stage 3 F).
    #[value(name = "2022")]
    Y2022,
}

/// Recursion-limit semantics flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DepthLimitArg {
    /// A mirror or glass hit on a ray of depth N or more returns black; other hits are shaded.
    MirrorGlass,
    /// Every ray of depth over N returns black, whatever it hits.
    All,
}

/// Debug channel flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ChannelArg {
    /// Rendered colour.
    Color,
    /// Shading normal.
    Normal,
    /// Distance to the first hit.
    Depth,
    /// A colour per entity.
    Entity,
    /// Material colour of the first hit.
    Albedo,
    /// BVH traversal cost heat map.
    Cost,
}

/// The course's flags plus rayscope's extras.
#[derive(Debug, Clone, Args)]
pub struct RenderArgs {
    /// Scene file to render.
    #[arg(short = 'f', long = "file", required = true, value_name = "SCENE")]
    pub file: Option<PathBuf>,
    /// Output image (.png, .exr or .ppm).
    #[arg(short = 'o', long = "output", required = true, value_name = "IMAGE")]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub opts: RenderOpts,
    #[command(flatten)]
    pub farm: FarmArgs,
}

/// Farm and animation flags of a render (docs/farm.md).
#[derive(Debug, Clone, Args)]
pub struct FarmArgs {
    /// Render only part K of N (K from 0 to N-1) into an EXR part; `rayscope merge` joins parts.
    #[arg(long, value_name = "K/N", value_parser = rayscope_core::farm::PartSpec::parse)]
    pub part: Option<rayscope_core::farm::PartSpec>,
    /// Render frames A to B (both included, at most 100000 frames) of an animation, each to a
    /// numbered file (a run of `#` in -o becomes the frame number, else `_NNNN` goes before the
    /// extension).
    #[arg(long, value_name = "A..B", value_parser = parse_frames)]
    pub frames: Option<(u32, u32)>,
    /// Circle the point X,Y,Z about the vertical axis over the frames (see --turntable-frames).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true, requires = "frames")]
    pub turntable: Option<Vec3>,
    /// Frames per full turn of --turntable.
    #[arg(long = "turntable-frames", value_name = "N", default_value_t = 120, value_parser = clap::value_parser!(u32).range(1..))]
    pub turntable_frames: u32,
    /// A camera position keyframe, FRAME:X,Y,Z (repeatable; interpolated linearly between frames).
    #[arg(long = "key-p", value_name = "FRAME:X,Y,Z", value_parser = parse_key_vec3, allow_hyphen_values = true, requires = "frames")]
    pub key_p: Vec<(u32, Vec3)>,
    /// A camera axis keyframe, FRAME:X,Y,Z (repeatable).
    #[arg(long = "key-a", value_name = "FRAME:X,Y,Z", value_parser = parse_key_vec3, allow_hyphen_values = true, requires = "frames")]
    pub key_a: Vec<(u32, Vec3)>,
    /// A camera angle keyframe, FRAME:DEGREES (repeatable).
    #[arg(long = "key-n", value_name = "FRAME:DEG", value_parser = parse_key_f32, allow_hyphen_values = true, requires = "frames")]
    pub key_n: Vec<(u32, f32)>,
}

impl FarmArgs {
    /// The camera path the flags describe.
    pub fn camera_path(&self) -> Result<rayscope_core::animation::CameraPath, String> {
        use rayscope_core::animation::{CameraPath, Keys, Turntable};
        if let Some((_, a)) = self.key_a.iter().find(|(_, a)| *a == Vec3::ZERO) {
            return Err(format!("--key-a {a}: an axis must not be (0, 0, 0)"));
        }
        Ok(CameraPath {
            position: Keys::new(self.key_p.clone(), "--key-p")?,
            axis: Keys::new(self.key_a.clone(), "--key-a")?,
            angle: Keys::new(self.key_n.clone(), "--key-n")?,
            turntable: self.turntable.map(|center| Turntable {
                center,
                frames: self.turntable_frames,
            }),
        })
    }
}

/// Most frames one `--frames` run renders: 69 minutes at 24 frames a second. Frames are rendered
/// one after another and nothing is kept per frame; the bound catches a mistyped range.
pub const MAX_FRAMES: u32 = 100_000;

fn parse_frames(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("expected frames A..B such as 0..119 (both included), or one frame N, found '{s}'");
    let (a, b) = match s.split_once("..") {
        Some((a, b)) => (a, b),
        None => (s, s),
    };
    let a: u32 = a.trim().parse().map_err(|_| bad())?;
    let b: u32 = b.trim().parse().map_err(|_| bad())?;
    if b < a {
        return Err(format!("--frames {s}: the last frame comes before the first"));
    }
    if b - a >= MAX_FRAMES {
        return Err(format!(
            "--frames {s} is {} frames; one run renders at most {MAX_FRAMES}: split the range over several runs (or array tasks)",
            u64::from(b - a) + 1
        ));
    }
    Ok((a, b))
}

fn split_key(s: &str) -> Result<(u32, &str), String> {
    let (f, v) = s
        .split_once(':')
        .ok_or_else(|| format!("expected FRAME:VALUE such as 30:0,1,0, found '{s}'"))?;
    let f = f
        .trim()
        .parse()
        .map_err(|_| format!("expected a frame number before ':', found '{f}' in '{s}'"))?;
    Ok((f, v))
}

fn parse_key_vec3(s: &str) -> Result<(u32, Vec3), String> {
    let (f, v) = split_key(s)?;
    Ok((f, parse_vec3(v)?))
}

fn parse_key_f32(s: &str) -> Result<(u32, f32), String> {
    let (f, v) = split_key(s)?;
    Ok((f, parse_finite(v)?))
}

/// Flags that shape a render, shared by rendering, `trace`, `view`, `debug` and `bench`.
#[derive(Debug, Clone, Args)]
pub struct RenderOpts {
    /// Image width in pixels.
    #[arg(short = 'w', long = "width", default_value_t = 400, allow_hyphen_values = true, value_parser = parse_size)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(short = 'h', long = "height", default_value_t = 400, allow_hyphen_values = true, value_parser = parse_height)]
    pub height: u32,
    /// Anti-aliasing: an N×N grid of samples per pixel.
    #[arg(short = 'x', long = "aa-mult", default_value_t = 1, allow_hyphen_values = true, value_parser = parse_aa, value_name = "N")]
    pub aa: u32,
    /// Ambient (indirect) lighting, stage 3.
    #[arg(short = 'l', long = "ambient")]
    pub ambient: bool,
    /// Camera position "x,y,z".
    #[arg(short = 'p', long = "cam-pos", default_value = "0,0,0", value_parser = parse_vec3, allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub cam_pos: Vec3,
    /// Camera rotation axis "x,y,z".
    #[arg(short = 'a', long = "cam-axis", default_value = "0,0,1", value_parser = parse_vec3, allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub cam_axis: Vec3,
    /// Camera rotation angle about the axis, in degrees.
    #[arg(short = 'n', long = "cam-angle", default_value_t = 0.0, value_parser = parse_finite, allow_hyphen_values = true, value_name = "DEG")]
    pub cam_angle: f32,
    /// Lens radius for depth of field (0: pinhole).
    #[arg(short = 'r', long = "aperture-radius", default_value_t = 0.0, allow_hyphen_values = true, value_parser = parse_aperture, value_name = "R")]
    pub aperture: f32,
    /// Distance in focus.
    #[arg(short = 't', long = "focal-length", default_value_t = 1.0, allow_hyphen_values = true, value_parser = parse_focal_length, value_name = "D")]
    pub focal_length: f32,
    /// Quality: more samples for stochastic effects.
    #[arg(short = 'q', long = "quality", default_value_t = 0, value_parser = parse_quality, value_name = "Q")]
    pub quality: u32,
    /// Render only up to this stage of the course.
    #[arg(long, value_enum)]
    pub stage: Option<StageArg>,
    /// Field of view in degrees (above 180 the picture turns half a turn).
    #[arg(long, default_value_t = 60.0, value_parser = parse_fov)]
    pub fov: f32,
    /// Which image side the field of view spans.
    #[arg(long = "fov-axis", value_enum, default_value_t = FovAxisArg::Horizontal)]
    pub fov_axis: FovAxisArg,
    /// Most secondary bounces for mirrors and glass (N; see --depth-limit).
    #[arg(long = "max-depth", default_value_t = 8, value_parser = parse_max_depth, value_name = "N")]
    pub max_depth: u32,
    /// What --max-depth N stops. The camera ray has depth 0 and each reflected, refracted or
    /// bounce ray one more than the ray whose hit sent it. mirror-glass: a mirror or glass hit on
    /// a ray of depth N or more returns black (-l's bounces do not count). all: every ray of depth
    /// over N returns black whatever it hits, -l's bounces counted, as `if (depth > maxDepth)
    /// return black` at the top of Trace(ray, depth). Whitted (stage 2) images are the same
    /// under both.
    #[arg(long = "depth-limit", value_enum, default_value_t = DepthLimitArg::MirrorGlass, value_name = "RULE")]
    pub depth_limit: DepthLimitArg,
    /// The course edition the scene is read by: 2021 (a glass colour plays no part) or 2022 (a
    /// glass colour is Beer's-law absorbance per unit distance, stage 3 F).
    #[arg(long, value_enum, default_value_t = EditionArg::Y2022, value_name = "YEAR")]
    pub edition: EditionArg,
    /// Seed for every random stream.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Write a debug channel instead of the colour.
    #[arg(long = "aov", value_enum, default_value_t = ChannelArg::Color)]
    pub aov: ChannelArg,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// No progress bar, warnings or summary.
    #[arg(long)]
    pub quiet: bool,
    /// Allow images over the pixel budget (64 megapixels).
    #[arg(long = "allow-large")]
    pub allow_large: bool,
    /// Render as a tracer with these common mistakes would (`--mistake help` lists them).
    #[arg(long = "mistake", value_name = "NAME[,NAME…]", value_parser = MistakeParser)]
    pub mistake: Option<rayscope_core::Mistakes>,
}

impl RenderOpts {
    /// Validates the flags together and converts them into render settings.
    pub fn settings(&self) -> Result<RenderSettings, String> {
        let settings = RenderSettings {
            width: self.width,
            height: self.height,
            aa: self.aa,
            stage: match self.stage {
                Some(StageArg::One) => Stage::One,
                Some(StageArg::Two) => Stage::Two,
                Some(StageArg::Three) | None => Stage::Full,
            },
            ambient: self.ambient,
            quality: self.quality,
            max_depth: self.max_depth,
            depth_limit: match self.depth_limit {
                DepthLimitArg::MirrorGlass => DepthLimit::MirrorGlass,
                DepthLimitArg::All => DepthLimit::All,
            },
            edition: match self.edition {
                EditionArg::Y2021 => Edition::Y2021,
                EditionArg::Y2022 => Edition::Y2022,
            },
            camera: CameraSettings {
                position: self.cam_pos,
                axis: unit_camera_axis(self.cam_axis),
                angle_deg: self.cam_angle,
                fov_deg: self.fov,
                fov_axis: match self.fov_axis {
                    FovAxisArg::Horizontal => FovAxis::Horizontal,
                    FovAxisArg::Vertical => FovAxis::Vertical,
                },
                aperture_radius: self.aperture,
                focal_length: self.focal_length,
            },
            seed: self.seed,
            channel: match self.aov {
                ChannelArg::Color => Channel::Color,
                ChannelArg::Normal => Channel::Normal,
                ChannelArg::Depth => Channel::Depth,
                ChannelArg::Entity => Channel::Entity,
                ChannelArg::Albedo => Channel::Albedo,
                ChannelArg::Cost => Channel::Cost,
            },
            mistakes: self.mistake.unwrap_or_default(),
        };
        settings.check(&Limits::command_line(self.allow_large))?;
        Ok(settings)
    }
}

/// `rayscope trace`.
#[derive(Debug, Clone, Args)]
pub struct TraceArgs {
    /// Scene file.
    #[arg(short = 'f', long = "file", value_name = "SCENE")]
    pub file: PathBuf,
    /// Pixel "X,Y", 0-based from the top-left.
    #[arg(long, value_parser = parse_pixel, value_name = "X,Y")]
    pub pixel: (u32, u32),
    /// Sample index within the pixel (0-based; the N×N grid is row-major).
    #[arg(long, default_value_t = 0)]
    pub sample: u32,
    /// Print JSON (schema in docs/debugger.md, numbers at full precision) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Decimals of the numbers in the text (very small ones switch to scientific notation).
    #[arg(long, default_value_t = 4, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=12))]
    pub precision: u8,
    #[command(flatten)]
    pub opts: RenderOpts,
}

/// `rayscope bench …`.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Time a render (median of several runs, render loop only).
    Render(BenchRenderArgs),
    /// Closest-hit throughput: build the BVH, trace a batch of rays, report Mrays/s.
    ///
    /// Rays go one at a time (walks interleaved for scattered rays in trees over 16 MiB) or, with
    /// --packets, as packets of 16.
    Rays(BenchRaysArgs),
}

/// `rayscope bench rays`.
#[derive(Debug, Clone, Args)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["primary", "rays_file"])))]
pub struct BenchRaysArgs {
    /// Scene file.
    #[arg(short = 'f', long = "file", value_name = "SCENE")]
    pub file: PathBuf,
    /// Trace the primary rays of a WxH image from the scene's default camera.
    #[arg(long, value_parser = parse_wxh, value_name = "WxH")]
    pub primary: Option<(u32, u32)>,
    /// Trace rays from a file of little-endian f32 records (ox, oy, oz, dx, dy, dz).
    #[arg(long = "rays-file", value_name = "FILE")]
    pub rays_file: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// Timed passes over the rays; the median is reported.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub repeat: u32,
    /// Trace the rays as packets of 16, as renders trace camera and shadow rays: consecutive
    /// rays of the file, or 4×4 pixel blocks of the primary image.
    #[arg(long)]
    pub packets: bool,
    /// Walk every ray alone, one after another, even where interleaving the walks of scattered
    /// rays would be faster (to measure the plain single-ray walk).
    #[arg(long, conflicts_with = "packets")]
    pub no_interleave: bool,
    /// Also print how many nodes and leaves a ray's closest-hit walk tests, on average, for the
    /// rays that hit and for those that miss (counted in a pass of its own, not timed).
    #[arg(long)]
    pub visits: bool,
}

/// `rayscope bench render`.
#[derive(Debug, Clone, Args)]
pub struct BenchRenderArgs {
    /// Scene file.
    #[arg(short = 'f', long = "file", value_name = "SCENE")]
    pub file: PathBuf,
    /// Timed runs (after one warm-up).
    #[arg(long, default_value_t = 7, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub repeat: u32,
    #[command(flatten)]
    pub opts: RenderOpts,
}

/// `rayscope debug`.
#[derive(Debug, Clone, Args)]
pub struct DebugArgs {
    /// Scene file.
    pub scene: PathBuf,
    /// Port (default: a free one).
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    /// Address to bind (default 127.0.0.1: only this machine can connect).
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// A host name the debugger answers to besides localhost and IP addresses (repeatable): the
    /// name other machines use to reach it with `--host 0.0.0.0`.
    #[arg(long, value_name = "NAME")]
    pub allow_host: Vec<String>,
    /// Open the browser.
    #[arg(long)]
    pub open: bool,
    /// Your tracer's ray log (JSON Lines, or RayTracer.Debug's `.rays`): judged as `rayscope check`
    /// does, shown as a verdict map and as your rays beside rayscope's (docs/debugger.md).
    #[arg(long = "rays", value_name = "LOG")]
    pub rays: Option<PathBuf>,
    /// Your tracer's image (PNG, JPEG or PPM), shown beside rayscope's render.
    #[arg(long = "image", value_name = "IMAGE")]
    pub image: Option<PathBuf>,
    /// What a `.rays` file's ids mean: "x,y" (default), e.g. "x,y,sample,id,parent", or "none".
    #[arg(long = "ray-ids", default_value = "x,y", value_name = "ROLES")]
    pub ray_ids: String,
    /// Skip malformed lines of the ray log, counting them, instead of refusing it.
    #[arg(long)]
    pub lenient: bool,
    #[command(flatten)]
    pub opts: RenderOpts,
}

/// `rayscope view`.
#[derive(Debug, Clone, Args)]
pub struct ViewArgs {
    /// Scene file.
    #[arg(short = 'f', long = "file", value_name = "SCENE")]
    pub file: PathBuf,
    /// Output image (.png).
    #[arg(short = 'o', long = "output", value_name = "IMAGE")]
    pub output: PathBuf,
    /// Eye position of the view camera "x,y,z" (default: a three-quarter view).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<Vec3>,
    /// Point the view camera looks at "x,y,z".
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub target: Option<Vec3>,
    /// Debug rays: none, frustum, pixel:X,Y, row:Y, all.
    #[arg(long, default_value = "frustum")]
    pub rays: String,
    /// Show the traced image on the grid ("traced"), a black grid ("black") or none ("none").
    #[arg(long, default_value = "traced")]
    pub image: String,
    /// With --rays pixel:X,Y: also draw the pixel's sub-pixel samples (and lens samples).
    #[arg(long)]
    pub samples: bool,
    /// With --rays pixel:X,Y: also draw the pixel's ray tree (sample 0), coloured by kind.
    #[arg(long)]
    pub tree: bool,
    /// Highlight entity NAME and draw its normals as arrows (a triangle's vertices numbered, so
    /// its winding shows).
    #[arg(long, value_name = "ENTITY")]
    pub normals: Option<String>,
    /// Your tracer's ray log: draws your rays dashed (those of --rays pixel:X,Y, else of pixels
    /// spread over the image) and the verdict map on the grid (red: disagrees).
    #[arg(long = "rays-log", value_name = "LOG")]
    pub rays_log: Option<PathBuf>,
    /// What a `.rays` file's ids mean: "x,y" (default), e.g. "x,y,sample,id,parent", or "none".
    #[arg(long = "ray-ids", default_value = "x,y", value_name = "ROLES")]
    pub ray_ids: String,
    /// Skip malformed lines of the ray log instead of refusing it.
    #[arg(long)]
    pub lenient: bool,
    /// View width in pixels.
    #[arg(long = "view-width", default_value_t = 960, value_parser = clap::value_parser!(u32).range(16..=8192))]
    pub view_width: u32,
    /// View height in pixels.
    #[arg(long = "view-height", default_value_t = 640, value_parser = clap::value_parser!(u32).range(16..=8192))]
    pub view_height: u32,
    #[command(flatten)]
    pub opts: RenderOpts,
}

/// `rayscope probe`.
#[derive(Debug, Clone, Args)]
pub struct ProbeArgs {
    /// Scene file whose spheres, planes, triangles and mesh triangles are tested.
    #[arg(short = 'f', long = "file", value_name = "SCENE")]
    pub file: PathBuf,
    /// Seconds to wait for each answer before giving up on the program.
    #[arg(long, default_value_t = 5.0, value_parser = parse_positive_f64, value_name = "SECS")]
    pub timeout: f64,
    /// Seconds to wait for the program's first line (it may compile first, as `dotnet run` does).
    #[arg(long = "startup-timeout", default_value_t = 60.0, value_parser = parse_positive_f64, value_name = "SECS")]
    pub startup_timeout: f64,
    /// Rays per case and primitive.
    #[arg(long = "rays-per-case", default_value_t = 6, value_parser = clap::value_parser!(u32).range(1..=1000), value_name = "N")]
    pub rays_per_case: u32,
    /// Triangles tested from each OBJ mesh (spread evenly over the mesh).
    #[arg(long = "mesh-triangles", default_value_t = 8, value_parser = clap::value_parser!(u32).range(0..=100_000), value_name = "N")]
    pub mesh_triangles: u32,
    /// Seed of the random rays.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Print the report as JSON (schema in docs/probe.md).
    #[arg(long)]
    pub json: bool,
    /// Show every example of each finding, not just the first.
    #[arg(long = "all-examples")]
    pub all_examples: bool,
    /// The program to run and its arguments, after `--`.
    #[arg(last = true, required = true, value_name = "COMMAND")]
    pub command: Vec<String>,
}

fn parse_positive_f64(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("expected a number of seconds greater than 0, found '{s}'")),
    }
}

/// `rayscope check`.
#[derive(Debug, Clone, Args)]
pub struct CheckArgs {
    /// Scene file.
    #[arg(short = 'f', long = "file", value_name = "SCENE")]
    pub file: PathBuf,
    /// Your tracer's ray log: JSON Lines (docs/check.md), or RayTracer.Debug's binary `.rays`.
    #[arg(long = "rays", value_name = "LOG")]
    pub rays: PathBuf,
    /// Print JSON (for scripts and autograders) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Skip malformed lines, counting them, instead of stopping at the first.
    #[arg(long)]
    pub lenient: bool,
    /// What a `.rays` file's ids mean: "x,y" (default), e.g. "x,y,sample,id,parent", or "none".
    #[arg(long = "ray-ids", default_value = "x,y", value_name = "ROLES")]
    pub ray_ids: String,
    /// Examples shown per verdict.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(0..=1000))]
    pub examples: u32,
    /// Your tracer's picture (PNG) from the same run: its bytes are checked against the colours
    /// your camera rays logged (clamp, trunc(v · 255), samples averaged).
    #[arg(long, value_name = "PNG")]
    pub image: Option<PathBuf>,
    #[command(flatten)]
    pub opts: RenderOpts,
}

/// A whole-number `setting`, within the command line's range of it ([`Ranges::COMMAND_LINE`]).
fn parse_whole(s: &str, setting: Setting) -> Result<u32, String> {
    match s.trim().parse::<i64>() {
        Ok(v) => Ranges::COMMAND_LINE.whole(setting, v),
        Err(_) => Err(format!("expected a whole number, found '{s}'")),
    }
}

fn parse_size(s: &str) -> Result<u32, String> {
    parse_whole(s, Setting::Width)
}

fn parse_height(s: &str) -> Result<u32, String> {
    parse_whole(s, Setting::Height)
}

fn parse_aa(s: &str) -> Result<u32, String> {
    parse_whole(s, Setting::Aa)
}

fn parse_finite(s: &str) -> Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("expected a number, found '{s}'"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("expected a finite number, found '{s}'"))
    }
}

fn parse_quality(s: &str) -> Result<u32, String> {
    parse_whole(s, Setting::Quality)
}

fn parse_max_depth(s: &str) -> Result<u32, String> {
    parse_whole(s, Setting::MaxDepth)
}

fn parse_real(s: &str, setting: Setting) -> Result<f32, String> {
    Ranges::COMMAND_LINE.real(setting, parse_finite(s)?)
}

fn parse_aperture(s: &str) -> Result<f32, String> {
    parse_real(s, Setting::Aperture)
}

fn parse_focal_length(s: &str) -> Result<f32, String> {
    parse_real(s, Setting::FocalLength)
}

fn parse_fov(s: &str) -> Result<f32, String> {
    parse_real(s, Setting::Fov)
}

/// Parses "x,y,z" (spaces and surrounding parentheses allowed) into a finite vector.
pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let inner = s.trim().trim_start_matches('(').trim_end_matches(')');
    let parts: Vec<&str> = inner.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected three numbers \"x,y,z\", found '{s}'"));
    }
    let mut v = [0.0f32; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        *slot = parse_finite(p).map_err(|e| format!("{e} in '{s}'"))?;
    }
    Ok(Vec3::from(v))
}

fn parse_wxh(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WxH such as 1024x1024, found '{s}'"))?;
    Ok((parse_size(w)?, parse_size(h)?))
}

fn parse_pixel(s: &str) -> Result<(u32, u32), String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    match parts.as_slice() {
        [x, y] => match (x.parse(), y.parse()) {
            (Ok(x), Ok(y)) => Ok((x, y)),
            _ => Err(format!("expected two whole numbers \"x,y\", found '{s}'")),
        },
        _ => Err(format!("expected two whole numbers \"x,y\", found '{s}'")),
    }
}

/// `rayscope diff`.
#[derive(Debug, Clone, Args)]
pub struct DiffArgs {
    /// First image.
    pub a: PathBuf,
    /// Second image.
    pub b: PathBuf,
    /// Write a difference heat map here: each channel is that channel's |a − b|, with a scale
    /// bar under the image.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Heat map: the difference (in 8-bit levels) shown at full brightness; default: chosen
    /// from the images (all but the 1 % most different of the differing pixels fit).
    #[arg(long, value_name = "LEVELS", value_parser = clap::value_parser!(u8).range(1..=255))]
    pub range: Option<u8>,
    /// Heat map without the scale bar, the size of the images.
    #[arg(long = "no-legend")]
    pub no_legend: bool,
    /// Succeed when PSNR ≥ DB instead of requiring identical images.
    #[arg(long, value_name = "DB")]
    pub tol: Option<f64>,
    /// Scene the images were rendered from: say which entities the differing pixels show,
    /// through rayscope's ray tree of each (render flags as for the render; the size is the
    /// images' unless -w/-h say otherwise).
    #[arg(long, value_name = "SCENE")]
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub opts: RenderOpts,
}

/// `rayscope diagnose`.
#[derive(Debug, Clone, Args)]
pub struct DiagnoseArgs {
    /// Scene file the image was rendered from.
    #[arg(short = 'f', long = "file", value_name = "SCENE")]
    pub file: PathBuf,
    /// The image to explain (PNG); its size is the render's unless -w/-h say otherwise.
    #[arg(value_name = "IMAGE")]
    pub image: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Try single mistakes and settings only, not pairs.
    #[arg(long = "no-pairs")]
    pub no_pairs: bool,
    #[command(flatten)]
    pub opts: RenderOpts,
}

/// Parses `--mistake` values; `help` prints the catalogue.
#[derive(Debug, Clone, Copy)]
pub struct MistakeParser;

impl clap::builder::TypedValueParser for MistakeParser {
    type Value = Mistakes;

    fn parse_ref(&self, cmd: &clap::Command, _arg: Option<&clap::Arg>, value: &OsStr) -> Result<Mistakes, clap::Error> {
        let s = value.to_string_lossy();
        if s == "help" {
            // Like --help: the catalogue on stdout, exit 0, whatever else the line lacks.
            print!("{}", catalogue_text());
            std::process::exit(0);
        }
        Mistakes::parse(&s).map_err(|e| {
            clap::Error::raw(
                ErrorKind::ValueValidation,
                format!("invalid value for --mistake: {e}\n"),
            )
            .with_cmd(cmd)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors() {
        assert_eq!(parse_vec3("1,2,3").unwrap(), Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(parse_vec3("(1, -2, .5)").unwrap(), Vec3::new(1.0, -2.0, 0.5));
        assert!(parse_vec3("1,2").is_err());
        assert!(parse_vec3("1,2,x").is_err());
        assert!(parse_vec3("1,2,inf").is_err());
    }

    /// Settings with every flag away from its default, written as flags and read back by the
    /// command line, come back the same: what `check` and the debugger print for a student to
    /// paste replays the render they judged.
    #[test]
    fn settings_written_as_flags_read_back_the_same() {
        #[derive(Parser)]
        #[command(disable_help_flag = true)]
        struct T {
            #[command(flatten)]
            o: RenderOpts,
        }
        let mistakes = rayscope_core::Mistakes::parse("no-shadow-offset,schlick").expect("catalogue names");
        let all = RenderSettings {
            width: 120,
            height: 90,
            aa: 3,
            stage: Stage::Two,
            ambient: true,
            quality: 2,
            max_depth: 3,
            depth_limit: DepthLimit::All,
            edition: Edition::Y2021,
            camera: CameraSettings {
                position: Vec3::new(1.0, -2.5, 0.125),
                axis: Vec3::X,
                angle_deg: 15.0,
                fov_deg: 50.0,
                fov_axis: FovAxis::Vertical,
                aperture_radius: 0.1,
                focal_length: 4.0,
            },
            seed: 7,
            channel: Channel::Color,
            mistakes,
        };
        let normals = RenderSettings {
            channel: Channel::Normal,
            ..RenderSettings::default()
        };
        for s in [all, RenderSettings::default(), normals] {
            let flags = s.flags();
            let args = std::iter::once("rayscope").chain(flags.split(' '));
            let back = T::try_parse_from(args)
                .unwrap_or_else(|e| panic!("{flags}: {e}"))
                .o
                .settings()
                .unwrap_or_else(|e| panic!("{flags}: {e}"));
            assert_eq!(back, s, "{flags}");
        }
    }
}
