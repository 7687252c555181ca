// barsynth studio: undo and redo of the settings, and the A/B snapshots (docs/studio.md).
//
// A step is one settled change of the settings: a slider dragged (from press to release), a
// value typed, a choice or box changed, a preset chosen, a Randomize or Mutate, a snapshot
// recalled. The page calls record() after each; a change not yet recorded (a slider still held)
// is recorded before an undo, so Undo always goes back to the settings before it. A state holds
// the values, the preset chosen, its values (what a link leaves out) and the last draw
// (current.draw, so a link names its seed again after an undo back to it). Choosing another model
// starts a new history; the A and B snapshots stay, each recalled only while its model is chosen.

import { showAll } from "./controls.js";
import { restart } from "./live.js";
import { $, clearMessage, current, same, studio } from "./page.js";
import { schedulePicture } from "./plots.js";

const MAX_STEPS = 200;  // the oldest steps are forgotten beyond this

const past = [];  // states before now, oldest first
const future = [];  // states undone, the next redo last
let now = null;  // the state recorded last
const slots = { a: null, b: null };

function snapshot() {
  return {
    model: current.model.name,
    choice: $("preset").value,  // the preset list's entry ("(fitted)" too)
    preset: studio.preset,  // the preset a link names
    base: current.base,
    values: { ...current.values },  // (values are replaced, never changed in place: a shallow copy holds)
    draw: current.draw,
    description: $("description").value,
  };
}

function sameValues(a, b) {
  const names = new Set([...Object.keys(a), ...Object.keys(b)]);
  return [...names].every((name) => same(a[name], b[name]));
}

function sameState(a, b) {
  return a.model === b.model && a.choice === b.choice && sameValues(a.values, b.values);
}

// Show a state: the sliders, the preset list, the live sound (a new voice, struck) and the pictures.
function show(state) {
  clearMessage();
  $("preset").value = state.choice;
  studio.preset = state.preset;
  current.base = state.base;
  current.values = { ...state.values };
  current.draw = state.draw;
  $("description").value = state.description;
  showAll();
  restart();
  schedulePicture(0);
}

function update() {
  studio.history = { undo: past.length, redo: future.length };
  $("undo").disabled = past.length === 0;
  $("redo").disabled = future.length === 0;
  const name = current.model ? current.model.name : null;
  let showing = "";
  for (const key of ["a", "b"]) {
    const slot = slots[key];
    const usable = !!slot && slot.model === name;
    $(`recall-${key}`).disabled = !usable;
    const here = usable && now !== null && sameState(slot, now);
    $(`recall-${key}`).classList.toggle("on", here);
    if (here && !showing) showing = key;
  }
  $("swap-ab").disabled = $("recall-a").disabled || $("recall-b").disabled;
  studio.ab = { a: !!slots.a, b: !!slots.b, showing };
}

// The settings now are one step (if they differ from the last recorded).
export function record() {
  if (!current.model) return;
  const state = snapshot();
  if (now !== null && sameState(now, state)) {
    now = state;  // the same settings (a draw that changed nothing): nothing to undo
  } else {
    if (now !== null) past.push(now);
    if (past.length > MAX_STEPS) past.shift();
    future.length = 0;
    now = state;
  }
  update();
}

// A new history, starting from the settings now (the page opened, another model chosen).
export function newHistory() {
  past.length = 0;
  future.length = 0;
  now = current.model ? snapshot() : null;
  update();
}

export function undo() {
  record();
  if (!past.length) return;
  future.push(now);
  now = past.pop();
  show(now);
  update();
}

export function redo() {
  record();
  if (!future.length) return;
  past.push(now);
  now = future.pop();
  show(now);
  update();
}

// --- A/B ---------------------------------------------------------------------------------------

export function store(key) {
  record();
  slots[key] = now;
  update();
}

// Recall snapshot A or B (one step).
export function recall(key) {
  const slot = slots[key];
  if (!slot || slot.model !== current.model.name) return;
  record();
  if (sameState(slot, now)) return;
  show(slot);
  record();
}

// The other snapshot than the one the settings are now (A when neither).
export function swap() {
  record();
  recall(studio.ab.showing === "a" ? "b" : "a");
}
