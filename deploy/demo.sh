#!/usr/bin/env bash
# The main job end to end on the embedded defaults: the arm-torsion scene of seed 000. Loads the
# default forearm, applies 2.07 N·m in ten steps with the coil-spring model (per step: cutoff layer,
# total twist, overload flag, vertices moved), writes the deformed mesh as OBJ, then shows what
# happens past the limb's capacity, how far the model is from Saint-Venant torsion, and three
# scripted trainees performing the arm-torsion task through the full haptic simulation, and the
# authenticated UDP channel's round trip with eight stations on loopback, and the control plane:
# vsurg-server on a temporary SQLite file, three evaluator groups scoring three simulator models
# (seed 000 §4.4), the weighted reports, and the administrator's CSV export.
set -euo pipefail
source "$(dirname "$0")/lib.sh"
root="$(vsurg_root)"
vsurg_install_packages
vsurg_build
sim="$root/build/bin/vsurg-sim"
out="$root/build/demo"
mkdir -p "$out"

echo
echo "== Arm torsion: seed 000's 2.07 N*m in 10 steps =="
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
echo "== Weighted evaluation offline (seed 000 eq. 9-11): 40 raters score the coil-spring model =="
"$sim" score --input "$root/deploy/samples/ratings-coil-spring.csv"

echo
echo "== Control plane: vsurg-server on a temporary SQLite file; evaluators score three models =="
admin="$root/build/bin/vsurg-admin"
tmp="$(mktemp -d)"
server_pid=""
cleanup() {
  if [ -n "$server_pid" ]; then kill "$server_pid" 2>/dev/null || true; wait "$server_pid" 2>/dev/null || true; fi
  rm -rf "$tmp"
}
trap cleanup EXIT
VSURG_TOKEN="$("$admin" init --db "$tmp/vsurg.db" 2>/dev/null)"
export VSURG_TOKEN
"$root/build/bin/vsurg-server" --db "$tmp/vsurg.db" --listen 127.0.0.1:0 --udp-port 0 \
  --ready-file "$tmp/ready.json" 2> "$tmp/server.log" &
server_pid=$!
for _ in $(seq 100); do [ -s "$tmp/ready.json" ] && break; sleep 0.1; done
port="$(sed -n 's/.*"grpc_port":\([0-9]*\).*/\1/p' "$tmp/ready.json")"
[ -n "$port" ] || { echo "demo: vsurg-server did not start" >&2; cat "$tmp/server.log" >&2; exit 1; }
server="127.0.0.1:$port"
"$admin" user-add --server "$server" --name dr-chief --role evaluator --group chief > /dev/null
"$admin" import --server "$server" --input "$root/deploy/samples/ratings-three-models.csv" \
  --subject-kind model
"$admin" report --server "$server" --subject-kind model --subjects coil-spring,mass-spring,fem
"$admin" export --server "$server" --format csv --out "$out/scores.csv"
echo "-- first rows of $out/scores.csv"
head -4 "$out/scores.csv"
kill -TERM "$server_pid"
wait "$server_pid"
server_pid=""
echo "-- server log"
cat "$tmp/server.log"

echo
echo "demo: deformed meshes, trajectories and scores.csv in $out"
