// Reports: weighted evaluation reports, the training effect, a trainee's scores over trials.
import { api } from '../api.js';
import { lineChart } from '../charts.js';
import { el, fmt, message } from '../dom.js';

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

export async function pageReports(main) {
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
