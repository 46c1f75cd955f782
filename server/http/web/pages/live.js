// Live stations: every live session's row, sorted by need with the reason in words, filterable;
// an in-page alert (and an optional sound) when a station starts needing attention; preparing a
// session.
import { api } from '../api.js';
import { el, fmt, message, row, stateBadge } from '../dom.js';
import { loadScenes, scenesByName, taskCell } from '../scenes.js';
import { level, needs } from '../triage.js';

const COLUMNS = [{ label: 'Trainee' }, { label: 'Needs' }, { label: 'Scene' }, { label: 'State' },
  { label: 'Twist / depth', num: true }, { label: 'Force (N)', num: true }, { label: 'Score', num: true },
  { label: 'Round trip (ms)', num: true }, { label: 'Loss (%)', num: true }, { label: '' }];

export async function pageLive(main) {
  const scenes = await loadScenes();
  const status = el('div', { class: 'status-line', id: 'live-status' }, 'connecting…');
  const alerts = el('div', { id: 'alerts', role: 'alert', 'aria-live': 'assertive' });
  const body = el('tbody', { id: 'live-rows' });
  const table = el('table', { id: 'live-table', class: 'cards' },
    el('thead', {}, el('tr', {}, COLUMNS.map((c) => el('th', { class: c.num ? 'num' : '', scope: 'col' }, c.label)))), body);
  const search = el('input', { type: 'search', id: 'live-search', placeholder: 'trainee or scene' });
  const only = el('input', { type: 'checkbox', id: 'live-only' });
  const sound = el('input', { type: 'checkbox', id: 'live-sound' });
  const filters = el('div', { class: 'filters' }, el('label', {}, 'Find', search),
    el('label', { class: 'check' }, only, 'Only stations that need attention'),
    el('label', { class: 'check' }, sound, 'Sound when a station needs attention'));
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
  main.replaceChildren(el('h1', {}, 'Live stations'), status, alerts, filters, el('div', { class: 'panel' }, table),
    el('h2', {}, 'Prepare a session for a trainee'), el('div', { class: 'panel' }, prepare, note));

  const seen = new Map();  // id → {row, t, reasons, history, last, gone}
  const t0 = performance.now();
  let lastFrame = 0;
  const render = () => {
    const q = search.value.trim().toLowerCase();
    const entries = [...seen.values()].sort((a, b) => (b.gone ? -1 : level(b.reasons)) - (a.gone ? -1 : level(a.reasons)) ||
      a.t.trainee.localeCompare(b.t.trainee));
    for (const e of entries) {
      const hide = (only.checked && !level(e.reasons)) || (q && !`${e.t.trainee} ${e.t.scene}`.toLowerCase().includes(q));
      e.row.hidden = hide;
      body.append(e.row);  // in order
    }
  };
  const draw = (e) => {
    const t = e.t, lv = e.gone ? 0 : level(e.reasons);
    const cells = [t.trainee,
      e.gone ? 'left the live list' : e.reasons.length ? el('span', { class: 'reason' }, e.reasons.map((r) => r.text).join('; ')) : el('span', { class: 'muted' }, 'nothing'),
      t.scene, stateBadge(e.gone ? 'gone' : t.state), taskCell(t), fmt(t.force_n, 2), fmt(t.score, 1),
      fmt(t.rtt_us / 1000, t.rtt_us < 10e3 ? 2 : 1), fmt(t.loss_ratio * 100, 2), el('a', { href: '/session/' + t.id, 'aria-label': `Open ${t.trainee}'s session` }, 'Open')];
    const fresh = row(COLUMNS, { cells, attrs: { 'data-session': t.id, class: e.gone ? 'gone' : lv ? 'need' + lv : '' } });
    e.row.replaceWith(fresh); e.row = fresh;
  };
  const es = new EventSource('/api/v1/live/events');
  es.onmessage = (ev) => {
    lastFrame = Date.now();
    const list = JSON.parse(ev.data), now = (performance.now() - t0) / 1000, ids = new Set();
    const raised = [];
    for (const t of list) {
      ids.add(t.id);
      let e = seen.get(t.id);
      if (!e) { e = { row: el('tr'), history: [], reasons: [] }; seen.set(t.id, e); body.append(e.row); }
      e.t = t; e.last = Date.now(); e.gone = false;
      e.history.push({ at: now, score: t.score });
      while (e.history.length && e.history[0].at < now - 15) e.history.shift();
      const before = level(e.reasons);
      e.reasons = needs(t, scenesByName[t.scene], e.history);
      if (level(e.reasons) >= 2 && before < 2) raised.push(`${t.trainee}: ${e.reasons[0].text}`);
      draw(e);
    }
    // Sessions that left the live list: shown as gone (disconnected or ended) for 15 s.
    for (const [id, e] of seen) {
      if (ids.has(id)) continue;
      if (!e.gone) { e.gone = true; draw(e); }
      if (Date.now() - e.last > 15000) { e.row.remove(); seen.delete(id); }
    }
    render();
    if (raised.length) notify(alerts, raised, sound.checked);
    const attention = [...seen.values()].filter((e) => !e.gone && level(e.reasons) >= 2).length;
    document.title = (attention ? `(${attention}) ` : '') + 'Live stations · vsurg';
    if (!performance.getEntriesByName('vsurg-live-data').length) performance.mark('vsurg-live-data');
    status.className = 'status-line';
    status.textContent = `${list.length} live session${list.length === 1 ? '' : 's'}, ${attention} needing attention · updated ${new Date().toLocaleTimeString()}`;
  };
  search.addEventListener('input', render);
  only.addEventListener('change', render);
  setInterval(() => {
    if (Date.now() - lastFrame > 3000) {
      status.className = 'status-line lost';
      status.textContent = 'No update for ' + Math.round((Date.now() - lastFrame) / 1000) + ' s: reconnecting…';
    }
  }, 1000);
}

function notify(alerts, raised, withSound) {
  alerts.replaceChildren(el('div', { class: 'msg warn' }, 'Needs attention: ' + raised.join('; ')));
  if (!withSound) return;
  try {  // a short two-tone chime
    const ctx = new AudioContext(), g = ctx.createGain();
    g.gain.value = 0.08; g.connect(ctx.destination);
    [880, 660].forEach((f, i) => {
      const o = ctx.createOscillator(); o.frequency.value = f; o.connect(g);
      o.start(ctx.currentTime + i * 0.15); o.stop(ctx.currentTime + i * 0.15 + 0.12);
    });
  } catch (err) { /* no audio device: the in-page alert stands */ }
}

