#!/usr/bin/env bash
# The visual frames' traffic of a cut, beside the same trial uncut: a vsurg-server and headless
# vsurg-station runs of scenes/pattern-cut.json with the scene's grasper in the second hand:
#   cut      the scripted good cut (the blade 5.7 mm below the patch's plane, through it);
#   pressed  the same blade path raised PRESS_MM (3.5): it drags a 2.2 mm dimple round the circle
#            and never punctures (the same moving tissue, no cut);
#   lifted   raised LIFT_MM (10): it never touches (the frames carry the grasper's lift only).
# All against one server, RUNS (3) times in turn. Prints per run the SceneFrame datagrams and
# bytes the station received (header and tag included; of them, the cut's faces' chunks), per
# second of trial, and the coverage.
# usage: [RUNS=3] [PRESS_MM=3.5] [LIFT_MM=10] bench/cut_frames.sh [BIN_DIR]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
B="$(cd "${1:-build/bin}" && pwd)"; d=$(mktemp -d); trap 'kill $spid 2>/dev/null; rm -rf $d' EXIT
cd "$d"
source "$here/local_server.sh"
$B/vsurg-sim trainee --scene pattern-cut --style good --out cut.csv > /dev/null
# The same path raised: the z column (metres) by PRESS_MM and by LIFT_MM.
python3 - "${PRESS_MM:-3.5}" "${LIFT_MM:-10}" <<'PY'
import csv, sys
rows = list(csv.reader(open("cut.csv")))
z = rows[0].index("z")
for name, mm in (("pressed", sys.argv[1]), ("lifted", sys.argv[2])):
    with open(name + ".csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(rows[0])
        for r in rows[1:]:
            w.writerow(r[:z] + [repr(float(r[z]) + float(mm) * 1e-3)] + r[z + 1:])
PY
for run in $(seq ${RUNS:-3}); do
  for kind in cut pressed lifted; do
    $B/vsurg-station --server 127.0.0.1:$PORT --token-file t.tok --scene pattern-cut --trajectory $kind.csv \
        --second-device grasper --headless --width 320 --height 200 --fps 10 --quality low --json \
        --realtime-priority 0 2>/dev/null \
      | python3 -c "import json,sys; j=json.load(sys.stdin); m=j['metrics']; t=max(m['duration'],1e-9); print('run=$run trial=$kind frames_per_s=%.1f bytes_per_s=%.0f topology_bytes_per_s=%.0f bytes=%d duration_s=%.2f coverage=%.2f' % (j['scene_chunks']/t, j['scene_bytes']/t, j['topology_bytes']/t, j['scene_bytes'], m['duration'], m.get('coverage', 0)))"
  done
done
