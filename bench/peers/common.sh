# Sourced by the peer scripts (rtt.sh, fem.sh, msm.sh): reads BIN_DIR and the peer's checkout from the
# first two arguments into $bin and $peer (absolute), refuses a checkout inside this repository
# (the peers' code never enters it), and makes $out (OUT, or a temporary folder) for raw results.
# $here is the peers folder. The caller then `shift 2`s its own arguments.
peers_setup() {  # NAME BIN_DIR CHECKOUT
  local name=$1
  bin="$(cd "${2:?BIN_DIR}" && pwd)"
  peer="$(cd "${3:?PEER_CHECKOUT}" && pwd)"
  here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
  peers_outside "$name" "$peer"
  out="${OUT:-$(mktemp -d)}"
  mkdir -p "$out"
}

# The single-threaded steps (fem.sh, msm.sh) run pinned to one core, ours and the peers' alike:
# on this machine kind the two cores differ (the same binary's sphere step 37 µs on one, 52 µs on
# the other, and VegaFEM's 980 against 1 550 µs), so an unpinned run is a lottery per process.
# PIN_CPU picks the core (default 0); PIN_CPU= runs unpinned.
peers_pinned() {  # COMMAND ARGS...
  if [ -n "${PIN_CPU-0}" ] && command -v taskset >/dev/null; then
    taskset -c "${PIN_CPU-0}" "$@"
  else
    "$@"
  fi
}

peers_outside() {  # NAME CHECKOUT: exits unless the checkout is outside this repository
  local root
  root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
  case "$2/" in "$root"/*)
    echo "$1: the peer's checkout must be outside this repository" >&2; exit 2 ;;
  esac
}

# Our VegaFEM harnesses (vegafem/: vega_fem_step, vega_msm_step) built against CHECKOUT into
# CHECKOUT-harness, unless both are there already.
peers_build_vega() {  # NAME CHECKOUT
  local harness="$2-harness"
  [ -x "$harness/vega_fem_step" ] && [ -x "$harness/vega_msm_step" ] &&
    [ -x "$harness/vega_hyper_step" ] && return 0
  echo "$1: building the harness with VegaFEM's sources in $harness" >&2
  cmake -S "$here/vegafem" -B "$harness" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    "-DVEGA_SOURCE=$2" >/dev/null
  cmake --build "$harness" -j2 >/dev/null
}
