#!/usr/bin/env bash
# Installs the project's Debian packages (only the missing ones), builds with -j2 and runs every
# test through ctest (the sanitizer builds compiling beside it at the lowest priority); then the
# sanitizer builds (deploy/sanitize.sh: ASan+UBSan on the unit and
# integration tests, TSan on the threaded suites) and every fuzz target for 5 s on the
# kept corpus (deploy/fuzz.sh). Exits non-zero on any failure.
# Usage: deploy/test.sh [extra cmake -D options for the main build]
# VSURG_QUICK=1 skips the sanitizer and fuzz stages (the main build's tests only).
set -euo pipefail
source "$(dirname "$0")/lib.sh"
root="$(vsurg_root)"
stage() { echo; echo "== test.sh: $* ($(date -u +%H:%M:%S)) =="; }
stage "main build and tests"
vsurg_install_packages
vsurg_install_npm
vsurg_build "$@"
# The sanitizer builds compile at the lowest CPU priority while the main tests run: they take
# only the cycles the tests leave (the tests hold beside two CPU hogs at normal priority), and
# the sanitizer stage then starts on trees mostly built.
sanitizer_build=""
if [ "${VSURG_QUICK:-0}" != 1 ]; then
  setsid nice -n 19 "$root/deploy/sanitize.sh" build > "$root/build/sanitizer-build.log" 2>&1 &
  sanitizer_build=$!  # its own process group: stopped whole if the tests fail
  trap 'kill -- "-$sanitizer_build" 2>/dev/null || true' EXIT
fi
ctest --test-dir "$root/build" --output-on-failure -j2 --timeout 300
if [ "${VSURG_QUICK:-0}" = 1 ]; then exit 0; fi
stage "sanitizer builds (begun beside the tests)"
wait "$sanitizer_build" || { tail -50 "$root/build/sanitizer-build.log"; exit 1; }
trap - EXIT
stage "sanitizers"
"$root/deploy/sanitize.sh" all
stage "fuzzing, 5 s per target"
"$root/deploy/fuzz.sh" all 5
stage "done"
