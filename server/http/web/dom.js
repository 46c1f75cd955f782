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
  target.replaceChildren(el('div', { class: 'msg ' + (ok ? 'ok' : 'error') }, text));
}
export function stateBadge(state) { return el('span', { class: 'badge ' + state }, state); }
