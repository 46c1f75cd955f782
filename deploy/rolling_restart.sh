#!/usr/bin/env bash
# A rolling restart of a whole site under load (docs/SCALING.md "Live migration"), every part a
# real process on loopback: PostgreSQL, a control replica, three simulation nodes and replaying
# trainee stations. Each node in turn gets SIGTERM (what a rolling update or a Kubernetes eviction
# sends): it moves its live sessions to the other nodes and exits; then it is started again under
# its name before the next one goes. The stations follow their sessions; at the end each stops its
# session and prints its summary.
# Prints what it measured and writes it as JSON to $OUT/rolling.json: sessions created (one per
# station if none was lost), aborted, trials recorded, the moves the nodes logged and the stations
# followed, reconnections, each drain's length, and the longest force gap any station had.
# Exits non-zero when a process does not start; the checks are the caller's
# (tests/e2e/cluster_test.cpp).
#
# Usage: deploy/rolling_restart.sh BIN_DIR OUT_DIR [STATIONS]   (STATIONS default 24)
set -euo pipefail
bin="$1"
out="$2"
stations="${3:-24}"
root="$(cd "$(dirname "$0")/.." && pwd)"
mkdir -p "$out"
source "$root/deploy/processes.sh"
vsurg_site_begin "PostgreSQL, a control replica"
head -c 32 /dev/urandom | base64 | tr -d '\n' > "$tmp/cluster-token"
admin_token="$("$bin/vsurg-server" init --db "$uri" 2>/dev/null)"
# A lease of 6 s, not 2: the test runs 24 stations, three nodes, a control replica and
# PostgreSQL on two cores (beside two CPU hogs in the hold-on-a-busy-machine runs), where a
# heartbeat may wait past 2 s to be answered; at 2 s the nodes lost their leases mid-restart and
# refused the sessions moved to them (docs/SCALING.md, --cluster-heartbeat-timeout).
lease=(--cluster-heartbeat-timeout 6)
"$bin/vsurg-server" --role control --db "$uri" --listen 127.0.0.1:0 --http 127.0.0.1:0 \
  --cluster-listen 127.0.0.1:0 --cluster-token-file "$tmp/cluster-token" "${lease[@]}" \
  --ready-file "$tmp/control.json" 2> "$out/control.log" &
pids+=("$!")
wait_file "$tmp/control.json"
server="127.0.0.1:$(port_of "$tmp/control.json" grpc_port)"
internal="127.0.0.1:$(port_of "$tmp/control.json" cluster_port)"

# Every node can take every station: while one drains, the other two take all of them.
declare -a sim_pid
start_node() {  # I: sim-I, its log appended to
  rm -f "$tmp/sim-$1.json"
  "$bin/vsurg-server" --role sim --db "$uri" --node-name "sim-$1" --control "$internal" \
    --cluster-token-file "$tmp/cluster-token" "${lease[@]}" --udp-port 0 --capacity "$stations" \
    --cases-ready 0 --ready-file "$tmp/sim-$1.json" 2>> "$out/sim-$1.log" &
  sim_pid[$1]=$!
  pids+=("${sim_pid[$1]}")
  wait_file "$tmp/sim-$1.json"
}
nodes_up() { psql_q "SELECT count(*) FROM nodes WHERE down = 0 AND draining = 0"; }
step "Three simulation nodes"
for i in 0 1 2; do start_node "$i"; done
for _ in $(seq 100); do [ "$(nodes_up)" = 3 ] && break; sleep 0.1; done

step "$stations trainees, each with a replaying headless station"
adm() { "$bin/vsurg-admin" "$@" --server "$server" --token "$admin_token"; }
"$bin/vsurg-sim" trainee --scene arm-torsion --style good --out "$tmp/twist.csv" > /dev/null
declare -a station_pid
for i in $(seq 0 $((stations - 1))); do
  token="$(adm user-add --name "trainee-$i" --role trainee --issue-token | tail -1)"
  nice -n 10 "$bin/vsurg-station" --server "$server" --token "$token" --scene arm-torsion --device replay \
    --trajectory "$tmp/twist.csv" --headless --width 64 --height 48 --fps 10 --duration 600 \
    --realtime-priority 0 --json > "$out/station-$i.json" 2> "$out/station-$i.log" &
  station_pid[$i]=$!
  pids+=("${station_pid[$i]}")
done
running() { psql_q "SELECT count(*) FROM sessions WHERE state = 'running'"; }
wait_all_running() {
  for _ in $(seq 600); do [ "$(running)" -ge "$stations" ] && return 0; sleep 0.1; done
  return 1
}
wait_all_running || echo "not every station runs" >&2
echo "running sessions per node: $(psql_q "SELECT node || '=' || count(*) FROM sessions WHERE state = 'running' GROUP BY node ORDER BY node" | tr '\n' ' ')"
sleep 2  # every trainee well into the task

drains=""
for i in 0 1 2; do
  step "Rolling restart: sim-$i gets SIGTERM, moves its sessions, exits; started again"
  had="$(psql_q "SELECT count(*) FROM sessions WHERE state IN ('created', 'running', 'stalled') AND node = 'sim-$i'")"
  t0="$(now_ms)"
  kill -TERM "${sim_pid[$i]}"
  wait "${sim_pid[$i]}" || true
  drain_ms=$(( $(now_ms) - t0 ))
  drains="$drains${drains:+,}$drain_ms"
  echo "sim-$i had $had live sessions; it drained and exited in $drain_ms ms"
  start_node "$i"
  for _ in $(seq 100); do [ "$(nodes_up)" = 3 ] && break; sleep 0.1; done
  wait_all_running || echo "not every station runs after sim-$i's restart" >&2
  echo "running sessions per node: $(psql_q "SELECT node || '=' || count(*) FROM sessions WHERE state = 'running' GROUP BY node ORDER BY node" | tr '\n' ' ')"
done
sleep 2  # the stations on their new nodes for a while

step "The stations finish (SIGINT: each stops its session and prints its summary)"
for i in $(seq 0 $((stations - 1))); do kill -INT "${station_pid[$i]}" 2>/dev/null || true; done
for i in $(seq 0 $((stations - 1))); do wait "${station_pid[$i]}" 2>/dev/null || true; done
sleep 1  # the last stops' records committed
sessions="$(psql_q "SELECT count(*) FROM sessions")"
# Aborted by the site, and abandoned: created for a station that had stopped waiting (it asked
# again), never started, aborted at once (docs/SCALING.md "Placement").
aborted="$(psql_q "SELECT count(*) FROM sessions WHERE state = 'aborted' AND end_reason NOT LIKE 'abandoned:%'")"
abandoned="$(psql_q "SELECT count(*) FROM sessions WHERE state = 'aborted' AND end_reason LIKE 'abandoned:%'")"
ended="$(psql_q "SELECT count(*) FROM sessions WHERE state = 'ended'")"
disconnected="$(psql_q "SELECT count(*) FROM sessions WHERE state = 'disconnected'")"
trial_twice="$(psql_q "SELECT count(*) FROM (SELECT session_id FROM trial_metrics GROUP BY session_id HAVING count(*) > 1) AS t")"
trials="$(psql_q "SELECT count(*) FROM trial_metrics")"
migrated="$(cat "$out"/sim-*.log | grep -c "event=session_migrated" || true)"
failed="$(cat "$out"/sim-*.log | grep -c "event=session_migration_failed" || true)"
read -r moves reconnects longest_gap_ms summaries < <(cat "$out"/station-*.json | /usr/bin/python3 -c '
import json, sys
rows = [json.loads(l) for l in sys.stdin if l.strip().startswith("{")]
print(sum(r["moves"] for r in rows), sum(r["reconnects"] for r in rows),
      round(max([r["longest_gap_ms"] for r in rows] or [-1])), len(rows))')
echo "sessions: $sessions ($ended ended, $disconnected disconnected, $aborted aborted, $abandoned abandoned), trials recorded: $trials ($trial_twice twice)"
echo "moves logged by the nodes: $migrated ($failed failed); followed by the stations: $moves; reconnections: $reconnects"
echo "drains (ms): $drains; the longest force gap at any station: $longest_gap_ms ms"

cat > "$out/rolling.json" <<EOF
{"stations": $stations, "summaries": $summaries, "sessions": $sessions, "ended": $ended,
 "disconnected": $disconnected, "aborted": $aborted, "abandoned": $abandoned, "trials": $trials, "trial_twice": $trial_twice, "migrated": $migrated, "migration_failed": $failed,
 "moves": $moves, "reconnects": $reconnects, "drain_ms": [$drains],
 "longest_gap_ms": $longest_gap_ms}
EOF
cat "$out/rolling.json"
