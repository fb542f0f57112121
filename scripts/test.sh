#!/usr/bin/env bash
# README command 2: install what is missing, build, run the whole test suite.
#   scripts/test.sh              # the suite (CI runs this)
#   scripts/test.sh --extended   # also the Extended/ tests: the same bars on scenarios the suite
#                                # already covers, left out of CI for time
# Other arguments go to ctest (e.g. -R Pipeline).
set -euo pipefail
cd "$(dirname "$0")/.."
extended=0
args=()
for arg in "$@"; do
  if [ "$arg" = --extended ]; then extended=1; else args+=("$arg"); fi
done
scripts/install_deps.sh
scripts/build.sh
jobs=$(nproc 2>/dev/null || echo 2)
if [ "$extended" = 1 ]; then
  ctest --test-dir build --output-on-failure -j "$jobs" "${args[@]}"
else
  ctest --test-dir build --output-on-failure -j "$jobs" -E '^Extended/' "${args[@]}"
fi
