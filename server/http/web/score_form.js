// The evaluator's form: each index with its question and rubric anchors, the training moment
// chosen explicitly, a comment for the trainee. Fields are marked invalid only once touched.
import { api } from './api.js';
import { el, message } from './dom.js';
import { ANCHOR_SCORES, INDEXES, MOMENTS, momentText } from './rubric.js';

// `names`: the API's index_names (stored order); `weights`: the default index weights.
export function scoreForm(kind, subject, names, weights, onDone) {
  const key = 'web:' + (crypto.randomUUID ? crypto.randomUUID() : String(Math.random()).slice(2) + Date.now());
  const note = el('div');
  const fields = names.map((n, j) => {
    const x = INDEXES.find((i) => i.key === n) || { name: n, question: '', anchors: ['', '', ''] };
    const hint = `hint-${j}`;
    return el('fieldset', { class: 'index' },
      el('legend', {}, `${j + 1}. ${x.name}`, el('span', { class: 'muted' }, ` (weight ${weights[j]})`)),
      el('p', { class: 'question', id: hint + 'q' }, x.question),
      el('ul', { class: 'anchors', id: hint }, x.anchors.map((a, k) => el('li', {}, el('b', {}, ANCHOR_SCORES[k]), ' ', a))),
      el('label', {}, `Score for ${x.name}, 0 to 10`,
        el('input', { type: 'number', min: 0, max: 10, step: 0.5, required: true, name: 'i' + j,
          inputmode: 'decimal', 'aria-describedby': `${hint}q ${hint}` })));
  });
  const moment = el('select', { name: 'moment', required: true, id: 'moment' },
    el('option', { value: '' }, 'Choose…'), el('option', { value: 'none' }, 'Not at a training moment'),
    MOMENTS.map((m) => el('option', { value: String(m) }, `${m} min into training`)));
  const comment = el('textarea', { name: 'comment', maxlength: 4000, rows: 4, class: 'prose',
    placeholder: 'What went well, and what to practise next (the trainee reads this).' });
  const submit = el('button', { type: 'submit' }, 'Submit scores');
  const form = el('form', { class: 'score-form', id: 'score' },
    el('label', {}, 'Training moment of this evaluation', moment),
    fields, el('label', {}, 'Comment to the trainee (optional)', comment), submit, note);
  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    form.classList.add('tried');
    if (!form.reportValidity()) return;
    const scores = names.map((_, j) => Number(form.elements['i' + j].value));
    const m = moment.value === 'none' ? null : Number(moment.value);
    submit.disabled = true;
    try {
      // The same key on a retry: the server stores one submission and says it was a duplicate.
      const r = await api('POST', '/evaluations', { idempotency_key: key, subject_kind: kind, subject,
        scores, moment_min: m, comment: comment.value });
      message(note, `Stored (submission ${r.submission_id}, ${momentText(m)}${r.duplicate ? ', already stored' : ''}).`, true);
      if (onDone) onDone(r);
    } catch (err) { message(note, err.message); submit.disabled = false; }
  });
  return form;
}
