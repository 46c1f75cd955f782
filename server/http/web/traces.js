// A session's traces as charts with their units, each on its own axis: the force with the task's
// force limit and the device's limit; the twist with its target band (or the press depth and its
// target); the torque; the round trip in ms. A palpation has its force and round trip only. Live (a 60 s window fed by the event stream, after
// the record so far) or recorded (the whole session, with the replay's cursor).
import { TimeChart } from './charts.js';
import { el } from './dom.js';

export function traceCharts(scene, live) {
  const press = scene && scene.task === 'press', span = live ? 60 : undefined;
  // A search or a cut: its force and link (a cut's line, depth and tearing are its metrics).
  const palpate = scene && (scene.task === 'palpate' || scene.task === 'cut');
  const needle = scene && scene.task === 'insert';  // the needle's depth along its tract
  const limit = [];
  if (scene && scene.force_limit_n) limit.push({ y: scene.force_limit_n, label: 'task force limit', colour: '#f3c13a' });
  if (scene && scene.device_max_force_n) limit.push({ y: scene.device_max_force_n, label: 'device limit', colour: '#ff6b6b' });
  const target = [];
  if (scene && scene.target) {
    target.push({ y: scene.target, label: 'target', colour: '#5fd38a' });
    if (scene.tolerance) {
      target.push({ y: scene.target + scene.tolerance, label: 'tolerance', colour: '#5fd38a88' });
      target.push({ y: Math.max(0, scene.target - scene.tolerance), label: '', colour: '#5fd38a88' });
    }
  }
  const canvas = (id) => el('canvas', { id });
  const specs = [
    { id: 'plot-force', key: ['force_n'], opts: { title: 'force', unit: 'N', min: 0,
      suggestedMax: (scene && scene.device_max_force_n) || 1, series: [{ label: 'force at the tool' }], lines: limit } },
    palpate ? null : needle
      ? { id: 'plot-depth', key: ['depth_mm'], opts: { title: 'needle depth along its tract', unit: 'mm', min: 0,
        suggestedMax: 40, series: [{ label: 'depth', colour: '#8cc8ff' }] } }
      : press
      ? { id: 'plot-depth', key: ['depth_mm'], opts: { title: 'press depth', unit: 'mm', min: 0,
        suggestedMax: scene && scene.target ? scene.target * 1.5 : 10, series: [{ label: 'depth', colour: '#8cc8ff' }], lines: target } }
      : { id: 'plot-twist', key: ['twist_deg'], opts: { title: 'twist', unit: '°',
        suggestedMax: scene && scene.target ? scene.target * 1.5 : 45, series: [{ label: 'twist', colour: '#8cc8ff' }], lines: target } },
    press || palpate || needle ? null : { id: 'plot-torque', key: ['torque_nm'], scale: 1000, opts: { title: 'torque', unit: 'mN·m',
      series: [{ label: 'torque', colour: '#5fd38a' }] } },
    { id: 'plot-rtt', key: ['rtt_us'], scale: 1e-3, opts: { title: 'round trip', unit: 'ms', min: 0,
      suggestedMax: 5, series: [{ label: 'round trip', colour: '#f3c13a' }] } },
  ].filter(Boolean);
  const boxes = specs.map((s) => canvas(s.id));
  const panel = el('div', { class: 'traces' }, boxes);
  let charts = null;
  const make = () => {  // once the canvases are in the page (Chart.js measures their box)
    if (!charts) charts = specs.map((s, i) => ({ s, c: new TimeChart(boxes[i], Object.assign({ span, height: 170 }, s.opts)) }));
    return charts;
  };
  const value = (s, src) => s.key.map((k) => (src[k] === undefined ? NaN : src[k] * (s.scale || 1)));
  return {
    panel,
    // The record (trace JSON's series): every chart's whole data.
    setRecord(series) {
      const t = series.time_s || [];
      for (const { s, c } of make()) c.setAll(t, s.key.map((k) => (series[k] || []).map((v) => v * (s.scale || 1))));
    },
    // One live sample (the event stream's telemetry, by the same names).
    add(t) {
      for (const { s, c } of make()) c.add(t.time_s, value(s, t));
    },
    update() { for (const { c } of make()) c.update(); },
    cursor(time) { for (const { c } of make()) c.setCursor(time); },
  };
}
