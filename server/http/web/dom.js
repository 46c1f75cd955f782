// Small DOM helpers. Every text from the server goes into the page through textContent (el's
// children become text nodes), never as HTML.
export function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === 'class') e.className = v;
    else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null && v !== false) e.setAttribute(k, v === true ? '' : v);
  }
  for (const c of children.flat()) {
    if (c === null || c === undefined) continue;
    e.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return e;
}
export const $ = (sel) => document.querySelector(sel);
export function fmt(x, digits) {
  return (x === null || x === undefined || !isFinite(x)) ? '—' : Number(x).toFixed(digits);
}
export function message(target, text, ok) {
  // Errors are announced at once (role=alert), other news when the reader is idle (role=status).
  target.replaceChildren(el('div', { class: 'msg ' + (ok ? 'ok' : 'error'), role: ok ? 'status' : 'alert' }, text));
}
export function stateBadge(state) { return el('span', { class: 'badge ' + state }, state); }

// A time the server sends (ISO 8601, UTC, to the microsecond) as this browser's local date and
// time to the minute, with its time zone; the full UTC stamp stays in the tooltip.
export function when(iso) {
  if (!iso) return '—';
  const d = new Date(iso);
  if (isNaN(d)) return iso;
  // (dateStyle and timeStyle may not be combined with timeZoneName: the parts one by one.)
  const text = d.toLocaleString(undefined, { year: 'numeric', month: 'short', day: 'numeric',
    hour: '2-digit', minute: '2-digit', timeZoneName: 'short' });
  return el('time', { datetime: iso, title: iso }, text);
}

// A destructive action runs only once the person confirmed it, told what it does.
export function confirmed(what) { return window.confirm(what); }

// A table that reads as cards on a phone: every cell carries its column's name (data-label,
// shown by the stylesheet under 700 px). columns: [{label, num}]; rows: arrays of cell contents
// (or {cells, attrs} for a row with attributes).
export function table(columns, rows, attrs) {
  const head = el('thead', {}, el('tr', {}, columns.map((c) => el('th', { class: c.num ? 'num' : '', scope: 'col' }, c.label))));
  const body = el('tbody', {}, rows.map((r) => row(columns, r)));
  return el('table', Object.assign({ class: 'cards' }, attrs || {}), head, body);
}
export function row(columns, r) {
  const cells = Array.isArray(r) ? r : r.cells;
  return el('tr', Array.isArray(r) ? {} : r.attrs, cells.map((c, i) =>
    el('td', { class: columns[i].num ? 'num' : '', 'data-label': columns[i].label || null }, c)));
}
// A definition list from [term, value] pairs.
export function kv(pairs, attrs) {
  return el('dl', Object.assign({ class: 'kv' }, attrs || {}), pairs.flatMap(([k, v]) => [el('dt', {}, k), el('dd', {}, v)]));
}
// A compact strip of [term, value] pairs (a record's head), wrapping on a narrow screen.
export function facts(pairs, attrs) {
  return el('dl', Object.assign({ class: 'facts' }, attrs || {}), pairs.map(([k, v]) => el('div', {}, el('dt', {}, k), el('dd', {}, v))));
}
