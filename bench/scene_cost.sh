#!/usr/bin/env bash
# What one station costs the node, scene by scene: vsurg-bench haptic-rtt with STATIONS (4)
# full-rate stations on each shipped scene in turn, ROUNDS (2) times, each figure the server's own
# CPU (every thread of the node, the driver's excluded) per station, as a fraction of one core.
# Each station rests 4 mm inside the tissue and circles 5 mm once a second (a palpating hand); on
# the twist scenes it grasps and turns by TWIST_DEG (45) there and back every 2 s. Last, per scene
# the dearest round and the stations that 70% of this machine's cores hold at that cost.
#   usage: [ROUNDS=2] [STATIONS=4] [SECONDS_EACH=3] [TWIST_DEG=45] bench/scene_cost.sh [BIN_DIR] [SCENE...]
set -euo pipefail
BIN=${1:-build/bin}; shift || true
here="$(cd "$(dirname "$0")/.." && pwd)"
[ $# -ge 1 ] || set -- $(cd "$here/scenes" && ls *.json | sed 's/\.json$//')
ROUNDS=${ROUNDS:-2}; STATIONS=${STATIONS:-4}; SECONDS_EACH=${SECONDS_EACH:-3}
TWIST_DEG=${TWIST_DEG:-45}
out=$(mktemp); trap 'rm -f "$out"' EXIT
for r in $(seq "$ROUNDS"); do for scene in "$@"; do
  twist=0
  case "$scene" in *torsion*|*twist*) twist=$TWIST_DEG ;; esac
  "$BIN/vsurg-bench" haptic-rtt --scene "$scene" --stations "$STATIONS" --seconds "$SECONDS_EACH" \
      --stroke-mm 5 --twist-deg "$twist" --json \
    | python3 -c "import json,sys; j=json.load(sys.stdin); print('$scene', $r, j['server_process_cpu_per_station'], j['server_cpu_per_station'], j['loss'], j['rtt_p99_us'], j['frame_bytes_per_station_s'])" \
    | tee -a "$out"
done; done
python3 - "$out" "$(nproc)" <<'PY'
import collections, sys
rows = collections.defaultdict(list)
for line in open(sys.argv[1]):
    scene, r, proc, io, loss, p99, frames = line.split()
    rows[scene].append((float(proc), float(io), float(loss), float(p99), float(frames)))
cores = int(sys.argv[2])
print(f'{"scene":28} {"core/station":>13} {"of it I/O":>10} {"p99 us":>8} {"frames kB/s":>12} {"at 70%% of %d cores" % cores:>20}')
for scene, rs in sorted(rows.items(), key=lambda kv: -max(r[0] for r in kv[1])):
    proc = [r[0] for r in rs]
    worst = max(proc)
    print(f'{scene:28} {min(proc):6.4f}-{worst:6.4f} {max(r[1] for r in rs):10.4f} '
          f'{max(r[3] for r in rs):8.0f} {max(r[4] for r in rs) / 1e3:12.1f} {int(0.7 * cores / worst):20d}')
PY
