// barsynth studio: the live sound.
//
// Three threads: the stream's Worker (link.js) owns the WebSocket, the AudioWorklet
// (worklet.js) plays, and they talk over a MessageChannel of their own: blocks one way,
// `played` reports the other. This thread only opens and stops streams, passes on the
// controls' messages, and keeps window.studio's figures from what the two tell it, so a busy
// page (pictures, layout, a screenshot) never starves the sound.

import { $, RATE, clearMessage, current, note, showMessage, studio } from "./page.js";

const MAX_LATENCIES = 1000;

const live = {
  ctx: null,
  node: null,
  gain: null,
  tap: null,  // an AnalyserNode between the worklet and the volume: what is played (studio.liveSamples)
  worker: null,
  ready: null,
  gen: 0,  // the socket that sounds now (0: none); each Play opens one with a new number
  lastGen: 0,
  asked: 0,  // Play and Stop presses: a Play still waiting for the audio gives way to a later press
  waiting: null,  // messages for the stream being opened (null: none is)
  started: false,
  pending: new Map(),  // set id -> {sentAt, changedAt} (performance.now()) on socket `gen`
  heardId: -1,  // the newest set id heard on socket `gen`, and when
  heardAt: 0,
  playedOf: new Map(),  // gen -> samples of it counted in studio.samplesPlayed
};

function volume() {
  const v = Number($("volume").value) / 100;
  return v * v;
}

// The volume slider moved: the gain follows within a few ms.
export function setVolume() {
  if (live.gain) live.gain.gain.setTargetAtTime(volume(), live.ctx.currentTime, 0.01);
}

// The AudioContext (made inside the click that asks for sound, as browsers require), the
// worklet, the stream's worker and the channel between the two.
async function ensureAudio() {
  if (!live.ctx) {
    let ctx;
    try {
      ctx = new AudioContext({ sampleRate: 48000, latencyHint: "interactive" });
    } catch (err) {
      ctx = new AudioContext({ latencyHint: "interactive" });  // a device that cannot run at 48 kHz
    }
    live.ctx = ctx;
    live.ready = (async () => {
      await ctx.audioWorklet.addModule("/static/worklet.js");
      const node = new AudioWorkletNode(ctx, "barsynth-stream",
        { numberOfInputs: 0, numberOfOutputs: 1, outputChannelCount: [1] });
      const gain = ctx.createGain();
      gain.gain.value = volume();
      const tap = ctx.createAnalyser();
      tap.fftSize = 32768;
      node.connect(tap).connect(gain).connect(ctx.destination);
      live.tap = tap;
      node.port.onmessage = (event) => fromWorklet(event.data);
      const worker = new Worker("/static/link.js");
      worker.onmessage = (event) => fromWorker(event.data);
      worker.onerror = (event) => showMessage(`The live sound's worker failed: ${event.message || "an error"}`);
      const channel = new MessageChannel();
      node.port.postMessage({ type: "link", port: channel.port1 }, [channel.port1]);
      worker.postMessage({ type: "worklet", port: channel.port2 }, [channel.port2]);
      live.node = node;
      live.gain = gain;
      live.worker = worker;
    })();
  }
  const resumed = live.ctx.state === "running" ? null : live.ctx.resume();
  await live.ready;
  if (resumed) await resumed;
}

// A message for the server on the socket that sounds now (the worker keeps it until the
// socket is open).
function send(message) {
  if (live.gen) live.worker.postMessage({ type: "send", gen: live.gen, message });
}

function startMessage() {
  return { type: "start", model: current.model.name, parameters: { ...current.values }, sample_rate: live.ctx.sampleRate };
}

// The newest `count` samples the worklet played (before the volume), for the tests' ears.
studio.liveSamples = (count = 32768) => {
  if (!live.tap) return [];
  const samples = new Float32Array(live.tap.fftSize);
  live.tap.getFloatTimeDomainData(samples);
  return Array.from(samples.subarray(samples.length - Math.min(count, samples.length)));
};

// Play: start the live sound and strike (the Play button, or a trigger with no stream open).
export function play() {
  return open([{ type: "trigger" }]);
}

// Open a stream whose first messages after its start are `first` (a trigger, or a note).
// Notes played while it opens join them (a chord from a MIDI device arrives all at once).
async function open(first) {
  clearMessage();
  const asked = ++live.asked;
  live.waiting = [...(live.waiting || []), ...first];
  try {
    await ensureAudio();
  } catch (err) {
    showMessage(`This browser cannot play the live sound: ${err.message || err}`);
    return;
  }
  if (asked !== live.asked) return;  // Stop (or another Play) was pressed meanwhile
  const messages = live.waiting || [];
  live.waiting = null;
  if (live.gen) {
    for (const message of messages) send(message);
    return;
  }
  const gen = ++live.lastGen;
  live.gen = gen;
  live.started = false;
  live.pending.clear();
  live.heardId = -1;
  studio.heardSetId = -1;
  studio.lastSet = null;
  live.node.port.postMessage({ type: "reset", gen });
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/api/stream`;
  live.worker.postMessage({ type: "open", gen, url, start: [startMessage(), ...messages] });
  studio.streams += 1;
  setState("playing");
}

function fromWorker(message) {
  if (message.type === "counts") {
    studio.blocksReceived = message.blocks;
    studio.sets = message.sets;
    studio.playedReports = message.reports;
    if (message.gen === live.gen) studio.setsWaiting = message.waiting;
    return;
  }
  if (message.gen !== live.gen) return;  // a stopped socket's
  if (message.type === "message") {
    fromServer(message.message);
  } else if (message.type === "sent") {
    const sentAt = message.at - performance.timeOrigin;
    const changedAt = message.changedAt === null ? sentAt : message.changedAt - performance.timeOrigin;
    studio.lastSet = { id: message.id, parameters: message.parameters };
    if (message.id <= live.heardId) {  // heard before this message came (the two come by different ways)
      latency(live.heardAt, { sentAt, changedAt });
    } else {
      live.pending.set(message.id, { sentAt, changedAt });
    }
  } else if (message.type === "close") {  // closed by the server or the network, not by a Stop
    live.gen = 0;
    studio.closes += 1;
    setState("idle");
    if (message.code !== 1000) {
      showMessage(message.reason || (message.code === 1006
        ? "The live sound was cut off: the studio server cannot be reached."
        : `The live sound stopped (WebSocket closed with code ${message.code}).`));
    }
  }
}

function fromServer(message) {
  if (message.type === "started") {
    live.started = true;
    live.block = message.block;
    live.lead = message.lead;
  } else if (message.type === "error") {
    showMessage(message.error);
  }
}

function latency(heardAt, sent) {
  const ctx = live.ctx;
  const output = 1000 * (ctx.outputLatency || ctx.baseLatency || 0);
  studio.latencies.push(heardAt - sent.sentAt + output);
  studio.changeLatencies.push(heardAt - sent.changedAt + output);
  for (const list of [studio.latencies, studio.changeLatencies]) {
    if (list.length > MAX_LATENCIES) list.splice(0, list.length - MAX_LATENCIES);
  }
}

// Samples played, per socket: a socket's count only grows, so a late or repeated report of an
// old socket can never count twice.
function countPlayed(gen, played) {
  const before = live.playedOf.get(gen) || 0;
  if (played <= before) return;
  studio.samplesPlayed += played - before;
  live.playedOf.set(gen, played);
  if (live.playedOf.size > 8) live.playedOf.delete(live.playedOf.keys().next().value);
}

function fromWorklet(message) {
  if (message.stats) {
    countPlayed(message.gen, message.played);
    studio.buffered = message.buffered;
    studio.maxBufferedFrames = Math.max(studio.maxBufferedFrames, message.maxBuffered);
  } else if (message.heard !== undefined) {
    if (message.gen !== live.gen) return;
    const now = performance.now();
    live.heardId = message.heard;
    live.heardAt = now;
    studio.heardSetId = message.heard;
    for (const [id, sent] of live.pending) {
      if (id <= message.heard) {
        latency(now, sent);
        live.pending.delete(id);
      } else if (now - sent.sentAt > 2000) {
        live.pending.delete(id);  // never heard (the stream slept or refused it)
      }
    }
  } else if (message.underrun) {
    studio.underruns += 1;
    studio.dropouts.push(Math.round(performance.now()));
    if (studio.dropouts.length > 100) studio.dropouts.shift();
  } else if (message.stopped) {
    countPlayed(message.gen, message.played);
  }
}

export function trigger() {
  if (!live.gen) {
    play();
    return;
  }
  send({ type: "trigger" });
}

// A note for the stream (keys.js): a note on opens the live sound if it is not playing; a note
// off or a control change with no stream has nothing to act on and is dropped.
export function sendNote(message) {
  if (live.gen) {
    send(message);
  } else if (live.waiting) {
    live.waiting.push(message);
  } else if (message.type === "note_on") {
    open([message]);
  }
}

export function release() {
  send({ type: "release" });
}

// The worklet fades out over 10 ms and drops what comes after; the worker tells the server
// and closes the socket when the fade is over. A Play right after opens a new socket: the
// generation numbers keep the two apart.
export function stop() {
  live.asked += 1;
  live.waiting = null;
  const gen = live.gen;
  if (!gen) return;
  live.gen = 0;
  live.worker.postMessage({ type: "stop", gen });
  live.node.port.postMessage({ type: "stop", gen });
  setState("idle");
}

// A new voice on the open stream (the server cross-fades), struck at once.
export function restart() {
  if (!live.gen) return;
  send(startMessage());  // the worker drops changes not sent yet: the start has them
  send({ type: "trigger" });
}

// Changes go to the worker, which merges them and sends one set at a time (link.js).
export function queueSet(name, v) {
  if (!live.gen) return;
  live.worker.postMessage({ type: "set", gen: live.gen, parameters: { [name]: v },
    at: performance.timeOrigin + performance.now() });
}

function setState(state) {
  studio.state = state;
  document.body.classList.toggle("playing", state === "playing");
  $("play").classList.toggle("on", state === "playing");
  updateLive();
}

function median(list) {
  if (!list.length) return NaN;
  const sorted = [...list].sort((a, b) => a - b);
  return sorted[Math.floor(sorted.length / 2)];
}

export function updateLive() {
  if (studio.state !== "playing") {
    note("stopped");
    return;
  }
  const rate = live.ctx ? live.ctx.sampleRate : RATE;
  const parts = [`playing at ${rate} Hz`, `buffer ${(1000 * studio.buffered / rate).toFixed(0)} ms`];
  const recent = studio.latencies.slice(-20);
  if (recent.length) parts.push(`change heard after ${median(recent).toFixed(0)} ms`);
  if (studio.underruns) parts.push(`${studio.underruns} dropout${studio.underruns === 1 ? "" : "s"}`);
  note(parts.join(" · "));
}
