//! The debugger's local web app: an axum server with the UI embedded in the binary.
//!
//! Renders run off the request path on blocking threads; a new settings change cancels the
//! render before it through its cancel flag. Every request parameter is validated and bounded
//! and answered with a JSON `{"error": …}` and status 400 when it is not acceptable; every other
//! refusal (403, 404, 405, 408, 413, 414, 415, 431, 503) is the same JSON error.
//!
//! Security: the server answers only `Host` names on its allow-list (see [`HostPolicy`]), and
//! only the debugger's own page may change state or start work (see [`cross_site_refusal`]):
//! `POST`s need `Content-Type: application/json` (settings), `image/png` (compare, the student's
//! image) or `application/x-ndjson` / `application/octet-stream` (a ray log), types a page on
//! another origin cannot send without a preflight, which is never granted. Heavy
//! requests share [`ServerLimits::heavy_slots`]; connections, head reads, bodies and writes are
//! bounded in number and time (see [`ServerLimits`]).
//!
//! Endpoints (all `GET` unless noted):
//! - `/`, `/app.js`, `/app.css`: the UI.
//! - `/api/scene`: entities, lights, materials, settings, limits and a default view.
//! - `/api/settings` (`GET`, `POST` JSON partial update): starts a render job, returns its id.
//! - `/api/render/status`: progress of the current job.
//! - `/api/image.png?channel=color|normal|depth|entity|albedo|cost`: the image (0-based pixels).
//! - `/api/view?eye=x,y,z&target=x,y,z&w=&h=&rays=&image=&channel=&select=&pixel=x,y&tree=1&
//!   sample=&samples=1&check=1&normals=1&format=jpeg|png`: a scene-view frame (`normals=1`: the
//!   selected entity's normals as arrows).
//! - `/api/pick?eye=&target=&w=&h=&x=&y=`: what is under a view pixel.
//! - `/api/trace?x=&y=&sample=&intersector=ours|reference`: a pixel sample's ray tree.
//! - `/api/check`: pixels where rayscope's intersector and the parry3d reference disagree.
//! - `/api/compare` (`POST`, the student's PNG, `Content-Type: image/png`; `GET` again after a
//!   settings change): PSNR against the current render, a heat map with its scale, the
//!   differing pixels attributed to entities and the diagnosis; `/api/compare/pixel?x=&y=`,
//!   `/api/compare/heatmap.png?id=`: see `compare_api`.
//! - `/api/rays` (`POST`, a student's ray log), `/api/rays/summary`, `/api/rays/map.png`,
//!   `/api/rays/pixel`, `/api/rays/image` (`POST`) and `/api/rays/image.png`: see `rays_api`.
//!
//! [`HostPolicy`]: crate::guard::HostPolicy
//! [`cross_site_refusal`]: crate::guard::cross_site_refusal

use std::collections::{HashMap, VecDeque};
use std::net::{IpAddr, SocketAddr, TcpListener as StdListener, ToSocketAddrs};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use axum::body::{Body, Bytes};
use axum::extract::{Query, Request, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use glam::Vec3;
use rayon::prelude::*;
use rayscope_core::integrator::Integrator;
use rayscope_core::reference::ReferenceIntersector;
use rayscope_core::scene::{Intersect, Scene};
use rayscope_core::settings::{Limits, Ranges, SettingsPatch};
use rayscope_core::{render, trace_pixel_with, Channel, RenderSettings};
use rayscope_scene::{SceneFile, Shape};
use serde_json::{json, Value};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

use crate::encode;
use crate::guard::{cross_site_refusal, HostPolicy};
pub use crate::limits::ServerLimits;
use crate::net::MAX_URL_BYTES;
use crate::view::{auto_view, pick, render_view, ImageMode, RayMode, RgbImage, Selection, ViewCamera, ViewOptions};

mod compare_api;
mod rays_api;
use crate::limits::COMPARE_BODY_LIMIT;
pub use crate::limits::{KEEP_LOG_BYTES, RAY_DETAIL_CAP};
pub use rays_api::MAX_LOG_BYTES;

/// Largest image the debugger renders, per side.
pub const MAX_IMAGE_SIDE: u32 = Ranges::DEBUGGER.max_side;
/// Largest view frame, per side.
pub const MAX_VIEW_SIDE: u32 = 2560;
/// Most debug rays drawn in one frame.
pub const MAX_RAYS: u32 = 4096;
/// Largest settings body in bytes.
const SETTINGS_BODY_LIMIT: usize = 16 * 1024;
/// Most a reference PNG's decoder may hold besides its pixels (chunks before the image data).
const REFERENCE_CHUNK_BYTES: u64 = 4 * 1024 * 1024;
/// Most primitive tests the intersector check may cost (pixels × primitives).
const CHECK_BUDGET: u64 = 2_000_000_000;
/// Most mismatches listed (all are counted).
const CHECK_LIST: usize = 5000;

/// Why the debugger could not start.
#[derive(Debug, thiserror::Error)]
pub enum DebugError {
    /// The address could not be bound or resolved.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// Host and port asked for.
        addr: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Anything else going wrong in the server.
    #[error("debugger server failed: {0}")]
    Server(String),
    /// Settings outside the debugger's limits.
    #[error("{0}")]
    Settings(String),
}

/// What `rayscope debug` serves.
#[derive(Debug, Clone)]
pub struct ServeConfig {
    /// The scene file (shown in the UI).
    pub scene_path: PathBuf,
    /// The parsed scene (for the inspector's parameters).
    pub scene_file: SceneFile,
    /// The render-ready scene.
    pub scene: Scene,
    /// Initial render settings.
    pub settings: RenderSettings,
    /// Address to bind (127.0.0.1 keeps it local to this machine).
    pub host: String,
    /// Port (0: any free port).
    pub port: u16,
    /// Host names the server answers to besides `localhost`, IP addresses it listens on and
    /// `host` itself (the `Host` allow-list against DNS rebinding).
    pub allow_hosts: Vec<String>,
    /// Bounds on connections, time and concurrent heavy work.
    pub limits: ServerLimits,
    /// A student's ray log and image to load at the start (`rayscope debug --rays --image`).
    pub student: crate::student::StudentInput,
}

/// A server running on a background thread.
#[derive(Debug)]
pub struct RunningServer {
    /// The address it listens on.
    pub addr: SocketAddr,
    /// The URL to open on this machine.
    pub url: String,
    /// The host names it answers to besides IP addresses (sorted).
    pub host_names: Vec<String>,
    shutdown: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<JoinHandle<Result<(), String>>>,
}

impl RunningServer {
    /// Blocks until the server stops.
    ///
    /// # Errors
    /// If the server failed.
    pub fn wait(mut self) -> Result<(), DebugError> {
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(r)) => r.map_err(DebugError::Server),
            Some(Err(_)) => Err(DebugError::Server("server thread panicked".into())),
            None => Ok(()),
        }
    }

    /// Stops the server and waits for it.
    pub fn stop(mut self) {
        if let Some(tx) = self.shutdown.take() {
            let _ = tx.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Checks that settings fit the debugger's limits ([`Limits::debugger`]).
///
/// # Errors
/// A message naming the offending setting and the bound it breaks.
pub fn check_settings(s: &RenderSettings) -> Result<(), String> {
    s.check(&Limits::debugger())
}

/// Starts the server on a background thread and returns once it listens.
///
/// # Errors
/// If the address cannot be bound, or the settings are outside the debugger's limits.
pub fn start(mut cfg: ServeConfig) -> Result<RunningServer, DebugError> {
    check_settings(&cfg.settings).map_err(DebugError::Settings)?;
    let student = std::mem::take(&mut cfg.student);
    let addr_text = format!("{}:{}", cfg.host, cfg.port);
    let bind_err = |source| DebugError::Bind {
        addr: addr_text.clone(),
        source,
    };
    let addrs: Vec<SocketAddr> = (cfg.host.as_str(), cfg.port)
        .to_socket_addrs()
        .map_err(bind_err)?
        .collect();
    let listener = StdListener::bind(&addrs[..]).map_err(bind_err)?;
    listener.set_nonblocking(true).map_err(bind_err)?;
    let addr = listener.local_addr().map_err(bind_err)?;
    // The name the user bound to is one they will type.
    let mut names = cfg.allow_hosts.clone();
    if cfg.host.parse::<IpAddr>().is_err() {
        names.push(cfg.host.clone());
    }
    let hosts = HostPolicy::new(addr, &names);
    let host = match addr.ip() {
        IpAddr::V4(ip) if ip.is_unspecified() => "127.0.0.1".to_string(),
        IpAddr::V6(ip) if ip.is_unspecified() => "[::1]".to_string(),
        IpAddr::V6(ip) => format!("[{ip}]"),
        IpAddr::V4(ip) => ip.to_string(),
    };
    let url = format!("http://{host}:{}/", addr.port());
    let limits = cfg.limits;
    let host_names = hosts.names().to_vec();
    let state = Arc::new(AppState::new(cfg, hosts));
    state.start_render();
    rays_api::start(&state, student);
    let app = router(state);
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| DebugError::Server(e.to_string()))?;
    let thread = std::thread::Builder::new()
        .name("rayscope-debug-server".into())
        .spawn(move || {
            runtime.block_on(async move {
                let listener = tokio::net::TcpListener::from_std(listener).map_err(|e| e.to_string())?;
                crate::net::serve(listener, app, limits, async move {
                    let _ = rx.await;
                })
                .await;
                Ok(())
            })
        })
        .map_err(|e| DebugError::Server(e.to_string()))?;
    Ok(RunningServer {
        addr,
        url,
        host_names,
        shutdown: Some(tx),
        thread: Some(thread),
    })
}

/// Starts the server, prints its URL, opens a browser when `open` (ignoring failure) and serves
/// until the process is stopped.
///
/// # Errors
/// See [`start`].
pub fn serve(cfg: ServeConfig, open: bool) -> Result<(), DebugError> {
    let server = start(cfg)?;
    if server.addr.ip().is_loopback() {
        say(&format!("rayscope debugger listening on {}", server.url));
    } else {
        let ip = server.addr.ip();
        let port = server.addr.port();
        let shown = server.addr.to_string();
        let which = if ip.is_unspecified() {
            " (every network interface)"
        } else {
            ""
        };
        say(&format!("rayscope debugger listening on http://{shown}/{which}"));
        say(&format!("  on this machine: {}", server.url));
        let names: Vec<String> = server
            .host_names
            .iter()
            .filter(|n| *n != "localhost")
            .map(|n| format!("http://{n}:{port}/"))
            .collect();
        if ip.is_unspecified() {
            say(&format!(
                "  from other machines: http://<this machine's IP address>:{port}/"
            ));
        }
        if !names.is_empty() {
            say(&format!("  by name: {}", names.join(", ")));
        }
        tell(&exposure_warning(&shown));
    }
    say("press Ctrl-C to stop");
    if open {
        let _ = std::process::Command::new("xdg-open")
            .arg(&server.url)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn();
    }
    server.wait()
}

/// Writes a line of the launcher's messages to standard output. Nothing depends on them being
/// read, so a closed pipe (`rayscope debug … | true`) neither stops nor panics the server,
/// which goes on serving.
fn say(line: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{line}").and_then(|()| out.flush());
}

/// [`say`] for standard error.
fn tell(text: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr().lock(), "{text}");
}

/// What `rayscope debug` prints when it listens beyond this machine.
fn exposure_warning(shown: &str) -> String {
    format!(
        "WARNING: the debugger is listening on {shown}, which other machines on the network can reach.\n\
         WARNING: it has no password and no encryption: anyone who can connect sees the scene (and its file\n\
         WARNING: names) and can start renders on this machine. Requests are answered only for this\n\
         WARNING: machine's IP addresses, localhost and names given with --allow-host.\n\
         WARNING: Leave out --host (the default is 127.0.0.1) unless you need this."
    )
}

/// A finished colour render.
struct Rendered {
    job: u64,
    settings: RenderSettings,
    image: Arc<RgbImage>,
    millis: f64,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum JobState {
    Running,
    Done,
    Cancelled,
}

impl JobState {
    fn name(self) -> &'static str {
        match self {
            JobState::Running => "running",
            JobState::Done => "done",
            JobState::Cancelled => "cancelled",
        }
    }
}

struct Job {
    id: u64,
    cancel: Arc<AtomicBool>,
    done: Arc<AtomicU64>,
    total: u64,
    state: JobState,
    started: Instant,
    millis: f64,
}

#[derive(Clone, serde::Serialize)]
struct HitAnswer {
    entity: u32,
    name: String,
    t: f32,
}

#[derive(Clone, serde::Serialize)]
struct Mismatch {
    x: u32,
    y: u32,
    /// "entity", "distance", "missing" or "tie".
    kind: &'static str,
    ours: Option<HitAnswer>,
    reference: Option<HitAnswer>,
}

struct CheckResult {
    settings: RenderSettings,
    json: Value,
    cells: Vec<(u32, u32)>,
}

struct Inner {
    settings: RenderSettings,
    job: Job,
    rendered: Option<Arc<Rendered>>,
    channels: HashMap<&'static str, (RenderSettings, Arc<RgbImage>)>,
    check: Option<Arc<CheckResult>>,
    heatmaps: VecDeque<(u64, Arc<Vec<u8>>)>,
    next_id: u64,
}

struct AppState {
    scene: Arc<Scene>,
    scene_file: Arc<SceneFile>,
    scene_json: Value,
    hosts: HostPolicy,
    limits: ServerLimits,
    heavy: HeavyPool,
    bodies: BodyBudget,
    inner: Mutex<Inner>,
    rays: rays_api::RaysState,
    compare: compare_api::CompareState,
}

/// The slots heavy requests take, so that a flood of them costs a bounded amount of memory.
struct HeavyPool(Arc<Semaphore>, usize);

/// A heavy request's slot, shared by the blocking tasks doing its work: the slot is free once
/// the work has stopped, not when the client gives up.
type HeavySlot = Arc<OwnedSemaphorePermit>;

impl HeavyPool {
    fn new(n: usize) -> Self {
        Self(Arc::new(Semaphore::new(n.max(1))), n.max(1))
    }

    /// A free slot, or the 503 to answer.
    fn slot(&self) -> ApiResult<HeavySlot> {
        match self.0.clone().try_acquire_owned() {
            Ok(p) => Ok(Arc::new(p)),
            Err(_) => Err(ApiError(
                StatusCode::SERVICE_UNAVAILABLE,
                format!(
                    "the debugger is busy: {} views, traces, renders or compares are already running; try again in a moment",
                    self.1
                ),
            )),
        }
    }
}

/// The bytes of request bodies held at once ([`ServerLimits::body_budget`]), counted in KiB.
struct BodyBudget(Arc<Semaphore>, usize);

/// A body's share of the [`BodyBudget`], given back when the body is dropped.
struct BodyPermit(#[allow(dead_code)] OwnedSemaphorePermit);

impl BodyBudget {
    fn new(bytes: usize) -> Self {
        let kib = bytes.div_ceil(1024).clamp(1, Semaphore::MAX_PERMITS);
        Self(Arc::new(Semaphore::new(kib)), bytes)
    }

    /// Room for a body of `bytes`, or the answer to give before reading it: 503 while other
    /// bodies take the room, 413 when the body could never fit.
    fn reserve(&self, bytes: u64, what: &str) -> ApiResult<BodyPermit> {
        if bytes > self.1 as u64 {
            return Err(ApiError(
                StatusCode::PAYLOAD_TOO_LARGE,
                format!(
                    "{what} is too large ({bytes} bytes; the debugger holds at most {} bytes of uploads at once)",
                    self.1
                ),
            ));
        }
        let kib = u32::try_from(bytes.div_ceil(1024).max(1)).unwrap_or(u32::MAX);
        match self.0.clone().try_acquire_many_owned(kib) {
            Ok(p) => Ok(BodyPermit(p)),
            Err(_) => Err(ApiError(
                StatusCode::SERVICE_UNAVAILABLE,
                format!(
                    "the debugger is busy receiving other uploads (at most {} MiB of them at once): send {what} again in a moment",
                    self.1 >> 20
                ),
            )),
        }
    }
}

/// A request body as received, with its share of the [`BodyBudget`].
struct Received {
    bytes: Bytes,
    _budget: BodyPermit,
}

impl std::ops::Deref for Received {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.bytes
    }
}

/// The pace a body must keep ([`ServerLimits::body_timeout`], [`ServerLimits::min_body_rate`]):
/// only the time spent waiting for the client counts, not the time the server itself takes to
/// use what arrived (a ray log judged as it arrives).
struct BodyPace {
    grace: Duration,
    min_rate: u64,
    waited: Duration,
    received: u64,
}

impl BodyPace {
    fn new(limits: &ServerLimits) -> Self {
        Self {
            grace: limits.body_timeout,
            min_rate: limits.min_body_rate.max(1),
            waited: Duration::ZERO,
            received: 0,
        }
    }

    /// The body's next frame, or the 408 to answer when it paused too long or arrived too slowly.
    async fn next(&mut self, body: &mut Body, what: &str) -> ApiResult<Option<Bytes>> {
        use http_body_util::BodyExt;
        loop {
            let earned = self.grace + Duration::from_secs_f64(self.received as f64 / self.min_rate as f64);
            let left = earned.saturating_sub(self.waited);
            let wait = left.min(self.grace);
            let t = Instant::now();
            let frame = tokio::time::timeout(wait, body.frame()).await;
            self.waited += t.elapsed();
            match frame {
                Err(_) if wait < self.grace => {
                    return Err(ApiError(
                        StatusCode::REQUEST_TIMEOUT,
                        format!(
                            "{what} arrived too slowly ({} bytes in {:.0} s; after the first {} s a body must arrive at {} bytes a second or faster)",
                            self.received,
                            self.waited.as_secs_f64(),
                            self.grace.as_secs_f64(),
                            self.min_rate
                        ),
                    ))
                }
                Err(_) => {
                    return Err(ApiError(
                        StatusCode::REQUEST_TIMEOUT,
                        format!(
                            "{what} did not arrive: nothing came for {} s",
                            self.grace.as_secs_f64()
                        ),
                    ))
                }
                Ok(None) => return Ok(None),
                Ok(Some(Err(e))) => return Err(ApiError::bad(format!("could not read {what}: {e}"))),
                Ok(Some(Ok(f))) => {
                    if let Ok(data) = f.into_data() {
                        self.received += data.len() as u64;
                        return Ok(Some(data));
                    }
                }
            }
        }
    }
}

impl AppState {
    fn new(cfg: ServeConfig, hosts: HostPolicy) -> Self {
        let scene_json = scene_json(&cfg);
        Self {
            scene: Arc::new(cfg.scene),
            scene_file: Arc::new(cfg.scene_file),
            scene_json,
            hosts,
            limits: cfg.limits,
            heavy: HeavyPool::new(cfg.limits.heavy_slots),
            bodies: BodyBudget::new(cfg.limits.body_budget),
            rays: rays_api::RaysState::default(),
            compare: compare_api::CompareState::default(),
            inner: Mutex::new(Inner {
                settings: cfg.settings,
                job: Job {
                    id: 0,
                    cancel: Arc::new(AtomicBool::new(false)),
                    done: Arc::new(AtomicU64::new(0)),
                    total: 0,
                    state: JobState::Cancelled,
                    started: Instant::now(),
                    millis: 0.0,
                },
                rendered: None,
                channels: HashMap::new(),
                check: None,
                heatmaps: VecDeque::new(),
                next_id: 1,
            }),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        // A panic while holding the lock leaves consistent data (plain assignments), so recover.
        self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Cancels the current render and starts one for the current settings; returns its id.
    fn start_render(self: &Arc<Self>) -> u64 {
        let (id, settings, cancel, done) = {
            let mut g = self.lock();
            g.job.cancel.store(true, Ordering::Relaxed);
            let id = g.next_id;
            g.next_id += 1;
            let s = g.settings;
            g.job = Job {
                id,
                cancel: Arc::new(AtomicBool::new(false)),
                done: Arc::new(AtomicU64::new(0)),
                total: s.width as u64 * s.height as u64,
                state: JobState::Running,
                started: Instant::now(),
                millis: 0.0,
            };
            (id, s, g.job.cancel.clone(), g.job.done.clone())
        };
        let state = self.clone();
        std::thread::spawn(move || {
            let start = Instant::now();
            let progress = |d: u64, _t: u64| done.store(d, Ordering::Relaxed);
            let settings = RenderSettings {
                channel: Channel::Color,
                ..settings
            };
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                render(&state.scene, &settings, &progress, &cancel)
            }));
            let millis = start.elapsed().as_secs_f64() * 1000.0;
            let mut g = state.lock();
            if g.job.id != id {
                return;
            }
            g.job.millis = millis;
            match result {
                Ok(Ok(out)) => {
                    g.job.state = JobState::Done;
                    g.rendered = Some(Arc::new(Rendered {
                        job: id,
                        settings,
                        image: Arc::new(RgbImage {
                            width: out.film.width,
                            height: out.film.height,
                            rgb: out.film.to_rgb8(),
                        }),
                        millis,
                    }));
                }
                _ => g.job.state = JobState::Cancelled,
            }
        });
        id
    }
}

fn v3(v: glam::DVec3) -> [f64; 3] {
    v.to_array()
}

fn scene_json(cfg: &ServeConfig) -> Value {
    let f = &cfg.scene_file;
    let entities: Vec<Value> = f
        .entities
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let params = match &e.shape {
                Shape::Plane { point, normal } => json!({
                    "point": v3(*point),
                    "normal": v3(*normal),
                    "unit_normal": v3(normal.normalize_or_zero()),
                }),
                Shape::Sphere { center, radius } => json!({"center": v3(*center), "radius": radius}),
                Shape::Triangle { vertices } => {
                    // The course's front face: (v1 − v0) × (v2 − v0), what the renderer uses.
                    let n = (vertices[1] - vertices[0]).cross(vertices[2] - vertices[0]);
                    json!({
                        "v0": v3(vertices[0]),
                        "v1": v3(vertices[1]),
                        "v2": v3(vertices[2]),
                        "normal": v3(n.normalize_or_zero()),
                    })
                }
                Shape::Mesh {
                    source,
                    offset,
                    scale,
                    mesh,
                } => json!({
                    "file": source.file_name().map(|n| n.to_string_lossy().to_string()),
                    "offset": v3(*offset),
                    "scale": scale,
                    "triangles": mesh.triangles.len(),
                }),
            };
            let primitives = cfg.scene.entities.get(i).map_or(0, |x| x.primitives);
            json!({
                "index": i,
                "name": e.name,
                "kind": e.shape.command(),
                "material": e.material,
                "material_name": f.materials.get(e.material).map(|m| m.name.clone()),
                "line": e.line,
                "primitives": primitives,
                "params": params,
            })
        })
        .collect();
    let lights: Vec<Value> = f
        .lights
        .iter()
        .enumerate()
        .map(|(i, l)| json!({"index": i, "name": l.name, "position": v3(l.position), "color": v3(l.color), "line": l.line}))
        .collect();
    let materials: Vec<Value> = f
        .materials
        .iter()
        .enumerate()
        .map(|(i, m)| {
            json!({"index": i, "name": m.name, "kind": m.kind.name(), "color": v3(m.color), "value": m.value, "line": m.line})
        })
        .collect();
    json!({
        "path": cfg.scene_path.display().to_string(),
        "name": cfg.scene_path.file_name().map(|n| n.to_string_lossy().to_string()),
        "entities": entities,
        "lights": lights,
        "materials": materials,
        "primitives": cfg.scene.primitive_count(),
        "warnings": f.warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>(),
        "limits": {"max_image_side": MAX_IMAGE_SIDE, "max_view_side": MAX_VIEW_SIDE, "max_rays": MAX_RAYS},
    })
}

fn settings_json(s: &RenderSettings) -> Value {
    serde_json::to_value(SettingsPatch::of(s)).unwrap_or(Value::Null)
}

/// An API error: status and message, answered as JSON.
struct ApiError(StatusCode, String);

impl ApiError {
    fn bad(msg: impl Into<String>) -> Self {
        ApiError(StatusCode::BAD_REQUEST, msg.into())
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut res = (self.0, Json(json!({ "error": self.1 }))).into_response();
        match self.0 {
            StatusCode::SERVICE_UNAVAILABLE => {
                res.headers_mut()
                    .insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
            }
            // The rest of the body may still be on its way: do not read it as the next request.
            StatusCode::REQUEST_TIMEOUT | StatusCode::PAYLOAD_TOO_LARGE => {
                res.headers_mut()
                    .insert(header::CONNECTION, HeaderValue::from_static("close"));
            }
            _ => {}
        }
        res
    }
}

type ApiResult<T> = Result<T, ApiError>;
type Params = Query<HashMap<String, String>>;

fn router(state: Arc<AppState>) -> Router {
    let routes = Router::new()
        .route("/", get(index))
        .route("/index.html", get(index))
        .route("/app.js", get(app_js))
        .route("/app.css", get(app_css))
        .route("/api/scene", get(api_scene))
        .route("/api/settings", get(api_get_settings).post(api_post_settings))
        .route("/api/render/status", get(api_status))
        .route("/api/image.png", get(api_image))
        .route("/api/view", get(api_view))
        .route("/api/pick", get(api_pick))
        .route("/api/trace", get(api_trace))
        .route("/api/check", get(api_check))
        .route("/api/compare", get(compare_api::api_get).post(compare_api::api_post))
        .route("/api/compare/pixel", get(compare_api::api_pixel))
        .route("/api/compare/heatmap.png", get(compare_api::api_heatmap))
        .route("/api/rays", post(rays_api::api_upload))
        .route("/api/rays/summary", get(rays_api::api_summary))
        .route("/api/rays/map.png", get(rays_api::api_map))
        .route("/api/rays/pixel", get(rays_api::api_pixel))
        .route("/api/rays/image", post(rays_api::api_image_upload))
        .route("/api/rays/image.png", get(rays_api::api_image))
        .fallback(|| async { ApiError(StatusCode::NOT_FOUND, "no such page".into()) })
        .with_state(state.clone());
    // The guard wraps the whole router rather than each route, so that it also sees what the
    // router adds outside its routes (the `Allow` header of a 405).
    Router::new()
        .fallback_service(routes)
        .layer(middleware::from_fn_with_state(state, guard))
}

/// Refuses requests for a `Host` off the allow-list (DNS rebinding), from another page (see
/// [`cross_site_refusal`]) or with an overlong URL, before any handler runs; then makes every
/// error the JSON one and adds the headers every answer carries.
async fn guard(State(st): State<Arc<AppState>>, req: Request, next: Next) -> Response {
    let method = req.method().clone();
    let path = req.uri().path().to_string();
    let host = req
        .headers()
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .unwrap_or("")
        .to_string();
    let url_len = req.uri().path_and_query().map_or(0, |p| p.as_str().len());
    let has_body =
        req.headers().contains_key(header::TRANSFER_ENCODING) || declared_length(req.headers()).is_some_and(|n| n > 0);
    let res = if !st.hosts.allows(&host) {
        ApiError(
            StatusCode::FORBIDDEN,
            format!(
                "unexpected Host header '{host}': the debugger answers only for its own addresses and names (add one with --allow-host)"
            ),
        )
        .into_response()
    } else if let Some(why) = cross_site_refusal(&method, &path, req.headers(), &host) {
        ApiError(StatusCode::FORBIDDEN, why).into_response()
    } else if url_len > MAX_URL_BYTES {
        ApiError(
            StatusCode::URI_TOO_LONG,
            format!("the URL is too long ({url_len} bytes; at most {MAX_URL_BYTES})"),
        )
        .into_response()
    } else {
        next.run(req).await
    };
    let mut res = finish_response(res, &method, &path).await;
    // A refused request's body may be unread: it must not be read as the next request, and the
    // client, told the connection closes, stops sending it (the socket drains what is already
    // on its way, see net.rs, so the answer is not lost to a reset).
    if has_body && (res.status().is_client_error() || res.status().is_server_error()) {
        res.headers_mut()
            .insert(header::CONNECTION, HeaderValue::from_static("close"));
    }
    res
}

/// Replaces a non-JSON error answer (axum's 405 and extractor rejections) with the JSON one,
/// and adds no-cache, nosniff and no-framing headers.
async fn finish_response(res: Response, method: &axum::http::Method, path: &str) -> Response {
    let status = res.status();
    let is_json = res
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|t| t.starts_with("application/json"));
    let mut res = if (status.is_client_error() || status.is_server_error()) && !is_json {
        let (mut parts, body) = res.into_parts();
        let text = axum::body::to_bytes(body, 4096)
            .await
            .map(|b| String::from_utf8_lossy(&b).trim().to_string())
            .unwrap_or_default();
        let message = if status == StatusCode::METHOD_NOT_ALLOWED {
            let allowed = parts
                .headers
                .get(header::ALLOW)
                .and_then(|v| v.to_str().ok())
                .unwrap_or("")
                .to_string();
            format!("{method} is not allowed on {path}; it takes {allowed}")
        } else if text.is_empty() {
            status.canonical_reason().unwrap_or("error").to_string()
        } else {
            text
        };
        parts.headers.remove(header::CONTENT_LENGTH);
        let mut res = ApiError(status, message).into_response();
        for (k, v) in parts.headers.iter() {
            if k != header::CONTENT_TYPE {
                res.headers_mut().insert(k.clone(), v.clone());
            }
        }
        res
    } else {
        res
    };
    let h = res.headers_mut();
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    h.insert(header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff"));
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static("frame-ancestors 'none'"),
    );
    // Other pages may not embed the debugger's images or data (an <img> on another site).
    h.insert("cross-origin-resource-policy", HeaderValue::from_static("same-origin"));
    res
}

/// The request's `Content-Type` as sent, and its essence (before any `;`), trimmed and lowercased.
fn content_type(headers: &HeaderMap) -> (Option<String>, String) {
    let sent = headers
        .get(header::CONTENT_TYPE)
        .map(|v| String::from_utf8_lossy(v.as_bytes()).into_owned());
    let essence = sent
        .as_deref()
        .and_then(|t| t.split(';').next())
        .unwrap_or("")
        .trim()
        .to_ascii_lowercase();
    (sent, essence)
}

/// The body length the request declares (`Content-Length`), so an oversized body is refused
/// before any of it is read.
fn declared_length(headers: &HeaderMap) -> Option<u64> {
    headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok())
}

/// Reads a request body sent as `mime`, at most `limit` bytes, at the pace [`BodyPace`] sets,
/// within the [`BodyBudget`].
///
/// The type is required, not guessed: `application/json` and `image/png` are types a page on
/// another origin cannot send without a preflight, so requiring them keeps forms and no-cors
/// fetches (which may only send `text/plain`, form and multipart bodies) out. Every refusal
/// comes before the body is read, so the answer goes out at once (the guard closes the
/// connection after it, see [`guard`]).
async fn read_body(
    st: &AppState,
    headers: &HeaderMap,
    mut body: Body,
    mime: &str,
    what: &str,
    limit: usize,
) -> ApiResult<Received> {
    let (sent, essence) = content_type(headers);
    if essence != mime {
        return Err(ApiError(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            format!(
                "send {what} with Content-Type: {mime} (got {})",
                sent.map_or("none".to_string(), |t| format!("'{t}'"))
            ),
        ));
    }
    let too_large = || {
        ApiError(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!("{what} is too large (at most {limit} bytes)"),
        )
    };
    let declared = declared_length(headers);
    if declared.is_some_and(|n| n > limit as u64) {
        return Err(too_large());
    }
    // A body without a length may grow to the limit: it reserves that much.
    let budget = st.bodies.reserve(declared.unwrap_or(limit as u64), what)?;
    let mut pace = BodyPace::new(&st.limits);
    let mut bytes = Vec::with_capacity(declared.map_or(0, |n| n as usize));
    while let Some(data) = pace.next(&mut body, what).await? {
        if bytes.len() + data.len() > limit {
            return Err(too_large());
        }
        bytes.extend_from_slice(&data);
    }
    Ok(Received {
        bytes: Bytes::from(bytes),
        _budget: budget,
    })
}

async fn index() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/html; charset=utf-8")],
        include_str!("ui/index.html"),
    )
}

async fn app_js() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        include_str!("ui/app.js"),
    )
}

async fn app_css() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/css; charset=utf-8")],
        include_str!("ui/app.css"),
    )
}

async fn api_scene(State(st): State<Arc<AppState>>) -> Json<Value> {
    let s = st.lock().settings;
    let mut v = st.scene_json.clone();
    let view = auto_view(&st.scene, &s, 1.5);
    v["settings"] = settings_json(&s);
    v["view"] = json!({"eye": view.eye.to_array(), "target": view.target.to_array(), "fov": view.fov_deg});
    Json(v)
}

async fn api_get_settings(State(st): State<Arc<AppState>>) -> Json<Value> {
    let g = st.lock();
    Json(json!({"settings": settings_json(&g.settings), "job": g.job.id}))
}

async fn api_post_settings(State(st): State<Arc<AppState>>, headers: HeaderMap, body: Body) -> ApiResult<Json<Value>> {
    let body = read_body(
        &st,
        &headers,
        body,
        "application/json",
        "the settings",
        SETTINGS_BODY_LIMIT,
    )
    .await?;
    let patch: SettingsPatch =
        serde_json::from_slice(&body).map_err(|e| ApiError::bad(format!("invalid settings JSON: {e}")))?;
    let current = st.lock().settings;
    let new = patch.apply(&current);
    check_settings(&new).map_err(ApiError::bad)?;
    let changed = new != current;
    let job = if changed || st.lock().job.state == JobState::Cancelled {
        {
            let mut g = st.lock();
            g.settings = new;
            g.channels.clear();
        }
        st.start_render()
    } else {
        st.lock().job.id
    };
    Ok(Json(
        json!({"job": job, "settings": settings_json(&new), "changed": changed}),
    ))
}

async fn api_status(State(st): State<Arc<AppState>>) -> Json<Value> {
    let g = st.lock();
    let j = &g.job;
    let done = j.done.load(Ordering::Relaxed);
    let elapsed = if j.state == JobState::Running {
        j.started.elapsed().as_secs_f64() * 1000.0
    } else {
        j.millis
    };
    Json(json!({
        "job": j.id,
        "state": j.state.name(),
        "done": done,
        "total": j.total,
        "progress": if j.total > 0 { done as f64 / j.total as f64 } else { 0.0 },
        "elapsed_ms": elapsed,
        "rendered": g.rendered.as_ref().map(|r| json!({"job": r.job, "width": r.settings.width, "height": r.settings.height, "millis": r.millis})),
        "settings": settings_json(&g.settings),
    }))
}

fn parse_channel(s: &str) -> Result<(Channel, &'static str), ApiError> {
    Ok(match s {
        "color" => (Channel::Color, "color"),
        "normal" => (Channel::Normal, "normal"),
        "depth" => (Channel::Depth, "depth"),
        "entity" => (Channel::Entity, "entity"),
        "albedo" => (Channel::Albedo, "albedo"),
        "cost" => (Channel::Cost, "cost"),
        other => {
            return Err(ApiError::bad(format!(
                "channel must be color, normal, depth, entity, albedo or cost, not '{other}'"
            )))
        }
    })
}

/// The image for `channel` at the current settings; colour comes from the last finished render
/// (`None` while none matches the current image size). A render it needs runs under `slot`.
async fn channel_image(
    st: &Arc<AppState>,
    channel: Channel,
    name: &'static str,
    slot: &HeavySlot,
) -> ApiResult<Option<Arc<RgbImage>>> {
    let settings = st.lock().settings;
    if channel == Channel::Color {
        let g = st.lock();
        return Ok(g
            .rendered
            .as_ref()
            .filter(|r| r.settings.width == settings.width && r.settings.height == settings.height)
            .map(|r| r.image.clone()));
    }
    if let Some((s, img)) = st.lock().channels.get(name) {
        if *s == settings {
            return Ok(Some(img.clone()));
        }
    }
    let st2 = st.clone();
    let slot = slot.clone();
    let img = tokio::task::spawn_blocking(move || {
        let _slot = slot;
        let s = RenderSettings { channel, ..settings };
        let never = AtomicBool::new(false);
        render(&st2.scene, &s, &|_, _| {}, &never).ok().map(|out| RgbImage {
            width: out.film.width,
            height: out.film.height,
            rgb: out.film.to_rgb8(),
        })
    })
    .await
    .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, format!("render failed: {e}")))?;
    let Some(img) = img else { return Ok(None) };
    let img = Arc::new(img);
    st.lock().channels.insert(name, (settings, img.clone()));
    Ok(Some(img))
}

fn png_response(bytes: Vec<u8>) -> Response {
    ([(header::CONTENT_TYPE, "image/png")], bytes).into_response()
}

async fn api_image(State(st): State<Arc<AppState>>, Query(q): Params) -> ApiResult<Response> {
    let (channel, name) = parse_channel(q.get("channel").map_or("color", String::as_str))?;
    let slot = st.heavy.slot()?;
    let img = channel_image(&st, channel, name, &slot).await?;
    match img {
        Some(img) => {
            let bytes = tokio::task::spawn_blocking(move || {
                let _slot = slot;
                encode::png(&img)
            })
            .await
            .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
            Ok(png_response(bytes))
        }
        None => Err(ApiError(StatusCode::CONFLICT, "no finished render yet".into())),
    }
}

fn parse_vec3(name: &str, s: &str) -> ApiResult<Vec3> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let err = || {
        ApiError::bad(format!(
            "{name} must be three finite numbers \"x,y,z\" within ±1e6, not '{s}'"
        ))
    };
    if parts.len() != 3 {
        return Err(err());
    }
    let mut v = [0.0f32; 3];
    for (slot, p) in v.iter_mut().zip(parts) {
        *slot = p.parse().map_err(|_| err())?;
        if !slot.is_finite() || slot.abs() > 1e6 {
            return Err(err());
        }
    }
    Ok(Vec3::from(v))
}

fn parse_num<T: std::str::FromStr + PartialOrd + std::fmt::Display + Copy>(
    q: &HashMap<String, String>,
    name: &str,
    default: T,
    lo: T,
    hi: T,
) -> ApiResult<T> {
    match q.get(name) {
        None => Ok(default),
        Some(s) => match s.trim().parse::<T>() {
            Ok(v) if v >= lo && v <= hi => Ok(v),
            _ => Err(ApiError::bad(format!(
                "{name} must be a number from {lo} to {hi}, not '{s}'"
            ))),
        },
    }
}

fn parse_pixel(s: &str, settings: &RenderSettings) -> ApiResult<(u32, u32)> {
    let err = || {
        ApiError::bad(format!(
            "pixel must be \"x,y\" inside the {}×{} image (0-based from the top-left), not '{s}'",
            settings.width, settings.height
        ))
    };
    let (x, y) = s.split_once(',').ok_or_else(err)?;
    let x: u32 = x.trim().parse().map_err(|_| err())?;
    let y: u32 = y.trim().parse().map_err(|_| err())?;
    if x >= settings.width || y >= settings.height {
        return Err(err());
    }
    Ok((x, y))
}

fn view_camera(
    q: &HashMap<String, String>,
    st: &AppState,
    settings: &RenderSettings,
    w: u32,
    h: u32,
) -> ApiResult<ViewCamera> {
    let auto = auto_view(&st.scene, settings, w as f32 / h as f32);
    let eye = q
        .get("eye")
        .map(|s| parse_vec3("eye", s))
        .transpose()?
        .unwrap_or(auto.eye);
    let target = q
        .get("target")
        .map(|s| parse_vec3("target", s))
        .transpose()?
        .unwrap_or(auto.target);
    if (eye - target).length() < 1e-4 {
        return Err(ApiError::bad("eye and target must differ"));
    }
    let fov_deg = parse_num(q, "fov", auto.fov_deg, 5.0, 150.0)?;
    Ok(ViewCamera { eye, target, fov_deg })
}

fn view_size(q: &HashMap<String, String>) -> ApiResult<(u32, u32)> {
    Ok((
        parse_num(q, "w", 960u32, 16, MAX_VIEW_SIDE)?,
        parse_num(q, "h", 640u32, 16, MAX_VIEW_SIDE)?,
    ))
}

/// True when the query sets `name=0`.
fn is_off(q: &HashMap<String, String>, name: &str) -> bool {
    matches!(q.get(name).map(String::as_str), Some("0"))
}

fn parse_selection(s: &str) -> ApiResult<Option<Selection>> {
    let err = || ApiError::bad(format!("select must be entity:N, light:N or camera, not '{s}'"));
    if s.is_empty() || s == "none" {
        return Ok(None);
    }
    if s == "camera" {
        return Ok(Some(Selection::Camera));
    }
    let (k, n) = s.split_once(':').ok_or_else(err)?;
    let n: u32 = n.parse().map_err(|_| err())?;
    match k {
        "entity" => Ok(Some(Selection::Entity(n))),
        "light" => Ok(Some(Selection::Light(n))),
        _ => Err(err()),
    }
}

async fn api_view(State(st): State<Arc<AppState>>, Query(q): Params) -> ApiResult<Response> {
    let settings = st.lock().settings;
    let (w, h) = view_size(&q)?;
    let camera = view_camera(&q, &st, &settings, w, h)?;
    let mut opts = ViewOptions::new(w, h, camera);
    if let Some(r) = q.get("rays") {
        opts.rays = r.parse::<RayMode>().map_err(ApiError::bad)?;
        match opts.rays {
            RayMode::Pixel(x, y) if x >= settings.width || y >= settings.height => {
                return Err(ApiError::bad(format!("rays pixel {x},{y} is outside the image")))
            }
            RayMode::Row(y) if y >= settings.height => {
                return Err(ApiError::bad(format!("rays row {y} is outside the image")))
            }
            _ => {}
        }
    }
    if let Some(m) = q.get("image") {
        opts.image = m.parse::<ImageMode>().map_err(ApiError::bad)?;
    }
    opts.max_rays = parse_num(&q, "max_rays", 2500u32, 1, MAX_RAYS)?;
    if let Some(s) = q.get("select") {
        opts.selection = parse_selection(s)?;
        match opts.selection {
            Some(Selection::Entity(e)) if e as usize >= st.scene.entities.len() => {
                return Err(ApiError::bad("no such entity"))
            }
            Some(Selection::Light(l)) if l as usize >= st.scene.lights.len() => {
                return Err(ApiError::bad("no such light"))
            }
            _ => {}
        }
    }
    let flag = |name: &str| q.get(name).is_some_and(|v| v == "1" || v == "true");
    if let Some(p) = q.get("pixel") {
        opts.pixel = Some(parse_pixel(p, &settings)?);
    }
    let spp = Integrator::new(&st.scene, &settings).samples_per_pixel();
    let sample = parse_num(&q, "sample", 0u32, 0, spp.saturating_sub(1))?;
    opts.samples = flag("samples");
    opts.cutaway = !is_off(&q, "cutaway");
    opts.ground_grid = !is_off(&q, "ground");
    opts.antialias = !is_off(&q, "aa");
    opts.normals = flag("normals");
    opts.hidden_alpha = parse_num(&q, "hidden", 0.12f32, 0.0, 1.0)?;
    let (channel, name) = parse_channel(q.get("channel").map_or("color", String::as_str))?;
    let want_tree = flag("tree");
    let jpeg = !matches!(q.get("format").map(String::as_str), Some("png"));
    let quality = parse_num(&q, "quality", 88u8, 30, 100)?;
    let slot = st.heavy.slot()?;
    let mut image = if opts.image == ImageMode::Traced {
        channel_image(&st, channel, name, &slot).await?
    } else {
        None
    };
    rays_api::view_hook(&st, &q, &settings, sample, &mut opts, &mut image)?;
    if flag("check") {
        if let Some(c) = st.lock().check.as_ref().filter(|c| c.settings == settings) {
            opts.highlight = c.cells.clone();
        }
    }
    let st2 = st.clone();
    let (bytes, info) = tokio::task::spawn_blocking(move || {
        let _slot = slot;
        if want_tree {
            if let Some((x, y)) = opts.pixel {
                opts.tree = Some(trace_pixel_with(&st2.scene, &*st2.scene, &settings, x, y, sample));
            }
        }
        let frame = render_view(&st2.scene, &settings, image.as_deref(), &opts);
        let bytes = if jpeg {
            encode::jpeg(&frame.image, quality)
        } else {
            encode::png(&frame.image)
        };
        (bytes, frame.info)
    })
    .await
    .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, format!("view failed: {e}")))?;
    let info = serde_json::to_string(&info).unwrap_or_default();
    let ct = if jpeg { "image/jpeg" } else { "image/png" };
    let mut res = ([(header::CONTENT_TYPE, ct)], bytes).into_response();
    if let Ok(v) = HeaderValue::from_str(&info) {
        res.headers_mut().insert("x-view-info", v);
    }
    Ok(res)
}

async fn api_pick(State(st): State<Arc<AppState>>, Query(q): Params) -> ApiResult<Json<Value>> {
    let settings = st.lock().settings;
    let (w, h) = view_size(&q)?;
    let camera = view_camera(&q, &st, &settings, w, h)?;
    let x = parse_num(&q, "x", 0u32, 0, w - 1)?;
    let y = parse_num(&q, "y", 0u32, 0, h - 1)?;
    let opts = ViewOptions::new(w, h, camera);
    let sel = pick(&st.scene, &settings, &opts, x, y);
    Ok(Json(json!({ "selection": sel })))
}

async fn api_trace(State(st): State<Arc<AppState>>, Query(q): Params) -> ApiResult<Json<Value>> {
    let settings = st.lock().settings;
    let x = parse_num(&q, "x", u32::MAX, 0, settings.width - 1)
        .map_err(|_| ApiError::bad(format!("x must be a pixel column from 0 to {}", settings.width - 1)))?;
    let y = parse_num(&q, "y", u32::MAX, 0, settings.height - 1)
        .map_err(|_| ApiError::bad(format!("y must be a pixel row from 0 to {}", settings.height - 1)))?;
    if x == u32::MAX || y == u32::MAX {
        return Err(ApiError::bad("x and y are required (0-based pixel from the top-left)"));
    }
    let spp = Integrator::new(&st.scene, &settings).samples_per_pixel();
    let sample = parse_num(&q, "sample", 0u32, 0, spp - 1)?;
    let reference = match q.get("intersector").map(String::as_str) {
        None | Some("ours") => false,
        Some("reference") => true,
        Some(o) => {
            return Err(ApiError::bad(format!(
                "intersector must be ours or reference, not '{o}'"
            )))
        }
    };
    let st2 = st.clone();
    let slot = st.heavy.slot()?;
    let tree = tokio::task::spawn_blocking(move || {
        let _slot = slot;
        if reference {
            trace_pixel_with(
                &st2.scene,
                &ReferenceIntersector { scene: &st2.scene },
                &settings,
                x,
                y,
                sample,
            )
        } else {
            trace_pixel_with(&st2.scene, &*st2.scene, &settings, x, y, sample)
        }
    })
    .await
    .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, format!("trace failed: {e}")))?;
    let integ = Integrator::new(&st.scene, &settings);
    let positions: Vec<[f32; 2]> = (0..spp.min(256))
        .map(|s| {
            let (u, v) = integ.sample_position(x, y, s);
            [u * settings.width as f32, v * settings.height as f32]
        })
        .collect();
    let pixel = st.lock().rendered.as_ref().filter(|r| r.settings == settings).map(|r| {
        let i = (y * settings.width + x) as usize * 3;
        [r.image.rgb[i], r.image.rgb[i + 1], r.image.rgb[i + 2]]
    });
    Ok(Json(json!({
        "tree": tree,
        "samples_per_pixel": spp,
        "sample_positions": positions,
        "pixel_rgb8": pixel,
        "intersector": if reference { "reference" } else { "ours" },
    })))
}

fn answer(scene: &Scene, h: Option<rayscope_core::scene::Hit>) -> Option<HitAnswer> {
    h.map(|h| {
        let (e, _) = scene.prim_info(h.prim);
        HitAnswer {
            entity: e,
            name: scene.entities[e as usize].name.clone(),
            t: h.t,
        }
    })
}

fn run_check(scene: &Scene, settings: &RenderSettings) -> (Vec<Mismatch>, u64) {
    let integ = Integrator::new(scene, settings);
    let reference = ReferenceIntersector { scene };
    let (w, h) = (settings.width, settings.height);
    let rows: Vec<Vec<Mismatch>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut out = Vec::new();
            for x in 0..w {
                let ray = integ.camera_ray(x, y, 0, &mut integ.sample_rng(x, y, 0));
                let a = scene.intersect(&ray, 0.0, f32::INFINITY);
                let b = reference.intersect(&ray, 0.0, f32::INFINITY);
                let kind = match (&a, &b) {
                    (None, None) => None,
                    (Some(_), None) | (None, Some(_)) => Some("missing"),
                    (Some(p), Some(q)) => {
                        let (ep, _) = scene.prim_info(p.prim);
                        let (eq, _) = scene.prim_info(q.prim);
                        let tol = 1e-3 * p.t.abs().max(1.0);
                        let close = (p.t - q.t).abs() <= tol;
                        match (ep == eq, close) {
                            (true, true) => None,
                            (true, false) => Some("distance"),
                            // Two entities at the same distance: either answer is right.
                            (false, true) => Some("tie"),
                            (false, false) => Some("entity"),
                        }
                    }
                };
                if let Some(kind) = kind {
                    out.push(Mismatch {
                        x,
                        y,
                        kind,
                        ours: answer(scene, a),
                        reference: answer(scene, b),
                    });
                }
            }
            out
        })
        .collect();
    let all: Vec<Mismatch> = rows.into_iter().flatten().collect();
    let n = all.len() as u64;
    (all, n)
}

async fn api_check(State(st): State<Arc<AppState>>) -> ApiResult<Json<Value>> {
    let settings = st.lock().settings;
    if let Some(c) = st.lock().check.as_ref().filter(|c| c.settings == settings) {
        return Ok(Json(c.json.clone()));
    }
    let cost = settings.width as u64 * settings.height as u64 * st.scene.primitive_count().max(1) as u64;
    if cost > CHECK_BUDGET {
        return Err(ApiError::bad(format!(
            "checking {}×{} pixels against {} primitives with the brute-force reference is too slow; lower the image size",
            settings.width,
            settings.height,
            st.scene.primitive_count()
        )));
    }
    let st2 = st.clone();
    let slot = st.heavy.slot()?;
    let start = Instant::now();
    let (all, n) = tokio::task::spawn_blocking(move || {
        let _slot = slot;
        run_check(&st2.scene, &settings)
    })
    .await
    .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, format!("check failed: {e}")))?;
    let ties = all.iter().filter(|m| m.kind == "tie").count();
    let cells: Vec<(u32, u32)> = all.iter().map(|m| (m.x, m.y)).collect();
    let json = json!({
        "total": settings.width as u64 * settings.height as u64,
        "count": n,
        "ties": ties,
        "listed": all.len().min(CHECK_LIST),
        "mismatches": all.into_iter().take(CHECK_LIST).collect::<Vec<_>>(),
        "millis": start.elapsed().as_secs_f64() * 1000.0,
        "note": "first hit of each pixel's camera ray (sample 0), rayscope's BVH vs the parry3d reference; a tie is two entities at the same distance",
    });
    st.lock().check = Some(Arc::new(CheckResult {
        settings,
        json: json.clone(),
        cells,
    }));
    Ok(Json(json))
}

/// Decodes a reference PNG of exactly `width` × `height` pixels.
fn decode_reference(png: &[u8], width: u32, height: u32) -> Result<image::RgbImage, String> {
    decode_png_sized(png, |w, h| {
        if (w, h) == (width, height) {
            Ok(())
        } else {
            Err(format!("the reference is {w}×{h} but the render is {width}×{height}"))
        }
    })
}

/// Decodes a PNG whose size, read from its header, `accept` allows.
///
/// The size is read from the header first and the decoder is limited to that size, so a small
/// file that would decode to a huge image (a decompression bomb) costs no more than the header.
fn decode_png_sized(
    png: &[u8],
    accept: impl FnOnce(u32, u32) -> Result<(), String>,
) -> Result<image::RgbImage, String> {
    let reader = |limits: image::Limits| {
        let mut r = image::ImageReader::with_format(std::io::Cursor::new(png), image::ImageFormat::Png);
        r.limits(limits);
        r
    };
    // Chunks before the pixels (text, ICC profiles) are read too: bounded by max_alloc.
    let mut header = image::Limits::default();
    header.max_alloc = Some(REFERENCE_CHUNK_BYTES);
    let (w, h) = reader(header)
        .into_dimensions()
        .map_err(|e| format!("not a readable PNG: {e}"))?;
    accept(w, h)?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(w);
    limits.max_image_height = Some(h);
    // The largest pixel format (16-bit RGBA) plus the decoder's own buffers.
    limits.max_alloc = Some(u64::from(w) * u64::from(h) * 8 + REFERENCE_CHUNK_BYTES);
    Ok(reader(limits)
        .decode()
        .map_err(|e| format!("not a readable PNG: {e}"))?
        .into_rgb8())
}
