#!/usr/bin/env bash
# Installs the project's Debian packages (only the missing ones), builds with -j2 and runs every
# test through ctest; then the sanitizer builds (deploy/sanitize.sh: ASan+UBSan on the unit and
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
ctest --test-dir "$root/build" --output-on-failure -j2 --timeout 300
if [ "${VSURG_QUICK:-0}" = 1 ]; then exit 0; fi
stage "sanitizers"
"$root/deploy/sanitize.sh" all
stage "fuzzing, 5 s per target"
"$root/deploy/fuzz.sh" all 5
stage "done"
