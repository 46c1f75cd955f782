#!/usr/bin/env bash
# One site on this machine, every part a real process on loopback (DESIGN.md "Beyond one
# machine", docs/SCALING.md): PostgreSQL, two control replicas, three simulation nodes and
# replaying trainee stations. Then the failures a site must survive:
#   1. every session placed, spread over the nodes within one session of each other;
#   2. SIGKILL one simulation node: its stations are back on other nodes (force faded by their
#      watchdog meanwhile, never above the device limit), timed from the kill;
#   3. SIGKILL one control replica during a burst of evaluation submissions: every acknowledged
#      submission is in PostgreSQL;
#   4. the surviving control plane still lists every live session (vsurg-monitor) and the
#      dashboard's API too.
# Before 2 and 3, two chaos steps (the fencing of docs/SCALING.md):
#   a. SIGSTOP sim-1 past its lease and the control plane's timeout, then SIGCONT: its stations
#      are back on other nodes; the resumed node answers none of them, writes none of its old
#      sessions (they stay aborted, with no trial recorded) and takes its name again; no trainee
#      ever has two live sessions;
#   b. a second process started under sim-2's name is refused with a clear error and takes
#      nothing from sim-2; so is one whose certificate names another node.
# The internal API runs mutual TLS (certificates from deploy/cluster_certs.sh).
# Prints what it measured, and writes it as JSON to $OUT/cluster.json. Exits non-zero when a
# process does not start; the checks are the caller's (tests/e2e/cluster_test.cpp; deploy/demo.sh
# prints them).
#
# Usage: deploy/cluster_flow.sh BIN_DIR OUT_DIR [STATIONS]   (STATIONS default 24)
set -euo pipefail
bin="$1"
out="$2"
stations="${3:-24}"
root="$(cd "$(dirname "$0")/.." && pwd)"
mkdir -p "$out"
source "$root/deploy/processes.sh"
vsurg_site_begin "PostgreSQL on loopback"
head -c 32 /dev/urandom | base64 | tr -d '\n' > "$tmp/cluster-token"
head -c 32 /dev/urandom | base64 | tr -d '\n' > "$tmp/metrics-token"  # Prometheus': the scrape only
# The internal API with mutual TLS (docs/SCALING.md): a site CA, the control replicas' certificate
# and one per node; sim-rogue's is the site's too, but names another node.
"$root/deploy/cluster_certs.sh" "$tmp/pki" vsurg-control sim-0 sim-1 sim-2 sim-rogue
tls_as() { echo "--cluster-tls-cert $tmp/pki/$1.pem --cluster-tls-key $tmp/pki/$1.key --cluster-tls-ca $tmp/pki/ca.pem"; }
admin_token="$("$bin/vsurg-server" init --db "$uri" 2>/dev/null)"

step "Two control replicas (gRPC, HTTP, the nodes' registry)"
declare -a control_pid
for i in 0 1; do
  "$bin/vsurg-server" --role control --db "$uri" --listen 127.0.0.1:0 --http 127.0.0.1:0 \
    --cluster-listen 127.0.0.1:0 --cluster-token-file "$tmp/cluster-token" $(tls_as vsurg-control) \
    --ready-file "$tmp/control-$i.json" 2> "$out/control-$i.log" &
  control_pid[$i]=$!
  pids+=("${control_pid[$i]}")
done
for i in 0 1; do wait_file "$tmp/control-$i.json"; done
grpc0="127.0.0.1:$(port_of "$tmp/control-0.json" grpc_port)"
grpc1="127.0.0.1:$(port_of "$tmp/control-1.json" grpc_port)"
http1="127.0.0.1:$(port_of "$tmp/control-1.json" http_port)"
servers="$grpc0,$grpc1"  # clients fail over between the replicas
internal="127.0.0.1:$(port_of "$tmp/control-0.json" cluster_port),127.0.0.1:$(port_of "$tmp/control-1.json" cluster_port)"
echo "control: gRPC $servers, internal $internal"

step "Three simulation nodes"
declare -a sim_pid
capacity=$(( (stations + 2) / 3 + 8 ))
# --cases-ready 0: this flow's stations press the arm; no node builds palpation cases ahead.
for i in 0 1 2; do
  "$bin/vsurg-server" --role sim --db "$uri" --node-name "sim-$i" --control "$internal" \
    --cluster-token-file "$tmp/cluster-token" $(tls_as "sim-$i") --udp-port 0 --capacity "$capacity" \
    --cases-ready 0 \
    --http 127.0.0.1:0 --metrics-token-file "$tmp/metrics-token" $([ "$i" = 2 ] && echo --log-format json) \
    --ready-file "$tmp/sim-$i.json" 2> "$out/sim-$i.log" &
  sim_pid[$i]=$!
  pids+=("${sim_pid[$i]}")
done
for i in 0 1 2; do wait_file "$tmp/sim-$i.json"; done
for _ in $(seq 100); do
  [ "$(psql_q "SELECT count(*) FROM nodes WHERE down = 0")" = 3 ] && break
  sleep 0.1
done
psql -q "$uri" -c "SELECT name, grpc_address, udp_port, capacity FROM nodes ORDER BY name"

# At a site each station has its own computer; here the 24 share the two cores with the site's
# servers, so they run at normal policy and nice 19: their SCHED_FIFO haptic threads would take
# the cores from the nodes' heartbeats and the control plane (a node starved for 2 s is declared
# down), and at equal priority their 24 loops would slow every node's scene build and every
# control-plane call tenfold, which no real site does to its servers. At nice 10 their ~170
# threads still took 93% of a core beside two CPU hogs and PostgreSQL's commits took 0.3-1.3 s
# (docs/BENCHMARKS.md, "A killed node's stations beside two CPU hogs"); at nice 19, 34%.
step "$stations trainees, each with a replaying headless station"
adm() { "$bin/vsurg-admin" "$@" --server "$servers" --token "$admin_token"; }
"$bin/vsurg-sim" trainee --scene arm-torsion --style good --out "$tmp/twist.csv" > /dev/null
declare -a station_pid
for i in $(seq 0 $((stations - 1))); do
  token="$(adm user-add --name "trainee-$i" --role trainee --group group-a --issue-token | tail -1)"
  nice -n 19 "$bin/vsurg-station" --server "$servers" --token "$token" --scene arm-torsion --device replay \
    --trajectory "$tmp/twist.csv" --headless --width 64 --height 48 --fps 10 --duration 600 \
    --realtime-priority 0 --json > "$out/station-$i.json" 2> "$out/station-$i.log" &
  station_pid[$i]=$!
  pids+=("${station_pid[$i]}")
done
running() { psql_q "SELECT count(*) FROM sessions WHERE state = 'running'"; }
for _ in $(seq 300); do [ "$(running)" -ge "$stations" ] && break; sleep 0.1; done
# The placement, by live session: a station at nice 19 beside the others may miss 0.5 s of
# samples under load, and its session reads stalled a moment (still placed, still served).
spread="$(psql_q "SELECT node || '=' || count(*) FROM sessions WHERE state IN ('running', 'stalled') GROUP BY node ORDER BY node" | tr '\n' ' ')"
echo "live sessions per node: $spread"

# The most live sessions any one trainee has, now.
max_live_per_trainee() {
  psql_q "SELECT coalesce(max(c), 0) FROM (SELECT trainee_id, count(*) AS c FROM sessions
          WHERE state IN ('created', 'running', 'stalled') GROUP BY trainee_id) AS live"
}
wait_all_running() {
  for _ in $(seq 300); do [ "$(running)" -ge "$stations" ] && return 0; sleep 0.1; done
  return 1
}

step "Chaos: sim-1 frozen past its lease (SIGSTOP 3.5 s), then resumed"
# Live, running or stalled (a loaded machine stalls a session whose station was briefly silent):
# every one of them is lost with the node and its station comes back.
frozen_ids="$(psql_q "SELECT string_agg(id::text, ',') FROM sessions WHERE state IN ('running', 'stalled') AND node = 'sim-1'")"
frozen_victims="$(psql_q "SELECT count(*) FROM sessions WHERE state IN ('running', 'stalled') AND node = 'sim-1'")"
kill -STOP "${sim_pid[1]}"
stopped_at="$(now_ms)"
max_live=0
while [ $(( $(now_ms) - stopped_at )) -lt 3500 ]; do
  m="$(max_live_per_trainee)"; [ "$m" -gt "$max_live" ] && max_live="$m"
  sleep 0.2
done
kill -CONT "${sim_pid[1]}"
resumed_at="$(now_ms)"
wait_all_running || echo "not every station runs again after the freeze" >&2
# Watch for 3 s after the resume: a node that came back must not bring its old sessions back.
while [ $(( $(now_ms) - resumed_at )) -lt 3000 ]; do
  m="$(max_live_per_trainee)"; [ "$m" -gt "$max_live" ] && max_live="$m"
  sleep 0.2
done
frozen_not_aborted="$(psql_q "SELECT count(*) FROM sessions WHERE id IN (${frozen_ids:-0}) AND state <> 'aborted'")"
frozen_trials="$(psql_q "SELECT count(*) FROM trial_metrics WHERE session_id IN (${frozen_ids:-0})")"
for _ in $(seq 50); do grep -q "event=lease_acquired node=sim-1 epoch=2" "$out/sim-1.log" && break; sleep 0.1; done
lease_lost="$(grep -c "event=lease_lost" "$out/sim-1.log" || true)"
reacquired="$(grep -c "event=lease_acquired node=sim-1 epoch=2" "$out/sim-1.log" || true)"
echo "sim-1 had $frozen_victims sessions; after the resume $frozen_not_aborted of them are not aborted, $frozen_trials have a trial recorded"
echo "sim-1's log: lease_lost $lease_lost time(s), took its name again at epoch 2: $reacquired"
echo "most live sessions of one trainee during and after the freeze: $max_live"

step "Chaos: a second process under sim-2's name"
sim2_running="$(psql_q "SELECT count(*) FROM sessions WHERE state = 'running' AND node = 'sim-2'")"
# Its sessions by id: stations re-placed from the frozen node may still arrive on sim-2
# meanwhile, so what must hold is that every one of these is still running there afterwards.
sim2_ids="$(psql_q "SELECT string_agg(id::text, ',') FROM sessions WHERE state = 'running' AND node = 'sim-2'")"
sim2_address="$(psql_q "SELECT grpc_address FROM nodes WHERE name = 'sim-2'")"
twin_rc=0
timeout 30 "$bin/vsurg-server" --role sim --db "$uri" --node-name sim-2 --control "$internal" \
  --cluster-token-file "$tmp/cluster-token" $(tls_as sim-2) --udp-port 0 --capacity "$capacity" \
  --cases-ready 0 --ready-file "$tmp/sim-twin.json" 2> "$out/sim-twin.log" || twin_rc=$?
twin_refused="$(grep -c "held by another live process" "$out/sim-twin.log" || true)"
# And a process with the token and a site certificate that names another node: refused at once.
rogue_rc=0
timeout 30 "$bin/vsurg-server" --role sim --db "$uri" --node-name sim-2 --control "$internal" \
  --cluster-token-file "$tmp/cluster-token" $(tls_as sim-rogue) --udp-port 0 --capacity "$capacity" \
  --cases-ready 0 --ready-file "$tmp/sim-rogue.json" 2> "$out/sim-rogue.log" || rogue_rc=$?
rogue_refused="$(grep -c "certificate names sim-rogue, not node sim-2" "$out/sim-rogue.log" || true)"
echo "a certificate for sim-rogue claiming sim-2: exit $rogue_rc: $(tail -1 "$out/sim-rogue.log")"
sleep 1  # a heartbeat of sim-2 after the twin's attempts
sim2_running_after="$(psql_q "SELECT count(*) FROM sessions WHERE state = 'running' AND node = 'sim-2'")"
sim2_kept="$(psql_q "SELECT count(*) FROM sessions WHERE state = 'running' AND node = 'sim-2' AND id IN (${sim2_ids:-0})")"
sim2_address_after="$(psql_q "SELECT grpc_address FROM nodes WHERE name = 'sim-2' AND down = 0")"
m="$(max_live_per_trainee)"; [ "$m" -gt "$max_live" ] && max_live="$m"
echo "the twin exited with $twin_rc: $(tail -1 "$out/sim-twin.log")"
echo "sim-2 ran $sim2_running sessions before, $sim2_running_after after ($sim2_kept of the first still there); its address $sim2_address, after $sim2_address_after"
twin_kept=$([ "$sim2_kept" = "$sim2_running" ] && [ "$sim2_address" = "$sim2_address_after" ] && echo 1 || echo 0)

step "SIGKILL sim-0: its stations come back on the other nodes"
victims="$(psql_q "SELECT count(*) FROM sessions WHERE state IN ('running', 'stalled') AND node = 'sim-0'")"
kill -KILL "${sim_pid[0]}"
killed_at="$(now_ms)"
# Wait until every station runs again, then read when each new session started from the
# sessions' own rows (polling psql here would add its own latency to the figure).
for _ in $(seq 300); do
  [ "$(psql_q "SELECT count(*) FROM sessions WHERE state = 'running' AND node <> 'sim-0'")" -ge "$stations" ] && break
  sleep 0.05
done
back_ms="$(psql_q "SELECT coalesce(max(started_us) / 1000 - $killed_at, -1) FROM sessions WHERE created_us / 1000 > $killed_at AND state = 'running'")"
moved="$(psql_q "SELECT count(*) FROM sessions WHERE created_us / 1000 > $killed_at AND state = 'running' AND node <> 'sim-0'")"
aborted="$(psql_q "SELECT count(*) FROM sessions WHERE node = 'sim-0' AND state = 'aborted'")"
echo "the new sessions, ms after the kill (created, started): $(psql_q "SELECT string_agg((created_us / 1000 - $killed_at) || '/' || (started_us / 1000 - $killed_at), ' ' ORDER BY id) FROM sessions WHERE created_us / 1000 > $killed_at")"
echo "sim-0 had $victims sessions; aborted $aborted; the last of them started again on another node ${back_ms} ms after the kill"
spread_after="$(psql_q "SELECT node || '=' || count(*) FROM sessions WHERE state IN ('running', 'stalled') GROUP BY node ORDER BY node" | tr '\n' ' ')"
echo "live sessions per node: $spread_after"

step "SIGKILL control-0 during a burst of evaluation submissions"
evaluator_token="$(adm user-add --name dr-burst --role evaluator --group chief --issue-token | tail -1)"
{
  echo "evaluator_id,group,i1,i2,i3,i4,i5,i6,i7,i8,i9,subject"
  for i in $(seq 1 400); do echo "dr-burst,chief,8,7,9,8,7,8,9,6,7,model-$i"; done
} > "$tmp/burst.csv"
import() {
  "$bin/vsurg-admin" import --server "$servers" --token "$evaluator_token" \
    --input "$tmp/burst.csv" --subject-kind model --timeout 5 > "$1" 2>&1
}
import "$out/burst-1.log" &
burst_pid=$!
sleep 0.4
kill -KILL "${control_pid[0]}"
wait "$burst_pid" || true
# Acknowledged: the rows the client was told were stored. Each must be in PostgreSQL.
sed -n 's/.* on \(model-[0-9]*\)): stored$/\1/p' "$out/burst-1.log" | sort > "$tmp/acked"
psql_q "SELECT subject FROM submissions WHERE subject LIKE 'model-%'" | sort > "$tmp/in-db"
acked="$(wc -l < "$tmp/acked")"
acked_missing="$(comm -23 "$tmp/acked" "$tmp/in-db" | wc -l)"
echo "acknowledged before and around the kill: $acked; missing from PostgreSQL: $acked_missing"
tail -2 "$out/burst-1.log"
# The client retries against the other replica: the same import again stores the rest, and
# stores nothing twice (idempotency keys).
import "$out/burst-2.log" || true
tail -1 "$out/burst-2.log"
stored="$(psql_q "SELECT count(*) FROM submissions WHERE subject LIKE 'model-%'")"
echo "submissions in PostgreSQL after the retry: $stored of 400"

step "The surviving control plane still shows every live session"
monitor_token="$(adm user-add --name ivo --role instructor --issue-token | tail -1)"
listed="$("$bin/vsurg-monitor" list --server "$grpc1" --token "$monitor_token" | grep -c $'\trunning\t' || true)"
echo "vsurg-monitor list via control-1: $listed running"
dashboard="$(/usr/bin/python3 -c '
import sys, urllib.request
r = urllib.request.Request(sys.argv[1], headers={"Authorization": "Bearer " + sys.argv[2]})
print(urllib.request.urlopen(r, timeout=10).read().decode())' \
  "http://$http1/api/v1/sessions?live=1" "$monitor_token" || true)"
dashboard_live="$(grep -o '"state":"running"' <<< "$dashboard" | wc -l)"
echo "dashboard API via control-1: $dashboard_live running"

step "Metrics on every role (Prometheus text, parsed by prometheus_client)"
# Late in the run (a scrape makes a control replica poll the nodes' telemetry from then on, as
# for a monitor): a node's scrape with the metrics token (on a node nothing else is served, and that token reads
# nothing else), a control replica's with an administrator's.
metrics_check() {  # ROLE HOST:PORT TOKEN: the series' names go to $tmp/series-ROLE
  /usr/bin/python3 - "$1" "$2" "$3" "$tmp/series-$1" <<'PY'
import sys, urllib.request, urllib.error
from prometheus_client.parser import text_string_to_metric_families
role, address, token, names = sys.argv[1:]
def get(path):
    req = urllib.request.Request(f"http://{address}{path}", headers={"Authorization": f"Bearer {token}"})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, r.read().decode()
    except urllib.error.HTTPError as e:
        return e.code, ""
status, text = get("/api/v1/metrics")
values, families = {}, set()
for family in text_string_to_metric_families(text):
    families |= {family.name, family.name + "_total"}  # the parser drops a counter's _total
    for sample in family.samples:
        values[sample.name] = values.get(sample.name, 0) + sample.value
open(names, "w").write("\n".join(sorted(set(values) | families)) + "\n")
want = {"sim": ["vsurg_lease_held", "vsurg_lease_seconds_left", "vsurg_udp_forces_sent_total",
                "vsurg_store_commit_seconds_count", "vsurg_heartbeats_total"],
        "control": ["vsurg_placements_total", "vsurg_nodes", "vsurg_node_lease_age_seconds",
                    "vsurg_store_commit_seconds_count"]}[role]
missing = [n for n in want if n not in values and n not in families]
moving = role == "control" or (values.get("vsurg_lease_held") == 1 and
                                values.get("vsurg_udp_forces_sent_total", 0) > 0 and
                                values.get("vsurg_lease_seconds_left", 0) > 0)
other = get("/api/v1/sessions")[0] if role == "sim" else 404
print(f"{role} {address}: {status}, {len(values)} series, missing {missing}, "
      f"placements {values.get('vsurg_placements_total', 0):.0f}, "
      f"forces {values.get('vsurg_udp_forces_sent_total', 0):.0f}, other route {other}")
sys.exit(0 if status == 200 and not missing and moving and other == 404 else 1)
PY
}
metrics_ok=1
metrics_check sim "127.0.0.1:$(port_of "$tmp/sim-1.json" http_port)" "$(cat "$tmp/metrics-token")" || metrics_ok=0
metrics_check control "$http1" "$admin_token" || metrics_ok=0
# The Grafana dashboard's "Site:" panels read series these two roles serve.
/usr/bin/python3 - "$root/deploy/grafana/vsurg.json" "$tmp/series-sim" "$tmp/series-control" <<'PY' || metrics_ok=0
import json, re, sys
served = set(open(sys.argv[2]).read().split()) | set(open(sys.argv[3]).read().split())
panels = [p for p in json.load(open(sys.argv[1]))["panels"] if p["title"].startswith("Site:")]
asked = {re.sub(r"_(bucket|sum|count)$", "", m) for p in panels for t in p["targets"]
         for m in re.findall(r"vsurg_[a-z_]+", t["expr"])}
served |= {re.sub(r"_(bucket|sum|count)$", "", m) for m in served}
missing = sorted(asked - served)
print(f"Grafana's site panels: {len(panels)}, {len(asked)} series, missing {missing}")
sys.exit(1 if missing or not panels else 0)
PY

step "The stations finish (SIGINT: each stops its session and prints its summary)"
for i in $(seq 0 $((stations - 1))); do kill -INT "${station_pid[$i]}" 2>/dev/null || true; done
for i in $(seq 0 $((stations - 1))); do wait "${station_pid[$i]}" 2>/dev/null || true; done
# Per station: did it reconnect, did its force fade meanwhile, the largest force it sent.
# Why each station gave a session up: it was aborted (its node lost), or the control plane did
# not answer for give_up_s (a loaded machine), or something else.
read -r reconnected faded max_force reconnects drops_aborted drops_unanswered drops_other < <(
  cat "$out"/station-*.json | /usr/bin/python3 -c '
import json, sys
rows = [json.loads(l) for l in sys.stdin if l.strip().startswith("{")]
back = [r for r in rows if r["reconnects"] > 0]
drops = [d for r in rows for d in r.get("drops", [])]
aborted = sum(1 for d in drops if d.endswith(" is aborted"))
unanswered = sum(1 for d in drops if d.startswith("the server does not answer"))
for d in drops: print(d, file=sys.stderr)
print(len(back), sum(1 for r in back if r["watchdog_fades"] > 0),
      repr(max([r["max_force_n"] for r in rows] or [0])), sum(r["reconnects"] for r in rows),
      aborted, unanswered, len(drops) - aborted - unanswered)' 2> "$out/drops.txt")
echo "stations reconnected: $reconnected ($reconnects reconnections; force faded meanwhile: $faded); largest force sent: $max_force N"
echo "sessions given up: $drops_aborted aborted, $drops_unanswered unanswered, $drops_other otherwise ($out/drops.txt)"

step "sim-2 logged JSON lines (--log-format json), each about a session carrying its id"
sleep 1  # the stations' last stops reach the node
json_log_ok=0
/usr/bin/python3 - "$out/sim-2.log" <<'PY' && json_log_ok=1
import json, sys
events, bad, sessionless, ended = 0, [], [], 0
for line in open(sys.argv[1], encoding="utf-8"):
    if line.startswith("ts="):
        bad.append(line)  # a logfmt line from a process told to write JSON
    if not line.startswith("{"):
        continue  # gRPC's own diagnostics have their own format
    try:
        e = json.loads(line)
    except ValueError:
        bad.append(line)
        continue
    events += 1
    if e["event"].startswith("session_") and not isinstance(e.get("session"), int):
        sessionless.append(line)
    ended += e["event"] == "session_ended"
print(f"{events} JSON events, {ended} session_ended, {len(bad)} not JSON, {len(sessionless)} about a session without its id")
sys.exit(0 if events and ended and not bad and not sessionless else 1)
PY

cat > "$out/cluster.json" <<EOF
{"stations": $stations, "spread": "$spread", "victims": $victims, "aborted": $aborted,
 "moved": $moved, "back_ms": $back_ms, "spread_after": "$spread_after", "acked": $acked,
 "acked_missing": $acked_missing, "stored": $stored,
 "monitor_running": $listed, "dashboard_running": $dashboard_live,
 "reconnected": $reconnected, "reconnected_faded": $faded, "max_force_n": $max_force,
 "reconnects": $reconnects, "drops_aborted": $drops_aborted,
 "drops_unanswered": $drops_unanswered, "drops_other": $drops_other,
 "frozen_victims": $frozen_victims, "frozen_not_aborted": $frozen_not_aborted,
 "frozen_trials": $frozen_trials, "lease_lost": $lease_lost, "reacquired": $reacquired,
 "max_live_per_trainee": $max_live, "twin_rc": $twin_rc, "twin_refused": $twin_refused,
 "twin_kept": $twin_kept, "rogue_rc": $rogue_rc, "rogue_refused": $rogue_refused,
 "metrics_ok": $metrics_ok, "json_log_ok": $json_log_ok}
EOF
cat "$out/cluster.json"
