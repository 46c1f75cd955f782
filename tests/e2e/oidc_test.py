#!/usr/bin/env python3
"""Sign-in through a hospital's identity provider, end to end, in a real headless Chromium against
a real OpenID Connect provider (Glewlwyd from Debian, deploy/oidc_provider.sh) and a real
vsurg-server:

- dr-lee, unknown to vsurg, signs in at the provider's own login page and lands on the
  instructor's page as an instructor (the role from the provider's claim); tia lands on her own
  page as a trainee; a token sign-in still works beside them;
- the provider's answer replayed (the same callback URL again) is refused: the state is used once;
- a sign-in begun in one browser and finished in another is refused (the binding cookie);
- a user disabled at the provider cannot get past the provider; a user disabled in vsurg is
  refused by vsurg; a user the provider gives no vsurg role, and one whose role here differs from
  the provider's, are refused; none of them ends up with a web session.

Forged, expired, wrong-audience and wrong-issuer ID tokens, `alg: none` and HS256 are refused by
the token check itself (tests/server/http/oidc_test.cpp). Run by ctest (label e2e):
oidc_test.py BIN_DIR SCENES_DIR SHOTS_DIR ROOT_DIR. Exits 0 when every check held.
"""
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import urllib.error
import urllib.request

from selenium.common.exceptions import StaleElementReferenceException
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from browser import api, check, chrome, failures, sign_in, start_server

BIN, SCENES, SHOTS, ROOT = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
os.makedirs(SHOTS, exist_ok=True)
tmp = tempfile.mkdtemp(prefix="vsurg_oidc_")
idp_dir = os.path.join(tmp, "idp")
procs = []


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def start(http):
    """The identity provider, then vsurg-server with the dashboard on `http` trusting it."""
    redirect = f"http://127.0.0.1:{http}/api/v1/signin/oidc/callback"
    issuer = subprocess.run([f"{ROOT}/deploy/oidc_provider.sh", "start", idp_dir, redirect],
                            capture_output=True, text=True, check=True).stdout.strip()
    env = dict(os.environ, VSURG_SCENES=SCENES)
    admin, _ = start_server(BIN, tmp, procs, env, http=f"127.0.0.1:{http}",
                            extra=["--oidc-issuer", issuer, "--oidc-client-id", "vsurg-dashboard",
                                   "--oidc-redirect-uri", redirect])
    return admin


def me(driver):
    """/api/v1/me as the page's own cookie sees it: {user, role, ...}, or None (signed out)."""
    return driver.execute_script(
        "return fetch('/api/v1/me', {credentials: 'same-origin'})"
        ".then(r => r.ok ? r.json() : null)")


def through_provider(driver, wait, base, user, shots=False):
    """From vsurg's sign-in page through the provider's login page with `user`'s password, to
    wherever that leads: True once back on vsurg, False when the provider kept the browser.
    `shots`: screenshots of both sign-in pages, filled in."""
    driver.delete_all_cookies()
    driver.get(base + "/signin")
    wait.until(lambda d: d.find_elements(By.ID, "signin-oidc"))
    if shots:
        driver.save_screenshot(os.path.join(SHOTS, "oidc-signin.png"))
    wait.until(lambda d: clicked(d, By.ID, "signin-oidc"))
    wait.until(lambda d: d.find_elements(By.ID, "loginbut") and d.find_element(By.ID, "username").is_displayed())
    driver.find_element(By.ID, "username").send_keys(user)
    driver.find_element(By.ID, "password").send_keys(user + "-pass-1")
    if shots:
        driver.save_screenshot(os.path.join(SHOTS, "oidc-provider.png"))
    wait.until(lambda d: clicked(d, By.ID, "loginbut"))

    def next_step(d):
        try:
            if d.current_url.startswith(base):
                return "back"
            for b in d.find_elements(By.TAG_NAME, "button"):
                if b.text.strip() == "Continue" and b.is_displayed():
                    b.click()
                    return None
            if d.find_elements(By.CSS_SELECTOR, ".alert-danger, .alert-warning, .text-danger"):
                return "kept"
        except StaleElementReferenceException:  # the provider's page re-rendered meanwhile
            pass
        return None

    return wait.until(next_step) == "back"


def clicked(driver, by, what):
    """Clicks the element once it is there and holds still; False (try again) meanwhile."""
    try:
        found = driver.find_elements(by, what)
        if found and found[0].is_displayed():
            found[0].click()
            return True
    except StaleElementReferenceException:
        pass
    return False


def callback_urls(driver):
    """The callback requests the browser made, from Chromium's performance log."""
    urls = []
    for entry in driver.get_log("performance"):
        msg = json.loads(entry["message"])["message"]
        if msg.get("method") == "Network.requestWillBeSent":
            url = msg["params"]["request"]["url"]
            if "/api/v1/signin/oidc/callback" in url:
                urls.append(url)
    return urls


class NoRedirect(urllib.request.HTTPRedirectHandler):
    def redirect_request(self, *args):
        return None


def begin_elsewhere(base):
    """A sign-in begun outside the browser: the provider's URL it redirects to, and the binding
    cookie it sets ("name=value")."""
    try:
        urllib.request.build_opener(NoRedirect).open(base + "/api/v1/signin/oidc", timeout=10)
        return "", ""
    except urllib.error.HTTPError as e:
        return e.headers.get("Location", ""), e.headers.get("Set-Cookie", "").split(";")[0]


def finish_elsewhere(base, location, cookie):
    """The callback for that sign-in with a made-up code: the refusal's text."""
    state = re.search(r"[?&]state=([^&]+)", location).group(1)
    req = urllib.request.Request(f"{base}/api/v1/signin/oidc/callback?code=made-up&state={state}")
    req.add_header("Cookie", cookie)
    try:
        return urllib.request.build_opener(NoRedirect).open(req, timeout=30).read().decode()
    except urllib.error.HTTPError as e:
        return e.read().decode()


def refused_text(driver, wait):
    wait.until(lambda d: d.find_elements(By.ID, "refused"))
    return driver.find_element(By.ID, "refused").text


def main():
    http = free_port()
    admin = start(http)
    base = f"http://127.0.0.1:{http}"
    methods = json.loads(urllib.request.urlopen(base + "/api/v1/signin/methods", timeout=10).read())
    check(methods == {"token": True, "oidc": True}, "the sign-in page is told the site has a provider")
    api(http, "POST", "/users", admin, {"name": "ada", "role": "trainee", "group": "residents"})
    driver = chrome(1280, 800, performance=True)
    wait = WebDriverWait(driver, 60)

    # An instructor unknown to vsurg: created with the provider's role, on the instructor's page.
    check(through_provider(driver, wait, base, "dr-lee", shots=True),
          "dr-lee passes the provider's login page")
    wait.until(lambda d: d.find_elements(By.ID, "signout"))
    who = me(driver)
    check(who and who["user"] == "dr-lee" and who["role"] == "instructor",
          f"dr-lee is signed in as an instructor ({who})")
    check(driver.current_url.rstrip("/").endswith("/live"), f"on the instructor's page ({driver.current_url})")
    driver.save_screenshot(os.path.join(SHOTS, "oidc-signed-in.png"))
    used = callback_urls(driver)
    check(len(used) == 1 and "state=" in used[0] and "code=" in used[0], "one callback with a code and a state")

    # The provider's answer replayed: refused, and it signs nobody in.
    driver.delete_all_cookies()
    driver.get(used[0])
    text = refused_text(driver, wait)
    check("already used" in text, f"a replayed state is refused ({text})")
    check(me(driver) is None, "the replay left no web session")

    # Begun elsewhere (another browser, or an attacker's own sign-in), finished here: refused.
    location, _ = begin_elsewhere(base)
    state = re.search(r"[?&]state=([^&]+)", location)
    check(state is not None, "the sign-in begins with a redirect to the provider with a state")
    driver.delete_all_cookies()
    driver.get(f"{base}/api/v1/signin/oidc/callback?code=stolen&state={state.group(1) if state else ''}")
    text = refused_text(driver, wait)
    check("another browser" in text, f"a sign-in finished in another browser is refused ({text})")

    # Sign-ins begun in a loop and abandoned (50 from this address, over its share of 16): the
    # server forgets that address's oldest and keeps its newest (which, with its own binding, gets
    # as far as the provider, who refuses the made-up code).
    begun = [begin_elsewhere(base) for _ in range(50)]
    check(all("state=" in loc and cookie for loc, cookie in begun), "50 sign-ins begun and left")
    text = finish_elsewhere(base, *begun[0])
    check("already used" in text, f"the address's oldest was forgotten ({text[-160:]})")
    text = finish_elsewhere(base, *begun[-1])
    check("refused the code" in text, f"its newest was kept ({text[-160:]})")

    # A trainee: created as one, on her own page; then disabled in vsurg, and refused.
    check(through_provider(driver, wait, base, "tia"), "tia passes the provider's login page")
    wait.until(lambda d: d.find_elements(By.ID, "signout"))
    who = me(driver)
    check(who and who["user"] == "tia" and who["role"] == "trainee", f"tia is a trainee ({who})")
    api(http, "POST", "/users/tia/disabled", admin, {"disabled": True})
    check(through_provider(driver, wait, base, "tia"), "tia still passes the provider")
    text = refused_text(driver, wait)
    check("disabled" in text, f"an account disabled in vsurg is refused ({text})")
    check(me(driver) is None, "and has no web session")

    # Disabled at the provider: never past its login page.
    check(not through_provider(driver, wait, base, "dr-gone"), "a user disabled at the provider stays there")
    driver.get(base + "/signin")
    check(me(driver) is None, "and has no web session in vsurg")

    # No vsurg role at the provider; a role here that differs from the provider's.
    check(through_provider(driver, wait, base, "mo"), "mo passes the provider")
    text = refused_text(driver, wait)
    check("no vsurg role" in text, f"a user without a vsurg role is refused ({text})")
    check(through_provider(driver, wait, base, "ada"), "ada passes the provider")
    text = refused_text(driver, wait)
    check("role" in text and "trainee" in text and "admin" in text,
          f"a role that differs from the provider's is refused ({text})")
    driver.save_screenshot(os.path.join(SHOTS, "oidc-refused.png"))
    check(me(driver) is None, "and has no web session")

    # Tokens still sign in beside the provider.
    sign_in(driver, wait, base, admin)
    who = me(driver)
    check(who and who["role"] == "admin", "a token still signs the administrator in")
    driver.quit()


if __name__ == "__main__":
    try:
        main()
    except Exception as e:  # a crash is a failure, with the server's last words
        failures.append(f"crashed: {e!r}")
        print(f"FAIL crashed: {e!r}", flush=True)
    finally:
        for p in procs:
            p.terminate()
            p.wait(timeout=30)
        subprocess.run([f"{ROOT}/deploy/oidc_provider.sh", "stop", idp_dir])
        if failures:
            log = os.path.join(tmp, "server.log")
            if os.path.exists(log):
                print(open(log).read()[-3000:])
        shutil.rmtree(tmp, ignore_errors=True)
    sys.exit(1 if failures else 0)
