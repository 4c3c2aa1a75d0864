//! The debugger's API for a student's ray log and image (see [`crate::student`]).
//!
//! - `POST /api/rays?name=FILE` with the log as the body: `Content-Type: application/x-ndjson`
//!   for JSON Lines, `application/octet-stream` for RayTracer.Debug's `.rays` (both types a page
//!   on another origin cannot send without a preflight). At most [`MAX_LOG_BYTES`]; the body is
//!   judged as it arrives, at the pace [`ServerLimits::min_body_rate`] sets, so memory stays
//!   bounded; a log of up to [`ServerLimits::keep_log_bytes`] is kept to judge again when the
//!   settings change. One log is received at a time, outside the heavy slots: a newer upload
//!   replaces one still arriving (answered 409), so a slow or stalled upload holds nothing
//!   another request needs. Answers the summary once judged.
//! - `GET /api/rays/summary`: the judgement's state and counts; judges again when the settings
//!   changed and the log can be read again (a file, or a kept upload), else says `stale`.
//! - `GET /api/rays/map.png`: the verdict map, one pixel per image pixel.
//! - `GET /api/rays/pixel?x=&y=&sample=&offset=&limit=`: the student's rays of a pixel sample
//!   beside rayscope's tree, aligned, with the first divergence explained; at most
//!   [`student::PAGE_RAYS`] rays of the sample from `offset`, with their count (`rays_total`)
//!   and how many follow (`more`).
//! - `POST /api/rays/image` (`image/png`, at most 32 MiB, at most 2048 pixels a side) and
//!   `GET /api/rays/image.png`: the student's image.
//! - `/api/view` takes `student=1` (the student's rays of the selected pixel), `verdicts=1` (the
//!   verdict map on the grid) and `grid=student` (their image on the grid).

use std::io::Read;
use std::path::Path;

use axum::extract::Query;
use rayscope_check::image::LogNext;
use rayscope_check::log::IdRole;
use rayscope_check::PixelLog;

use super::*;
use crate::student::{self, StudentInput};

/// Largest ray log the debugger accepts as an upload.
pub const MAX_LOG_BYTES: u64 = 4 << 30;
/// How long a new upload waits for the one it replaces to stop.
const REPLACE_WAIT: Duration = Duration::from_secs(5);
/// The blocks a kept upload is stored in: no copy of the whole log is ever made, and a block
/// holds only bytes of the log, whatever the sizes of the parts it arrived in.
const KEEP_BLOCK: usize = 1 << 20;
/// Largest uploaded student image in bytes.
const IMAGE_BODY_LIMIT: usize = 32 * 1024 * 1024;
/// Pixels that disagree listed in the summary (all are counted).
const LIST: usize = 2000;

enum Data {
    File(PathBuf),
    Kept(Arc<Kept>),
    /// An upload too large to keep.
    Gone,
}

/// An upload's bytes, kept in blocks of [`KEEP_BLOCK`].
#[derive(Default)]
struct Kept {
    blocks: Vec<Vec<u8>>,
    len: usize,
}

impl Kept {
    /// Appends `data`; false (and nothing kept any more) once the log would pass `cap` bytes.
    fn push(&mut self, data: &[u8], cap: usize) -> bool {
        if self.len + data.len() > cap {
            self.blocks = Vec::new();
            return false;
        }
        let mut rest = data;
        while !rest.is_empty() {
            if self.blocks.last().is_none_or(|b| b.len() == KEEP_BLOCK) {
                self.blocks.push(Vec::with_capacity(KEEP_BLOCK.min(cap)));
            }
            let b = self.blocks.last_mut().expect("a block was just pushed");
            let n = rest.len().min(KEEP_BLOCK - b.len());
            b.extend_from_slice(&rest[..n]);
            rest = &rest[n..];
        }
        self.len += data.len();
        true
    }
}

/// Reads a [`Kept`] log from its start.
struct KeptReader {
    kept: Arc<Kept>,
    block: usize,
    at: usize,
}

impl Read for KeptReader {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        while let Some(b) = self.kept.blocks.get(self.block) {
            if self.at < b.len() {
                let n = buf.len().min(b.len() - self.at);
                buf[..n].copy_from_slice(&b[self.at..self.at + n]);
                self.at += n;
                return Ok(n);
            }
            self.block += 1;
            self.at = 0;
        }
        Ok(0)
    }
}

struct Source {
    name: String,
    binary: bool,
    data: Data,
    roles: Vec<IdRole>,
    lenient: bool,
}

struct Judged {
    settings: RenderSettings,
    log: Arc<PixelLog>,
    tint: Arc<Vec<[u8; 4]>>,
    map_png: Arc<Vec<u8>>,
    name: String,
    millis: f64,
    job: u64,
}

struct Running {
    id: u64,
    settings: RenderSettings,
    cancel: Arc<AtomicBool>,
    done: Arc<AtomicU64>,
    total: Arc<AtomicU64>,
    started: Instant,
    name: String,
}

#[derive(Default)]
struct RInner {
    source: Option<Arc<Source>>,
    judged: Option<Arc<Judged>>,
    running: Option<Running>,
    /// The last judgement's failure, with the settings it ran under.
    error: Option<(RenderSettings, String)>,
    image: Option<(String, Arc<RgbImage>)>,
    next: u64,
    /// What to log next for a judged log, image and render ([`NextKey`]), once worked out.
    log_next: Option<(NextKey, Option<Value>)>,
    /// How to stop the upload being received, so that a newer one replaces it.
    receiving: Option<Arc<tokio::sync::Notify>>,
}

/// The student's log and image, held by the server.
pub(super) struct RaysState {
    inner: Mutex<RInner>,
    /// The one upload being received.
    upload: Arc<Semaphore>,
}

impl Default for RaysState {
    fn default() -> Self {
        Self {
            inner: Mutex::default(),
            upload: Arc::new(Semaphore::new(1)),
        }
    }
}

impl RaysState {
    fn lock(&self) -> std::sync::MutexGuard<'_, RInner> {
        self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// The student's image and its name, if one is loaded.
pub(super) fn their_image(st: &AppState) -> Option<(String, Arc<RgbImage>)> {
    st.rays.lock().image.clone()
}

/// Keeps `img` as the student's image.
pub(super) fn set_their_image(st: &AppState, name: String, img: RgbImage) {
    st.rays.lock().image = Some((name, Arc::new(img)));
}

/// Loads what `rayscope debug --rays … --image …` gave and starts judging the log.
pub(super) fn start(st: &Arc<AppState>, input: StudentInput) {
    if let Some(img) = input.image {
        st.rays.lock().image = Some(("your image".into(), Arc::new(img)));
    }
    if let Some(path) = input.rays {
        let source = Arc::new(Source {
            name: path
                .file_name()
                .map_or("log".into(), |n| n.to_string_lossy().into_owned()),
            binary: student::is_binary_log(&path),
            data: Data::File(path),
            roles: if input.ray_ids.is_empty() {
                student::default_ray_ids()
            } else {
                input.ray_ids
            },
            lenient: input.lenient,
        });
        st.rays.lock().source = Some(source.clone());
        let settings = st.lock().settings;
        let _ = start_job(st, source, None, settings);
    }
}

/// A `Read` over the parts of a request body as they arrive.
struct ChannelReader {
    rx: tokio::sync::mpsc::Receiver<Result<Bytes, String>>,
    cur: Bytes,
}

impl Read for ChannelReader {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        while self.cur.is_empty() {
            match self.rx.blocking_recv() {
                None => return Ok(0),
                Some(Ok(b)) => self.cur = b,
                Some(Err(e)) => return Err(std::io::Error::other(e)),
            }
        }
        let n = buf.len().min(self.cur.len());
        buf[..n].copy_from_slice(&self.cur[..n]);
        self.cur = self.cur.slice(n..);
        Ok(n)
    }
}

type JobResult = tokio::sync::oneshot::Receiver<Result<(), String>>;

/// Starts judging `source` (read from `reader` when given) under `settings`, cancelling the
/// judgement before it; returns the job id and where its outcome arrives.
fn start_job(
    st: &Arc<AppState>,
    source: Arc<Source>,
    reader: Option<(Box<dyn Read + Send>, u64)>,
    settings: RenderSettings,
) -> (u64, JobResult) {
    let (tx, rx) = tokio::sync::oneshot::channel();
    let cancel = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicU64::new(0));
    let total = Arc::new(AtomicU64::new(0));
    let id = {
        let mut g = st.rays.lock();
        if let Some(r) = g.running.take() {
            r.cancel.store(true, Ordering::Relaxed);
        }
        g.next += 1;
        let id = g.next;
        g.running = Some(Running {
            id,
            settings,
            cancel: cancel.clone(),
            done: done.clone(),
            total: total.clone(),
            started: Instant::now(),
            name: source.name.clone(),
        });
        id
    };
    let st = st.clone();
    std::thread::spawn(move || {
        let start = Instant::now();
        let progress = |d: u64, t: u64| {
            done.store(d, Ordering::Relaxed);
            total.store(t, Ordering::Relaxed);
        };
        let name = Path::new(&source.name);
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let (reader, len): (Box<dyn Read + Send>, u64) = match (reader, &source.data) {
                (Some(r), _) => r,
                (None, Data::File(p)) => {
                    let f = std::fs::File::open(p).map_err(|e| format!("cannot read ray log {}: {e}", p.display()))?;
                    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
                    (Box::new(std::io::BufReader::with_capacity(1 << 20, f)), len)
                }
                (None, Data::Kept(k)) => (
                    Box::new(KeptReader {
                        kept: k.clone(),
                        block: 0,
                        at: 0,
                    }),
                    k.len as u64,
                ),
                (None, Data::Gone) => return Err("the log was not kept: send it again".to_string()),
            };
            total.store(len, Ordering::Relaxed);
            student::judge_reader(
                &st.scene,
                &settings,
                reader,
                name,
                len,
                source.binary,
                &source.roles,
                source.lenient,
                rayscope_check::PixelOptions {
                    detail_cap: st.limits.ray_detail_cap,
                    ..rayscope_check::PixelOptions::default()
                },
                &progress,
                &cancel,
            )
            .map_err(|e| e.to_string().trim_start_matches("error: ").to_string())
        }))
        .unwrap_or_else(|_| Err("judging the log failed (a bug in rayscope: please report it)".into()));
        let result = match outcome {
            Ok(Some(log)) => {
                let map_png = encode::png(&student::verdict_map(&log));
                let tint = student::verdict_tint(&log);
                Ok(Judged {
                    settings,
                    log: Arc::new(log),
                    tint: Arc::new(tint),
                    map_png: Arc::new(map_png),
                    name: source.name.clone(),
                    millis: start.elapsed().as_secs_f64() * 1000.0,
                    job: id,
                })
            }
            Ok(None) => Err(None),
            Err(e) => Err(Some(e)),
        };
        let mut g = st.rays.lock();
        let current = g.running.as_ref().is_some_and(|r| r.id == id);
        if current {
            g.running = None;
        }
        let answer = match result {
            Ok(j) if current => {
                g.judged = Some(Arc::new(j));
                g.error = None;
                Ok(())
            }
            Ok(_) | Err(None) => Err("cancelled: another log (or the same one under new settings) replaced it".into()),
            Err(Some(e)) => {
                if current {
                    g.error = Some((settings, e.clone()));
                    g.judged = None;
                }
                Err(e)
            }
        };
        drop(g);
        let _ = tx.send(answer);
    });
    (id, rx)
}

/// Judges the log again when the settings changed since and it can be read again.
fn refresh(st: &Arc<AppState>) {
    let settings = st.lock().settings;
    let source = {
        let g = st.rays.lock();
        let Some(source) = g.source.clone() else {
            return;
        };
        if g.running.is_some() || matches!(source.data, Data::Gone) {
            return;
        }
        let judged_now = g.judged.as_ref().is_some_and(|j| j.settings == settings);
        let failed_now = g.error.as_ref().is_some_and(|(s, _)| *s == settings);
        if judged_now || failed_now {
            return;
        }
        source
    };
    let _ = start_job(st, source, None, settings);
}

fn summary(st: &Arc<AppState>) -> Value {
    let settings = st.lock().settings;
    let g = st.rays.lock();
    let image = g.image.as_ref().map(|(name, img)| {
        json!({
            "name": name,
            "width": img.width,
            "height": img.height,
            "matches": img.width == settings.width && img.height == settings.height,
        })
    });
    let mut v = json!({
        "state": "none",
        "image": image,
        "keep_bytes": st.limits.keep_log_bytes,
        "max_bytes": MAX_LOG_BYTES,
    });
    if let Some(r) = &g.running {
        v["state"] = json!("judging");
        v["name"] = json!(r.name);
        v["progress"] = json!({
            "done": r.done.load(Ordering::Relaxed),
            "total": r.total.load(Ordering::Relaxed),
            "elapsed_ms": r.started.elapsed().as_secs_f64() * 1000.0,
        });
        v["for_current_settings"] = json!(r.settings == settings);
    }
    if let Some(j) = &g.judged {
        let stale = j.settings != settings;
        let mut s = student::summary_json(&j.log, LIST);
        s["name"] = json!(j.name);
        s["millis"] = json!(j.millis);
        s["job"] = json!(j.job);
        s["stale"] = json!(stale);
        s["settings"] = settings_json(&j.settings);
        s["map"] = json!(format!("/api/rays/map.png?job={}", j.job));
        s["detail_cap"] = json!(st.limits.ray_detail_cap);
        v["judged"] = s;
        if g.running.is_none() {
            v["state"] = json!(if stale { "stale" } else { "done" });
        }
    }
    if let Some((s, e)) = &g.error {
        v["error"] = json!(e);
        v["error_stale"] = json!(*s != settings);
        if g.running.is_none() && g.judged.is_none() {
            v["state"] = json!("error");
        }
    }
    if let Some(src) = &g.source {
        v["source"] = json!({
            "name": src.name,
            "kind": match src.data { Data::File(_) => "file", Data::Kept(_) => "upload", Data::Gone => "upload-not-kept" },
            "format": if src.binary { "rays" } else { "jsonl" },
        });
    }
    v
}

/// The image's name for a command to paste: as it is when a shell takes it as one word, else a
/// placeholder (an image given at start, or named with spaces, has no such name).
fn pasteable(name: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "._-+/".contains(c);
    if !name.is_empty() && name.chars().all(plain) {
        name.to_string()
    } else {
        "YOUR_PICTURE.png".to_string()
    }
}

/// What [`log_next`] was worked out for: the judgement's job, the student's image (held, so that
/// its allocation cannot be reused by a newer one) and the render's job.
struct NextKey(u64, Arc<RgbImage>, u64);

impl NextKey {
    fn same(&self, o: &NextKey) -> bool {
        self.0 == o.0 && Arc::ptr_eq(&self.1, &o.1) && self.2 == o.2
    }
}

/// What to log next when the judged log has no mistake but does not show the whole picture:
/// with the student's image, the pixels where it differs from rayscope's finished render of the
/// same settings that the log lacks (not for renders with random sampling, whose noise differs
/// everywhere); without one, a grid of pixels when the log lacks some. `None` while the log,
/// the image or the render is not ready for the current settings.
fn log_next(st: &AppState) -> Option<Value> {
    let rendered = compare_api::current_render(st);
    let settings = st.lock().settings;
    let (judged, image) = {
        let g = st.rays.lock();
        let j = g.judged.clone()?;
        if g.running.is_some() || j.settings != settings || j.log.report.disagree > 0 {
            return None;
        }
        (j, g.image.clone())
    };
    let log = &judged.log;
    let scene_path = st.scene_file.path.display().to_string();
    let flags = settings.flags();
    let Some((name, img)) = image.filter(|(_, i)| (i.width, i.height) == (settings.width, settings.height)) else {
        let sparse = LogNext::sparse(
            log.report.camera_rays,
            (log.width, log.height, log.spp),
            &flags,
            &scene_path,
        );
        return sparse.and_then(|n| serde_json::to_value(n).ok());
    };
    let rendered = rendered.filter(|r| r.settings == settings)?;
    let key = NextKey(judged.job, img.clone(), rendered.job);
    if let Some((k, v)) = &st.rays.lock().log_next {
        if k.same(&key) {
            return v.clone();
        }
    }
    // Worked out once per key, as is the answer for a render with random sampling (none).
    let v = next_for_picture(
        st,
        &settings,
        (&rendered.image.rgb, &img.rgb),
        log,
        &flags,
        (&scene_path, &pasteable(&name)),
    );
    st.rays.lock().log_next = Some((key, v.clone()));
    v
}

/// [`log_next`] for the student's picture against rayscope's render `(ours, theirs)`.
fn next_for_picture(
    st: &AppState,
    settings: &RenderSettings,
    (ours, theirs): (&[u8], &[u8]),
    log: &PixelLog,
    flags: &str,
    paths: (&str, &str),
) -> Option<Value> {
    if rayscope_core::integrator::Integrator::new(&st.scene, settings).stochastic {
        return None;
    }
    let logged: Vec<bool> = (0..log.height)
        .flat_map(|y| (0..log.width).map(move |x| (x, y)))
        .map(|(x, y)| log.status_at(x, y) != rayscope_check::PixelStatus::NotLogged)
        .collect();
    serde_json::to_value(LogNext::picture(
        &st.scene,
        settings,
        (ours, theirs),
        &logged,
        flags,
        paths,
    ))
    .ok()
}

pub(super) async fn api_summary(State(st): State<Arc<AppState>>) -> Json<Value> {
    refresh(&st);
    Json(summary_with_next(&st).await)
}

/// [`summary`] with what to log next ([`log_next`]) in its judgement. Every answer that carries
/// the summary carries it, since the page shows the last answer to arrive: an upload's answer
/// that lacked it could replace a poll's answer that had it.
async fn summary_with_next(st: &Arc<AppState>) -> Value {
    let mut v = summary(st);
    if v.get("judged").is_some() {
        // Traces up to a few thousand pixels the first time: off the async workers.
        let s = st.clone();
        if let Ok(Some(next)) = tokio::task::spawn_blocking(move || log_next(&s)).await {
            v["judged"]["next"] = next;
        }
    }
    v
}

/// A file name as sent, without its folders and control characters, at most 120 characters.
pub(super) fn clean_name(s: &str) -> String {
    let s: String = s
        .chars()
        .filter(|c| !c.is_control())
        .take(120)
        .collect::<String>()
        .rsplit(['/', '\\'])
        .next()
        .unwrap_or("")
        .to_string();
    if s.is_empty() {
        "uploaded log".into()
    } else {
        s
    }
}

pub(super) async fn api_upload(
    State(st): State<Arc<AppState>>,
    Query(q): Params,
    headers: HeaderMap,
    body: Body,
) -> ApiResult<Json<Value>> {
    let (sent, essence) = content_type(&headers);
    let name = clean_name(q.get("name").map_or("", String::as_str));
    let binary = match essence.as_str() {
        "application/x-ndjson" | "application/jsonl" => false,
        "application/octet-stream" => !name.to_ascii_lowercase().ends_with(".jsonl"),
        _ => {
            return Err(ApiError(
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                format!(
                    "send a ray log with Content-Type: application/x-ndjson (JSON Lines) or application/octet-stream (a .rays file) (got {})",
                    sent.map_or("none".to_string(), |t| format!("'{t}'"))
                ),
            ))
        }
    };
    let roles = match q.get("ray_ids") {
        Some(r) => IdRole::parse_list(r).map_err(|e| ApiError::bad(format!("ray_ids: {e}")))?,
        None => student::default_ray_ids(),
    };
    let lenient = q.get("lenient").is_some_and(|v| v == "1" || v == "true");
    let too_large = || {
        ApiError(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!("the ray log is too large (at most {MAX_LOG_BYTES} bytes); judge it with `rayscope debug SCENE --rays LOG` instead"),
        )
    };
    let declared = declared_length(&headers);
    if declared.is_some_and(|n| n > MAX_LOG_BYTES) {
        return Err(too_large());
    }
    // The newest upload wins: the one still arriving stops (its client is answered 409), so a
    // stalled upload cannot keep a new one out.
    let abort = Arc::new(tokio::sync::Notify::new());
    if let Some(old) = st.rays.lock().receiving.replace(abort.clone()) {
        old.notify_one();
    }
    let permit = match tokio::time::timeout(REPLACE_WAIT, st.rays.upload.clone().acquire_owned()).await {
        Ok(Ok(p)) => p,
        _ => {
            return Err(ApiError(
                StatusCode::SERVICE_UNAVAILABLE,
                format!(
                "another ray log is still being received and did not stop within {} s: send this one again in a moment",
                REPLACE_WAIT.as_secs()
            ),
            ))
        }
    };
    let outcome = receive(&st, body, &abort, name, binary, roles, lenient, declared).await;
    drop(permit);
    {
        let mut g = st.rays.lock();
        if g.receiving.as_ref().is_some_and(|a| Arc::ptr_eq(a, &abort)) {
            g.receiving = None;
        }
    }
    outcome?;
    Ok(Json(summary_with_next(&st).await))
}

/// Receives an upload's body and judges it as it arrives; `Ok` once judged.
#[allow(clippy::too_many_arguments)]
async fn receive(
    st: &Arc<AppState>,
    mut body: Body,
    abort: &tokio::sync::Notify,
    name: String,
    binary: bool,
    roles: Vec<IdRole>,
    lenient: bool,
    declared: Option<u64>,
) -> ApiResult<()> {
    let too_large = || {
        ApiError(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!("the ray log is too large (at most {MAX_LOG_BYTES} bytes); judge it with `rayscope debug SCENE --rays LOG` instead"),
        )
    };
    let settings = st.lock().settings;
    let (tx, rx) = tokio::sync::mpsc::channel::<Result<Bytes, String>>(16);
    let reader = ChannelReader { rx, cur: Bytes::new() };
    let placeholder = Arc::new(Source {
        name: name.clone(),
        binary,
        data: Data::Gone,
        roles: roles.clone(),
        lenient,
    });
    let (id, result) = start_job(
        st,
        placeholder,
        Some((Box::new(reader), declared.unwrap_or(0))),
        settings,
    );

    let keep_cap = st.limits.keep_log_bytes;
    let mut kept = (declared.unwrap_or(0) <= keep_cap as u64).then(Kept::default);
    let mut pace = BodyPace::new(&st.limits);
    let mut failure: Option<ApiError> = None;
    loop {
        let next = tokio::select! {
            biased;
            () = abort.notified() => Err(ApiError(
                StatusCode::CONFLICT,
                "replaced: another ray log was sent while this one was arriving".into(),
            )),
            n = pace.next(&mut body, "the ray log") => n,
        };
        let data = match next {
            Ok(Some(d)) => d,
            Ok(None) => break,
            Err(e) => {
                failure = Some(e);
                break;
            }
        };
        if pace.received > MAX_LOG_BYTES {
            failure = Some(too_large());
            break;
        }
        if kept.as_mut().is_some_and(|k| !k.push(&data, keep_cap)) {
            kept = None;
        }
        if tx.send(Ok(data)).await.is_err() {
            // The judge stopped reading: a malformed line, or a newer log replaced this one.
            break;
        }
    }
    if let Some(f) = failure {
        let _ = tx.send(Err("the upload did not complete".into())).await;
        drop(tx);
        let _ = result.await;
        return Err(f);
    }
    drop(tx);
    // The log as it can be read again, before the outcome, so that no refresh judges a stale
    // source in between.
    {
        let mut g = st.rays.lock();
        if g.running.as_ref().is_some_and(|r| r.id == id) || g.judged.as_ref().is_some_and(|j| j.job == id) {
            g.source = Some(Arc::new(Source {
                name,
                binary,
                data: kept.map_or(Data::Gone, |k| Data::Kept(Arc::new(k))),
                roles,
                lenient,
            }));
        }
    }
    let outcome = result
        .await
        .unwrap_or_else(|_| Err("judging the log failed".to_string()));
    match outcome {
        Ok(()) => Ok(()),
        Err(e) if e.starts_with("cancelled") => Err(ApiError(StatusCode::CONFLICT, e)),
        Err(e) => Err(ApiError::bad(e)),
    }
}

fn judged(st: &AppState) -> ApiResult<Arc<Judged>> {
    st.rays.lock().judged.clone().ok_or_else(|| {
        ApiError(
            StatusCode::NOT_FOUND,
            "no ray log judged yet: load one (POST /api/rays, or rayscope debug SCENE --rays LOG)".into(),
        )
    })
}

pub(super) async fn api_map(State(st): State<Arc<AppState>>) -> ApiResult<Response> {
    let j = judged(&st)?;
    Ok(png_response(j.map_png.to_vec()))
}

pub(super) async fn api_pixel(State(st): State<Arc<AppState>>, Query(q): Params) -> ApiResult<Json<Value>> {
    let j = judged(&st)?;
    let (w, h) = (j.log.width, j.log.height);
    let x = parse_num(&q, "x", u32::MAX, 0, w - 1)
        .map_err(|_| ApiError::bad(format!("x must be a pixel column from 0 to {}", w - 1)))?;
    let y = parse_num(&q, "y", u32::MAX, 0, h - 1)
        .map_err(|_| ApiError::bad(format!("y must be a pixel row from 0 to {}", h - 1)))?;
    if x == u32::MAX || y == u32::MAX {
        return Err(ApiError::bad("x and y are required (0-based pixel from the top-left)"));
    }
    let sample = match q.get("sample") {
        Some(_) => Some(parse_num(&q, "sample", 0u32, 0, u32::MAX)?),
        None => None,
    };
    let page = student::RayPage {
        offset: parse_num(&q, "offset", 0usize, 0, usize::MAX)?,
        limit: parse_num(&q, "limit", student::PAGE_RAYS, 1, student::PAGE_RAYS)?,
    };
    let slot = st.heavy.slot()?;
    let st2 = st.clone();
    let j2 = j.clone();
    // Paged before anything is copied, so the answer and what is built for it stay within a
    // page of rays whatever the pixel holds.
    let cmp = tokio::task::spawn_blocking(move || {
        let _slot = slot;
        student::compare_pixel_page(&st2.scene, &j2.settings, &j2.log, x, y, sample, page)
    })
    .await
    .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, format!("comparison failed: {e}")))?;
    let mut v = serde_json::to_value(&cmp).map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    v["page_rays"] = json!(student::PAGE_RAYS);
    let settings = st.lock().settings;
    v["stale"] = json!(j.settings != settings);
    v["samples_per_pixel"] = json!(j.log.spp);
    let px = |img: &RgbImage| {
        (img.width == w && img.height == h).then(|| {
            let i = (y * w + x) as usize * 3;
            [img.rgb[i], img.rgb[i + 1], img.rgb[i + 2]]
        })
    };
    v["their_rgb8"] = json!(st.rays.lock().image.as_ref().and_then(|(_, img)| px(img)));
    v["rayscope_rgb8"] = json!(st
        .lock()
        .rendered
        .as_ref()
        .filter(|r| r.settings.width == w && r.settings.height == h)
        .and_then(|r| px(&r.image)));
    Ok(Json(v))
}

/// Decodes a PNG of at most [`MAX_IMAGE_SIDE`] pixels a side.
fn decode_png(png: &[u8]) -> Result<RgbImage, String> {
    let img = decode_png_sized(png, |w, h| {
        if w == 0 || h == 0 || w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
            Err(format!("the image is {w}×{h}; at most {MAX_IMAGE_SIDE} pixels a side"))
        } else {
            Ok(())
        }
    })?;
    Ok(RgbImage {
        width: img.width(),
        height: img.height(),
        rgb: img.into_raw(),
    })
}

pub(super) async fn api_image_upload(
    State(st): State<Arc<AppState>>,
    Query(q): Params,
    headers: HeaderMap,
    body: Body,
) -> ApiResult<Json<Value>> {
    let body = read_body(&st, &headers, body, "image/png", "your image", IMAGE_BODY_LIMIT).await?;
    if body.is_empty() {
        return Err(ApiError::bad("send your image (a PNG) as the request body"));
    }
    let name = clean_name(q.get("name").map_or("your image", String::as_str));
    let slot = st.heavy.slot()?;
    let img = tokio::task::spawn_blocking(move || {
        let _slot = slot;
        decode_png(&body)
    })
    .await
    .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?
    .map_err(ApiError::bad)?;
    st.rays.lock().image = Some((name, Arc::new(img)));
    Ok(Json(summary_with_next(&st).await))
}

pub(super) async fn api_image(State(st): State<Arc<AppState>>) -> ApiResult<Response> {
    let img = st
        .rays
        .lock()
        .image
        .as_ref()
        .map(|(_, i)| i.clone())
        .ok_or_else(|| ApiError(StatusCode::NOT_FOUND, "no image of yours loaded".into()))?;
    let slot = st.heavy.slot()?;
    let bytes = tokio::task::spawn_blocking(move || {
        let _slot = slot;
        encode::png(&img)
    })
    .await
    .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
    Ok(png_response(bytes))
}

/// The view's student layers: `student=1` draws the student's rays of the selected pixel (its
/// first divergent ray highlighted), `verdicts=1` tints the grid with the verdict map,
/// `grid=student` paints their image on the grid.
pub(super) fn view_hook(
    st: &AppState,
    q: &HashMap<String, String>,
    settings: &RenderSettings,
    sample: u32,
    opts: &mut ViewOptions,
    image: &mut Option<Arc<RgbImage>>,
) -> ApiResult<()> {
    let on = |name: &str| q.get(name).is_some_and(|v| v == "1" || v == "true");
    match q.get("grid").map(String::as_str) {
        None | Some("rayscope") => {}
        Some("student") => {
            let g = st.rays.lock();
            if let Some((_, img)) = g.image.as_ref() {
                if img.width == settings.width && img.height == settings.height && opts.image == ImageMode::Traced {
                    *image = Some(img.clone());
                }
            }
        }
        Some(o) => return Err(ApiError::bad(format!("grid must be rayscope or student, not '{o}'"))),
    }
    let j = st.rays.lock().judged.clone();
    let Some(j) = j.filter(|j| j.log.width == settings.width && j.log.height == settings.height) else {
        return Ok(());
    };
    if on("verdicts") {
        opts.cell_tint = Some(j.tint.clone());
    }
    if on("student") {
        if let Some((x, y)) = opts.pixel {
            let cmp = student::compare_pixel(&st.scene, &j.settings, &j.log, x, y, Some(sample));
            let hl = cmp.alignment.divergence.and_then(|r| cmp.alignment.rows[r].yours);
            opts.foreign_rays = student::foreign_rays(&cmp.yours, hl);
        }
    }
    Ok(())
}
