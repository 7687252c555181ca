// barsynth studio: the AudioWorklet that plays the samples the server streams.
//
// The blocks come straight from the stream's Worker (link.js) over a MessageChannel whose port
// the page hands over once ({type: "link", port}); the page's main thread is not on the audio's
// way, so drawing or a screenshot there cannot run the buffer dry. Each block is
// {type: "block", gen, buffer, offset, setId} (and the server's lead comes as {type: "started",
// gen, lead}); this processor keeps them in a FIFO ring buffer and plays them out, one render
// quantum at a time.
//
// Generations: every socket the page opens has a number (gen), counted up. A block of an older
// gen than the newest seen is dropped (it was in flight at a Stop); a block of a newer one
// starts that gen at once, even if the page's {type: "reset", gen} is still on its way. So
// the samples of two sockets are never mixed, whatever order the two ports deliver in.
//
// Reports:
// - to the worker, over the link: {type: "played", gen, samples} every 256 frames and when the
//   buffer runs dry (frames of this gen taken from the buffer in all: the server's flow
//   control); {type: "stopped", gen} when a stop's fade is over (the socket may close).
// - to the page, on this.port: {stats: true, gen, played, buffered, maxBuffered} every 1024
//   frames and when running dry; {heard: id, gen} the moment the first frame of a block with a
//   higher set id than any before is played (the page measures how long a change took);
//   {underrun: true, gen}; {stopped: true, gen, played} with the gen's final count.
//
// If the buffer runs dry (no more than one render quantum left), what is left is played with
// a linear fade to zero and then silence; when more than a quantum (and half the server's lead,
// from {type: "started", gen, lead} passed on by the worker) is back, it fades in over 128
// frames (the very start too). {type: "stop", gen} fades out over 10 ms (or over what is
// buffered, if less) and drops the rest; a new gen starting while the old one still sounds
// does the same to the old one first. process() allocates nothing but its reports.
"use strict";

const CAPACITY = 1 << 17;  // frames (2.7 s at 48 kHz): far more than the server ever sends ahead
const MASK = CAPACITY - 1;
const REPORT_EVERY = 256;  // frames between played reports (the server's lead is only 1536)
const STATS_EVERY = 1024;  // frames between figures for the page: it only shows them
const FADE_IN = 128;
const STOP_S = 0.010;
const MAX_MARKS = 4096;
const AUDIBLE = 1e-4;  // a buffer running dry below this level (-80 dBFS) is no audible underrun

class StreamPlayer extends AudioWorkletProcessor {
  constructor() {
    super();
    this.ring = new Float32Array(CAPACITY);
    this.marks = new Float64Array(MAX_MARKS * 2);  // [start frame, set id] of queued blocks, a ring too
    this.link = null;  // the port to the stream's worker
    this.written = 0;  // frames written in all (every gen)
    this.read = 0;  // frames read (played) in all
    this.gain = 1;  // the gain of the last frame played (0 after running dry)
    this.fadeIn = 0;  // frames of fade-in left
    this.dry = true;  // nothing to play: wait for more than a quantum, then fade in
    this.lastLevel = 0;
    this.stopFrames = 0;  // > 0: fading out over this many frames
    this.stopLeft = 0;
    this.stopping = null;  // {gen, played}: told when the fade is over
    this.gen = 0;
    this.begin(0);
    this.port.onmessage = (event) => this.receive(event.data);
  }

  // A new socket's samples start after whatever is (still) buffered for the fade.
  begin(gen) {
    if (this.gen !== gen) this.fadeOut();  // the old socket's sound ends in a fade, not a step
    this.gen = gen;
    this.start = this.written;  // this gen's first frame
    this.stopped = false;  // true once this gen is stopped: its blocks are dropped
    this.markHead = 0;
    this.markTail = 0;
    this.heardId = -1;
    this.lastReport = 0;
    this.lastStats = 0;
    this.maxBuffered = 0;
    this.lead = 0;  // the server's lead (frames), once the worker has passed on its `started`
  }

  // Fade out what sounds now over 10 ms (or over what is buffered, if less) and drop the rest
  // of the buffer. Returns whether a fade began (false: nothing sounded, or a fade is running).
  fadeOut() {
    if (this.stopLeft > 0) {  // already fading: what was queued behind it never sounded
      this.written = this.read + this.stopLeft;
      return false;
    }
    const buffered = this.written - this.read;
    if (this.dry || buffered === 0) {
      this.written = this.read;
      return false;
    }
    this.stopFrames = Math.min(Math.round(STOP_S * sampleRate), buffered);
    this.stopLeft = this.stopFrames;
    this.written = this.read + this.stopLeft;
    return true;
  }

  setLink(port) {
    this.link = port;
    port.onmessage = (event) => this.receive(event.data);
  }

  receive(message) {
    const gen = message.gen || 0;
    if (message.type === "block") {
      this.block(message, gen);
    } else if (message.type === "started") {
      if (gen > this.gen) this.begin(gen);
      if (gen === this.gen) this.lead = message.lead;
    } else if (message.type === "link") {
      this.setLink(message.port);
    } else if (message.type === "reset") {
      if (gen > this.gen) this.begin(gen);  // (a block of this gen may have begun it already)
    } else if (message.type === "stop") {
      if (gen !== this.gen || this.stopped) return;
      this.stopped = true;
      const played = Math.max(0, this.read - this.start);
      if (this.fadeOut()) {
        this.stopping = { gen, played: played + this.stopLeft };
      } else {  // nothing of this gen sounds: stopped now
        this.ended(gen, played);
      }
    }
  }

  block(message, gen) {
    if (gen < this.gen) return;  // an old socket's, in flight at the stop
    if (gen > this.gen) this.begin(gen);  // its reset is still on its way
    if (this.stopped) return;  // in flight at the stop
    const samples = new Float32Array(message.buffer, message.offset);
    let n = samples.length;
    if (this.written - this.read + n > CAPACITY) n = CAPACITY - (this.written - this.read);  // never overwrite
    if (n <= 0) return;
    if (this.markTail - this.markHead < MAX_MARKS) {
      const k = (this.markTail % MAX_MARKS) * 2;
      this.marks[k] = this.written;
      this.marks[k + 1] = message.setId;
      this.markTail += 1;
    }
    let w = this.written & MASK;
    for (let i = 0; i < n; i++) {
      this.ring[w] = samples[i];
      w = (w + 1) & MASK;
    }
    this.written += n;
    const buffered = this.written - this.read;
    if (buffered > this.maxBuffered) this.maxBuffered = buffered;
  }

  ended(gen, played) {
    this.port.postMessage({ stopped: true, gen, played });
    if (this.link) this.link.postMessage({ type: "stopped", gen });
  }

  process(_inputs, outputs) {
    const out = outputs[0][0];
    if (!out) return true;
    const quantum = out.length;
    let r = this.read & MASK;

    if (this.stopLeft > 0) {  // fading out what was buffered (written - read >= stopLeft)
      const from = this.fadeIn > 0 ? 1 - this.fadeIn / FADE_IN : 1;
      let i = 0;
      for (; i < quantum && this.stopLeft > 0; i++) {
        this.stopLeft -= 1;
        out[i] = this.ring[r] * from * (this.stopLeft / this.stopFrames);
        r = (r + 1) & MASK;
      }
      this.read += i;
      out.fill(0, i);
      if (this.stopLeft === 0) {  // a new gen's samples (if any) fade in from the next quantum
        this.dry = true;
        this.fadeIn = 0;
        this.gain = 0;
        this.lastLevel = 0;
        if (this.stopping) {
          this.ended(this.stopping.gen, this.stopping.played);
          this.stopping = null;
        }
      }
      return true;
    }

    const available = this.written - this.read;
    // Samples are back: fade in over 128 frames. Half the server's lead first, when it is known:
    // a stream's first block (or the first after a stall) often comes alone, and playing it at
    // once runs dry again a few ms later. This costs nothing after: the server keeps the buffer
    // at the lead whatever this waits for.
    if (this.dry && available > quantum && available >= this.lead / 2) {
      this.dry = false;
      this.fadeIn = FADE_IN;
    }
    if (this.dry || available === 0) {  // nothing to play (yet): silence, and keep what little there is
      out.fill(0);
      return true;
    }

    let n = quantum;
    let peak = 0;
    this.heard(Math.min(quantum, available));
    if (available > quantum) {  // the usual case: a full quantum, more behind it
      for (let i = 0; i < quantum; i++) {
        let g = 1;
        if (this.fadeIn > 0) {
          g = 1 - this.fadeIn / FADE_IN;
          this.fadeIn -= 1;
        }
        const x = this.ring[r] * g;
        out[i] = x;
        if (x > peak) peak = x; else if (-x > peak) peak = -x;
        r = (r + 1) & MASK;
      }
      this.gain = 1;
    } else {  // the last frames buffered: play them fading out to zero, then silence
      n = available;
      const from = this.fadeIn > 0 ? 1 - this.fadeIn / FADE_IN : this.gain;
      for (let i = 0; i < n; i++) {
        const x = this.ring[r] * from * (1 - (i + 1) / n);
        out[i] = x;
        if (x > peak) peak = x; else if (-x > peak) peak = -x;
        r = (r + 1) & MASK;
      }
      out.fill(0, n);
      if (this.lastLevel > AUDIBLE || peak > AUDIBLE) this.port.postMessage({ underrun: true, gen: this.gen });
      this.dry = true;
      this.fadeIn = 0;
      this.gain = 0;
    }
    this.read += n;
    this.lastLevel = peak;
    this.report();
    return true;
  }

  // Played reports for the worker (and so the server), figures for the page. Running dry is
  // reported at once: the server then knows exactly how far the page got.
  report() {
    const played = this.read - this.start;
    if (this.link && (played - this.lastReport >= REPORT_EVERY || (this.dry && played !== this.lastReport))) {
      this.lastReport = played;
      this.link.postMessage({ type: "played", gen: this.gen, samples: played });
    }
    if (played - this.lastStats >= STATS_EVERY || (this.dry && played !== this.lastStats)) {
      this.lastStats = played;
      const buffered = this.written - this.read;
      this.port.postMessage({ stats: true, gen: this.gen, played, buffered, maxBuffered: this.maxBuffered });
      this.maxBuffered = buffered;
    }
  }

  // The first frame of a block is about to be played: post a higher set id than any before.
  heard(n) {
    const end = this.read + n;
    let newest = -1;
    while (this.markHead < this.markTail) {
      const k = (this.markHead % MAX_MARKS) * 2;
      if (this.marks[k] >= end) break;
      if (this.marks[k + 1] > newest) newest = this.marks[k + 1];
      this.markHead += 1;
    }
    if (newest > this.heardId) {
      this.heardId = newest;
      this.port.postMessage({ heard: newest, gen: this.gen });
    }
  }
}

registerProcessor("barsynth-stream", StreamPlayer);
