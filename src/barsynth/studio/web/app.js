// barsynth studio: the page (ES modules, no build step, no libraries; docs/studio.md is its spec).
//
// The controls are generated from each model's parameter table (GET /api/models; controls.js).
// The server runs the model: the live sound comes over the WebSocket /api/stream, which a
// Worker owns (link.js), and is played by an AudioWorklet (worklet.js) fed by that worker
// directly, not through this thread (live.js); the pictures (POST /api/picture; plots.js), WAV
// files, mode tables and preset files (files.js) come over HTTP. Every value is checked by the
// server, whose one-line message is shown as it is. page.js holds what they share, among it
// window.studio, the figures the tests read. A recording dropped on the page (or opened) is fitted
// and played against its resynthesis by fit.js; notes come from the computer keyboard, the
// on-screen keyboard and a MIDI device (keys.js). This module wires them together and starts the page.

import { onChange } from "./controls.js";
import { chooseModel, choosePreset, download, savePreset, share } from "./files.js";
import { play, queueSet, release, setVolume, stop, trigger, updateLive } from "./live.js";
import { startFitting } from "./fit.js";
import { newHistory, record, recall, redo, store, swap, undo } from "./history.js";
import { keyDown, startKeys } from "./keys.js";
import { $, api, clearMessage, current, element, failed, showMessage, studio, typing } from "./page.js";
import { followSize, redrawSpectrogram, schedulePicture } from "./plots.js";
import { draw, linkedDraw, startVariations } from "./variations.js";

// Keys: space or t strikes, r releases a bow stroke, s or Escape stops, x switches between the
// A and B snapshots, Ctrl+Z undoes and Ctrl+Shift+Z (or Ctrl+Y) redoes (not while typing in a
// box); while the keys play notes (k), their letters are notes (keys.js).
function onKey(event) {
  if (keyDown(event)) return;
  if ((event.ctrlKey || event.metaKey) && !event.altKey && !typing(event)) {
    const key = event.key.toLowerCase();
    if (key === "z" || key === "y") {
      event.preventDefault();
      if (key === "z" && !event.shiftKey) undo();
      else redo();
    }
    return;
  }
  if (event.ctrlKey || event.metaKey || event.altKey || event.repeat) return;
  const target = event.target;
  const tag = target.tagName;
  if (event.key === "Escape") {
    stop();
    return;
  }
  if (typing(event)) return;
  const key = event.key.toLowerCase();
  if (key === " " && (tag === "BUTTON" || target.type === "checkbox")) return;  // their own action
  if (key === " " || key === "t") {
    event.preventDefault();
    trigger();
  } else if (key === "r") {
    release();
  } else if (key === "s") {
    stop();
  } else if (key === "x") {
    swap();
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
  $("volume").addEventListener("input", setVolume);
  $("model").addEventListener("change", () => chooseModel($("model").value).catch(failed));
  $("preset").addEventListener("change", () => {
    clearMessage();
    choosePreset($("preset").value).catch(failed).then(record);
  });
  $("controls").addEventListener("change", record);  // a control settled (a slider let go): one step
  startVariations();
  $("undo").addEventListener("click", undo);
  $("redo").addEventListener("click", redo);
  for (const key of ["a", "b"]) {
    $(`store-${key}`).addEventListener("click", () => store(key));
    $(`recall-${key}`).addEventListener("click", () => recall(key));
  }
  $("swap-ab").addEventListener("click", swap);
  $("spec-scale").addEventListener("change", redrawSpectrogram);
  document.addEventListener("keydown", onKey);
  startKeys();
  followSize();
  onChange((name, v) => {  // a control's change: to the live sound, and new pictures
    queueSet(name, v);
    schedulePicture();
  });
  setInterval(updateLive, 250);

  let data;
  try {
    data = await api("GET", "/api/models");
  } catch (err) {
    failed(err);
    return;
  }
  const models = new Map(data.models.map((m) => [m.name, m]));
  current.models = models;
  startFitting(data.fit);
  $("model").replaceChildren(...data.models.map((m) => element("option", { value: m.name }, m.name)));
  const query = new URLSearchParams(location.search);
  const wanted = query.get("model");
  if (wanted && !models.has(wanted)) {
    showMessage(`unknown model '${wanted}' in the link; available: ${[...models.keys()].join(", ")}`);
  }
  const name = models.has(wanted) ? wanted : data.models[0].name;
  await chooseModel(name, { preset: query.get("preset"), overrides: models.has(wanted) ? query : null });
  const drawn = models.has(wanted) ? linkedDraw(query) : null;  // random=SEED or mutate=SEED&spread=S
  if (drawn) await draw(drawn.mode, drawn.seed, drawn.spread, { step: false });
  newHistory();
  studio.ready = true;
}

init();
