#!/usr/bin/python3
"""The training programme at a large site's scale: 200 trainees x 10 exercises x 50 attempts
(100,000 recorded trials) in one cohort and one course. Times, on loopback against a
vsurg-server on an SQLite store: the cohort grid's API (GET /training/cohorts/1/grid), one
trainee's learning curve (GET /training/curve) and the cohort curve, each N times (median and
max); then the training page in headless Chromium until its grid shows all 200 rows, and the
curve until its CUSUM chart is drawn (navigation start to drawn, N loads each).
The store is seeded with SQL in one transaction after `vsurg-server init` made the schema.
usage: bench/training_load.py BIN_DIR SCENES_DIR [LOADS=5]"""
import json
import os
import random
import shutil
import signal
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request

from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "e2e"))
from browser import chrome, sign_in  # noqa: E402 (the browser tests' helpers)

BIN, SCENES = sys.argv[1], sys.argv[2]
LOADS = int(sys.argv[3]) if len(sys.argv) > 3 else 5
TRAINEES, EXERCISES, ATTEMPTS = 200, 10, 50
tmp = tempfile.mkdtemp(prefix="vsurg_training_load_")
env = dict(os.environ, VSURG_SCENES=SCENES)
db = os.path.join(tmp, "vsurg.db")
admin = subprocess.run([f"{BIN}/vsurg-server", "init", "--db", db], capture_output=True,
                       text=True, check=True, env=env).stdout.strip()

# --- seed: an instructor, a course of ten exercises, a cohort of 200, 100,000 trials ---
t_seed = time.time()
rng = random.Random(1)
c = sqlite3.connect(db)
now = int(time.time() * 1e6)
c.execute("INSERT INTO users(name, role, created_us) VALUES ('ian', 'instructor', ?)", (now,))
ian = c.execute("SELECT id FROM users WHERE name = 'ian'").fetchone()[0]
c.execute("INSERT INTO courses(name, description, owner_id, created_us) VALUES ('Scale', '', ?, ?)", (ian, now))
spec = json.dumps({"targets": [{"metric": "completion_time_s", "value": 20}, {"metric": "peak_force_n", "value": 2.0},
                               {"metric": "overload_events", "value": 1}], "consecutive": 2})
for e in range(EXERCISES):
    c.execute("INSERT INTO exercises(course_id, position, title, scene, spec_json) VALUES (1, ?, ?, 'arm-torsion', ?)",
              (e + 1, f"Exercise {e + 1}", spec))
c.execute("INSERT INTO scenes(name, first_used_us) VALUES ('arm-torsion', ?)", (now,))
c.execute("INSERT INTO cohorts(name, instructor_id, created_us) VALUES ('Everyone', ?, ?)", (ian, now))
c.execute("INSERT INTO enrolments(course_id, cohort_id, starts_us, created_us) VALUES (1, 1, ?, ?)", (now - 10**12, now))
sid = 0
for t in range(TRAINEES):
    name = f"trainee{t:03d}"
    c.execute("INSERT INTO trainees(name) VALUES (?)", (name,))
    tid = c.execute("SELECT id FROM trainees WHERE name = ?", (name,)).fetchone()[0]
    c.execute("INSERT INTO cohort_members(cohort_id, trainee_id) VALUES (1, ?)", (tid,))
    skill = rng.random()
    sessions, metrics = [], []
    for e in range(EXERCISES):
        for a in range(ATTEMPTS):
            sid += 1
            at = now - 10**11 + sid * 1000
            sessions.append((sid, tid, at, at, at, e + 1))
            p = min(0.95, 0.2 + skill * 0.6 + a * 0.01)  # better with practice
            ok = rng.random() < p
            metrics.append((sid, 15 + rng.random() * (3 if ok else 20), 1.0 + rng.random() * (0.8 if ok else 2.0),
                            0 if ok else rng.randint(0, 3), rng.random() * 10, at))
    c.executemany("INSERT INTO sessions(id, trainee_id, scene, state, created_us, started_us, ended_us, exercise_id) "
                  "VALUES (?, ?, 'arm-torsion', 'ended', ?, ?, ?, ?)", sessions)
    c.executemany("INSERT INTO trial_metrics(session_id, completed, completion_time_s, task_error, peak_force_n, "
                  "time_over_force_limit_s, path_length_m, rms_jerk, overload_events, duration_s, score, raw_score, "
                  "caps, recorded_us) VALUES (?, 1, ?, 0, ?, 0, 0.1, 0, ?, 30, ?, 0, 0, ?)", metrics)
c.commit()
c.close()
print(f"seeded {sid} trials ({TRAINEES} trainees x {EXERCISES} exercises x {ATTEMPTS}) in {time.time() - t_seed:.1f} s", flush=True)

ready = os.path.join(tmp, "ready.json")
server = subprocess.Popen([f"{BIN}/vsurg-server", "--db", db, "--listen", "127.0.0.1:0", "--udp-port", "0",
                           "--http", "127.0.0.1:0", "--ready-file", ready], stderr=subprocess.DEVNULL, env=env)
driver = None
try:
    for _ in range(300):
        if os.path.exists(ready) and os.path.getsize(ready):
            break
        time.sleep(0.1)
    port = json.load(open(ready))["http_port"]
    base = f"http://127.0.0.1:{port}"

    def call(path, token):
        req = urllib.request.Request(base + "/api/v1" + path, method="POST" if path.startswith("/users") else "GET")
        req.add_header("Authorization", "Bearer " + token)
        if req.method == "POST":
            req.add_header("Content-Type", "application/json")
        with urllib.request.urlopen(req, b"{}" if req.method == "POST" else None, timeout=60) as r:
            return r.read()
    ian_token = json.loads(call("/users/ian/token", admin))["token"]

    def timed(what, path):
        ms = []
        for _ in range(LOADS):
            t0 = time.perf_counter()
            body = call(path, ian_token)
            ms.append((time.perf_counter() - t0) * 1e3)
        print(f"{what}: median {statistics.median(ms):.0f} ms, max {max(ms):.0f} ms, {len(body) / 1024:.0f} KiB "
              f"({LOADS} requests)", flush=True)
    timed("API grid (200 x 10, 100,000 trials)", "/training/cohorts/1/grid?course=1")
    timed("API learning curve (one trainee, one exercise)", "/training/curve?trainee=trainee007&exercise=3")
    timed("API cohort curve (200 trainees, one exercise)", "/training/cohorts/1/curve?exercise=3")

    driver = chrome(1366, 768)
    wait = WebDriverWait(driver, 60, poll_frequency=0.02)
    sign_in(driver, wait, base, ian_token)
    grid_ms, curve_ms = [], []
    # The page stamps, on its own clock (performance.now(): from navigation start), when it drew
    # the grid and a curve: what is timed is the page, not this script's polling.
    driver.get(base + "/training")  # one load first, not counted: the browser's own start-up
    wait.until(lambda d: len(d.find_elements(By.CSS_SELECTOR, "#progress-grid tbody tr")) == TRAINEES)
    for _ in range(LOADS):
        driver.get(base + "/training")
        wait.until(lambda d: len(d.find_elements(By.CSS_SELECTOR, "#progress-grid tbody tr")) == TRAINEES)
        grid_ms.append(float(driver.find_element(By.ID, "cohort-grid").get_attribute("data-drawn-at")))
        t0 = driver.execute_script("return performance.now()")
        driver.find_element(By.CSS_SELECTOR, "#progress-grid tbody tr td.cell button").click()
        wait.until(lambda d: d.find_element(By.ID, "curve").get_attribute("data-drawn-at"))
        curve_ms.append(float(driver.find_element(By.ID, "curve").get_attribute("data-drawn-at")) - t0)
    print(f"page: training grid drawn (200 rows) {statistics.median(grid_ms):.0f} ms median, {max(grid_ms):.0f} ms max "
          f"from navigation start ({LOADS} loads)", flush=True)
    print(f"page: a learning curve drawn (click to CUSUM chart) {statistics.median(curve_ms):.0f} ms median, "
          f"{max(curve_ms):.0f} ms max", flush=True)
finally:
    if driver:
        driver.quit()
    server.send_signal(signal.SIGTERM)
    server.wait(timeout=30)
    shutil.rmtree(tmp, ignore_errors=True)
