// Sign-in with an access token, or through the site's identity provider when it has one.
import { api, auth } from '../api.js';
import { el, message } from '../dom.js';
import { PAGES } from '../nav.js';

export function pageSignIn(main) {
  const note = el('div');
  const form = el('form', { id: 'signin' },
    el('label', {}, 'Your access token (from your administrator)',
      el('input', { type: 'password', name: 'token', required: true, autocomplete: 'current-password' })),
    el('p', {}, el('button', { type: 'submit' }, 'Sign in')));
  form.addEventListener('submit', async (e) => {
    e.preventDefault();
    try {
      auth.me = await api('POST', '/signin', { token: new FormData(form).get('token') });
      const next = new URLSearchParams(location.search).get('next');
      location.href = PAGES.some((p) => p.page === next) ? '/' + next : '/';
    } catch (err) { message(note, err.message); }
  });
  const panel = el('div', { class: 'panel signin' }, el('h1', {}, 'Sign in to vsurg'), form, note);
  main.replaceChildren(panel);
  // The site's identity provider, when it has one: the hospital's own account.
  api('GET', '/signin/methods').then((m) => {
    if (!m || !m.oidc) return;
    panel.insertBefore(el('p', {}, el('a', { id: 'signin-oidc', class: 'button', href: '/api/v1/signin/oidc' },
      "Sign in with your organisation's account")), form);
  }).catch(() => {});
}
