// barsynth studio: the pictures of the current settings (POST /api/picture, or the modes only
// from POST /api/describe on a server without pictures): waveform, spectrogram, modes and the
// mode table, drawn on canvases. fit.js paints its two spectrograms with paintSpectrogram.

import { $, RATE, api, current, element, failed, studio } from "./page.js";

const PICTURE_S = 1.5;
const PICTURE_DELAY_MS = 150;
const GROUP_COLOURS = ["#1f6fb4", "#d9730d", "#2f9e44", "#c2255c", "#7048e8", "#0c8599", "#a61e4d", "#5c940d"];

const pictures = { timer: 0, busy: false, again: false, api: "picture", data: null };

export function schedulePicture(delay = PICTURE_DELAY_MS) {
  clearTimeout(pictures.timer);
  pictures.timer = setTimeout(updatePictures, delay);
}

async function updatePictures() {
  if (pictures.busy) {
    pictures.again = true;
    return;
  }
  pictures.busy = true;
  const asked = { model: current.model.name, parameters: { ...current.values } };
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
    if (data && data.model === current.model.name) {
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

export function hash(text) {  // FNV-1a, 32 bits, hex
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

export function plotWidth(canvas) {
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
  const spec = data.spectrogram;
  const T = spec ? spec.times_s.length : 0;
  const duration = data.duration_s || (T ? spec.times_s[T - 1] : PICTURE_S);
  paintSpectrogram($("spectrogram"), spec, duration, { empty: "no spectrogram from this server (it has no /api/picture)" });
}

// A spectrogram as /api/picture (and /api/fit) sends it, on a canvas: time across, frequency up
// (log or linear, as the page's "frequency axis" says), the levels in colour with a colour bar
// (unless colourBar is false). marks: [{frequency_hz, dashed}] drawn as lines across (the
// partials of a fit: dashed where the resynthesis has the partial, dotted where it lacks it).
export function paintSpectrogram(canvas, spec, duration, { colourBar = true, marks = [], empty = "no spectrogram" } = {}) {
  const bar = colourBar ? 54 : 0;  // the colour bar at the right
  const { g, box } = prepare(canvas, MARGIN.right + bar);
  if (!spec) {
    emptyPlot(g, box, empty);
    return;
  }
  const levels = decode(spec.levels);
  const bins = spec.bins;
  const times = spec.times_s;
  const T = times.length;
  const F = spec.max_frequency_hz;
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
  g.save();
  g.strokeStyle = "#3fe0ff";
  g.lineWidth = 1;
  for (const mark of marks) {
    const f = mark.frequency_hz;
    if (!(f >= fLow && f <= F)) continue;
    const y = Math.round(toY(f)) + 0.5;
    g.setLineDash(mark.dashed ? [6, 4] : [1, 3]);
    g.beginPath();
    g.moveTo(box.x, y);
    g.lineTo(box.x + box.w, y);
    g.stroke();
  }
  g.restore();
  frame(g, box);
  xTicks(g, box, timeTicks(duration, box.w), (t) => box.x + (t / duration) * box.w, "time (s)");
  const fTicks = logAxis ? logTicks(fLow, F) : linearTicks(0, F, 6).map((f) => [f, hzText(f)]);
  yTicks(g, box, fTicks, toY, "frequency (Hz)");
  if (!colourBar) return;

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
  table.caption.textContent = `${modes.length} modes of ${current.model.name}` +
    (colours.size > 1 ? ` in ${colours.size} groups` : "");
}

// The spectrogram's frequency axis changed: redraw it.
export function redrawSpectrogram() {
  if (pictures.data) drawSpectrogram(pictures.data);
}

// A resized window: redraw at the new size, and ask for new pictures when the plots are much
// wider or narrower than those asked for.
export function followSize() {
  let width = $("waveform").clientWidth;
  window.addEventListener("resize", () => {
    if (!pictures.data) return;
    drawAll(pictures.data);
    if (Math.abs($("waveform").clientWidth - width) > 40) {
      width = $("waveform").clientWidth;
      schedulePicture();
    }
  });
}
