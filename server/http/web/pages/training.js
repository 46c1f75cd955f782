// The training programme for instructors (and administrators): the cohort grid (trainees ×
// exercises, coloured by state, stalled trainees flagged, refreshed every 5 s), one trainee's
// learning curves and CUSUM, the cohort's mean curve against the experts', building a course
// with targets fixed or taken from expert trials, cohorts and enrolments, and the exports.
import { api } from '../api.js';
import { el, message } from '../dom.js';
import { metricName, showCohortCurve, showCurve, stateCell, targetText, taskText } from '../progress.js';
import { loadScenes } from '../scenes.js';

const METRIC_NAMES = ['completion_time_s', 'peak_force_n', 'time_over_force_limit_s', 'overload_events',
  'path_length_m', 'rms_jerk', 'task_error', 'score', 'guided_share', 'lumps_missed', 'false_marks',
  'localisation_error_m', 'coverage', 'depth_error_m', 'path_deviation_m', 'extra_punctures',
  'back_wall_breaches', 'lateral_strain'];
const REFRESH_MS = 5000;

export async function pageTraining(main) {
  const [courses, cohorts, experts, scenes] = await Promise.all([api('GET', '/training/courses'),
    api('GET', '/training/cohorts'), api('GET', '/training/experts'), loadScenes()]);
  const state = { courses: courses.courses, cohorts: cohorts.cohorts, timer: null };
  const news = el('div', { id: 'training-news', 'aria-live': 'polite' });
  const pick = el('form', { class: 'filters', id: 'grid-pick' });
  const grid = el('div', { id: 'cohort-grid' }), curve = el('div', { id: 'curve' }), cohortCurve = el('div', { id: 'cohort-curve' });
  const exports = el('p', { id: 'progress-exports' });
  main.replaceChildren(el('h1', {}, 'Training programme'), news,
    el('h2', {}, 'Cohort progress'), el('div', { class: 'panel' }, pick, exports, grid),
    el('div', { class: 'grid' }, el('div', { class: 'panel' }, curve), el('div', { class: 'panel' }, cohortCurve)),
    el('h2', {}, 'Build a course'), el('div', { class: 'panel' }, courseForm(scenes, experts.experts, news, async () => {
      state.courses = (await api('GET', '/training/courses')).courses; fillPick();
    })),
    el('h2', {}, 'Cohorts and enrolments'), el('div', { class: 'panel' }, cohortForm(state, news, async () => {
      state.cohorts = (await api('GET', '/training/cohorts')).cohorts; fillPick();
    })));

  const cohortSel = el('select', { name: 'cohort', id: 'grid-cohort' }), courseSel = el('select', { name: 'course', id: 'grid-course' });
  pick.replaceChildren(el('label', {}, 'Cohort', cohortSel), el('label', {}, 'Course', courseSel));
  function fillPick() {
    const keep = [cohortSel.value, courseSel.value];
    cohortSel.replaceChildren(...state.cohorts.map((c) => el('option', { value: c.id }, `${c.name} (${c.members.length})`)));
    courseSel.replaceChildren(...state.courses.map((c) => el('option', { value: c.id }, c.name)));
    if (keep[0]) cohortSel.value = keep[0];
    if (keep[1]) courseSel.value = keep[1];
    drawGrid();
  }
  async function drawGrid() {
    clearTimeout(state.timer);
    if (!cohortSel.value || !courseSel.value) {
      grid.replaceChildren(el('p', { class: 'muted' }, 'Make a course and a cohort below, enrol the cohort, and its grid shows here.'));
      return;
    }
    try {
      const g = await api('GET', `/training/cohorts/${cohortSel.value}/grid?course=${courseSel.value}&offset=${state.offset || 0}`);
      const q = `course=${courseSel.value}&cohort=${cohortSel.value}`;
      exports.replaceChildren('Export progress: ', ...['csv', 'jsonl', 'xapi'].flatMap((f, i) =>
        [i ? ' · ' : '', el('a', { href: `/api/v1/training/export?${q}&format=${f}`, download: '' }, f === 'xapi' ? 'xAPI statements' : f.toUpperCase())]));
      grid.replaceChildren(gridTable(g, (trainee, exercise) => showCurve(curve, trainee, exercise)
        .then(() => { curve.dataset.drawnAt = performance.now().toFixed(1); }).catch((e) => message(curve, e.message)),
      (exercise) => showCohortCurve(cohortCurve, cohortSel.value, exercise).catch((e) => message(cohortCurve, e.message))),
      gridPager(g, (offset) => { state.offset = offset; drawGrid(); }));
      // When the grid was drawn, on the page's clock (the benchmark reads it: bench/training_load.py).
      grid.dataset.drawnAt = performance.now().toFixed(1);
    } catch (err) {
      message(grid, err.message);
    }
    state.timer = setTimeout(drawGrid, REFRESH_MS);  // live: the grid follows the trainees
  }
  const fromStart = () => { state.offset = 0; drawGrid(); };
  cohortSel.addEventListener('change', fromStart);
  courseSel.addEventListener('change', fromStart);
  fillPick();
}

// A large cohort's grid comes a page of trainees at a time: where this page is, and the way on.
function gridPager(g, go) {
  if (g.total_trainees <= g.limit) return null;
  const last = Math.min(g.offset + g.trainees.length, g.total_trainees);
  return el('p', { class: 'pager', id: 'grid-pager' }, `Trainees ${g.offset + 1}–${last} of ${g.total_trainees} `,
    el('button', { type: 'button', disabled: g.offset === 0, onclick: () => go(Math.max(0, g.offset - g.limit)) }, '‹ Previous'), ' ',
    el('button', { type: 'button', disabled: last >= g.total_trainees, onclick: () => go(g.offset + g.limit) }, 'Next ›'));
}

// The grid: a row per trainee (stalled ones flagged first in their name cell), a column per
// exercise; each cell a button opening that trainee's curves.
function gridTable(g, openCurve, openCohortCurve) {
  const head = el('tr', {}, el('th', { scope: 'col' }, 'Trainee'), g.course.exercises.map((e) =>
    el('th', { scope: 'col' }, el('button', { class: 'link', type: 'button', title: 'The cohort curve of this exercise', onclick: () => openCohortCurve(e.id) },
      `${e.position}. ${e.title}`))), el('th', { scope: 'col' }, 'Next'));
  const stalled = g.trainees.filter((t) => t.stalled).length, done = g.trainees.filter((t) => t.completed).length;
  // Trainees in trouble first (stalled), then the rest by name, as the server sends them.
  const ordered = g.trainees.filter((t) => t.stalled).concat(g.trainees.filter((t) => !t.stalled));
  const rows = ordered.map((t) => el('tr', { class: t.stalled ? 'stalled-row' : '', 'data-trainee': t.trainee },
    el('th', { scope: 'row' }, t.trainee, t.stalled ? el('span', { class: 'badge st-stalled flag' }, 'stalled') : null),
    t.exercises.map((c, i) => el('td', { class: 'cell st-' + c.state, 'data-state': c.state, 'data-exercise': c.exercise_id },
      el('button', { type: 'button', class: 'cell-button',
        'aria-label': `${t.trainee}, ${g.course.exercises[i].title}: ${c.state.replace('_', ' ')}, ${c.attempts} attempts` },
      stateCell(c.state), el('span', { class: 'cell-figures' }, `${c.attempts} att · ${c.streak}/${g.course.exercises[i].spec.consecutive}`)))),
    el('td', {}, t.completed ? 'course reached' : t.next_exercise ? (g.course.exercises.find((e) => e.id === t.next_exercise) || {}).title : '—')));
  return el('div', {},
    el('p', { class: 'muted', id: 'grid-summary' }, `${g.trainees.length} trainees · ${done} reached the course · ${stalled} stalled · refreshed ${new Date().toLocaleTimeString()}`),
    // One listener for the 2,000 cells: a cell's button opens its trainee's curves.
    el('div', { class: 'scroll-x' }, el('table', { class: 'progress-grid', id: 'progress-grid', onclick: (ev) => {
      const cell = ev.target.closest('td.cell');
      if (cell && ev.target.closest('button')) openCurve(cell.parentElement.dataset.trainee, Number(cell.dataset.exercise));
    } }, el('thead', {}, head), el('tbody', {}, rows))),
    el('p', { class: 'muted' }, g.course.exercises.map((e) => `${e.position}. ${e.title} (${taskText(e.task)}): ${e.targets.map(targetText).join('; ')}`).join(' — ')));
}

// A course: its name and exercises, each with a scene and targets (a fixed value, or from the
// experts' trials: their mean + 1 SD, or their best quartile).
function courseForm(scenes, experts, news, done) {
  const list = el('div', { id: 'exercise-list' });
  const add = () => list.append(exerciseFieldset(list.children.length + 1, scenes));
  add(); add();
  const form = el('form', { id: 'course-form' },
    el('div', { class: 'filters' },
      el('label', {}, 'Course name', el('input', { name: 'name', required: true, maxlength: 128 })),
      el('label', {}, 'Description', el('input', { name: 'description', maxlength: 400 })),
      el('label', {}, 'Expert benchmark', el('select', { name: 'benchmark' }, el('option', { value: 'mean_sd' }, 'experts’ mean + 1 SD'),
        el('option', { value: 'best_quartile' }, 'experts’ best quartile')))),
    el('p', { class: 'muted' }, experts.length ? `Experts whose trials set benchmarks: ${experts.join(', ')}.` : 'No experts marked yet: mark trainees as experts below before taking targets from them.'),
    list,
    el('button', { type: 'button', onclick: add }, 'Add an exercise'), ' ',
    el('button', { type: 'submit' }, 'Create the course'));
  form.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    const f = new FormData(form);
    const exercises = [...list.children].map((fs, i) => {
      const n = i + 1, get = (k) => fs.querySelector(`[name="${k}-${n}"]`);
      const targets = METRIC_NAMES.filter((m) => get(`use-${m}`).checked).map((m) =>
        get(`experts-${m}`).checked ? { metric: m, from_experts: true } : { metric: m, value: Number(get(`value-${m}`).value) });
      return { title: get('title').value, scene: get('scene').value, spec: { targets, consecutive: Number(get('consecutive').value),
        max_attempts_per_day: Number(get('per-day').value), benchmark: f.get('benchmark'), task: taskSettings(get, scenes) } };
    });
    try {
      const r = await api('POST', '/training/courses', { name: f.get('name'), description: f.get('description'), exercises });
      message(news, `Course “${r.course.name}” created with ${r.course.exercises.length} exercises.`, true);
      await done();
    } catch (err) { message(news, err.message); }
  });
  return form;
}

// The exercise's own task settings from its fieldset: only the fields filled in (the others stay
// as the scene has them), in the scene file's names and units (a press's depth in metres).
function taskSettings(get, scenes) {
  const scene = scenes.find((s) => s.name === get('scene').value), twist = !scene || scene.task === 'twist';
  const out = {}, num = (k) => (!get(k) || get(k).value === '' ? null : Number(get(k).value));
  if (num('task-target') !== null) out[twist ? 'target_deg' : 'target_depth_m'] = twist ? num('task-target') : num('task-target') / 1000;
  if (num('task-tolerance') !== null) out[twist ? 'tolerance_deg' : 'tolerance_m'] = twist ? num('task-tolerance') : num('task-tolerance') / 1000;
  for (const [k, name] of [['task-hold', 'hold_s'], ['task-force', 'force_limit_n'], ['task-time', 'time_limit_s']])
    if (num(k) !== null) out[name] = num(k);
  return out;
}

// The task fields, their units and the scene's own values as placeholders, for the chosen scene.
function taskFields(n, scene) {
  const twist = !scene || scene.task === 'twist', unit = twist ? '°' : 'mm';
  const field = (label, k, value) => el('label', {}, label, el('input', { type: 'number', step: 'any', min: 0, name: `${k}-${n}`, placeholder: scene ? String(value) : '', inputmode: 'decimal' }));
  const limits = [field('Force limit (N)', 'task-force', scene && scene.force_limit_n), field('Time limit (s)', 'task-time', scene && scene.time_limit_s)];
  if (scene && scene.task === 'palpate') return limits;  // a search has no target, tolerance or hold
  return [field(`Target (${unit})`, 'task-target', scene && scene.target), field(`Tolerance (${unit})`, 'task-tolerance', scene && scene.tolerance),
    field('Hold (s)', 'task-hold', scene && scene.hold_s), ...limits];
}

function exerciseFieldset(n, scenes) {
  const metricRow = (m, checked, value, fromExperts) => el('div', { class: 'target-row' },
    el('label', { class: 'inline' }, el('input', { type: 'checkbox', name: `use-${m}-${n}`, checked }), metricName(m)),
    el('label', { class: 'inline' }, 'value', el('input', { type: 'number', step: 'any', name: `value-${m}-${n}`, value, inputmode: 'decimal' })),
    el('label', { class: 'inline' }, el('input', { type: 'checkbox', name: `experts-${m}-${n}`, checked: fromExperts }), 'from experts'));
  const sceneSel = el('select', { name: `scene-${n}` }, scenes.map((s, i) => el('option', { value: s.name, selected: n === 2 ? s.task === 'twist' && !scenes.slice(0, i).some((x) => x.task === 'twist') : i === 0 }, s.name)));
  const task = el('fieldset', { class: 'filters task-fields' }, el('legend', {}, 'Task (empty: as the scene sets it)'));
  const fillTask = () => task.replaceChildren(task.firstChild, ...taskFields(n, scenes.find((s) => s.name === sceneSel.value)));
  sceneSel.addEventListener('change', fillTask);
  fillTask();
  return el('fieldset', { class: 'exercise-fields' }, el('legend', {}, `Exercise ${n}`),
    el('div', { class: 'filters' },
      el('label', {}, 'Title', el('input', { name: `title-${n}`, required: true, maxlength: 128, value: n === 1 ? 'Palpate the sphere' : n === 2 ? 'Twist the arm' : '' })),
      el('label', {}, 'Scene', sceneSel),
      el('label', {}, 'Passes in a row', el('input', { type: 'number', name: `consecutive-${n}`, min: 1, max: 20, value: 2 })),
      el('label', {}, 'Attempts a day (0: no limit)', el('input', { type: 'number', name: `per-day-${n}`, min: 0, max: 1000, value: 0 }))),
    task,
    el('div', { class: 'targets-fields' },
      metricRow('completion_time_s', true, '', true), metricRow('peak_force_n', true, '', true),
      metricRow('overload_events', false, 0, false), metricRow('score', false, 7, false),
      metricRow('time_over_force_limit_s', false, 0.5, false), metricRow('path_length_m', false, '', true),
      metricRow('rms_jerk', false, '', true), metricRow('task_error', false, '', true),
      metricRow('guided_share', false, 0, false),
      // A palpation's own (a search for hidden lumps).
      metricRow('lumps_missed', false, 0, false), metricRow('false_marks', false, 0, false),
      metricRow('localisation_error_m', false, '', true), metricRow('coverage', false, '', true),
      // A needle insertion's own.
      metricRow('depth_error_m', false, '', true), metricRow('path_deviation_m', false, '', true),
      metricRow('extra_punctures', false, 0, false), metricRow('back_wall_breaches', false, 0, false),
      metricRow('lateral_strain', false, '', true)));
}

// Cohorts (name and members) enrolled in a course from a day to a day, one trainee enrolled on
// their own, and experts.
function cohortForm(state, news, done) {
  const courseSelect = () => el('select', { name: 'course' }, state.courses.map((c) => el('option', { value: c.id }, c.name)));
  const dates = () => [el('label', {}, 'From (day; empty: today)', el('input', { type: 'date', name: 'starts' })),
    el('label', {}, 'Until (day, inclusive; empty: open)', el('input', { type: 'date', name: 'ends' }))];
  // The enrolment's days are this browser's local days: from its midnight to the next day's.
  const period = (f) => {
    const out = {};
    if (f.get('starts')) out.starts = new Date(f.get('starts') + 'T00:00').toISOString();
    if (f.get('ends')) { const d = new Date(f.get('ends') + 'T00:00'); d.setDate(d.getDate() + 1); out.ends = d.toISOString(); }
    return out;
  };
  const cohortForm_ = el('form', { id: 'cohort-form', class: 'filters' },
    el('label', {}, 'Cohort name', el('input', { name: 'name', required: true, maxlength: 128 })),
    el('label', { class: 'wide' }, 'Members (trainee names, separated by commas or lines)', el('textarea', { name: 'members', rows: 2 })),
    el('label', {}, 'Enrol in course', courseSelect()), dates(),
    el('button', { type: 'submit' }, 'Create and enrol'));
  cohortForm_.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    const f = new FormData(cohortForm_);
    try {
      const members = String(f.get('members')).split(/[\s,]+/).filter(Boolean);
      const r = await api('POST', '/training/cohorts', { name: f.get('name'), members });
      if (f.get('course')) await api('POST', '/training/enrolments', Object.assign({ course: Number(f.get('course')), cohort: r.cohort.id }, period(f)));
      message(news, `Cohort “${r.cohort.name}” (${r.cohort.members.length} trainees) created${f.get('course') ? ' and enrolled' : ''}.`, true);
      await done();
    } catch (err) { message(news, err.message); }
  });
  const personForm = el('form', { id: 'enrol-form', class: 'filters' },
    el('label', {}, 'Enrol one trainee', el('input', { name: 'trainee', required: true, maxlength: 128 })),
    el('label', {}, 'in course', courseSelect()), dates(),
    el('button', { type: 'submit' }, 'Enrol'));
  personForm.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    const f = new FormData(personForm);
    try {
      await api('POST', '/training/enrolments', Object.assign({ course: Number(f.get('course')), trainee: f.get('trainee') }, period(f)));
      message(news, `${f.get('trainee')} enrolled.`, true);
    } catch (err) { message(news, err.message); }
  });
  const expertForm = el('form', { id: 'expert-form', class: 'filters' },
    el('label', {}, 'Trainee to mark as an expert', el('input', { name: 'trainee', required: true, maxlength: 128 })),
    el('button', { type: 'submit' }, 'Mark as expert'));
  expertForm.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    try {
      await api('POST', '/training/experts', { trainee: new FormData(expertForm).get('trainee'), expert: true });
      message(news, 'Marked as an expert: their trials now set the benchmarks.', true);
    } catch (err) { message(news, err.message); }
  });
  // Keep the forms' course lists current.
  for (const form of [cohortForm_, personForm])
    form.addEventListener('focusin', () => {
      const sel = form.elements.course, keep = sel.value;
      if (sel.options.length === state.courses.length) return;
      sel.replaceChildren(...courseSelect().children);
      if (keep) sel.value = keep;
    });
  return el('div', {}, cohortForm_, personForm, expertForm);
}
