//! The debugger's comparison of the student's image with rayscope's render, and its diagnosis.
//!
//! The student's image is the one [`rays_api`](super::rays_api) holds ("your image"): sent here,
//! sent with a ray log, or given with `rayscope debug --image`. Every answer is for the current
//! settings: a comparison is made against the finished render of the current render job only
//! (never an earlier one), and made again when the settings change and that render finishes.
//!
//! - `POST /api/compare?name=&range=` (`image/png`, the render's size): keeps the image as
//!   "your image" and answers like `GET /api/compare`.
//! - `GET /api/compare?range=auto|1..255`: `state` is `none` (no image), `size` (the image is
//!   not the render's size; `message` says what to set), `rendering` (the current render is not
//!   finished) or `done`, with PSNR, the counts, the heat map (its URL, the `heatmap_range` in
//!   levels shown at full brightness, whether it was chosen automatically and how many pixels
//!   it clips), the differing pixels attributed to entities (through mirrors) and the
//!   `diagnosis`: `running`, `waiting` (another diagnosis finishes first, or the server is
//!   busy), `done` (with `result`, [`Diagnosis`] as JSON, and `text`, the report in words) or
//!   `error`. A diagnosis for the current image and settings starts when none has run.
//! - `GET /api/compare/pixel?x=&y=`: both colours of a pixel, their difference and the entity
//!   rayscope's ray of the pixel ends on (and the mirrors it is seen in).
//! - `GET /api/compare/heatmap.png?id=`: a heat map, as the comparison names it.
//!
//! [`Diagnosis`]: rayscope_core::diagnose::Diagnosis

use rayscope_core::compare::{compare_rgb8, heatmap};
use rayscope_core::diagnose::{attribution, diagnose, differing_pixels, headline, report_text, DiagnoseOptions, Image};

use super::rays_api::their_image;
use super::*;

/// Heat maps kept for `/api/compare/heatmap.png`.
const KEEP_HEATMAPS: usize = 4;

/// A comparison of one image with one render at one heat-map range.
struct Compared {
    image: Arc<RgbImage>,
    job: u64,
    range: Option<u8>,
    json: Value,
}

/// A diagnosis in progress.
struct Diagnosing {
    image: Arc<RgbImage>,
    settings: RenderSettings,
    started: Instant,
}

/// A finished diagnosis: the result as JSON, or why it failed.
struct Diagnosed {
    image: Arc<RgbImage>,
    settings: RenderSettings,
    result: Result<Value, String>,
    millis: f64,
}

#[derive(Default)]
struct CInner {
    compared: Option<Arc<Compared>>,
    running: Option<Diagnosing>,
    done: Option<Diagnosed>,
}

/// The last comparison and diagnosis, held by the server.
#[derive(Default)]
pub(super) struct CompareState {
    inner: Mutex<CInner>,
}

impl CompareState {
    fn lock(&self) -> std::sync::MutexGuard<'_, CInner> {
        self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// The heat map's range: `auto` (or none) picks it from the images, else 1 to 255 levels.
fn parse_range(q: &HashMap<String, String>) -> ApiResult<Option<u8>> {
    match q.get("range").map(|s| s.trim()) {
        None | Some("") | Some("auto") => Ok(None),
        Some(s) => match s.parse::<u8>() {
            Ok(v) if v >= 1 => Ok(Some(v)),
            _ => Err(ApiError::bad(format!(
                "range must be auto or a whole number of levels from 1 to 255, not '{s}'"
            ))),
        },
    }
}

/// The finished render of the current render job, if it has finished.
pub(super) fn current_render(st: &AppState) -> Option<Arc<Rendered>> {
    let g = st.lock();
    g.rendered
        .clone()
        .filter(|r| r.job == g.job.id && g.job.state == JobState::Done)
}

fn size_message(img: &RgbImage, s: &RenderSettings) -> String {
    format!(
        "your image is {}×{} but the render is {}×{}: set the image size to {}×{} to compare them",
        img.width, img.height, s.width, s.height, img.width, img.height
    )
}

/// The comparison of the student's image with the current render (`state` says when there is
/// none yet), with the diagnosis's state; starts the diagnosis when none has run for them.
async fn compare_now(st: &Arc<AppState>, range: Option<u8>) -> ApiResult<Value> {
    let settings = st.lock().settings;
    let Some((name, img)) = their_image(st) else {
        return Ok(json!({"state": "none", "settings": settings_json(&settings)}));
    };
    let mut v = json!({
        "state": "done",
        "image": {"name": name, "width": img.width, "height": img.height},
        "settings": settings_json(&settings),
    });
    if (img.width, img.height) != (settings.width, settings.height) {
        v["state"] = json!("size");
        v["message"] = json!(size_message(&img, &settings));
        return Ok(v);
    }
    let Some(rendered) = current_render(st) else {
        v["state"] = json!("rendering");
        return Ok(v);
    };
    let cached = st
        .compare
        .lock()
        .compared
        .clone()
        .filter(|c| Arc::ptr_eq(&c.image, &img) && c.job == rendered.job && c.range == range);
    let compared = match cached {
        Some(c) => c,
        None => {
            let slot = st.heavy.slot()?;
            let scene = st.scene.clone();
            let (img2, r2) = (img.clone(), rendered.clone());
            let (json, png) = tokio::task::spawn_blocking(move || {
                let _slot = slot;
                compare_images(&scene, &r2, &img2, range)
            })
            .await
            .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, format!("compare failed: {e}")))?;
            let mut json = json;
            {
                let mut g = st.lock();
                let id = g.next_id;
                g.next_id += 1;
                g.heatmaps.push_back((id, Arc::new(png)));
                while g.heatmaps.len() > KEEP_HEATMAPS {
                    g.heatmaps.pop_front();
                }
                json["heatmap"] = json!(format!("/api/compare/heatmap.png?id={id}"));
            }
            let c = Arc::new(Compared {
                image: img.clone(),
                job: rendered.job,
                range,
                json,
            });
            st.compare.lock().compared = Some(c.clone());
            c
        }
    };
    if let (Some(o), Some(c)) = (v.as_object_mut(), compared.json.as_object()) {
        for (k, val) in c {
            o.insert(k.clone(), val.clone());
        }
    }
    v["diagnosis"] = diagnosis(st, &img, rendered.settings);
    Ok(v)
}

/// PSNR, counts, the heat map (as PNG bytes) and the attribution of the differing pixels.
fn compare_images(scene: &Scene, rendered: &Rendered, img: &RgbImage, range: Option<u8>) -> (Value, Vec<u8>) {
    let (ours, theirs) = (&rendered.image.rgb, &img.rgb);
    let c = compare_rgb8(ours, theirs);
    let heat = heatmap(ours, theirs, range);
    let (differing, threshold) = differing_pixels(ours, theirs);
    let shares = attribution(scene, &rendered.settings, &differing);
    let png = encode::png(&RgbImage {
        width: img.width,
        height: img.height,
        rgb: heat.rgb,
    });
    let json = json!({
        "psnr": if c.psnr.is_finite() { json!(c.psnr) } else { json!("inf") },
        "differing": c.differing,
        "total": c.total,
        "max_diff": c.max_diff,
        "threshold": threshold,
        "differing_at_threshold": differing.len(),
        "heatmap_range": heat.range,
        "heatmap_auto": heat.auto,
        "heatmap_clipped": heat.clipped,
        "attribution": shares,
        "render_job": rendered.job,
    });
    (json, png)
}

/// The diagnosis of `img` under `settings`: its result when finished, else its state; starts it
/// when none runs.
fn diagnosis(st: &Arc<AppState>, img: &Arc<RgbImage>, settings: RenderSettings) -> Value {
    let mut g = st.compare.lock();
    if let Some(d) = g
        .done
        .as_ref()
        .filter(|d| Arc::ptr_eq(&d.image, img) && d.settings == settings)
    {
        return match &d.result {
            Ok(v) => {
                let mut v = v.clone();
                v["state"] = json!("done");
                v["millis"] = json!(d.millis);
                v
            }
            Err(e) => json!({"state": "error", "error": e}),
        };
    }
    if let Some(r) = &g.running {
        let current = Arc::ptr_eq(&r.image, img) && r.settings == settings;
        return json!({
            "state": if current { "running" } else { "waiting" },
            "elapsed_ms": r.started.elapsed().as_secs_f64() * 1000.0,
            "why": if current { "" } else { "the diagnosis for the earlier settings finishes first" },
        });
    }
    let Ok(slot) = st.heavy.slot() else {
        return json!({"state": "waiting", "elapsed_ms": 0.0, "why": "the debugger is busy"});
    };
    g.running = Some(Diagnosing {
        image: img.clone(),
        settings,
        started: Instant::now(),
    });
    drop(g);
    let (st2, img2) = (st.clone(), img.clone());
    std::thread::spawn(move || {
        let _slot = slot;
        let start = Instant::now();
        let image = Image {
            width: img2.width,
            height: img2.height,
            rgb: &img2.rgb,
            alpha: None,
        };
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            diagnose(&st2.scene_file, &settings, image, &DiagnoseOptions::default())
        }));
        let scene_name = st2.scene_json["path"].as_str().unwrap_or("scene.txt").to_string();
        let result = match outcome {
            Ok(Ok(d)) => Ok(json!({
                "result": d,
                "headline": headline(&d),
                "text": report_text(&d, &scene_name),
            })),
            Ok(Err(e)) => Err(e.to_string()),
            Err(_) => Err("the diagnosis failed (a bug in rayscope: please report it)".to_string()),
        };
        let mut g = st2.compare.lock();
        g.running = None;
        g.done = Some(Diagnosed {
            image: img2.clone(),
            settings,
            result,
            millis: start.elapsed().as_secs_f64() * 1000.0,
        });
    });
    json!({"state": "running", "elapsed_ms": 0.0, "why": ""})
}

pub(super) async fn api_get(State(st): State<Arc<AppState>>, Query(q): Params) -> ApiResult<Json<Value>> {
    let range = parse_range(&q)?;
    Ok(Json(compare_now(&st, range).await?))
}

pub(super) async fn api_post(
    State(st): State<Arc<AppState>>,
    Query(q): Params,
    headers: HeaderMap,
    body: Body,
) -> ApiResult<Json<Value>> {
    let range = parse_range(&q)?;
    let name = rays_api::clean_name(q.get("name").map_or("your image", String::as_str));
    let body = read_body(
        &st,
        &headers,
        body,
        "image/png",
        "your image (a PNG)",
        COMPARE_BODY_LIMIT,
    )
    .await?;
    if body.is_empty() {
        return Err(ApiError::bad("send your image (a PNG) as the request body"));
    }
    let settings = st.lock().settings;
    let slot = st.heavy.slot()?;
    let img = tokio::task::spawn_blocking(move || {
        let _slot = slot;
        decode_reference(&body, settings.width, settings.height)
    })
    .await
    .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, format!("compare failed: {e}")))?
    .map_err(ApiError::bad)?;
    let img = RgbImage {
        width: img.width(),
        height: img.height(),
        rgb: img.into_raw(),
    };
    rays_api::set_their_image(&st, name, img);
    Ok(Json(compare_now(&st, range).await?))
}

pub(super) async fn api_pixel(State(st): State<Arc<AppState>>, Query(q): Params) -> ApiResult<Json<Value>> {
    let settings = st.lock().settings;
    let (_, img) = their_image(&st).ok_or_else(|| {
        ApiError(
            StatusCode::NOT_FOUND,
            "no image of yours loaded: choose compare… and load your PNG first".into(),
        )
    })?;
    if (img.width, img.height) != (settings.width, settings.height) {
        return Err(ApiError(StatusCode::CONFLICT, size_message(&img, &settings)));
    }
    let (w, h) = (settings.width, settings.height);
    let x = parse_num(&q, "x", u32::MAX, 0, w - 1)
        .map_err(|_| ApiError::bad(format!("x must be a pixel column from 0 to {}", w - 1)))?;
    let y = parse_num(&q, "y", u32::MAX, 0, h - 1)
        .map_err(|_| ApiError::bad(format!("y must be a pixel row from 0 to {}", h - 1)))?;
    if x == u32::MAX || y == u32::MAX {
        return Err(ApiError::bad("x and y are required (0-based pixel from the top-left)"));
    }
    let rendered = current_render(&st).ok_or_else(|| {
        ApiError(
            StatusCode::CONFLICT,
            "the render for the current settings has not finished yet".into(),
        )
    })?;
    let slot = st.heavy.slot()?;
    let scene = st.scene.clone();
    let base = rendered.settings;
    let share = tokio::task::spawn_blocking(move || {
        let _slot = slot;
        attribution(&scene, &base, &[y * w + x]).into_iter().next()
    })
    .await
    .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, format!("trace failed: {e}")))?;
    let i = (y * w + x) as usize * 3;
    let yours = [img.rgb[i], img.rgb[i + 1], img.rgb[i + 2]];
    let ours = [
        rendered.image.rgb[i],
        rendered.image.rgb[i + 1],
        rendered.image.rgb[i + 2],
    ];
    let diff: Vec<i16> = yours
        .iter()
        .zip(&ours)
        .map(|(a, b)| i16::from(*a) - i16::from(*b))
        .collect();
    Ok(Json(json!({
        "x": x,
        "y": y,
        "yours": yours,
        "rayscope": ours,
        "difference": diff,
        "max_difference": diff.iter().map(|d| d.unsigned_abs()).max().unwrap_or(0),
        "entity": share.as_ref().map(|s| s.entity.clone()),
        "seen_in": share.map(|s| s.seen_in).unwrap_or_default(),
        "render_job": rendered.job,
    })))
}

pub(super) async fn api_heatmap(State(st): State<Arc<AppState>>, Query(q): Params) -> ApiResult<Response> {
    let id = parse_num(&q, "id", 0u64, 0, u64::MAX)?;
    let g = st.lock();
    let png = g
        .heatmaps
        .iter()
        .find(|(i, _)| *i == id)
        .map(|(_, p)| p.clone())
        .ok_or_else(|| {
            ApiError(
                StatusCode::NOT_FOUND,
                format!("no such heat map (only the last {KEEP_HEATMAPS} are kept)"),
            )
        })?;
    Ok(png_response(png.to_vec()))
}
