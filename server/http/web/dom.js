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
