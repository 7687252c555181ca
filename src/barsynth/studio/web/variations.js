// barsynth studio: Randomize and Mutate (POST /api/draw; docs/studio.md).
//
// The server draws a set of the model's settings that it accepts (barsynth.batch.sampler),
// from a seed: Randomize over every range, Mutate around the settings now by the spread (a
// fraction of each range). Each press takes a new random 32-bit seed. The same model, base
// settings, seed and spread give the same settings, so a link names a draw by its seed: the
// link holds the settings the draw started from (as any link: what differs from the preset),
// then random=SEED, or mutate=SEED&spread=S. Opening it loads those settings and draws again.
// Once a drawn setting is changed by hand, the link holds the values instead (files.js).

import { showAll } from "./controls.js";
import { record } from "./history.js";
import { restart } from "./live.js";
import { $, RATE, api, clearMessage, current, failed, showMessage, studio } from "./page.js";
import { schedulePicture } from "./plots.js";

export const DEFAULT_SPREAD = 0.1;

export function newSeed() {
  return crypto.getRandomValues(new Uint32Array(1))[0];
}

// A number when the text reads as one (so the server's message says "= 5", not "= '5'").
function asNumber(text) {
  const raw = String(text).trim();
  return raw !== "" && Number.isFinite(Number(raw)) ? Number(raw) : raw;
}

// The spread box's value: a number from 0 to 1 (the server refuses any other with its message).
export function spread() {
  return asNumber($("spread").value);
}

function tell(text) {
  $("draw-note").textContent = text;
}

// Draw (mode "random" or "mutate") from the settings now and show the result (one step of the
// history unless asked not to: a link's draw is where the page starts).
export async function draw(mode, seed = newSeed(), by = spread(), { step = true } = {}) {
  const model = current.model.name;
  const from = { ...current.values };
  const body = { model, mode, seed, parameters: from, sample_rate: RATE };
  if (mode === "mutate") body.spread = by;
  for (const id of ["randomize", "mutate"]) $(id).disabled = true;
  tell(mode === "random" ? "drawing…" : "mutating…");
  let data;
  try {
    data = await api("POST", "/api/draw", body);
  } catch (err) {
    tell("");
    failed(err);
    return false;
  } finally {
    for (const id of ["randomize", "mutate"]) $(id).disabled = false;
  }
  if (model !== current.model.name) return false;  // another model was chosen meanwhile
  clearMessage();
  current.values = { ...data.parameters };
  current.draw = { mode, seed: data.seed, spread: data.spread, from, result: { ...data.parameters } };
  studio.draws += 1;
  studio.lastDraw = { mode, seed: data.seed, spread: data.spread, rejected: data.rejected };
  const refused = data.rejected ? ` · ${data.rejected} refused first` : "";
  tell(`${mode === "random" ? "random" : `mutated by ${data.spread}`}, seed ${data.seed}${refused}`);
  showAll();
  restart();
  schedulePicture(0);
  if (step) record();
  return true;
}

// The draw a link asks for ({mode, seed, spread}), or null; the spread box shows its spread.
export function linkedDraw(query) {
  const random = query.get("random");
  const mutate = query.get("mutate");
  if (random !== null && mutate !== null) {
    showMessage("a link holds random=SEED or mutate=SEED, not both; neither was drawn");
    return null;
  }
  if (random === null && mutate === null) return null;
  if (random !== null) return { mode: "random", seed: asNumber(random), spread: undefined };
  const text = query.get("spread");
  if (text !== null) $("spread").value = text;
  return { mode: "mutate", seed: asNumber(mutate), spread: text === null ? DEFAULT_SPREAD : asNumber(text) };
}

export function startVariations() {
  $("randomize").addEventListener("click", () => draw("random").catch(failed));
  $("mutate").addEventListener("click", () => draw("mutate").catch(failed));
}
