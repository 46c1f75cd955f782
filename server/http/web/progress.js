// The training programme's shared views: a trainee's progress through a course (states,
// targets met or missed, what to improve), one exercise's learning curves (each target's metric
// over attempts with its target band, and the CUSUM chart with its decision limits), and a
// cohort's mean curve against the experts'. Used by the instructor's page and the trainee's own.
import { api } from './api.js';
import { xyChart } from './charts.js';
import { el, fmt } from './dom.js';

// Metric names as people read them, with their units.
const METRICS = {
  completion_time_s: ['completion time', 's', 1], task_error: ['task error', '', 3],
  peak_force_n: ['peak force', 'N', 2], time_over_force_limit_s: ['time over the force limit', 's', 2],
  path_length_m: ['path length', 'm', 3], rms_jerk: ['RMS jerk', 'm/s³', 0],
  overload_events: ['overload events', '', 0], score: ['score', '/10', 1],
  guided_share: ['share of the trial guided', '', 2],
  lumps_missed: ['lumps missed', '', 0], false_marks: ['false marks', '', 0],
  localisation_error_m: ['localisation error', 'm', 4], coverage: ['share of the surface examined', '', 2],
  depth_error_m: ['needle depth error', 'm', 4], path_deviation_m: ['needle path deviation', 'm', 4],
  extra_punctures: ['punctures beyond the path\'s own', '', 0], back_wall_breaches: ['back-wall breaches', '', 0],
  lateral_strain: ['lateral tissue strain', '', 3],
  cut_deviation_max_m: ['largest deviation from the line', 'm', 4], cut_outside_m: ['length cut outside the band', 'm', 4],
  torn_length_m: ['length torn by pulling', 'm', 4], cut_lifts: ['blade lifts mid-cut', '', 0],
};
export function metricName(m) { return (METRICS[m] || [m])[0]; }
export function metricValue(m, v) {
  const [, unit, digits] = METRICS[m] || [m, '', 2];
  return v === null || v === undefined ? '—' : `${fmt(v, digits)}${unit ? ' ' + unit : ''}`;
}
export const STATE_TEXT = { locked: 'locked', not_started: 'not started', training: 'training', stalled: 'stalled', proficient: 'proficient' };
export function stateCell(state) { return el('span', { class: 'badge st-' + state }, STATE_TEXT[state] || state); }

// An exercise's task as a sentence: "twist to 60° ± 5°, held 2 s, under 2 N, within 45 s".
export function taskText(t) {
  if (!t) return '';
  if (t.kind === 'palpate')
    return `search for hidden lumps and mark them, under ${fmt(t.force_limit_n, 1)} N, within ${fmt(t.time_limit_s, 0)} s`;
  if (t.kind === 'insert')
    return `place a needle in the target within ${fmt(t.tolerance, 1)} mm of its middle, under ${fmt(t.force_limit_n, 1)} N, within ${fmt(t.time_limit_s, 0)} s`;
  const u = t.unit === 'deg' ? '°' : ' mm';
  return `${t.kind === 'twist' ? 'twist to' : 'press to'} ${fmt(t.target, t.unit === 'deg' ? 0 : 1)}${u} ± ${fmt(t.tolerance, 1)}${u}, ` +
    `held ${fmt(t.hold_s, 1)} s, under ${fmt(t.force_limit_n, 1)} N, within ${fmt(t.time_limit_s, 0)} s`;
}

// A target as a sentence: "peak force ≤ 1.50 N (experts, 3 trials)".
export function targetText(t) {
  if (t.value === null) return `${metricName(t.metric)}: waiting for expert trials (${t.expert_trials} of 2)`;
  return `${metricName(t.metric)} ${t.better === 'higher' ? '≥' : '≤'} ${metricValue(t.metric, t.value)}` +
    (t.from_experts ? ` (experts, ${t.expert_trials} trials)` : '');
}

// One exercise's checks of the last attempt: each target met or missed, with the value.
export function checksList(checks) {
  return el('ul', { class: 'checks' }, checks.map((c) => el('li', { class: c.met ? 'met' : 'missed' },
    el('span', { class: 'mark', 'aria-hidden': 'true' }, c.met ? '✓' : '✗'),
    `${metricName(c.metric)} ${metricValue(c.metric, c.value)} `, el('span', { class: 'muted' }, `(target ${metricValue(c.metric, c.target)})`),
    el('span', { class: 'sr-only' }, c.met ? ' met' : ' missed'))));
}

// A trainee's course: one card per exercise, in order.
export function courseCards(course, progress) {
  return el('div', { class: 'course-cards' }, course.exercises.map((e, i) => {
    const p = progress.exercises[i];
    return el('article', { class: 'exercise st-' + p.state, 'data-exercise': e.id },
      el('h3', {}, `${e.position}. ${e.title} `, stateCell(p.state), progress.next_exercise === e.id ? el('span', { class: 'badge next' }, 'next') : null),
      el('p', { class: 'muted' }, `${e.scene} · ${p.attempts} attempt${p.attempts === 1 ? '' : 's'} · ${p.streak} passed in a row of ${e.spec.consecutive} needed` +
        (p.proficient_at ? ` · proficient at attempt ${p.proficient_at}` : '')),
      e.task ? el('p', { class: 'task' }, 'Task: ', taskText(e.task)) : null,
      el('ul', { class: 'targets' }, e.targets.map((t) => el('li', {}, targetText(t)))),
      p.last_checks.length ? [el('h4', {}, 'Your last attempt'), checksList(p.last_checks)] : null,
      p.to_improve.length && p.state !== 'proficient' ? el('p', { class: 'improve' }, 'To improve: ', p.to_improve.map(metricName).join(', ')) : null);
  }));
}

// One trainee's curves at one exercise into `target`.
export async function showCurve(target, trainee, exerciseId) {
  const c = await api('GET', `/training/curve?trainee=${encodeURIComponent(trainee)}&exercise=${exerciseId}`);
  const k = c.cusum, n = c.attempts.length;
  const charts = [];
  const cusumCanvas = el('canvas', { id: 'cusum-chart' });
  const crossing = k.proficient_at ? `crossed into proficiency (below −h₀) at attempt ${k.proficient_at}`
    : k.unacceptable_at ? `crossed the unacceptable limit h₁ at attempt ${k.unacceptable_at}` : 'between the limits so far';
  const parts = [el('h3', {}, `${c.trainee} · ${c.exercise.title} (${c.course.name})`),
    el('p', {}, `${n} attempt${n === 1 ? '' : 's'}; ${c.progress.proficient_at ? `proficient at attempt ${c.progress.proficient_at} (${c.exercise.spec.consecutive} passes in a row)` : 'not proficient yet'}.`),
    el('h4', {}, 'CUSUM of failed attempts'),
    el('p', { class: 'muted' }, `Acceptable failure rate p₀ = ${k.p0}, unacceptable p₁ = ${k.p1}, α = ${k.alpha}, β = ${k.beta}: each pass lowers the sum by s = ${fmt(k.s, 3)}, each failure raises it by ${fmt(1 - k.s, 3)}; limits h₁ = ${fmt(k.h1, 2)} and −h₀ = ${fmt(-k.h0, 2)}. The curve ${crossing}.`),
    el('div', { class: 'chart-box' }, cusumCanvas)];
  for (const t of c.exercise.targets) {
    const canvas = el('canvas', { class: 'metric-chart', 'data-metric': t.metric });
    parts.push(el('h4', {}, `${metricName(t.metric)} over attempts`), el('div', { class: 'chart-box' }, canvas));
    charts.push([canvas, t]);
  }
  target.replaceChildren(...parts);
  const xs = c.attempts.map((a) => a.n);
  const flat = (y) => [{ x: 1, y }, { x: Math.max(n, 2), y }];
  xyChart(cusumCanvas, { xLabel: 'attempt', yLabel: 'CUSUM', height: 220,
    series: [{ label: 'CUSUM', points: c.attempts.map((a, i) => ({ x: a.n, y: k.values[i] })) },
      { label: 'h₁ (unacceptable)', points: flat(k.h1) }, { label: '−h₀ (proficient)', points: flat(-k.h0) }],
    describe: `CUSUM over ${n} attempts: ${k.values.map((v) => fmt(v, 2)).join(', ') || 'none yet'}; limits ${fmt(k.h1, 2)} and ${fmt(-k.h0, 2)}; ${crossing}.` });
  for (const [canvas, t] of charts) {
    const pts = c.attempts.filter((a) => a.metrics[t.metric] !== null).map((a) => ({ x: a.n, y: a.metrics[t.metric] }));
    const ys = pts.map((p) => p.y).concat(t.value === null ? [] : [t.value]);
    const top = Math.max(...ys, 0) * 1.15 || 1;
    const band = t.value === null ? undefined : t.better === 'higher' ? { lo: t.value, hi: Math.max(top, t.value), label: 'target met' } : { lo: 0, hi: t.value, label: 'target met' };
    xyChart(canvas, { xLabel: 'attempt', yLabel: `${metricName(t.metric)}${METRICS[t.metric] && METRICS[t.metric][1] ? ' (' + METRICS[t.metric][1] + ')' : ''}`, height: 200,
      yMin: 0, series: [{ label: metricName(t.metric), points: pts }], band,
      describe: `${metricName(t.metric)} over ${xs.length} attempts: ${pts.map((p) => metricValue(t.metric, p.y)).join(', ') || 'none yet'}; ${targetText(t)}.` });
  }
  return c;
}

// A cohort's mean curve (± SD) at one exercise, beside the experts' mean ± SD.
export async function showCohortCurve(target, cohortId, exerciseId) {
  const c = await api('GET', `/training/cohorts/${cohortId}/curve?exercise=${exerciseId}`);
  const parts = [el('h3', {}, `Cohort curve · ${c.exercise.title}`)];
  const charts = [];
  for (const m of c.metrics) {
    const canvas = el('canvas', { class: 'cohort-chart', 'data-metric': m.metric });
    parts.push(el('h4', {}, `${metricName(m.metric)}: cohort mean ± SD by attempt, experts ${m.experts.trials ? `${metricValue(m.metric, m.experts.mean)} ± ${metricValue(m.metric, m.experts.sd)} (${m.experts.trials} trials)` : '(no expert trials)'}`),
      el('div', { class: 'chart-box' }, canvas));
    charts.push([canvas, m]);
  }
  target.replaceChildren(...parts);
  for (const [canvas, m] of charts) {
    const pts = (f) => m.points.map((p) => ({ x: p.n, y: f(p) }));
    xyChart(canvas, { xLabel: 'attempt', yLabel: metricName(m.metric), height: 200, yMin: 0,
      series: [{ label: 'cohort mean', points: pts((p) => p.mean) }, { label: 'mean + SD', points: pts((p) => p.mean + p.sd) },
        { label: 'mean − SD', points: pts((p) => Math.max(0, p.mean - p.sd)) }],
      band: m.experts.trials ? { lo: Math.max(0, m.experts.mean - m.experts.sd), hi: m.experts.mean + m.experts.sd, label: 'experts mean ± SD' } : undefined,
      describe: `${metricName(m.metric)}, cohort mean by attempt: ${m.points.map((p) => `${p.n}: ${metricValue(m.metric, p.mean)} (${p.trainees})`).join(', ') || 'no attempts'}.` });
  }
}

