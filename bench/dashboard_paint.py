#!/usr/bin/python3
"""The live page's time to first paint and to its first live data, in headless Chromium on
loopback: a vsurg-server with the dashboard on a fresh store, an instructor signed in, the page
loaded N times (the browser's own Paint Timing and Navigation Timing entries).
usage: bench/dashboard_paint.py BIN_DIR SCENES_DIR [LOADS=5]"""
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.support.ui import WebDriverWait

BIN, SCENES = sys.argv[1], sys.argv[2]
LOADS = int(sys.argv[3]) if len(sys.argv) > 3 else 5
tmp = tempfile.mkdtemp(prefix="vsurg_paint_")
env = dict(os.environ, VSURG_SCENES=SCENES)
db = os.path.join(tmp, "vsurg.db")
admin = subprocess.run([f"{BIN}/vsurg-server", "init", "--db", db], capture_output=True,
                       text=True, check=True).stdout.strip()
ready = os.path.join(tmp, "ready.json")
server = subprocess.Popen([f"{BIN}/vsurg-server", "--db", db, "--listen", "127.0.0.1:0",
                           "--udp-port", "0", "--http", "127.0.0.1:0", "--ready-file", ready],
                          stderr=subprocess.DEVNULL, env=env)
try:
    for _ in range(300):
        if os.path.exists(ready) and os.path.getsize(ready):
            break
        time.sleep(0.1)
    port = json.load(open(ready))["http_port"]
    base = f"http://127.0.0.1:{port}"
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for flag in ["--headless=new", "--no-sandbox", "--disable-dev-shm-usage"]:
        options.add_argument(flag)
    driver = webdriver.Chrome(options=options, service=Service("/usr/bin/chromedriver"))
    driver.get(base + "/signin")
    driver.execute_async_script("""
        const done = arguments[1];
        fetch('/api/v1/signin', {method: 'POST', headers: {'Content-Type': 'application/json'},
              body: JSON.stringify({token: arguments[0]})}).then(() => done());""", admin)
    paints, data = [], []
    for _ in range(LOADS):
        driver.get(base + "/live")
        WebDriverWait(driver, 20).until(lambda d: "updated" in d.execute_script(
            "const s = document.getElementById('live-status'); return s ? s.textContent : '';"))
        fcp = driver.execute_script(
            "const e = performance.getEntriesByName('first-contentful-paint')[0];"
            "return e ? e.startTime : null;")
        first = driver.execute_script(
            "return performance.getEntriesByName('vsurg-live-data')[0].startTime;")
        paints.append(fcp)
        data.append(first)
    driver.quit()
    print("live page, %d loads on loopback: first contentful paint median %.0f ms (min %.0f, max "
          "%.0f); first live data shown by %.0f ms (median; at most %.0f)" %
          (LOADS, statistics.median(paints), min(paints), max(paints), statistics.median(data),
           max(data)))
finally:
    server.send_signal(signal.SIGTERM)
    server.wait(timeout=10)
    shutil.rmtree(tmp, ignore_errors=True)
