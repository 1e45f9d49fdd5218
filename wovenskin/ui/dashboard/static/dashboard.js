// The wovenskin dashboard page: one WebSocket, a virtual skin, a three.js arm, controls.
// The server sends {"type": "scene"} once and {"type": "state"} at the page rate; the page
// sends touches and commands. Nothing here decides a command: touches go to the simulated
// skin's physics on the server and through the same recogniser and safety layer as a real skin.
import * as THREE from "./vendor/three.min.js";
import { makeTaskView, setupStudy } from "./study.js";
import { setupAdapt } from "./adapt.js";

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);
const token = params.get("token");

const page = {
  scene: null, state: null, socket: null, received: 0, receivedAt: [], errors: [],
  releasedAt: null, releaseMs: [], // a release with a command on (ms), -> the state without
  sent: 0, connected: false,
};
window.wovenskin = page; // for tests and the browser console

// ------------------------------------------------------------------ socket
function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const url = `${scheme}://${location.host}/ws${token ? `?token=${encodeURIComponent(token)}` : ""}`;
  const ws = new WebSocket(url);
  page.socket = ws;
  ws.onopen = () => {
    page.connected = true;
    document.body.classList.remove("offline");
    setPill($("link"), "live", "ok");
  };
  ws.onclose = () => {
    page.connected = false;
    // Nothing on the page is live any more: the figures grey out and the rates and the
    // safety state say they are unknown, until the server is back.
    document.body.classList.add("offline");
    $("rates").textContent = "";
    setPill($("safety"), "unknown", "bad");
    setPill($("link"), "disconnected: retrying", "bad");
    setTimeout(connect, 1000);
  };
  ws.onmessage = (event) => {
    const message = JSON.parse(event.data);
    if (message.type === "scene") onScene(message);
    else if (message.type === "state") onState(message);
    else if (message.type === "error") { page.errors.push(message.message); addLocalMessage(`error: ${message.message}`); }
  };
}

function send(message) {
  if (page.socket && page.socket.readyState === WebSocket.OPEN) {
    page.socket.send(JSON.stringify(message));
    page.sent += 1;
  }
}
const command = (cmd, extra = {}) => send({ type: "command", cmd, ...extra });

function setPill(el, text, kind) { el.textContent = text; el.className = `pill ${kind}`; }

const localMessages = [];
function addLocalMessage(text) { localMessages.push(text); if (localMessages.length > 5) localMessages.shift(); }

// ------------------------------------------------------------------ scene and state
function onScene(message) {
  page.scene = message;
  $("sources").textContent = `skin ${message.skin} · robot ${message.robot}`;
  $("skin-spec").value = message.skin;
  $("robot-spec").value = message.robot;
  const choices = $("skin-choices");
  for (const port of message.ports || []) {
    if (![...choices.options].some((o) => o.value === `serial:${port}`)) {
      const option = document.createElement("option");
      option.value = `serial:${port}`;
      choices.appendChild(option);
    }
  }
  buildPerformButtons(message.gestures);
  buildBars(message.classes);
  arm.build(message.scene, message.workspace);
  taskView.build(message.task);
  study.onScene(message);
}

function onState(state) {
  page.state = state;
  page.received += 1;
  const now = performance.now();
  page.receivedAt.push(now);
  while (page.receivedAt.length && now - page.receivedAt[0] > 2000) page.receivedAt.shift();
  if (page.releasedAt !== null && !state.recognition?.command) { // the release's effect, seen
    page.releaseMs.push(now - page.releasedAt);
    if (page.releaseMs.length > 50) page.releaseMs.shift();
    page.releasedAt = null;
  }
  updateHeader(state);
  updateSkin(state.skin);
  updateRecognition(state);
  updateControls(state);
  arm.update(state.robot);
  taskView.update(state.task);
  study.update(state);
  adapt.update(state);
  drawTimeline(state);
  updateMessages(state.messages);
}

// Arrivals per second over the stamps (ms); null until two arrived apart in time (two
// states handled in the same millisecond would otherwise give Infinity).
function ratePerSecond(stamps) {
  if (stamps.length < 2) return null;
  const span = (stamps[stamps.length - 1] - stamps[0]) / 1000;
  return span > 0 ? (stamps.length - 1) / span : null;
}

function median(values) {
  if (!values.length) return null;
  const sorted = [...values].sort((a, b) => a - b);
  const mid = sorted.length >> 1;
  return sorted.length % 2 ? sorted[mid] : (sorted[mid - 1] + sorted[mid]) / 2;
}

function pageRate() {
  const rate = ratePerSecond(page.receivedAt);
  return rate === null ? "-" : rate.toFixed(0);
}

function updateHeader(state) {
  const r = state.rates || {};
  const release = median(page.releaseMs.slice(-10));
  $("rates").textContent = `control ${r.control_hz ?? "-"} Hz · page ${pageRate()} Hz`
    + (release === null ? "" : ` · release to stop ${release.toFixed(0)} ms`);
  const s = state.safety;
  if (s.user_stopped) setPill($("safety"), "STOPPED (resume to move)", "bad");
  else if (s.stopped) setPill($("safety"), `stopped: ${s.stops.length ? s.stops[s.stops.length - 1].reason : ""}`, "warn");
  else setPill($("safety"), "running", "ok");
  $("resume").style.display = s.stopped ? "" : "none";
}

// ------------------------------------------------------------------ the skin
const skinCanvas = $("skin");
const skinCtx = skinCanvas.getContext("2d");
const skinTexture = document.createElement("canvas"); // the heatmap alone, for the 3D patch
skinTexture.width = 10; skinTexture.height = 10; // resized (with a new GPU texture) per layout
const skinTextureCtx = skinTexture.getContext("2d");
let layout = { rows: 10, cols: 10, row_pitch_mm: 14, col_pitch_mm: 10 };

const MIN_SCALE = 0.01; // the heatmap's least full scale: 1 % relative change
let shownScale = MIN_SCALE;
function colour(v) { // 0..1 -> a perceptual dark-to-bright ramp (inferno-like)
  const x = Math.max(0, Math.min(1, v));
  const stops = [[0, 0, 4], [40, 11, 84], [101, 21, 110], [159, 42, 99], [212, 72, 66],
    [245, 125, 21], [250, 193, 39], [252, 255, 164]];
  const f = x * (stops.length - 1), i = Math.min(stops.length - 2, Math.floor(f)), t = f - i;
  const a = stops[i], b = stops[i + 1];
  return `rgb(${a.map((c, k) => Math.round(c + (b[k] - c) * t)).join(",")})`;
}

function sizeSkinCanvas() {
  const widthMm = layout.cols * layout.col_pitch_mm, heightMm = layout.rows * layout.row_pitch_mm;
  const cssWidth = skinCanvas.clientWidth || 280;
  skinCanvas.style.height = `${(cssWidth * heightMm) / widthMm}px`;
  const dpr = window.devicePixelRatio || 1;
  skinCanvas.width = Math.round(cssWidth * dpr);
  skinCanvas.height = Math.round(((cssWidth * heightMm) / widthMm) * dpr);
}

function updateSkin(skin) {
  if (skin.rows !== layout.rows || skin.cols !== layout.cols ||
      skin.row_pitch_mm !== layout.row_pitch_mm || skin.col_pitch_mm !== layout.col_pitch_mm) {
    layout = { rows: skin.rows, cols: skin.cols, row_pitch_mm: skin.row_pitch_mm, col_pitch_mm: skin.col_pitch_mm };
    sizeSkinCanvas();
  }
  const { rows, cols } = skin;
  const W = skinCanvas.width, H = skinCanvas.height, cw = W / cols, ch = H / rows;
  if (skinTexture.width !== cols || skinTexture.height !== rows) {
    skinTexture.width = cols; skinTexture.height = rows;
    arm.resizeTexture();
  }
  // The brightest colour follows the touch: the frame's peak (decaying over about a second),
  // never above the full scale nor below MIN_SCALE, so a light touch on a weak skin is as
  // bright as a firm one on a strong skin, and noise alone stays dark.
  const peak = Math.max(0, ...skin.signal);
  shownScale = Math.min(skin.full_scale, Math.max(MIN_SCALE, peak, shownScale * 0.97));
  for (let r = 0; r < rows; r++) {
    for (let c = 0; c < cols; c++) {
      const v = Math.sqrt(Math.max(0, skin.signal[r * cols + c]) / shownScale); // gamma: light touches show
      skinCtx.fillStyle = colour(v);
      skinCtx.fillRect(c * cw, r * ch, cw + 0.5, ch + 0.5);
      skinTextureCtx.fillStyle = colour(v);
      skinTextureCtx.fillRect(c, r, 1, 1);
    }
  }
  skinCtx.strokeStyle = "rgba(255,255,255,0.06)";
  for (let c = 1; c < cols; c++) { skinCtx.beginPath(); skinCtx.moveTo(c * cw, 0); skinCtx.lineTo(c * cw, H); skinCtx.stroke(); }
  for (let r = 1; r < rows; r++) { skinCtx.beginPath(); skinCtx.moveTo(0, r * ch); skinCtx.lineTo(W, r * ch); skinCtx.stroke(); }
  for (const c of skin.contacts) { // centroids in channel units, channel centres at integers
    const x = (c.col + 0.5) * cw, y = (c.row + 0.5) * ch;
    const radius = Math.max(4, Math.sqrt(c.size) * Math.min(cw, ch) * 0.55);
    skinCtx.strokeStyle = "#7ee0ff"; skinCtx.lineWidth = 2 * (window.devicePixelRatio || 1);
    skinCtx.beginPath(); skinCtx.arc(x, y, radius, 0, 2 * Math.PI); skinCtx.stroke();
    skinCtx.fillStyle = "#7ee0ff"; skinCtx.beginPath(); skinCtx.arc(x, y, 3, 0, 2 * Math.PI); skinCtx.fill();
  }
  drawTracks(skin.tracks || [], cw, ch);
  const mm = mmToCanvas();
  for (const tip of touchList()) { // where the virtual fingertips are
    skinCtx.strokeStyle = "rgba(255,255,255,0.8)"; skinCtx.lineWidth = 1.5;
    skinCtx.beginPath(); skinCtx.arc(tip.x_mm * mm.x, tip.y_mm * mm.y, 6 * mm.x, 0, 2 * Math.PI); skinCtx.stroke();
  }
  if (hover && pointers.size === 0 && Number($("fingers").value) > 1) { // the hand, before it lands
    skinCtx.setLineDash([3, 3]); skinCtx.strokeStyle = "rgba(255,255,255,0.45)"; skinCtx.lineWidth = 1;
    for (const tip of handTips(0, hover, 0, handSpread())) {
      skinCtx.beginPath(); skinCtx.arc(tip.x_mm * mm.x, tip.y_mm * mm.y, 6 * mm.x, 0, 2 * Math.PI); skinCtx.stroke();
    }
    skinCtx.setLineDash([]);
  }
  if (skin.calibrating) {
    skinCtx.fillStyle = "rgba(0,0,0,0.55)"; skinCtx.fillRect(0, 0, W, H);
    skinCtx.fillStyle = "#fff"; skinCtx.font = `${14 * (window.devicePixelRatio || 1)}px system-ui`;
    skinCtx.fillText("calibrating: hands off", 10, H / 2);
  }
  const k = skin.counters;
  $("skin-status").textContent = `${skin.fps.toFixed(0)} fps${skin.stalled ? " · STALLED" : ""}${skin.virtual ? "" : " · drawing off (not simulated)"}${slowMotion(page.state)}`;
  $("skin-counters").textContent = `frames ${k.good} · bad ${k.bad} · dropped ${k.dropped} · reconnects ${k.reconnects} · errors ${k.session_errors}` +
    (skin.last_error ? `\nlast: ${skin.last_error}` : "");
}

// The recogniser's contact tracks: where each will be in TRACK_ARROW_S at its velocity.
const TRACK_ARROW_S = 0.15;

function trackMarks(tracks, cw, ch) { // canvas geometry of each track (channel units in)
  return tracks.map((t) => {
    const x = (t.col + 0.5) * cw, y = (t.row + 0.5) * ch;
    return { id: t.id, merged: t.merged, x, y,
      toX: x + t.v_col * TRACK_ARROW_S * cw, toY: y + t.v_row * TRACK_ARROW_S * ch,
      label: t.merged ? `${t.id} merged` : String(t.id) };
  });
}

function drawTracks(tracks, cw, ch) { // a marker per track, its id and a velocity arrow
  const dpr = window.devicePixelRatio || 1;
  skinCtx.font = `${11 * dpr}px system-ui`; skinCtx.lineWidth = 1.5 * dpr;
  for (const m of trackMarks(tracks, cw, ch)) {
    const colour = m.merged ? "#ffb347" : "#b6f36b"; // merged: sharing another's peak
    skinCtx.strokeStyle = colour; skinCtx.fillStyle = colour;
    skinCtx.setLineDash(m.merged ? [3 * dpr, 3 * dpr] : []);
    skinCtx.beginPath(); skinCtx.rect(m.x - 5 * dpr, m.y - 5 * dpr, 10 * dpr, 10 * dpr); skinCtx.stroke();
    skinCtx.setLineDash([]);
    const dx = m.toX - m.x, dy = m.toY - m.y, length = Math.hypot(dx, dy);
    if (length > 3 * dpr) { // still fingers get no arrow
      const ux = dx / length, uy = dy / length, head = 5 * dpr;
      skinCtx.beginPath(); skinCtx.moveTo(m.x, m.y); skinCtx.lineTo(m.toX, m.toY);
      skinCtx.lineTo(m.toX - head * (ux - 0.5 * uy), m.toY - head * (uy + 0.5 * ux));
      skinCtx.moveTo(m.toX, m.toY);
      skinCtx.lineTo(m.toX - head * (ux + 0.5 * uy), m.toY - head * (uy - 0.5 * ux));
      skinCtx.stroke();
    }
    skinCtx.fillText(m.label, m.x + 7 * dpr, m.y - 7 * dpr);
  }
}

// When this computer cannot keep the session in real time, the simulated skin slows the
// simulated world rather than hand the session seconds-old touches (sim/live.py): say so.
let slowSeen = null; // [page ms, slowed s] a second ago
function slowMotion(state) {
  const slowed = state.sim_slowed_s;
  if (slowed === null || slowed === undefined) return "";
  const now = performance.now();
  if (slowSeen === null || now - slowSeen[0] > 2000) slowSeen = [now, slowed, 0];
  else if (now - slowSeen[0] > 1000) slowSeen = [now, slowed, (slowed - slowSeen[1]) / ((now - slowSeen[0]) / 1000)];
  const lost = slowSeen[2] || 0; // wall seconds held back per second
  page.simSpeed = Math.max(0, 1 - lost);
  return lost > 0.05 ? ` · slow motion: ${Math.round(100 * (1 - lost))}% of real time (this computer is busy)` : "";
}

function mmToCanvas() {
  return { x: skinCanvas.width / (layout.cols * layout.col_pitch_mm), y: skinCanvas.height / (layout.rows * layout.row_pitch_mm) };
}

// ------------------------------------------------------------------ virtual touches
const pointers = new Map(); // pointerId -> {x_mm, y_mm, pressure, mouse}
// A mouse "hand" of 2 or 5 fingertips: its spread (mm: the gap of 2, the radius of 5) is
// set with the wheel while hovering (shown as ghost fingertips) and changed with the wheel
// while pressing (a pinch). Each press starts from the hover spread.
let hoverSpread = null; // null: the finger count's default
let spread = null; // while pressing
let hover = null; // {x_mm, y_mm} of a mouse over the skin, not pressing
const SPREAD = { 2: [10, 80, 18], 5: [5, 45, 30] }; // min, max, default (2: gap, 5: radius)

function pointerMm(event) {
  const rect = skinCanvas.getBoundingClientRect();
  return {
    x_mm: ((event.clientX - rect.left) / rect.width) * layout.cols * layout.col_pitch_mm,
    y_mm: ((event.clientY - rect.top) / rect.height) * layout.rows * layout.row_pitch_mm,
  };
}

function pressureOf(event, current) { // the device's pressure where it reports one; a mouse
  // keeps its own (the slider's, raised by the wheel or Shift while pressing: see pressMouse)
  const fromDevice = event.pointerType !== "mouse" && event.pressure > 0 && event.pressure !== 0.5;
  if (fromDevice) return event.pressure;
  return current ?? Number($("pressure").value);
}

// A mouse cannot press harder by itself: while it presses, Shift (any hand) or the wheel
// rolled up (one finger) presses firmly, ramping at PRESS_RATE (from the slider's 0.35 to a
// firm 1.4 in ~0.26 s: how people perform `push`). Releasing Shift, or the wheel rolled
// down, eases back to the slider's pressure. The ramp is a function of the page's clock:
// when a busy page ticks late, the ticks it missed are filled in at RAMP_STEP_MS spacing, so
// the server receives the ramp people make, not the page's hiccups.
const PRESS_RATE = 4; // pressure units per second
const PRESS_MAX = 1.4; // a firm press: 4.1 N, beyond the slider's 1 (3 N), as people push
const RAMP_STEP_MS = 10;
let pressTarget = null; // null: the slider's pressure
let shiftPressing = false;
function mousePointer() { for (const p of pointers.values()) if (p.mouse) return p; return null; }
function pressMouse(target) { pressTarget = target === null ? null : Math.max(0.05, Math.min(PRESS_MAX, target)); }
let pressTick = null; // the page time (ms) up to which the ramp has been sent
setInterval(() => { // ramp a pressing mouse's pressure toward its target, on the page's clock
  const p = mousePointer();
  const now = performance.now();
  const last = pressTick;
  pressTick = now;
  if (!p || last === null) return;
  const target = shiftPressing ? PRESS_MAX : (pressTarget ?? Number($("pressure").value));
  if (Math.abs(p.pressure - target) < 1e-3) return;
  const samples = [];
  for (let t = Math.min(now, last + RAMP_STEP_MS); ; t = Math.min(now, t + RAMP_STEP_MS)) {
    const step = PRESS_RATE * RAMP_STEP_MS / 1000;
    p.pressure = p.pressure + Math.max(-step, Math.min(step, target - p.pressure));
    page.pressSamples = [...(page.pressSamples || []).slice(-80), [Math.round(t), Number(p.pressure.toFixed(2))]];
    samples.push({ t: t / 1000, touches: touchList() });
    if (t >= now || Math.abs(p.pressure - target) < 1e-3) break;
  }
  page.mousePressure = p.pressure;
  sendTouches(samples.slice(-64));
}, 16);
window.addEventListener("keydown", (event) => { if (event.key === "Shift") shiftPressing = true; });
window.addEventListener("keyup", (event) => { if (event.key === "Shift") shiftPressing = false; });

const forceOf = (pressure) => 0.2 + 2.8 * pressure; // N: light touch .. firm press

function handTips(id, p, force_n, s) { // the fingertips of a mouse hand centred on p
  const fingers = Number($("fingers").value);
  if (fingers === 1) return [{ id, x_mm: p.x_mm, y_mm: p.y_mm, force_n }];
  if (fingers === 2) {
    return [
      { id: id * 10, x_mm: p.x_mm - s / 2, y_mm: p.y_mm, force_n },
      { id: id * 10 + 1, x_mm: p.x_mm + s / 2, y_mm: p.y_mm, force_n },
    ];
  }
  const tips = [];
  for (let k = 0; k < 5; k++) { // thumb low left, four fingers above, on a circle
    const angle = (-200 + k * 55) * Math.PI / 180;
    tips.push({ id: id * 10 + k, x_mm: p.x_mm + s * Math.cos(angle), y_mm: p.y_mm + s * Math.sin(angle), force_n });
  }
  return tips;
}

const handSpread = () => spread ?? hoverSpread ?? SPREAD[Number($("fingers").value)]?.[2] ?? 0;

function touchList() {
  const tips = [];
  for (const [id, p] of pointers) {
    const force_n = forceOf(p.pressure);
    if (!p.mouse) tips.push({ id, x_mm: p.x_mm, y_mm: p.y_mm, force_n }); // one finger each
    else tips.push(...handTips(id, p, force_n, handSpread()));
  }
  return tips;
}

// Each message carries the events' own times (seconds on the page's clock): the server
// plays the samples at that spacing, so a busy page or network cannot distort a gesture.
// The samples leave in time order: pointer events carry the times the device sampled them,
// the heartbeat and the press ramp the page's clock, and a busy page can run a timer before
// it hands over input sampled earlier; such a sample goes at the newest time already sent
// (played at once) rather than back in time.
let sentT = -Infinity; // the newest sample time sent (s, page clock)
let sentAt = 0; // performance.now() when a sample was last sent
function sendTouches(samples) {
  for (const s of samples) { s.t = Math.max(s.t, sentT); sentT = s.t; }
  sentAt = performance.now();
  send({ type: "touch", samples });
}
const sample = (event) => ({ t: event.timeStamp / 1000, touches: touchList() });

skinCanvas.addEventListener("pointerdown", (event) => {
  event.preventDefault();
  skinCanvas.setPointerCapture(event.pointerId);
  if (event.pointerType === "mouse") { spread = null; hover = null; pressTarget = null; }
  pointers.set(event.pointerId, { ...pointerMm(event), pressure: pressureOf(event), mouse: event.pointerType === "mouse" });
  sendTouches([sample(event)]);
});
skinCanvas.addEventListener("pointermove", (event) => {
  const p = pointers.get(event.pointerId);
  if (!p) { // hovering: where the ghost fingertips of a mouse hand are drawn
    hover = event.pointerType === "mouse" ? pointerMm(event) : null;
    return;
  }
  const events = event.getCoalescedEvents ? event.getCoalescedEvents() : [];
  const samples = [];
  for (const e of events.length ? events : [event]) { // every sample the device gave
    Object.assign(p, pointerMm(e), { pressure: pressureOf(e, p.mouse ? p.pressure : null) });
    samples.push(sample(e));
  }
  sendTouches(samples.slice(-64));
});
for (const kind of ["pointerup", "pointercancel", "lostpointercapture"]) {
  skinCanvas.addEventListener(kind, (event) => {
    if (pointers.delete(event.pointerId)) {
      if (pointers.size === 0) {
        spread = null; // the next press starts from the hover spread
        if (page.state?.recognition?.command) page.releasedAt = performance.now();
      }
      sendTouches([sample(event)]);
    }
  });
}
skinCanvas.addEventListener("pointerleave", () => { hover = null; });
function liftAll() { // the page loses the pointer (another window, hidden tab): lift every finger
  if (pointers.size === 0) return;
  pointers.clear();
  sendTouches([{ t: performance.now() / 1000, touches: [] }]);
}
// Hold-to-run heartbeat: while fingers rest without moving the page repeats them, so the
// server can tell a resting finger from a page that stopped talking (it lifts after 1 s).
// Only after 250 ms without a sample: a moving hand's own samples say it is there.
setInterval(() => {
  if (!pointers.size || performance.now() - sentAt < 250) return;
  sendTouches([{ t: performance.now() / 1000, touches: touchList() }]);
}, 50);
window.addEventListener("blur", liftAll);
document.addEventListener("visibilitychange", () => { if (document.hidden) liftAll(); });
skinCanvas.addEventListener("wheel", (event) => { // hovering: spread the hand; pressing: pinch
  const fingers = Number($("fingers").value);
  if (fingers === 1) { // one finger pressing: the wheel up presses firmly, down eases back
    const p = mousePointer();
    if (!p) return;
    event.preventDefault();
    pressMouse(event.deltaY < 0 ? PRESS_MAX : null);
    return;
  }
  event.preventDefault();
  const [low, high] = SPREAD[fingers];
  const next = Math.max(low, Math.min(high, handSpread() + (event.deltaY > 0 ? -3 : 3)));
  if (pointers.size === 0) { hoverSpread = next; return; }
  spread = next;
  sendTouches([sample(event)]);
}, { passive: false });

// ------------------------------------------------------------------ recognition
function buildBars(classes) {
  const bars = $("bars");
  bars.innerHTML = "";
  for (const name of classes) {
    const row = document.createElement("div");
    row.className = "bar"; row.dataset.name = name;
    row.innerHTML = `<span class="mono">${name}</span><span class="track"><span class="fill"></span></span><span class="mono p">0.00</span>`;
    bars.appendChild(row);
  }
}

function updateRecognition(state) {
  const rec = state.recognition;
  $("command").textContent = rec.command ? `${rec.command}  ${rec.command_for_s.toFixed(1)} s` : "no command";
  $("command").classList.toggle("idle", !rec.command);
  $("command").dataset.command = rec.command || "";
  $("action").textContent = rec.action && rec.action !== "-" ? rec.action : ""; // idle: nothing twice
  $("unsure").textContent = rec.unsure || "";
  const motion = rec.motion || {};
  const moving = (motion.linear_mm_s || 0) > 0.05 || (motion.angular_deg_s || 0) > 0.05;
  let phase = "";
  if (motion.nudging) phase = "  (nudge)";
  else if (motion.fraction != null) phase = motion.fraction < 0.999 ? `  (${Math.round(motion.fraction * 100)} % of full: hold to speed up)` : "  (full speed)";
  $("motion-speed").textContent = moving ? `arm ${motion.linear_mm_s.toFixed(1)} mm/s  ${motion.angular_deg_s.toFixed(1)} deg/s${phase}` : "arm still";
  $("motion-speed").dataset.linear = String(motion.linear_mm_s || 0);
  const holding = (state.safety && state.safety.holding) || [];
  $("holding").textContent = holding.length ? `held back: ${holding.join("; ")}` : "";
  $("holding").dataset.holding = holding.join("\n");
  const rows = $("bars").children;
  for (const row of rows) {
    const k = rec.classes.indexOf(row.dataset.name);
    const p = k >= 0 ? rec.p[k] : 0;
    row.querySelector(".fill").style.width = `${(100 * p).toFixed(1)}%`;
    row.querySelector(".p").textContent = p.toFixed(2);
    row.classList.toggle("top", row.dataset.name === rec.top[0]);
  }
}

const COMMAND_COLOURS = {};
function commandColour(name) {
  if (!COMMAND_COLOURS[name]) {
    let h = 0; for (const ch of name) h = (h * 31 + ch.charCodeAt(0)) % 360;
    COMMAND_COLOURS[name] = `hsl(${h}, 65%, 55%)`;
  }
  return COMMAND_COLOURS[name];
}

// Labels never overlap: a command's name is drawn only where its bar has room for it
// (clipped to the bar, and after the previous label's end), a stop's only clear of the last.
function drawTimeline(state) {
  const canvas = $("timeline");
  const dpr = window.devicePixelRatio || 1;
  canvas.width = Math.round(canvas.clientWidth * dpr); canvas.height = Math.round(54 * dpr);
  const ctx = canvas.getContext("2d"), W = canvas.width, H = canvas.height;
  ctx.clearRect(0, 0, W, H);
  const span = 30, now = state.t, x = (t) => Math.max(0, W * (1 - (now - t) / span));
  ctx.font = `${10 * dpr}px system-ui`;
  const bars = [];
  const commands = state.timeline.filter((e) => e.kind === "command");
  commands.forEach((e, k) => {
    const end = k + 1 < commands.length ? x(commands[k + 1].t) : W;
    if (e.name) bars.push({ name: e.name, x0: x(e.t), x1: end });
  });
  let labelEnd = -Infinity;
  page.timelineLabels = [];
  for (const bar of bars) {
    ctx.fillStyle = commandColour(bar.name);
    ctx.fillRect(bar.x0, 6 * dpr, Math.max(2, bar.x1 - bar.x0), 22 * dpr);
    const width = ctx.measureText(bar.name).width;
    const at = Math.max(bar.x0 + 2, labelEnd + 4 * dpr);
    if (at + width <= bar.x1 - 2) {
      ctx.fillStyle = "#fff"; ctx.fillText(bar.name, at, 20 * dpr);
      page.timelineLabels.push([at, at + width]);
      labelEnd = at + width;
    }
  }
  let stopEnd = -Infinity;
  const stopWidth = ctx.measureText("stop").width;
  for (const e of state.timeline.filter((item) => item.kind === "stop")) {
    ctx.fillStyle = "#e5484d"; ctx.fillRect(x(e.t) - dpr, 0, 2 * dpr, 34 * dpr);
    if (x(e.t) + 3 > stopEnd + 4 * dpr && x(e.t) + 3 + stopWidth < W - 2) {
      ctx.fillText("stop", x(e.t) + 3, 40 * dpr);
      stopEnd = x(e.t) + 3 + stopWidth;
    }
  }
  ctx.fillStyle = "#8b93a1"; ctx.fillText("-30 s", 2, H - 2); ctx.fillText("now", W - 24 * dpr, H - 2);
}

function updateMessages(messages) {
  const list = $("messages");
  const lines = [...messages, ...localMessages].slice(-12);
  if (list.dataset.text === lines.join("\n")) return;
  list.dataset.text = lines.join("\n");
  list.innerHTML = "";
  for (const line of lines.reverse()) {
    const li = document.createElement("li");
    li.textContent = line;
    if (line.includes("error")) li.className = "error";
    list.appendChild(li);
  }
}

// ------------------------------------------------------------------ controls
function buildPerformButtons(gestures) {
  const grid = $("perform");
  grid.innerHTML = "";
  for (const name of gestures) {
    const button = document.createElement("button");
    button.textContent = name; button.dataset.gesture = name;
    button.addEventListener("click", () => command("perform", { gesture: name }));
    grid.appendChild(button);
  }
}

function updateControls(state) {
  const recording = Boolean(state.recording);
  $("record").textContent = recording ? "Stop recording" : "Record";
  $("record").classList.toggle("active", recording);
  $("record").title = recording ? state.recording : "record frames, predictions, commands and robot state";
  if (document.activeElement !== $("speed")) {
    $("speed").value = state.speed_scale;
    $("speed-value").textContent = `${Math.round(state.speed_scale * 100)}%`;
  }
  $("autoplay").disabled = state.autoplay === null;
  if (state.autoplay !== null) $("autoplay").checked = state.autoplay;
  for (const button of $("perform").children) button.disabled = !state.skin.virtual;
  $("robot-status").textContent = state.robot.connected ? (state.robot.fault ? `fault: ${state.robot.fault}` : state.robot.spec) : "not connected";
}

$("stop").addEventListener("click", () => command("stop"));
$("resume").addEventListener("click", () => command("resume"));
$("calibrate").addEventListener("click", () => command("calibrate"));
$("home").addEventListener("click", () => command("home"));
$("initial").addEventListener("click", () => command("initial"));
$("set-initial").addEventListener("click", () => command("set_initial"));
$("record").addEventListener("click", () => command("record", { on: !(page.state && page.state.recording) }));
$("speed").addEventListener("input", () => { $("speed-value").textContent = `${Math.round($("speed").value * 100)}%`; });
$("speed").addEventListener("change", () => command("speed", { value: Number($("speed").value) }));
$("autoplay").addEventListener("change", () => command("autoplay", { on: $("autoplay").checked }));
$("switch").addEventListener("click", () => {
  command("switch", { skin: $("skin-spec").value.trim(), robot: $("robot-spec").value.trim() });
  settleSpecsAfterSwitch();
});

// After Apply, once the server has answered (a "now: ..." line or a "switch:" error), the
// spec fields show the specs of the session that runs: a rejected spec does not linger.
function settleSpecsAfterSwitch(waited_ms = 0) {
  const last = page.state && page.state.messages.length ? page.state.messages[page.state.messages.length - 1] : "";
  const answered = last.startsWith("now: skin") || last.startsWith("error: switch:");
  if (!answered && waited_ms < 10000) { setTimeout(() => settleSpecsAfterSwitch(waited_ms + 200), 200); return; }
  if (page.state) { $("skin-spec").value = page.state.skin.source; $("robot-spec").value = page.state.robot.spec; }
}
$("fingers").addEventListener("change", () => { spread = null; hoverSpread = null; });
window.addEventListener("keydown", (event) => { // space: stop, wherever the focus is but a text field
  const el = document.activeElement;
  if (event.code !== "Space" || (el && el.tagName === "INPUT" && el.type !== "range" && el.type !== "checkbox")) return;
  event.preventDefault();
  command("stop");
});
window.addEventListener("resize", sizeSkinCanvas);

// ------------------------------------------------------------------ the 3D arm (z up, metres)
const arm = (() => {
  const container = $("view");
  const renderer = new THREE.WebGLRenderer({ antialias: true });
  renderer.setPixelRatio(Math.min(2, window.devicePixelRatio || 1));
  let dirty = true; // draw only when a state arrived or the camera moved: idle pages cost nothing
  renderer.outputColorSpace = THREE.SRGBColorSpace;
  // Without a GPU (a software rasteriser: SwiftShader, llvmpipe) one frame of this view costs
  // a CPU core tens of ms, in a browser process that runs at raised priority: drawn at 60 Hz
  // it starved the control session on a 2-core machine. There the view draws at most
  // SOFTWARE_FPS; with a GPU, at the display's rate.
  const SOFTWARE_FPS = 12;
  const gl = renderer.getContext();
  const info = gl.getExtension("WEBGL_debug_renderer_info");
  const rasteriser = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : "";
  page.softwareRendering = /swiftshader|llvmpipe|softpipe|software/i.test(rasteriser);
  const minFrameMs = page.softwareRendering ? 1000 / SOFTWARE_FPS : 0;
  let lastFrame = -Infinity;
  container.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x181b20);
  const camera = new THREE.PerspectiveCamera(45, 1, 0.01, 20);
  camera.up.set(0, 0, 1);
  camera.position.set(1.05, -0.9, 0.75);
  const controls = new THREE.OrbitControls(camera, renderer.domElement);
  controls.target.set(0.2, 0, 0.3);
  controls.update();
  controls.addEventListener("change", () => { dirty = true; });
  scene.add(new THREE.HemisphereLight(0xdfe8ff, 0x303030, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(2, -1, 3);
  scene.add(sun);
  const grid = new THREE.GridHelper(2, 20, 0x3a414d, 0x262b33);
  grid.rotation.x = Math.PI / 2;
  scene.add(grid);
  scene.add(new THREE.AxesHelper(0.15));
  const meshes = [];
  let patch = null;
  const texture = new THREE.CanvasTexture(skinTexture);
  texture.magFilter = THREE.NearestFilter; texture.minFilter = THREE.NearestFilter;
  texture.colorSpace = THREE.SRGBColorSpace;
  const tcpAxes = new THREE.AxesHelper(0.09);
  scene.add(tcpAxes);
  const linear = new THREE.ArrowHelper(new THREE.Vector3(1, 0, 0), new THREE.Vector3(), 0.1, 0x4aa3ff, 0.035, 0.02);
  const angular = new THREE.ArrowHelper(new THREE.Vector3(1, 0, 0), new THREE.Vector3(), 0.1, 0xc77dff, 0.035, 0.02);
  scene.add(linear, angular);
  // On the skin patch: where a swipe_up (green, toward row 0) and a swipe_right (orange,
  // toward the last column) stroke go on the skin, so its directions read off the arm.
  const patchUp = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 0.06, 0x2fb36d, 0.018, 0.012);
  const patchRight = new THREE.ArrowHelper(new THREE.Vector3(1, 0, 0), new THREE.Vector3(), 0.045, 0xf2a93b, 0.015, 0.01);
  patchUp.name = "swipe_up direction"; patchRight.name = "swipe_right direction";
  patchUp.visible = patchRight.visible = false;
  scene.add(patchUp, patchRight);

  function geometryOf(shape) {
    const s = shape.size;
    let g;
    if (shape.type === "box") g = new THREE.BoxGeometry(2 * s[0], 2 * s[1], 2 * s[2]);
    else if (shape.type === "sphere") g = new THREE.SphereGeometry(s[0], 24, 16);
    else if (shape.type === "capsule") { g = new THREE.CapsuleGeometry(s[0], 2 * s[1], 8, 20); g.rotateX(Math.PI / 2); }
    else { g = new THREE.CylinderGeometry(s[0], s[0], 2 * s[1], 28); g.rotateX(Math.PI / 2); }
    return g; // three's capsules and cylinders run along y, MuJoCo's along z
  }

  // Frame the arm: on its first pose after a (re)build, and on a double click in the view.
  let framed = false;
  const VIEW_DIRECTION = new THREE.Vector3(1.05, -0.9, 0.75).normalize();
  function frame() { // the box around the shapes' centres (three's Box3 is not in the bundle)
    if (!meshes.length) return;
    const low = meshes[0].position.clone(), high = meshes[0].position.clone();
    for (const m of meshes) { low.min(m.position); high.max(m.position); }
    const centre = low.clone().add(high).multiplyScalar(0.5);
    const size = high.clone().sub(low).length() + 0.2; // + the shapes' own extent, roughly
    controls.target.copy(centre);
    camera.position.copy(centre).addScaledVector(VIEW_DIRECTION, Math.max(0.8, 1.7 * size));
    controls.update();
    framed = true; dirty = true;
  }
  renderer.domElement.addEventListener("dblclick", frame);

  // The safety layer's workspace box: its 12 edges as thin bars, shown when asked for
  // (the "workspace" box) and, in red, whenever the TCP comes within 5 cm of a face.
  const boxMaterial = new THREE.MeshBasicMaterial({ color: 0x4aa3ff, transparent: true, opacity: 0.3 });
  const boxEdges = [];
  let box = null;
  function buildBox(workspace) {
    for (const edge of boxEdges) scene.remove(edge);
    boxEdges.length = 0;
    box = workspace || null;
    if (!box) return;
    const [lo, hi] = [box.lower, box.upper], t = 0.003;
    for (let axis = 0; axis < 3; axis++) { // 4 edges along each axis
      const length = hi[axis] - lo[axis], o1 = (axis + 1) % 3, o2 = (axis + 2) % 3;
      for (const a of [lo[o1], hi[o1]]) {
        for (const b of [lo[o2], hi[o2]]) {
          const size = [t, t, t]; size[axis] = length;
          const edge = new THREE.Mesh(new THREE.BoxGeometry(...size), boxMaterial);
          const centre = [0, 0, 0];
          centre[axis] = (lo[axis] + hi[axis]) / 2; centre[o1] = a; centre[o2] = b;
          edge.position.set(...centre);
          edge.name = "workspace";
          boxEdges.push(edge); scene.add(edge);
        }
      }
    }
  }
  function updateBox(position) {
    if (!box) return;
    const near = position.some((v, k) => v - box.lower[k] < 0.05 || box.upper[k] - v < 0.05);
    boxMaterial.color.set(near ? 0xe5484d : 0x4aa3ff);
    boxMaterial.opacity = near ? 0.6 : 0.3;
    for (const edge of boxEdges) edge.visible = near || $("show-box").checked;
    page.nearWorkspaceEdge = near;
    page.workspaceEdgesShown = boxEdges.filter((edge) => edge.visible).length;
  }
  $("show-box").addEventListener("change", () => { if (page.state) updateBox(page.state.robot.tcp.pos); dirty = true; });

  function build(description, workspace) {
    dirty = true;
    framed = false;
    buildBox(workspace);
    for (const m of meshes) scene.remove(m);
    meshes.length = 0;
    if (patch) { scene.remove(patch); patch = null; }
    if (!description) return;
    for (const shape of description.geoms) {
      const [r, g, b, a] = shape.rgba;
      const material = new THREE.MeshStandardMaterial({ color: new THREE.Color(r, g, b), transparent: a < 1, opacity: a, roughness: 0.6, metalness: 0.1 });
      const mesh = new THREE.Mesh(geometryOf(shape), material);
      mesh.name = shape.name;
      if (shape.name === "skin_patch") mesh.visible = false; // drawn as the live heatmap below
      meshes.push(mesh); scene.add(mesh);
    }
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.Float32BufferAttribute(new Float32Array(12), 3));
    geometry.setAttribute("uv", new THREE.Float32BufferAttribute([0, 1, 1, 1, 0, 0, 1, 0], 2));
    geometry.setIndex([0, 2, 1, 1, 2, 3]);
    patch = new THREE.Mesh(geometry, new THREE.MeshBasicMaterial({ map: texture, side: THREE.DoubleSide }));
    patch.name = "skin";
    scene.add(patch);
  }

  function update(robot) {
    if (!robot || !robot.connected) return;
    dirty = true;
    if (robot.geoms && robot.geoms.length === meshes.length) {
      robot.geoms.forEach((p, k) => {
        meshes[k].position.set(p[0], p[1], p[2]);
        meshes[k].quaternion.set(p[4], p[5], p[6], p[3]);
      });
      if (!framed) frame();
    }
    if (patch && robot.skin_corners) { // top-left, top-right, bottom-left: a 1 mm lift off the link
      const [tl, tr, bl] = robot.skin_corners.map((c) => new THREE.Vector3(...c));
      const normal = new THREE.Vector3().subVectors(tr, tl).cross(new THREE.Vector3().subVectors(bl, tl)).normalize();
      const lift = normal.multiplyScalar(-0.001);
      const br = new THREE.Vector3().addVectors(tr, bl).sub(tl);
      const position = patch.geometry.attributes.position;
      [tl, tr, bl, br].forEach((v, k) => { v.add(lift); position.setXYZ(k, v.x, v.y, v.z); });
      position.needsUpdate = true;
      patch.geometry.computeBoundingSphere();
      texture.needsUpdate = true;
      const centre = new THREE.Vector3().addVectors(tr, bl).multiplyScalar(0.5).addScaledVector(lift, 4);
      const up = new THREE.Vector3().subVectors(tl, bl).normalize(); // toward row 0
      const right = new THREE.Vector3().subVectors(tr, tl).normalize(); // toward the last column
      patchUp.position.copy(centre); patchUp.setDirection(up); patchUp.visible = true;
      patchRight.position.copy(centre); patchRight.setDirection(right); patchRight.visible = true;
      page.patchArrows = { up: up.toArray(), right: right.toArray() };
    }
    const [x, y, z] = robot.tcp.pos, [qw, qx, qy, qz] = robot.tcp.quat;
    updateBox(robot.tcp.pos);
    tcpAxes.position.set(x, y, z);
    tcpAxes.quaternion.set(qx, qy, qz, qw);
    const origin = new THREE.Vector3(x, y, z);
    const v = new THREE.Vector3(...robot.twist.slice(0, 3)), w = new THREE.Vector3(...robot.twist.slice(3));
    linear.visible = v.length() > 1e-3; angular.visible = w.length() > 1e-3;
    if (linear.visible) { linear.position.copy(origin); linear.setDirection(v.clone().normalize()); linear.setLength(0.05 + v.length() * 0.8, 0.03, 0.018); }
    if (angular.visible) { angular.position.copy(origin); angular.setDirection(w.clone().normalize()); angular.setLength(0.05 + w.length() * 0.15, 0.03, 0.018); }
    const deg = (a) => (a * 180 / Math.PI).toFixed(1).padStart(7);
    const mm = (m) => (m * 1000).toFixed(1).padStart(8);
    $("tcp").textContent =
      `TCP  x ${mm(x)}  y ${mm(y)}  z ${mm(z)} mm   speed ${(robot.tcp_speed * 1000).toFixed(0)} mm/s\n` +
      `quat w ${qw.toFixed(3)} x ${qx.toFixed(3)} y ${qy.toFixed(3)} z ${qz.toFixed(3)}${robot.moving ? "   moving" : ""}\n` +
      `q    ${robot.q.map(deg).join(" ")} deg`;
  }

  function resizeTexture() { texture.dispose(); } // three.js allocates the new size on next use

  function render() {
    const w = container.clientWidth, h = container.clientHeight;
    if (renderer.domElement.width !== Math.round(w * renderer.getPixelRatio()) || renderer.domElement.height !== Math.round(h * renderer.getPixelRatio())) {
      renderer.setSize(w, h, false);
      renderer.domElement.style.width = "100%"; renderer.domElement.style.height = "100%";
      camera.aspect = w / Math.max(1, h); camera.updateProjectionMatrix();
      dirty = true;
    }
    const now = performance.now();
    if (dirty && now - lastFrame >= minFrameMs) {
      renderer.render(scene, camera); dirty = false; lastFrame = now;
      page.rendered = (page.rendered || 0) + 1;
    }
    requestAnimationFrame(render);
  }
  requestAnimationFrame(render);
  return { build, update, resizeTexture, scene, meshes, grid, markDirty: () => { dirty = true; } };
})();
const taskView = makeTaskView(THREE, arm, page);
const study = setupStudy({ $, page, send, command });
const adapt = setupAdapt({ $, colour, token });
page.adapt = adapt; // for tests and the browser console

sizeSkinCanvas();
connect();
