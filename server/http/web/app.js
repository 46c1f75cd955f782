// vsurg dashboard: the entry module of every page (body[data-page]); each page is a module of its
// own under pages/, over the shared helpers (dom, api, charts, scenes, tissue_view). Native ES
// modules served by the server itself: no framework, no bundler, no CDN. Chart.js (Debian's
// libjs-chart.js) is embedded in the server at build time and loaded first, as window.Chart.
import { api, auth } from './api.js';
import { $, el, message } from './dom.js';
import { PAGES } from './nav.js';
import { pageAdmin } from './pages/admin.js';
import { pageEvaluate } from './pages/evaluate.js';
import { pageLive } from './pages/live.js';
import { pageMine } from './pages/mine.js';
import { pageRecords } from './pages/records.js';
import { pageReports } from './pages/reports.js';
import { pageSession } from './pages/session.js';
import { pageSignIn } from './pages/signin.js';
import { pageTraining } from './pages/training.js';

async function start() {
  const page = document.body.dataset.page, main = $('#main');
  if (page === 'signin') return pageSignIn(main);
  try { auth.me = await api('GET', '/me'); } catch (err) { return; }
  $('#nav').replaceChildren(...PAGES.filter((p) => p.roles.includes(auth.me.role)).map((p) =>
    el('a', { href: '/' + p.page, class: p.page === page ? 'here' : '' }, p.title)));
  $('#who').replaceChildren(`${auth.me.user} (${auth.me.role}) `, el('button', { id: 'signout', onclick: async () => {
    try { await api('POST', '/signout'); } finally { location.href = '/signin'; }
  } }, 'Sign out'));
  if (page === 'forbidden') {
    const name = location.pathname.split('/')[1], entry = PAGES.find((p) => p.page === name);
    return main.replaceChildren(el('h1', {}, 'Forbidden'), el('div', { class: 'msg error', role: 'alert' },
      entry ? `${entry.title} is for the ${entry.roles.join(' and ')} role${entry.roles.length > 1 ? 's' : ''}; you are signed in as ${auth.me.role}.`
        : `You are signed in as ${auth.me.role}, which cannot open this page.`, ' ', el('a', { href: '/' }, 'Back to your start page')));
  }
  const pages = { live: pageLive, session: pageSession, evaluate: pageEvaluate, reports: pageReports, admin: pageAdmin, mine: pageMine, records: pageRecords, training: pageTraining };
  try { await pages[page](main); } catch (err) { if (err.message !== 'signed out') message(main, err.message); }
}
document.addEventListener('DOMContentLoaded', start);
