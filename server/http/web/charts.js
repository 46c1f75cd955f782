// Plots on a 2D canvas: a scrolling window of live values (Plot) and a static line chart.
export class Plot {
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
export function lineChart(canvas, series, xLabel, yLabel) {
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
