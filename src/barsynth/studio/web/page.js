// barsynth studio: what every module of the page shares (docs/studio.md is the page's spec):
// the element helpers, the state of the page, messages and the server's API.
//
// For tests, window.studio holds live figures: state ("idle" | "playing"), blocksReceived,
// samplesPlayed, maxBufferedFrames, underruns and dropouts, latencies (ms from a change being
// sent to its first sample leaving the speakers) and changeLatencies (from the change being
// made: a set may wait for the one before it), sets, lastSet ({id, parameters} of the last set
// sent), heardSetId, setsWaiting, playedReports (sent to the server, heartbeats too), streams
// (sockets opened) and closes (closed by the server or the network), lastPicture and errors;
// also inactive (the names of the controls greyed out because they have no effect now) and fit
// (the last fit of a recording and its A/B player: see fit.js), keys (the notes played: see keys.js)
// and liveSamples(count) (the newest samples the worklet played: see live.js); draws (Randomize
// and Mutate answered) and lastDraw ({mode, seed, spread, rejected}: see variations.js), history
// ({undo, redo}: steps that can be undone and redone) and ab ({a, b, showing}: whether each
// snapshot holds settings, and which one the settings are now: "a", "b" or ""; see history.js).

export const $ = (id) => document.getElementById(id);

export const RATE = 48000;  // pictures and WAV files; the live stream uses the AudioContext's rate

export const studio = {
  ready: false,
  state: "idle",
  model: null,
  preset: "",
  values: {},
  inactive: [],
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
  draws: 0,
  lastDraw: null,
  history: { undo: 0, redo: 0 },
  ab: { a: false, b: false, showing: "" },
  fit: { state: "idle", fits: 0, result: null, playing: null, plays: { recording: 0, resynthesis: 0 },
    heardPeak: { recording: 0, resynthesis: 0 } },
};
window.studio = studio;

// What the page is showing; the modules change these fields (never the object itself).
export const current = {
  models: new Map(),  // name -> {name, summary, parameters: [rows], presets: [names]}
  model: null,  // the chosen model's entry
  base: {},  // the chosen preset's values (or the table's defaults): what a link leaves out
  values: {},  // the current, accepted values
  fitted: null,  // the last fit's settings: {model, values, label, description} (fit.js)
  draw: null,  // the last Randomize or Mutate: {mode, seed, spread, from, result} (variations.js)
};

// The words of a link that are not parameters: the model, the preset, and a draw (variations.js).
export const LINK_WORDS = new Set(["model", "preset", "random", "mutate", "spread"]);

// --- messages and the server ---------------------------------------------------------------

export function showMessage(text) {
  const box = $("message");
  box.textContent = text;
  box.hidden = false;
  studio.errors.push(text);
}

export function clearMessage() {
  $("message").hidden = true;
  $("message").textContent = "";
}

export function note(text) {
  $("live").textContent = text;
}

export class ApiError extends Error {
  constructor(status, message, data) { super(message); this.status = status; this.data = data; }
}

// JSON in; JSON (or, with asBlob, a Blob) out; an ApiError with the server's one line otherwise.
export async function api(method, path, payload, asBlob = false) {
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

export function failed(err) {
  showMessage(err instanceof ApiError ? err.message : `Something went wrong: ${err.message || err}`);
}

// Whether a key press is typing into a box (keys then are text, not commands); with sliders,
// moving a focused slider counts too (the note keys leave a slider its arrows and letters).
export function typing(event, { sliders = false } = {}) {
  const target = event.target;
  const tag = target.tagName;
  if (target.isContentEditable || tag === "TEXTAREA" || tag === "SELECT") return true;
  return tag === "INPUT" && (sliders || target.type !== "range") &&
    !["checkbox", "button", "radio", "file"].includes(target.type);
}

// --- values and elements ---------------------------------------------------------------------

export function fmt(v) {
  if (typeof v !== "number") return String(v);
  if (!Number.isFinite(v) || v === 0) return String(v);
  const a = Math.abs(v);
  if (a >= 1e5 || a < 1e-3) return v.toExponential(3).replace(/\.?0+e/, "e").replace("e+", "e");
  return String(Number(v.toPrecision(4)));
}

export function listText(list) {
  return list.map((x) => String(x)).join(",");
}

// Whether two values are the same setting (numbers within rounding, lists item by item).
export function same(a, b) {
  if (Array.isArray(a) || Array.isArray(b)) {
    return Array.isArray(a) && Array.isArray(b) && a.length === b.length && a.every((x, i) => same(x, b[i]));
  }
  if (typeof a === "number" && typeof b === "number") {
    return a === b || Math.abs(a - b) <= 1e-12 * Math.max(Math.abs(a), Math.abs(b));
  }
  return a === b;
}

export function element(tag, props = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(props)) {
    if (k === "class") node.className = v;
    else if (k in node) node[k] = v;
    else node.setAttribute(k, v);
  }
  node.append(...children);
  return node;
}
