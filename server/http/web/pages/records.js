// Past sessions as records: filters (trainee, scene, dates, score), pages of 25, each row opening
// the session's page (its replay, traces, metrics and ratings). For instructors and evaluators.
import { api, auth } from '../api.js';
import { el, fmt, message, stateBadge, table, when } from '../dom.js';
import { loadScenes } from '../scenes.js';

const COLUMNS = [{ label: 'Session' }, { label: 'Trainee' }, { label: 'Scene' }, { label: 'State' },
  { label: 'Created' }, { label: 'Score', num: true }, { label: 'Record' }, { label: '' }];

export async function pageRecords(main) {
  const scenes = await loadScenes();
  const params = new URLSearchParams(location.search);
  const input = (name, attrs) => el('input', Object.assign({ name, id: 'f-' + name, value: params.get(name) || '' }, attrs));
  const form = el('form', { class: 'filters', id: 'records-form', role: 'search' },
    el('label', {}, 'Search (a part of a name)', input('q', { type: 'search', maxlength: 128, autocomplete: 'off' })),
    el('label', {}, 'Trainee', input('trainee', { maxlength: 128, autocomplete: 'off' })),
    el('label', {}, 'Scene', el('select', { name: 'scene', id: 'f-scene' }, el('option', { value: '' }, 'any'),
      scenes.map((s) => el('option', { value: s.name, selected: params.get('scene') === s.name }, s.name)))),
    el('label', {}, 'From (date)', input('from', { type: 'date' })),
    el('label', {}, 'To (date, inclusive)', input('to', { type: 'date' })),
    el('label', {}, 'Score at least', input('min_score', { type: 'number', min: 0, max: 10, step: 0.5, inputmode: 'decimal' })),
    el('label', {}, 'Score at most', input('max_score', { type: 'number', min: 0, max: 10, step: 0.5, inputmode: 'decimal' })),
    el('button', { type: 'submit' }, 'Search'));
  if (auth.me.role === 'trainee') form.elements.trainee.closest('label').hidden = true;
  const out = el('div', { id: 'records' });
  const pager = el('nav', { class: 'pager', 'aria-label': 'Pages' });
  main.replaceChildren(el('h1', {}, 'Sessions'), el('p', { class: 'muted' },
    'Every ended session with its score. Open one to replay it beside its traces and ratings.'),
  el('div', { class: 'panel' }, form), el('div', { class: 'panel' }, out, pager));
  let page = Number(params.get('page')) || 1;
  const load = async () => {
    const f = new FormData(form), q = new URLSearchParams({ page, per_page: 25 });
    for (const k of ['q', 'trainee', 'scene', 'min_score', 'max_score']) if (f.get(k)) q.set(k, f.get(k));
    // Dates are this browser's local days: from its midnight, to the next day's.
    if (f.get('from')) q.set('from', new Date(f.get('from') + 'T00:00').toISOString());
    if (f.get('to')) { const d = new Date(f.get('to') + 'T00:00'); d.setDate(d.getDate() + 1); q.set('to', d.toISOString()); }
    try {
      const r = await api('GET', '/records?' + q);
      const pages = Math.max(1, Math.ceil(r.total / r.per_page));
      out.replaceChildren(r.sessions.length ? table(COLUMNS, r.sessions.map((s) => [
        String(s.id), s.trainee, s.scene, stateBadge(s.state), when(s.created),
        s.score === null ? '—' : el('b', {}, fmt(s.score, 1)), s.has_record ? 'replay' : '—',
        el('a', { href: '/session/' + s.id, 'aria-label': `Open session ${s.id}` }, 'Open')]), { id: 'records-table' })
        : el('p', { class: 'muted' }, 'No session matches.'));
      pager.replaceChildren(
        el('button', { type: 'button', disabled: page <= 1, onclick: () => { page -= 1; load(); } }, '‹ Newer'),
        el('span', { role: 'status' }, `Page ${page} of ${pages} · ${r.total} session${r.total === 1 ? '' : 's'}`),
        el('button', { type: 'button', disabled: page >= pages, onclick: () => { page += 1; load(); } }, 'Older ›'));
      const shown = new URLSearchParams([...f].filter(([, v]) => v));
      if (page > 1) shown.set('page', page);
      history.replaceState(null, '', '/records' + (shown.toString() ? '?' + shown : ''));
    } catch (err) { message(out, err.message); }
  };
  form.addEventListener('submit', (e) => { e.preventDefault(); page = 1; load(); });
  await load();
}
