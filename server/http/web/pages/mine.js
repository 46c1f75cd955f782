// A trainee's own sessions.
import { api, auth } from '../api.js';
import { el, fmt, stateBadge, when } from '../dom.js';

export async function pageMine(main) {
  const r = await api('GET', '/sessions?trainee=' + encodeURIComponent(auth.me.user));
  main.replaceChildren(el('h1', {}, 'My sessions'), el('div', { class: 'panel' }, el('table', {},
    el('thead', {}, el('tr', {}, ['Session', 'Scene', 'State', 'Started', 'Score'].map((h) => el('th', {}, h)))),
    el('tbody', {}, r.sessions.map((s) => el('tr', {}, el('td', {}, s.id), el('td', {}, s.scene), el('td', {}, stateBadge(s.state)),
      el('td', {}, when(s.started)), el('td', { class: 'num' }, s.metrics ? fmt(s.metrics.score, 1) : '—')))))),
  el('p', { class: 'muted' }, 'A session an instructor prepared for you: start your station with --join ID.'));
}
