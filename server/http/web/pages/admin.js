// Administration: users and tokens, weight sets, exports and backups.
import { api } from '../api.js';
import { confirmed, el, message, row, when } from '../dom.js';

const COLUMNS = [{ label: 'Name' }, { label: 'Role' }, { label: 'Group' }, { label: 'Created' }, { label: 'Status' }, { label: '' }];

export async function pageAdmin(main) {
  const users = el('tbody', { id: 'users' });
  const note = el('div', { id: 'admin-note' });
  const refresh = async () => {
    const r = await api('GET', '/users');
    users.replaceChildren(...r.users.map((u) => row(COLUMNS, [u.name, u.role, u.group, when(u.created), u.disabled ? 'disabled' : 'active',
      el('span', { class: 'actions' },
        el('button', { onclick: async () => {
          try {
            const t = await api('POST', `/users/${encodeURIComponent(u.name)}/token`, { label: 'dashboard' });
            note.replaceChildren(el('div', { class: 'msg ok' }, `Token for ${u.name} (shown once; give it to the user): `,
              el('div', { class: 'token' }, t.token)));
          } catch (err) { message(note, err.message); }
        } }, 'Issue token'), ' ',
        el('button', { class: 'danger', onclick: async () => {
          if (!confirmed(`Revoke every token of ${u.name}? Their live sessions end now, and they must be given a new token to sign in again.`)) return;
          try { await api('POST', `/users/${encodeURIComponent(u.name)}/revoke`, {}); message(note, `Tokens of ${u.name} revoked.`, true); }
          catch (err) { message(note, err.message); }
        } }, 'Revoke tokens'), ' ',
        el('button', { onclick: async () => {
          if (!u.disabled && !confirmed(`Disable ${u.name}? Their live sessions end now and they cannot sign in until enabled again.`)) return;
          try { await api('POST', `/users/${encodeURIComponent(u.name)}/disabled`, { disabled: !u.disabled }); await refresh(); }
          catch (err) { message(note, err.message); }
        } }, u.disabled ? 'Enable' : 'Disable'))])));
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
  const wsText = el('textarea', { id: 'weight-set', 'aria-label': 'Weight set (JSON)' }, JSON.stringify(ws.default, null, 2));
  const wsNote = el('div');
  const wsButton = el('button', { onclick: async () => {
    try { await api('POST', '/weight-sets', wsText.value); message(wsNote, 'Weight set stored.', true); }
    catch (err) { message(wsNote, err.message); }
  } }, 'Store weight set');
  const exportForm = el('form', { class: 'inline', id: 'export-form' },
    el('label', {}, 'Format', el('select', { name: 'format' }, ['csv', 'jsonl', 'xapi'].map((f) => el('option', { value: f }, f)))),
    el('label', {}, 'From (optional)', el('input', { name: 'from', type: 'date' })),
    el('label', {}, 'To, inclusive (optional)', el('input', { name: 'to', type: 'date' })),
    el('label', {}, 'Trainee (optional)', el('input', { name: 'trainee' })),
    el('label', {}, 'Session (optional)', el('input', { name: 'session', inputmode: 'numeric', pattern: '[0-9]+' })),
    el('button', { type: 'submit' }, 'Download'));
  const exportNote = el('div', { id: 'export-note', role: 'status' });
  exportForm.addEventListener('submit', async (e) => {
    e.preventDefault();
    if (!exportForm.reportValidity()) return;
    const f = new FormData(exportForm), q = new URLSearchParams({ format: f.get('format') });
    // Dates are this browser's local days: from its first microsecond to the end of the last.
    const day = (v, next) => { const [y, m, d] = v.split('-').map(Number); return new Date(y, m - 1, d + (next ? 1 : 0)).getTime() * 1000; };
    const from = f.get('from') ? day(f.get('from'), false) : null, to = f.get('to') ? day(f.get('to'), true) - 1 : null;
    if (from !== null && to !== null && from > to) return message(exportNote, '"From" is after "To".');
    if (from !== null) q.set('from', String(from));
    if (to !== null) q.set('to', String(to));
    for (const k of ['trainee', 'session']) if (f.get(k)) q.set(k, f.get(k));
    // Fetched, not navigated to: a refusal (a busy server, a bad filter) is said here, never shown
    // as a page of JSON. The file is then saved under the server's name for it.
    message(exportNote, 'Exporting…', true);
    try {
      const res = await fetch('/api/v1/export?' + q, { credentials: 'same-origin' });
      if (!res.ok) {
        let why = res.statusText;
        try { why = (await res.json()).error || why; } catch (err) { /* not JSON */ }
        return message(exportNote, why);
      }
      const name = (/filename="([^"]+)"/.exec(res.headers.get('Content-Disposition') || '') || [])[1] || 'vsurg-export';
      const link = el('a', { href: URL.createObjectURL(await res.blob()), download: name });
      document.body.append(link); link.click(); link.remove();
      setTimeout(() => URL.revokeObjectURL(link.href), 60000);
      message(exportNote, `Saved ${name}.`, true);
    } catch (err) { message(exportNote, err.message); }
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
      el('table', { class: 'cards' }, el('thead', {}, el('tr', {}, COLUMNS.map((c) => el('th', { scope: 'col' }, c.label)))), users)),
    el('h2', {}, 'Weight sets'), el('div', { class: 'panel' }, el('p', { class: 'muted' }, 'Stored: ' + (ws.names.join(', ') || 'none')), wsText, wsButton, wsNote),
    el('h2', {}, 'Export evaluations'), el('div', { class: 'panel' }, exportForm, exportNote),
    el('h2', {}, 'Backup'), el('div', { class: 'panel' }, backupForm, backupNote));
  await refresh();
}
