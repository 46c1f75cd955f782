#!/usr/bin/env python3
"""The training programme end to end, in a real headless Chromium, with real stations:

- three experts train on the arm (two smooth trials, one hesitant) at replaying stations;
- the instructor marks them as experts on the training page, builds a two-exercise course whose
  first exercise takes its targets from the experts' trials, makes a cohort of ten and enrols it;
- ten scripted trainees train at stations that follow the course (--course): tina reaches
  proficiency in both exercises (two passes in a row each), rory trains hesitantly and misses,
  the others make one smooth attempt each; the cohort grid, open in the browser, follows them
  live (never reloaded) until tina's row reads proficient, proficient;
- each station's end-of-trial summary says which targets were met;
- tina's learning curves (metrics over attempts with the target band, the CUSUM chart) and the
  cohort curve against the experts' open from the grid; tina reads her own course on her page;
- the progress exports (CSV, xAPI) agree with the grid; axe-core finds no serious violation.
Run by ctest (label e2e): training_test.py BIN_DIR SCENES_DIR SHOTS_DIR. Exits 0 when every
check held.
"""
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.error

from prometheus_client.parser import text_string_to_metric_families
from selenium.common.exceptions import WebDriverException
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from browser import (AXE, accessible, api as request, axe_source, check, chrome, failures, sign_in,
                     start_server)

BIN, SCENES, SHOTS = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(SHOTS, exist_ok=True)
tmp = tempfile.mkdtemp(prefix="vsurg_training_")
procs = []
TRAINEES = ["tina", "rory", "anna", "ben", "carl", "dana", "eli", "fay", "gus", "hana"]
EXPERTS = ["exa", "exb", "exc"]


def main():
    env = dict(os.environ, VSURG_SCENES=SCENES)
    admin, ports = start_server(BIN, tmp, procs, env)
    http, grpc = ports["http_port"], ports["grpc_port"]
    base = f"http://127.0.0.1:{http}"
    tokens = {}
    for name, role in [("ian", "instructor")] + [(n, "trainee") for n in EXPERTS + TRAINEES]:
        request(http, "POST", "/users", admin, {"name": name, "role": role, "group": "staff" if name in EXPERTS else "residents"})
        tokens[name] = request(http, "POST", f"/users/{name}/token", admin, {})["token"]

    def scrape():
        """GET /api/v1/metrics as the administrator, parsed by Prometheus' own text parser:
        {sample name: {labels as a sorted tuple: value}}."""
        out = {}
        for family in text_string_to_metric_families(request(http, "GET", "/metrics", admin, raw=True)):
            for sample in family.samples:
                out.setdefault(sample.name, {})[tuple(sorted(sample.labels.items()))] = sample.value
        return out

    first = scrape()
    check({"vsurg_sessions_live", "vsurg_station_rtt_seconds_bucket", "vsurg_udp_datagrams_dropped_total",
           "vsurg_http_requests_total"} <= set(first), "the metrics parse as Prometheus text, every family there")
    try:
        request(http, "GET", "/metrics", tokens["tina"], raw=True)
        check(False, "a trainee may not read the metrics")
    except urllib.error.HTTPError as e:
        check(e.code == 403, f"a trainee may not read the metrics ({e.code})")

    def recording(scene, style):
        path = os.path.join(tmp, f"{scene}-{style}.csv")
        subprocess.run([f"{BIN}/vsurg-sim", "trainee", "--scene", scene, "--style", style, "--out", path],
                       check=True, capture_output=True, env=env)
        return path
    arm_good, arm_hesitant = recording("arm-torsion", "good"), recording("arm-torsion", "hesitant")
    calf_good = recording("calf-torsion", "good")

    runs = [0]

    def station(name, trajectory, course=True, scene="arm-torsion", summary_png=None):
        """One trial at a replaying station, headless and small; returns its JSON summary."""
        runs[0] += 1
        out = os.path.join(tmp, f"station-{name}-{runs[0]}.json")
        size = ["--width", "720", "--height", "450"] if summary_png else ["--width", "160", "--height", "100"]
        args = [f"{BIN}/vsurg-station", "--server", f"127.0.0.1:{grpc}", "--token", tokens[name],
                "--device", "replay", "--trajectory", trajectory, "--headless", "--settle", "0.5",
                "--json", "--realtime-priority", "0", "--fps", "4", "--quality", "low",
                "--connect-timeout", "120"] + size
        if summary_png:
            args += ["--screenshot-summary", summary_png]
        args += ["--course"] if course else ["--scene", scene]
        p = subprocess.Popen(args, stdout=open(out, "w"),
                             stderr=open(out.replace(".json", ".log"), "w"), env=env)
        procs.append(p)
        return p, out

    def finish(p, out):
        p.wait(timeout=300)
        try:
            return json.load(open(out))
        except ValueError:
            print(open(out.replace(".json", ".log")).read(), flush=True)
            return {}

    # --- three experts' trials on the arm: two smooth, one hesitant ---
    expert_runs = [station("exa", arm_good, False), station("exb", arm_good, False),
                   station("exc", arm_hesitant, False)]
    expert_summaries = [finish(*r) for r in expert_runs]
    check(all(s.get("metrics_recorded") for s in expert_summaries), "the three expert trials were recorded")

    driver = chrome(1366, 900)
    driver.set_script_timeout(60)
    wait = WebDriverWait(driver, 60)
    axe = axe_source()
    check(axe is not None, f"axe-core is installed ({AXE})")
    try:
        def shot(name, height=None):
            try:
                if height:
                    driver.set_window_size(1366, height)
                    time.sleep(0.6)
                driver.save_screenshot(os.path.join(SHOTS, f"training-{name}.png"))
            except WebDriverException as e:
                print(f"screenshot {name} skipped: {e.msg}", flush=True)
            finally:
                if height:
                    driver.set_window_size(1366, 900)

        def cell_states(trainee):
            return driver.execute_script(
                "const r = document.querySelector(`#progress-grid tr[data-trainee='${arguments[0]}']`);"
                "return r ? [...r.querySelectorAll('td.cell')].map((c) => c.dataset.state) : [];", trainee)

        def fill(css, value):
            e = driver.find_element(By.CSS_SELECTOR, css)
            e.clear()
            e.send_keys(value)

        def tick(css, on):
            e = driver.find_element(By.CSS_SELECTOR, css)
            if e.is_selected() != on:
                e.click()

        # --- the instructor: experts, a course from their trials, a cohort of ten ---
        sign_in(driver, wait, base, tokens["ian"])
        driver.get(base + "/training")
        wait.until(lambda d: d.find_elements(By.ID, "course-form"))
        for e in EXPERTS:
            fill("#expert-form input[name=trainee]", e)
            driver.find_element(By.CSS_SELECTOR, "#expert-form button").click()
            wait.until(lambda d: "Marked as an expert" in d.find_element(By.ID, "training-news").text)
            driver.execute_script("document.getElementById('training-news').textContent = ''")
        check(request(http, "GET", "/training/experts", tokens["ian"])["experts"] == EXPERTS,
              "the three experts are marked from the page")
        fill("#course-form input[name=name]", "Limb torsion basics")
        fill("#course-form input[name=description]", "Twist the forearm to target, then the calf")
        fill("#course-form input[name=title-1]", "Twist the forearm")
        driver.find_element(By.CSS_SELECTOR, "#course-form select[name=scene-1] option[value='arm-torsion']").click()
        # Exercise 1: completion time from the experts (the default), peak force at most 3 N
        # (fixed), two passes in a row.
        tick("#course-form input[name=experts-peak_force_n-1]", False)
        fill("#course-form input[name=value-peak_force_n-1]", "3")
        fill("#course-form input[name=title-2]", "Twist the calf")
        driver.find_element(By.CSS_SELECTOR, "#course-form select[name=scene-2] option[value='calf-torsion']").click()
        # Exercise 2: fixed targets (no expert trials on the calf): score at least 5, at most 2 overloads.
        tick("#course-form input[name=use-completion_time_s-2]", False)
        tick("#course-form input[name=use-peak_force_n-2]", False)
        tick("#course-form input[name=use-score-2]", True)
        fill("#course-form input[name=value-score-2]", "5")
        tick("#course-form input[name=use-overload_events-2]", True)
        fill("#course-form input[name=value-overload_events-2]", "2")
        # Its own task: the calf's twist within 50 s (the scene allows 60).
        fill("#course-form input[name=task-time-2]", "50")
        driver.find_element(By.CSS_SELECTOR, "#course-form button[type=submit]").click()
        wait.until(lambda d: "created with 2 exercises" in d.find_element(By.ID, "training-news").text)
        course = request(http, "GET", "/training/courses", tokens["ian"])["courses"][0]
        t = {x["metric"]: x for x in course["exercises"][0]["targets"]}
        times = [round(s["metrics"]["completion_time"], 2) for s in expert_summaries]
        check(t["completion_time_s"]["from_experts"] and t["completion_time_s"]["expert_trials"] == 3,
              f"exercise 1's time target comes from the 3 expert trials ({t['completion_time_s']['value']} s from {times})")
        calf_task = course["exercises"][1]["task"]
        check(course["exercises"][1]["spec"]["task"] == {"time_limit_s": 50} and calf_task["time_limit_s"] == 50
              and calf_task["kind"] == "twist", f"exercise 2 sets its own time limit, the rest as the scene has it ({calf_task})")
        fill("#cohort-form input[name=name]", "Residents 2026")
        fill("#cohort-form textarea[name=members]", ", ".join(TRAINEES))
        driver.find_element(By.CSS_SELECTOR, "#cohort-form button").click()
        wait.until(lambda d: "created and enrolled" in d.find_element(By.ID, "training-news").text)
        wait.until(lambda d: len(d.find_elements(By.CSS_SELECTOR, "#progress-grid tbody tr")) == 10)
        check(cell_states("tina") == ["not_started", "locked"], f"the grid: ten trainees, the calf locked ({cell_states('tina')})")
        check("within 50 s" in driver.find_element(By.ID, "cohort-grid").text, "the grid names each exercise's task")
        shot("grid-empty")

        # --- ten trainees train at stations that follow the course; the grid follows live ---
        t_live = time.time()
        before = scrape()
        others = [station(n, arm_good) for n in TRAINEES[2:5]]
        # The Prometheus scrape while they train: stations driving, their round trips counted.
        live = scrape()
        deadline = time.time() + 30
        while live["vsurg_stations_driving"][()] < 1 and time.time() < deadline:
            time.sleep(0.2)
            live = scrape()
        check(live["vsurg_stations_driving"][()] >= 1 and live["vsurg_station_rtt_seconds_count"][()] >= 1
              and live["vsurg_udp_forces_sent_total"][()] > before["vsurg_udp_forces_sent_total"][()]
              and live["vsurg_udp_residence_seconds_count"][()] > before["vsurg_udp_residence_seconds_count"][()]
              and live["vsurg_udp_residence_seconds_sum"][()] > before["vsurg_udp_residence_seconds_sum"][()],
              f"the metrics move while stations run ({live['vsurg_stations_driving'][()]:.0f} driving, forces "
              f"{before['vsurg_udp_forces_sent_total'][()]:.0f} -> {live['vsurg_udp_forces_sent_total'][()]:.0f}, "
              f"answers timed on the node {before['vsurg_udp_residence_seconds_count'][()]:.0f} -> "
              f"{live['vsurg_udp_residence_seconds_count'][()]:.0f})")
        # The Grafana dashboard is built from these metrics: every series it asks for exists.
        grafana = json.load(open(os.path.join(os.path.dirname(__file__), "../../deploy/grafana/vsurg.json")))
        # (The "Site:" panels read the control and sim roles' series: deploy/cluster_flow.sh checks those.)
        asked = {m for p in grafana["panels"] if not p["title"].startswith("Site:")
                 for t in p["targets"] for m in re.findall(r"vsurg_[a-z_]+", t["expr"])}
        check(asked and asked <= set(live), f"the Grafana dashboard's series all exist ({sorted(asked - set(live))} missing)")
        rory = station("rory", arm_hesitant)
        tina_summaries = []
        for trial in range(2):  # two passes in a row reach the forearm
            tina_summaries.append(finish(*station("tina", arm_good)))
        for n in TRAINEES[5:]:
            others.append(station(n, arm_good))
        summary_png = os.path.join(SHOTS, "training-station-summary.png")
        for trial in range(2):  # the calf opened: two more (the last one's summary on screen)
            tina_summaries.append(finish(*station("tina", calf_good, summary_png=summary_png if trial else None)))
        summaries = [finish(*r) for r in others]
        rory_summary = finish(*rory)
        wait.until(lambda d: cell_states("tina") == ["proficient", "proficient"])
        check(True, f"the open grid turned tina's row proficient, proficient without a reload ({time.time() - t_live:.0f} s of training)")
        ex = [s.get("exercise", {}) for s in tina_summaries]
        check([e.get("title") for e in ex] == ["Twist the forearm"] * 2 + ["Twist the calf"] * 2,
              f"tina's station followed the course: {[e.get('title') for e in ex]}")
        check(all(e.get("passed") and e.get("targets") and all(x["met"] for x in e["targets"]) for e in ex),
              f"each of tina's summaries lists its targets, all met: {[e.get('targets') for e in ex]}")
        missed = [x["metric"] for x in rory_summary.get("exercise", {}).get("targets", []) if not x["met"]]
        check(rory_summary.get("exercise", {}).get("passed") is False and "completion_time_s" in missed,
              f"rory's hesitant trial misses the experts' time and says so ({missed})")
        wait.until(lambda d: sum(s[0] in ("training", "proficient", "stalled") for s in
                                 (cell_states(n) for n in TRAINEES)) == 10)
        states = {n: cell_states(n) for n in TRAINEES}
        check(states["rory"][0] == "training" and states["rory"][1] == "locked",
              f"rory trains on, the calf still locked for him ({states['rory']})")
        check(all(s.get("exercise", {}).get("targets") for s in summaries),
              "every other trainee's station summary names the targets")
        check(os.path.getsize(summary_png) > 0 if os.path.exists(summary_png) else False,
              "the station drew its end-of-trial summary with the targets (training-station-summary.png)")
        # One more trainee, enrolled on her own from the page, gets the course too.
        fill("#enrol-form input[name=trainee]", "una")
        driver.find_element(By.CSS_SELECTOR, "#enrol-form button").click()
        wait.until(lambda d: "una enrolled" in d.find_element(By.ID, "training-news").text)
        request(http, "POST", "/users", admin, {"name": "una", "role": "trainee", "group": "residents"})
        una = request(http, "POST", "/users/una/token", admin, {})["token"]
        check(request(http, "GET", "/training/next", una)["next"] == course["exercises"][0]["id"],
              "a trainee enrolled on her own from the page is given the course's first exercise")
        driver.execute_script("window.scrollTo(0, 0)")
        shot("grid", 1250)
        accessible(driver, axe, "the training page")

        # --- tina's curves and the cohort curve, from the grid ---
        driver.find_element(By.CSS_SELECTOR, "#progress-grid tr[data-trainee='tina'] td.cell button").click()
        wait.until(lambda d: d.find_elements(By.ID, "cusum-chart"))
        wait.until(lambda d: d.execute_script("const c = window.Chart && Chart.getChart('cusum-chart'); return c && c.data.datasets[0].data.length"))
        n_cusum = driver.execute_script("return Chart.getChart('cusum-chart').data.datasets[0].data.length")
        check(n_cusum == 2, f"tina's CUSUM has one point per attempt ({n_cusum})")
        check("proficient at attempt 2" in driver.find_element(By.ID, "curve").text, "her curve says when she became proficient")
        driver.find_element(By.CSS_SELECTOR, "#progress-grid thead button").click()
        wait.until(lambda d: d.find_elements(By.CSS_SELECTOR, "#cohort-curve canvas"))
        check("experts" in driver.find_element(By.ID, "cohort-curve").text, "the cohort curve stands beside the experts'")
        driver.execute_script("document.getElementById('curve').scrollIntoView()")
        shot("curves", 1300)

        # --- exports agree with the grid ---
        q = f"course={course['id']}&cohort=1"
        csv = request(http, "GET", f"/training/export?{q}&format=csv", tokens["ian"], raw=True).splitlines()
        check(len(csv) == 1 + 2 * len(TRAINEES), f"the CSV has a row per trainee and exercise ({len(csv) - 1})")
        check(any(',tina,proficient,2,2,2,2,' in line for line in csv), "tina's CSV rows say proficient at attempt 2")
        xapi = [json.loads(x) for x in request(http, "GET", f"/training/export?{q}&format=xapi", tokens["ian"], raw=True).splitlines()]
        verbs = [x["verb"]["display"]["en-US"] for x in xapi if x["actor"]["account"]["name"] == "tina"]
        check(verbs.count("attempted") == 4 and verbs.count("passed") == 2 and verbs.count("completed") == 1,
              f"tina's xAPI: 4 attempted, 2 passed, 1 completed ({verbs})")

        # --- tina reads her own course ---
        sign_in(driver, wait, base, tokens["tina"])
        driver.get(base + "/mine")
        wait.until(lambda d: d.find_elements(By.CSS_SELECTOR, "#my-course article.exercise"))
        text = driver.find_element(By.ID, "my-course").text
        check("reached proficiency in every exercise" in text, "tina's page says she reached the course")
        shot("mine", 1300)
        accessible(driver, axe, "the trainee's page with her course")
        try:
            request(http, "GET", "/training/cohorts/1/grid?course=1", tokens["tina"])
            check(False, "a trainee cannot read the cohort grid")
        except urllib.error.HTTPError as e:
            check(e.code == 403, f"a trainee cannot read the cohort grid ({e.code})")
    finally:
        driver.quit()


try:
    main()
except Exception as e:  # noqa: BLE001 — a test reports, it does not crash
    import traceback
    traceback.print_exc()
    failures.append(str(e))
finally:
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
    if failures:
        print("server log:\n" + open(os.path.join(tmp, "server.log")).read()[-3000:], flush=True)
    shutil.rmtree(tmp, ignore_errors=True)
print(f"{len(failures)} failure(s)" if failures else "all checks held", flush=True)
sys.exit(1 if failures else 0)
