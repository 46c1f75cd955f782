#!/usr/bin/env bash
# The station's view end to end: a vsurg-server and, per scene, a headless vsurg-station driven
# by that scene's scripted trainee, rendering at 1280x720 on this machine's renderer (Mesa
# llvmpipe here) while its haptic loop runs at 1 kHz, server and station on the same machine.
# Prints per scene and quality level the frame time (draw and finish, ms: p50, p99), the frames
# drawn, the levels the trial started and ended at (with --quality auto, the probe's p90 per level
# tried before the trial), and the device loop's rate (over the run; its slowest and fastest whole second), all from
# the same run; with SHOTS=DIR writes DIR/<scene>.png (AT s in, 3.5 by default) and DIR/<scene>-summary.png.
# BASE_BIN=DIR adds a row per scene for another build's vsurg-station (the previous renderer:
# a worktree of an older commit built outside the repository), against the same server; at
# each of BASE_QUALITIES (its default level when unset).
# WIDTH and HEIGHT change the frame's size (1280x720).
# usage: [SCENES="arm-torsion ..."] [QUALITIES="high medium low"] [STYLE=hesitant]
#        [SHOTS=DIR] [BASE_BIN=DIR [BASE_QUALITIES="medium ..."]] bench/station_view.sh [BIN_DIR]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
B="$(cd "${1:-build/bin}" && pwd)"; d=$(mktemp -d); trap 'kill $spid 2>/dev/null; rm -rf $d' EXIT
SCENES=${SCENES:-"arm-torsion organ-surface-twist kidney-palpation sphere-palpation-256"}
QUALITIES=${QUALITIES:-"high"}
[ -n "${SHOTS:-}" ] && mkdir -p "$SHOTS" && SHOTS="$(cd "$SHOTS" && pwd)"
cd "$d"
source "$here/local_server.sh"
for scene in $SCENES; do
  $B/vsurg-sim trainee --scene $scene --style "${STYLE:-hesitant}" --out $scene.csv > /dev/null
  if [ -n "${BASE_BIN:-}" ]; then
    for bq in ${BASE_QUALITIES:-default}; do
      qflag=(); [ "$bq" != default ] && qflag=(--quality $bq)
      "$BASE_BIN/vsurg-station" --server 127.0.0.1:$PORT --token-file t.tok --scene $scene --trajectory $scene.csv \
          --headless --width ${WIDTH:-1280} --height ${HEIGHT:-720} "${qflag[@]}" --json 2>/dev/null \
        | python3 -c "import json,sys; j=json.load(sys.stdin); print('scene=$scene quality=base-$bq draw_ms_p50=%.1f draw_ms_p99=%.1f frames=%d loop_hz=%.2f loop_hz_1s=%.1f..%.1f score=%.1f render_threads=%s' % (j['draw_ms_p50'], j['draw_ms_p99'], j['frames'], j['loop_hz'], j['loop_hz_min_1s'], j['loop_hz_max_1s'], j['metrics']['score'], j.get('render_threads', 'default')))"
    done
  fi
  for q in $QUALITIES; do
    shots=()
    if [ -n "${SHOTS:-}" ] && [ "$q" = "$(echo $QUALITIES | cut -d' ' -f1)" ]; then
      shots=(--screenshot "$SHOTS/$scene.png" --screenshot-at ${AT:-3.5} --screenshot-summary "$SHOTS/$scene-summary.png")
    fi
    $B/vsurg-station --server 127.0.0.1:$PORT --token-file t.tok --scene $scene --trajectory $scene.csv \
        --headless --width ${WIDTH:-1280} --height ${HEIGHT:-720} --quality $q "${shots[@]}" --json 2>/dev/null \
      | python3 -c "import json,sys; j=json.load(sys.stdin); print('scene=$scene quality=$q draw_ms_p50=%.1f draw_ms_p99=%.1f frames=%d loop_hz=%.2f loop_hz_1s=%.1f..%.1f score=%.1f render_threads=%s levels=%s..%s probe_p90_ms=%s' % (j['draw_ms_p50'], j['draw_ms_p99'], j['frames'], j['loop_hz'], j['loop_hz_min_1s'], j['loop_hz_max_1s'], j['metrics']['score'], j.get('render_threads', 'default'), j.get('quality_start', '-'), j.get('quality_end', '-'), json.dumps(j.get('quality_probe_p90_ms', {}), separators=(',', ':'))))"
  done
done
