// Administration: users and tokens, weight sets, exports and backups.
import { api } from '../api.js';
import { el, message } from '../dom.js';

export async function pageAdmin(main) {
  const users = el('tbody', { id: 'users' });
  const note = el('div', { id: 'admin-note' });
  const refresh = async () => {
    const r = await api('GET', '/users');
    users.replaceChildren(...r.users.map((u) => el('tr', {}, el('td', {}, u.name), el('td', {}, u.role), el('td', {}, u.group),
      el('td', {}, u.created), el('td', {}, u.disabled ? 'disabled' : 'active'),
      el('td', {},
        el('button', { onclick: async () => {
          try {
            const t = await api('POST', `/users/${encodeURIComponent(u.name)}/token`, { label: 'dashboard' });
            note.replaceChildren(el('div', { class: 'msg ok' }, `Token for ${u.name} (shown once; give it to the user): `,
              el('div', { class: 'token' }, t.token)));
          } catch (err) { message(note, err.message); }
        } }, 'Issue token'), ' ',
        el('button', { class: 'danger', onclick: async () => {
          try { await api('POST', `/users/${encodeURIComponent(u.name)}/revoke`, {}); message(note, `Tokens of ${u.name} revoked.`, true); }
          catch (err) { message(note, err.message); }
        } }, 'Revoke tokens'), ' ',
        el('button', { onclick: async () => {
          try { await api('POST', `/users/${encodeURIComponent(u.name)}/disabled`, { disabled: !u.disabled }); await refresh(); }
          catch (err) { message(note, err.message); }
        } }, u.disabled ? 'Enable' : 'Disable')))));
  };
  const create = el('form', { class: 'inline', id: 'create-user' },
    el('label', {}, 'Name', el('input', { name: 'name', required: true, maxlength: 128 })),
    el('label', {}, 'Role', el('select', { name: 'role' }, ['trainee', 'instructor', 'evaluator', 'admin'].map((r) => el('option', { value: r }, r)))),
    el('label', {}, 'Group', el('input', { name: 'group', placeholder: 'e.g. residents, chief' })),
    el('button', { type: 'submit' }, 'Create user'));
  create.addEventListener('submit', async (e) => {
    e.preventDefault();
    const f = new FormData(create);
    try { await api('POST', '/users', { name: f.get('name'), role: f.get('role'), group: f.get('group') }); await refresh(); message(note, 'User created.', true); }
    catch (err) { message(note, err.message); }
  });
  const ws = await api('GET', '/weight-sets');
  const wsText = el('textarea', { id: 'weight-set' }, JSON.stringify(ws.default, null, 2));
  const wsNote = el('div');
  const wsButton = el('button', { onclick: async () => {
    try { await api('POST', '/weight-sets', wsText.value); message(wsNote, 'Weight set stored.', true); }
    catch (err) { message(wsNote, err.message); }
  } }, 'Store weight set');
  const exportForm = el('form', { class: 'inline', id: 'export-form' },
    el('label', {}, 'Format', el('select', { name: 'format' }, ['csv', 'jsonl', 'xapi'].map((f) => el('option', { value: f }, f)))),
    el('label', {}, 'From (ISO, optional)', el('input', { name: 'from', placeholder: '2026-11-01T00:00:00Z' })),
    el('label', {}, 'To (ISO, optional)', el('input', { name: 'to' })),
    el('label', {}, 'Trainee (optional)', el('input', { name: 'trainee' })),
    el('label', {}, 'Session (optional)', el('input', { name: 'session', inputmode: 'numeric' })),
    el('button', { type: 'submit' }, 'Download'));
  exportForm.addEventListener('submit', (e) => {
    e.preventDefault();
    const q = new URLSearchParams();
    for (const [k, v] of new FormData(exportForm)) if (v) q.append(k, v);
    location.href = '/api/v1/export?' + q;  // streamed by the server, saved by the browser
  });
  const backupNote = el('div');
  const backupForm = el('form', { class: 'inline', id: 'backup-form' },
    el('label', {}, 'Backup file name', el('input', { name: 'name', required: true, value: 'vsurg-' + new Date().toISOString().slice(0, 10) + '.db' })),
    el('button', { type: 'submit' }, 'Back up now'));
  backupForm.addEventListener('submit', async (e) => {
    e.preventDefault();
    try { await api('POST', '/backup', { name: new FormData(backupForm).get('name') }); message(backupNote, 'Backup written.', true); }
    catch (err) { message(backupNote, err.message); }
  });
  main.replaceChildren(el('h1', {}, 'Administration'),
    el('h2', {}, 'Users'), el('div', { class: 'panel' }, create, note,
      el('table', {}, el('thead', {}, el('tr', {}, ['Name', 'Role', 'Group', 'Created', 'Status', ''].map((h) => el('th', {}, h)))), users)),
    el('h2', {}, 'Weight sets'), el('div', { class: 'panel' }, el('p', { class: 'muted' }, 'Stored: ' + (ws.names.join(', ') || 'none')), wsText, wsButton, wsNote),
    el('h2', {}, 'Export evaluations'), el('div', { class: 'panel' }, exportForm),
    el('h2', {}, 'Backup'), el('div', { class: 'panel' }, backupForm, backupNote));
  await refresh();
}
