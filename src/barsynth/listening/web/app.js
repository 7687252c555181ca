// barsynth listening test: the participant's page (no build step, no libraries).
// The server holds the truth (plan, plays, answers); this page shows the current step,
// keeps unsent slider positions in localStorage so a reload does not lose them, and
// sends each answer once.
"use strict";

const $ = (id) => document.getElementById(id);
const SECTIONS = ["loading", "welcome", "mushra", "ab", "done"];
const player = new Audio();
const SLIDER_KEYS = new Set(["ArrowLeft", "ArrowRight", "ArrowUp", "ArrowDown", "Home", "End", "PageUp", "PageDown"]);
let state = null;
let busy = false;

function show(name) {
  for (const s of SECTIONS) $(s).hidden = s !== name;
  $("switch").hidden = name !== "mushra" && name !== "ab";
}

function setStatus(message) {
  $("status").textContent = message || "";
  $("status").hidden = !message;
}

class ApiError extends Error {
  constructor(status, message) { super(message); this.status = status; }
}

async function api(method, path, payload) {
  const options = { method, credentials: "same-origin", headers: {} };
  if (payload !== undefined) {
    options.headers["Content-Type"] = "application/json";
    options.body = JSON.stringify(payload);
  }
  let response;
  try {
    response = await fetch(path, options);
  } catch (err) {
    throw new ApiError(0, "The test server cannot be reached. Everything you submitted is saved; " +
                          "please wait a moment and try again.");
  }
  let data = null;
  try { data = await response.json(); } catch (err) { data = null; }
  if (!response.ok) {
    throw new ApiError(response.status, (data && data.error) || `The server answered ${response.status}.`);
  }
  return data;
}

// --- drafts: what the participant set but has not submitted yet ---------------------

function draftKey() {
  return `barsynth:${state.participant}:${state.step.index}`;
}

function loadDraft() {
  try { return JSON.parse(localStorage.getItem(draftKey()) || "{}"); } catch (err) { return {}; }
}

function saveDraft(draft) {
  try { localStorage.setItem(draftKey(), JSON.stringify(draft)); } catch (err) { /* private mode */ }
}

// --- playing --------------------------------------------------------------------------

let playing = 0;  // which click the player belongs to; older clicks' events are ignored

function stopPlaying() {
  playing += 1;
  player.onplaying = player.onended = player.onerror = null;
  player.pause();
  for (const b of document.querySelectorAll("button.play.playing")) b.classList.remove("playing");
}

// Play a sound. The play is counted once the browser really starts playing it,
// so "played" on the page (and in the results) means heard, not just clicked.
function play(clip, button, counter) {
  setStatus("");
  stopPlaying();
  const mine = playing;
  const failed = (why) => {
    if (mine !== playing) return;
    button.classList.remove("playing");
    setStatus(`This sound could not be played (${why}). Check the connection and the volume, then try again.`);
  };
  button.classList.add("playing");
  player.onplaying = async () => {
    player.onplaying = null;
    try {
      const answer = await api("POST", "/api/play", { handle: clip.handle });
      clip.plays = answer.plays;
      counter.textContent = playsText(clip.plays);
      updateButtons();
    } catch (err) {
      setStatus(err.message);
    }
  };
  player.onended = () => { if (mine === playing) button.classList.remove("playing"); };
  player.onerror = () => failed("it did not load");
  player.src = `/api/audio/${encodeURIComponent(clip.handle)}`;
  player.play().catch((err) => failed(err.name || "refused"));
}

// A Play button for one sound and the count of its plays beside it.
function playControls(clip, text, counterTag) {
  const button = document.createElement("button");
  button.type = "button";
  button.className = "play";
  button.dataset.handle = clip.handle;
  button.textContent = text;
  button.setAttribute("aria-label", `Play ${clip.label}`);
  const counter = document.createElement(counterTag);
  counter.className = "plays";
  counter.textContent = playsText(clip.plays);
  button.addEventListener("click", () => play(clip, button, counter));
  return [button, counter];
}

function playsText(n) {
  return n === 1 ? "played once" : n ? `played ${n} times` : "not played yet";
}

// --- drawing the current step -----------------------------------------------------------

function render(newState) {
  state = newState;
  stopPlaying();
  document.title = state.title;
  $("title").textContent = state.title;
  if (!state.step) {
    $("progress").textContent = `All ${state.steps_total} steps answered.`;
    $("participant").textContent = state.participant;
    show("done");
    return;
  }
  const kind = state.step.kind === "mushra" ? "Page" : "Pair";
  $("progress").textContent =
    `${kind} ${state.step.number} of ${state.step.of} · step ${state.steps_done + 1} of ${state.steps_total}`;
  if (state.step.kind === "mushra") renderMushra(); else renderAB();
  window.scrollTo(0, 0);
}

function renderMushra() {
  const draft = loadDraft();
  const list = $("mushra-clips");
  list.replaceChildren();
  for (const clip of state.step.clips) {
    const saved = draft[clip.handle] || {};
    const item = document.createElement("li");
    item.className = "clip";
    item.dataset.handle = clip.handle;

    const head = document.createElement("div");
    head.className = "clip-head";
    const name = document.createElement("span");
    name.className = "clip-name";
    name.textContent = clip.label;
    head.append(name, ...playControls(clip, "▶ Play", "span"));

    const row = document.createElement("div");
    row.className = "rating-row";
    const slider = document.createElement("input");
    slider.type = "range";
    slider.className = "rating";
    slider.min = "0";
    slider.max = String(state.rating_max);
    slider.step = "0.01";
    slider.value = saved.rating !== undefined ? String(saved.rating) : "0";
    if (saved.touched) item.dataset.touched = "yes";
    slider.setAttribute("aria-label", `Rating for ${clip.label}`);
    const value = document.createElement("output");
    value.textContent = Number(slider.value).toFixed(2);
    // Set means touched: a click or key on the slider counts even where the value stays (0 at 0).
    const touched = () => {
      value.textContent = Number(slider.value).toFixed(2);
      item.dataset.touched = "yes";
      keepMushraDraft();
      updateButtons();
    };
    slider.addEventListener("input", touched);
    slider.addEventListener("pointerdown", touched);
    slider.addEventListener("keydown", (event) => { if (SLIDER_KEYS.has(event.key)) touched(); });
    row.append(slider, value);

    const scale = document.createElement("div");
    scale.className = "scale";
    scale.innerHTML = "<span>0 not realistic at all</span><span>9.99 very realistic</span>";

    const comment = document.createElement("textarea");
    comment.className = "comment";
    comment.maxLength = 2000;
    comment.placeholder = "Comment (optional)";
    comment.setAttribute("aria-label", `Comment on ${clip.label}`);
    comment.value = saved.comment || "";
    comment.addEventListener("input", keepMushraDraft);

    item.append(head, row, scale, comment);
    list.append(item);
  }
  show("mushra");
  updateButtons();
}

function mushraAnswers() {
  return [...document.querySelectorAll("#mushra-clips li.clip")].map((item) => ({
    handle: item.dataset.handle,
    rating: Number(item.querySelector("input.rating").value),
    comment: item.querySelector("textarea.comment").value,
  }));
}

function keepMushraDraft() {
  const draft = {};
  for (const item of document.querySelectorAll("#mushra-clips li.clip")) {
    draft[item.dataset.handle] = {
      rating: Number(item.querySelector("input.rating").value),
      comment: item.querySelector("textarea.comment").value,
      touched: item.dataset.touched === "yes",
    };
  }
  saveDraft(draft);
}

// The sounds whose slider has not been set yet (a rating of 0 must be chosen, not left).
function unrated() {
  return [...document.querySelectorAll("#mushra-clips li.clip")]
    .filter((item) => item.dataset.touched !== "yes")
    .map((item) => item.querySelector(".clip-name").textContent);
}

function renderAB() {
  const draft = loadDraft();
  const box = $("ab-clips");
  box.replaceChildren();
  for (const clip of state.step.clips) {
    const wrap = document.createElement("div");
    wrap.append(...playControls(clip, `▶ Play ${clip.label}`, "div"));
    box.append(wrap);
  }
  for (const radio of document.querySelectorAll("input[name=picked]")) {
    radio.checked = radio.value === draft.picked;
  }
  const options = $("ab-difficulty-options");
  options.replaceChildren();
  state.difficulty_labels.forEach((text, i) => {
    const label = document.createElement("label");
    const radio = document.createElement("input");
    radio.type = "radio";
    radio.name = "difficulty";
    radio.value = String(i + 1);
    radio.checked = draft.difficulty === i + 1;
    radio.addEventListener("change", keepABDraft);
    label.append(radio, ` ${i + 1} ${text}`);
    options.append(label);
  });
  show("ab");
  updateButtons();
}

function abAnswer() {
  const picked = document.querySelector("input[name=picked]:checked");
  const difficulty = document.querySelector("input[name=difficulty]:checked");
  return { picked: picked ? picked.value : null, difficulty: difficulty ? Number(difficulty.value) : null };
}

function keepABDraft() {
  saveDraft(abAnswer());
  updateButtons();
}

function updateButtons() {
  if (!state || !state.step) return;
  const unplayed = state.step.clips.filter((c) => !c.plays).map((c) => c.label);
  const waiting = unplayed.length ? `Play ${unplayed.join(", ")} before submitting.` : "";
  if (state.step.kind === "mushra") {
    const unset = unrated();
    $("mushra-submit").disabled = busy || unplayed.length > 0 || unset.length > 0;
    $("mushra-hint").textContent = [waiting, unset.length ? `Set the slider of ${unset.join(", ")}.` : ""]
      .filter(Boolean).join(" ");
  } else {
    const answer = abAnswer();
    $("ab-difficulty").disabled = !answer.picked;
    $("ab-submit").disabled = busy || unplayed.length > 0 || !answer.picked || !answer.difficulty;
    $("ab-hint").textContent = waiting;
  }
}

// --- sending ------------------------------------------------------------------------------

async function submit(payload) {
  if (busy) return;
  busy = true;
  updateButtons();
  setStatus("");
  const key = draftKey();
  try {
    const next = await api("POST", `/api/steps/${state.step.index}/answer`, payload);
    try { localStorage.removeItem(key); } catch (err) { /* private mode */ }
    busy = false;
    render(next);
  } catch (err) {
    busy = false;
    setStatus(err.message);
    if (err.status === 409 || err.status === 401) await refresh();
    else updateButtons();
  }
}

async function refresh() {
  try {
    render(await api("GET", "/api/session"));
  } catch (err) {
    if (err.status !== 401) { setStatus(err.message); return; }
    setStatus("");
    try {
      const about = await api("GET", "/api/health");
      document.title = about.title;
      $("title").textContent = about.title;
    } catch (err2) { /* the heading stays generic */ }
    show("welcome");
  }
}

function forgetDrafts() {
  try {
    for (const key of Object.keys(localStorage)) if (key.startsWith("barsynth:")) localStorage.removeItem(key);
  } catch (err) { /* private mode */ }
}

async function start(fresh) {
  setStatus("");
  try {
    const next = await api("POST", "/api/session", fresh ? { new: true } : {});
    if (fresh) forgetDrafts();
    render(next);
  } catch (err) {
    setStatus(err.message);
  }
}

document.addEventListener("DOMContentLoaded", () => {
  $("start").addEventListener("click", () => start(false));
  $("next-participant").addEventListener("click", () => start(true));
  $("new-participant").addEventListener("click", () => {
    if (confirm("Start as a new participant? Everything answered so far stays saved under the previous id; " +
                "what is on this page and not yet submitted is dropped.")) start(true);
  });
  $("mushra-submit").addEventListener("click", () => submit({ ratings: mushraAnswers() }));
  $("ab-submit").addEventListener("click", () => submit(abAnswer()));
  for (const radio of document.querySelectorAll("input[name=picked]")) {
    radio.addEventListener("change", keepABDraft);
  }
  refresh();
});
