// One session, live or as a record: its head, the tissue in 3D (live, or replayed on a timeline),
// its traces on their own axes with targets and limits, the trial metrics, its ratings, and for
// an evaluator the scoring form beside the evidence.
import { api, auth } from '../api.js';
import { confirmed, el, facts, fmt, kv, message, stateBadge, when } from '../dom.js';
import { guidancePanel } from '../guidance.js';
import { Replay } from '../replay.js';
import { indexName, momentText } from '../rubric.js';
import { loadScenes, scenesByName } from '../scenes.js';
import { scoreForm } from '../score_form.js';
import { TissueView } from '../tissue_view.js';
import { traceCharts } from '../traces.js';

const LIVE = ['created', 'running', 'stalled'];

function metricsList(m, palpation, needle) {
  if (!m) return el('p', { class: 'muted' }, 'No trial metrics recorded.');
  const rows = [
    ['Score (0–10)', fmt(m.score, 2)], ['Raw score (before caps)', fmt(m.raw_score, 2)],
    ['Task completed', m.completed ? 'yes' : 'no'], ['Completion time (s)', fmt(m.completion_time, 2)],
    ['Task error', fmt(m.task_error, 4)], ['Peak force (N)', fmt(m.peak_force, 2)],
    ['Time over the task force limit (s)', fmt(m.time_over_force_limit, 2)], ['Path length (m)', fmt(m.path_length, 3)],
    ['RMS jerk (m/s³)', fmt(m.rms_jerk, 1)], ['Tissue overload events (model capacity exceeded)', m.overload_events],
    ['Duration (s)', fmt(m.duration, 1)],
  ];
  const caps = [m.capped_not_completed && 'not completed (at most 5)', m.capped_force_limit && 'over the force limit for more than 0.5 s (at most 4)',
    m.capped_overload && 'tissue overloaded (at most 3)', m.capped_back_wall && 'through the target\'s back wall (at most 3)'].filter(Boolean);
  rows.push(['Score capped because', caps.length ? caps.join('; ') : 'no cap']);
  if (palpation) {  // a search for hidden lumps: what it found, where, and how much it examined
    rows.push(['Lumps found', `${m.lumps_found} of ${m.lumps}` + (m.lumps > m.lumps_found ? ` (${m.lumps - m.lumps_found} missed)` : '')],
      ['False marks (no lump there)', m.false_marks],
      ['Localisation error (mm, mean over the lumps found)', m.lumps_found ? fmt(1e3 * m.localisation_error, 1) : '—'],
      ['Share of the surface examined', `${fmt(100 * m.coverage, 0)}%`], ['Mean force in contact (N)', fmt(m.mean_force, 2)]);
  }
  if (needle) {  // a needle insertion: where the tip went, the aim, and what it cost the tissue
    rows.push(['Needle depth error (mm, from the target\'s middle along the tract)', m.punctures ? fmt(1e3 * m.depth_error, 1) : '—'],
      ['Path deviation (mm, the tract from the target\'s centre)', m.punctures ? fmt(1e3 * m.path_deviation, 1) : '—'],
      ['Punctures', `${m.punctures}` + (m.extra_punctures ? ` (${m.extra_punctures} beyond the path's own)` : '')],
      ['Back-wall breaches', m.back_wall_breaches], ['Lateral tissue strain (peak)', `${fmt(100 * m.lateral_strain, 1)}%`]);
  }
  if (m.cut_deviation_max > 0 || m.cut_lifts > 0 || m.torn_length > 0) {  // a pattern cut
    rows.push(['Deviation from the line (mm, RMS / largest)', `${fmt(1e3 * m.task_error, 2)} / ${fmt(1e3 * m.cut_deviation_max, 2)}`],
      ['Share of the pattern cut within the band', `${fmt(100 * m.coverage, 0)}%`],
      ['Cut outside the band (mm)', fmt(1e3 * m.cut_outside, 1)], ['Torn by pulling (mm)', fmt(1e3 * m.torn_length, 1)],
      ['Blade lifts mid-cut', m.cut_lifts]);
  }
  // Four-handed training: how much of the trial an instructor's hand weighed in, and how much.
  rows.push(['Share of the trial guided', m.guided_share > 0 ? `${fmt(100 * m.guided_share, 0)}% at a mean α of ${fmt(m.guided_alpha, 2)}` : 'none: the trainee alone']);
  const l = m.link;  // what the station rendered and how the link held (0 when not reported)
  if (l && l.rate_hz > 0) {
    rows.push(['Peak force felt at the station (N)', fmt(l.station_peak_force_n, 2)],
      ['Time over the force limit at the station (s)', fmt(l.station_time_over_limit_s, 2)],
      ['Link: round trip (ms)', fmt(l.rtt_ms, 1)], ['Link: jitter (ms)', fmt(l.jitter_ms, 2)],
      ['Link: loss (%)', fmt(100 * l.loss_ratio, 1)], ['Link: stylus datagrams (per s)', fmt(l.rate_hz, 0)]);
  }
  return kv(rows, { id: 'metrics' });
}

function ratingsList(ratings) {
  if (!ratings.length) return el('p', { class: 'muted' }, 'No evaluation yet.');
  return el('div', { id: 'ratings' }, ratings.map((r) => el('article', { class: 'rating' },
    el('h3', {}, `${r.evaluator ? r.evaluator + ', ' : ''}${r.evaluator_group.replace('_', ' ')} · ${momentText(r.moment_min)} · `, when(r.submitted)),
    r.comment ? el('blockquote', { class: 'comment' }, r.comment) : el('p', { class: 'muted' }, 'No comment.'),
    el('ul', { class: 'index-scores' }, r.scores.map((x, j) => el('li', {}, el('span', {}, indexName(WEIGHTS.names[j], j)), el('b', {}, fmt(x, 1))))))));
}
const WEIGHTS = { names: [], index: [] };

// The hands on the tool as the 3D view draws them: the trainee's tip (blue) and, while one is on
// the tool, the instructor's (amber); `src` is a telemetry sample or a record's series at one index.
const TRAINEE = [0.35, 0.72, 1.0], INSTRUCTOR = [1.0, 0.68, 0.18];
function toolsOf(src) {
  const out = [];
  if (src.tip_x_mm === undefined) return out;
  out.push({ p: [src.tip_x_mm, src.tip_y_mm, src.tip_z_mm], colour: TRAINEE, size: 12 });
  if (src.instructor) out.push({ p: [src.instructor_x_mm, src.instructor_y_mm, src.instructor_z_mm], colour: INSTRUCTOR, size: 22 });
  return out;
}
// The record's sample at time t (the last at or before it).
function seriesAt(series, t) {
  const T = (series && series.time_s) || [];
  if (!T.length || t < T[0]) return {};
  let lo = 0, hi = T.length - 1;
  while (lo < hi) { const mid = (lo + hi + 1) >> 1; if (T[mid] <= t) lo = mid; else hi = mid - 1; }
  const out = {};
  for (const [k, v] of Object.entries(series)) out[k] = v[lo];
  return out;
}
const legend = () => el('p', { class: 'tool-legend muted' }, el('span', { class: 'dot trainee' }), ' the trainee\'s tool ',
  el('span', { class: 'dot instructor' }), ' the instructor\'s hand (four-handed training)');
const taskText = (scene) => scene.task === 'press' ? `press to ${fmt(scene.target, 0)} mm`
  : scene.task === 'palpate' ? 'search for hidden lumps and mark them'
  : scene.task === 'insert' ? 'place a needle in the target under the skin'
  : scene.task === 'cut' ? 'hold the tissue with one hand, cut out the marked pattern with the other'
    : `twist to ${fmt(scene.target, 0)}° ± ${fmt(scene.tolerance, 0)}°`;
// An ended search's lumps (over the surface above each: red, green once a mark placed by the time
// shown found it) and the trainee's marks placed by then (green on a lump, orange on none; a
// record from before marks carried their lump draws them green), as the station's summary draws
// them; during the search nobody sees the lumps.
const LUMP = [0.95, 0.3, 0.25], MARK = [0.3, 0.9, 0.45], FALSE_MARK = [1.0, 0.62, 0.1];
function palpationMarkers(p, t) {
  if (!p) return [];
  const placed = p.marks.filter((k) => k.time_s <= t);
  const found = new Set(placed.filter((k) => k.lump >= 0).map((k) => k.lump));
  return p.lumps.map((l, i) => ({ p: l.surface_mm, colour: found.has(i) ? MARK : LUMP, size: 10 + 2 * l.radius_mm, found: found.has(i) }))
    .concat(placed.map((k) => ({ p: k.position_mm, colour: k.lump === -1 ? FALSE_MARK : MARK, size: 12 })));
}
// An ended insertion's target (red, at its centre, sized by it) and the tracts the needle left
// (green: where each entered the skin; darker: the deepest point it cut).
const TRACT = [0.15, 0.55, 0.3];
function needleMarkers(n) {
  if (!n) return [];
  const out = n.target ? [{ p: n.target.centre_mm, colour: LUMP, size: 10 + 2 * n.target.radius_mm }] : [];
  for (const t of n.tracts) out.push({ p: t.entry_mm, colour: MARK, size: 10 }, { p: t.deepest_mm, colour: TRACT, size: 8 });
  return out;
}
const needleLegend = () => el('p', { class: 'tool-legend muted', id: 'needle-legend' }, el('span', { class: 'dot lump' }),
  ' the target (at its centre, sized by it) ', el('span', { class: 'dot mark' }), ' where the needle entered the skin, and the deepest point of each tract; the blue line: the tip\'s path');
// The tool's path up to time t from the record's series (at most 4000 points: every k-th sample),
// for a search's or an insertion's replay: where the trainee examined, where the needle went.
function trailOf(series, t) {
  const T = (series && series.time_s) || [], X = series && series.tip_x_mm;
  if (!X || !T.length) return null;
  let n = 0;
  while (n < T.length && T[n] <= t) ++n;
  const step = Math.max(1, Math.ceil(n / 4000)), out = [];
  for (let i = 0; i < n; i += step) out.push(X[i], series.tip_y_mm[i], series.tip_z_mm[i]);
  return new Float32Array(out);
}
const palpationLegend = () => el('p', { class: 'tool-legend muted', id: 'palpation-legend' }, el('span', { class: 'dot lump' }),
  ' a hidden lump (over its centre, sized by it; ', el('span', { class: 'dot mark' }), ' once a mark found it) ',
  el('span', { class: 'dot mark' }), ' the trainee\'s marks (', el('span', { class: 'dot false-mark' }), ' where there was no lump); the blue line: the search\'s path');

export async function pageSession(main) {
  const id = location.pathname.split('/')[2];
  const [s] = await Promise.all([api('GET', '/sessions/' + id), loadScenes()]);
  const ws = await api('GET', '/weight-sets').catch(() => null);
  if (ws) { WEIGHTS.names = ws.index_names; WEIGHTS.index = ws.default.index; }
  const scene = scenesByName[s.scene] || { name: s.scene };
  const record = await api('GET', `/sessions/${id}/trace`).catch(() => null);
  const role = auth.me.role, live = LIVE.includes(s.state);
  const head = el('div', { class: 'panel' });
  const renderHead = (x) => head.replaceChildren(facts([['Trainee', x.trainee], ['Scene', x.scene],
    ['Task', taskText(scene)],
    ['State', stateBadge(x.state)], ['Started', when(x.started)], ['Ended', when(x.ended)], ['End reason', x.end_reason || '—'],
    ['Score', x.metrics ? el('b', { class: 'score' }, fmt(x.metrics.score, 1) + ' / 10') : '—']]));
  renderHead(s);
  const note = el('div');
  const view = el('canvas', { id: 'view3d' });
  const traces = traceCharts(scene, live);
  const tissue = el('div', { class: 'panel' }, el('h2', {}, live ? 'Tissue, live' : 'Tissue, replayed'), view, legend());
  const palpation = scene.task === 'palpate';
  const results = el('div', { class: 'panel', id: 'results' }, metricsList(s.metrics, palpation, scene.task === 'insert'));
  const feedback = el('div', { class: 'panel', id: 'feedback' });
  const evidence = el('div', { class: 'evidence' }, tissue, el('div', { class: 'panel' }, el('h2', {}, 'Traces'), traces.panel));
  const stop = el('button', { class: 'danger', id: 'stop' }, 'Stop session');
  const liveFigures = el('div', { class: 'panel', id: 'live-panel' });
  const left = [head, note];
  if (live && (role === 'instructor' || role === 'admin')) left.push(stop);
  const guidance = live ? guidancePanel(id, scene) : null;
  if (live) left.push(liveFigures, guidance.panel);
  left.push(evidence, el('h2', {}, 'Trial metrics and safety events'), results,
    el('h2', {}, role === 'trainee' ? 'What your evaluators said' : 'Evaluations'), feedback);
  // An evaluator scores an ended session beside its replay, traces and metrics.
  const scoring = !live && (role === 'evaluator' || role === 'admin') && ws;
  const body = [el('h1', {}, `Session ${id}`)];
  const rated = el('p', { class: 'muted', id: 'rated' });  // the evaluator's own earlier ratings
  if (scoring) {
    const form = el('div', { class: 'panel', id: 'score-panel' }, el('h2', {}, 'Your evaluation'), rated,
      scoreForm('session', String(id), ws.index_names, ws.default.index, () => loadFeedback()));
    body.push(el('div', { class: 'score-layout' }, el('div', {}, left), form));
  } else {
    body.push(...left);
  }
  main.replaceChildren(...body);
  async function loadFeedback() {
    try {
      const ratings = (await api('GET', `/sessions/${id}/feedback`)).ratings;
      feedback.replaceChildren(ratingsList(ratings));
      const own = ratings.filter((r) => r.evaluator === auth.me.user);
      rated.textContent = own.length ? `You rated this session ${own.map((r) => momentText(r.moment_min)).join(' and ')}; ` +
        'a rating at another moment is a new one.' : '';
    } catch (err) { message(feedback, err.message); }
  }
  loadFeedback();

  let view3d = null;
  try {
    const surface = record && record.rest && record.rest.triangles.length ? record.rest
      : live ? await api('GET', `/sessions/${id}/surface`) : null;
    if (surface) { view3d = new TissueView(view, surface, scene); view3d.draw(); }
    else tissue.append(el('p', { class: 'muted' }, 'This session was never driven: there is nothing to replay.'));
  } catch (err) { message(note, '3D view: ' + err.message); }
  if (record && record.series) { traces.setRecord(record.series); }
  if (!live) {
    if (record && record.frames) {
      const replay = await Replay.load(record, view3d, (t) => {
        traces.cursor(t);
        if (!view3d) return;
        const searched = palpationMarkers(record.palpation, t);
        view3d.tools = toolsOf(seriesAt(record.series, t)).concat(searched, needleMarkers(record.needle));
        view3d.canvas.dataset.found = searched.filter((k) => k.found).length;
        if (record.palpation || record.needle) view3d.setTrail(trailOf(record.series, t));
      });
      tissue.append(replay.controls);
      if (record.palpation) tissue.append(palpationLegend());
      if (record.needle) tissue.append(needleLegend());
    }
    return;
  }
  stop.addEventListener('click', async () => {
    if (!confirmed(`Stop session ${id} now? The trainee's trial ends where it is and is scored as it stands.`)) return;
    try { renderHead(await api('POST', `/sessions/${id}/stop`, { reason: 'stopped by the instructor' })); }
    catch (err) { message(note, err.message); }
  });
  guidance.start();
  watch(id, s, scene, traces, view3d, liveFigures, renderHead, results, stop, guidance);
}

function watch(id, s, scene, traces, view3d, liveFigures, renderHead, results, stop, guidance) {
  const press = scene.task === 'press';
  const figures = el('dl', { class: 'facts', id: 'live-figures' });
  // Said aloud when it changes (a screen reader does not read a figure that changes 10 times a second).
  const spoken = el('p', { class: 'sr-only', role: 'status', 'aria-live': 'polite', id: 'live-summary' });
  liveFigures.replaceChildren(figures, spoken);
  const es = new EventSource(`/api/v1/sessions/${id}/events`);
  let drawn = 0, said = '';
  es.onmessage = (ev) => {
    const t = JSON.parse(ev.data);
    if (t.state !== s.state) { s.state = t.state; renderHead(s); }
    if (t.samples > 0) traces.add(t);
    if (performance.now() - drawn > 250) { traces.update(); drawn = performance.now(); }
    const atLimit = scene.device_max_force_n && t.force_n >= 0.97 * scene.device_max_force_n;
    figures.replaceChildren(...[['State', stateBadge(t.state)],
      ['Force (N)', el('span', { class: atLimit ? 'flag' : '' }, fmt(t.force_n, 2), atLimit ? ' at the device limit' : '')],
      scene.task === 'palpate' ? ['Task', 'searching for lumps'] :
      scene.task === 'insert' ? ['Needle depth (mm)', fmt(t.depth_mm, 1)] :
        [press ? 'Depth (mm)' : 'Twist (°)', press ? fmt(t.depth_mm, 1) : `${fmt(t.twist_deg, 1)} (target ${fmt(scene.target, 0)})`],
      ['Time over the force limit (s)', fmt(t.over_limit_s, 1)], ['Tissue overload events', t.overload_events],
      ['Round trip (ms)', fmt(t.rtt_us / 1000, t.rtt_us < 10e3 ? 2 : 1)], ['Loss (%)', fmt(t.loss_ratio * 100, 2)],
      ['Haptic rate (Hz)', fmt(t.haptic_rate_hz, 0)], ['Score so far', fmt(t.score, 1)], ['Clock jumps', t.clock_jumps]]
      .map(([k, v]) => el('div', {}, el('dt', {}, k), el('dd', {}, v))));
    const say = `${t.state}; score ${fmt(t.score, 0)}${atLimit ? '; at the device force limit' : ''}`;
    if (say !== said) { spoken.textContent = say; said = say; }
    if (view3d) {
      const tools = toolsOf(t), moved = JSON.stringify(tools) !== JSON.stringify(view3d.tools);
      view3d.tools = tools;
      if (t.surface) view3d.apply(t.surface);
      else if (moved) view3d.draw();
    }
  };
  es.addEventListener('ended', async () => {
    es.close();
    const done = await api('GET', '/sessions/' + id);
    renderHead(done); stop.disabled = true; guidance.stop();
    results.replaceChildren(metricsList(done.metrics, scene.task === 'palpate', scene.task === 'insert'));
  });
}
