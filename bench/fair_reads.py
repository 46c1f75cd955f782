#!/usr/bin/python3
"""One instructor's burst of long reads beside another instructor's page, on loopback against a
vsurg-server on an SQLite store. Instructor ian has a cohort of 2,000 trainees in a course of 64
exercises (one recorded trial per trainee and exercise: 128,000); instructor olga a cohort of 10
in a course of 4. Ian's 40 keep-alive connections ask for his grid as fast as they are answered
for DURATION seconds; meanwhile olga asks for her grid every 0.5 s. Prints olga's statuses and
latencies (median, max) and ian's statuses: the promise is that olga is always answered (200),
whatever ian asks.
usage: bench/fair_reads.py BIN_DIR SCENES_DIR [DURATION_S=20]"""
import http.client
import json
import os
import shutil
import signal
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from collections import Counter

BIN, SCENES = sys.argv[1], sys.argv[2]
DURATION = float(sys.argv[3]) if len(sys.argv) > 3 else 20.0
BIG, BIG_EXERCISES, SMALL, SMALL_EXERCISES, CONNECTIONS = 2000, 64, 10, 4, 40
tmp = tempfile.mkdtemp(prefix="vsurg_fair_reads_")
env = dict(os.environ, VSURG_SCENES=SCENES)
db = os.path.join(tmp, "vsurg.db")
admin = subprocess.run([f"{BIN}/vsurg-server", "init", "--db", db], capture_output=True,
                       text=True, check=True, env=env).stdout.strip()


def seed():
    c = sqlite3.connect(db)
    now = int(time.time() * 1e6)
    c.execute("INSERT INTO scenes(name, first_used_us) VALUES ('arm-torsion', ?)", (now,))
    spec = json.dumps({"targets": [{"metric": "completion_time_s", "value": 20}], "consecutive": 2})
    sid = 0
    for course, (who, trainees, exercises) in enumerate([("ian", BIG, BIG_EXERCISES),
                                                        ("olga", SMALL, SMALL_EXERCISES)], start=1):
        c.execute("INSERT INTO users(name, role, created_us) VALUES (?, 'instructor', ?)", (who, now))
        uid = c.execute("SELECT id FROM users WHERE name = ?", (who,)).fetchone()[0]
        c.execute("INSERT INTO courses(id, name, description, owner_id, created_us) VALUES (?, ?, '', ?, ?)",
                  (course, f"course-{who}", uid, now))
        first_exercise = c.execute("SELECT coalesce(max(id), 0) FROM exercises").fetchone()[0] + 1
        for e in range(exercises):
            c.execute("INSERT INTO exercises(course_id, position, title, scene, spec_json) "
                      "VALUES (?, ?, ?, 'arm-torsion', ?)", (course, e + 1, f"Exercise {e + 1}", spec))
        c.execute("INSERT INTO cohorts(id, name, instructor_id, created_us) VALUES (?, ?, ?, ?)",
                  (course, f"cohort-{who}", uid, now))
        c.execute("INSERT INTO enrolments(course_id, cohort_id, starts_us, created_us) VALUES (?, ?, ?, ?)",
                  (course, course, now - 10**12, now))
        sessions, metrics = [], []
        for t in range(trainees):
            name = f"{who}-trainee{t:04d}"
            c.execute("INSERT INTO trainees(name) VALUES (?)", (name,))
            tid = c.execute("SELECT id FROM trainees WHERE name = ?", (name,)).fetchone()[0]
            c.execute("INSERT INTO cohort_members(cohort_id, trainee_id) VALUES (?, ?)", (course, tid))
            for e in range(exercises):
                sid += 1
                at = now - 10**11 + sid * 1000
                sessions.append((sid, tid, at, at, at, first_exercise + e))
                metrics.append((sid, 15 + (sid % 10), at))
        c.executemany("INSERT INTO sessions(id, trainee_id, scene, state, created_us, started_us, ended_us, "
                      "exercise_id) VALUES (?, ?, 'arm-torsion', 'ended', ?, ?, ?, ?)", sessions)
        c.executemany("INSERT INTO trial_metrics(session_id, completed, completion_time_s, task_error, "
                      "peak_force_n, time_over_force_limit_s, path_length_m, rms_jerk, overload_events, "
                      "duration_s, score, raw_score, caps, recorded_us) "
                      "VALUES (?, 1, ?, 0, 1.0, 0, 0.1, 0, 0, 30, 8, 0, 0, ?)", metrics)
    c.commit()
    c.close()
    return sid


t_seed = time.time()
trials = seed()
print(f"seeded {trials} trials in {time.time() - t_seed:.1f} s", flush=True)
ready = os.path.join(tmp, "ready.json")
server = subprocess.Popen([f"{BIN}/vsurg-server", "--db", db, "--listen", "127.0.0.1:0", "--udp-port", "0",
                           "--http", "127.0.0.1:0", "--ready-file", ready], stderr=subprocess.DEVNULL, env=env)
try:
    for _ in range(300):
        if os.path.exists(ready) and os.path.getsize(ready):
            break
        time.sleep(0.1)
    port = json.load(open(ready))["http_port"]

    def token(who):
        req = urllib.request.Request(f"http://127.0.0.1:{port}/api/v1/users/{who}/token", method="POST",
                                     data=b"{}", headers={"Authorization": "Bearer " + admin,
                                                          "Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=60) as r:
            return json.loads(r.read())["token"]
    tokens = {who: token(who) for who in ("ian", "olga")}
    stop = time.monotonic() + DURATION
    ian_statuses, lock = Counter(), threading.Lock()

    def grid(conn, who, course):
        t0 = time.perf_counter()
        conn.request("GET", f"/api/v1/training/cohorts/{course}/grid?course={course}",
                     headers={"Authorization": "Bearer " + tokens[who]})
        r = conn.getresponse()
        r.read()
        return r.status, (time.perf_counter() - t0) * 1e3

    def burst():
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
        while time.monotonic() < stop:
            status, _ = grid(conn, "ian", 1)
            with lock:
                ian_statuses[status] += 1
        conn.close()

    threads = [threading.Thread(target=burst) for _ in range(CONNECTIONS)]
    for t in threads:
        t.start()
    time.sleep(1)  # the burst under way
    olga, ms = Counter(), []
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=120)
    while time.monotonic() < stop:
        status, took = grid(conn, "olga", 2)
        olga[status] += 1
        ms.append(took)
        time.sleep(0.5)
    for t in threads:
        t.join()
    print(f"olga's small grid ({SMALL} x {SMALL_EXERCISES}) beside ian's {CONNECTIONS} connections on his "
          f"{BIG} x {BIG_EXERCISES} grid for {DURATION:.0f} s: statuses {dict(olga)}, median {statistics.median(ms):.0f} ms, "
          f"max {max(ms):.0f} ms ({len(ms)} requests)", flush=True)
    print(f"ian's requests: statuses {dict(ian_statuses)}", flush=True)
finally:
    server.send_signal(signal.SIGTERM)
    server.wait(timeout=30)
    shutil.rmtree(tmp, ignore_errors=True)
