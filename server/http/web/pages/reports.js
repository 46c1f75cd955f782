// Reports: the weighted evaluation of chosen subjects (picked from those rated), several compared
// side by side as a chart; the training effect as a chart; a trainee's scores over trials.
import { api } from '../api.js';
import { xyChart } from '../charts.js';
import { el, fmt, kv, message, table } from '../dom.js';
import { indexName } from '../rubric.js';

function single(x) {
  return el('div', { class: 'panel report' }, el('h2', {}, 'Subject ' + (x.subject || '')),
    kv([['N (comprehensive score)', el('b', { class: 'comprehensive' }, fmt(x.comprehensive, 3))],
      ['Raters', el('span', { class: 'raters' }, x.raters)],
      ['ICC(2,k)', fmt(x.icc2k, 3)], ["Cronbach's α", fmt(x.cronbach_alpha, 3)],
      ['Absent groups', x.absent_groups && x.absent_groups.length ? x.absent_groups.join(', ') + ' (weights renormalised)' : 'none'],
      ['Weights', x.weights ? x.weights.name : '']]),
    table([{ label: 'Index' }, { label: 'Mean M_j', num: true }, { label: 'SD s_j', num: true }, { label: 'Weight', num: true }],
      x.index_names.map((n, j) => [indexName(n), fmt(x.index_means[j], 2), fmt(Math.sqrt(x.index_variances[j]), 2),
        x.weights ? fmt(x.weights.index[j], 2) : '—'])));
}

function reportView(r) {
  if (!r.subjects) return single(r);
  const chart = el('canvas', { id: 'compare-chart' });
  const box = el('div', {}, el('div', { class: 'panel' }, el('h2', {}, 'Side by side'),
    el('p', {}, `Raters who scored every subject: ${r.common_raters}`), chart), el('div', { class: 'grid' }, r.subjects.map(single)));
  requestAnimationFrame(() => xyChart(chart, { type: 'bar', labels: r.subjects[0].index_names.map(indexName), yMin: 0, yMax: 10,
    yLabel: 'mean score (0–10)', height: 260,
    series: r.subjects.map((x) => ({ label: `${x.subject} (N ${fmt(x.comprehensive, 2)})`, values: x.index_means })),
    describe: 'Mean score per index: ' + r.subjects.map((x) => `${x.subject} N ${fmt(x.comprehensive, 2)}`).join('; ') }));
  return box;
}

export async function pageReports(main) {
  const ws = await api('GET', '/weight-sets');
  const out = el('div', { id: 'report-out' });
  const picks = el('fieldset', { id: 'subjects', class: 'picks' }, el('legend', {}, 'Subjects (up to 32)'));
  const kind = el('select', { name: 'kind', id: 'report-kind' }, ['model', 'trainee', 'session'].map((k) => el('option', { value: k }, k)));
  const form = el('form', { class: 'inline', id: 'report-form' }, el('label', {}, 'Subject kind', kind), picks,
    el('label', {}, 'Weight set', el('select', { name: 'weights' }, el('option', { value: '' }, 'the coil-spring paper\'s (built in)'),
      ws.names.map((n) => el('option', { value: n }, n)))),
    el('button', { type: 'submit' }, 'Report'));
  const loadPicks = async () => {
    const r = await api('GET', '/subjects?kind=' + kind.value);
    picks.replaceChildren(el('legend', {}, 'Subjects (up to 32)'), ...(r.subjects.length ? r.subjects.map((s, i) =>
      el('label', { class: 'check' }, el('input', { type: 'checkbox', name: 'subject', value: s, checked: i < 3 }), s))
      : [el('span', { class: 'muted' }, `No ${kind.value} has been rated yet.`)]));
  };
  kind.addEventListener('change', () => loadPicks().catch((err) => message(out, err.message)));
  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    const f = new FormData(form), q = new URLSearchParams({ kind: f.get('kind'), weights: f.get('weights') });
    const subjects = f.getAll('subject');
    if (!subjects.length) return message(out, 'Choose at least one subject.');
    for (const s of subjects) q.append('subject', s);
    try { out.replaceChildren(reportView(await api('GET', '/reports?' + q))); } catch (err) { message(out, err.message); }
  });
  const effect = el('div', { id: 'training-effect' }), effectChart = el('canvas', { id: 'effect-chart' });
  const traineeOut = el('div'), traineeChart = el('div');
  const known = el('datalist', { id: 'trainee-names' });
  const traineeForm = el('form', { class: 'inline', id: 'trainee-form' },
    el('label', {}, 'Trainee', el('input', { name: 'trainee', required: true, list: 'trainee-names', autocomplete: 'off' })), known,
    el('button', { type: 'submit' }, 'Show'));
  traineeForm.addEventListener('submit', async (e) => {
    e.preventDefault();
    const name = new FormData(traineeForm).get('trainee');
    try {
      const r = await api('GET', '/sessions?trainee=' + encodeURIComponent(name));
      const done = r.sessions.filter((s) => s.metrics).sort((a, b) => a.id - b.id);
      traineeOut.textContent = `${done.length} scored trial${done.length === 1 ? '' : 's'} of ${name}`;
      const c = el('canvas', { id: 'trainee-chart' });
      traineeChart.replaceChildren(c);
      xyChart(c, { xLabel: 'trial', yLabel: 'score (0–10)', yMin: 0, yMax: 10, band: { lo: 8, hi: 10, label: 'proficient (8–10)' },
        series: [{ label: `${name}: trial score`, points: done.map((s, i) => ({ x: i + 1, y: s.metrics.score })) }],
        describe: `${name}'s trial scores: ${done.map((s) => fmt(s.metrics.score, 1)).join(', ')}` });
    } catch (err) { message(traineeOut, err.message); }
  });
  main.replaceChildren(el('h1', {}, 'Reports'), el('div', { class: 'panel' }, form), out,
    el('h2', {}, 'Training effect (trainee group × moment)'), el('div', { class: 'panel' }, effectChart, effect),
    el('h2', {}, "A trainee's scores over trials"), el('div', { class: 'panel' }, traineeForm, traineeOut, traineeChart));
  await loadPicks().catch((err) => message(out, err.message));
  api('GET', '/records?per_page=100').then((r) => known.replaceChildren(...[...new Set(r.sessions.map((s) => s.trainee))]
    .map((n) => el('option', { value: n })))).catch(() => {});
  try {
    const cells = await api('GET', '/training-effect');
    const groups = [...new Set(cells.map((c) => c.trainee_group))];
    const moments = [...new Set(cells.map((c) => c.moment_min))].sort((a, b) => a - b);
    const cell = (g, m) => cells.find((c) => c.trainee_group === g && c.moment_min === m);
    effect.replaceChildren(cells.length ? table([{ label: 'Group' }, ...moments.map((m) => ({ label: m + ' min', num: true }))],
      groups.map((g) => [g, ...moments.map((m) => { const c = cell(g, m); return c ? `${fmt(c.mean, 2)} (n=${c.trainees})` : '—'; })]),
      { id: 'effect-table' }) : el('p', { class: 'muted' }, 'No trainee evaluations at training moments yet.'));
    // Each group its own colour, dash and marker: two groups with equal means stay two lines.
    xyChart(effectChart, { xLabel: 'minutes of training', yLabel: 'mean score (0–10)', yMin: 0, yMax: 10,
      series: groups.map((g) => ({ label: g, points: moments.filter((m) => cell(g, m)).map((m) => ({ x: m, y: cell(g, m).mean })) })),
      describe: 'Training effect: ' + groups.map((g) => `${g}: ` + moments.filter((m) => cell(g, m))
        .map((m) => `${fmt(cell(g, m).mean, 2)} at ${m} min`).join(', ')).join('; ') });
  } catch (err) { message(effect, err.message); }
}
