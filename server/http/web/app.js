// vsurg dashboard. One script for every page (body[data-page]); no framework, no CDN.
// Every text from the server goes into the page through textContent, never as HTML.
'use strict';

const PAGES = [
  { page: 'live', title: 'Live stations', roles: ['instructor', 'admin'] },
  { page: 'evaluate', title: 'Evaluate', roles: ['evaluator', 'admin'] },
  { page: 'reports', title: 'Reports', roles: ['instructor', 'evaluator', 'admin'] },
  { page: 'admin', title: 'Administration', roles: ['admin'] },
  { page: 'mine', title: 'My sessions', roles: ['trainee', 'admin'] },
];

let me = null;  // {user, role, group, csrf}

// ---- small DOM helpers ----
function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === 'class') e.className = v;
    else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null && v !== false) e.setAttribute(k, v === true ? '' : v);
  }
  for (const c of children.flat()) {
    if (c === null || c === undefined) continue;
    e.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return e;
}
const $ = (sel) => document.querySelector(sel);
function fmt(x, digits) {
  return (x === null || x === undefined || !isFinite(x)) ? '—' : Number(x).toFixed(digits);
}
function message(target, text, ok) {
  target.replaceChildren(el('div', { class: 'msg ' + (ok ? 'ok' : 'error') }, text));
}

// ---- the API ----
async function api(method, path, body) {
  const opts = { method, credentials: 'same-origin', headers: {} };
  if (method !== 'GET') {
    opts.headers['X-CSRF-Token'] = me ? me.csrf : '';
    if (body !== undefined) {
      opts.headers['Content-Type'] = 'application/json';
      opts.body = typeof body === 'string' ? body : JSON.stringify(body);
    }
  }
  const res = await fetch('/api/v1' + path, opts);
  if (res.status === 401 && document.body.dataset.page !== 'signin') {
    location.href = '/signin?next=' + encodeURIComponent(document.body.dataset.page);
    throw new Error('signed out');
  }
  const text = await res.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch (e) { data = { error: text }; }
  if (!res.ok) {
    const err = new Error((data && data.error) || res.statusText);
    err.status = res.status;
    throw err;
  }
  return data;
}

// ---- plots: a scrolling window of the last `span` seconds ----
class Plot {
  constructor(canvas, series, unit, span) {
    this.canvas = canvas; this.series = series; this.unit = unit; this.span = span || 30;
    this.data = series.map(() => []);
  }
  add(t, values) {
    values.forEach((v, i) => { if (isFinite(v)) this.data[i].push([t, v]); });
    for (const d of this.data) while (d.length && d[0][0] < t - this.span) d.shift();
    this.now = t;
  }
  draw() {
    const c = this.canvas, dpr = window.devicePixelRatio || 1;
    const w = c.clientWidth, h = c.clientHeight;
    if (c.width !== w * dpr) { c.width = w * dpr; c.height = h * dpr; }
    const g = c.getContext('2d');
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, w, h);
    let lo = Infinity, hi = -Infinity;
    for (const d of this.data) for (const [, v] of d) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    if (!isFinite(lo)) { lo = 0; hi = 1; }
    if (hi - lo < 1e-9) { hi += 0.5; lo -= 0.5; }
    const pad = (hi - lo) * 0.08; lo -= pad; hi += pad;
    const L = 52, R = 8, T = 8, B = 18, t1 = this.now || 0, t0 = t1 - this.span;
    const X = (t) => L + (t - t0) / this.span * (w - L - R);
    const Y = (v) => T + (1 - (v - lo) / (hi - lo)) * (h - T - B);
    g.strokeStyle = '#3a4252'; g.fillStyle = '#9aa3b2'; g.font = '11px system-ui'; g.lineWidth = 1;
    for (let k = 0; k <= 4; ++k) {
      const v = lo + (hi - lo) * k / 4, y = Y(v);
      g.beginPath(); g.moveTo(L, y); g.lineTo(w - R, y); g.stroke();
      g.fillText(v.toPrecision(3), 4, y + 4);
    }
    g.fillText('−' + this.span + ' s', L, h - 4);
    g.fillText(this.unit, w - R - g.measureText(this.unit).width, h - 4);
    this.series.forEach((s, i) => {
      g.strokeStyle = s.colour; g.lineWidth = 2; g.beginPath();
      this.data[i].forEach(([t, v], k) => (k ? g.lineTo(X(t), Y(v)) : g.moveTo(X(t), Y(v))));
      g.stroke();
      g.fillStyle = s.colour; g.fillText(s.name, L + 8 + i * 110, T + 12);
    });
  }
}

// A static chart: lines through points {x, y} per series.
function lineChart(canvas, series, xLabel, yLabel) {
  const c = canvas, dpr = window.devicePixelRatio || 1, w = c.clientWidth, h = c.clientHeight;
  c.width = w * dpr; c.height = h * dpr;
  const g = c.getContext('2d');
  g.setTransform(dpr, 0, 0, dpr, 0, 0);
  let x0 = Infinity, x1 = -Infinity, y0 = 0, y1 = 10;
  for (const s of series) for (const p of s.points) {
    x0 = Math.min(x0, p.x); x1 = Math.max(x1, p.x); y0 = Math.min(y0, p.y); y1 = Math.max(y1, p.y);
  }
  if (!isFinite(x0)) { x0 = 0; x1 = 1; }
  if (x1 === x0) { x0 -= 1; x1 += 1; }
  const L = 40, R = 10, T = 10, B = 30;
  const X = (x) => L + (x - x0) / (x1 - x0) * (w - L - R), Y = (y) => T + (1 - (y - y0) / (y1 - y0)) * (h - T - B);
  g.strokeStyle = '#3a4252'; g.fillStyle = '#9aa3b2'; g.font = '11px system-ui';
  for (let k = 0; k <= 5; ++k) {
    const v = y0 + (y1 - y0) * k / 5, y = Y(v);
    g.beginPath(); g.moveTo(L, y); g.lineTo(w - R, y); g.stroke(); g.fillText(v.toFixed(1), 4, y + 4);
  }
  g.fillText(xLabel, L, h - 6); g.fillText(yLabel, w - R - g.measureText(yLabel).width, h - 6);
  const colours = ['#f0b296', '#8cc8ff', '#5fd38a', '#f3c13a', '#d49cff'];
  series.forEach((s, i) => {
    const col = colours[i % colours.length];
    g.strokeStyle = col; g.fillStyle = col; g.lineWidth = 2; g.beginPath();
    s.points.forEach((p, k) => (k ? g.lineTo(X(p.x), Y(p.y)) : g.moveTo(X(p.x), Y(p.y))));
    g.stroke();
    for (const p of s.points) { g.beginPath(); g.arc(X(p.x), Y(p.y), 3, 0, 7); g.fill(); }
    g.fillText(s.name, L + 8 + i * 140, T + 12);
  });
}

// ---- the tissue in 3D (WebGL2): the rest surface, moved by the telemetry's surface states ----
// The station's look (client/render/shaders.cpp) in a browser: skin with wrapped (subsurface)
// diffuse, wet organs with a second sharp lobe, tone and vessels that move with the tissue (a
// value noise at each point's rest position: per vertex for the broad pattern, per pixel for pores
// and their bump), a drape-covered table under it with the tissue's soft contact shadow.
// Positions in mm, as the server sends them.
const kLooks = {  // albedo (linear), roughness, wet lobe, pore scale (per mm)
  skin: { albedo: [0.66, 0.41, 0.30], rough: 0.52, wet: 0, pores: 1.3 },
  organ: { albedo: [0.32, 0.075, 0.055], rough: 0.42, wet: 0.9, pores: 0.7 },
  kidney: { albedo: [0.20, 0.042, 0.030], rough: 0.40, wet: 0.9, pores: 0.8 },
};
// A value noise in [0, 1) over a lattice of hashed corners, smoothly interpolated.
function hash3(x, y, z) {
  let h = Math.imul(x, 374761393) ^ Math.imul(y, 668265263) ^ Math.imul(z, 2147483647);
  h = Math.imul(h ^ (h >>> 13), 1274126177);
  return ((h ^ (h >>> 16)) >>> 0) / 4294967296;
}
function valueNoise(x, y, z) {
  const ix = Math.floor(x), iy = Math.floor(y), iz = Math.floor(z);
  const s = (t) => t * t * (3 - 2 * t);
  const fx = s(x - ix), fy = s(y - iy), fz = s(z - iz);
  let v = 0;
  for (let c = 0; c < 8; ++c) {
    const a = c & 1, b = (c >> 1) & 1, d = (c >> 2) & 1;
    v += (a ? fx : 1 - fx) * (b ? fy : 1 - fy) * (d ? fz : 1 - fz) * hash3(ix + a, iy + b, iz + d);
  }
  return v;
}
class TissueView {
  constructor(canvas, surface, scene) {
    this.canvas = canvas;
    const gl = canvas.getContext('webgl2', { preserveDrawingBuffer: true, antialias: true });
    if (!gl) throw new Error('WebGL2 is not available');
    this.gl = gl;
    this.look = kLooks[(scene && scene.material) || 'skin'] || kLooks.skin;
    this.up = scene && scene.limb ? [0, 1, 0] : [0, 0, 1];
    this.rest = new Float32Array(surface.positions_mm);
    this.pos = new Float32Array(this.rest);
    this.tris = new Uint32Array(surface.triangles);
    const n = this.rest.length / 3;
    let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (let i = 0; i < n; ++i) for (let a = 0; a < 3; ++a) {
      lo[a] = Math.min(lo[a], this.rest[3 * i + a]); hi[a] = Math.max(hi[a], this.rest[3 * i + a]);
    }
    this.lo = lo; this.hi = hi;
    this.centre = lo.map((l, a) => (l + hi[a]) / 2);
    this.radius = Math.max(1, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
    this.yaw = this.up[1] ? 1.1 : 0.6; this.pitch = 0.45;
    // The broad pattern per vertex: tone (blotches of ~2 cm) and vessels (the ridges of a
    // noise of ~1.5 cm), at the rest position, so they twist with the tissue.
    this.broad = new Float32Array(n * 2);
    for (let i = 0; i < n; ++i) {
      const x = this.rest[3 * i], y = this.rest[3 * i + 1], z = this.rest[3 * i + 2];
      const tone = 0.65 * valueNoise(x / 22, y / 22, z / 22) + 0.35 * valueNoise(x / 11, y / 11, z / 11);
      const ridge = 1 - Math.abs(2 * valueNoise(x / 14 + 7, y / 14, z / 14) - 1);
      this.broad[2 * i] = tone; this.broad[2 * i + 1] = Math.pow(ridge, 12);
    }
    const vs = `#version 300 es
      layout(location = 0) in vec3 aPos; layout(location = 1) in vec3 aNormal;
      layout(location = 2) in vec3 aRest; layout(location = 3) in vec2 aBroad;
      uniform mat4 uM; out vec3 vWorld; out vec3 vNormal; out vec3 vRest; out vec2 vBroad;
      void main() { gl_Position = uM * vec4(aPos, 1.0); vWorld = aPos; vNormal = aNormal;
        vRest = aRest; vBroad = aBroad; }`;
    const fs = `#version 300 es
      precision highp float;
      in vec3 vWorld; in vec3 vNormal; in vec3 vRest; in vec2 vBroad; out vec4 colour;
      uniform vec3 uView; uniform vec3 uKey; uniform vec3 uUp; uniform vec3 uAlbedo;
      uniform float uRough; uniform float uWet; uniform float uPores; uniform int uTable;
      uniform float uTableHeight; uniform vec3 uFootCentre; uniform vec2 uFootHalf;
      const float PI = 3.14159265;
      float hash(vec3 p) { p = fract(p * 0.3183099 + 0.1); p *= 17.0; return fract(p.x * p.y * p.z * (p.x + p.y + p.z)); }
      float noise(vec3 x) { vec3 i = floor(x), f = fract(x); f = f * f * (3.0 - 2.0 * f);
        return mix(mix(mix(hash(i), hash(i + vec3(1, 0, 0)), f.x), mix(hash(i + vec3(0, 1, 0)), hash(i + vec3(1, 1, 0)), f.x), f.y),
                   mix(mix(hash(i + vec3(0, 0, 1)), hash(i + vec3(1, 0, 1)), f.x), mix(hash(i + vec3(0, 1, 1)), hash(i + vec3(1, 1, 1)), f.x), f.y), f.z); }
      float ggx(vec3 n, vec3 v, vec3 l, float r) { vec3 h = normalize(v + l); float a = r * r, a2 = a * a;
        float nh = max(dot(n, h), 0.0), d = nh * nh * (a2 - 1.0) + 1.0; float nl = max(dot(n, l), 0.0), nv = max(dot(n, v), 1e-3);
        float f = 0.028 + 0.972 * pow(1.0 - max(dot(v, h), 0.0), 5.0);
        return a2 / (PI * d * d) * f * nl * 0.5 / (nl * sqrt(nv * nv * (1.0 - a2) + a2) + nv * sqrt(nl * nl * (1.0 - a2) + a2) + 1e-5); }
      vec3 tonemap(vec3 x) { return pow(clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0), vec3(1.0 / 2.2)); }
      void main() {
        vec3 v = normalize(uView), sky = vec3(0.24, 0.26, 0.31), ground = vec3(0.05, 0.07, 0.08), key = vec3(1.36, 1.27, 1.14);
        if (uTable == 1) {  // the drape, darker under the tissue
          vec2 d = vec2(dot(vWorld - uFootCentre, vec3(1, 0, 0)), dot(vWorld - uFootCentre, uUp.z > 0.5 ? vec3(0, 1, 0) : vec3(0, 0, 1))) / uFootHalf;
          float ao = 1.0 - 0.6 * exp(-max(length(d) - 0.85, 0.0) * 4.0);
          vec3 drape = vec3(0.035, 0.15, 0.17) * (0.9 + 0.15 * noise(vWorld * 1.5));
          colour = vec4(tonemap(drape * (key * max(dot(uUp, uKey), 0.0) + sky) * ao), 1.0); return;
        }
        vec3 n = normalize(vNormal); if (dot(n, v) < 0.0) n = -n;
        float pores = noise(vRest * uPores), h = noise(vRest * uPores * 2.3) * 0.6 + pores * 0.4;
        vec3 dpdx = dFdx(vWorld), dpdy = dFdy(vWorld), r1 = cross(dpdy, n), r2 = cross(n, dpdx);
        float det = dot(dpdx, r1); vec3 g = sign(det) * (dFdx(h * 0.25) * r1 + dFdy(h * 0.25) * r2);
        vec3 b = abs(det) * n - g; if (abs(det) > 1e-10) n = normalize(b);
        vec3 albedo = uAlbedo * mix(0.80, 1.12, vBroad.x) * (1.0 - 0.14 * smoothstep(0.7, 0.9, pores));
        albedo = mix(albedo, uWet > 0.0 ? vec3(0.25, 0.05, 0.07) : albedo * vec3(0.78, 0.8, 1.02), (uWet > 0.0 ? 0.6 : 0.55) * vBroad.y);
        float nl = dot(n, uKey);
        vec3 w = uWet > 0.0 ? vec3(0.0) : vec3(0.55, 0.30, 0.22);
        vec3 diffuse = albedo * key * clamp((vec3(nl) + w) / ((1.0 + w) * (1.0 + w)), 0.0, 1.0);
        vec3 spec = key * (ggx(n, v, uKey, uRough) + uWet * ggx(n, v, uKey, 0.12));
        float height = dot(vWorld, uUp) - uTableHeight;
        float ao = mix(0.45, 1.0, smoothstep(0.0, 30.0, height)) * (0.8 + 0.2 * dot(n, uUp));
        vec3 ambient = albedo * mix(ground, sky, 0.5 + 0.5 * dot(n, uUp)) * ao;
        colour = vec4(tonemap(diffuse + spec + ambient), 1.0);
      }`;
    const prog = gl.createProgram();
    for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
      const sh = gl.createShader(type); gl.shaderSource(sh, src); gl.compileShader(sh);
      if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(sh));
      gl.attachShader(prog, sh);
    }
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
    this.prog = prog;
    const buffer = (data, usage) => { const b = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, b); gl.bufferData(gl.ARRAY_BUFFER, data, usage); return b; };
    this.normals = new Float32Array(this.pos.length);
    this.vao = gl.createVertexArray(); gl.bindVertexArray(this.vao);
    this.buf = { p: buffer(this.pos, gl.DYNAMIC_DRAW), n: buffer(this.normals, gl.DYNAMIC_DRAW) };
    const attribute = (loc, buf, size) => { gl.bindBuffer(gl.ARRAY_BUFFER, buf); gl.enableVertexAttribArray(loc); gl.vertexAttribPointer(loc, size, gl.FLOAT, false, 0, 0); };
    attribute(0, this.buf.p, 3); attribute(1, this.buf.n, 3);
    attribute(2, buffer(this.rest, gl.STATIC_DRAW), 3); attribute(3, buffer(this.broad, gl.STATIC_DRAW), 2);
    const ebo = gl.createBuffer(); gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ebo); gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, this.tris, gl.STATIC_DRAW);
    // The table: a square of drape under the tissue's lowest point.
    this.tableHeight = Math.min(...[0, 1, 2].map((a) => this.up[a] ? lo[a] : Infinity));
    const e1 = this.up[2] ? [1, 0, 0] : [1, 0, 0], e2 = this.up[2] ? [0, 1, 0] : [0, 0, 1], half = this.radius * 6;
    const corner = (s1, s2) => [0, 1, 2].map((a) => this.centre[a] * (1 - this.up[a]) + this.tableHeight * this.up[a] + s1 * half * e1[a] + s2 * half * e2[a]);
    const table = new Float32Array([...corner(-1, -1), ...corner(1, -1), ...corner(1, 1), ...corner(-1, 1)]);
    this.tableVao = gl.createVertexArray(); gl.bindVertexArray(this.tableVao);
    attribute(0, buffer(table, gl.STATIC_DRAW), 3);
    gl.vertexAttrib3f(1, ...this.up);
    const tebo = gl.createBuffer(); gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, tebo); gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, new Uint32Array([0, 1, 2, 0, 2, 3]), gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    let drag = null;
    canvas.addEventListener('pointerdown', (e) => { drag = [e.clientX, e.clientY]; });
    window.addEventListener('pointerup', () => { drag = null; });
    canvas.addEventListener('pointermove', (e) => {
      if (!drag) return;
      this.yaw += (e.clientX - drag[0]) * 0.01; this.pitch += (e.clientY - drag[1]) * 0.01;
      drag = [e.clientX, e.clientY]; this.draw();
    });
    this.frames = 0;
  }
  // Moved vertices (indices, positions in mm) as the server sends them; the others are at rest.
  // The server sends a surface only when it changed, so the view keeps the last one between.
  apply(surface) {
    this.pos.set(this.rest);
    const idx = surface.indices, p = surface.positions_mm;
    for (let k = 0; k < idx.length; ++k) {
      const i = idx[k];
      if (i >= 0 && 3 * i + 2 < this.pos.length) {
        this.pos[3 * i] = p[3 * k]; this.pos[3 * i + 1] = p[3 * k + 1]; this.pos[3 * i + 2] = p[3 * k + 2];
      }
    }
    this.draw();
  }
  computeNormals() {
    const P = this.pos, N = this.normals, T = this.tris;
    N.fill(0);
    for (let t = 0; t < T.length; t += 3) {
      const a = 3 * T[t], b = 3 * T[t + 1], c = 3 * T[t + 2];
      const ux = P[b] - P[a], uy = P[b + 1] - P[a + 1], uz = P[b + 2] - P[a + 2];
      const vx = P[c] - P[a], vy = P[c + 1] - P[a + 1], vz = P[c + 2] - P[a + 2];
      const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
      for (const v of [a, b, c]) { N[v] += nx; N[v + 1] += ny; N[v + 2] += nz; }
    }
    for (let v = 0; v < N.length; v += 3) {
      const l = Math.hypot(N[v], N[v + 1], N[v + 2]) || 1;
      N[v] /= l; N[v + 1] /= l; N[v + 2] /= l;
    }
  }
  draw() {
    const gl = this.gl, c = this.canvas, dpr = window.devicePixelRatio || 1;
    if (c.width !== c.clientWidth * dpr) { c.width = c.clientWidth * dpr; c.height = c.clientHeight * dpr; }
    gl.viewport(0, 0, c.width, c.height);
    gl.clearColor(0.10, 0.11, 0.13, 1); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    this.computeNormals();
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buf.p); gl.bufferSubData(gl.ARRAY_BUFFER, 0, this.pos);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buf.n); gl.bufferSubData(gl.ARRAY_BUFFER, 0, this.normals);
    // Orbit camera: rotation (yaw, pitch) about the centre, orthographic-ish perspective; the
    // view's "up" is the table's normal.
    const cy = Math.cos(this.yaw), sy = Math.sin(this.yaw), cp = Math.cos(this.pitch), sp = Math.sin(this.pitch);
    // Columns: the images of the scene's x, y, z; the table's normal goes up the screen.
    let r = [cy, sy * sp, -sy * cp, 0, cp, sp, sy, -cy * sp, cy * cp];  // y up
    if (this.up[2]) r = [r[0], r[1], r[2], -r[6], -r[7], -r[8], r[3], r[4], r[5]];  // z up
    const s = 1 / (this.radius * 1.6), aspect = c.width / c.height;
    const [ox, oy, oz] = this.centre;
    const m = new Float32Array(16);
    for (let col = 0; col < 3; ++col) {
      m[4 * col] = r[3 * col] * s / aspect; m[4 * col + 1] = r[3 * col + 1] * s; m[4 * col + 2] = -r[3 * col + 2] * s * 0.3;
    }
    m[12] = -(m[0] * ox + m[4] * oy + m[8] * oz); m[13] = -(m[1] * ox + m[5] * oy + m[9] * oz);
    m[14] = -(m[2] * ox + m[6] * oy + m[10] * oz); m[15] = 1;
    const view = [r[2], r[5], r[8]];  // toward the viewer, in the scene frame
    const key = [0.55 * view[0] + 0.8 * this.up[0] + 0.3, 0.55 * view[1] + 0.8 * this.up[1] - 0.2, 0.55 * view[2] + 0.8 * this.up[2]];
    const kl = Math.hypot(...key);
    gl.useProgram(this.prog);
    const u = (name) => gl.getUniformLocation(this.prog, name);
    gl.uniformMatrix4fv(u('uM'), false, m);
    gl.uniform3fv(u('uView'), view); gl.uniform3fv(u('uKey'), key.map((x) => x / kl)); gl.uniform3fv(u('uUp'), this.up);
    gl.uniform3fv(u('uAlbedo'), this.look.albedo); gl.uniform1f(u('uRough'), this.look.rough);
    gl.uniform1f(u('uWet'), this.look.wet); gl.uniform1f(u('uPores'), this.look.pores);
    gl.uniform1f(u('uTableHeight'), this.tableHeight);
    gl.uniform3fv(u('uFootCentre'), this.centre);
    gl.uniform2fv(u('uFootHalf'), [(this.hi[0] - this.lo[0]) / 2, this.up[2] ? (this.hi[1] - this.lo[1]) / 2 : (this.hi[2] - this.lo[2]) / 2]);
    gl.uniform1i(u('uTable'), 0);
    gl.bindVertexArray(this.vao);
    gl.drawElements(gl.TRIANGLES, this.tris.length, gl.UNSIGNED_INT, 0);
    gl.uniform1i(u('uTable'), 1);
    gl.bindVertexArray(this.tableVao);
    gl.drawElements(gl.TRIANGLES, 6, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
    this.frames++;
    c.dataset.frames = this.frames;
  }
}

// ---- pages ----
const scenesByName = {};
async function loadScenes() {
  const s = await api('GET', '/scenes');
  for (const x of s.scenes) scenesByName[x.name] = x;
  return s.scenes;
}

function stateBadge(state) { return el('span', { class: 'badge ' + state }, state); }
function taskCell(t) {
  const sc = scenesByName[t.scene];
  if (sc && sc.task === 'press') return fmt(t.depth_mm, 1) + ' mm';
  return fmt(t.twist_deg, 1) + '°';
}

async function pageLive(main) {
  const scenes = await loadScenes();
  const status = el('div', { class: 'status-line', id: 'live-status' }, 'connecting…');
  const body = el('tbody', { id: 'live-rows' });
  const table = el('table', { id: 'live-table' },
    el('thead', {}, el('tr', {}, ['Trainee', 'Scene', 'State', 'Twist / depth', 'Force (N)', 'RTT (µs)',
      'Loss (%)', 'Haptic (Hz)', 'Score', ''].map((h, i) => el('th', { class: i >= 4 && i <= 8 ? 'num' : '' }, h)))),
    body);
  const note = el('div');
  const prepare = el('form', { class: 'inline', id: 'prepare' },
    el('label', {}, 'Trainee', el('input', { name: 'trainee', required: true, maxlength: 128 })),
    el('label', {}, 'Scene', el('select', { name: 'scene' }, scenes.map((s) => el('option', { value: s.name }, s.name)))),
    el('button', { type: 'submit' }, 'Prepare session'));
  prepare.addEventListener('submit', async (e) => {
    e.preventDefault();
    const f = new FormData(prepare);
    try {
      const r = await api('POST', '/sessions', { trainee: f.get('trainee'), scene: f.get('scene') });
      const s = r.session;
      message(note, `Session ${s.id} prepared for ${s.trainee} on ${s.scene}. The trainee's station joins it: ` +
        `vsurg-station --join ${s.id} --scene ${s.scene}`, true);
    } catch (err) { message(note, err.message); }
  });
  main.replaceChildren(el('h1', {}, 'Live stations'), status, el('div', { class: 'panel' }, table),
    el('h2', {}, 'Prepare a session for a trainee'), el('div', { class: 'panel' }, prepare, note));

  const seen = new Map();  // id → {row, last: time seen in the stream, gone}
  let lastFrame = 0;
  const es = new EventSource('/api/v1/live/events');
  es.onmessage = (ev) => {
    lastFrame = Date.now();
    const list = JSON.parse(ev.data);
    const now = Date.now();
    const ids = new Set();
    for (const t of list) {
      ids.add(t.id);
      let entry = seen.get(t.id);
      if (!entry) { entry = { row: el('tr', { 'data-session': t.id }) }; seen.set(t.id, entry); body.append(entry.row); }
      entry.last = now; entry.gone = false;
      entry.row.className = t.state === 'stalled' ? 'stalled' : '';
      entry.row.replaceChildren(
        el('td', {}, t.trainee), el('td', {}, t.scene), el('td', {}, stateBadge(t.state)),
        el('td', {}, taskCell(t)), el('td', { class: 'num' }, fmt(t.force_n, 2)),
        el('td', { class: 'num' }, fmt(t.rtt_us, 0)), el('td', { class: 'num' }, fmt(t.loss_ratio * 100, 2),
          poorLink(t) ? [' ', el('span', { class: 'badge stalled', title: poorLinkWhy }, 'poor link')] : null),
        el('td', { class: 'num' }, fmt(t.haptic_rate_hz, 0)), el('td', { class: 'num' }, fmt(t.score, 1)),
        el('td', {}, el('a', { href: '/session/' + t.id }, 'Open')));
    }
    // Sessions that left the live list: shown as gone (disconnected or ended) for 15 s.
    for (const [id, entry] of seen) {
      if (ids.has(id)) continue;
      if (!entry.gone) {
        entry.gone = true; entry.row.className = 'gone';
        entry.row.children[2].replaceChildren(stateBadge('gone'));
      }
      if (now - entry.last > 15000) { entry.row.remove(); seen.delete(id); }
    }
    if (!performance.getEntriesByName('vsurg-live-data').length) performance.mark('vsurg-live-data');
    status.className = 'status-line';
    status.textContent = `${list.length} live session${list.length === 1 ? '' : 's'} · updated ${new Date().toLocaleTimeString()}`;
  };
  setInterval(() => {
    if (Date.now() - lastFrame > 3000) {
      status.className = 'status-line lost';
      status.textContent = 'No update for ' + Math.round((Date.now() - lastFrame) / 1000) + ' s: reconnecting…';
    }
  }, 1000);
}

// Beyond what the station's local model holds faithfully (docs/BENCHMARKS.md "Haptics across
// networks"), the station tells its trainee and the live table flags the row.
const poorLinkWhy = 'Round trip over 300 ms or over 10% lost: the station warns its trainee';
function poorLink(t) { return t.rtt_us > 300e3 || t.loss_ratio > 0.10; }

function metricsList(m) {
  if (!m) return el('p', { class: 'muted' }, 'No trial metrics recorded.');
  const rows = [
    ['Score (0–10)', fmt(m.score, 2)], ['Raw score', fmt(m.raw_score, 2)],
    ['Completed', m.completed ? 'yes' : 'no'], ['Completion time (s)', fmt(m.completion_time, 2)],
    ['Task error', fmt(m.task_error, 4)], ['Peak force (N)', fmt(m.peak_force, 2)],
    ['Time over force limit (s)', fmt(m.time_over_force_limit, 2)], ['Path length (m)', fmt(m.path_length, 3)],
    ['RMS jerk (m/s³)', fmt(m.rms_jerk, 1)], ['Overload events', m.overload_events], ['Duration (s)', fmt(m.duration, 1)],
    ['Capped: not completed', m.capped_not_completed ? 'yes' : 'no'],
    ['Capped: force limit', m.capped_force_limit ? 'yes' : 'no'], ['Capped: overload', m.capped_overload ? 'yes' : 'no'],
  ];
  // What the station rendered and how the link held (0 when the station did not report them).
  const l = m.link;
  if (l && l.rate_hz > 0) {
    rows.push(['Peak force felt at the station (N)', fmt(l.station_peak_force_n, 2)],
      ['Time over force limit at the station (s)', fmt(l.station_time_over_limit_s, 2)],
      ['Link: round trip (ms)', fmt(l.rtt_ms, 1)], ['Link: jitter (ms)', fmt(l.jitter_ms, 2)],
      ['Link: loss (%)', fmt(100 * l.loss_ratio, 1)], ['Link: stylus datagrams (per s)', fmt(l.rate_hz, 0)]);
  }
  return el('dl', { class: 'kv', id: 'metrics' }, rows.flatMap(([k, v]) => [el('dt', {}, k), el('dd', {}, v)]));
}

async function pageSession(main) {
  const id = location.pathname.split('/')[2];
  const s = await api('GET', '/sessions/' + id);
  await loadScenes();
  const head = el('div', { class: 'panel' });
  const renderHead = (x) => head.replaceChildren(
    el('dl', { class: 'kv' }, ['Trainee', x.trainee, 'Scene', x.scene, 'State', stateBadge(x.state),
      'Started', x.started || '—', 'Ended', x.ended || '—', 'End reason', x.end_reason || '—']
      .map((v, i) => (i % 2 ? el('dd', {}, v) : el('dt', {}, v)))));
  renderHead(s);
  const stop = el('button', { class: 'danger', id: 'stop' }, 'Stop session');
  const note = el('div');
  stop.addEventListener('click', async () => {
    try { renderHead(await api('POST', `/sessions/${id}/stop`, { reason: 'stopped by the instructor' })); }
    catch (err) { message(note, err.message); }
  });
  const canvases = { force: el('canvas', { class: 'plot', id: 'plot-force' }),
    twist: el('canvas', { class: 'plot', id: 'plot-twist' }), rtt: el('canvas', { class: 'plot', id: 'plot-rtt' }) };
  const press = scenesByName[s.scene] && scenesByName[s.scene].task === 'press';
  const plots = {
    force: new Plot(canvases.force, [{ name: '|F| (N)', colour: '#f0b296' }], 'N'),
    twist: new Plot(canvases.twist, press ? [{ name: 'depth (mm)', colour: '#8cc8ff' }]
      : [{ name: 'twist (°)', colour: '#8cc8ff' }, { name: 'torque (mN·m)', colour: '#5fd38a' }], press ? 'mm' : '° / mN·m'),
    rtt: new Plot(canvases.rtt, [{ name: 'RTT (µs)', colour: '#f3c13a' }], 'µs'),
  };
  const view = el('canvas', { id: 'view3d' });
  const live = el('dl', { class: 'kv', id: 'live-figures' });
  const results = el('div', { id: 'results' }, metricsList(s.metrics));
  main.replaceChildren(el('h1', {}, `Session ${id}`), head, stop, note,
    el('div', { class: 'grid' },
      el('div', { class: 'panel' }, el('h2', {}, 'Tissue'), view),
      el('div', { class: 'panel' }, el('h2', {}, 'Live'), live, canvases.force, canvases.twist, canvases.rtt)),
    el('h2', {}, 'Trial metrics and safety events'), el('div', { class: 'panel' }, results));
  if (!['created', 'running', 'stalled'].includes(s.state)) { stop.disabled = true; return; }
  let tissue = null;
  try { tissue = new TissueView(view, await api('GET', `/sessions/${id}/surface`), scenesByName[s.scene]); tissue.draw(); }
  catch (err) { message(note, '3D view: ' + err.message); }
  const es = new EventSource(`/api/v1/sessions/${id}/events`);
  const t0 = performance.now();
  es.onmessage = (ev) => {
    const t = JSON.parse(ev.data), now = (performance.now() - t0) / 1000;
    if (t.state !== s.state) { s.state = t.state; renderHead(s); }
    plots.force.add(now, [t.force_n]);
    plots.twist.add(now, press ? [t.depth_mm] : [t.twist_deg, t.torque_nm * 1000]);
    plots.rtt.add(now, [t.rtt_us]);
    Object.values(plots).forEach((p) => p.draw());
    live.replaceChildren(...[['State', stateBadge(t.state)], ['Force (N)', fmt(t.force_n, 2)],
      [press ? 'Depth (mm)' : 'Twist (°)', press ? fmt(t.depth_mm, 1) : fmt(t.twist_deg, 1)],
      ['RTT (µs)', fmt(t.rtt_us, 0)], ['Loss (%)', fmt(t.loss_ratio * 100, 2)], ['Haptic rate (Hz)', fmt(t.haptic_rate_hz, 0)],
      ['Score so far', fmt(t.score, 1)], ['Overload events', t.overload_events], ['Clock jumps', t.clock_jumps]]
      .flatMap(([k, v]) => [el('dt', {}, k), el('dd', {}, v)]));
    if (tissue && t.surface) tissue.apply(t.surface);
  };
  es.addEventListener('ended', async () => {
    es.close();
    const done = await api('GET', '/sessions/' + id);
    renderHead(done); stop.disabled = true;
    results.replaceChildren(metricsList(done.metrics));
  });
}

async function pageEvaluate(main) {
  const [queue, weights] = await Promise.all([api('GET', '/evaluations/mine'), api('GET', '/weight-sets')]);
  const names = weights.index_names, w = weights.default.index;
  const formBox = el('div', { class: 'panel', id: 'score-form' }, el('p', { class: 'muted' }, 'Choose a session or a model to score.'));
  const openForm = (kind, subject) => {
    const key = 'web:' + (crypto.randomUUID ? crypto.randomUUID() : String(Math.random()).slice(2) + Date.now());
    const note = el('div');
    const inputs = names.map((n, j) => el('label', {}, `${n} (weight ${w[j]})`,
      el('input', { type: 'number', min: 0, max: 10, step: 0.5, required: true, name: 'i' + j })));
    const submit = el('button', { type: 'submit' }, 'Submit scores');
    const form = el('form', { class: 'inline' }, inputs, submit);
    form.addEventListener('submit', async (e) => {
      e.preventDefault();
      if (!form.reportValidity()) return;
      const scores = names.map((_, j) => Number(form.elements['i' + j].value));
      submit.disabled = true;
      try {
        // The same key on a retry: the server stores one submission and says it was a duplicate.
        const r = await api('POST', '/evaluations', { idempotency_key: key, subject_kind: kind, subject, scores });
        message(note, `Stored (submission ${r.submission_id}${r.duplicate ? ', already stored' : ''}).`, true);
        setTimeout(() => pageEvaluate(main), 800);
      } catch (err) { message(note, err.message); submit.disabled = false; }
    });
    formBox.replaceChildren(el('h2', {}, `Score ${kind} ${subject}`), form, note);
  };
  const sessions = el('table', { id: 'pending-sessions' },
    el('thead', {}, el('tr', {}, ['Session', 'Trainee', 'Scene', 'Ended', ''].map((h) => el('th', {}, h)))),
    el('tbody', {}, queue.sessions.map((s) => el('tr', {}, el('td', {}, s.id), el('td', {}, s.trainee),
      el('td', {}, s.scene), el('td', {}, s.ended),
      el('td', {}, el('button', { onclick: () => openForm('session', String(s.id)) }, 'Score'))))));
  const models = el('table', { id: 'pending-models' }, el('tbody', {}, queue.models.map((m) => el('tr', {},
    el('td', {}, m), el('td', {}, el('button', { onclick: () => openForm('model', m) }, 'Score'))))));
  const past = el('table', { id: 'past' },
    el('thead', {}, el('tr', {}, ['Submitted', 'Kind', 'Subject', ...names.map((_, j) => 'i' + (j + 1))].map((h) => el('th', {}, h)))),
    el('tbody', {}, queue.submitted.map((s) => el('tr', {}, el('td', {}, s.submitted), el('td', {}, s.subject_kind),
      el('td', {}, s.subject), s.scores.map((x) => el('td', { class: 'num' }, fmt(x, 1)))))));
  main.replaceChildren(el('h1', {}, 'Evaluate'),
    el('h2', {}, 'Sessions waiting for your scores'), el('div', { class: 'panel' }, queue.sessions.length ? sessions : el('p', { class: 'muted' }, 'None.')),
    el('h2', {}, 'Simulator models waiting for your scores'), el('div', { class: 'panel' }, queue.models.length ? models : el('p', { class: 'muted' }, 'None.')),
    formBox, el('h2', {}, 'Your submissions'), el('div', { class: 'panel' }, past));
}

function reportView(r) {
  const single = (x) => el('div', { class: 'panel report' },
    el('h2', {}, 'Subject ' + (x.subject || '')),
    el('dl', { class: 'kv' }, [['N (raters)', x.raters], ['Comprehensive score', fmt(x.comprehensive, 3)],
      ['ICC(2,k)', fmt(x.icc2k, 3)], ["Cronbach's α", fmt(x.cronbach_alpha, 3)],
      ['Absent groups', x.absent_groups && x.absent_groups.length ? x.absent_groups.join(', ') + ' (weights renormalised)' : 'none'],
      ['Weights', x.weights ? x.weights.name : '']].flatMap(([k, v]) => [el('dt', {}, k), el('dd', { class: k === 'N (raters)' ? 'raters' : '' }, v)])),
    el('table', {}, el('thead', {}, el('tr', {}, ['Index', 'M_j', 's_j', 'weight'].map((h, i) => el('th', { class: i ? 'num' : '' }, h)))),
      el('tbody', {}, x.index_names.map((n, j) => el('tr', {}, el('td', {}, n), el('td', { class: 'num' }, fmt(x.index_means[j], 2)),
        el('td', { class: 'num' }, fmt(Math.sqrt(x.index_variances[j]), 2)),
        el('td', { class: 'num' }, x.weights ? fmt(x.weights.index[j], 2) : '—'))))));
  if (r.subjects) return el('div', {}, el('p', {}, `Common raters: ${r.common_raters}`), r.subjects.map(single));
  return single(r);
}

async function pageReports(main) {
  const ws = await api('GET', '/weight-sets');
  const out = el('div', { id: 'report-out' });
  const form = el('form', { class: 'inline', id: 'report-form' },
    el('label', {}, 'Subject kind', el('select', { name: 'kind' }, ['session', 'trainee', 'model'].map((k) => el('option', { value: k }, k)))),
    el('label', {}, 'Subjects (comma-separated, up to 32)', el('input', { name: 'subjects', required: true, size: 36 })),
    el('label', {}, 'Weight set', el('select', { name: 'weights' }, el('option', { value: '' }, 'seed 000 (built in)'),
      ws.names.map((n) => el('option', { value: n }, n)))),
    el('button', { type: 'submit' }, 'Report'));
  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    const f = new FormData(form), q = new URLSearchParams({ kind: f.get('kind'), weights: f.get('weights') });
    for (const s of String(f.get('subjects')).split(',').map((x) => x.trim()).filter(Boolean)) q.append('subject', s);
    try { out.replaceChildren(reportView(await api('GET', '/reports?' + q))); } catch (err) { message(out, err.message); }
  });
  const effect = el('div', { id: 'training-effect' });
  const effectChart = el('canvas', { class: 'plot', id: 'effect-chart' });
  const traineeOut = el('div');
  const traineeChart = el('canvas', { class: 'plot', id: 'trainee-chart' });
  const traineeForm = el('form', { class: 'inline', id: 'trainee-form' },
    el('label', {}, 'Trainee', el('input', { name: 'trainee', required: true })), el('button', { type: 'submit' }, 'Show'));
  traineeForm.addEventListener('submit', async (e) => {
    e.preventDefault();
    const name = new FormData(traineeForm).get('trainee');
    try {
      const r = await api('GET', '/sessions?trainee=' + encodeURIComponent(name));
      const done = r.sessions.filter((s) => s.metrics);
      traineeOut.textContent = `${done.length} scored trial${done.length === 1 ? '' : 's'} of ${name}`;
      lineChart(traineeChart, [{ name: 'trial score', points: done.map((s, i) => ({ x: i + 1, y: s.metrics.score })) }], 'trial', 'score 0–10');
    } catch (err) { message(traineeOut, err.message); }
  });
  main.replaceChildren(el('h1', {}, 'Reports'),
    el('div', { class: 'panel' }, form), out,
    el('h2', {}, 'Training effect (trainee group × moment)'), el('div', { class: 'panel' }, effect, effectChart),
    el('h2', {}, "A trainee's scores over trials"), el('div', { class: 'panel' }, traineeForm, traineeOut, traineeChart));
  try {
    const cells = await api('GET', '/training-effect');
    const groups = [...new Set(cells.map((c) => c.trainee_group))];
    const moments = [...new Set(cells.map((c) => c.moment_min))].sort((a, b) => a - b);
    const cell = (g, m) => cells.find((c) => c.trainee_group === g && c.moment_min === m);
    effect.replaceChildren(cells.length ? el('table', {},
      el('thead', {}, el('tr', {}, el('th', {}, 'group'), moments.map((m) => el('th', { class: 'num' }, m + ' min')))),
      el('tbody', {}, groups.map((g) => el('tr', {}, el('td', {}, g), moments.map((m) => {
        const c = cell(g, m);
        return el('td', { class: 'num' }, c ? `${fmt(c.mean, 2)} (n=${c.trainees})` : '—');
      }))))) : el('p', { class: 'muted' }, 'No trainee evaluations at training moments yet.'));
    lineChart(effectChart, groups.map((g) => ({ name: g, points: moments.filter((m) => cell(g, m)).map((m) => ({ x: m, y: cell(g, m).mean })) })), 'minutes of training', 'score');
  } catch (err) { message(effect, err.message); }
}

async function pageAdmin(main) {
  const users = el('tbody', { id: 'users' });
  const note = el('div', { id: 'admin-note' });
  const refresh = async () => {
    const r = await api('GET', '/users');
    users.replaceChildren(...r.users.map((u) => el('tr', {}, el('td', {}, u.name), el('td', {}, u.role), el('td', {}, u.group),
      el('td', {}, u.created), el('td', {}, u.disabled ? 'disabled' : 'active'),
      el('td', {},
        el('button', { onclick: async () => {
          try {
            const t = await api('POST', `/users/${encodeURIComponent(u.name)}/token`, { label: 'dashboard' });
            note.replaceChildren(el('div', { class: 'msg ok' }, `Token for ${u.name} (shown once; give it to the user): `,
              el('div', { class: 'token' }, t.token)));
          } catch (err) { message(note, err.message); }
        } }, 'Issue token'), ' ',
        el('button', { class: 'danger', onclick: async () => {
          try { await api('POST', `/users/${encodeURIComponent(u.name)}/revoke`, {}); message(note, `Tokens of ${u.name} revoked.`, true); }
          catch (err) { message(note, err.message); }
        } }, 'Revoke tokens'), ' ',
        el('button', { onclick: async () => {
          try { await api('POST', `/users/${encodeURIComponent(u.name)}/disabled`, { disabled: !u.disabled }); await refresh(); }
          catch (err) { message(note, err.message); }
        } }, u.disabled ? 'Enable' : 'Disable')))));
  };
  const create = el('form', { class: 'inline', id: 'create-user' },
    el('label', {}, 'Name', el('input', { name: 'name', required: true, maxlength: 128 })),
    el('label', {}, 'Role', el('select', { name: 'role' }, ['trainee', 'instructor', 'evaluator', 'admin'].map((r) => el('option', { value: r }, r)))),
    el('label', {}, 'Group', el('input', { name: 'group', placeholder: 'e.g. residents, chief' })),
    el('button', { type: 'submit' }, 'Create user'));
  create.addEventListener('submit', async (e) => {
    e.preventDefault();
    const f = new FormData(create);
    try { await api('POST', '/users', { name: f.get('name'), role: f.get('role'), group: f.get('group') }); await refresh(); message(note, 'User created.', true); }
    catch (err) { message(note, err.message); }
  });
  const ws = await api('GET', '/weight-sets');
  const wsText = el('textarea', { id: 'weight-set' }, JSON.stringify(ws.default, null, 2));
  const wsNote = el('div');
  const wsButton = el('button', { onclick: async () => {
    try { await api('POST', '/weight-sets', wsText.value); message(wsNote, 'Weight set stored.', true); }
    catch (err) { message(wsNote, err.message); }
  } }, 'Store weight set');
  const exportForm = el('form', { class: 'inline', id: 'export-form' },
    el('label', {}, 'Format', el('select', { name: 'format' }, ['csv', 'jsonl', 'xapi'].map((f) => el('option', { value: f }, f)))),
    el('label', {}, 'From (ISO, optional)', el('input', { name: 'from', placeholder: '2026-11-01T00:00:00Z' })),
    el('label', {}, 'To (ISO, optional)', el('input', { name: 'to' })),
    el('label', {}, 'Trainee (optional)', el('input', { name: 'trainee' })),
    el('label', {}, 'Session (optional)', el('input', { name: 'session', inputmode: 'numeric' })),
    el('button', { type: 'submit' }, 'Download'));
  exportForm.addEventListener('submit', (e) => {
    e.preventDefault();
    const q = new URLSearchParams();
    for (const [k, v] of new FormData(exportForm)) if (v) q.append(k, v);
    location.href = '/api/v1/export?' + q;  // streamed by the server, saved by the browser
  });
  const backupNote = el('div');
  const backupForm = el('form', { class: 'inline', id: 'backup-form' },
    el('label', {}, 'Backup file name', el('input', { name: 'name', required: true, value: 'vsurg-' + new Date().toISOString().slice(0, 10) + '.db' })),
    el('button', { type: 'submit' }, 'Back up now'));
  backupForm.addEventListener('submit', async (e) => {
    e.preventDefault();
    try { await api('POST', '/backup', { name: new FormData(backupForm).get('name') }); message(backupNote, 'Backup written.', true); }
    catch (err) { message(backupNote, err.message); }
  });
  main.replaceChildren(el('h1', {}, 'Administration'),
    el('h2', {}, 'Users'), el('div', { class: 'panel' }, create, note,
      el('table', {}, el('thead', {}, el('tr', {}, ['Name', 'Role', 'Group', 'Created', 'Status', ''].map((h) => el('th', {}, h)))), users)),
    el('h2', {}, 'Weight sets'), el('div', { class: 'panel' }, el('p', { class: 'muted' }, 'Stored: ' + (ws.names.join(', ') || 'none')), wsText, wsButton, wsNote),
    el('h2', {}, 'Export evaluations'), el('div', { class: 'panel' }, exportForm),
    el('h2', {}, 'Backup'), el('div', { class: 'panel' }, backupForm, backupNote));
  await refresh();
}

async function pageMine(main) {
  const r = await api('GET', '/sessions?trainee=' + encodeURIComponent(me.user));
  main.replaceChildren(el('h1', {}, 'My sessions'), el('div', { class: 'panel' }, el('table', {},
    el('thead', {}, el('tr', {}, ['Session', 'Scene', 'State', 'Started', 'Score'].map((h) => el('th', {}, h)))),
    el('tbody', {}, r.sessions.map((s) => el('tr', {}, el('td', {}, s.id), el('td', {}, s.scene), el('td', {}, stateBadge(s.state)),
      el('td', {}, s.started || '—'), el('td', { class: 'num' }, s.metrics ? fmt(s.metrics.score, 1) : '—')))))),
  el('p', { class: 'muted' }, 'A session an instructor prepared for you: start your station with --join ID.'));
}

function pageSignIn(main) {
  const note = el('div');
  const form = el('form', { id: 'signin' },
    el('label', {}, 'Your access token (from your administrator)',
      el('input', { type: 'password', name: 'token', required: true, autocomplete: 'current-password' })),
    el('p', {}, el('button', { type: 'submit' }, 'Sign in')));
  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    try {
      me = await api('POST', '/signin', { token: new FormData(form).get('token') });
      const next = new URLSearchParams(location.search).get('next');
      location.href = PAGES.some((p) => p.page === next) ? '/' + next : '/';
    } catch (err) { message(note, err.message); }
  });
  main.replaceChildren(el('div', { class: 'panel signin' }, el('h1', {}, 'Sign in to vsurg'), form, note));
}

async function start() {
  const page = document.body.dataset.page, main = $('#main');
  if (page === 'signin') return pageSignIn(main);
  try { me = await api('GET', '/me'); } catch (err) { return; }
  $('#nav').replaceChildren(...PAGES.filter((p) => p.roles.includes(me.role)).map((p) =>
    el('a', { href: '/' + p.page, class: p.page === page ? 'here' : '' }, p.title)));
  $('#who').replaceChildren(`${me.user} (${me.role}) `, el('button', { id: 'signout', onclick: async () => {
    try { await api('POST', '/signout'); } finally { location.href = '/signin'; }
  } }, 'Sign out'));
  const pages = { live: pageLive, session: pageSession, evaluate: pageEvaluate, reports: pageReports, admin: pageAdmin, mine: pageMine };
  try { await pages[page](main); } catch (err) { if (err.message !== 'signed out') message(main, err.message); }
}
document.addEventListener('DOMContentLoaded', start);
