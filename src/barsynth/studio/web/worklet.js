// barsynth studio: the AudioWorklet that plays the samples the server streams.
//
// The page forwards each block it receives ({type: "block", buffer, offset, setId}); this
// processor keeps them in a FIFO ring buffer and plays them out, one render quantum at a time.
// Every 256 frames it posts {played: frames taken from the buffer in all, buffered, maxBuffered}
// so the page can tell the server how far it has got (flow control). When it starts playing
// the first frame of a block whose set id is higher than any heard before, it posts
// {heard: id} (the page measures how long a change took to reach the speakers).
//
// If the buffer runs dry (no more than one render quantum left), what is left is played with
// a linear fade to zero and then silence; when more than a quantum is back, it fades in over
// 128 frames (the very start too). "stop" fades out over 10 ms (or over what is buffered, if
// less), then empties the buffer. process() allocates nothing but its reports.
"use strict";

const CAPACITY = 1 << 17;  // frames (2.7 s at 48 kHz): far more than the server ever sends ahead
const MASK = CAPACITY - 1;
const REPORT_EVERY = 256;
const FADE_IN = 128;
const MAX_MARKS = 4096;
const AUDIBLE = 1e-4;  // a buffer running dry below this level (-80 dBFS) is no audible underrun

class StreamPlayer extends AudioWorkletProcessor {
  constructor() {
    super();
    this.ring = new Float32Array(CAPACITY);
    this.marks = new Float64Array(MAX_MARKS * 2);  // [start frame, set id] of queued blocks, a ring too
    this.reset();
    this.port.onmessage = (event) => this.receive(event.data);
  }

  reset() {
    this.written = 0;  // frames written in all
    this.read = 0;  // frames read (played) in all
    this.markHead = 0;
    this.markTail = 0;
    this.heardId = -1;
    this.lastReport = 0;
    this.maxBuffered = 0;
    this.gain = 1;  // the gain of the last frame played (0 after running dry)
    this.fadeIn = 0;  // frames of fade-in left
    this.dry = true;  // nothing to play: wait for more than a quantum, then fade in
    this.stopFrames = 0;  // > 0: fading out for a stop over this many frames
    this.stopLeft = 0;
    this.stopped = false;
    this.lastLevel = 0;
  }

  receive(message) {
    if (message.type === "block") {
      if (this.stopped || this.stopLeft > 0) return;  // a block that was in flight at the stop
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
    } else if (message.type === "stop") {
      // 10 ms, or what is buffered if that is less: the fade always reaches zero
      this.stopFrames = Math.max(1, Math.min(Math.round(0.010 * sampleRate), this.written - this.read));
      this.stopLeft = this.stopFrames;
      this.stopped = false;
    } else if (message.type === "reset") {
      this.reset();
    }
  }

  process(_inputs, outputs) {
    const out = outputs[0][0];
    if (!out) return true;
    const quantum = out.length;
    const available = this.written - this.read;
    let r = this.read & MASK;

    if (this.stopLeft > 0) {  // stopping: what is buffered, fading out over 10 ms
      const from = this.dry ? 0 : this.fadeIn > 0 ? 1 - this.fadeIn / FADE_IN : 1;
      let i = 0;
      for (; i < available && i < quantum && this.stopLeft > 0; i++) {
        this.stopLeft -= 1;
        out[i] = this.ring[r] * from * (this.stopLeft / this.stopFrames);
        r = (r + 1) & MASK;
      }
      this.read += i;
      out.fill(0, i);
      if (this.stopLeft === 0 || i < quantum) {
        const played = this.read;
        this.reset();
        this.stopped = true;
        this.port.postMessage({ stopped: true, played });
      }
      return true;
    }

    if (this.dry && available > quantum) {  // samples are back: fade in over 128 frames
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
      if (this.lastLevel > AUDIBLE || peak > AUDIBLE) this.port.postMessage({ underrun: true });
      this.dry = true;
      this.fadeIn = 0;
      this.gain = 0;
    }
    this.read += n;
    this.lastLevel = peak;
    if (this.read - this.lastReport >= REPORT_EVERY) {
      this.lastReport = this.read;
      this.port.postMessage({ played: this.read, buffered: this.written - this.read, maxBuffered: this.maxBuffered });
      this.maxBuffered = this.written - this.read;
    }
    return true;
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
      this.port.postMessage({ heard: newest });
    }
  }
}

registerProcessor("barsynth-stream", StreamPlayer);
