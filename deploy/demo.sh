#!/usr/bin/env bash
# The main job end to end on the embedded defaults: the arm-torsion scene of the coil-spring paper. Loads the
# default forearm, applies 2.07 N·m in ten steps with the coil-spring model (per step: cutoff layer,
# total twist, overload flag, vertices moved), writes the deformed mesh as OBJ, then shows what
# happens past the limb's capacity, how far the model is from Saint-Venant torsion, and three
# scripted trainees performing the arm-torsion task through the full haptic simulation, and the
# authenticated UDP channel's round trip with eight stations on loopback; then the platform as its
# users touch it (deploy/demo_flow.sh): vsurg-server on a temporary SQLite file, a trainee's
# headless station twisting the arm over UDP, an instructor's monitor following it live, three
# evaluator groups scoring the session, the weighted report, the trial metrics and the CSV
# export; screenshots of the station before and after the twist (and the monitor) go to docs/;
# then one site over several processes (deploy/cluster_flow.sh, docs/SCALING.md): PostgreSQL, two
# control replicas, three simulation nodes, 24 stations; a node frozen past its lease and resumed,
# a second process under a live node's name, then a node and a replica killed; a rolling restart
# of the nodes with live migration (deploy/rolling_restart.sh); then the training
# programme (tests/e2e/training_test.py): a course from three expert runs, a cohort of ten
# trained by stations that follow it, the instructor's grid updating live in Chromium.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
root="$(vsurg_root)"
vsurg_install_packages
vsurg_build
sim="$root/build/bin/vsurg-sim"
out="$root/build/demo"
mkdir -p "$out"

echo
echo "== Arm torsion: the coil-spring paper's 2.07 N*m in 10 steps =="
"$sim" deform --scene arm --torque 2.07 --steps 10 --out "$out/arm_twisted.obj"

echo
echo "== Past capacity: 5 N*m is more than a forearm takes (3.3 N*m) =="
"$sim" deform --scene arm --torque 5 --steps 2 --out "$out/arm_overloaded.obj"

echo
echo "== Calf torsion at 2.07 N*m =="
"$sim" deform --scene calf --torque 2.07 --steps 3 --out "$out/calf_twisted.obj"

echo
echo "== Coil model against Saint-Venant torsion of the same forearm (G = 12 kPa), haptic-scale torques =="
"$sim" calibrate --scene arm --max-torque 0.1

echo
echo "== Three scripted trainees twist the forearm 45 degrees (arm-torsion scene): metrics and score =="
for style in good hesitant rough; do
  "$sim" trainee --scene arm-torsion --style "$style" --out "$out/twist-$style.csv" > /dev/null
  echo "-- $style"
  "$sim" run --scene arm-torsion --trajectory "$out/twist-$style.csv"
done

echo
echo "== The UDP haptic channel: 8 stations at 1 kHz against a real endpoint on loopback, 2 s =="
"$root/build/bin/vsurg-bench" haptic-rtt --stations 8 --seconds 2

echo
echo "== Weighted evaluation offline (the coil-spring paper eq. 9-11): 40 raters score the coil-spring model =="
"$sim" score --input "$root/deploy/samples/ratings-coil-spring.csv"

echo
echo "== Pattern cutting, as a drill: a scripted trainee's two hands cut a marked circle out of a taut skin patch =="
for hand in expert novice; do
  "$sim" cut --drill "$root/scenes/drills/pattern-cut.json" --hand "$hand" --figure "$out/cut-$hand" |
    /usr/bin/python3 -c 'import json, sys; d = json.load(sys.stdin); print("%s: score %.1f, %.2f mm RMS from the line, %d lifts, the piece out in %.1f s (figure: %s)" % (d["hand"], d["score"], d["deviation_rms_mm"], d["lifts"], d["completion_time_s"], sys.argv[1]))' "$out/cut-$hand/cut.png"
done

echo
echo "==== The platform end to end: server, a trainee's station, an instructor's monitor, evaluators, administrator ===="
"$root/deploy/demo_flow.sh" "$root/build/bin" "$out/flow" "$root/docs"

echo
echo "==== Beyond one machine: PostgreSQL, 2 control replicas, 3 simulation nodes, 24 stations; a node frozen and resumed, a duplicate node refused, a node and a replica killed ===="
"$root/deploy/cluster_flow.sh" "$root/build/bin" "$out/cluster" 24

echo
echo "==== A rolling restart under load: each of 3 nodes in turn drains (SIGTERM), moving its live sessions with their state to the others, and comes back; 24 stations follow their sessions ===="
"$root/deploy/rolling_restart.sh" "$root/build/bin" "$out/rolling" 24

echo
echo "==== The training programme: three expert runs set the targets, a course of two exercises, a cohort of ten training at stations that follow it, the instructor's grid following them live ===="
vsurg_install_npm  # axe-core for the page checks
/usr/bin/python3 "$root/tests/e2e/training_test.py" "$root/build/bin" "$root/scenes" "$out/training"
echo "(the pages as they were: $out/training/training-*.png)"

echo
echo "==== The web dashboard on the demo's store ===="
http="127.0.0.1:${VSURG_HTTP_PORT:-8080}"
rm -f "$out/flow/ready.json"
VSURG_SCENES="$root/scenes" "$root/build/bin/vsurg-server" --db "$out/flow/vsurg.db" \
  --listen 127.0.0.1:0 --udp-port 0 --http "$http" --ready-file "$out/flow/ready.json" \
  2> "$out/flow/dashboard-server.log" &
dashboard_pid=$!
trap 'kill "$dashboard_pid" 2>/dev/null || true; wait "$dashboard_pid" 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -s "$out/flow/ready.json" ] && break; sleep 0.1; done
[ -s "$out/flow/ready.json" ] || { cat "$out/flow/dashboard-server.log" >&2; exit 1; }
echo "web dashboard: http://$http/  (sign in with a token from $out/flow/tokens.txt:"
echo "               instructor: live stations and sessions; evaluator: scoring; admin: everything)"
echo
echo "demo: deformed meshes and trajectories in $out; the platform run's logs and scores.csv in $out/flow;"
echo "      screenshots in docs/ (station-before.png, station-twisted.png, monitor-view.png,"
echo "      station-palpation-novice.png)"
if [ -t 0 ]; then
  echo "The dashboard runs until Ctrl-C."
  wait "$dashboard_pid" || true
fi
