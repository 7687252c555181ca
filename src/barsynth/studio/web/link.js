// barsynth studio: the live stream's WebSocket, in a dedicated Worker (docs/studio.md).
//
// Why a worker: the page's main thread draws the pictures, lays the page out and takes
// screenshots; while it relayed the audio, every long task there left the AudioWorklet dry.
// Here the socket's blocks go straight to the worklet over a MessageChannel (each ArrayBuffer
// is transferred, not copied) and the worklet's `played` reports come straight back, so the
// sound depends on this thread and the audio thread only. The page sends control messages and
// gets the server's text messages, open and close events and counters.
//
// Generations: each socket the page opens has a number (gen) the page counts up. Blocks go to
// the worklet tagged with their socket's gen (it drops blocks of an older one) and a played
// report is only sent on the socket of its gen, so nothing of a stopped stream is ever mixed
// into the next one, however quickly Stop and Play follow each other.
//
// Sets: at most one `set` is in flight. The next one (all changes since, merged) goes when the
// server has applied the last (a block header carries its id) or after SET_WAIT_MS, whichever
// is first, and never sooner than SET_EVERY_MS after the last; the last value always goes. A
// change that needs a new design (an all-pass bar: 90-290 ms a value) then costs the server
// one design at a time instead of a queue of them.
//
// From the page: {type: "worklet", port}; {type: "open", gen, url, start: [messages]} (sent
// in order once the socket is open); {type: "send", gen, message}; {type: "set", gen,
// parameters, at}; {type: "stop", gen}.
// To the page: {type: "open", gen}; {type: "message", gen, message} (the server's JSON);
// {type: "close", gen, code, reason}; {type: "sent", gen, id, parameters, at, changedAt} (a set
// went out; times are performance.timeOrigin + performance.now(), the page's clock too);
// {type: "counts", gen, blocks, sets, reports, waiting} at most every TICK_MS.
"use strict";

const SET_EVERY_MS = 20;
const SET_WAIT_MS = 300;  // a set not seen applied by then (refused, or the stream sleeps) stops blocking
const HEARTBEAT_MS = 500;  // a `played` at least this often: the server closes a silent page after 120 s
const STOP_CLOSE_MS = 150;  // close a stopped socket this long after the stop at the latest
const TICK_MS = 50;

let worklet = null;  // the MessagePort to the AudioWorklet
let current = null;  // the socket that sounds now: see open()
const closing = new Map();  // gen -> a stopped stream whose socket is still open
let blocks = 0;  // blocks passed on to the worklet, in all
let sets = 0;  // sets sent, in all
let reports = 0;  // played reports sent, in all (heartbeats too)
let told = "";  // the counts last posted

const now = () => performance.now();
const clock = () => performance.timeOrigin + performance.now();

function isOpen(stream) {
  return stream.ws.readyState === WebSocket.OPEN;
}

function send(stream, message) {
  if (message.type === "start") {  // a start carries every value: changes waiting are in it
    stream.changes = {};
    stream.changedAt = null;
  }
  if (isOpen(stream)) stream.ws.send(JSON.stringify(message));
  else stream.queue.push(message);
}

function open(gen, url, start) {
  if (current) stop(current.gen);  // (the page stops first; this is only a safeguard)
  const stream = {
    gen,
    ws: new WebSocket(url),
    queue: [...start],  // messages waiting for the socket to open
    changes: {},  // parameter changes not sent yet, merged
    changedAt: null,  // when the oldest of them was made
    nextId: 0,
    inFlight: 0,  // the id of the set sent and not yet seen applied (0: none)
    inFlightAt: 0,
    lastSetAt: -Infinity,
    setTimer: 0,
    played: 0,  // the worklet's last report for this gen
    playedAt: now(),  // when a played report last went out
    closeTimer: 0,
  };
  current = stream;
  const ws = stream.ws;
  ws.binaryType = "arraybuffer";
  ws.onopen = () => {
    if (stream !== current) return;  // stopped while connecting: closed by stop()
    for (const message of stream.queue) ws.send(JSON.stringify(message));
    stream.queue = [];
    stream.playedAt = now();
    self.postMessage({ type: "open", gen });
    flushSets(stream);
  };
  ws.onmessage = (event) => {
    if (stream !== current) return;
    if (typeof event.data === "string") {
      const message = JSON.parse(event.data);
      if (message.type === "error" && stream.inFlight) {  // most likely the answer to the set in flight
        stream.inFlight = 0;
        flushSets(stream);
      }
      if (message.type === "started" && worklet) {  // the worklet waits for half the lead before it plays
        worklet.postMessage({ type: "started", gen, lead: message.lead });
      }
      self.postMessage({ type: "message", gen, message });
    } else {
      block(stream, event.data);
    }
  };
  ws.onclose = (event) => {
    clearTimeout(stream.closeTimer);
    clearTimeout(stream.setTimer);
    closing.delete(gen);
    if (stream === current) current = null;
    self.postMessage({ type: "close", gen, code: event.code, reason: event.reason });
  };
}

// A binary frame: uint32 LE block number, uint32 LE set id, then float32 LE samples
// (the worklet reads them in the platform's order, little-endian everywhere browsers run).
function block(stream, buffer) {
  if (buffer.byteLength < 8 || !worklet) return;
  const setId = new DataView(buffer, 0, 8).getUint32(4, true);
  blocks += 1;
  worklet.postMessage({ type: "block", gen: stream.gen, buffer, offset: 8, setId }, [buffer]);
  if (stream.inFlight && setId >= stream.inFlight) {  // applied: the next set may go
    stream.inFlight = 0;
    if (Object.keys(stream.changes).length) flushSets(stream);
  }
}

function queueSet(stream, parameters, at) {
  Object.assign(stream.changes, parameters);
  if (stream.changedAt === null) stream.changedAt = at;
  if (!stream.setTimer) flushSets(stream);
}

// Send the merged changes if the last set is applied (or SET_WAIT_MS old) and SET_EVERY_MS
// has passed; otherwise try again when it may be.
function flushSets(stream) {
  clearTimeout(stream.setTimer);
  stream.setTimer = 0;
  if (stream !== current || !isOpen(stream) || Object.keys(stream.changes).length === 0) return;
  const t = now();
  let wait = stream.lastSetAt + SET_EVERY_MS - t;
  if (stream.inFlight) wait = Math.max(wait, stream.inFlightAt + SET_WAIT_MS - t);
  if (wait > 0) {
    stream.setTimer = setTimeout(() => flushSets(stream), wait);
    return;
  }
  const id = ++stream.nextId;
  const parameters = stream.changes;
  stream.ws.send(JSON.stringify({ type: "set", id, parameters }));
  self.postMessage({ type: "sent", gen: stream.gen, id, parameters, at: clock(), changedAt: stream.changedAt });
  stream.changes = {};
  stream.changedAt = null;
  stream.inFlight = id;
  stream.inFlightAt = t;
  stream.lastSetAt = t;
  sets += 1;
}

function played(stream, samples) {
  stream.played = samples;
  stream.playedAt = now();
  stream.ws.send(JSON.stringify({ type: "played", samples }));
  reports += 1;
}

// The stream fades out (the server's and the worklet's 10 ms); the socket closes when the
// worklet says its fade is over, or after STOP_CLOSE_MS.
function stop(gen) {
  const stream = current;
  if (!stream || stream.gen !== gen) return;
  current = null;
  clearTimeout(stream.setTimer);
  stream.setTimer = 0;
  const ws = stream.ws;
  if (ws.readyState === WebSocket.CONNECTING) {
    ws.close(1000, "stopped");  // (throws nothing; onopen will not run)
    return;
  }
  if (ws.readyState !== WebSocket.OPEN) return;
  ws.send(JSON.stringify({ type: "stop" }));
  stream.closeTimer = setTimeout(() => close(stream), STOP_CLOSE_MS);
  closing.set(gen, stream);
}

function close(stream) {
  clearTimeout(stream.closeTimer);
  closing.delete(stream.gen);
  const ws = stream.ws;
  if (ws.readyState === WebSocket.OPEN || ws.readyState === WebSocket.CONNECTING) ws.close(1000, "stopped");
}

function fromWorklet(message) {
  if (message.type === "played") {
    const stream = current;
    if (stream && stream.gen === message.gen && isOpen(stream)) played(stream, message.samples);
  } else if (message.type === "stopped") {
    const stream = closing.get(message.gen);
    if (stream) close(stream);
  }
}

self.onmessage = (event) => {
  const message = event.data;
  const stream = current && current.gen === message.gen ? current : null;
  if (message.type === "worklet") {
    worklet = message.port;
    worklet.onmessage = (e) => fromWorklet(e.data);
  } else if (message.type === "open") {
    open(message.gen, message.url, message.start);
  } else if (message.type === "send") {
    if (stream) send(stream, message.message);
  } else if (message.type === "set") {
    if (stream) queueSet(stream, message.parameters, message.at);
  } else if (message.type === "stop") {
    stop(message.gen);
  }
};

// The heartbeat (a sleeping stream sends nothing, so the worklet has nothing to report; the
// server would close a stream that says nothing for 120 s) and the page's counters.
setInterval(() => {
  const stream = current;
  if (stream && isOpen(stream) && now() - stream.playedAt >= HEARTBEAT_MS) played(stream, stream.played);
  const waiting = !!stream && (stream.inFlight !== 0 || Object.keys(stream.changes).length > 0);
  const counts = { type: "counts", gen: stream ? stream.gen : 0, blocks, sets, reports, waiting };
  const text = JSON.stringify(counts);
  if (text !== told) {
    told = text;
    self.postMessage(counts);
  }
}, TICK_MS);
