// An evaluator's queue, the scoring form and their submissions.
import { api } from '../api.js';
import { el, fmt, message, when } from '../dom.js';

export async function pageEvaluate(main) {
  const [queue, weights] = await Promise.all([api('GET', '/evaluations/mine'), api('GET', '/weight-sets')]);
  const names = weights.index_names, w = weights.default.index;
  const formBox = el('div', { class: 'panel', id: 'score-form' }, el('p', { class: 'muted' }, 'Choose a session or a model to score.'));
  const openForm = (kind, subject) => {
    const key = 'web:' + (crypto.randomUUID ? crypto.randomUUID() : String(Math.random()).slice(2) + Date.now());
    const note = el('div');
    const inputs = names.map((n, j) => el('label', {}, `${n} (weight ${w[j]})`,
      el('input', { type: 'number', min: 0, max: 10, step: 0.5, required: true, name: 'i' + j })));
    const submit = el('button', { type: 'submit' }, 'Submit scores');
    const form = el('form', { class: 'inline' }, inputs, submit);
    form.addEventListener('submit', async (e) => {
      e.preventDefault();
      if (!form.reportValidity()) return;
      const scores = names.map((_, j) => Number(form.elements['i' + j].value));
      submit.disabled = true;
      try {
        // The same key on a retry: the server stores one submission and says it was a duplicate.
        const r = await api('POST', '/evaluations', { idempotency_key: key, subject_kind: kind, subject, scores });
        message(note, `Stored (submission ${r.submission_id}${r.duplicate ? ', already stored' : ''}).`, true);
        setTimeout(() => pageEvaluate(main), 800);
      } catch (err) { message(note, err.message); submit.disabled = false; }
    });
    formBox.replaceChildren(el('h2', {}, `Score ${kind} ${subject}`), form, note);
  };
  const sessions = el('table', { id: 'pending-sessions' },
    el('thead', {}, el('tr', {}, ['Session', 'Trainee', 'Scene', 'Ended', ''].map((h) => el('th', {}, h)))),
    el('tbody', {}, queue.sessions.map((s) => el('tr', {}, el('td', {}, s.id), el('td', {}, s.trainee),
      el('td', {}, s.scene), el('td', {}, when(s.ended)),
      el('td', {}, el('button', { onclick: () => openForm('session', String(s.id)) }, 'Score'))))));
  const models = el('table', { id: 'pending-models' }, el('tbody', {}, queue.models.map((m) => el('tr', {},
    el('td', {}, m), el('td', {}, el('button', { onclick: () => openForm('model', m) }, 'Score'))))));
  const past = el('table', { id: 'past' },
    el('thead', {}, el('tr', {}, ['Submitted', 'Kind', 'Subject', ...names.map((_, j) => 'i' + (j + 1))].map((h) => el('th', {}, h)))),
    el('tbody', {}, queue.submitted.map((s) => el('tr', {}, el('td', {}, when(s.submitted)), el('td', {}, s.subject_kind),
      el('td', {}, s.subject), s.scores.map((x) => el('td', { class: 'num' }, fmt(x, 1)))))));
  main.replaceChildren(el('h1', {}, 'Evaluate'),
    el('h2', {}, 'Sessions waiting for your scores'), el('div', { class: 'panel' }, queue.sessions.length ? sessions : el('p', { class: 'muted' }, 'None.')),
    el('h2', {}, 'Simulator models waiting for your scores'), el('div', { class: 'panel' }, queue.models.length ? models : el('p', { class: 'muted' }, 'None.')),
    formBox, el('h2', {}, 'Your submissions'), el('div', { class: 'panel' }, past));
}
