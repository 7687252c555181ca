// barsynth studio: the controls, built from the chosen model's parameter table (GET /api/models):
// a slider and a number box for a number, a <select> for a choice, a checkbox for a bool and a
// text box for a list; none for a data row ("data": a recorded attack's samples and their rate),
// whose value the page keeps and sends as it came (from the defaults or a preset). A row whose "when" ({"excitation": ["bow"]}, {"vibrato_rate_hz": {"op": ">",
// "than": 0}}) does not hold for the current values is greyed out: disabled, dimmed, its title
// saying under which settings it acts (the row's "when_text", in the table's words).

import { $, RATE, api, clearMessage, current, element, failed, fmt, listText, same, studio } from "./page.js";

const SLIDER_STEPS = 1000;

const controls = new Map();  // name -> {row, show(value), wrap, inputs, tip}
const controllers = new Set();  // the names other rows' "when" depend on
let changed = () => {};  // what an accepted change sets off besides (the live sound, the pictures)

// What else happens when a control changes a value (app.js: the live sound and the pictures).
export function onChange(what) {
  changed = what;
}

// --- values: parsing, sliders ----------------------------------------------------------------

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

// --- when a control acts -----------------------------------------------------------------------

const COMPARE = { "<": (a, b) => a < b, "<=": (a, b) => a <= b, ">": (a, b) => a > b, ">=": (a, b) => a >= b };

// A list counts its values where a comparison has "count" (and where "than" names a list).
const counted = (v) => (Array.isArray(v) ? v.length : v);

// Whether parameter name's value meets one condition of a "when": a list of values it must hold
// one of, or a comparison {op, than, count} with a number or with another parameter's value
// (parameters.py: Compare.holds).
function holds(condition, name, values) {
  const value = values[name];
  if (Array.isArray(condition)) return condition.some((a) => same(a, value));
  const than = typeof condition.than === "string" ? counted(values[condition.than]) : condition.than;
  return COMPARE[condition.op](condition.count ? value.length : value, than);
}

// A row's "when" as a list of clauses: null (none), one clause, or a list of them.
const clauses = (row) => (!row.when ? [] : Array.isArray(row.when) ? row.when : [row.when]);

// Whether a row has any effect with these values: its "when" maps names of parameters to a
// condition each (all must hold), or is a list of such maps (any one must hold); a row without
// "when" always acts (parameters.py: Parameter.acts_under).
export function acts(row, values) {
  const all = clauses(row);
  return all.length === 0 || all.some((clause) => Object.entries(clause).every(([name, c]) => holds(c, name, values)));
}

// The parameters a row's "when" reads: a change of one may turn the row on or off.
export function reads(row) {
  const names = new Set();
  for (const clause of clauses(row)) {
    for (const [name, c] of Object.entries(clause)) {
      names.add(name);
      if (!Array.isArray(c) && typeof c.than === "string") names.add(c.than);
    }
  }
  return [...names].sort();
}

// Grey out every control that has no effect now and bring back every one that has.
function greyOut() {
  const inactive = [];
  for (const [name, control] of controls) {
    const on = acts(control.row, current.values);
    if (!on) inactive.push(name);
    const title = on ? control.tip : `no effect unless ${control.row.when_text}; ${control.tip}`;
    control.wrap.classList.toggle("inactive", !on);
    control.wrap.title = title;
    for (const input of control.inputs) {
      input.disabled = !on;
      input.title = title;
    }
  }
  studio.inactive = inactive;
}

// --- controls ----------------------------------------------------------------------------------

function makeControl(row) {
  const id = `param-${row.name}`;
  const tip = `${row.doc}${row.unit ? ` (${row.unit})` : ""}`;
  const wrap = element("div", { class: `param kind-${row.kind}`, title: tip });
  wrap.dataset.name = row.name;
  const label = element("label", { htmlFor: id, class: "name" }, row.name);
  const unit = element("span", { class: "unit" }, row.unit);
  let show;
  let inputs;

  if (row.kind === "float" || row.kind === "int") {
    const slider = element("input", { type: "range", id, min: "0", max: String(sliderSteps(row)), step: "1",
      title: tip, class: row.scale === "log" ? "log" : "linear" });
    const box = element("input", { type: "number", id: `num-${row.name}`, step: "any", class: "num", title: tip,
      inputMode: "decimal" });
    box.setAttribute("aria-label", `${row.name} value${row.unit ? ` in ${row.unit}` : ""}`);
    slider.addEventListener("input", () => {
      const v = fromSlider(row, Number(slider.value));
      box.value = fmt(v);
      if (!same(v, current.values[row.name])) change(row.name, v);
    });
    box.addEventListener("change", () => typed(row.name, box.value));
    show = (v) => {
      slider.value = String(toSlider(row, v));
      box.value = fmt(v);
    };
    inputs = [slider, box];
    wrap.append(label, slider, box, unit);
    wrap.classList.add("slider");
  } else if (row.kind === "choice") {
    const select = element("select", { id, title: tip });
    for (const c of row.choices) select.append(element("option", { value: c }, c));
    select.addEventListener("change", () => change(row.name, select.value));
    show = (v) => { select.value = v; };
    inputs = [select];
    wrap.append(label, select, unit);
  } else if (row.kind === "bool") {
    const box = element("input", { type: "checkbox", id, title: tip });
    box.addEventListener("change", () => change(row.name, box.checked));
    show = (v) => { box.checked = !!v; };
    inputs = [box];
    wrap.append(label, box, unit);
  } else {  // floats: "1,4,10"
    const text = element("input", { type: "text", id, title: tip, placeholder: "e.g. 1,4,10", class: "list",
      spellcheck: false });
    text.addEventListener("change", () => typed(row.name, text.value));
    show = (v) => { text.value = listText(v); };
    inputs = [text];
    wrap.append(label, text, unit);
  }
  controls.set(row.name, { row, show, wrap, inputs, tip });
  return wrap;
}

export function buildControls() {
  controls.clear();
  controllers.clear();
  for (const row of current.model.parameters) {
    for (const name of reads(row)) controllers.add(name);
  }
  $("controls").replaceChildren(...current.model.parameters.filter((row) => !row.data).map(makeControl));
}

// Every control shows the current values (a preset, the defaults), greyed out where it has no effect.
export function showAll() {
  for (const [name, control] of controls) control.show(current.values[name]);
  studio.values = { ...current.values };
  greyOut();
}

function rowOf(name) {
  return current.model.parameters.find((r) => r.name === name);
}

// An accepted change from a control: remember it, grey out what it turns off, send it to the
// live sound and redraw the pictures (onChange).
function change(name, v) {
  clearMessage();
  const changes = [[name, v], ...setsAlong(name, v)];
  for (const [n, value] of changes) {
    current.values[n] = value;
    if (n !== name && controls.has(n)) controls.get(n).show(value);
  }
  studio.values = { ...current.values };
  if (changes.some(([n]) => controllers.has(n))) greyOut();
  for (const [n, value] of changes) changed(n, value);
}

// What else a change sets: a material chosen sets the rows its "sets" names (Young's modulus,
// density) to its values; one of those moved by hand turns the material back to its default
// ("custom"), as the server's resolve does.
function setsAlong(name, v) {
  const along = [];
  const row = rowOf(name);
  const values = row && row.sets ? row.sets.values[v] : undefined;
  if (values) row.sets.names.forEach((n, i) => along.push([n, values[i]]));
  for (const other of current.model.parameters) {
    if (other.sets && other.sets.names.includes(name) && !same(current.values[other.name], other.default)) {
      along.push([other.name, other.default]);
    }
  }
  return along;
}

// A typed value: taken when the table allows it; otherwise sent as typed for the server's
// message, and the control goes back to its last good value.
export async function typed(name, text) {
  const row = rowOf(name);
  const v = row ? parsed(row, text) : undefined;
  if (v !== undefined) {
    controls.get(name)?.show(v);  // (a data row has no control)
    if (!same(v, current.values[name])) change(name, v);
    return;
  }
  if (controls.has(name)) controls.get(name).show(current.values[name]);
  await refuse(name, row ? asTyped(row, text) : text);
}

async function refuse(name, sent) {
  const modelName = current.model.name;
  try {
    await api("POST", "/api/describe", { model: modelName, parameters: { ...current.values, [name]: sent }, sample_rate: RATE });
  } catch (err) {
    failed(err);
    return;
  }
  // The server took it after all (it reads a few more spellings than this page does).
  const row = rowOf(name);
  if (modelName === current.model.name && row) {
    const v = row.kind === "floats" && !Array.isArray(sent) ? parsed(row, sent) : sent;
    if (v !== undefined) {
      controls.get(name)?.show(v);
      change(name, v);
    }
  }
}

// The table's defaults (a fresh copy of each list).
export function defaults() {
  return Object.fromEntries(current.model.parameters.map((r) => [r.name, Array.isArray(r.default) ? [...r.default] : r.default]));
}
