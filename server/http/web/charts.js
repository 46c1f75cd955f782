// Charts over Chart.js (Debian's libjs-chart.js, served by the server at /static/lib/chart.min.js
// and loaded before the modules as window.Chart): a time chart for traces, live (a scrolling
// window) or recorded (with the replay's cursor), and an x–y chart for reports. Every chart's
// canvas is an image with a text alternative (aria-label) kept true to its data.
const C = window.Chart;
if (C) {
  C.defaults.color = '#c9ced8';
  C.defaults.borderColor = '#3a4252';
  C.defaults.font.family = 'system-ui, sans-serif';
}
export const COLOURS = ['#f0b296', '#8cc8ff', '#5fd38a', '#f3c13a', '#d49cff', '#ff8f8f'];
const DASHES = [[], [6, 4], [2, 3], [10, 3, 2, 3]];

// The vertical line of a replay's cursor (chart.$cursor: an x value, or undefined).
const cursorPlugin = {
  id: 'vsurgCursor',
  afterDatasetsDraw(chart) {
    const x = chart.$cursor;
    if (x === undefined) return;
    const s = chart.scales.x, a = chart.chartArea, g = chart.ctx;
    if (x < s.min || x > s.max) return;
    g.save(); g.strokeStyle = '#e6e8ec'; g.lineWidth = 1.5;
    g.beginPath(); g.moveTo(s.getPixelForValue(x), a.top); g.lineTo(s.getPixelForValue(x), a.bottom); g.stroke();
    g.restore();
  },
};

function box(canvas, height) {
  // Chart.js sizes a canvas to its parent: a box of a fixed height, full width.
  const wrap = document.createElement('div');
  wrap.className = 'chart-box';
  wrap.style.height = (height || 180) + 'px';
  canvas.replaceWith(wrap);
  wrap.append(canvas);
  canvas.setAttribute('role', 'img');
}

function range(values) {
  let lo = Infinity, hi = -Infinity;
  for (const v of values) if (isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  return isFinite(lo) ? [lo, hi] : null;
}

// A trace over time (s). opts: {title, unit, series: [{label, colour}], min, suggestedMax,
// lines: [{y, label, colour}] (targets and limits, dashed), span (s; a live window), height}.
export class TimeChart {
  constructor(canvas, opts) {
    this.opts = opts; this.canvas = canvas; this.t = []; this.cols = opts.series.map(() => []);
    box(canvas, opts.height);
    const datasets = opts.series.map((s, i) => ({ label: s.label, data: [], borderColor: s.colour || COLOURS[i],
      backgroundColor: s.colour || COLOURS[i], borderWidth: 1.8, pointRadius: 0, tension: 0 }));
    for (const l of opts.lines || []) {
      datasets.push({ label: l.label, data: [], borderColor: l.colour, backgroundColor: l.colour,
        borderDash: [6, 4], borderWidth: 1.2, pointRadius: 0, $line: l.y });
    }
    this.chart = new C(canvas, {
      type: 'line', data: { datasets }, plugins: [cursorPlugin],
      options: {
        animation: false, parsing: false, normalized: true, responsive: true, maintainAspectRatio: false,
        interaction: { mode: 'nearest', axis: 'x', intersect: false },
        scales: {
          x: { type: 'linear', title: { display: true, text: 'time (s)' }, ticks: { maxTicksLimit: 8, includeBounds: false } },
          y: { title: { display: true, text: `${opts.title} (${opts.unit})` }, min: opts.min,
            suggestedMax: opts.suggestedMax, ticks: { maxTicksLimit: 6 } },
        },
        plugins: { legend: { labels: { boxWidth: 14, filter: (item) => item.text !== '' } }, tooltip: { callbacks: {
          label: (c) => `${c.dataset.label}: ${Number(c.parsed.y).toFixed(2)} ${opts.unit}` } } },
      },
    });
    this.labelled = 0;
    this.describe();
  }
  // The whole record: times and one column per series.
  setAll(times, columns) {
    this.t = times.slice(); this.cols = columns.map((c) => c.slice());
    this.update();
  }
  // One live sample; a live chart keeps its last `span` seconds.
  add(t, values) {
    this.t.push(t); values.forEach((v, i) => this.cols[i].push(v));
    const span = this.opts.span;
    if (span) while (this.t.length && this.t[0] < t - span) { this.t.shift(); this.cols.forEach((c) => c.shift()); }
  }
  setCursor(t) { this.chart.$cursor = t; this.chart.draw(); }
  update() {
    const ds = this.chart.data.datasets, n = this.opts.series.length;
    for (let i = 0; i < n; ++i) ds[i].data = this.t.map((t, k) => ({ x: t, y: this.cols[i][k] }));
    const t0 = this.t.length ? this.t[0] : 0, t1 = this.t.length ? this.t[this.t.length - 1] : 1;
    for (let i = n; i < ds.length; ++i) ds[i].data = [{ x: t0, y: ds[i].$line }, { x: t1, y: ds[i].$line }];
    const x = this.chart.options.scales.x;
    // A live window shows its last `span` seconds once it has them, and the session so far before.
    x.min = this.opts.span ? Math.max(t0, t1 - this.opts.span) : t0; x.max = Math.max(t1, x.min + 1);
    this.chart.update('none');
    if (performance.now() - this.labelled > 2000) this.describe();
  }
  describe() {
    this.labelled = performance.now();
    const o = this.opts, parts = o.series.map((s, i) => {
      const r = range(this.cols[i]), last = this.cols[i][this.cols[i].length - 1];
      return r ? `${s.label} ${Number(last).toFixed(2)} ${o.unit} now, ${r[0].toFixed(2)} to ${r[1].toFixed(2)}`
        : `${s.label}: no data yet`;
    });
    const lines = (o.lines || []).map((l) => `${l.label || 'tolerance'} at ${Number(l.y).toFixed(1)} ${o.unit}`);
    const span = this.t.length > 1 ? ` over ${(this.t[this.t.length - 1] - this.t[0]).toFixed(0)} s` : '';
    this.canvas.setAttribute('aria-label', `${o.title} plot${span}: ${parts.join('; ')}${lines.length ? '; ' + lines.join('; ') : ''}.`);
  }
}

// Lines (or bars) through points: opts {xLabel, yLabel, type: 'line'|'bar', labels (bar x
// categories), series: [{label, points: [{x, y}] | values: [...]}], band: {lo, hi, label},
// yMin, yMax, height, describe: text}.
export function xyChart(canvas, opts) {
  box(canvas, opts.height || 220);
  const bar = opts.type === 'bar';
  const datasets = opts.series.map((s, i) => ({
    label: s.label, data: bar ? s.values : s.points, borderColor: COLOURS[i % COLOURS.length],
    backgroundColor: COLOURS[i % COLOURS.length] + (bar ? 'cc' : ''), borderWidth: 2,
    borderDash: bar ? undefined : DASHES[i % DASHES.length], pointRadius: bar ? 0 : 4,
    pointStyle: ['circle', 'rect', 'triangle', 'rectRot', 'star', 'cross'][i % 6], tension: 0,
  }));
  if (opts.band && !bar) {
    const xs = opts.series.flatMap((s) => s.points.map((p) => p.x)), r = range(xs) || [0, 1];
    const edge = (y) => [{ x: r[0], y }, { x: r[1], y }];
    datasets.push({ label: opts.band.label, data: edge(opts.band.hi), borderColor: '#5fd38a55', pointRadius: 0,
      backgroundColor: 'rgba(95, 211, 138, 0.14)', fill: '+1', borderWidth: 1 });
    datasets.push({ label: '', data: edge(opts.band.lo), borderColor: '#5fd38a55', pointRadius: 0, borderWidth: 1 });
  }
  canvas.setAttribute('aria-label', opts.describe || opts.series.map((s) => s.label).join(', '));
  return new C(canvas, {
    type: bar ? 'bar' : 'line', data: { labels: opts.labels, datasets },
    options: {
      animation: false, responsive: true, maintainAspectRatio: false,
      scales: {
        x: bar ? { title: { display: !!opts.xLabel, text: opts.xLabel } }
          : { type: 'linear', title: { display: true, text: opts.xLabel }, ticks: { precision: 0 } },
        y: { min: opts.yMin, max: opts.yMax, title: { display: true, text: opts.yLabel } },
      },
      plugins: { legend: { labels: { boxWidth: 14, filter: (item) => item.text !== '' } } },
    },
  });
}
