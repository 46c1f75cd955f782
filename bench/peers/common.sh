# Sourced by the peer scripts (rtt.sh, fem.sh): reads BIN_DIR and the peer's checkout from the
# first two arguments into $bin and $peer (absolute), refuses a checkout inside this repository
# (the peers' code never enters it), and makes $out (OUT, or a temporary folder) for raw results.
# $here is the peers folder. The caller then `shift 2`s its own arguments.
peers_setup() {  # NAME BIN_DIR CHECKOUT
  local name=$1
  bin="$(cd "${2:?BIN_DIR}" && pwd)"
  peer="$(cd "${3:?PEER_CHECKOUT}" && pwd)"
  here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
  local root
  root="$(cd "$here/../.." && pwd)"
  case "$peer/" in "$root"/*)
    echo "$name: the peer's checkout must be outside this repository" >&2; exit 2 ;;
  esac
  out="${OUT:-$(mktemp -d)}"
  mkdir -p "$out"
}
