// The tissue in 3D (WebGL2): the rest surface, moved by the telemetry's surface states.
// The station's look (client/render/shaders.cpp) in a browser: skin with wrapped (subsurface)
// diffuse, wet organs with a second sharp lobe, tone and vessels that move with the tissue (a
// value noise at each point's rest position: per vertex for the broad pattern, per pixel for pores
// and their bump), a drape-covered table under it with the tissue's soft contact shadow.
// Positions in mm, as the server sends them. The hands' tool tips are drawn over it as markers.
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
// A GLSL program from its two shaders; a compile or link error is raised with the driver's log.
function linkProgram(gl, vs, fs) {
  const prog = gl.createProgram();
  for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
    const sh = gl.createShader(type); gl.shaderSource(sh, src); gl.compileShader(sh);
    if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(sh));
    gl.attachShader(prog, sh);
  }
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  return prog;
}
export class TissueView {
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
    this.restTris = new Uint32Array(surface.triangles);
    // Where each vertex reads the tissue's tone and detail: its rest position, and a cut's copy
    // its original's (setTriangles), as the station's view does.
    this.material = new Float32Array(this.rest);
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
    this.prog = linkProgram(gl, vs, fs);
    const buffer = (data, usage) => { const b = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, b); gl.bufferData(gl.ARRAY_BUFFER, data, usage); return b; };
    this.normals = new Float32Array(this.pos.length);
    this.vao = gl.createVertexArray(); gl.bindVertexArray(this.vao);
    this.buf = { p: buffer(this.pos, gl.DYNAMIC_DRAW), n: buffer(this.normals, gl.DYNAMIC_DRAW) };
    const attribute = (loc, buf, size) => { gl.bindBuffer(gl.ARRAY_BUFFER, buf); gl.enableVertexAttribArray(loc); gl.vertexAttribPointer(loc, size, gl.FLOAT, false, 0, 0); };
    attribute(0, this.buf.p, 3); attribute(1, this.buf.n, 3);
    this.buf.r = buffer(this.material, gl.DYNAMIC_DRAW); this.buf.b = buffer(this.broad, gl.DYNAMIC_DRAW);
    attribute(2, this.buf.r, 3); attribute(3, this.buf.b, 2);
    this.ebo = gl.createBuffer(); gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.ebo); gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, this.tris, gl.DYNAMIC_DRAW);
    // The table: a square of drape just under the tissue's lowest point (a flat patch at rest
    // would otherwise share its plane and fight it for depth).
    this.tableHeight = Math.min(...[0, 1, 2].map((a) => this.up[a] ? lo[a] : Infinity)) - 0.02 * this.radius;
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
    // The keyboard turns it too (arrows), and a screen reader hears what it shows.
    canvas.tabIndex = 0;
    canvas.setAttribute('role', 'img');
    canvas.setAttribute('aria-label', `The ${(scene && scene.material) || 'tissue'} in 3D` +
      `${scene && scene.name ? ' (' + scene.name + ')' : ''}, as the trainee deforms it; arrow keys turn the view.`);
    canvas.addEventListener('keydown', (e) => {
      const turn = { ArrowLeft: [-0.1, 0], ArrowRight: [0.1, 0], ArrowUp: [0, -0.1], ArrowDown: [0, 0.1] }[e.key];
      if (!turn) return;
      e.preventDefault(); this.yaw += turn[0]; this.pitch += turn[1]; this.draw();
    });
    this.frames = 0;
    this.tools = [];
    this.trail = null;
    this.initTools();
    this.initTrail();
  }
  // The tool's path over the tissue (a replay's: where the tip went up to the time shown), a thin
  // line never hidden by the tissue, as the markers are not.
  initTrail() {
    const gl = this.gl;
    const vs = `#version 300 es
      layout(location = 0) in vec3 aPos; uniform mat4 uM;
      void main() { gl_Position = uM * vec4(aPos, 1.0); gl_Position.z = -0.998 * gl_Position.w; }`;
    const fs = `#version 300 es
      precision mediump float; uniform vec3 uColour; out vec4 colour;
      void main() { colour = vec4(uColour, 1.0); }`;
    this.trailProg = linkProgram(gl, vs, fs);
    this.trailVao = gl.createVertexArray(); gl.bindVertexArray(this.trailVao);
    this.trailBuf = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, this.trailBuf);
    gl.enableVertexAttribArray(0); gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.bindVertexArray(null);
  }
  // points: the path's positions in mm, x y z each (a Float32Array), or null; drawn at the next
  // draw().
  setTrail(points) { this.trail = points; }
  drawTrail(m) {
    const gl = this.gl, n = this.trail ? Math.floor(this.trail.length / 3) : 0;
    this.canvas.dataset.trail = n;
    if (n < 2) return;
    gl.useProgram(this.trailProg);
    gl.uniformMatrix4fv(gl.getUniformLocation(this.trailProg, 'uM'), false, m);
    gl.uniform3fv(gl.getUniformLocation(this.trailProg, 'uColour'), [0.2, 0.45, 0.8]);
    gl.bindVertexArray(this.trailVao);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.trailBuf);
    gl.bufferData(gl.ARRAY_BUFFER, this.trail, gl.DYNAMIC_DRAW);
    gl.disable(gl.DEPTH_TEST);
    gl.drawArrays(gl.LINE_STRIP, 0, n);
    gl.enable(gl.DEPTH_TEST);
    gl.bindVertexArray(null);
  }
  // The hands' tool tips as round markers over the tissue (never hidden by it: a tip pressed in
  // is still seen): the trainee's, and an instructor's while one is on the tool.
  initTools() {
    const gl = this.gl;
    const vs = `#version 300 es
      layout(location = 0) in vec3 aPos; uniform mat4 uM; uniform float uSize;
      void main() { gl_Position = uM * vec4(aPos, 1.0); gl_Position.z = -0.999 * gl_Position.w; gl_PointSize = uSize; }`;
    const fs = `#version 300 es
      precision mediump float; uniform vec3 uColour; out vec4 colour;
      void main() { vec2 d = gl_PointCoord - 0.5; float r = length(d); if (r > 0.5) discard;
        colour = vec4(r > 0.36 ? vec3(0.05) : uColour, 1.0); }`;
    this.toolProg = linkProgram(gl, vs, fs);
    this.toolVao = gl.createVertexArray(); gl.bindVertexArray(this.toolVao);
    this.toolBuf = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, this.toolBuf);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(3 * 40), gl.DYNAMIC_DRAW);
    gl.enableVertexAttribArray(0); gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.bindVertexArray(null);
  }
  // tools: [{ p: [x, y, z] mm, colour: [r, g, b], size: px }] (the hands, and a palpation's lumps
  // and marks: at most 40), drawn at the next draw().
  setTools(tools) { this.tools = tools.slice(0, 40); this.draw(); }
  drawTools(m) {
    const gl = this.gl, dpr = window.devicePixelRatio || 1;
    this.canvas.dataset.tools = this.tools.length;
    if (!this.tools.length) return;
    gl.useProgram(this.toolProg);
    gl.uniformMatrix4fv(gl.getUniformLocation(this.toolProg, 'uM'), false, m);
    gl.bindVertexArray(this.toolVao);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.toolBuf);
    const tools = this.tools.slice(0, 40);
    gl.bufferSubData(gl.ARRAY_BUFFER, 0, new Float32Array(tools.flatMap((t) => t.p)));
    // The larger marker first, over it the smaller: two hands at one point read as a ring.
    gl.disable(gl.DEPTH_TEST);
    const order = tools.map((t, i) => i).sort((a, b) => (tools[b].size || 14) - (tools[a].size || 14));
    for (const i of order) {
      gl.uniform1f(gl.getUniformLocation(this.toolProg, 'uSize'), (tools[i].size || 14) * dpr);
      gl.uniform3fv(gl.getUniformLocation(this.toolProg, 'uColour'), tools[i].colour);
      gl.drawArrays(gl.POINTS, i, 1);
    }
    gl.enable(gl.DEPTH_TEST);
    gl.bindVertexArray(null);
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
  // A recorded frame: every vertex's displacement from rest (3 per vertex) in units of `unit` mm.
  setDisplacement(d, unit) {
    const n = Math.min(d.length, this.rest.length);
    for (let i = 0; i < n; ++i) this.pos[i] = this.rest[i] + d[i] * unit;
    this.draw();
  }
  // A cut's triangles (as many as the rest's: a removed one is 0, 0, 0), drawn from the next draw.
  setTriangles(tris) {
    if (tris.length !== this.tris.length) return;
    this.tris = tris;
    const gl = this.gl;
    // A copy a cut made takes its original's material, so the skin is continuous at the lips.
    const copies = new Set();
    for (let k = 0; k < tris.length; ++k) {
      const v = tris[k], o = this.restTris[k];
      if (v === o || 3 * v >= this.material.length || (tris[k - k % 3] === 0 && tris[k - k % 3 + 1] === 0)) continue;
      for (let a = 0; a < 3; ++a) this.material[3 * v + a] = this.rest[3 * o + a];
      for (let a = 0; a < 2; ++a) this.broad[2 * v + a] = this.broad[2 * o + a];
      copies.add(v);
    }
    this.canvas.dataset.copies = String(copies.size);  // copies drawn with their original's skin
    if (copies.size) {
      gl.bindBuffer(gl.ARRAY_BUFFER, this.buf.r); gl.bufferSubData(gl.ARRAY_BUFFER, 0, this.material);
      gl.bindBuffer(gl.ARRAY_BUFFER, this.buf.b); gl.bufferSubData(gl.ARRAY_BUFFER, 0, this.broad);
    }
    gl.bindVertexArray(this.vao);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.ebo); gl.bufferSubData(gl.ELEMENT_ARRAY_BUFFER, 0, this.tris);
    gl.bindVertexArray(null);
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
    this.drawTrail(m);
    this.drawTools(m);
    this.frames++;
    c.dataset.frames = this.frames;
  }
}
