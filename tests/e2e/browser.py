"""What the browser tests share (dashboard_test.py, training_test.py; bench/training_load.py):
checks that count their failures, the HTTP API with a bearer token, a headless Chromium (Debian's
chromium and chromedriver), signing in on the dashboard's page, and axe-core's verdict."""
import json
import os
import subprocess
import time
import urllib.request

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By

# axe-core from the npm registry (tests/e2e/package-lock.json; deploy/test.sh runs npm ci).
AXE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "node_modules", "axe-core", "axe.min.js")
T0 = time.time()
failures = []


def check(ok, what):
    """Says the check with the seconds since the start (where a slow run spends its time)."""
    print(("ok   " if ok else "FAIL ") + f"[{time.time() - T0:5.1f} s] " + what, flush=True)
    if not ok:
        failures.append(what)


def api(port, method, path, token, body=None, raw=False):
    """A call of /api/v1 with a bearer token: the JSON answer (or its text, `raw`)."""
    req = urllib.request.Request(f"http://127.0.0.1:{port}/api/v1{path}", method=method)
    req.add_header("Authorization", "Bearer " + token)
    data = None
    if body is not None:
        req.add_header("Content-Type", "application/json")
        data = json.dumps(body).encode()
    with urllib.request.urlopen(req, data, timeout=30) as r:
        text = r.read().decode()
        return text if raw else (json.loads(text) if text else None)


def start_server(bin_dir, tmp, procs, env, http="127.0.0.1:0", extra=()):
    """vsurg-server on a new SQLite file in `tmp` (its log in tmp/server.log), the dashboard on
    `http`, appended to `procs` once it is serving: the first administrator's token and the ready
    file's ports ({"http_port", "grpc_port", ...})."""
    db = os.path.join(tmp, "vsurg.db")
    admin = subprocess.run([f"{bin_dir}/vsurg-server", "init", "--db", db], capture_output=True,
                           text=True, check=True, env=env).stdout.strip()
    ready = os.path.join(tmp, "ready.json")
    procs.append(subprocess.Popen(
        [f"{bin_dir}/vsurg-server", "--db", db, "--listen", "127.0.0.1:0", "--udp-port", "0",
         "--http", http, "--ready-file", ready, *extra],
        stderr=open(os.path.join(tmp, "server.log"), "w"), env=env))
    for _ in range(600):
        if os.path.exists(ready) and os.path.getsize(ready) > 0:
            break
        time.sleep(0.1)
    return admin, json.load(open(ready))


def chrome(width, height, prefs=None, console=False, performance=False):
    """Headless Chromium at width × height on the software renderer; `console` keeps the page's
    console, `performance` the network events (driver.get_log)."""
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for flag in ["--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                 f"--window-size={width},{height}", "--use-angle=swiftshader",
                 "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
                 "--disable-background-networking", "--disable-component-update"]:
        options.add_argument(flag)
    if prefs:
        options.add_experimental_option("prefs", prefs)
    logs = {**({"browser": "ALL"} if console else {}), **({"performance": "ALL"} if performance else {})}
    if logs:
        options.set_capability("goog:loggingPrefs", logs)
    return webdriver.Chrome(options=options, service=Service(executable_path="/usr/bin/chromedriver"))


def sign_in(driver, wait, base, token):
    """Signs in on /signin with `token` and waits for the page it leads to."""
    driver.delete_all_cookies()
    driver.get(base + "/signin")
    wait.until(lambda d: d.find_elements(By.CSS_SELECTOR, "#signin input"))
    driver.find_element(By.CSS_SELECTOR, "#signin input").send_keys(token)
    driver.find_element(By.CSS_SELECTOR, "#signin button").click()
    wait.until(lambda d: "/signin" not in d.current_url)
    wait.until(lambda d: d.find_elements(By.ID, "signout"))


def axe_source():
    return open(AXE).read() if os.path.exists(AXE) else None


def accessible(driver, source, what):
    """axe-core on the page as it is now: checks that no violation is serious or critical."""
    if not source:
        return
    if not driver.execute_script("return !!window.axe"):
        driver.execute_script(source)
    result = driver.execute_async_script(
        "const done = arguments[0];"
        "axe.run(document, {resultTypes: ['violations']}).then((r) => done(r.violations"
        ".map((v) => ({id: v.id, impact: v.impact, nodes: v.nodes.length,"
        " target: v.nodes[0] && v.nodes[0].target.join(' ')})))).catch((e) => done(String(e)));")
    if isinstance(result, str):
        return check(False, f"axe ran on {what}: {result}")
    bad = [v for v in result if v["impact"] in ("serious", "critical")]
    check(not bad, f"axe: no serious or critical violation on {what} {bad[:4] if bad else ''}")
