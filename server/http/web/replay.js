// A recorded session played back: the tissue's surface frames (server/session/trace_recorder.h:
// int16 displacements from rest, each frame sent as its difference from the one before, deflated,
// base64) interpolated on a timeline, a cut's faces as they were at each moment (the record's
// topology changes), with the traces' cursor. Keyboard: the timeline is a range
// input (arrows step, Home/End), the button plays and pauses.
import { el } from './dom.js';

// The frames of a record: inflate (the browser's own DecompressionStream), then each frame the
// running sum of the differences (Int16Array arithmetic wraps modulo 2^16, as they were made).
async function decode(f) {
  if (!f || !f.deflated || !f.time_s.length) return [];
  const bin = atob(f.deflated), packed = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; ++i) packed[i] = bin.charCodeAt(i);
  const stream = new Blob([packed]).stream().pipeThrough(new DecompressionStream('deflate'));
  const all = new Int16Array(await new Response(stream).arrayBuffer());  // little-endian hosts
  const n = 3 * f.vertices, frames = [];
  let sum = new Int16Array(n);
  for (let k = 0; k < f.time_s.length; ++k) {
    const next = new Int16Array(n), d = all.subarray(k * n, (k + 1) * n);
    for (let i = 0; i < n; ++i) next[i] = sum[i] + d[i];
    frames.push(next); sum = next;
  }
  return frames;
}

export class Replay {
  // record: the trace JSON; view: a TissueView of record.rest (or null); onTime(t): traces' cursor.
  static async load(record, view, onTime) { return new Replay(record, await decode(record.frames), view, onTime); }
  constructor(record, frames, view, onTime) {
    this.view = view; this.onTime = onTime;
    const f = record.frames || { time_s: [] };
    this.times = f.time_s; this.unit = f.unit_mm || 0.01;
    this.frames = frames;
    this.topology = record.topology && record.topology.time_s ? record.topology : null;
    this.restTris = record.rest && record.rest.triangles ? Uint32Array.from(record.rest.triangles) : null;
    this.changesShown = 0;
    const series = record.series && record.series.time_s ? record.series.time_s : [];
    this.t0 = Math.min(series.length ? series[0] : 0, this.times.length ? this.times[0] : Infinity);
    this.t1 = Math.max(series.length ? series[series.length - 1] : 0, this.times.length ? this.times[this.times.length - 1] : 0);
    this.time = this.t0; this.playing = false;
    this.slider = el('input', { type: 'range', id: 'timeline', min: this.t0, max: this.t1, step: 0.05, value: this.t0,
      'aria-label': 'Replay time', 'data-frames': this.frames.length });
    this.label = el('output', { id: 'replay-time', for: 'timeline' });
    this.button = el('button', { type: 'button', id: 'play', 'aria-pressed': 'false' }, 'Play');
    this.slider.addEventListener('input', () => { this.pause(); this.seek(Number(this.slider.value)); });
    this.button.addEventListener('click', () => (this.playing ? this.pause() : this.play()));
    this.controls = el('div', { class: 'replay-controls' }, this.button, this.slider, this.label);
    this.seek(this.t1);  // opens on the end state: what the trial left
  }
  seek(t) {
    this.time = Math.min(this.t1, Math.max(this.t0, t));
    this.slider.value = this.time;
    const text = `${this.time.toFixed(1)} s of ${this.t1.toFixed(1)} s`;
    this.label.textContent = text;
    this.slider.setAttribute('aria-valuetext', text);
    if (this.onTime) this.onTime(this.time);  // first: it may set what the view draws with the frame
    if (this.view && this.topology) this.showTopology(this.time);
    if (this.view && this.frames.length) this.view.setDisplacement(this.at(this.time), this.unit);
  }
  // A cut's faces as they were at `t`: the rest triangles with every change up to then applied in
  // turn (a removed face is 0, 0, 0 and draws nothing). Rebuilt only when `t` crossed a change.
  showTopology(t) {
    const T = this.topology.time_s;
    let k = 0;
    while (k < T.length && T[k] <= t) ++k;
    if (k === this.changesShown && this.view.canvas.dataset.cut !== undefined) return;
    const tris = Uint32Array.from(this.restTris);
    const faces = new Set();
    for (let c = 0; c < k; ++c) {
      const F = this.topology.faces[c];
      for (let i = 0; i + 3 < F.length; i += 4) {
        const f = F[i];
        if (3 * f + 2 >= tris.length) continue;
        tris[3 * f] = F[i + 1]; tris[3 * f + 1] = F[i + 2]; tris[3 * f + 2] = F[i + 3];
        faces.add(f);
      }
    }
    this.changesShown = k;
    this.view.setTriangles(tris);
    this.view.canvas.dataset.cut = String(faces.size);  // faces the cut has changed by then
  }
  // The displacement at `t`, linear between the two frames around it (before the first: rest).
  at(t) {
    const T = this.times, n = T.length;
    if (t < T[0]) return new Int16Array(this.frames[0].length);  // before the first: at rest
    if (t === T[0]) return this.frames[0];
    if (t >= T[n - 1]) return this.frames[n - 1];
    let k = 1;
    while (T[k] < t) ++k;
    const a = (t - T[k - 1]) / (T[k] - T[k - 1]), A = this.frames[k - 1], B = this.frames[k];
    const out = new Float32Array(A.length);
    for (let i = 0; i < A.length; ++i) out[i] = A[i] + a * (B[i] - A[i]);
    return out;
  }
  play() {
    if (this.time >= this.t1) this.seek(this.t0);
    this.playing = true; this.button.textContent = 'Pause'; this.button.setAttribute('aria-pressed', 'true');
    let last = performance.now();
    const step = (now) => {
      if (!this.playing) return;
      this.seek(this.time + (now - last) / 1000); last = now;
      if (this.time >= this.t1) return this.pause();
      requestAnimationFrame(step);
    };
    requestAnimationFrame(step);
  }
  pause() { this.playing = false; this.button.textContent = 'Play'; this.button.setAttribute('aria-pressed', 'false'); }
}
