// barsynth studio: the page (no build step, no libraries; docs/studio.md is its spec).
//
// The controls are generated from each model's parameter table (GET /api/models). The
// server runs the model: the live sound comes over the WebSocket /api/stream, which a Worker
// owns (link.js), and is played by an AudioWorklet (worklet.js) fed by that worker directly,
// not through this thread; the pictures (POST /api/picture), WAV files, mode tables
// and preset files come over HTTP. Every value is checked by the server, whose one-line
// message is shown as it is.
//
// For tests, window.studio holds live figures: state ("idle" | "playing"), blocksReceived,
// samplesPlayed, maxBufferedFrames, underruns and dropouts, latencies (ms from a change being
// sent to its first sample leaving the speakers) and changeLatencies (from the change being
// made: a set may wait for the one before it), sets, lastSet ({id, parameters} of the last set
// sent), heardSetId, setsWaiting, playedReports (sent to the server, heartbeats too), streams
// (sockets opened) and closes (closed by the server or the network), lastPicture and errors.
"use strict";

const $ = (id) => document.getElementById(id);

const RATE = 48000;  // pictures and WAV files; the live stream uses the AudioContext's rate
const PICTURE_S = 1.5;
const PICTURE_DELAY_MS = 150;
const MAX_LATENCIES = 1000;
const GROUP_COLOURS = ["#1f6fb4", "#d9730d", "#2f9e44", "#c2255c", "#7048e8", "#0c8599", "#a61e4d", "#5c940d"];
const SLIDER_STEPS = 1000;

const studio = {
  ready: false,
  state: "idle",
  model: null,
  preset: "",
  values: {},
  blocksReceived: 0,
  samplesPlayed: 0,
  buffered: 0,
  maxBufferedFrames: 0,
  underruns: 0,
  dropouts: [],  // when the buffer ran dry while it sounded (performance.now(), ms)
  latencies: [],
  changeLatencies: [],
  sets: 0,
  lastSet: null,
  heardSetId: -1,
  setsWaiting: false,
  playedReports: 0,
  streams: 0,
  closes: 0,
  lastPicture: null,
  pictures: 0,
  errors: [],
};
window.studio = studio;

let models = new Map();  // name -> {name, summary, parameters: [rows], presets: [names]}
let model = null;  // the chosen model's entry
let base = {};  // the chosen preset's values (or the table's defaults): what a link leaves out
let values = {};  // the current, accepted values
const controls = new Map();  // name -> {row, show(value)}

// --- messages and the server ---------------------------------------------------------------

function showMessage(text) {
  const box = $("message");
  box.textContent = text;
  box.hidden = false;
  studio.errors.push(text);
}

function clearMessage() {
  $("message").hidden = true;
  $("message").textContent = "";
}

function note(text) {
  $("live").textContent = text;
}

class ApiError extends Error {
  constructor(status, message, data) { super(message); this.status = status; this.data = data; }
}

// JSON in; JSON (or, with asBlob, a Blob) out; an ApiError with the server's one line otherwise.
async function api(method, path, payload, asBlob = false) {
  const options = { method, headers: {} };
  if (payload !== undefined) {
    options.headers["Content-Type"] = "application/json";
    options.body = JSON.stringify(payload);
  }
  let response;
  try {
    response = await fetch(path, options);
  } catch (err) {
    throw new ApiError(0, "The studio server cannot be reached; is `barsynth studio` still running?");
  }
  if (response.ok) return asBlob ? response.blob() : response.json();
  let data = null;
  try { data = await response.json(); } catch (err) { data = null; }
  const text = (data && data.error) || `The server answered ${response.status} ${response.statusText}.`;
  throw new ApiError(response.status, text, data);
}

function failed(err) {
  showMessage(err instanceof ApiError ? err.message : `Something went wrong: ${err.message || err}`);
}

// --- values: formatting, parsing, sliders ----------------------------------------------------

function fmt(v) {
  if (typeof v !== "number") return String(v);
  if (!Number.isFinite(v) || v === 0) return String(v);
  const a = Math.abs(v);
  if (a >= 1e5 || a < 1e-3) return v.toExponential(3).replace(/\.?0+e/, "e").replace("e+", "e");
  return String(Number(v.toPrecision(4)));
}

function listText(list) {
  return list.map((x) => String(x)).join(",");
}

function sliderSteps(row) {
  return row.kind === "int" && row.scale === "linear" && row.max - row.min <= SLIDER_STEPS ? row.max - row.min
    : SLIDER_STEPS;
}

function fromSlider(row, position) {
  const u = position / sliderSteps(row);
  let v = row.scale === "log" ? Math.exp(Math.log(row.min) + u * (Math.log(row.max) - Math.log(row.min)))
    : row.min + u * (row.max - row.min);
  v = row.kind === "int" ? Math.round(v) : Number(v.toPrecision(4));
  return Math.min(row.max, Math.max(row.min, v));
}

function toSlider(row, v) {
  const u = row.scale === "log" ? (Math.log(v) - Math.log(row.min)) / (Math.log(row.max) - Math.log(row.min))
    : (v - row.min) / (row.max - row.min);
  return Math.round(Math.min(1, Math.max(0, u)) * sliderSteps(row));
}

function same(a, b) {
  if (Array.isArray(a) || Array.isArray(b)) {
    return Array.isArray(a) && Array.isArray(b) && a.length === b.length && a.every((x, i) => same(x, b[i]));
  }
  if (typeof a === "number" && typeof b === "number") {
    return a === b || Math.abs(a - b) <= 1e-12 * Math.max(Math.abs(a), Math.abs(b));
  }
  return a === b;
}

// A typed value as the table would take it, or undefined when it is not acceptable.
function parsed(row, text) {
  const raw = String(text).trim();
  if (row.kind === "float" || row.kind === "int") {
    const v = raw === "" ? NaN : Number(raw);
    if (!Number.isFinite(v) || v < row.min || v > row.max) return undefined;
    if (row.kind === "int" && !Number.isInteger(v)) return undefined;
    return v;
  }
  if (row.kind === "floats") {
    const parts = raw.split(",").map((s) => s.trim()).filter((s) => s !== "");
    const list = parts.map(Number);
    if (list.length > row.max_items || list.some((v) => !Number.isFinite(v) || v < row.min || v > row.max)) {
      return undefined;
    }
    return list;
  }
  if (row.kind === "bool") {
    const word = raw.toLowerCase();
    if (["1", "true", "yes", "on"].includes(word)) return true;
    if (["0", "false", "no", "off"].includes(word)) return false;
    return undefined;
  }
  return row.choices.includes(raw.toLowerCase()) ? raw.toLowerCase() : undefined;
}

// How a typed value goes to the server: a number when it reads as one (so the message says
// "= 5", not "= '5'"), the text otherwise.
function asTyped(row, text) {
  const raw = String(text).trim();
  if ((row.kind === "float" || row.kind === "int") && raw !== "" && Number.isFinite(Number(raw))) {
    return Number(raw);
  }
  return raw;
}

// --- controls ---------------------------------------------------------------------------------

function element(tag, props = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(props)) {
    if (k === "class") node.className = v;
    else if (k in node) node[k] = v;
    else node.setAttribute(k, v);
  }
  node.append(...children);
  return node;
}

function makeControl(row) {
  const id = `param-${row.name}`;
  const tip = `${row.doc}${row.unit ? ` (${row.unit})` : ""}`;
  const wrap = element("div", { class: `param kind-${row.kind}`, title: tip });
  wrap.dataset.name = row.name;
  const label = element("label", { htmlFor: id, class: "name" }, row.name);
  const unit = element("span", { class: "unit" }, row.unit);
  let show;

  if (row.kind === "float" || row.kind === "int") {
    const slider = element("input", { type: "range", id, min: "0", max: String(sliderSteps(row)), step: "1",
      title: tip, class: row.scale === "log" ? "log" : "linear" });
    const box = element("input", { type: "number", id: `num-${row.name}`, step: "any", class: "num", title: tip,
      inputMode: "decimal" });
    box.setAttribute("aria-label", `${row.name} value${row.unit ? ` in ${row.unit}` : ""}`);
    slider.addEventListener("input", () => {
      const v = fromSlider(row, Number(slider.value));
      box.value = fmt(v);
      if (!same(v, values[row.name])) change(row.name, v);
    });
    box.addEventListener("change", () => typed(row.name, box.value));
    show = (v) => {
      slider.value = String(toSlider(row, v));
      box.value = fmt(v);
    };
    wrap.append(label, slider, box, unit);
    wrap.classList.add("slider");
  } else if (row.kind === "choice") {
    const select = element("select", { id, title: tip });
    for (const c of row.choices) select.append(element("option", { value: c }, c));
    select.addEventListener("change", () => change(row.name, select.value));
    show = (v) => { select.value = v; };
    wrap.append(label, select, unit);
  } else if (row.kind === "bool") {
    const box = element("input", { type: "checkbox", id, title: tip });
    box.addEventListener("change", () => change(row.name, box.checked));
    show = (v) => { box.checked = !!v; };
    wrap.append(label, box, unit);
  } else {  // floats: "1,4,10"
    const text = element("input", { type: "text", id, title: tip, placeholder: "e.g. 1,4,10", class: "list",
      spellcheck: false });
    text.addEventListener("change", () => typed(row.name, text.value));
    show = (v) => { text.value = listText(v); };
    wrap.append(label, text, unit);
  }
  controls.set(row.name, { row, show });
  return wrap;
}

function buildControls() {
  controls.clear();
  const form = $("controls");
  form.replaceChildren(...model.parameters.map(makeControl));
}

function showAll() {
  for (const [name, control] of controls) control.show(values[name]);
  studio.values = { ...values };
}

function rowOf(name) {
  return model.parameters.find((r) => r.name === name);
}

// An accepted change from a control: remember it, send it to the live sound, redraw the pictures.
function change(name, v) {
  clearMessage();
  values[name] = v;
  studio.values = { ...values };
  queueSet(name, v);
  schedulePicture();
}

// A typed value: taken when the table allows it; otherwise sent as typed for the server's
// message, and the control goes back to its last good value.
async function typed(name, text) {
  const row = rowOf(name);
  const v = row ? parsed(row, text) : undefined;
  if (v !== undefined) {
    controls.get(name).show(v);
    if (!same(v, values[name])) change(name, v);
    return;
  }
  if (controls.has(name)) controls.get(name).show(values[name]);
  await refuse(name, row ? asTyped(row, text) : text);
}

async function refuse(name, sent) {
  const modelName = model.name;
  try {
    await api("POST", "/api/describe", { model: modelName, parameters: { ...values, [name]: sent }, sample_rate: RATE });
  } catch (err) {
    failed(err);
    return;
  }
  // The server took it after all (it reads a few more spellings than this page does).
  const row = rowOf(name);
  if (modelName === model.name && row) {
    const v = row.kind === "floats" && !Array.isArray(sent) ? parsed(row, sent) : sent;
    if (v !== undefined) {
      controls.get(name).show(v);
      change(name, v);
    }
  }
}

// --- models and presets ----------------------------------------------------------------------

function defaults() {
  return Object.fromEntries(model.parameters.map((r) => [r.name, Array.isArray(r.default) ? [...r.default] : r.default]));
}

async function chooseModel(name, wanted = {}) {
  model = models.get(name);
  studio.model = name;
  $("model").value = name;
  $("summary").textContent = model.summary;
  const presetSelect = $("preset");
  presetSelect.replaceChildren(element("option", { value: "" }, "(defaults)"),
    ...model.presets.map((p) => element("option", { value: p }, p)));
  buildControls();
  await choosePreset(wanted.preset || "", wanted.overrides);  // an unknown one: the server's message
}

async function choosePreset(name, overrides) {
  let loaded = defaults();
  let description = `${model.name} settings`;
  if (name) {
    try {
      const data = await api("GET", `/api/models/${encodeURIComponent(model.name)}/presets/${encodeURIComponent(name)}`);
      loaded = data.parameters;
      description = data.description || description;
    } catch (err) {
      failed(err);
      name = "";
    }
  }
  $("preset").value = name;
  studio.preset = name;
  base = { ...loaded };
  values = { ...loaded };
  $("description").value = description;
  showAll();
  if (overrides) {
    for (const [key, text] of overrides) {
      if (key !== "model" && key !== "preset") await typed(key, text);
    }
  }
  restart();
  schedulePicture(0);
}

// --- the live sound ---------------------------------------------------------------------------
//
// Three threads: the stream's Worker (link.js) owns the WebSocket, the AudioWorklet
// (worklet.js) plays, and they talk over a MessageChannel of their own: blocks one way,
// `played` reports the other. This thread only opens and stops streams, passes on the
// controls' messages, and keeps window.studio's figures from what the two tell it, so a busy
// page (pictures, layout, a screenshot) never starves the sound.

const live = {
  ctx: null,
  node: null,
  gain: null,
  worker: null,
  ready: null,
  gen: 0,  // the socket that sounds now (0: none); each Play opens one with a new number
  lastGen: 0,
  asked: 0,  // Play and Stop presses: a Play still waiting for the audio gives way to a later press
  started: false,
  pending: new Map(),  // set id -> {sentAt, changedAt} (performance.now()) on socket `gen`
  heardId: -1,  // the newest set id heard on socket `gen`, and when
  heardAt: 0,
  playedOf: new Map(),  // gen -> samples of it counted in studio.samplesPlayed
};

function volume() {
  const v = Number($("volume").value) / 100;
  return v * v;
}

// The AudioContext (made inside the click that asks for sound, as browsers require), the
// worklet, the stream's worker and the channel between the two.
async function ensureAudio() {
  if (!live.ctx) {
    let ctx;
    try {
      ctx = new AudioContext({ sampleRate: 48000, latencyHint: "interactive" });
    } catch (err) {
      ctx = new AudioContext({ latencyHint: "interactive" });  // a device that cannot run at 48 kHz
    }
    live.ctx = ctx;
    live.ready = (async () => {
      await ctx.audioWorklet.addModule("/static/worklet.js");
      const node = new AudioWorkletNode(ctx, "barsynth-stream",
        { numberOfInputs: 0, numberOfOutputs: 1, outputChannelCount: [1] });
      const gain = ctx.createGain();
      gain.gain.value = volume();
      node.connect(gain).connect(ctx.destination);
      node.port.onmessage = (event) => fromWorklet(event.data);
      const worker = new Worker("/static/link.js");
      worker.onmessage = (event) => fromWorker(event.data);
      worker.onerror = (event) => showMessage(`The live sound's worker failed: ${event.message || "an error"}`);
      const channel = new MessageChannel();
      node.port.postMessage({ type: "link", port: channel.port1 }, [channel.port1]);
      worker.postMessage({ type: "worklet", port: channel.port2 }, [channel.port2]);
      live.node = node;
      live.gain = gain;
      live.worker = worker;
    })();
  }
  const resumed = live.ctx.state === "running" ? null : live.ctx.resume();
  await live.ready;
  if (resumed) await resumed;
}

// A message for the server on the socket that sounds now (the worker keeps it until the
// socket is open).
function send(message) {
  if (live.gen) live.worker.postMessage({ type: "send", gen: live.gen, message });
}

function startMessage() {
  return { type: "start", model: model.name, parameters: { ...values }, sample_rate: live.ctx.sampleRate };
}

async function play() {
  clearMessage();
  const asked = ++live.asked;
  try {
    await ensureAudio();
  } catch (err) {
    showMessage(`This browser cannot play the live sound: ${err.message || err}`);
    return;
  }
  if (asked !== live.asked) return;  // Stop (or another Play) was pressed meanwhile
  if (live.gen) {
    trigger();
    return;
  }
  const gen = ++live.lastGen;
  live.gen = gen;
  live.started = false;
  live.pending.clear();
  live.heardId = -1;
  studio.heardSetId = -1;
  studio.lastSet = null;
  live.node.port.postMessage({ type: "reset", gen });
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/api/stream`;
  live.worker.postMessage({ type: "open", gen, url, start: [startMessage(), { type: "trigger" }] });
  studio.streams += 1;
  setState("playing");
}

function fromWorker(message) {
  if (message.type === "counts") {
    studio.blocksReceived = message.blocks;
    studio.sets = message.sets;
    studio.playedReports = message.reports;
    if (message.gen === live.gen) studio.setsWaiting = message.waiting;
    return;
  }
  if (message.gen !== live.gen) return;  // a stopped socket's
  if (message.type === "message") {
    fromServer(message.message);
  } else if (message.type === "sent") {
    const sentAt = message.at - performance.timeOrigin;
    const changedAt = message.changedAt === null ? sentAt : message.changedAt - performance.timeOrigin;
    studio.lastSet = { id: message.id, parameters: message.parameters };
    if (message.id <= live.heardId) {  // heard before this message came (the two come by different ways)
      latency(live.heardAt, { sentAt, changedAt });
    } else {
      live.pending.set(message.id, { sentAt, changedAt });
    }
  } else if (message.type === "close") {  // closed by the server or the network, not by a Stop
    live.gen = 0;
    studio.closes += 1;
    setState("idle");
    if (message.code !== 1000) {
      showMessage(message.reason || (message.code === 1006
        ? "The live sound was cut off: the studio server cannot be reached."
        : `The live sound stopped (WebSocket closed with code ${message.code}).`));
    }
  }
}

function fromServer(message) {
  if (message.type === "started") {
    live.started = true;
    live.block = message.block;
    live.lead = message.lead;
  } else if (message.type === "error") {
    showMessage(message.error);
  }
}

function latency(heardAt, sent) {
  const ctx = live.ctx;
  const output = 1000 * (ctx.outputLatency || ctx.baseLatency || 0);
  studio.latencies.push(heardAt - sent.sentAt + output);
  studio.changeLatencies.push(heardAt - sent.changedAt + output);
  for (const list of [studio.latencies, studio.changeLatencies]) {
    if (list.length > MAX_LATENCIES) list.splice(0, list.length - MAX_LATENCIES);
  }
}

// Samples played, per socket: a socket's count only grows, so a late or repeated report of an
// old socket can never count twice.
function countPlayed(gen, played) {
  const before = live.playedOf.get(gen) || 0;
  if (played <= before) return;
  studio.samplesPlayed += played - before;
  live.playedOf.set(gen, played);
  if (live.playedOf.size > 8) live.playedOf.delete(live.playedOf.keys().next().value);
}

function fromWorklet(message) {
  if (message.stats) {
    countPlayed(message.gen, message.played);
    studio.buffered = message.buffered;
    studio.maxBufferedFrames = Math.max(studio.maxBufferedFrames, message.maxBuffered);
  } else if (message.heard !== undefined) {
    if (message.gen !== live.gen) return;
    const now = performance.now();
    live.heardId = message.heard;
    live.heardAt = now;
    studio.heardSetId = message.heard;
    for (const [id, sent] of live.pending) {
      if (id <= message.heard) {
        latency(now, sent);
        live.pending.delete(id);
      } else if (now - sent.sentAt > 2000) {
        live.pending.delete(id);  // never heard (the stream slept or refused it)
      }
    }
  } else if (message.underrun) {
    studio.underruns += 1;
    studio.dropouts.push(Math.round(performance.now()));
    if (studio.dropouts.length > 100) studio.dropouts.shift();
  } else if (message.stopped) {
    countPlayed(message.gen, message.played);
  }
}

function trigger() {
  if (!live.gen) {
    play();
    return;
  }
  send({ type: "trigger" });
}

function release() {
  send({ type: "release" });
}

// The worklet fades out over 10 ms and drops what comes after; the worker tells the server
// and closes the socket when the fade is over. A Play right after opens a new socket: the
// generation numbers keep the two apart.
function stop() {
  live.asked += 1;
  const gen = live.gen;
  if (!gen) return;
  live.gen = 0;
  live.worker.postMessage({ type: "stop", gen });
  live.node.port.postMessage({ type: "stop", gen });
  setState("idle");
}

// A new voice on the open stream (the server cross-fades), struck at once.
function restart() {
  if (!live.gen) return;
  send(startMessage());  // the worker drops changes not sent yet: the start has them
  send({ type: "trigger" });
}

// Changes go to the worker, which merges them and sends one set at a time (link.js).
function queueSet(name, v) {
  if (!live.gen) return;
  live.worker.postMessage({ type: "set", gen: live.gen, parameters: { [name]: v },
    at: performance.timeOrigin + performance.now() });
}

function setState(state) {
  studio.state = state;
  document.body.classList.toggle("playing", state === "playing");
  $("play").classList.toggle("on", state === "playing");
  updateLive();
}

function median(list) {
  if (!list.length) return NaN;
  const sorted = [...list].sort((a, b) => a - b);
  return sorted[Math.floor(sorted.length / 2)];
}

function updateLive() {
  if (studio.state !== "playing") {
    note("stopped");
    return;
  }
  const rate = live.ctx ? live.ctx.sampleRate : RATE;
  const parts = [`playing at ${rate} Hz`, `buffer ${(1000 * studio.buffered / rate).toFixed(0)} ms`];
  const recent = studio.latencies.slice(-20);
  if (recent.length) parts.push(`change heard after ${median(recent).toFixed(0)} ms`);
  if (studio.underruns) parts.push(`${studio.underruns} dropout${studio.underruns === 1 ? "" : "s"}`);
  note(parts.join(" · "));
}

// --- pictures ---------------------------------------------------------------------------------

const pictures = { timer: 0, busy: false, again: false, api: "picture", data: null };

function schedulePicture(delay = PICTURE_DELAY_MS) {
  clearTimeout(pictures.timer);
  pictures.timer = setTimeout(updatePictures, delay);
}

async function updatePictures() {
  if (pictures.busy) {
    pictures.again = true;
    return;
  }
  pictures.busy = true;
  const asked = { model: model.name, parameters: { ...values } };
  try {
    let data = null;
    if (pictures.api === "picture") {
      try {
        data = await api("POST", "/api/picture", { ...asked, duration_s: PICTURE_S, sample_rate: RATE,
          width: plotWidth($("waveform")) });
      } catch (err) {
        if (err.status !== 404 || (err.data && err.data.error)) throw err;
        pictures.api = "describe";  // a server without pictures: the modes only
      }
    }
    if (pictures.api === "describe") {
      data = await api("POST", "/api/describe", { ...asked, sample_rate: RATE });
    }
    if (data && data.model === model.name) {
      pictures.data = data;
      pictures.asked = asked.parameters;
      await drawAll(data);
    }
  } catch (err) {
    failed(err);
  } finally {
    pictures.busy = false;
    if (pictures.again) {
      pictures.again = false;
      schedulePicture(0);
    }
  }
}

function hash(text) {  // FNV-1a, 32 bits, hex
  let h = 0x811c9dc5;
  for (let i = 0; i < text.length; i++) {
    h ^= text.charCodeAt(i);
    h = Math.imul(h, 0x01000193) >>> 0;
  }
  return h.toString(16).padStart(8, "0");
}

const nextTask = () => new Promise((resolve) => setTimeout(resolve, 0));

async function drawAll(data) {
  const modes = data.modes || [];
  const groups = {};
  for (const m of modes) groups[m.group] = (groups[m.group] || 0) + 1;
  let loudest = null;
  for (const m of modes) if (!loudest || Math.abs(m.gain) > Math.abs(loudest.gain)) loudest = m;
  let peak = 0;
  if (data.waveform) {
    for (const v of data.waveform.min) peak = Math.max(peak, Math.abs(v));
    for (const v of data.waveform.max) peak = Math.max(peak, Math.abs(v));
  }
  const asked = { ...pictures.asked };
  // One picture per task, so the page stays responsive (the live sound no longer passes
  // through this thread, but its controls do).
  const steps = [() => drawWaveform(data), () => drawSpectrogram(data), () => drawModes(modes), () => fillTable(modes)];
  for (const step of steps) {
    if (pictures.data !== data) return;  // newer pictures came meanwhile
    step();
    await nextTask();
  }
  studio.pictures += 1;
  studio.lastPicture = {
    model: data.model,
    modes: modes.length,
    groups,
    loudestHz: loudest ? loudest.frequency_hz : null,
    table: modes.map((m) => ({ ...m })),
    spectrogramHash: data.spectrogram ? hash(data.spectrogram.levels) : null,
    waveformPeak: data.waveform ? peak : null,
    values: asked,  // the settings these pictures are of
  };
}

// Canvases: sized to their box at the screen's resolution, drawn in CSS pixels.
const MARGIN = { left: 58, right: 14, top: 12, bottom: 34 };

function prepare(canvas, right = MARGIN.right) {
  const dpr = window.devicePixelRatio || 1;
  const width = Math.max(200, Math.round(canvas.clientWidth || canvas.width));
  const height = Math.max(100, Math.round(canvas.clientHeight || canvas.height));
  if (canvas.width !== Math.round(width * dpr) || canvas.height !== Math.round(height * dpr)) {
    canvas.width = Math.round(width * dpr);
    canvas.height = Math.round(height * dpr);
  }
  const g = canvas.getContext("2d");
  g.setTransform(dpr, 0, 0, dpr, 0, 0);
  g.clearRect(0, 0, width, height);
  g.fillStyle = "#fff";
  g.fillRect(0, 0, width, height);
  g.font = "11px system-ui, sans-serif";
  const box = { x: MARGIN.left, y: MARGIN.top, w: width - MARGIN.left - right, h: height - MARGIN.top - MARGIN.bottom };
  return { g, width, height, box };
}

function plotWidth(canvas) {
  const width = Math.round(canvas.clientWidth || canvas.width);
  return Math.max(100, Math.min(1200, width - MARGIN.left - MARGIN.right));  // the server's MAX_COLUMNS
}

function frame(g, box) {
  g.strokeStyle = "#888";
  g.lineWidth = 1;
  g.strokeRect(box.x + 0.5, box.y + 0.5, box.w, box.h);
}

function emptyPlot(g, box, text) {
  frame(g, box);
  g.fillStyle = "#777";
  g.textAlign = "center";
  g.textBaseline = "middle";
  g.fillText(text, box.x + box.w / 2, box.y + box.h / 2);
}

function xTicks(g, box, ticks, toX, label) {
  g.fillStyle = "#333";
  g.strokeStyle = "#ddd";
  g.textAlign = "center";
  g.textBaseline = "top";
  for (const [value, text] of ticks) {
    const x = Math.round(toX(value)) + 0.5;
    if (x < box.x - 1 || x > box.x + box.w + 1) continue;
    g.beginPath();
    g.moveTo(x, box.y + box.h);
    g.lineTo(x, box.y + box.h + 4);
    g.stroke();
    g.fillText(text, x, box.y + box.h + 6);
  }
  g.textAlign = "right";
  g.fillText(label, box.x + box.w, box.y + box.h + 20);
}

function yTicks(g, box, ticks, toY, label) {
  g.fillStyle = "#333";
  g.strokeStyle = "#ccc";
  g.textAlign = "right";
  g.textBaseline = "middle";
  for (const [value, text] of ticks) {
    const y = Math.round(toY(value)) + 0.5;
    if (y < box.y - 1 || y > box.y + box.h + 1) continue;
    g.beginPath();
    g.moveTo(box.x - 4, y);
    g.lineTo(box.x, y);
    g.stroke();
    g.fillText(text, box.x - 6, y);
  }
  g.save();
  g.translate(13, box.y + box.h / 2);
  g.rotate(-Math.PI / 2);
  g.textAlign = "center";
  g.textBaseline = "middle";
  g.fillText(label, 0, 0);
  g.restore();
}

function timeTicks(duration, width) {
  const steps = [0.01, 0.02, 0.05, 0.1, 0.2, 0.25, 0.5, 1, 2, 5, 10];
  const step = steps.find((s) => duration / s <= Math.max(2, width / 70)) || 10;
  const ticks = [];
  for (let t = 0; t <= duration + 1e-9; t += step) ticks.push([t, Number(t.toFixed(3)).toString()]);
  return ticks;
}

function hzText(f) {
  if (f >= 1000) return `${Number((f / 1000).toPrecision(3))}k`;
  return `${Number(f.toPrecision(3))}`;
}

function logTicks(lo, hi) {
  const ticks = [];
  for (let decade = Math.pow(10, Math.floor(Math.log10(lo))); decade <= hi; decade *= 10) {
    for (const m of [1, 2, 5]) {
      const f = m * decade;
      if (f >= lo && f <= hi) ticks.push([f, hzText(f)]);
    }
  }
  return ticks;
}

function linearTicks(lo, hi, count) {
  const raw = (hi - lo) / count;
  const magnitude = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((m) => m * magnitude).find((s) => s >= raw);
  const ticks = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-9; v += step) ticks.push(v);
  return ticks;
}

function drawWaveform(data) {
  const canvas = $("waveform");
  const { g, box } = prepare(canvas);
  if (!data.waveform) {
    emptyPlot(g, box, "no waveform from this server (it has no /api/picture)");
    return;
  }
  const { min, max } = data.waveform;
  const duration = data.duration_s || PICTURE_S;
  const toY = (v) => box.y + box.h / 2 - (v * box.h) / 2;
  g.strokeStyle = "#eee";
  for (const v of [-0.5, 0, 0.5]) {
    g.beginPath();
    g.moveTo(box.x, Math.round(toY(v)) + 0.5);
    g.lineTo(box.x + box.w, Math.round(toY(v)) + 0.5);
    g.stroke();
  }
  g.fillStyle = "#1f5f9e";
  const n = min.length;
  const dx = box.w / n;
  for (let i = 0; i < n; i++) {
    const top = toY(Math.max(-1, Math.min(1, max[i])));
    const bottom = toY(Math.max(-1, Math.min(1, min[i])));
    g.fillRect(box.x + i * dx, top, Math.max(dx, 1), Math.max(1, bottom - top));
  }
  frame(g, box);
  xTicks(g, box, timeTicks(duration, box.w), (t) => box.x + (t / duration) * box.w, "time (s)");
  yTicks(g, box, [[-1, "-1"], [-0.5, "-0.5"], [0, "0"], [0.5, "0.5"], [1, "1"]], toY, "amplitude");
}

// A perceptual colour map ("magma"-like): floor dark, ceiling pale yellow.
const COLOURS = (() => {
  const stops = [[0, [0, 0, 4]], [0.13, [28, 16, 68]], [0.25, [79, 18, 123]], [0.38, [129, 37, 129]],
    [0.5, [181, 54, 122]], [0.63, [229, 80, 100]], [0.75, [251, 135, 97]], [0.88, [254, 194, 135]],
    [1, [252, 253, 191]]];
  const lut = new Uint8ClampedArray(256 * 3);
  for (let i = 0; i < 256; i++) {
    const u = i / 255;
    let k = 0;
    while (k < stops.length - 2 && u > stops[k + 1][0]) k++;
    const [u0, c0] = stops[k];
    const [u1, c1] = stops[k + 1];
    const t = (u - u0) / (u1 - u0);
    for (let j = 0; j < 3; j++) lut[i * 3 + j] = c0[j] + t * (c1[j] - c0[j]);
  }
  return lut;
})();

function decode(base64) {
  const text = atob(base64);
  const bytes = new Uint8Array(text.length);
  for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
  return bytes;
}

function drawSpectrogram(data) {
  const canvas = $("spectrogram");
  const bar = 54;  // the colour bar at the right
  const { g, box } = prepare(canvas, MARGIN.right + bar);
  const spec = data.spectrogram;
  if (!spec) {
    emptyPlot(g, box, "no spectrogram from this server (it has no /api/picture)");
    return;
  }
  const levels = decode(spec.levels);
  const bins = spec.bins;
  const times = spec.times_s;
  const T = times.length;
  const F = spec.max_frequency_hz;
  const duration = data.duration_s || (T ? times[T - 1] : PICTURE_S);
  const logAxis = $("spec-scale").value === "log";
  const logRows = spec.scale === "log";  // rows spaced evenly in log frequency from min_frequency_hz
  const fMin = logRows ? spec.min_frequency_hz : 0;
  const fLow = logRows ? fMin : Math.max(20, F / bins);
  const rowOf = logRows
    ? (f) => Math.floor((Math.log(Math.max(f, fMin) / fMin) / Math.log(F / fMin)) * bins)
    : (f) => Math.floor((f / F) * bins);  // row k: k F/bins to (k+1) F/bins
  const toY = logAxis
    ? (f) => box.y + box.h - (Math.log(f / fLow) / Math.log(F / fLow)) * box.h
    : (f) => box.y + box.h - (f / F) * box.h;
  const fromY = logAxis
    ? (py) => fLow * Math.pow(F / fLow, py / box.h)
    : (py) => (py / box.h) * F;

  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(box.w * dpr));
  const h = Math.max(1, Math.round(box.h * dpr));
  const image = g.createImageData(w, h);
  const rowOfY = new Int32Array(h);
  for (let y = 0; y < h; y++) {
    const f = fromY(((h - 1 - y) + 0.5) / dpr);
    rowOfY[y] = Math.min(bins - 1, Math.max(0, rowOf(f)));
  }
  const columnOfX = new Int32Array(w);
  const t0 = T ? times[0] : 0;
  const span = T > 1 ? times[T - 1] - t0 : 1;
  for (let x = 0; x < w; x++) {
    const t = ((x + 0.5) / w) * duration;
    columnOfX[x] = Math.min(T - 1, Math.max(0, Math.round(((t - t0) / span) * (T - 1))));
  }
  const pixels = image.data;
  for (let y = 0; y < h; y++) {
    const row = rowOfY[y] * T;
    for (let x = 0; x < w; x++) {
      const level = levels[row + columnOfX[x]];
      const p = (y * w + x) * 4;
      pixels[p] = COLOURS[level * 3];
      pixels[p + 1] = COLOURS[level * 3 + 1];
      pixels[p + 2] = COLOURS[level * 3 + 2];
      pixels[p + 3] = 255;
    }
  }
  g.putImageData(image, Math.round(box.x * dpr), Math.round(box.y * dpr));
  frame(g, box);
  xTicks(g, box, timeTicks(duration, box.w), (t) => box.x + (t / duration) * box.w, "time (s)");
  const fTicks = logAxis ? logTicks(fLow, F) : linearTicks(0, F, 6).map((f) => [f, hzText(f)]);
  yTicks(g, box, fTicks, toY, "frequency (Hz)");

  // colour bar: floor to ceiling in dB
  const cx = box.x + box.w + 12;
  const cw = 12;
  for (let i = 0; i < box.h; i++) {
    const level = Math.round(255 * (1 - i / box.h));
    g.fillStyle = `rgb(${COLOURS[level * 3]},${COLOURS[level * 3 + 1]},${COLOURS[level * 3 + 2]})`;
    g.fillRect(cx, box.y + i, cw, 1.5);
  }
  g.strokeStyle = "#888";
  g.strokeRect(cx + 0.5, box.y + 0.5, cw, box.h);
  g.fillStyle = "#333";
  g.textAlign = "left";
  g.textBaseline = "middle";
  const floor = spec.floor_db;
  const ceiling = spec.ceiling_db;
  for (const db of linearTicks(floor, ceiling, 4)) {
    g.fillText(`${db}`, cx + cw + 4, box.y + box.h * (1 - (db - floor) / (ceiling - floor)));
  }
  g.textBaseline = "top";
  g.fillText("dB", cx, box.y + box.h + 6);
}

function groupColours(modes) {
  const colours = new Map();
  for (const m of modes) {
    if (!colours.has(m.group)) colours.set(m.group, GROUP_COLOURS[colours.size % GROUP_COLOURS.length]);
  }
  return colours;
}

function levelDb(gain, loudest) {
  return loudest > 0 && gain !== 0 ? 20 * Math.log10(Math.abs(gain) / loudest) : -Infinity;
}

function drawModes(modes) {
  const canvas = $("modes");
  const colours = groupColours(modes);
  const counts = {};
  for (const m of modes) counts[m.group] = (counts[m.group] || 0) + 1;
  const lines = [...colours.keys()].map((group) => `${group} (${counts[group]})`);
  if (lines.length) lines.push("marker size: T60");
  const measure = canvas.getContext("2d");
  measure.font = "11px system-ui, sans-serif";
  const lw = lines.length ? Math.max(...lines.map((t) => measure.measureText(t).width)) + 32 : 0;
  const { g, box } = prepare(canvas, MARGIN.right + lw + (lw ? 10 : 0));
  const shown = modes.filter((m) => m.frequency_hz > 0 && Number.isFinite(m.frequency_hz));
  if (!shown.length) {
    emptyPlot(g, box, "no modes");
    return;
  }
  const loudest = Math.max(...modes.map((m) => Math.abs(m.gain)));
  let lo = Math.min(...shown.map((m) => m.frequency_hz)) / 1.5;
  let hi = Math.max(...shown.map((m) => m.frequency_hz)) * 1.5;
  if (hi / lo < 10) {
    const mid = Math.sqrt(hi * lo);
    lo = mid / Math.sqrt(10);
    hi = mid * Math.sqrt(10);
  }
  const FLOOR = -60;
  const toX = (f) => box.x + (Math.log(f / lo) / Math.log(hi / lo)) * box.w;
  const top = 9;  // room above 0 dB for the largest marker
  const toY = (db) => box.y + top + (db / FLOOR) * (box.h - top);
  g.strokeStyle = "#eee";
  for (const db of [-10, -20, -30, -40, -50]) {
    g.beginPath();
    g.moveTo(box.x, Math.round(toY(db)) + 0.5);
    g.lineTo(box.x + box.w, Math.round(toY(db)) + 0.5);
    g.stroke();
  }
  for (const m of shown) {
    const db = levelDb(m.gain, loudest);
    const below = !(db >= FLOOR);
    const x = toX(m.frequency_hz);
    const y = toY(below ? FLOOR : db);
    const colour = colours.get(m.group);
    g.strokeStyle = colour;
    g.lineWidth = 1.5;
    g.beginPath();
    g.moveTo(x, box.y + box.h);
    g.lineTo(x, y);
    g.stroke();
    const t60 = Number.isFinite(m.t60_s) ? m.t60_s : 0;
    const r = Math.min(10, 2.5 + 2.5 * Math.log10(1 + 20 * t60));
    g.beginPath();
    g.arc(x, y, r, 0, 2 * Math.PI);
    if (below) {
      g.fillStyle = "#fff";
      g.fill();
      g.stroke();
    } else {
      g.fillStyle = colour;
      g.globalAlpha = 0.75;
      g.fill();
      g.globalAlpha = 1;
    }
  }
  g.lineWidth = 1;
  frame(g, box);
  xTicks(g, box, logTicks(lo, hi), toX, "frequency (Hz)");
  yTicks(g, box, [0, -10, -20, -30, -40, -50, -60].map((db) => [db, `${db}`]), toY, "gain (dB)");

  // legend, right of the plot
  const entries = [...colours.entries()];
  const lh = 16 * lines.length + 8;
  const lx = box.x + box.w + 10;
  const ly = box.y;
  g.fillStyle = "#fff";
  g.fillRect(lx, ly, lw, lh);
  g.strokeStyle = "#bbb";
  g.strokeRect(lx + 0.5, ly + 0.5, lw, lh);
  g.textAlign = "left";
  g.textBaseline = "middle";
  lines.forEach((text, i) => {
    const y = ly + 12 + 16 * i;
    if (i < entries.length) {
      g.fillStyle = entries[i][1];
      g.fillRect(lx + 8, y - 5, 12, 10);
    } else {
      g.strokeStyle = "#555";
      for (const [dx, r] of [[10, 2.5], [17, 4.5]]) {
        g.beginPath();
        g.arc(lx + dx, y, r, 0, 2 * Math.PI);
        g.stroke();
      }
    }
    g.fillStyle = "#222";
    g.fillText(text, lx + 25, y);
  });
}

function cell(text, cls) {
  return element("td", cls ? { class: cls } : {}, text);
}

function fillTable(modes) {
  const table = $("mode-table");
  const withErrors = modes.some((m) => m.error_cents !== undefined);
  const heads = ["#", "group", "frequency (Hz)", "gain", "level (dB)", "T60 (s)"];
  if (withErrors) heads.push("error (cents)");
  table.tHead.replaceChildren(element("tr", {}, ...heads.map((h) => element("th", { scope: "col" }, h))));
  const colours = groupColours(modes);
  const loudest = Math.max(0, ...modes.map((m) => Math.abs(m.gain)));
  const rows = modes.map((m, i) => {
    const swatch = element("span", { class: "swatch" });
    swatch.style.background = colours.get(m.group);
    const db = levelDb(m.gain, loudest);
    const cells = [
      cell(String(i + 1), "n"),
      element("td", { class: "group" }, swatch, m.group),
      cell(m.frequency_hz === null ? "-" : m.frequency_hz.toFixed(m.frequency_hz < 100 ? 2 : 1), "n"),
      cell(m.gain === null ? "-" : Number(m.gain.toPrecision(3)).toString(), "n"),
      cell(Number.isFinite(db) ? db.toFixed(1) : "-inf", "n"),
      cell(m.t60_s === null ? "-" : Number(m.t60_s.toPrecision(3)).toString(), "n"),
    ];
    if (withErrors) {
      cells.push(cell(m.error_cents === undefined || m.error_cents === null ? "" : m.error_cents.toFixed(2), "n"));
    }
    return element("tr", {}, ...cells);
  });
  table.tBodies[0].replaceChildren(...rows);
  table.caption.textContent = `${modes.length} modes of ${model.name}` +
    (colours.size > 1 ? ` in ${colours.size} groups` : "");
}

// --- files and links ---------------------------------------------------------------------------

function save(blob, filename) {
  const url = URL.createObjectURL(blob);
  const link = $("saver");
  link.href = url;
  link.download = filename;
  link.click();
  setTimeout(() => URL.revokeObjectURL(url), 60000);
}

async function busy(button, work) {
  button.disabled = true;
  try {
    await work();
  } catch (err) {
    failed(err);
  } finally {
    button.disabled = false;
  }
}

function download() {
  const name = model.name;
  const text = $("duration").value.trim();
  const duration = text !== "" && Number.isFinite(Number(text)) ? Number(text) : text;
  return busy($("download"), async () => {
    const blob = await api("POST", "/api/render",
      { model: name, parameters: { ...values }, duration_s: duration, sample_rate: RATE }, true);
    clearMessage();
    save(blob, `${name}.wav`);
  });
}

function savePreset() {
  const name = model.name;
  const description = $("description").value.trim() || `${name} settings`;
  return busy($("save-preset"), async () => {
    const blob = await api("POST", "/api/preset-file", { model: name, parameters: { ...values }, description }, true);
    clearMessage();
    save(blob, `${name}.toml`);
  });
}

function valueText(v) {
  if (Array.isArray(v)) return listText(v);
  return String(v);
}

function shareUrl() {
  const query = new URLSearchParams();
  query.set("model", model.name);
  if (studio.preset) query.set("preset", studio.preset);
  for (const row of model.parameters) {
    if (!same(values[row.name], base[row.name])) query.set(row.name, valueText(values[row.name]));
  }
  return `${location.origin}${location.pathname}?${query}`;
}

async function share() {
  const url = shareUrl();
  history.replaceState(null, "", url);
  const field = $("share-url");
  field.value = url;
  field.select();
  try {
    await navigator.clipboard.writeText(url);
    field.title = "copied to the clipboard";
  } catch (err) {
    field.title = "select and copy this link (the browser did not allow copying)";
  }
}

// --- keys and start-up --------------------------------------------------------------------

function onKey(event) {
  if (event.ctrlKey || event.metaKey || event.altKey || event.repeat) return;
  const target = event.target;
  const tag = target.tagName;
  const typing = tag === "TEXTAREA" || tag === "SELECT" ||
    (tag === "INPUT" && !["range", "checkbox", "button", "radio"].includes(target.type));
  if (event.key === "Escape") {
    stop();
    return;
  }
  if (typing) return;
  const key = event.key.toLowerCase();
  if (key === " " && (tag === "BUTTON" || target.type === "checkbox")) return;  // their own action
  if (key === " " || key === "t") {
    event.preventDefault();
    trigger();
  } else if (key === "r") {
    release();
  } else if (key === "s") {
    stop();
  }
}

async function init() {
  $("play").addEventListener("click", play);
  $("trigger").addEventListener("click", trigger);
  $("release").addEventListener("click", release);
  $("stop").addEventListener("click", stop);
  $("download").addEventListener("click", download);
  $("save-preset").addEventListener("click", savePreset);
  $("share").addEventListener("click", share);
  $("controls").addEventListener("submit", (event) => event.preventDefault());
  $("volume").addEventListener("input", () => {
    if (live.gain) live.gain.gain.setTargetAtTime(volume(), live.ctx.currentTime, 0.01);
  });
  $("model").addEventListener("change", () => chooseModel($("model").value).catch(failed));
  $("preset").addEventListener("change", () => {
    clearMessage();
    choosePreset($("preset").value).catch(failed);
  });
  $("spec-scale").addEventListener("change", () => { if (pictures.data) drawSpectrogram(pictures.data); });
  document.addEventListener("keydown", onKey);
  let width = $("waveform").clientWidth;
  window.addEventListener("resize", () => {
    if (!pictures.data) return;
    drawAll(pictures.data);
    if (Math.abs($("waveform").clientWidth - width) > 40) {
      width = $("waveform").clientWidth;
      schedulePicture();
    }
  });
  setInterval(updateLive, 250);

  let data;
  try {
    data = await api("GET", "/api/models");
  } catch (err) {
    failed(err);
    return;
  }
  models = new Map(data.models.map((m) => [m.name, m]));
  $("model").replaceChildren(...data.models.map((m) => element("option", { value: m.name }, m.name)));
  const query = new URLSearchParams(location.search);
  const wanted = query.get("model");
  if (wanted && !models.has(wanted)) {
    showMessage(`unknown model '${wanted}' in the link; available: ${[...models.keys()].join(", ")}`);
  }
  const name = models.has(wanted) ? wanted : data.models[0].name;
  await chooseModel(name, { preset: query.get("preset"), overrides: models.has(wanted) ? query : null });
  studio.ready = true;
}

init();
