#!/usr/bin/env bash
# The node's default capacity, run: as vsurg-server derives it (--capacity 0), 70% of this
# machine's cores at the dearest cost per station its scenes state, that many full-rate stations
# on the dearest scene (haptic-rtt, each hand circling 5 mm), beside the bare echo with the same
# stations (udp-floor), alternating ROUNDS (3) times. Prints each run's loss, p50 and p99, and the
# server's CPU: the capacity holds when the node loses no more than the echo does.
#   usage: [ROUNDS=3] [SECONDS_EACH=5] [SCENE=dearest] [STATIONS=derived] bench/capacity_check.sh [BIN_DIR]
set -euo pipefail
BIN=${1:-build/bin}
here="$(cd "$(dirname "$0")/.." && pwd)"
read -r dearest cost < <(python3 - "$here/scenes" <<'PY'
import glob, json, sys
best = ("", 0.0)
for f in glob.glob(sys.argv[1] + "/*.json"):
    c = json.load(open(f)).get("cost", {}).get("core_per_station", 0)
    if c > best[1]: best = (f.rsplit("/", 1)[1][:-5], c)
print(*best)
PY
)
cores=$(nproc)
scene=${SCENE:-$dearest}
stations=${STATIONS:-$(python3 -c "import math; print(max(1, math.floor(0.7 * $cores / $cost)))")}
echo "capacity $stations: 70% of $cores cores at $dearest's $cost core per station; driving $scene"
for r in $(seq "${ROUNDS:-3}"); do
  floor=$("$BIN/vsurg-bench" udp-floor --stations "$stations" --seconds "${SECONDS_EACH:-5}" --json)
  node=$("$BIN/vsurg-bench" haptic-rtt --scene "$scene" --stations "$stations" \
           --seconds "${SECONDS_EACH:-5}" --stroke-mm 5 --json)
  python3 - "$r" "$floor" "$node" <<'PY'
import json, sys
f, n = json.loads(sys.argv[2]), json.loads(sys.argv[3])
print(f"round={sys.argv[1]} echo: loss={f['loss']:.4f} p50={f['rtt_p50_us']:.0f}us p99={f['rtt_p99_us']:.0f}us | "
      f"node: loss={n['loss']:.4f} p50={n['rtt_p50_us']:.0f}us p99={n['rtt_p99_us']:.0f}us "
      f"cpu={n['server_process_cpu_per_station'] * n['stations'] if 'stations' in n else n['server_process_cpu_per_station']:.3f}")
PY
done
