// A trainee's own page: their latest score and what the evaluators said, their scores over
// trials, and every session (each opens its replay). Reads on a phone.
import { api, auth } from '../api.js';
import { xyChart } from '../charts.js';
import { el, fmt, stateBadge, table, when } from '../dom.js';
import { courseCards, showCurve } from '../progress.js';
import { indexName, momentText } from '../rubric.js';

export async function pageMine(main) {
  const [r, ws] = await Promise.all([api('GET', '/sessions?trainee=' + encodeURIComponent(auth.me.user)),
    api('GET', '/weight-sets').catch(() => null)]);
  const scored = r.sessions.filter((s) => s.metrics).sort((a, b) => a.id - b.id);
  const latest = scored[scored.length - 1];
  const feedback = el('div', { id: 'my-feedback' });
  const chart = el('canvas', { id: 'my-scores' });
  const course = el('div', { id: 'my-course' });
  main.replaceChildren(el('h1', {}, 'My training'), course,
    el('div', { class: 'panel', id: 'my-latest' }, latest
      ? [el('h2', {}, 'Your latest trial'), el('p', { class: 'big' }, el('b', {}, fmt(latest.metrics.score, 1)), ' / 10 on ', latest.scene, ' · ', when(latest.ended)),
        el('a', { href: '/session/' + latest.id }, 'Replay it and see its traces')]
      : el('p', {}, 'No scored trial yet. When your instructor prepares a session for you, start your station with the session number they give you.')),
    el('h2', {}, 'What your evaluators said'), el('div', { class: 'panel' }, feedback),
    el('h2', {}, 'Your scores over trials'), el('div', { class: 'panel' }, chart),
    el('h2', {}, 'All your sessions'), el('div', { class: 'panel' }, table(
      [{ label: 'Session' }, { label: 'Scene' }, { label: 'State' }, { label: 'Started' }, { label: 'Score', num: true }, { label: '' }],
      r.sessions.map((s) => [String(s.id), s.scene, stateBadge(s.state), when(s.started), s.metrics ? fmt(s.metrics.score, 1) : '—',
        el('a', { href: '/session/' + s.id }, 'Open')]), { id: 'my-sessions' })));
  xyChart(chart, { xLabel: 'trial', yLabel: 'score (0–10)', yMin: 0, yMax: 10, height: 200,
    series: [{ label: 'trial score', points: scored.map((s, i) => ({ x: i + 1, y: s.metrics.score })) }],
    band: { lo: 8, hi: 10, label: 'proficient (8–10)' },
    describe: `Your trial scores, ${scored.length} trials: ${scored.map((s) => fmt(s.metrics.score, 1)).join(', ') || 'none yet'}.` });
  await showCourses(course);
  // Feedback on the latest sessions that have any (a few requests; the list is short).
  const items = [];
  for (const s of scored.slice(-10).reverse()) {
    const f = await api('GET', `/sessions/${s.id}/feedback`).catch(() => ({ ratings: [] }));
    for (const x of f.ratings) items.push({ s, x });
  }
  const names = ws ? ws.index_names : [];
  feedback.replaceChildren(...(items.length ? items.map(({ s, x }) => {
    return el('article', { class: 'rating' },
      el('h3', {}, `Session ${s.id} (${s.scene}) · ${x.evaluator_group.replace('_', ' ')} · ${momentText(x.moment_min)}`),
      x.comment ? el('blockquote', { class: 'comment' }, x.comment) : null,
      el('ul', { class: 'index-scores compact' }, x.scores.map((v, j) => el('li', {}, el('span', {}, indexName(names[j], j)), el('b', {}, fmt(v, 1))))),
      el('a', { href: '/session/' + s.id }, 'See the session'));
  }) : [el('p', { class: 'muted' }, 'No evaluation of your sessions yet.')]));
}

// The trainee's courses: each exercise's state, targets and last checks, and the curves of the
// exercise they are working on (or the last one they reached).
async function showCourses(target) {
  const r = await api('GET', '/training/mine').catch(() => ({ courses: [] }));
  if (!r.courses.length) return;
  const parts = [];
  const curves = [];
  for (const { course, progress } of r.courses) {
    const next = course.exercises.find((e) => e.id === progress.next_exercise);
    parts.push(el('h2', {}, `Your course: ${course.name}`),
      el('p', { class: 'big', id: 'my-next' }, progress.completed ? 'You reached proficiency in every exercise of this course.'
        : next ? [`Next: `, el('b', {}, `${next.position}. ${next.title}`), ` (${next.scene}). Sign in at a station and it starts this exercise.`] : ''),
      el('div', { class: 'panel' }, courseCards(course, progress)));
    const focus = next || course.exercises[course.exercises.length - 1];
    const box = el('div', { class: 'panel my-curve' });
    parts.push(el('h2', {}, `Your curve: ${focus.title}`), box);
    curves.push([box, focus.id]);
  }
  target.replaceChildren(...parts);
  for (const [box, id] of curves) await showCurve(box, auth.me.user, id).catch(() => null);
}
