// Four-handed training on a live session's page: who is in the session (the trainee and the
// instructor whose station joined it), the mode and the dominance α asked for and as the haptic
// path has ramped it; for that instructor, the switches (observe, guide at α, take over, hand
// back, leave). Every user who may see the session sees who is in it; only the joined instructor
// may switch (the server refuses anyone else). Read every second while the session is live.
import { api, auth } from './api.js';
import { el, fmt, message } from './dom.js';

const MODE_TEXT = { none: 'nobody guides', observe: 'observing (the instructor feels what the trainee feels)',
  guide: 'guiding (both hands on the tool)' };

export function guidancePanel(id, scene) {
  const status = el('p', { id: 'guidance-status' }, 'Reading who is in the session…');
  const note = el('div');
  const alpha = el('input', { type: 'range', id: 'guide-alpha', min: 0, max: 1, step: 0.05, value: 0.5,
    'aria-label': 'Dominance α for guiding (0: the trainee alone, 1: the instructor alone)' });
  const alphaText = el('output', { for: 'guide-alpha', id: 'guide-alpha-text' }, '0.50');
  alpha.addEventListener('input', () => { alphaText.textContent = fmt(Number(alpha.value), 2); });
  const send = async (mode, a) => {
    try { show(await api('POST', `/sessions/${id}/guide`, { mode, alpha: mode === 'guide' ? a : 0 })); note.replaceChildren(); }
    catch (err) { message(note, err.message); }
  };
  const button = (bid, label, act) => el('button', { type: 'button', id: bid, onclick: act }, label);
  const controls = el('div', { class: 'filters', id: 'guide-controls', hidden: true },
    button('guide-observe', 'Observe', () => send('observe', 0)),
    el('label', { class: 'inline' }, 'α', alpha, alphaText),
    button('guide-guide', 'Guide at α', () => send('guide', Number(alpha.value))),
    button('guide-take', 'Take over', () => send('guide', 1)),
    button('guide-back', 'Hand back', () => send('guide', 0)),
    button('guide-leave', 'Leave', () => send('none', 0)));
  const join = el('p', { class: 'muted', id: 'guide-join' });
  if (auth.me.role === 'instructor' || auth.me.role === 'admin')
    join.textContent = `To put your hands on the trainee's tool, join from your station: ` +
      `vsurg-station --instruct ${id} --scene ${scene.name}`;
  const panel = el('div', { class: 'panel', id: 'guidance-panel' }, el('h2', {}, 'Four hands'), status, controls, join, note);
  let last = null;
  function show(g) {
    last = g;
    const who = g.instructor ? `${g.trainee} and ${g.instructor} (instructor)` : `${g.trainee} alone`;
    const mode = g.instructor ? `; ${MODE_TEXT[g.mode] || g.mode}` +
      (g.mode === 'guide' ? `, α ${fmt(g.alpha_requested, 2)} asked, ${fmt(g.dominance_ratio, 2)} now` : '') : '';
    status.textContent = `In the session: ${who}${mode}.`;
    const mine = g.instructor && g.instructor === auth.me.user;
    controls.hidden = !mine;
    join.hidden = Boolean(g.instructor);
  }
  async function poll() {
    try { show(await api('GET', `/sessions/${id}/guidance`)); }
    catch (err) { if (!last) status.textContent = `Who is in the session cannot be read: ${err.message}`; }
  }
  let timer = null;
  return {
    panel,
    start() { poll(); timer = setInterval(poll, 1000); },
    stop() { if (timer) clearInterval(timer); timer = null; controls.hidden = true; join.hidden = true; },
  };
}
