// rayscope debugger UI: plain JavaScript, no libraries. The 3D view is drawn by the server;
// this file only sends input and shows frames, images and tables.
// Pixel coordinates are 0-based from the top-left everywhere.
"use strict";

const $ = (id) => document.getElementById(id);
const st = {
  scene: null,
  settings: null,
  selection: { type: "camera" },   // {type:"entity"|"light"|"material"|"camera", index}
  pixel: null,                      // [x, y]
  sample: 0,
  orbit: null,                      // {target:[..], dist, yaw, pitch, fov}
  defaultView: null,
  job: 0,
  renderedJob: -1,
  check: null,
  normals: false,                   // draw the selected entity's normals in the view
  zoom: 0,
  zooms: [],                        // [zoom, label] of the zoom list
  zoomChosen: false,                // the user picked a zoom: keep it when the panel changes size
  imageData: null,
};

// ---------- helpers ----------
// Numbers as a person reads them: `d` decimals, and a value too small for them in scientific
// notation, so that a tiny negative never reads "-0.000".
const fmt = (v, d = 3) => {
  if (typeof v !== "number") return String(v);
  if (Number.isInteger(v)) return String(v);
  if (Math.abs(v) < 0.5 * 10 ** -d) return v.toExponential(1);
  return v.toFixed(d);
};
const vec = (a, d = 3) => (a ? "(" + a.map((x) => fmt(x, d)).join(", ") + ")" : "—");
const rgbCss = (c) => `rgb(${c.map((x) => Math.round(Math.min(1, Math.max(0, x)) * 255)).join(",")})`;
function el(tag, attrs = {}, ...kids) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") e.className = v;
    else if (k === "style") e.style.cssText = v;
    else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else e.setAttribute(k, v);
  }
  for (const k of kids) if (k != null) e.append(k);
  return e;
}
// The server answers 503 with Retry-After while its heavy-request slots are all taken: wait and
// ask again a few times before showing the error.
async function fetchRetry(path, opts) {
  for (let attempt = 0; ; attempt++) {
    const r = await fetch(path, opts);
    if (r.status !== 503 || attempt >= 4) return r;
    const secs = Math.min(Number(r.headers.get("retry-after")) || 1, 5);
    await new Promise((done) => setTimeout(done, secs * 1000));
  }
}
async function api(path, opts) {
  const r = await fetchRetry(path, opts);
  const ct = r.headers.get("content-type") || "";
  const body = ct.includes("json") ? await r.json() : await r.text();
  if (!r.ok) throw new Error(body && body.error ? body.error : `${r.status} ${r.statusText}`);
  return body;
}

// ---------- orbit camera ----------
function orbitFrom(eye, target, fov) {
  const o = [eye[0] - target[0], eye[1] - target[1], eye[2] - target[2]];
  const dist = Math.hypot(...o);
  return { target: target.slice(), dist, yaw: Math.atan2(o[0], o[2]), pitch: Math.asin(o[1] / dist), fov };
}
function orbitEye(o) {
  const c = Math.cos(o.pitch);
  return [o.target[0] + o.dist * c * Math.sin(o.yaw), o.target[1] + o.dist * Math.sin(o.pitch), o.target[2] + o.dist * c * Math.cos(o.yaw)];
}
function orbitBasis(o) {
  const e = orbitEye(o);
  let f = [o.target[0] - e[0], o.target[1] - e[1], o.target[2] - e[2]];
  const n = Math.hypot(...f); f = f.map((x) => x / n);
  // Left-handed, +y up: right = up × forward.
  let r = [f[2], 0, -f[0]]; const rn = Math.hypot(...r) || 1; r = r.map((x) => x / rn);
  const u = [f[1] * r[2] - f[2] * r[1], f[2] * r[0] - f[0] * r[2], f[0] * r[1] - f[1] * r[0]];
  return { r, u, f };
}

// ---------- view frames ----------
let viewBusy = false, viewPending = null, viewUrl = null, draftTimer = null;
function viewParams(draft) {
  const img = $("view");
  const wrap = $("view-wrap");
  const scale = draft ? 0.5 : Math.min(window.devicePixelRatio || 1, 1.5);
  const w = Math.max(16, Math.min(2560, Math.round(wrap.clientWidth * scale)));
  const h = Math.max(16, Math.min(2560, Math.round(wrap.clientHeight * scale)));
  const o = st.orbit;
  const p = new URLSearchParams();
  p.set("eye", orbitEye(o).map((x) => x.toFixed(5)).join(","));
  p.set("target", o.target.map((x) => x.toFixed(5)).join(","));
  p.set("fov", String(o.fov));
  p.set("w", w); p.set("h", h);
  let rays = $("rays").value;
  if (rays === "pixel") rays = st.pixel ? `pixel:${st.pixel[0]},${st.pixel[1]}` : "frustum";
  else if (rays === "row") rays = st.pixel ? `row:${st.pixel[1]}` : "frustum";
  p.set("rays", rays);
  // "your image": the student's image on the pixel grid (the server's grid=student).
  const plane = $("image-mode").value;
  p.set("image", plane === "theirs" ? "traced" : plane);
  if (plane === "theirs") p.set("grid", "student");
  p.set("channel", $("channel").value);
  if (st.selection && (st.selection.type === "entity" || st.selection.type === "light")) p.set("select", `${st.selection.type}:${st.selection.index}`);
  if (st.normals && st.selection && st.selection.type === "entity") p.set("normals", "1");
  else if (st.selection && st.selection.type === "camera") p.set("select", "camera");
  if (st.pixel) {
    p.set("pixel", st.pixel.join(","));
    p.set("sample", String(st.sample));
    if ($("show-tree").checked) p.set("tree", "1");
    if ($("show-samples").checked) p.set("samples", "1");
  }
  if (st.check) p.set("check", "1");
  raysViewParams(p);
  if (!$("cutaway").checked) p.set("cutaway", "0");
  p.set("hidden", $("xray").checked ? "0.12" : "0");
  if (draft) { p.set("aa", "0"); p.set("quality", "70"); }
  return p;
}
function requestView(draft = false) {
  if (!st.orbit || !st.settings) return;
  const p = viewParams(draft);
  if (viewBusy) { viewPending = draft; return; }
  viewBusy = true;
  fetchRetry("/api/view?" + p.toString())
    .then(async (r) => {
      if (!r.ok) { const e = await r.json().catch(() => ({})); throw new Error(e.error || r.statusText); }
      const info = JSON.parse(r.headers.get("x-view-info") || "{}");
      const blob = await r.blob();
      const url = URL.createObjectURL(blob);
      const img = $("view");
      img.onload = () => { if (viewUrl && viewUrl !== url) URL.revokeObjectURL(viewUrl); viewUrl = url; };
      img.src = url;
      img.dataset.gridX = info.grid_lines_x; img.dataset.gridY = info.grid_lines_y;
      img.dataset.plane = p.get("grid") === "student" ? "yours" : p.get("image");
      img.dataset.frames = String(Number(img.dataset.frames || 0) + 1);
      const grid = info.grid_step > 1 ? `, every ${info.grid_step}th line` : "";
      const rays = info.ray_stride > 1 ? ` (every ${info.ray_stride}th pixel)` : "";
      const toolbar = $("view-toolbar").offsetHeight;
      $("view-info").textContent = `grid ${info.grid_lines_x}×${info.grid_lines_y} lines${grid} · ${info.rays_drawn} rays${rays} · ${info.millis.toFixed(0)} ms`;
      if ($("view-toolbar").offsetHeight !== toolbar) refitImage();
    })
    .catch((e) => { $("view-info").textContent = "view: " + e.message; })
    .finally(() => {
      viewBusy = false;
      if (viewPending !== null) { const d = viewPending; viewPending = null; requestView(d); }
    });
}
function dragView() {
  requestView(true);
  clearTimeout(draftTimer);
  draftTimer = setTimeout(() => requestView(false), 180);
}

function setupViewInput() {
  const img = $("view");
  let drag = null;
  img.addEventListener("contextmenu", (e) => e.preventDefault());
  img.addEventListener("pointerdown", (e) => {
    drag = { x: e.clientX, y: e.clientY, moved: false, pan: e.shiftKey || e.button === 2 || e.button === 1 };
    img.setPointerCapture(e.pointerId);
    img.classList.add("dragging");
  });
  img.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    if (!drag.moved && Math.hypot(dx, dy) < 3) return;
    drag.moved = true; drag.x = e.clientX; drag.y = e.clientY;
    const o = st.orbit;
    if (drag.pan) {
      const b = orbitBasis(o);
      const k = o.dist * 0.0016;
      for (let i = 0; i < 3; i++) o.target[i] += -b.r[i] * dx * k + b.u[i] * dy * k;
    } else {
      o.yaw += dx * 0.008;
      o.pitch = Math.max(-1.5, Math.min(1.5, o.pitch + dy * 0.008));
    }
    dragView();
  });
  img.addEventListener("pointerup", async (e) => {
    img.classList.remove("dragging");
    const d = drag; drag = null;
    if (!d || d.moved) return;
    // A click: pick what is under the pointer.
    const rect = img.getBoundingClientRect();
    const p = viewParams(false);
    const x = Math.floor((e.clientX - rect.left) / rect.width * Number(p.get("w")));
    const y = Math.floor((e.clientY - rect.top) / rect.height * Number(p.get("h")));
    const q = new URLSearchParams({ eye: p.get("eye"), target: p.get("target"), fov: p.get("fov"), w: p.get("w"), h: p.get("h"), x, y });
    try {
      const r = await api("/api/pick?" + q);
      const s = r.selection;
      if (!s) return;
      if (s.type === "pixel") selectPixel(s.index[0], s.index[1]);
      else select({ type: s.type, index: s.index });
    } catch (err) { $("view-info").textContent = err.message; }
  });
  img.addEventListener("wheel", (e) => {
    e.preventDefault();
    st.orbit.dist = Math.max(0.05, Math.min(1e5, st.orbit.dist * Math.exp(e.deltaY * 0.0012)));
    dragView();
  }, { passive: false });
  new ResizeObserver(() => { clearTimeout(draftTimer); draftTimer = setTimeout(() => requestView(false), 120); }).observe($("view-wrap"));
}

// ---------- hierarchy & inspector ----------
function buildHierarchy() {
  const ul = $("hierarchy");
  ul.innerHTML = "";
  const s = st.scene;
  const item = (sel, label, extra, cls) => {
    const li = el("li", { class: "item " + cls, "data-type": sel.type, "data-index": sel.index ?? "" }, ...extra, el("span", { class: "name" }, label));
    li.addEventListener("click", () => select(sel));
    return li;
  };
  ul.append(el("li", { class: "group" }, "Camera & image"));
  ul.append(item({ type: "camera" }, "Camera", [el("span", { class: "swatch", style: "background:#eee" })], "camera"));
  ul.append(el("li", { class: "group" }, `Entities (${s.entities.length})`));
  for (const e of s.entities) {
    const m = s.materials[e.material];
    ul.append(item({ type: "entity", index: e.index }, e.name, [el("span", { class: "swatch", style: `background:${rgbCss(m.color)}` })], "entity"));
    ul.lastChild.append(el("span", { class: "kind" }, e.kind));
  }
  ul.append(el("li", { class: "group" }, `Lights (${s.lights.length})`));
  for (const l of s.lights) {
    ul.append(item({ type: "light", index: l.index }, l.name, [el("span", { class: "swatch", style: `background:${rgbCss(l.color)};border-radius:50%` })], "light"));
  }
  ul.append(el("li", { class: "group" }, `Materials (${s.materials.length})`));
  for (const m of s.materials) {
    ul.append(item({ type: "material", index: m.index }, m.name, [el("span", { class: "swatch", style: `background:${rgbCss(m.color)}` })], "material"));
    ul.lastChild.append(el("span", { class: "kind" }, m.kind));
  }
}

function select(sel) {
  st.selection = sel;
  for (const li of document.querySelectorAll("#hierarchy li.item")) {
    li.classList.toggle("selected", li.dataset.type === sel.type && (sel.index === undefined || String(sel.index) === li.dataset.index));
  }
  renderInspector();
  requestView();
}

function dl(pairs) {
  const d = el("dl");
  for (const [k, v] of pairs) d.append(el("dt", {}, k), el("dd", {}, v));
  return d;
}
function materialLink(i) {
  const m = st.scene.materials[i];
  return el("a", { class: "link", onclick: () => select({ type: "material", index: i }) }, m ? m.name : "?");
}
function renderInspector() {
  const box = $("inspector");
  box.innerHTML = "";
  const s = st.scene, sel = st.selection;
  if (sel.type === "camera") {
    box.append(el("h3", {}, "Camera & image"));
    box.append($("settings-form").content.cloneNode(true));
    fillSettingsForm();
    for (const input of box.querySelectorAll("input, select")) input.addEventListener("change", onSettingsChange);
    return;
  }
  if (sel.type === "entity") {
    const e = s.entities[sel.index];
    box.append(el("h3", {}, e.name));
    const pairs = [["kind", e.kind], ["material", materialLink(e.material)], ["line", String(e.line)], ["primitives", String(e.primitives)]];
    const p = e.params;
    const shown = { unit_normal: 1, normal: e.kind === "Triangle" ? 1 : 0 };
    for (const [k, v] of Object.entries(p)) if (!shown[k]) pairs.push([k, Array.isArray(v) ? vec(v) : fmt(v)]);
    // Which side of a plane or triangle the ray tracer's camera is on: its front face is lit
    // and seen from there.
    const cam = st.settings && st.settings.cam_pos;
    const side = (n, q) => {
      if (!cam) return "—";
      const d = n[0] * (cam[0] - q[0]) + n[1] * (cam[1] - q[1]) + n[2] * (cam[2] - q[2]);
      return d > 0 ? "front face (the normal points towards it)" : d < 0 ? "back face (the normal points away)" : "edge-on";
    };
    if (e.kind === "Plane") {
      pairs.push(["unit normal", vec(p.unit_normal, 4)], ["camera sees", side(p.unit_normal, p.point)]);
    } else if (e.kind === "Triangle") {
      pairs.push(["normal", el("span", {}, vec(p.normal, 4), el("div", { class: "dim" }, "(v1 − v0) × (v2 − v0), normalised"))]);
      pairs.push(["winding", "v0 → v1 → v2 clockwise seen from the front (the side the normal points to; left-handed, +y up)"]);
      pairs.push(["camera sees", side(p.normal, p.v0)]);
    }
    box.append(dl(pairs));
    const cb = el("input", { type: "checkbox", id: "show-normals" });
    cb.checked = !!st.normals;
    cb.addEventListener("change", () => { st.normals = cb.checked; requestView(); });
    box.append(el("label", { class: "dim" }, cb, " show normals as arrows in the view"));
  } else if (sel.type === "light") {
    const l = s.lights[sel.index];
    box.append(el("h3", {}, l.name));
    box.append(dl([["kind", "PointLight"], ["position", vec(l.position)], ["colour", vec(l.color)], ["line", String(l.line)]]));
  } else if (sel.type === "material") {
    const m = s.materials[sel.index];
    box.append(el("h3", {}, m.name));
    const users = s.entities.filter((e) => e.material === m.index).map((e) => e.name).join(", ") || "—";
    box.append(dl([["type", m.kind], ["colour", el("span", {}, el("span", { class: "swatch", style: `background:${rgbCss(m.color)}` }), " " + vec(m.color))], [m.kind === "Refractive" ? "index" : "value", fmt(m.value)], ["line", String(m.line)], ["used by", users]]));
  }
  box.append(el("p", { class: "dim" }, el("a", { class: "link", onclick: () => select({ type: "camera" }) }, "← camera & image settings")));
}

function fillSettingsForm() {
  const s = st.settings;
  const f = $("settings");
  if (!f) return;
  for (const input of f.querySelectorAll("input, select")) {
    const v = s[input.name];
    if (input.dataset.i !== undefined) input.value = v[Number(input.dataset.i)];
    else if (input.type === "checkbox") input.checked = !!v;
    else input.value = v;
  }
}

let settingsTimer = null;
function onSettingsChange() {
  clearTimeout(settingsTimer);
  settingsTimer = setTimeout(sendSettings, 120);
}
async function sendSettings() {
  const f = $("settings");
  const patch = {};
  for (const input of f.querySelectorAll("input, select")) {
    const name = input.name;
    if (input.dataset.i !== undefined) {
      patch[name] = patch[name] || [0, 0, 0];
      patch[name][Number(input.dataset.i)] = Number(input.value);
    } else if (input.type === "checkbox") patch[name] = input.checked;
    else if (input.type === "number") patch[name] = Number(input.value);
    else patch[name] = input.value;
  }
  try {
    const r = await api("/api/settings", { method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(patch) });
    $("settings-error").textContent = "";
    onNewSettings(r.settings, r.job);
  } catch (e) {
    $("settings-error").textContent = e.message;
  }
}
function onNewSettings(settings, job) {
  const sizeChanged = !st.settings || settings.width !== st.settings.width || settings.height !== st.settings.height;
  st.settings = settings;
  st.job = job;
  if (st.pixel && (st.pixel[0] >= settings.width || st.pixel[1] >= settings.height)) st.pixel = null;
  if (sizeChanged) { st.check = null; $("check-summary").textContent = "not run yet"; st.zoomChosen = false; setupZoom(); }
  st.sample = 0;
  fillSettingsForm();
  pollStatus();
  requestView();
  if (st.pixel) tracePixel();
  raysOnSettings();
  compareOnSettings();
}

// ---------- render status ----------
let pollTimer = null;
async function pollStatus() {
  clearTimeout(pollTimer);
  try {
    const s = await api("/api/render/status");
    $("progress-bar").style.width = `${(s.progress * 100).toFixed(1)}%`;
    if (s.state === "running") {
      $("status-text").textContent = `rendering ${s.settings.width}×${s.settings.height}… ${(s.progress * 100).toFixed(0)}%`;
      pollTimer = setTimeout(pollStatus, 200);
    } else {
      $("status-text").textContent = s.state === "done" ? `rendered ${s.settings.width}×${s.settings.height} in ${s.elapsed_ms.toFixed(0)} ms` : s.state;
      if (s.rendered && s.rendered.job !== st.renderedJob) {
        st.renderedJob = s.rendered.job;
        loadImage();
        requestView();
        raysLoadRendered();
        if (cmp.loaded) comparePoll();
      }
    }
  } catch (e) {
    $("status-text").textContent = "server: " + e.message;
    pollTimer = setTimeout(pollStatus, 1000);
  }
}

// ---------- image panel ----------
// Zooms below 1× let a large image fit the panel; at 1× and above every image pixel is a
// square of screen pixels.
const ZOOMS = [[1 / 8, "⅛×"], [1 / 6, "⅙×"], [1 / 4, "¼×"], [1 / 3, "⅓×"], [1 / 2, "½×"], [2 / 3, "⅔×"], [3 / 4, "¾×"],
  [1, "1×"], [2, "2×"], [3, "3×"], [4, "4×"], [6, "6×"], [8, "8×"], [12, "12×"], [16, "16×"], [24, "24×"], [32, "32×"], [48, "48×"], [64, "64×"]];
function setupZoom() {
  const z = $("zoom");
  const s = st.settings;
  const box = $("image-scroll");
  // Side by side, two images and the gap between them share the width.
  const side = compareMode() === "side";
  const caption = side ? 18 : 0;
  const fitW = (box.clientWidth - 20 - (side ? 12 : 0)) / (s.width * (side ? 2 : 1));
  const fitH = (box.clientHeight - 20 - caption) / s.height;
  const fit = Math.max(0, Math.min(fitW, fitH));
  // An image larger than the panel starts at the zoom that fits it exactly.
  st.zooms = ZOOMS.filter(([k]) => Math.abs(k - fit) > 0.01);
  if (fit < 1) st.zooms.push([fit, `fit (${Math.round(fit * 100)} %)`]);
  st.zooms.sort((a, b) => a[0] - b[0]);
  z.innerHTML = "";
  st.zooms.forEach(([, label], i) => z.append(el("option", { value: String(i) }, label)));
  let best = 0;
  st.zooms.forEach(([k], i) => { if (k <= fit + 1e-9) best = i; });
  z.value = String(best);
  st.zoom = st.zooms[best][0];
  layoutImage();
}
// The fitting zoom again after the panel changed size, unless the user picked one.
function refitImage() {
  if (!st.zoomChosen && st.settings) setupZoom();
}
function layoutImage() {
  const s = st.settings;
  const w = Math.max(1, Math.round(s.width * st.zoom)), h = Math.max(1, Math.round(s.height * st.zoom));
  for (const [i, o] of [["image", "image-overlay"], ["image-b", "image-overlay-b"]]) {
    const img = $(i), ov = $(o);
    img.style.width = `${w}px`;
    img.style.height = `${h}px`;
    img.classList.toggle("smooth", st.zoom < 1);
    ov.width = w; ov.height = h;
    ov.style.width = img.style.width; ov.style.height = img.style.height;
  }
  $("image").dataset.zoom = String(st.zoom);
  drawOverlay();
}
// What the image panel shows: rayscope's channel, or with a comparison your image, the two
// alternating (flicker) or the heat map; side by side puts yours to the right.
function imageShowing() {
  const m = compareMode();
  if (m === "heat" && cmp.urls.heat) return "heat";
  if (m === "yours" && cmp.urls.theirs) return "yours";
  if (m === "flicker" && cmp.urls.rs) return cmp.showing;
  return "rayscope";
}
function imageSrc() {
  const showing = imageShowing();
  if (showing === "heat") return cmp.urls.heat;
  if (showing === "yours") return cmp.urls.theirs;
  if (compareMode() === "flicker" && cmp.urls.rs) return cmp.urls.rs;
  return `/api/image.png?channel=${$("channel").value}&job=${st.renderedJob}`;
}
function loadImage() {
  const img = $("image");
  img.dataset.showing = imageShowing();
  const b = $("image-b");
  if (compareMode() === "side" && cmp.urls.theirs) { if (b.src !== cmp.urls.theirs) b.src = cmp.urls.theirs; } else b.removeAttribute("src");
  img.onload = () => {
    const c = document.createElement("canvas");
    c.width = img.naturalWidth; c.height = img.naturalHeight;
    const g = c.getContext("2d");
    g.drawImage(img, 0, 0);
    try { st.imageData = g.getImageData(0, 0, c.width, c.height); } catch (_) { st.imageData = null; }
    img.dataset.loaded = `${img.naturalWidth}x${img.naturalHeight}`;
  };
  // A busy server (503) or a render still on its way: try again a few times.
  let tries = 0;
  img.onerror = () => {
    st.imageData = null;
    if (!imageSrc().startsWith("blob:") && ++tries <= 4) setTimeout(() => { img.src = imageSrc() + `&try=${tries}`; }, 1000);
  };
  img.src = imageSrc();
  layoutImage();
}
function drawOverlay() {
  const ov = $("image-overlay");
  const g = ov.getContext("2d");
  g.clearRect(0, 0, ov.width, ov.height);
  const z = st.zoom;
  if (st.check && st.check.mismatches) {
    g.strokeStyle = "#ff00ff"; g.lineWidth = Math.max(1, z / 6);
    g.fillStyle = "rgba(255,0,255,0.45)";
    for (const m of st.check.mismatches) { g.fillRect(m.x * z, m.y * z, z, z); }
  }
  raysDrawOverlay(g, z);
  const gb = $("image-overlay-b").getContext("2d");
  gb.clearRect(0, 0, ov.width, ov.height);
  if (st.pixel) {
    for (const c of [g, gb]) {
      c.strokeStyle = "#ffd21a"; c.lineWidth = Math.max(1.5, z / 5);
      c.strokeRect(st.pixel[0] * z + 0.5, st.pixel[1] * z + 0.5, Math.max(z - 1, 1), Math.max(z - 1, 1));
    }
  }
}
function imagePixelAt(e) {
  const img = e.currentTarget && e.currentTarget.id === "image-b" ? $("image-b") : $("image");
  const rect = img.getBoundingClientRect();
  const x = Math.floor((e.clientX - rect.left) / rect.width * st.settings.width);
  const y = Math.floor((e.clientY - rect.top) / rect.height * st.settings.height);
  if (x < 0 || y < 0 || x >= st.settings.width || y >= st.settings.height) return null;
  return [x, y];
}
function setupImageInput() {
  for (const img of [$("image"), $("image-b")]) {
    img.addEventListener("mousemove", (e) => {
      const p = imagePixelAt(e);
      if (!p) return;
      let col = "";
      const d = st.imageData;
      if (imageShowing() === "rayscope" && d && d.width === st.settings.width && d.height === st.settings.height) {
        const i = (p[1] * d.width + p[0]) * 4;
        const c = [d.data[i], d.data[i + 1], d.data[i + 2]];
        col = ` = rgb(${c.join(", ")}) = (${c.map((v) => (v / 255).toFixed(3)).join(", ")})`;
      }
      $("pixel-readout").textContent = raysReadout(p) || `pixel (${p[0]}, ${p[1]})${col}`;
      compareHover(p);
    });
    img.addEventListener("click", (e) => {
      const p = imagePixelAt(e);
      if (!p) return;
      const q = raysSnap(p);
      selectPixel(q[0], q[1]);
    });
  }
  $("zoom").addEventListener("change", () => { st.zoom = st.zooms[Number($("zoom").value)][0]; st.zoomChosen = true; layoutImage(); });
  // The panel changes size with the window and the toolbars above it: the fitting zoom follows.
  new ResizeObserver(refitImage).observe($("image-scroll"));
  $("channel").addEventListener("change", () => { loadImage(); requestView(); });
  compareSetupInput();
  $("check-btn").addEventListener("click", runCheck);
  raysSetupInput();
  $("rays-logged-filter").addEventListener("change", raysLoggedList);
}

// A click on a pixel the loaded ray log has no ray for selects the nearest logged pixel within
// about a dozen screen pixels: a log of a few pixels is clickable at any zoom.
function raysSnap(p) {
  const m = rays.mapData;
  if (!m || m.width !== st.settings.width || m.height !== st.settings.height) return p;
  const logged = (x, y) => {
    const i = (y * m.width + x) * 4;
    const s = RAYS_STATUS[`${m.data[i]},${m.data[i + 1]},${m.data[i + 2]}`];
    return s !== undefined && s !== "not logged";
  };
  if (logged(p[0], p[1])) return p;
  const r = Math.max(3, Math.ceil(12 / st.zoom));
  let best = p, bd = Infinity;
  for (let y = Math.max(0, p[1] - r); y <= Math.min(m.height - 1, p[1] + r); y++) {
    for (let x = Math.max(0, p[0] - r); x <= Math.min(m.width - 1, p[0] + r); x++) {
      const d = (x - p[0]) ** 2 + (y - p[1]) ** 2;
      if (d < bd && logged(x, y)) { bd = d; best = [x, y]; }
    }
  }
  return best;
}

function selectPixel(x, y, sample = 0) {
  st.pixel = [x, y];
  st.sample = sample;
  drawOverlay();
  tracePixel();
  requestView();
  raysPixel();
}

// ---------- ray tree ----------
// Very small numbers (an acne blocker at t = 3e-7) in scientific notation rather than as 0.000.
const fmtSmall = (v) => (v !== 0 && Math.abs(v) < 5e-4 ? v.toExponential(3) : fmt(v, 4));
// A secondary ray's origin as its parent's hit point P plus the offset.
function offsetText(n) {
  if (!n.offset) return null;
  let t;
  if (n.offset.every((x) => x === 0)) t = "P (no offset)";
  else if (n.offset_along_normal != null) t = `P ${n.offset_along_normal < 0 ? "−" : "+"} ${Math.abs(n.offset_along_normal).toExponential(3)}·n`;
  else t = "P + (" + n.offset.map((x) => x.toExponential(2)).join(", ") + ")";
  return el("div", { class: "dim" }, t);
}
function glassText(g) {
  let s = `glass: ${g.entering ? "entering" : "leaving"}, n₁ ${fmt(g.n1, 4)} → n₂ ${fmt(g.n2, 4)}, cos θᵢ ${fmt(g.cos_i, 4)}`;
  s += g.cos_t != null ? `, cos θₜ ${fmt(g.cos_t, 4)}` : ", total internal reflection";
  return s + `, Fresnel reflectance ${fmt(g.reflectance, 4)}`;
}
function branchText(br, g) {
  if (br.fate === "pruned") return `pruned, not traced: path weight ${br.path_weight.toExponential(2)} < ${g.prune_below.toExponential(2)}, so it could not change an 8-bit value (tracing it is not wrong)`;
  if (br.fate === "not_chosen") return "not chosen (after a sampled bounce glass follows one ray, picked by its Fresnel weight)";
  return g.tir && br.weight === 0 && !br.direction ? "none (total internal reflection)" : "none (weight 0)";
}
const KIND_COLORS = { camera: "#ffffff", shadow: "#ffdb33", reflection: "#33e5ff", refraction: "#ff59e5", emitter: "#ff9919", bounce: "#66ff66" };
async function tracePixel() {
  if (!st.pixel) return;
  const [x, y] = st.pixel;
  showTab("tree-tab");
  try {
    const r = await api(`/api/trace?x=${x}&y=${y}&sample=${st.sample}`);
    const t = r.tree;
    const head = $("tree-head");
    head.innerHTML = "";
    head.append(`pixel (${x}, ${y}), sample ${t.sample} of ${r.samples_per_pixel} — colour ${vec(t.color)}`);
    if (r.pixel_rgb8) head.append(` — image byte value rgb(${r.pixel_rgb8.join(", ")})`);
    if (r.samples_per_pixel > 1) {
      const sel = el("select", { id: "sample-select" });
      for (let i = 0; i < r.samples_per_pixel; i++) {
        const pos = r.sample_positions[i];
        sel.append(el("option", { value: i }, `sample ${i}` + (pos ? ` @ (${pos[0].toFixed(3)}, ${pos[1].toFixed(3)})` : "")));
      }
      sel.value = String(st.sample);
      sel.addEventListener("change", () => { st.sample = Number(sel.value); tracePixel(); requestView(); });
      head.append(" ", sel);
    }
    const tb = $("tree").querySelector("tbody");
    tb.innerHTML = "";
    for (const n of t.nodes) {
      // A blocked shadow ray shows its blocker's distance, point and face in the hit columns.
      const b = n.blocker;
      const h = n.hit || b;
      const face = (x) => (x.front_face ? " (front)" : " (back)");
      const entity = n.hit ? n.hit.entity_name : n.blocked_by ? `blocked by ${n.blocked_by}` : n.light ? `→ ${n.light} (clear)` : "miss";
      const tr = el("tr", {},
        el("td", {}, String(n.id) + (n.parent !== null && n.parent !== undefined ? ` ←${n.parent}` : "")),
        el("td", { class: "k", style: `color:${n.blocked_by ? "#ff4026" : KIND_COLORS[n.kind] || "#fff"}` }, n.kind),
        el("td", {}, String(n.depth)),
        el("td", { title: `origin ${JSON.stringify(n.origin)}` + (n.offset ? `\noffset from the parent's hit point ${JSON.stringify(n.offset)}` : "") }, vec(n.origin), offsetText(n)),
        el("td", { title: JSON.stringify(n.direction) }, vec(n.direction)),
        el("td", { title: h ? String(h.t) : "" }, h ? fmtSmall(h.t) : n.t_max != null ? `≤ ${fmt(n.t_max, 4)}` : "∞"),
        el("td", { class: "entity" }, entity),
        el("td", { title: h ? JSON.stringify(h.point) : "" }, h ? vec(h.point) : "—"),
        el("td", { title: h ? JSON.stringify(h.normal) : "" }, h ? vec(h.normal) + face(h) : "—"),
        el("td", {}, h ? `${h.material} (${h.material_kind})` : "—"),
        el("td", { title: String(n.weight) }, fmt(n.weight, 3)),
        el("td", {}, el("span", { class: "swatch", style: `background:${rgbCss(n.value)}` }), " " + vec(n.value)),
      );
      tb.append(tr);
      if (n.glass) {
        tb.append(el("tr", { class: "glass" }, el("td"), el("td", { colspan: "11" }, glassText(n.glass))));
        for (const [kind, br] of [["reflection", n.glass.reflected], ["refraction", n.glass.refracted]]) {
          if (br.fate === "traced") continue;
          tb.append(el("tr", { class: "pruned dim" },
            el("td", {}, `– ←${n.id}`),
            el("td", { class: "k" }, kind),
            el("td", {}, String(n.depth + 1)),
            el("td", {}, br.origin ? vec(br.origin) : "—"),
            el("td", {}, br.direction ? vec(br.direction) : "—"),
            el("td", { colspan: "7" }, branchText(br, n.glass))));
        }
      }
    }
  } catch (e) {
    $("tree-head").textContent = e.message;
  }
}

// ---------- intersector check ----------
async function runCheck() {
  showTab("check-tab");
  $("check-summary").textContent = "tracing every pixel with both intersectors…";
  try {
    const r = await api("/api/check");
    st.check = r;
    const real = r.count - r.ties;
    $("check-summary").textContent = `${r.count} of ${r.total} pixels disagree (${real} real, ${r.ties} ties between entities at the same distance) — ${r.millis.toFixed(0)} ms` + (r.listed < r.count ? ` — first ${r.listed} listed` : "");
    const tb = $("check-list").querySelector("tbody");
    tb.innerHTML = "";
    const ans = (a) => (a ? `${a.name} t=${fmt(a.t, 5)}` : "miss");
    for (const m of r.mismatches.slice(0, 1000)) {
      const tr = el("tr", {}, el("td", {}, `(${m.x}, ${m.y})`), el("td", {}, m.kind), el("td", {}, ans(m.ours)), el("td", {}, ans(m.reference)));
      tr.addEventListener("click", () => {
        for (const o of tb.querySelectorAll("tr.sel")) o.classList.remove("sel");
        tr.classList.add("sel");
        const box = $("check-detail");
        box.innerHTML = "";
        box.append(el("div", { class: "answers" },
          el("div", {}, el("b", {}, "rayscope"), el("br"), ans(m.ours)),
          el("div", {}, el("b", {}, "parry3d reference"), el("br"), ans(m.reference))));
        st.pixel = [m.x, m.y]; st.sample = 0; drawOverlay(); requestView();
      });
      tb.append(tr);
    }
    drawOverlay();
    requestView();
  } catch (e) {
    $("check-summary").textContent = e.message;
  }
}

// ---------- comparing the student's image ----------
// The server compares "your image" with the finished render of the current settings only and
// diagnoses it in the background. A settings change blanks the comparison until the new render
// has been compared, so no PSNR, heat map or diagnosis of other settings is ever on screen.
const cmp = {
  loaded: false, data: null, seq: 0, timer: null, urls: {}, loading: null, showing: "rayscope", flickerTimer: null,
  hover: null, hoverBusy: false, sideShown: false,
};
function compareMode() { return cmp.data ? $("compare-mode").value : "rayscope"; }
function compareSetupInput() {
  for (const id of ["compare-file", "compare-file-2"]) {
    $(id).addEventListener("change", () => { const f = $(id).files[0]; if (f) theirImageUpload(f); $(id).value = ""; });
  }
  $("compare-mode").addEventListener("change", compareShow);
  $("heat-range").addEventListener("change", comparePoll);
  $("flicker-auto").addEventListener("change", compareFlicker);
  $("flicker-swap").addEventListener("click", () => { $("flicker-auto").checked = false; compareFlicker(); flickerSwap(); });
}
// Their image goes to the server as "your image" (any size: the comparison says which size to
// set when it is not the render's).
async function theirImageUpload(file) {
  showTab("compare-tab");
  compareSummary(`reading ${file.name}…`, "loading");
  try {
    const s = await api(`/api/rays/image?name=${encodeURIComponent(file.name)}`, { method: "POST", headers: { "content-type": "image/png" }, body: file });
    raysOnSummary(s);
    raysPoll();
    raysChoose(null);
    cmp.data = null;
    compareDropImages();
    comparePoll();
  } catch (e) {
    compareSummary(`${file.name}: ${e.message}`, "error", "error");
    $("compare-result").textContent = `${file.name}: ${e.message}`;
  }
}
function compareSummary(text, state, cls) {
  const box = $("compare-summary");
  box.textContent = text;
  box.dataset.state = state;
  box.className = cls || "dim";
}
async function comparePoll() {
  clearTimeout(cmp.timer);
  const seq = ++cmp.seq;
  try {
    const v = await api(`/api/compare?range=${$("heat-range").value}`);
    if (seq === cmp.seq) compareOnAnswer(v);
  } catch (e) {
    if (seq !== cmp.seq) return;
    compareSummary(e.message, "error", "error");
    cmp.timer = setTimeout(comparePoll, 2000);
  }
}
function compareOnSettings() {
  if (!cmp.loaded) return;
  cmp.seq++;
  clearTimeout(cmp.timer);
  const had = !!cmp.data;
  cmp.data = null;
  $("compare-result").textContent = "settings changed: your image will be compared with the new render when it is finished…";
  const ro = $("pixel-readout");
  ro.textContent = "hover the image";
  for (const k of ["pixel", "yours", "rayscope", "entity"]) delete ro.dataset[k];
  $("compare-result").dataset.state = "stale";
  compareSummary("settings changed: comparing your image with the new render when it is finished…", "rendering", "warn");
  compareClearDetails();
  if (had) compareShow();
  comparePoll();
}
// Forgets the images of a comparison that no longer holds.
function compareDropImages() {
  for (const u of Object.values(cmp.urls)) if (typeof u === "string" && u.startsWith("blob:")) URL.revokeObjectURL(u);
  cmp.urls = {};
}
function compareClearDetails() {
  compareDropImages();
  raysChoose(null);
  $("diagnosis").innerHTML = "";
  $("diagnosis").dataset.state = "none";
  $("attribution-box").classList.add("hidden");
  $("attribution").querySelector("tbody").innerHTML = "";
}
const db = (v) => (v == null ? "∞ dB (identical)" : `${Number(v).toFixed(1)} dB`);
function compareOnAnswer(v) {
  const res = $("compare-result");
  cmp.loaded = v.state !== "none";
  $("compare-mode-label").classList.toggle("hidden", !cmp.loaded);
  // While comparing, the image panel takes more of the window.
  if (document.body.classList.contains("comparing") !== cmp.loaded) {
    document.body.classList.toggle("comparing", cmp.loaded);
    $("compare-bars").classList.toggle("hidden", !cmp.loaded);
    refitImage();
  }
  if (v.state !== "done") {
    const had = !!cmp.data;
    cmp.data = null;
    compareClearDetails();
    if (had) compareShow();
    res.dataset.state = v.state;
    if (v.state === "none") { res.textContent = ""; compareSummary("no image of yours loaded: choose “compare your image…” or drop your tracer's PNG on the page", "none"); return; }
    if (v.state === "size") {
      res.textContent = v.message;
      compareSummary(`${v.image.name}: ${v.message}`, "size", "warn");
      const w = v.image.width, h = v.image.height;
      $("compare-summary").append(" ", el("button", { id: "compare-set-size", onclick: () => applySettings({ width: w, height: h }) }, `render at ${w}×${h}`));
      return;
    }
    res.textContent = `${v.image.name}: waiting for the render at the current settings…`;
    compareSummary(res.textContent, "rendering");
    cmp.timer = setTimeout(comparePoll, 300);
    return;
  }
  // The images are fetched once per comparison (its heat map's URL names it).
  const fresh = cmp.urls.key !== v.heatmap && cmp.loading !== v.heatmap;
  cmp.data = v;
  const psnr = v.psnr === "inf" ? "∞ (identical)" : `${Number(v.psnr).toFixed(2)} dB`;
  const pct = (100 * v.differing / v.total).toFixed(1);
  const text = `${v.image.name} vs rayscope: PSNR ${psnr} · ${v.differing} of ${v.total} pixels differ (${pct} %) · largest difference ${v.max_diff} levels`;
  res.textContent = text;
  res.title = text;
  res.dataset.state = "done";
  res.dataset.job = String(v.render_job);
  compareSummary(`${text} — rendered at ${v.settings.width}×${v.settings.height}, -x ${v.settings.aa}, stage ${v.settings.stage}`, "done");
  $("compare-summary").dataset.job = String(v.render_job);
  // The heat map's scale.
  $("heat-max").textContent = `${v.heatmap_range} level${v.heatmap_range === 1 ? "" : "s"} or more` + (v.heatmap_auto ? " (auto)" : "");
  $("heat-note").textContent = v.heatmap_clipped ? `${v.heatmap_clipped} pixels differ by more (shown at full brightness)` : "no pixel differs by more";
  compareAttribution(v.attribution, v.differing_at_threshold, v.threshold);
  compareDiagnosis(v.diagnosis);
  if (fresh) compareLoadImages(v); else compareShow();
  const d = v.diagnosis;
  if (d && (d.state === "running" || d.state === "waiting")) cmp.timer = setTimeout(comparePoll, 700);
}
function compareAttribution(shares, n, threshold) {
  const box = $("attribution-box");
  const tb = $("attribution").querySelector("tbody");
  tb.innerHTML = "";
  box.classList.toggle("hidden", !shares.length);
  for (const s of shares.slice(0, 12)) {
    const where = s.seen_in.length ? el("span", { class: "dim" }, ` seen in ${s.seen_in.join(" in ")}`) : null;
    tb.append(el("tr", {}, el("td", { class: "bar" }, el("span", { style: `width:${Math.max(2, s.percent)}%` })), el("td", {}, `${s.percent.toFixed(1)} %`), el("td", { class: "entity" }, s.entity, where)));
  }
  $("attribution-box").querySelector("h4 .dim").textContent = `(${n} pixels differ by ${threshold} or more levels: what rayscope's ray of each ends on; through mirrors, the thing reflected)`;
}
function compareDiagnosis(d) {
  const box = $("diagnosis");
  box.innerHTML = "";
  box.dataset.state = d ? d.state : "none";
  if (!d) return;
  if (d.state === "running" || d.state === "waiting") {
    box.className = "diagnosis";
    box.append(el("b", {}, `diagnosing… ${(d.elapsed_ms / 1000).toFixed(0)} s`),
      el("p", { class: "dim" }, "rayscope renders the scene again with the settings students most often get wrong and with the catalogue of common mistakes, alone and in pairs, and looks for the render your image matches." + (d.why ? ` (${d.why})` : "")));
    return;
  }
  if (d.state === "error") {
    box.className = "diagnosis bad";
    box.append(el("span", { class: "error" }, `the diagnosis failed: ${d.error}`));
    return;
  }
  const r = d.result;
  // What is plain about the image (black, upside down, alpha, gamma…) comes first, before the search's verdict.
  const obvious = r.obvious || [];
  for (const o of obvious) box.append(el("p", { class: "obvious", "data-code": o.code }, el("b", {}, o.text)));
  const turned = obvious.some((o) => o.turned_back);
  const plain = obvious.find((o) => ["black", "white", "constant"].includes(o.code));
  const yours = obvious.some((o) => o.turned_back && o.code !== "channels") ? "Turned back, your image"
    : turned ? "With its channels in order, your image" : "Your image";
  // The match rule is the ties' (docs/mistakes.md): turned back, no pixel beyond them is a match too.
  if (r.matches || (turned && !r.explanations.length && r.ties.beyond_ties === 0)) {
    box.className = r.matches ? "diagnosis ok" : "diagnosis bad";
    box.append(el("b", {}, `${yours} matches rayscope's render.`),
      el("p", {}, r.ties.differing_pixels === 0 ? "Identical, pixel for pixel."
        : `PSNR ${db(r.psnr_db)}; the ${r.ties.differing_pixels} of ${r.total_pixels} pixels that are not rayscope's colour differ only where two correct tracers may: a ray of theirs passes within rounding of an edge, a rim, a seam or a shadow's edge, or their colour lies within rounding of a byte boundary.`));
    return;
  }
  box.className = "diagnosis bad";
  const partText = (e) => {
    const x = e.explained;
    if (!x) return "explains a part of it";
    const parts = x.parts.filter((p) => p.pixels >= 10);
    const best = parts.sort((a, b) => b.percent - a.percent)[0];
    const where = best ? `${best.percent.toFixed(0)} % of ${best.entity}${best.seen_in.length ? ` (seen in ${best.seen_in.join(" in ")})` : ""}'s differing pixels, ` : "";
    return `explains ${where}${x.percent.toFixed(0)} % of all the differing pixels`;
  };
  // The headline is the core's, word for word (the command line's report starts with it): the
  // cause, or what is recognised or fitted, or how much a known mistake explains, or that none does.
  const [head, ...beneath] = (d.headline || "").split("\n").filter((l) => l.trim());
  if (head) box.append(el("b", { id: "diagnosis-headline" }, head));
  for (const l of beneath) box.append(el("p", { class: "headline-more" }, l.trim()));
  box.append(el("p", {}, `${yours} differs from rayscope's: PSNR ${db(r.psnr_db)} (${db(r.psnr_downsampled_db)} on 4×4 averages); ${r.differing_pixels} of ${r.total_pixels} pixels differ by ${r.threshold} or more levels, by up to ${r.max_channel_diff}.` +
      (r.region ? ` They lie in columns ${r.region.x0}–${r.region.x1 - 1}, rows ${r.region.y0}–${r.region.y1 - 1}.` : "")));
  if (r.attribution && r.attribution.length) {
    const ul = el("ul", { id: "diagnosis-where" });
    for (const a of r.attribution.slice(0, 6)) {
      ul.append(el("li", {}, `${a.percent.toFixed(1)} % ${a.entity}${a.seen_in.length ? `, seen in ${a.seen_in.join(" in ")}` : ""}${a.how ? `: ${a.how}` : ""}`));
    }
    box.append(el("p", {}, "Where they are:"), ul);
  }
  const scene = st.scene.path;
  const list = (items, title, id, says) => {
    if (!items.length) return;
    box.append(el("p", {}, title));
    const ol = el("ol", { id });
    for (const e of items) {
      const li = el("li", { "data-settings": e.settings.join(" "), "data-mistakes": e.mistakes.join(" ") }, says(e),
        el("br"), el("span", { class: "dim" }, "see it: "), el("code", {}, `rayscope -f ${scene} -o explained.png ${e.flags}`));
      const patch = e.mistakes.length || !Object.keys(e.patch).length ? null : e.patch;
      if (patch) li.append(" ", el("button", { onclick: () => applySettings(patch) }, "render with this here"));
      ol.append(li);
    }
    box.append(ol);
  };
  // A render that matches by turning entities black, as painting them black does too, by losing
  // glass's refracted light or a kind's shadows, as losing them any other way does too, or as
  // other mistakes' renders do, is one way to get the picture: listed with the causes, said as
  // what it is.
  const lost = (e) => Boolean(e.loses_refraction && e.loses_refraction.length);
  const twins = (e) => Boolean(e.same_as && e.same_as.length);
  const shadowless = (e) => Boolean(e.shadowless);
  const oneWay = (e) => Boolean(e.blackens && e.blackens.length) || lost(e) || twins(e) || shadowless(e);
  const kinds = { Sphere: "spheres", Plane: "planes", Triangle: "triangles", ObjModel: "OBJ models" };
  list(r.explanations.filter((e) => e.cause || oneWay(e)), "What explains it, best first:", "explanations", (e) => {
    const how = e.psnr_db == null ? "exactly" : `at ${db(e.psnr_db)}, each pixel that differs within its ties`;
    // A one-coloured picture is what many renders are: an identical one is a lead, not its match.
    if (plain && e.psnr_db == null) return `${e.summary} renders it too, pixel for pixel: one way to get this picture. `;
    if (twins(e)) return `Your image matches ${e.summary}, ${how}: one way to get this picture, as is ${e.same_as.join(", and ")}: the picture alone cannot tell which is yours. `;
    if (shadowless(e)) return `${e.summary} gives your picture: one way to get it, as is every shadow of the ${kinds[e.shadowless] || e.shadowless} taken away any other way. `;
    if (lost(e)) return `${e.summary} gives your picture: one way to get it, as is losing the refracted light of ${e.loses_refraction.join(", ")} any other way. `;
    if (oneWay(e)) return `Your image matches ${e.summary}, ${how}: one way to get this picture, as is painting ${e.blackens.join(", ")} black. `;
    if (e.matches) return `Your image matches ${e.summary}, ${how}; rayscope's render is at ${db(r.psnr_db)}. `;
    return `${e.summary} accounts for the whole difference: its render reproduces ${e.explained.percent.toFixed(0)} % of the differing pixels (speckle on average over 4×4 blocks). `;
  });
  list(r.explanations.filter((e) => !e.cause && !oneWay(e)), "What explains a part of it:", "partial-explanations", (e) => `${e.summary} ${partText(e)}. `);
  if (r.next) diagnosisNext(box, r.next);
  box.append(el("p", { class: "dim" }, `${r.candidates} renders tried in ${(d.millis / 1000).toFixed(1)} s; \`rayscope mistakes\` lists the catalogue.`));
}
// The next step: the pixels to log, as the logging kits' variables, and the commands to run
// after. One button marks those pixels on the picture (with a ray log loaded, the verdict map and
// the list of logged pixels then show only them), another copies the variables.
function diagnosisNext(box, next) {
  const env = el("span", { id: "diagnosis-log-env" }, next.log_env);
  const pre = el("pre", { id: "diagnosis-next" }, env, ` <run your tracer>\n${next.check_command}\n${next.trace_command}`);
  const n = next.pixels.length;
  const show = el("button", {
    type: "button", id: "diagnosis-log-pixels", "data-pixels": next.pixels.map((p) => p.join(",")).join(" "),
    title: "Ring these pixels on the picture and trace the first; with your ray log loaded, the verdict map and the list of logged pixels show only them",
    onclick: () => raysChoose(next.pixels),
  }, `Show these ${n} pixel${n === 1 ? "" : "s"}`);
  const note = el("span", { id: "diagnosis-copy-note", class: "dim" });
  const copy = el("button", { type: "button", id: "diagnosis-copy-env", title: "Copy the variables to the clipboard", onclick: () => copyText(next.log_env, env, copy, note) }, "copy");
  box.append(el("p", {}, "To find out what your tracer does there, log its rays at these pixels (the logging kits: docs/check.md) and let rayscope judge them:"),
    el("div", { class: "next-actions" }, show, copy, note), pre);
}
// Copies `text` to the clipboard where the browser lets the page (a secure context), otherwise
// selects `node`, whose text it is, and asks the browser to copy the selection; `note` says
// which happened and `button.dataset.copied` records it: "clipboard", "copied" or "selected".
async function copyText(text, node, button, note) {
  let how = "selected";
  try {
    if (navigator.clipboard && navigator.clipboard.writeText) {
      await navigator.clipboard.writeText(text);
      how = "clipboard";
    }
  } catch (_) {
    how = "selected";
  }
  if (how === "selected") {
    const range = document.createRange();
    range.selectNodeContents(node);
    const sel = window.getSelection();
    sel.removeAllRanges();
    sel.addRange(range);
    try { if (document.execCommand("copy")) how = "copied"; } catch (_) { how = "selected"; }
  }
  button.dataset.copied = how;
  note.textContent = how === "selected" ? "selected: press Ctrl+C (⌘C) to copy" : "copied";
}
// Sets some settings as the inspector would.
async function applySettings(patch) {
  try {
    const r = await api("/api/settings", { method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(patch) });
    onNewSettings(r.settings, r.job);
  } catch (e) {
    compareSummary(e.message, "error", "error");
  }
}
// The three images of a comparison, fetched once each, so that flicker swaps them instantly.
async function compareLoadImages(v) {
  cmp.loading = v.heatmap;
  const blob = async (path) => URL.createObjectURL(await (await fetchRetry(path)).blob());
  try {
    const [rs, theirs, heat] = await Promise.all([
      blob(`/api/image.png?channel=color&job=${v.render_job}`),
      blob(`/api/rays/image.png?v=${rays.imageVersion}&job=${v.render_job}`),
      blob(v.heatmap),
    ]);
    // Kept while the comparison on screen is still the one they belong to (later answers of
    // the same comparison, while the diagnosis runs, do not replace it).
    if (!cmp.data || cmp.data.heatmap !== v.heatmap) { for (const u of [rs, theirs, heat]) URL.revokeObjectURL(u); return; }
    const old = cmp.urls;
    cmp.urls = { rs, theirs, heat, key: v.heatmap };
    compareShow();
    setTimeout(() => { for (const u of Object.values(old)) if (typeof u === "string" && u.startsWith("blob:")) URL.revokeObjectURL(u); }, 2000);
  } catch (e) {
    $("compare-result").textContent = `loading the images: ${e.message}`;
  } finally {
    if (cmp.loading === v.heatmap) cmp.loading = null;
  }
}
// Shows the image panel as the comparison mode says.
function compareShow() {
  const m = compareMode();
  const side = m === "side" && !!cmp.urls.theirs;
  $("cell-b").classList.toggle("hidden", !side);
  $("caption-a").classList.toggle("hidden", !side);
  $("compare-bars").classList.toggle("hidden", !cmp.loaded);
  $("heat-scale").classList.toggle("hidden", m !== "heat");
  $("compare-hint").classList.toggle("hidden", m === "heat" || m === "flicker");
  if (side !== cmp.sideShown) { cmp.sideShown = side; setupZoom(); }
  compareFlicker();
  loadImage();
}
function compareFlicker() {
  clearInterval(cmp.flickerTimer);
  cmp.flickerTimer = null;
  const on = compareMode() === "flicker";
  $("flicker-bar").classList.toggle("hidden", !on);
  if (!on) { cmp.showing = "rayscope"; return; }
  $("flicker-label").textContent = cmp.showing;
  if ($("flicker-auto").checked) cmp.flickerTimer = setInterval(flickerSwap, 700);
}
function flickerSwap() {
  if (compareMode() !== "flicker") return;
  cmp.showing = cmp.showing === "rayscope" ? "yours" : "rayscope";
  $("flicker-label").textContent = cmp.showing;
  loadImage();
}
// The hover readout: both values and the entity under the pixel, from the server (one request
// at a time; the latest pixel wins).
function compareHover(p) {
  if (!cmp.data) return;
  cmp.hover = p;
  if (cmp.hoverBusy) return;
  cmp.hoverBusy = true;
  const job = cmp.data.render_job;
  api(`/api/compare/pixel?x=${p[0]}&y=${p[1]}`)
    .then((r) => {
      const h = cmp.hover;
      if (h && h[0] === r.x && h[1] === r.y && cmp.data && cmp.data.render_job === job && r.render_job === job) compareReadout(r);
    })
    .catch(() => {})
    .finally(() => {
      cmp.hoverBusy = false;
      const h = cmp.hover;
      if (h && (h[0] !== p[0] || h[1] !== p[1])) compareHover(h);
    });
}
function compareReadout(r) {
  const f = (c) => `rgb(${c.join(", ")})`;
  const d = r.difference.map((v) => (v > 0 ? "+" : v < 0 ? "−" : "") + Math.abs(v)).join(", ");
  const what = r.entity == null ? "—" : r.seen_in.length ? `${r.entity}, seen in ${r.seen_in.join(" in ")}` : r.entity;
  const ro = $("pixel-readout");
  ro.textContent = `pixel (${r.x}, ${r.y}) · yours ${f(r.yours)} · rayscope ${f(r.rayscope)} · difference (${d}) · ${what}`;
  ro.title = ro.textContent;
  Object.assign(ro.dataset, { pixel: `${r.x},${r.y}`, yours: r.yours.join(","), rayscope: r.rayscope.join(","), entity: what });
}

// ---------- the student's ray log and image ----------
// The server judges the log with rayscope check's verdict engine once (again when the settings
// change); this section shows the verdict map, their image, and a pixel's two trees side by side.
const rays = {
  summary: null, file: null, mapJob: -1, mapCanvas: null, mapData: null,
  imageVersion: 0, imageKey: "", theirData: null, rsData: null, pollTimer: null, resending: false, pixelSeq: 0,
  chosen: null,                     // [[x, y], …]: the pixels a diagnosis says to log next, when shown
  only: null,                       // Set of "x,y" of those pixels: the verdict map and the list show only them
};
// Logs of at most this many pixels (and at most a quarter of the image) get a marker per pixel.
const MAX_MARKERS = 4096;
const RAYS_STATUS = { "46,204,113": "agrees", "241,196,15": "only ties", "255,38,38": "disagrees", "70,70,76": "not logged" };
function raysJudged() { return rays.summary && rays.summary.judged ? rays.summary.judged : null; }
function raysSizeMatches(w, h) { return st.settings && w === st.settings.width && h === st.settings.height; }
function raysSetupInput() {
  $("rays-only-clear").addEventListener("click", () => raysChoose(null));
  $("rays-file").addEventListener("change", () => { const f = $("rays-file").files[0]; if (f) raysUpload(f); $("rays-file").value = ""; });
  $("rays-image-file").addEventListener("change", () => { const f = $("rays-image-file").files[0]; if (f) theirImageUpload(f); $("rays-image-file").value = ""; });
  $("show-verdicts").addEventListener("change", () => { drawOverlay(); requestView(); });
  // Drag and drop anywhere on the page: a .png is their image, anything else their log.
  let depth = 0;
  const hint = (on) => $("drop-hint").classList.toggle("hidden", !on);
  document.addEventListener("dragenter", (e) => { if (e.dataTransfer && [...e.dataTransfer.types].includes("Files")) { depth++; hint(true); } });
  document.addEventListener("dragleave", () => { depth = Math.max(0, depth - 1); if (!depth) hint(false); });
  document.addEventListener("dragover", (e) => e.preventDefault());
  document.addEventListener("drop", (e) => {
    e.preventDefault(); depth = 0; hint(false);
    for (const f of e.dataTransfer.files) {
      if (/\.png$/i.test(f.name) || f.type === "image/png") theirImageUpload(f); else raysUpload(f);
    }
  });
}
function raysSummaryText(text, state, cls) {
  const box = $("rays-summary");
  box.textContent = text;
  box.dataset.state = state;
  box.className = cls || "dim";
}
async function raysUpload(file) {
  rays.file = file;
  showTab("rays-tab");
  raysSummaryText(`reading and judging ${file.name} (${(file.size / 1048576).toFixed(1)} MiB)…`, "judging");
  clearTimeout(rays.pollTimer);
  rays.pollTimer = setTimeout(raysPoll, 400);
  const type = /\.rays$/i.test(file.name) ? "application/octet-stream" : "application/x-ndjson";
  try {
    const s = await api(`/api/rays?name=${encodeURIComponent(file.name)}`, { method: "POST", headers: { "content-type": type }, body: file });
    raysOnSummary(s);
  } catch (e) {
    raysSummaryText(`${file.name}: ${e.message}`, "error", "error");
  }
}
async function raysPoll() {
  clearTimeout(rays.pollTimer);
  try {
    const s = await api("/api/rays/summary");
    raysOnSummary(s);
    if (s.state === "judging") rays.pollTimer = setTimeout(raysPoll, 300);
  } catch (e) {
    rays.pollTimer = setTimeout(raysPoll, 2000);
  }
}
function raysOnSettings() {
  // The server judges the log again under the new settings (or says it cannot: then send it).
  clearTimeout(rays.pollTimer);
  rays.pollTimer = setTimeout(raysPoll, 150);
}
function raysOnSummary(s) {
  rays.summary = s;
  const j = s.judged;
  const box = $("rays-summary");
  if ($("show-verdicts-label").classList.contains("hidden") === !!j) {
    $("show-verdicts-label").classList.toggle("hidden", !j);
    refitImage();
  }
  $("legend-yours").classList.toggle("hidden", !j);
  // Their image: compared with the render (see the comparison's section).
  if (s.image) {
    const key = `${s.image.name}:${s.image.width}x${s.image.height}:${s.image.matches}`;
    if (key !== rays.imageKey) { rays.imageKey = key; rays.imageVersion++; raysLoadTheirs(); comparePoll(); }
  }
  if (s.state === "none") { box.dataset.state = "none"; return; }
  if (s.state === "judging") {
    const p = s.progress || {};
    const pct = p.total ? ` ${(100 * p.done / p.total).toFixed(0)}%` : p.done ? ` ${(p.done / 1048576).toFixed(1)} MiB` : "";
    raysSummaryText(`judging ${s.name}…${pct}`, "judging");
    return;
  }
  if (s.state === "error") {
    raysSummaryText(`${s.source ? s.source.name + ": " : ""}${s.error}`, "error", "error");
    return;
  }
  if (!j) return;
  const px = j.pixels;
  const pct = (n) => (j.rays ? (100 * n / j.rays).toFixed(1) : "0");
  let text = `${j.name}: ${j.rays} rays, ${j.disagree} disagree (${pct(j.disagree)} %)` + (j.ties ? `, ${j.ties} genuine ties` : "") +
    ` — pixels: ${px.disagrees} disagree, ${px.agrees} agree` + (px.tie ? `, ${px.tie} only ties` : "") + `, ${px["not-logged"]} not logged` +
    ` — judged at ${j.width}×${j.height}` + (j.samples_per_pixel > 1 ? `, ${j.samples_per_pixel} samples per pixel` : "") + ` in ${j.millis.toFixed(0)} ms`;
  if (j.capped) text += ` — rays kept for display: ${j.kept} of ${j.kept + j.dropped} (the first ${j.detail_cap}, and samples that disagree up to twice that); pixels past the cap show their verdict only`;
  if (j.unplaced) text += ` — ${j.unplaced} rays name no pixel (judged, not on the map)`;
  if (j.skipped_lines) text += ` — ${j.skipped_lines} malformed lines skipped`;
  let cls = "";
  if (s.state === "stale") {
    const notKept = s.source && s.source.kind === "upload-not-kept";
    text = `STALE: judged under other settings (${j.settings.width}×${j.settings.height}, -x ${j.settings.aa}, stage ${j.settings.stage}); ` +
      (notKept ? (rays.file ? "sending the log again…" : "load the log again to judge it under these settings") : "judging again…") + " — " + text;
    cls = "warn";
    if (notKept && rays.file && !rays.resending) {
      rays.resending = true;
      raysUpload(rays.file).finally(() => { rays.resending = false; });
    } else if (!notKept) {
      clearTimeout(rays.pollTimer);
      rays.pollTimer = setTimeout(raysPoll, 300);
    }
  }
  raysSummaryText(text, s.state, cls);
  box.dataset.disagree = String(px.disagrees);
  box.dataset.job = String(j.job);
  const codes = $("rays-codes");
  codes.innerHTML = "";
  // One chip per root cause (what to fix), counted in pixel samples; the verdicts that follow
  // from a cause are in its tooltip, not chips of their own.
  if (j.causes.length) {
    codes.append(el("div", { class: "rays-headline" }, j.headline));
    // The first cause's entries in rayscope's catalogue of common mistakes, in its words.
    for (const m of j.causes[0].catalogue || []) {
      codes.append(el("div", { class: "rays-catalogue", title: m.looks },
        "rayscope's catalogue: ", el("b", {}, m.name), ` — ${m.wrong} (see it: rayscope -f SCENE -o out.png --mistake ${m.name})`));
    }
  }
  for (const c of j.causes) {
    const follows = (c.consequences ? `; ${c.consequences} verdicts below it follow from it` : "") +
      ((c.catalogue || []).length ? `; rayscope's catalogue: ${c.catalogue.map((m) => m.name).join(", ")}` : "");
    codes.append(el("span", { title: `${c.summary}${follows}` }, el("b", {}, c.name), ` × ${c.samples} sample${c.samples === 1 ? "" : "s"}`));
  }
  for (const v of j.tie_verdicts) codes.append(el("span", { title: v.summary + " (not counted against you)" }, v.code, ` × ${v.count}`));
  raysNext(s, j, codes);
  if (j.job !== rays.mapJob) {
    rays.mapJob = j.job;
    raysLoadMap(j);
    raysLoadRendered();
    if (st.pixel) raysPixel(); else requestView();
  }
}
// A log with no mistake that does not show the whole picture: the pixels to log next, as the
// logging kits' variables. The server works them out once the render and the student's image
// are there, so the summary is asked again until they are.
function raysNext(s, j, codes) {
  const nx = j.next;
  if (nx && nx.kind === "picture" && nx.next) {
    codes.append(el("div", { class: "rays-headline", id: "rays-next-headline" },
      `No mistake in your log, but your image differs from rayscope's render at ${nx.differing} pixel${nx.differing === 1 ? "" : "s"}, ` +
      `${nx.unlogged} of them not in your log: log some of those next (the logging kits read these variables; docs/check.md):`),
    el("pre", { id: "rays-next", class: "rays-next" }, `${nx.next.log_env} <run your tracer as before>\n${nx.next.check_command}`));
  } else if (nx && nx.kind === "sparse") {
    codes.append(el("div", { class: "dim", id: "rays-next-headline" },
      `Your log has ${nx.camera_rays} of the picture's ${nx.all} camera rays, so only those pixels were judged. ` +
      "Load your image (Compare) to find where it differs from rayscope's render, or log an even grid:"),
    el("pre", { id: "rays-next", class: "rays-next" }, `${nx.grid_env} <run your tracer as before>`));
  }
  const waiting = !nx && s.state === "done" && !j.disagree && s.image && s.image.matches;
  if (waiting && (rays.nextTries = (rays.nextTries || 0) + 1) <= 60) {
    clearTimeout(rays.pollTimer);
    rays.pollTimer = setTimeout(raysPoll, 1000);
  } else if (!waiting) {
    rays.nextTries = 0;
  }
}
function raysLoadMap(j) {
  const img = new Image();
  img.onload = () => {
    const c = document.createElement("canvas");
    c.width = img.naturalWidth; c.height = img.naturalHeight;
    const g = c.getContext("2d");
    g.drawImage(img, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height);
    rays.mapData = { width: c.width, height: c.height, data: new Uint8ClampedArray(d.data) };
    // A log of a few pixels: each logged pixel gets a marker, visible at any zoom.
    const logged = [];
    for (let i = 0; i < d.data.length && logged.length <= MAX_MARKERS; i += 4) {
      const s = RAYS_STATUS[`${d.data[i]},${d.data[i + 1]},${d.data[i + 2]}`];
      if (s && s !== "not logged") logged.push([(i / 4) % c.width, Math.floor(i / 4 / c.width), s]);
    }
    rays.logged = logged.length <= MAX_MARKERS && logged.length * 4 <= c.width * c.height ? logged : null;
    raysLoggedList();
    // The overlay: strong red where rays disagree, a light tint where they agree.
    for (let i = 0; i < d.data.length; i += 4) {
      const key = `${d.data[i]},${d.data[i + 1]},${d.data[i + 2]}`;
      const s = RAYS_STATUS[key];
      d.data[i + 3] = s === "disagrees" ? 175 : s === "only ties" ? 130 : s === "agrees" ? 60 : 0;
    }
    g.putImageData(d, 0, 0);
    rays.mapCanvas = c;
    drawOverlay();
    requestView();
  };
  img.src = j.map;
}
function raysImageData(src, done) {
  const img = new Image();
  img.onload = () => {
    const c = document.createElement("canvas");
    c.width = img.naturalWidth; c.height = img.naturalHeight;
    const g = c.getContext("2d");
    g.drawImage(img, 0, 0);
    done(g.getImageData(0, 0, c.width, c.height));
  };
  img.src = src;
}
function raysLoadTheirs() {
  raysImageData(`/api/rays/image.png?v=${rays.imageVersion}`, (d) => { rays.theirData = d; });
  raysLoadRendered();
  requestView();
}
function raysLoadRendered() {
  if (!raysJudged() && !(rays.summary && rays.summary.image)) return;
  if (st.renderedJob < 0) return;
  raysImageData(`/api/image.png?channel=color&job=${st.renderedJob}`, (d) => { rays.rsData = d; });
}
// Chooses the pixels a diagnosis says to log next (`null`: none): they are ringed on the picture,
// the first is selected so that its ray tree shows, and the verdict map and the list of logged
// pixels show only them until "show all".
function raysChoose(pixels) {
  if (!pixels && !rays.chosen) return;
  rays.chosen = pixels && pixels.length ? pixels.map(([x, y]) => [x, y]) : null;
  rays.only = rays.chosen ? new Set(rays.chosen.map(([x, y]) => `${x},${y}`)) : null;
  const bar = $("rays-only");
  if (rays.chosen) {
    const n = rays.chosen.length;
    $("rays-only-count").textContent = `${n} chosen pixel${n === 1 ? "" : "s"}`;
  }
  if (bar.classList.contains("hidden") === !!rays.chosen) {
    bar.classList.toggle("hidden", !rays.chosen);
    refitImage();
  }
  raysLoggedList();
  if (rays.chosen) selectPixel(rays.chosen[0][0], rays.chosen[0][1]);
  else drawOverlay();
}
// Whether the pixel is shown while some pixels are chosen (all are when none is).
const raysShown = (x, y) => !rays.only || rays.only.has(`${x},${y}`);
// The logged pixels of a sparse log, those that disagree first, filtered by verdict and to the
// chosen pixels; a row selects its pixel.
function raysLoggedList() {
  const box = $("rays-logged");
  box.classList.toggle("hidden", !rays.logged);
  if (!rays.logged) return;
  const want = $("rays-logged-filter").value;
  const rank = { disagrees: 0, "only ties": 1, agrees: 2 };
  const rows = rays.logged
    .filter((p) => (!want || p[2] === want) && raysShown(p[0], p[1]))
    .sort((a, b) => rank[a[2]] - rank[b[2]] || a[1] - b[1] || a[0] - b[0]);
  const tb = $("rays-logged-list").querySelector("tbody");
  tb.innerHTML = "";
  for (const [x, y, s] of rows) {
    const tr = el("tr", { class: `logged-${s.replace(" ", "-")}` }, el("td", {}, `(${x}, ${y})`), el("td", {}, s));
    tr.addEventListener("click", () => selectPixel(x, y));
    tb.append(tr);
  }
  box.dataset.rows = String(rows.length);
}

function raysDrawOverlay(g, z) {
  raysDrawVerdicts(g, z);
  raysDrawChosen(g, z);
}
// The verdict map over the image (only the chosen pixels' verdicts while some are chosen), with
// `data-verdicts` the number of pixels shown red.
function raysDrawVerdicts(g, z) {
  const ov = $("image-overlay");
  const j = raysJudged();
  if (!j || !rays.mapCanvas || !$("show-verdicts").checked || !raysSizeMatches(rays.mapCanvas.width, rays.mapCanvas.height)) { delete ov.dataset.verdicts; return; }
  g.imageSmoothingEnabled = false;
  if (rays.chosen) {
    const m = rays.mapData;
    let red = 0;
    for (const [x, y] of rays.chosen) {
      if (x >= m.width || y >= m.height) continue;
      g.drawImage(rays.mapCanvas, x, y, 1, 1, x * z, y * z, z, z);
      const i = (y * m.width + x) * 4;
      if (RAYS_STATUS[`${m.data[i]},${m.data[i + 1]},${m.data[i + 2]}`] === "disagrees") red++;
    }
    ov.dataset.verdicts = String(red);
  } else {
    g.drawImage(rays.mapCanvas, 0, 0, rays.mapCanvas.width * z, rays.mapCanvas.height * z);
    ov.dataset.verdicts = `${j.pixels.disagrees}`;
  }
  // Rings of a fixed screen size around the logged pixels of a sparse log: at a zoom below one
  // screen pixel per image pixel, the map alone would lose them.
  const marks = (rays.logged || []).filter(([x, y]) => raysShown(x, y));
  const colour = { disagrees: "#ff2626", "only ties": "#f1c40f", agrees: "#2ecc71" };
  g.lineWidth = 2;
  for (const [x, y, s] of marks) {
    g.strokeStyle = colour[s] || "#ffffff";
    g.beginPath();
    g.arc((x + 0.5) * z, (y + 0.5) * z, Math.max(4, 0.7 * z), 0, 2 * Math.PI);
    g.stroke();
  }
  ov.dataset.markers = String(marks.length);
}
// The chosen pixels' rings: larger than the logged pixels' and of a colour of their own, over a
// dark ring so that they show on any picture; `data-chosen` counts them.
const CHOSEN_COLOUR = "#c77dff";
function raysDrawChosen(g, z) {
  const ov = $("image-overlay");
  const s = st.settings;
  const marks = (rays.chosen || []).filter(([x, y]) => s && x < s.width && y < s.height);
  if (!marks.length) { delete ov.dataset.chosen; return; }
  const r = Math.max(7, 1.1 * z);
  for (const [colour, width] of [["rgba(0,0,0,0.7)", 4.5], [CHOSEN_COLOUR, 2]]) {
    g.strokeStyle = colour;
    g.lineWidth = width;
    for (const [x, y] of marks) {
      g.beginPath();
      g.arc((x + 0.5) * z, (y + 0.5) * z, r, 0, 2 * Math.PI);
      g.stroke();
    }
  }
  ov.dataset.chosen = String(marks.length);
}
function raysRgbAt(d, p) {
  if (!d || !raysSizeMatches(d.width, d.height)) return null;
  const i = (p[1] * d.width + p[0]) * 4;
  return [d.data[i], d.data[i + 1], d.data[i + 2]];
}
function raysReadout(p) {
  if (!raysJudged() && !(rays.summary && rays.summary.image)) return "";
  const f = (c) => (c ? `rgb(${c.join(", ")})` : "—");
  let s = `pixel (${p[0]}, ${p[1]}) · rayscope ${f(raysRgbAt(rays.rsData, p))}`;
  if (rays.summary && rays.summary.image) {
    const t = raysRgbAt(rays.theirData, p), r = raysRgbAt(rays.rsData, p);
    s += ` · yours ${f(t)}`;
    if (t && r) s += ` (Δ ${t.map((v, i) => v - r[i]).map((v) => (v > 0 ? "+" : "") + v).join(", ")})`;
  }
  const m = rays.mapData && raysSizeMatches(rays.mapData.width, rays.mapData.height) ? rays.mapData : null;
  if (m) {
    const i = (p[1] * m.width + p[0]) * 4;
    s += ` · rays: ${RAYS_STATUS[`${m.data[i]},${m.data[i + 1]},${m.data[i + 2]}`] || "?"}`;
  }
  return s;
}
function raysViewParams(p) {
  $("view").dataset.student = raysJudged() && st.pixel ? "1" : "0";
  if (raysJudged()) {
    p.set("student", "1");
    if ($("show-verdicts").checked) p.set("verdicts", "1");
  }
}
const rvec = (a) => (a ? "(" + a.map((x) => fmt(x, 4)).join(", ") + ")" : "—");
async function raysPixel() {
  const j = raysJudged();
  if (!j || !st.pixel) return;
  const [x, y] = st.pixel;
  if (x >= j.width || y >= j.height) return;
  const seq = ++rays.pixelSeq;
  showTab("rays-tab");
  try {
    const q = new URLSearchParams({ x, y });
    if (rays.pixelSample != null) q.set("sample", rays.pixelSample);
    if (rays.pixelOffset) q.set("offset", rays.pixelOffset);
    rays.pixelSample = null;
    rays.pixelOffset = 0;
    const r = await api("/api/rays/pixel?" + q);
    if (seq !== rays.pixelSeq) return;
    // The view and the ray tree follow the sample shown (the first one that disagrees).
    if (r.sample != null && r.sample !== st.sample && r.sample < r.samples_per_pixel) {
      st.sample = r.sample;
      tracePixel().then(() => showTab("rays-tab"));
    }
    requestView();
    raysShowPixel(r);
  } catch (e) {
    $("rays-pixel-head").textContent = e.message;
  }
}
function raysShowPixel(r) {
  const head = $("rays-pixel-head");
  head.innerHTML = "";
  const status = { "agrees": "agrees", "tie": "only genuine ties", "disagrees": "disagrees", "not-logged": "not in your log" }[r.status] || r.status;
  head.append(`pixel (${r.x}, ${r.y}): ${status}` + (r.code ? ` (${r.code})` : ""));
  if (r.samples.length > 1) {
    const sel = el("select", { id: "rays-sample" });
    for (const s of r.samples) sel.append(el("option", { value: s == null ? "" : s }, s == null ? "rays without a sample" : `sample ${s}`));
    sel.value = r.sample == null ? "" : String(r.sample);
    sel.addEventListener("change", () => { rays.pixelSample = sel.value === "" ? null : Number(sel.value); raysPixel(); });
    head.append(" ", sel);
  } else if (r.sample != null) head.append(`, sample ${r.sample}`);
  if (r.their_rgb8) head.append(` — yours rgb(${r.their_rgb8.join(", ")}), rayscope ${r.rayscope_rgb8 ? `rgb(${r.rayscope_rgb8.join(", ")})` : "—"}`);
  if (r.stale) head.append(el("span", { class: "warn" }, " — judged under other settings"));
  if (r.dropped) head.append(el("span", { class: "warn" }, " — some of this pixel's rays were not kept (the display cap): its verdict stands, the table shows the rays kept"));
  if (r.status === "not-logged") head.append(" — your log has no ray for this pixel");
  if (r.samples_total > r.samples.length) head.append(` — the list shows ${r.samples.length} of its ${r.samples_total} samples`);
  if (r.offset > 0 || r.more > 0) {
    // One page of the sample's rays: the rest are asked for a page at a time.
    const page = (offset) => () => { rays.pixelSample = r.sample; rays.pixelOffset = offset; raysPixel(); };
    const more = r.more > 0 ? `, and ${r.more} more` : "";
    const note = el("span", { class: "warn", id: "rays-page" }, ` — rays ${r.offset + 1} to ${r.offset + r.yours.length} of ${r.rays_total} in this sample${more} `);
    if (r.offset > 0) note.append(el("button", { type: "button", onclick: page(Math.max(0, r.offset - r.page_rays)) }, "previous"));
    if (r.more > 0) note.append(el("button", { type: "button", onclick: page(r.offset + r.yours.length) }, "next"));
    head.append(note);
  }
  // The first divergence, explained.
  const dv = $("rays-divergence");
  dv.innerHTML = "";
  if (r.divergence) {
    const d = r.divergence;
    const box = el("div", { class: "divergence", id: "rays-divergence-box", "data-code": d.code || "" },
      el("b", {}, "Where the trees part: "), d.code ? el("span", { class: "code" }, d.code) : "(shape only)", d.code ? " — " : " ", d.summary,
      el("p", {}, d.detail), el("p", { class: "dim" }, d.explanation));
    if (d.values.length) {
      const t = el("table", {}, el("thead", {}, el("tr", {}, el("th", {}, ""), el("th", {}, "yours"), el("th", {}, "rayscope"))));
      const tb = el("tbody");
      const show = (v) => (Array.isArray(v) ? rvec(v) : v === null ? "—" : String(v));
      for (const v of d.values) tb.append(el("tr", {}, el("td", {}, v.what), el("td", {}, show(v.yours)), el("td", {}, show(v.rayscope))));
      t.append(tb); box.append(t);
    }
    dv.append(box);
  } else if (r.yours.length) {
    dv.append(el("div", { class: "dim", id: "rays-divergence-box", "data-code": "" }, "Your rays of this sample agree with rayscope's, ray for ray."));
  }
  // The two trees, row by row.
  const tb = $("rays-table").querySelector("tbody");
  tb.innerHTML = "";
  // One space a level, at most six: deep glass paths must not push the answers off the panel.
  const indent = (d) => "\u00a0".repeat(Math.min(d, 6));
  // Each aligned pair stacked, yours above rayscope's, so the panel never needs to scroll sideways.
  r.alignment.rows.forEach((row, k) => {
    const y = row.yours != null ? r.yours[row.yours] : null;
    const n = row.rayscope != null ? r.rayscope.nodes[row.rayscope] : null;
    const verdict = y ? (y.findings.filter((f) => !f.code.startsWith("tie.")).map((f) => f.code).join(", ") || (y.findings.length ? y.findings.map((f) => f.code).join(", ") : "✓")) : "";
    const vcls = !y ? "" : row.verdict === "disagrees" ? "bad" : row.verdict === "tie" ? "tie" : "ok";
    const cls = (k === r.alignment.divergence ? "diverge " : "") + (row.shape !== "both" ? "only" : "");
    const answer = (text, dir, empty) => el("td", { class: "answer" + (empty ? " empty" : "") }, text,
      ...(dir ? [el("br"), el("span", { class: "dim" }, `direction ${rvec(dir)}`)] : []));
    tb.append(
      el("tr", { class: `${cls} yours` },
        el("td", { class: "who" }, y ? `line ${y.line}` : "yours"),
        el("td", { class: "k", style: y ? `color:${KIND_COLORS[y.kind] || "#ccc"}` : "" }, y ? indent(row.depth) + y.kind : "—"),
        answer(y ? y.answer : "not in your log", y && y.direction, !y),
        el("td", { class: `verdict ${vcls}`, title: y ? y.findings.map((f) => `${f.code}: ${f.detail}`).join("\n") : "" }, verdict)),
      el("tr", { class: `${cls} theirs` },
        el("td", { class: "who" }, "rayscope"),
        el("td", { class: "k", style: n ? `color:${KIND_COLORS[n.kind] || "#ccc"}` : "" }, n ? indent(row.depth) + n.kind : "—"),
        answer(n ? r.rayscope_answers[n.id] : "rayscope casts none", n && n.direction, !n),
        el("td", {}, "")),
    );
  });
  // The divergent row in view, scrolling the table only (not the page).
  const dr = tb.querySelector("tr.diverge");
  const wrap = tb.closest(".table-wrap");
  if (dr && wrap) wrap.scrollTop = Math.max(0, dr.offsetTop - wrap.clientHeight / 2);
}

function showTab(id) {
  for (const t of document.querySelectorAll(".tab")) t.classList.toggle("active", t.dataset.tab === id);
  for (const b of document.querySelectorAll(".tab-body")) b.classList.toggle("hidden", b.id !== id);
}

// ---------- start ----------
async function main() {
  try {
    const s = await api("/api/scene");
    st.scene = s;
    $("scene-name").textContent = s.path;
    $("scene-name").title = (s.warnings || []).join("\n");
    st.defaultView = s.view;
    st.orbit = orbitFrom(s.view.eye, s.view.target, s.view.fov);
    buildHierarchy();
    st.settings = s.settings;
    setupZoom();
    select({ type: "camera" });
    setupViewInput();
    setupImageInput();
    for (const id of ["rays", "image-mode", "show-tree", "show-samples", "cutaway", "xray"]) $(id).addEventListener("change", () => requestView());
    $("reset-view").addEventListener("click", () => { st.orbit = orbitFrom(st.defaultView.eye, st.defaultView.target, st.defaultView.fov); requestView(); });
    for (const t of document.querySelectorAll(".tab")) t.addEventListener("click", () => showTab(t.dataset.tab));
    // rayscope's own intersector self-test (its BVH against parry3d) checks rayscope, not the
    // student's code: it is offered only on a page opened with ?selftest=1.
    const selfTest = new URLSearchParams(location.search).has("selftest");
    for (const id of ["check-btn", "check-tab-btn"]) $(id).classList.toggle("hidden", !selfTest);
    document.body.dataset.ready = "1";
    pollStatus();
    raysPoll();
  } catch (e) {
    $("status-text").textContent = "cannot load the scene: " + e.message;
  }
}
main();
