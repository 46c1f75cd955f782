// One session: its head, the tissue in 3D, live plots, and its trial metrics once it ended.
import { api } from '../api.js';
import { Plot } from '../charts.js';
import { confirmed, el, fmt, message, stateBadge, when } from '../dom.js';
import { loadScenes, scenesByName } from '../scenes.js';
import { TissueView } from '../tissue_view.js';

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

export async function pageSession(main) {
  const id = location.pathname.split('/')[2];
  const s = await api('GET', '/sessions/' + id);
  await loadScenes();
  const head = el('div', { class: 'panel' });
  const renderHead = (x) => head.replaceChildren(
    el('dl', { class: 'kv' }, ['Trainee', x.trainee, 'Scene', x.scene, 'State', stateBadge(x.state),
      'Started', when(x.started), 'Ended', when(x.ended), 'End reason', x.end_reason || '—']
      .map((v, i) => (i % 2 ? el('dd', {}, v) : el('dt', {}, v)))));
  renderHead(s);
  const stop = el('button', { class: 'danger', id: 'stop' }, 'Stop session');
  const note = el('div');
  stop.addEventListener('click', async () => {
    if (!confirmed(`Stop session ${id} now? The trainee's trial ends where it is and is scored as it stands.`)) return;
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
