#!/usr/bin/env bash
# The implicit mass-spring step at several commits, side by side in one run: each commit's
# mass-spring sources compiled as one unit (as the unity build compiles them) with the build's
# flags, around bench/msm_standalone.cpp, then ROUNDS rounds that run every commit's binary in
# turn pinned to core PIN_CPU; prints each round's medians and each commit's ratio to the first
# per round. Works in a scratch folder outside the repository (git worktrees, removed at the end).
# Add BENCH_BIN=DIR to run DIR/vsurg-bench msm-step (the shipped build) in the same rounds.
#   usage: [ROUNDS=8] [STEPS=1000] [PIN_CPU=1] [BENCH_BIN=DIR] bench/msm_at_commits.sh COMMIT...
set -euo pipefail
[ $# -ge 1 ] || { echo "usage: bench/msm_at_commits.sh COMMIT..." >&2; exit 2; }
repo="$(cd "$(dirname "$0")/.." && pwd)"
ROUNDS=${ROUNDS:-8}; STEPS=${STEPS:-1000}; PIN_CPU=${PIN_CPU:-1}
work="$(mktemp -d)"
cleanup() {
  for c in "$@"; do git -C "$repo" worktree remove --force "$work/wt-$c" 2>/dev/null || true; done
  rm -rf "$work"
}
trap 'cleanup "$@"' EXIT
for c in "$@"; do
  wt="$work/wt-$c"
  git -C "$repo" worktree add --detach "$wt" "$c" >/dev/null 2>&1
  unit="$work/unit-$c.cpp"
  echo '#include "common/tissue/mass_spring.cpp"' > "$unit"
  [ -f "$wt/common/tissue/mass_spring_implicit.cpp" ] &&
    echo '#include "common/tissue/mass_spring_implicit.cpp"' >> "$unit"
  g++ -std=c++20 -O3 -g1 -DNDEBUG -fno-math-errno -I"$wt" -isystem /usr/include/eigen3 \
    "$repo/bench/msm_standalone.cpp" "$unit" "$wt/common/geometry/mesh_generators.cpp" \
    "$wt/common/geometry/mesh.cpp" -o "$work/msm-$c"
  echo "msm_at_commits.sh: built $c" >&2
done
for r in $(seq "$ROUNDS"); do
  for c in "$@"; do
    taskset -c "$PIN_CPU" "$work/msm-$c" "$STEPS" | sed "s/^/round=$r who=$c /"
  done
  if [ -n "${BENCH_BIN:-}" ]; then
    taskset -c "$PIN_CPU" "$BENCH_BIN/vsurg-bench" msm-step --steps "$STEPS" --json |
      python3 -c "import json,sys
for l in sys.stdin: j=json.loads(l); print('round=$r who=vsurg-bench %s %.2f' % (j['scene'], j['step_us_median']))"
  fi
done | tee "$work/rounds.txt"
python3 - "$work/rounds.txt" "$1" <<'PY'
import collections, statistics, sys
rows = collections.defaultdict(dict)  # (round, scene) -> who -> µs
for line in open(sys.argv[1]):
    r, who, scene, us = line.split()
    rows[(r.split('=')[1], scene)][who.split('=')[1]] = float(us)
first = sys.argv[2]
whos = list(dict.fromkeys(w for v in rows.values() for w in v))
for scene in sorted({s for _, s in rows}):
    print(f"{scene}:")
    for w in whos:
        us = [v[w] for (r, s), v in rows.items() if s == scene and w in v]
        ratio = [v[w] / v[first] for (r, s), v in rows.items() if s == scene and w in v and first in v]
        print(f"  {w:14s} median {statistics.median(us):7.1f} µs (min {min(us):.1f}); "
              f"÷ {first} per round: median {statistics.median(ratio):.2f}, "
              f"{min(ratio):.2f}-{max(ratio):.2f}")
PY
