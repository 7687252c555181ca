// barsynth studio: a recording fitted (docs/studio.md, "Fitting a recording").
//
// Drop a WAV, FLAC or OGG file anywhere on the page (or open one with the button, from the
// keyboard too): its bytes go to POST /api/fit with the model to fit, the server fits it in a
// worker and answers the fitted settings, the fit's report and both sounds with their
// spectrograms. The page then chooses the fitted model with those settings, as it chooses a
// preset (the preset list gets a "(fitted: FILE)" entry, so they can be had back), and shows the
// A/B player: the recording and the resynthesis (a and b on the keyboard), their spectrograms side
// by side on the same axes and levels with the recording's partials marked, each partial's
// error and the spectral distance against one decaying sine. The live sound plays the fitted
// settings (banded's recorded attack too), so the note can be played at other pitches.
//
// The A/B player is Web Audio (an AudioBufferSourceNode per press, through an AnalyserNode that
// tells window.studio.fit.heardPeak what reached the output): the page's Content-Security-Policy
// allows no blob: or data: media for an <audio> element.
//
// window.studio.fit: {state: "idle" | "fitting" | "done" | "failed", fits, result: {model, file,
// frequencyHz, partials, distanceDb, baselineDb, spectrogramHashes}, playing: null | "recording" |
// "resynthesis", plays: {recording, resynthesis}, heardPeak: {recording, resynthesis}}.

import { FITTED, chooseModel } from "./files.js";
import { stop as stopLive } from "./live.js";
import { $, ApiError, clearMessage, current, element, failed, fmt, showMessage, studio, typing } from "./page.js";
import { hash, paintSpectrogram, plotWidth } from "./plots.js";

const SOUNDS = ["recording", "resynthesis"];
const fit = {
  limits: { models: ["banded", "twang", "fd"], max_upload_bytes: 20 * 1024 * 1024, max_upload_s: 30 },
  data: null,  // the server's last answer
  buffers: {},  // decoded AudioBuffers of data's two sounds
  ctx: null,
  analyser: null,
  source: null,
  watch: 0,
  aborter: null,
  ticker: 0,
};

// --- the upload --------------------------------------------------------------------------------

function status(text) {
  $("fit-status").textContent = text;
}

function sizeText(bytes) {  // MB of 2^20 bytes, as the limit is given
  return bytes >= 1048576 ? `${Number((bytes / 1048576).toFixed(1))} MB` : `${Math.max(1, Math.round(bytes / 1024))} kB`;
}

// Send a file to be fitted; a new one stops the one under way (the server stops its job).
export async function fitFile(file) {
  if (!file) return;
  clearMessage();
  if (file.size > fit.limits.max_upload_bytes) {
    showMessage(`audio file ${file.name}: is ${sizeText(file.size)}; allowed: up to ` +
      `${fit.limits.max_upload_bytes} bytes (${fit.limits.max_upload_s} s of sound)`);
    studio.fit.state = "failed";
    return;
  }
  if (fit.aborter) fit.aborter.abort();
  const aborter = new AbortController();
  fit.aborter = aborter;
  const model = $("fit-model").value;
  const query = new URLSearchParams({ model, name: file.name || "upload",
    width: String(plotWidth($("fit-spec-recording"))) });
  studio.fit.state = "fitting";
  $("fit-cancel").hidden = false;
  const began = performance.now();
  const tick = () => status(`fitting ${model} to ${file.name} (${sizeText(file.size)})... ` +
    `${Math.round((performance.now() - began) / 1000)} s`);
  tick();
  clearInterval(fit.ticker);
  fit.ticker = setInterval(tick, 1000);
  let data;
  try {
    let response;
    try {
      response = await fetch(`/api/fit?${query}`, { method: "POST", body: file, signal: aborter.signal,
        headers: { "Content-Type": file.type || "application/octet-stream" } });
    } catch (err) {
      if (aborter.signal.aborted) throw err;
      throw new ApiError(0, "The studio server cannot be reached; is `barsynth studio` still running?");
    }
    if (!response.ok) {
      let answer = null;
      try { answer = await response.json(); } catch (err) { answer = null; }
      throw new ApiError(response.status, (answer && answer.error) ||
        `The server answered ${response.status} ${response.statusText}.`);
    }
    data = await response.json();
  } catch (err) {
    if (fit.aborter !== aborter) return;  // a newer file took over
    finish();
    if (aborter.signal.aborted) {
      status("fit cancelled");
      studio.fit.state = "idle";
      return;
    }
    failed(err);
    status(`no fit: ${err.message || err}`);
    studio.fit.state = "failed";
    return;
  }
  if (fit.aborter !== aborter) return;
  finish();
  await show(data, file.name);
}

function finish() {
  clearInterval(fit.ticker);
  fit.aborter = null;
  $("fit-cancel").hidden = true;
}

function cancel() {
  if (fit.aborter) fit.aborter.abort();
}

// --- the answer --------------------------------------------------------------------------------

async function show(data, fileName) {
  stopSound();
  fit.data = data;
  fit.buffers = {};
  const report = data.fit;
  current.fitted = { model: data.model, values: data.parameters, label: `(fitted: ${fileName})`.slice(0, 60),
    description: data.description };
  await chooseModel(data.model, { preset: FITTED });  // the sliders show the fit; the live sound plays it
  $("fit-result").hidden = false;
  $("fit-title").textContent = `${data.model} fitted to ${data.file}`;
  $("fit-distance").textContent = `spectral distance ${report.spectral_distance_db.toFixed(2)} dB; ` +
    `one decaying sine at f0 (${fmt(report.f0_hz)} Hz): ${report.sine_baseline_db.toFixed(2)} dB ` +
    "(lower is closer). The recording's partials are marked: dashed, dotted where the fit lacks one";
  drawPair();
  fillTable(report.partials, data.file);
  const matched = report.partials.filter((p) => p.resynthesis_hz !== null).length;
  status(`fitted: ${report.partials.length} partials (${matched} in the resynthesis); play them with a and b`);
  studio.fit.fits += 1;
  studio.fit.state = "done";
  studio.fit.result = {
    model: data.model, file: data.file, frequencyHz: data.parameters.frequency_hz ?? null,
    partials: report.partials.length, distanceDb: report.spectral_distance_db, baselineDb: report.sine_baseline_db,
    spectrogramHashes: SOUNDS.map((k) => hash(data[k].spectrogram.levels)),
  };
  $("fit-result").scrollIntoView({ block: "nearest" });
}

function drawPair() {
  const data = fit.data;
  if (!data) return;
  const marks = data.fit.partials.map((p) => ({ frequency_hz: p.frequency_hz, dashed: p.resynthesis_hz !== null }));
  for (const key of SOUNDS) {
    paintSpectrogram($(`fit-spec-${key}`), data[key].spectrogram, data.duration_s, { marks });
  }
}

function number(v, digits) {
  return v === null || v === undefined ? "-" : v.toFixed(digits);
}

function signed(v, digits) {
  if (v === null || v === undefined) return "-";
  const text = Math.abs(v).toFixed(digits);
  return Number(text) === 0 ? text : `${v > 0 ? "+" : "-"}${text}`;
}

function fillTable(partials, fileName) {
  const rows = partials.map((p, i) => element("tr", {},
    ...[String(i + 1), number(p.frequency_hz, 2), number(p.level_db, 1), number(p.t60_s, 3),
      number(p.resynthesis_hz, 2), signed(p.cents, 1), signed(p.level_error_db, 1),
      signed(p.t60_error_percent, 1)].map((text) => element("td", { class: "n" }, text))));
  $("fit-table").tBodies[0].replaceChildren(...rows);
  $("fit-table").caption.textContent = `${partials.length} partials of ${fileName}: the recording, and the ` +
    "resynthesis against it";
}

// --- the A/B player ----------------------------------------------------------------------------

function decode(base64) {
  const text = atob(base64);
  const bytes = new Uint8Array(text.length);
  for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
  return bytes.buffer;
}

async function audio() {
  if (!fit.ctx) {
    fit.ctx = new AudioContext();
    fit.analyser = fit.ctx.createAnalyser();
    fit.analyser.fftSize = 2048;
    fit.analyser.connect(fit.ctx.destination);
  }
  if (fit.ctx.state !== "running") await fit.ctx.resume();
  return fit.ctx;
}

// Play the recording or the resynthesis from its start (the other, and the live sound, stop).
export async function playSound(key) {
  const data = fit.data;
  if (!data) return;
  let ctx;
  try {
    ctx = await audio();
    if (!fit.buffers[key]) fit.buffers[key] = await ctx.decodeAudioData(decode(data[key].wav));
  } catch (err) {
    showMessage(`This browser cannot play the ${key}: ${err.message || err}`);
    return;
  }
  if (fit.data !== data) return;
  stopLive();
  stopSound();
  const source = ctx.createBufferSource();
  source.buffer = fit.buffers[key];
  source.connect(fit.analyser);
  source.onended = () => {
    if (fit.source === source) stopSound();
  };
  fit.source = source;
  studio.fit.playing = key;
  studio.fit.plays[key] += 1;
  for (const k of SOUNDS) $(`play-${k}`).classList.toggle("on", k === key);
  source.start();
  const samples = new Float32Array(fit.analyser.fftSize);
  clearInterval(fit.watch);
  fit.watch = setInterval(() => {  // what reaches the output, for the eye (and the tests)
    fit.analyser.getFloatTimeDomainData(samples);
    let peak = 0;
    for (const v of samples) peak = Math.max(peak, Math.abs(v));
    studio.fit.heardPeak[key] = Math.max(studio.fit.heardPeak[key], peak);
  }, 40);
}

export function stopSound() {
  clearInterval(fit.watch);
  const source = fit.source;
  fit.source = null;
  studio.fit.playing = null;
  for (const k of SOUNDS) $(`play-${k}`).classList.remove("on");
  if (source) {
    source.onended = null;
    try { source.stop(); } catch (err) { /* ended already */ }
  }
}

// --- the page's side ---------------------------------------------------------------------------

function onKey(event) {
  if (event.ctrlKey || event.metaKey || event.altKey || event.repeat || typing(event)) return;
  if (event.key === "Escape") {
    stopSound();
    return;
  }
  if (!fit.data || $("fit-result").hidden) return;
  const key = event.key.toLowerCase();
  if (key === "a") playSound("recording");
  else if (key === "b") playSound("resynthesis");
}

// Whether a drag carries files (not text or a link dragged about the page).
const carriesFiles = (event) => event.dataTransfer && [...event.dataTransfer.types].includes("Files");

function wireDrop() {
  let depth = 0;  // dragenter/dragleave come for every element crossed
  document.addEventListener("dragenter", (event) => {
    if (!carriesFiles(event)) return;
    event.preventDefault();
    depth += 1;
    document.body.classList.add("dropping");
  });
  document.addEventListener("dragleave", (event) => {
    if (!carriesFiles(event)) return;
    depth = Math.max(0, depth - 1);
    if (depth === 0) document.body.classList.remove("dropping");
  });
  document.addEventListener("dragover", (event) => {
    if (!carriesFiles(event)) return;
    event.preventDefault();  // else the browser opens the file instead
    event.dataTransfer.dropEffect = "copy";
  });
  document.addEventListener("drop", (event) => {
    if (!carriesFiles(event)) return;
    event.preventDefault();
    depth = 0;
    document.body.classList.remove("dropping");
    const file = event.dataTransfer.files[0];
    if (file) fitFile(file).catch(failed);
  });
}

// Wire the fit's controls; limits: the server's (GET /api/models: "fit").
export function startFitting(limits) {
  if (limits) fit.limits = limits;
  $("fit-model").replaceChildren(...fit.limits.models.map((m) => element("option", { value: m }, m)));
  $("fit-limits").textContent = `WAV, FLAC or OGG, up to ${fit.limits.max_upload_s} s and ` +
    `${sizeText(fit.limits.max_upload_bytes)}`;
  $("fit-choose").addEventListener("click", () => $("fit-file").click());
  $("fit-file").addEventListener("change", () => {
    const file = $("fit-file").files[0];
    $("fit-file").value = "";  // the same file again is a new choice
    fitFile(file).catch(failed);
  });
  $("fit-cancel").addEventListener("click", cancel);
  for (const key of SOUNDS) $(`play-${key}`).addEventListener("click", () => playSound(key));
  $("ab-stop").addEventListener("click", stopSound);
  $("play").addEventListener("click", stopSound);  // the live sound and the A/B player take turns
  $("fit-close").addEventListener("click", () => {
    stopSound();
    $("fit-result").hidden = true;
  });
  $("spec-scale").addEventListener("change", drawPair);
  window.addEventListener("resize", drawPair);
  document.addEventListener("keydown", onKey);
  wireDrop();
}
