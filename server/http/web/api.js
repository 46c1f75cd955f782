// The dashboard's JSON API (/api/v1) with the signed-in user's CSRF token on every change.
export const auth = { me: null };  // {user, role, group, csrf} once signed in

export async function api(method, path, body) {
  const opts = { method, credentials: 'same-origin', headers: {} };
  if (method !== 'GET') {
    opts.headers['X-CSRF-Token'] = auth.me ? auth.me.csrf : '';
    if (body !== undefined) {
      opts.headers['Content-Type'] = 'application/json';
      opts.body = typeof body === 'string' ? body : JSON.stringify(body);
    }
  }
  const res = await fetch('/api/v1' + path, opts);
  if (res.status === 401 && document.body.dataset.page !== 'signin') {
    location.href = '/signin?next=' + encodeURIComponent(document.body.dataset.page);
    throw new Error('signed out');
  }
  const text = await res.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch (e) { data = { error: text }; }
  if (!res.ok) {
    const err = new Error((data && data.error) || res.statusText);
    err.status = res.status;
    throw err;
  }
  return data;
}
