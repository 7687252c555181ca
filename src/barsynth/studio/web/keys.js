// barsynth studio: notes from the computer keyboard, the on-screen keyboard and a MIDI device.
//
// Two octaves on the computer keyboard, by physical key (any layout): z s x d c v g b h n j m
// for the lower octave, q 2 w 3 e r 5 t 6 y 7 u i for the upper (to its top C). They play only
// while "Keys play notes" is on (the button, or k), since some of them are the page's shortcuts
// otherwise (t, r, s, b); [ and ] shift the octaves. Key down sends note_on, key up note_off;
// auto-repeat never retriggers, and keys are ignored while a text box, list or slider has the
// focus. The velocity comes from the slider. The on-screen keyboard shows every held note
// (keys, mouse, MIDI) and plays with the mouse or a touch.
//
// Web MIDI: where the browser has navigator.requestMIDIAccess, the MIDI button asks for it and
// lists the inputs; note on/off (a note on of velocity 0 is a note off), CC 1 (the wheel) and CC 64 (sustain) of
// the chosen input (or of all) go to the stream. Without Web MIDI, or when it is refused, the
// panel says so and nothing else happens.
//
// window.studio.keys: {enabled, base, held: [pitches], notesSent, midi: {state: "absent" |
// "off" | "asking" | "refused" | "ready", inputs: [names], messages}}.

import { $, element, studio, typing } from "./page.js";
import { sendNote } from "./live.js";

const LOWER = ["KeyZ", "KeyS", "KeyX", "KeyD", "KeyC", "KeyV", "KeyG", "KeyB", "KeyH", "KeyN", "KeyJ", "KeyM"];
const UPPER = ["KeyQ", "Digit2", "KeyW", "Digit3", "KeyE", "KeyR", "Digit5", "KeyT", "Digit6", "KeyY", "Digit7",
  "KeyU", "KeyI"];
const CODES = new Map([...LOWER.map((code, k) => [code, k]), ...UPPER.map((code, k) => [code, 12 + k])]);
const LABELS = [..."zsxdcvgbhnjm", ..."q2w3er5t6y7ui"];
const NAMES = ["C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B"];
const BLACK = new Set([1, 3, 6, 8, 10]);
const KEYS = 25;  // two octaves and the top C
const MIN_BASE = 0;
const MAX_BASE = 96;  // the top C is then 120
const CONTROLS = new Set([1, 64]);  // the modulation wheel and the sustain pedal

const keys = {
  enabled: false,
  base: 60,  // the lower octave's C (MIDI note 60 = C4)
  held: [],
  notesSent: 0,
  midi: { state: "off", inputs: [], messages: 0 },
};
studio.keys = keys;

const down = new Map();  // source ("key:KeyZ", "mouse", "midi:60") -> pitch it holds
let access = null;

function velocity() {
  return Math.max(1, Math.min(127, Math.round(Number($("velocity").value) || 100)));
}

function noteOn(source, pitch, strength) {
  if (pitch < 0 || pitch > 127 || down.has(source)) return;
  down.set(source, pitch);
  keys.notesSent += 1;
  sendNote({ type: "note_on", pitch, velocity: strength });
  showHeld();
}

function noteOff(source) {
  if (!down.has(source)) return;
  const pitch = down.get(source);
  down.delete(source);
  sendNote({ type: "note_off", pitch });
  showHeld();
}

function releaseAll(prefix = "") {
  for (const source of [...down.keys()]) if (source.startsWith(prefix)) noteOff(source);
}

function showHeld() {
  keys.held = [...down.values()].sort((a, b) => a - b);
  const held = new Set(keys.held);
  for (const key of $("keyboard").children) {
    key.classList.toggle("down", held.has(keys.base + Number(key.dataset.step)));
  }
}

function noteName(pitch) {
  return `${NAMES[pitch % 12]}${Math.floor(pitch / 12) - 1}`;
}

function setBase(base) {
  keys.base = Math.max(MIN_BASE, Math.min(MAX_BASE, base));
  $("octave").textContent = `${noteName(keys.base)}–${noteName(keys.base + KEYS - 1)}`;
  for (const key of $("keyboard").children) {
    key.title = `${noteName(keys.base + Number(key.dataset.step))}${key.dataset.label ? ` (${key.dataset.label})` : ""}`;
  }
  showHeld();
}

function setEnabled(on) {
  keys.enabled = on;
  const button = $("keys-on");
  button.setAttribute("aria-pressed", String(on));
  button.classList.toggle("on", on);
  if (!on) releaseAll("key:");
}

// The computer keyboard; returns whether the key was the keyboard's (the page's shortcuts then
// leave it alone).
export function keyDown(event) {
  // A box, a list or a focused slider keeps its keys.
  if (event.ctrlKey || event.metaKey || event.altKey || typing(event, { sliders: true })) return false;
  if (event.code === "KeyK") {
    if (!event.repeat) setEnabled(!keys.enabled);
    return true;
  }
  if (!keys.enabled) return false;
  if (event.code === "BracketLeft" || event.code === "BracketRight") {
    if (!event.repeat) {
      releaseAll("key:");
      setBase(keys.base + (event.code === "BracketLeft" ? -12 : 12));
    }
    return true;
  }
  if (!CODES.has(event.code)) return false;
  event.preventDefault();
  if (!event.repeat) noteOn(`key:${event.code}`, keys.base + CODES.get(event.code), velocity());
  return true;
}

function keyUp(event) {
  if (down.has(`key:${event.code}`)) noteOff(`key:${event.code}`);
}

function buildKeyboard() {
  const board = $("keyboard");
  const white = [...Array(KEYS).keys()].filter((step) => !BLACK.has(step % 12)).length;
  let whites = 0;
  const children = [];
  for (let step = 0; step < KEYS; step += 1) {
    const black = BLACK.has(step % 12);
    const key = element("div", { class: black ? "key black" : "key white" });
    key.dataset.step = String(step);
    key.dataset.label = LABELS[step] || "";
    const left = black ? (whites - 0.3) / white : whites / white;
    key.style.left = `${(100 * left).toFixed(3)}%`;
    key.style.width = `${(100 * (black ? 0.6 : 1) / white).toFixed(3)}%`;
    if (!black) whites += 1;
    key.append(element("span", { class: "label" }, LABELS[step].toUpperCase()));
    key.addEventListener("pointerdown", (event) => {
      event.preventDefault();
      key.setPointerCapture(event.pointerId);
      noteOn(`pointer:${event.pointerId}`, keys.base + step, velocity());
    });
    const up = (event) => noteOff(`pointer:${event.pointerId}`);
    key.addEventListener("pointerup", up);
    key.addEventListener("pointercancel", up);
    children.push(key);
  }
  board.replaceChildren(...children);
}

// --- Web MIDI ---------------------------------------------------------------------------------

function midiStatus(text) {
  $("midi-status").textContent = text;
}

function listInputs() {
  const inputs = access ? [...access.inputs.values()] : [];
  keys.midi.inputs = inputs.map((input) => input.name || input.id);
  const select = $("midi-input");
  const chosen = select.value;
  select.replaceChildren(element("option", { value: "" }, "all inputs"),
    ...inputs.map((input) => element("option", { value: input.id }, input.name || input.id)));
  if (inputs.some((input) => input.id === chosen)) select.value = chosen;
  select.hidden = inputs.length === 0;
  for (const input of inputs) input.onmidimessage = (event) => fromMidi(input, event.data);
  midiStatus(inputs.length ? `${inputs.length} MIDI input${inputs.length === 1 ? "" : "s"}` : "no MIDI input connected");
}

function fromMidi(input, data) {
  const chosen = $("midi-input").value;
  if ((chosen && input.id !== chosen) || !data || data.length < 2) return;
  const kind = data[0] & 0xf0;
  const source = `midi:${input.id}:${data[1]}`;
  keys.midi.messages += 1;
  if (kind === 0x90 && data[2] > 0) {
    noteOff(source);  // a second note on of a held note: off, then on again
    noteOn(source, data[1], data[2]);
  } else if (kind === 0x80 || kind === 0x90) {
    noteOff(source);
  } else if (kind === 0xb0 && CONTROLS.has(data[1])) {
    sendNote({ type: "control", cc: data[1], value: data[2] });
  }
}

async function connectMidi() {
  if (!navigator.requestMIDIAccess) return;
  keys.midi.state = "asking";
  midiStatus("asking for MIDI…");
  try {
    access = await navigator.requestMIDIAccess();
  } catch (err) {
    keys.midi.state = "refused";
    midiStatus("MIDI was not allowed");
    return;
  }
  keys.midi.state = "ready";
  access.onstatechange = listInputs;
  listInputs();
}

export function startKeys() {
  buildKeyboard();
  setBase(keys.base);
  $("keys-on").addEventListener("click", () => setEnabled(!keys.enabled));
  $("octave-down").addEventListener("click", () => { releaseAll("key:"); setBase(keys.base - 12); });
  $("octave-up").addEventListener("click", () => { releaseAll("key:"); setBase(keys.base + 12); });
  $("velocity").addEventListener("change", () => $("velocity").blur());  // the keys play again at once
  document.addEventListener("keyup", keyUp);
  window.addEventListener("blur", () => releaseAll("key:"));
  $("midi-input").addEventListener("change", () => releaseAll("midi:"));
  if (navigator.requestMIDIAccess) {
    $("midi-connect").addEventListener("click", connectMidi);
  } else {
    keys.midi.state = "absent";
    $("midi-connect").disabled = true;
    midiStatus("this browser has no Web MIDI");
  }
}
