// barsynth studio: settings in and out: models and presets loaded (GET /api/models/.../presets/...),
// the settings of the last fit (fit.js) loaded as a preset is, WAV files (POST /api/render) and
// preset files (POST /api/preset-file) saved, and a link to the current settings (the model, the
// preset and what differs from it, in the address, and the seed of the last Randomize or Mutate
// (variations.js) while its settings are unchanged; not a data row's samples: they come with the
// preset, and a fitted attack does not go into a link).

import { buildControls, defaults, showAll, typed } from "./controls.js";
import { newHistory, record } from "./history.js";
import { restart } from "./live.js";
import { $, LINK_WORDS, RATE, api, clearMessage, current, element, failed, listText, same, studio } from "./page.js";
import { schedulePicture } from "./plots.js";

// --- models and presets ------------------------------------------------------------------------

// The preset list's entry for the settings of the last fit (current.fitted), while its model is chosen.
export const FITTED = "(fitted)";

export async function chooseModel(name, wanted = {}) {
  const before = current.model;
  current.model = current.models.get(name);
  current.draw = null;
  studio.model = name;
  $("model").value = name;
  $("summary").textContent = current.model.summary;
  const presetSelect = $("preset");
  const fitted = current.fitted && current.fitted.model === name
    ? [element("option", { value: FITTED }, current.fitted.label)] : [];
  presetSelect.replaceChildren(element("option", { value: "" }, "(defaults)"), ...fitted,
    ...current.model.presets.map((p) => element("option", { value: p }, p)));
  buildControls();
  await choosePreset(wanted.preset || "", wanted.overrides);  // an unknown one: the server's message
  if (before === current.model) record();  // (a fit's settings for the model shown: one step)
  else newHistory();
}

// A preset's values (or the defaults, or the last fit's: FITTED) in every control. A link leaves
// out what equals the preset's values; for a fit, what equals the defaults (a link cannot name a fit).
export async function choosePreset(name, overrides) {
  let loaded = defaults();
  let base = null;
  let description = `${current.model.name} settings`;
  if (name === FITTED && current.fitted && current.fitted.model === current.model.name) {
    base = defaults();
    loaded = { ...loaded, ...structuredClone(current.fitted.values) };
    description = current.fitted.description;
  } else if (name === FITTED) {
    name = "";
  } else if (name) {
    try {
      const data = await api("GET", `/api/models/${encodeURIComponent(current.model.name)}/presets/${encodeURIComponent(name)}`);
      loaded = data.parameters;
      description = data.description || description;
    } catch (err) {
      failed(err);
      name = "";
    }
  }
  $("preset").value = name;
  studio.preset = name === FITTED ? "" : name;
  current.base = base || { ...loaded };
  current.values = { ...loaded };
  $("description").value = description;
  showAll();
  if (overrides) {
    for (const [key, text] of overrides) {
      if (!LINK_WORDS.has(key)) await typed(key, text);
    }
  }
  restart();
  schedulePicture(0);
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

export function download() {
  const name = current.model.name;
  const text = $("duration").value.trim();
  const duration = text !== "" && Number.isFinite(Number(text)) ? Number(text) : text;
  return busy($("download"), async () => {
    const blob = await api("POST", "/api/render",
      { model: name, parameters: { ...current.values }, duration_s: duration, sample_rate: RATE }, true);
    clearMessage();
    save(blob, `${name}.wav`);
  });
}

export function savePreset() {
  const name = current.model.name;
  const description = $("description").value.trim() || `${name} settings`;
  return busy($("save-preset"), async () => {
    const blob = await api("POST", "/api/preset-file", { model: name, parameters: { ...current.values }, description }, true);
    clearMessage();
    save(blob, `${name}.toml`);
  });
}

function valueText(v) {
  if (Array.isArray(v)) return listText(v);
  return String(v);
}

// The link: the model, the preset and what differs from it; after a Randomize or Mutate whose
// settings are unchanged since, what differed when it drew, and its seed (and spread).
function shareUrl() {
  const query = new URLSearchParams();
  query.set("model", current.model.name);
  if (studio.preset) query.set("preset", studio.preset);
  const rows = current.model.parameters;
  const draw = current.draw;
  const drawn = draw && rows.every((row) => same(current.values[row.name], draw.result[row.name]));
  const values = drawn ? draw.from : current.values;
  for (const row of rows) {  // (a data row's thousands of samples stay out of a link)
    if (!row.data && !same(values[row.name], current.base[row.name])) {
      query.set(row.name, valueText(values[row.name]));
    }
  }
  if (drawn) {
    query.set(draw.mode, String(draw.seed));
    if (draw.mode === "mutate") query.set("spread", String(draw.spread));
  }
  return `${location.origin}${location.pathname}?${query}`;
}

export async function share() {
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
