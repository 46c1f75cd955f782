// Live stations: every live session's row, updated from the event stream; preparing a session.
import { api } from '../api.js';
import { el, fmt, message, stateBadge } from '../dom.js';
import { loadScenes, taskCell } from '../scenes.js';

export async function pageLive(main) {
  const scenes = await loadScenes();
  const status = el('div', { class: 'status-line', id: 'live-status' }, 'connecting…');
  const body = el('tbody', { id: 'live-rows' });
  const table = el('table', { id: 'live-table' },
    el('thead', {}, el('tr', {}, ['Trainee', 'Scene', 'State', 'Twist / depth', 'Force (N)', 'RTT (µs)',
      'Loss (%)', 'Haptic (Hz)', 'Score', ''].map((h, i) => el('th', { class: i >= 4 && i <= 8 ? 'num' : '' }, h)))),
    body);
  const note = el('div');
  const prepare = el('form', { class: 'inline', id: 'prepare' },
    el('label', {}, 'Trainee', el('input', { name: 'trainee', required: true, maxlength: 128 })),
    el('label', {}, 'Scene', el('select', { name: 'scene' }, scenes.map((s) => el('option', { value: s.name }, s.name)))),
    el('button', { type: 'submit' }, 'Prepare session'));
  prepare.addEventListener('submit', async (e) => {
    e.preventDefault();
    const f = new FormData(prepare);
    try {
      const r = await api('POST', '/sessions', { trainee: f.get('trainee'), scene: f.get('scene') });
      const s = r.session;
      message(note, `Session ${s.id} prepared for ${s.trainee} on ${s.scene}. The trainee's station joins it: ` +
        `vsurg-station --join ${s.id} --scene ${s.scene}`, true);
    } catch (err) { message(note, err.message); }
  });
  main.replaceChildren(el('h1', {}, 'Live stations'), status, el('div', { class: 'panel' }, table),
    el('h2', {}, 'Prepare a session for a trainee'), el('div', { class: 'panel' }, prepare, note));

  const seen = new Map();  // id → {row, last: time seen in the stream, gone}
  let lastFrame = 0;
  const es = new EventSource('/api/v1/live/events');
  es.onmessage = (ev) => {
    lastFrame = Date.now();
    const list = JSON.parse(ev.data);
    const now = Date.now();
    const ids = new Set();
    for (const t of list) {
      ids.add(t.id);
      let entry = seen.get(t.id);
      if (!entry) { entry = { row: el('tr', { 'data-session': t.id }) }; seen.set(t.id, entry); body.append(entry.row); }
      entry.last = now; entry.gone = false;
      entry.row.className = t.state === 'stalled' ? 'stalled' : '';
      entry.row.replaceChildren(
        el('td', {}, t.trainee), el('td', {}, t.scene), el('td', {}, stateBadge(t.state)),
        el('td', {}, taskCell(t)), el('td', { class: 'num' }, fmt(t.force_n, 2)),
        el('td', { class: 'num' }, fmt(t.rtt_us, 0)), el('td', { class: 'num' }, fmt(t.loss_ratio * 100, 2),
          poorLink(t) ? [' ', el('span', { class: 'badge stalled', title: poorLinkWhy }, 'poor link')] : null),
        el('td', { class: 'num' }, fmt(t.haptic_rate_hz, 0)), el('td', { class: 'num' }, fmt(t.score, 1)),
        el('td', {}, el('a', { href: '/session/' + t.id }, 'Open')));
    }
    // Sessions that left the live list: shown as gone (disconnected or ended) for 15 s.
    for (const [id, entry] of seen) {
      if (ids.has(id)) continue;
      if (!entry.gone) {
        entry.gone = true; entry.row.className = 'gone';
        entry.row.children[2].replaceChildren(stateBadge('gone'));
      }
      if (now - entry.last > 15000) { entry.row.remove(); seen.delete(id); }
    }
    if (!performance.getEntriesByName('vsurg-live-data').length) performance.mark('vsurg-live-data');
    status.className = 'status-line';
    status.textContent = `${list.length} live session${list.length === 1 ? '' : 's'} · updated ${new Date().toLocaleTimeString()}`;
  };
  setInterval(() => {
    if (Date.now() - lastFrame > 3000) {
      status.className = 'status-line lost';
      status.textContent = 'No update for ' + Math.round((Date.now() - lastFrame) / 1000) + ' s: reconnecting…';
    }
  }, 1000);
}

// Beyond what the station's local model holds faithfully (docs/BENCHMARKS.md "Haptics across
// networks"), the station tells its trainee and the live table flags the row.
const poorLinkWhy = 'Round trip over 300 ms or over 10% lost: the station warns its trainee';
export function poorLink(t) { return t.rtt_us > 300e3 || t.loss_ratio > 0.10; }
