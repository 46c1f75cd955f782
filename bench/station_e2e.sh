#!/usr/bin/env bash
# The platform path end to end (vsurg-server + a headless vsurg-station rendering at 60 fps on the
# same machine): the station's round trip and its device loop's rate (over the run and the slowest
# and fastest whole second) with and without SCHED_FIFO haptic threads, alternating, 3 runs each (server and station restarted per setting).
# usage: [STYLE=good|hesitant|rough] bench/station_e2e.sh [BIN_DIR]
#   STYLE: the scripted trainee's trajectory (vsurg-sim trainee): good (default) lasts 7 s,
#   hesitant 14 s (the loop rate's goal is read over 10 s).
set -euo pipefail
B="$(cd "${1:-build/bin}" && pwd)"; d=$(mktemp -d); cd "$d"
$B/vsurg-server init --db vs.db > admin.out 2>/dev/null
$B/vsurg-sim trainee --scene arm-torsion --style "${STYLE:-good}" --out good.csv > /dev/null
for rep in 1 2 3; do for prio in 0 20; do
  $B/vsurg-server --db vs.db --listen 127.0.0.1:0 --udp-port 0 --ready-file ready.json --realtime-priority $prio 2>/dev/null & spid=$!
  for _ in $(seq 100); do [ -s ready.json ] && break; sleep 0.1; done
  PORT=$(python3 -c "import json;print(json.load(open('ready.json'))['grpc_port'])")
  [ -s t.tok ] || $B/vsurg-admin user-add --server 127.0.0.1:$PORT --token $(head -1 admin.out) --name ana --role trainee --issue-token | tail -1 > t.tok
  $B/vsurg-station --server 127.0.0.1:$PORT --token-file t.tok --trajectory good.csv --headless --realtime-priority $prio --json 2>/dev/null \
    | python3 -c "import json,sys; j=json.load(sys.stdin); print('priority=$prio rtt_p50_us=%.0f rtt_p99_us=%.0f loss=%.4f draw_ms_p50=%.1f frames=%d loop_hz=%.2f loop_hz_1s=%.1f..%.1f' % (j['rtt_p50_us'], j['rtt_p99_us'], j['loss'], j['draw_ms_p50'], j['frames'], j['loop_hz'], j['loop_hz_min_1s'], j['loop_hz_max_1s']))"
  kill $spid; wait $spid || true; rm -f ready.json
done; done
rm -rf $d
