// An evaluator's queue (sessions to score open beside their replay), the simulator models to
// score, and their own submissions with the moment and comment of each.
import { api } from '../api.js';
import { el, fmt, table, when } from '../dom.js';
import { indexName, momentText } from '../rubric.js';
import { scoreForm } from '../score_form.js';

export async function pageEvaluate(main) {
  const [queue, weights] = await Promise.all([api('GET', '/evaluations/mine'), api('GET', '/weight-sets')]);
  const names = weights.index_names, w = weights.default.index;
  const formBox = el('div', { id: 'model-form' });
  const sessions = table([{ label: 'Session' }, { label: 'Trainee' }, { label: 'Scene' }, { label: 'Ended' }, { label: '' }],
    queue.sessions.map((s) => [String(s.id), s.trainee, s.scene, when(s.ended),
      el('a', { class: 'button', href: `/session/${s.id}#score`, 'aria-label': `Score session ${s.id} beside its replay` }, 'Open and score')]),
    { id: 'pending-sessions' });
  const models = table([{ label: 'Model' }, { label: '' }], queue.models.map((m) => [m,
    el('button', { type: 'button', onclick: () => formBox.replaceChildren(el('div', { class: 'panel' },
      el('h2', {}, `Score the ${m} model`), scoreForm('model', m, names, w, () => setTimeout(() => pageEvaluate(main), 800)))) }, 'Score')]),
  { id: 'pending-models' });
  const past = table([{ label: 'Submitted' }, { label: 'Subject' }, { label: 'Moment' }, { label: 'Scores' }, { label: 'Comment' }],
    queue.submitted.map((s) => [when(s.submitted), `${s.subject_kind} ${s.subject}`, momentText(s.moment_min),
      el('ul', { class: 'index-scores compact' }, s.scores.map((x, j) => el('li', {}, el('span', {}, indexName(names[j], j)), el('b', {}, fmt(x, 1))))),
      s.comment || '—']), { id: 'past' });
  main.replaceChildren(el('h1', {}, 'Evaluate'),
    el('h2', {}, 'Sessions waiting for your scores'),
    el('div', { class: 'panel' }, queue.sessions.length ? sessions : el('p', { class: 'muted' }, 'None.')),
    el('h2', {}, 'Simulator models waiting for your scores'),
    el('div', { class: 'panel' }, queue.models.length ? models : el('p', { class: 'muted' }, 'None.')), formBox,
    el('h2', {}, 'Your submissions'), el('div', { class: 'panel' }, queue.submitted.length ? past : el('p', { class: 'muted' }, 'None yet.')));
}
