#!/usr/bin/env bash
# The platform end to end, as its three kinds of users touch it (stations, monitor, admin):
#   an administrator starts vsurg-server on a temporary SQLite file and creates the users;
#   a trainee's station (headless, a replayed stylus) twists the forearm 45 degrees over UDP;
#   an instructor's monitor follows the session live (text, and an OpenGL view);
#   the instructor's own station joins a second trial and guides it (four-handed training);
#   a scripted novice searches a pad for hidden lumps drawn for the attempt (palpation);
#   three evaluators (intern, associate chief, chief) score the session with their own tokens;
#   the administrator prints the weighted report (the coil-spring paper eq. 9-11) and the trial metrics and
#   exports the evaluations as CSV.
# Screenshots of the station before and after the twist, of the monitor, and of the search's
# summary go to SHOTS_DIR.
# Exits 0 when every step worked, and leaves no process behind.
#
# usage: deploy/demo_flow.sh BIN_DIR OUT_DIR [SHOTS_DIR]   (deploy/demo.sh and the e2e test run it)
set -euo pipefail
bin="$(cd "${1:?BIN_DIR}" && pwd)"
out="${2:?OUT_DIR}"
shots="${3:-$out}"
mkdir -p "$out" "$shots"
out="$(cd "$out" && pwd)"
shots="$(cd "$shots" && pwd)"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export VSURG_SCENES="$root/scenes"

source "$root/deploy/processes.sh"
vsurg_temp_and_cleanup

step "Administrator: vsurg-server on a temporary SQLite file, with the web dashboard"
vsurg_start_server "$bin" "$out/server.log" --http 127.0.0.1:0
http_port="$(sed -n 's/.*"http_port":\([0-9]*\).*/\1/p' "$tmp/ready.json")"
echo "vsurg-server pid $server_pid serving gRPC on $server"
echo "web dashboard: http://127.0.0.1:$http_port/ (sign in with a user's token)"
# The dashboard answers (bash's /dev/tcp: no HTTP client needed): the sign-in page.
exec 3<>"/dev/tcp/127.0.0.1/$http_port"
printf 'GET /signin HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n' >&3
status="$(head -1 <&3 | tr -d '\r')"
exec 3<&-
[ "$status" = "HTTP/1.1 200 OK" ] || { echo "demo: the dashboard answered '$status'" >&2; exit 1; }
echo "the dashboard's sign-in page: $status"
adm() { "$bin/vsurg-admin" "$@" --server "$server" --token "$admin_token"; }
token_of() { adm user-add --name "$1" --role "$2" ${3:+--group "$3"} --issue-token | tail -1; }
trainee_token="$(token_of tia trainee group-a)"
instructor_token="$(token_of ivo instructor)"
intern_token="$(token_of dr-intern evaluator intern)"
associate_token="$(token_of dr-associate evaluator associate_chief)"
chief_token="$(token_of dr-chief evaluator chief)"
adm users
adm scenes

step "Trainee: a scripted, smooth 45-degree twist of the forearm (replay device)"
"$bin/vsurg-sim" trainee --scene arm-torsion --style good --out "$out/twist-good.csv"

step "Instructor: vsurg-monitor follows the first live session (text, 2 lines/s)"
"$bin/vsurg-monitor" follow --server "$server" --token "$instructor_token" --text --print-hz 2 \
  --wait 60 > "$out/monitor.log" 2>&1 &
monitor_pid=$!
pids+=("$monitor_pid")
"$bin/vsurg-monitor" follow --server "$server" --token "$instructor_token" --headless \
  --width 960 --height 600 --wait 60 --duration 5 --screenshot "$shots/monitor-view.png" \
  > "$out/monitor-view.log" 2>&1 &
monitor_view_pid=$!
pids+=("$monitor_view_pid")

step "Station: vsurg-station, headless, the twist over UDP at 1 kHz"
"$bin/vsurg-station" --server "$server" --token "$trainee_token" --scene arm-torsion \
  --device replay --trajectory "$out/twist-good.csv" --headless --width 960 --height 600 \
  --screenshot-before "$shots/station-before.png" --screenshot "$shots/station-twisted.png" \
  --screenshot-at 4.5 --json > "$out/station.json" 2> "$out/station.log"
cat "$out/station.log"
cat "$out/station.json"
session="$(sed -n 's/.*"session":\([0-9]*\).*/\1/p' "$out/station.json")"
[ -n "$session" ] || { echo "demo: the station reported no session" >&2; exit 1; }

wait "$monitor_pid"
wait "$monitor_view_pid"
echo "-- the instructor's terminal (every line: twist, torque, force, round trip, loss, rate, score)"
cat "$out/monitor.log"

step "Four hands: the instructor's station joins a second trial and guides it (observe, guide, take over, hand back)"
"$bin/vsurg-station" --server "$server" --token "$trainee_token" --scene arm-torsion \
  --device replay --trajectory "$out/twist-good.csv" --headless --width 320 --height 200 \
  --settle 4 --json > "$out/station-guided.json" 2> "$out/station-guided.log" &
guided_pid=$!
pids+=("$guided_pid")
guided=""
for _ in $(seq 300); do
  guided="$(sed -n 's/.*event=state state=live session=\([0-9]*\).*/\1/p' "$out/station-guided.log" | head -1)"
  [ -n "$guided" ] && break
  sleep 0.1
done
[ -n "$guided" ] || { echo "demo: the trainee's second station never went live" >&2; exit 1; }
"$bin/vsurg-station" --server "$server" --token "$instructor_token" --instruct "$guided" \
  --scene arm-torsion --device replay --trajectory "$out/twist-good.csv" --headless \
  --width 320 --height 200 --settle 600 --duration 6 --guide-plan "1:guide:0.5,3:guide:1,4.5:guide:0" \
  --json > "$out/station-instructor.json" 2> "$out/station-instructor.log"
wait "$guided_pid"
echo "the instructor's station: $(cat "$out/station-instructor.json")"
share="$(sed -n 's/.*"guided_share":\([0-9.e-]*\).*/\1/p' "$out/station-guided.json")"
echo "session $guided, the trainee's record: guided share $share"
[ -n "$share" ] && [ "$share" != 0 ] || { echo "demo: the guided trial records no guidance" >&2; exit 1; }

step "Palpation: a scripted novice searches a pad for the lumps drawn for this attempt (search device)"
# The lumps are drawn for the session from a random seed; the station never shows them, and the
# score and what the search found come at the end (the dashboard's replay shows where they were).
# Its session waits for its case's table (built ahead at nice 10: about 7 s of a core, a minute on
# a busy machine), hence the longer --connect-timeout.
"$bin/vsurg-station" --server "$server" --token "$trainee_token" --scene lump-search \
  --device search --search-style novice --headless --width 960 --height 600 --connect-timeout 120 \
  --screenshot-summary "$shots/station-palpation-novice.png" --json \
  > "$out/station-palpation.json" 2> "$out/station-palpation.log"
lumps="$(sed -n 's/.*"lumps":\([0-9]*\).*/\1/p' "$out/station-palpation.json")"
found="$(sed -n 's/.*"lumps_found":\([0-9]*\).*/\1/p' "$out/station-palpation.json")"
coverage="$(sed -n 's/.*"coverage":\([0-9.e-]*\).*/\1/p' "$out/station-palpation.json")"
echo "the novice's search: $found of $lumps lumps found, $coverage of the pad examined"
[ -n "$lumps" ] && [ -n "$coverage" ] || { echo "demo: the search was not scored" >&2; exit 1; }

step "Needle insertion: a scripted hesitant trainee reaches the vein (the station renders the pops)"
# It aims wide first, misses, draws out and enters again above the vein; the station feels each
# layer give way from its own copy of the needle model, the server scores where the tip went.
"$bin/vsurg-sim" trainee --scene needle-vessel --style hesitant --out "$tmp/needle.csv" > /dev/null
"$bin/vsurg-station" --server "$server" --token "$trainee_token" --scene needle-vessel \
  --trajectory "$tmp/needle.csv" --headless --width 960 --height 600 \
  --screenshot-summary "$shots/station-needle-hesitant.png" --json \
  > "$out/station-needle.json" 2> "$out/station-needle.log"
punctures="$(sed -n 's/.*"punctures":\([0-9]*\).*/\1/p' "$out/station-needle.json")"
depth_error="$(sed -n 's/.*"depth_error":\([0-9.e-]*\).*/\1/p' "$out/station-needle.json")"
echo "the hesitant insertion: $punctures punctures, the tip placed $depth_error m from the vein's middle"
[ -n "$punctures" ] && [ "$punctures" -ge 4 ] || { echo "demo: the insertion was not scored" >&2; exit 1; }

step "Pattern cutting with both hands: the blade from a recording, the scene's grasper on a second device"
# The station drives two devices on two channels into one session: the right hand's blade cuts
# the marked circle while the left hand's grasper lifts the piece for counter-traction and feels
# its pull; the piece comes free when the circle closes.
"$bin/vsurg-sim" trainee --scene pattern-cut --style good --out "$tmp/cut.csv" > /dev/null
"$bin/vsurg-station" --server "$server" --token "$trainee_token" --scene pattern-cut \
  --trajectory "$tmp/cut.csv" --second-device grasper --headless --width 960 --height 600 \
  --screenshot-at 9 --screenshot "$shots/station-cut-two-hands.png" --json \
  > "$out/station-cut.json" 2> "$out/station-cut.log"
coverage="$(sed -n 's/.*"coverage":\([0-9.e-]*\).*/\1/p' "$out/station-cut.json")"
grasp="$(sed -n 's/.*"second_hand":{[^}]*"max_force_n":\([0-9.e-]*\).*/\1/p' "$out/station-cut.json")"
echo "the cut: $coverage of the circle cut, the grasper's peak pull $grasp N"
[ -n "$coverage" ] && [ -n "$grasp" ] || { echo "demo: the two-handed cut was not scored" >&2; exit 1; }

step "Evaluators: three groups score session $session (9 indexes, 0-10), each with their own token"
header="evaluator_id,group,i1,i2,i3,i4,i5,i6,i7,i8,i9"
printf '%s\ndr-intern,intern,8,8.5,9,8.5,8,7.5,8,7,6.5\n' "$header" > "$tmp/intern.csv"
printf '%s\ndr-associate,associate_chief,8.5,8,9,9,8,8,8.5,7.5,7\n' "$header" > "$tmp/associate.csv"
printf '%s\ndr-chief,chief,9,8.5,9.5,9,8.5,8,8,7.5,7\n' "$header" > "$tmp/chief.csv"
"$bin/vsurg-admin" import --server "$server" --token "$intern_token" --input "$tmp/intern.csv" \
  --subject-kind session --subject "$session"
"$bin/vsurg-admin" import --server "$server" --token "$associate_token" \
  --input "$tmp/associate.csv" --subject-kind session --subject "$session"
"$bin/vsurg-admin" import --server "$server" --token "$chief_token" --input "$tmp/chief.csv" \
  --subject-kind session --subject "$session"

step "Administrator: the weighted report of session $session (the coil-spring paper eq. 9-11)"
adm report --subject-kind session --subjects "$session"
step "Administrator: the scoring loop's trial metrics"
adm sessions
step "Administrator: the simulator models compared by 120 raters (synthetic sample ratings)"
adm import --input "$root/deploy/samples/ratings-three-models.csv" --subject-kind model --quiet
adm report --subject-kind model --subjects coil-spring,mass-spring,fem
step "Administrator: export of every evaluation as CSV"
adm export --format csv --out "$out/scores.csv"
echo "-- first rows of $out/scores.csv"
head -4 "$out/scores.csv"

step "Administrator: a copy of the store for the dashboard after the demo (vsurg-server backup)"
"$bin/vsurg-server" backup --db "$tmp/vsurg.db" --out "$tmp/demo-copy.db"
mv "$tmp/demo-copy.db" "$out/vsurg.db"
printf 'admin %s\ninstructor %s\nevaluator %s\ntrainee %s\n' "$admin_token" \
  "$instructor_token" "$chief_token" "$trainee_token" > "$out/tokens.txt"
chmod 600 "$out/tokens.txt"
echo "store copy: $out/vsurg.db; the users' tokens: $out/tokens.txt"

step "Shutdown: SIGTERM, the store drained"
kill -TERM "$server_pid"
wait "$server_pid"
pids=()
tail -3 "$out/server.log"
left="$(pgrep -f "$tmp/vsurg.db" || true)"
[ -z "$left" ] || { echo "demo: processes left behind: $left" >&2; exit 1; }
echo
echo "demo flow: screenshots in $shots (station-before.png, station-twisted.png, monitor-view.png,"
echo "           station-palpation-novice.png, station-needle-hesitant.png);"
echo "           logs, station.json, monitor.log and scores.csv in $out"
