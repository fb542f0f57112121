#!/usr/bin/env bash
# Builds with ThreadSanitizer into build-tsan/ and runs the tests that start threads (the mapping
# thread, the preparing stage, the bounded queue). Passes when no report is left after
# scripts/tsan.supp, which only covers libraries not built with TSan. TSan slows the pipeline
# 20-50x, so the threaded tests of a few dozen frames are run (the bit-for-bit stage test alone
# takes 9 minutes under it): about 15 minutes on 2 cores after the build; not in scripts/test.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)
# Training the built-in vocabulary under TSan would take many minutes: embed the Release
# build's when there is one.
vocabulary=()
if [ -f build/src/sdoslam/place/default_vocabulary.sdv ]; then
  vocabulary=(-DSDOSLAM_DEFAULT_VOCABULARY="$PWD/build/src/sdoslam/place/default_vocabulary.sdv")
fi
cmake -S . -B build-tsan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSDOSLAM_SANITIZE=thread \
  "${vocabulary[@]}" >/dev/null
cmake --build build-tsan -j "$jobs" --target slam_test runner_test core_test
log=$(mktemp)
export TSAN_OPTIONS="suppressions=$PWD/scripts/tsan.supp halt_on_error=0 report_signal_unsafe=0"
status=0
build-tsan/src/sdoslam/core/core_test --gtest_filter='BoundedQueue.*' >"$log" 2>&1 || status=$?
build-tsan/src/sdoslam/runner/runner_test \
  --gtest_filter='PipelineStages.AnUnreadable*:PipelineStages.AnInterrupted*:PipelineStages.FramesReadAtTheCameraRate*' >>"$log" 2>&1 || status=$?
build-tsan/src/sdoslam/slam/slam_test --gtest_filter='SlamThreaded.*' >>"$log" 2>&1 || status=$?
reports=$(grep -c "WARNING: ThreadSanitizer" "$log" || true)
grep -E "^\[  (PASSED|FAILED)" "$log" || true
echo "tsan: $reports report(s); log in $log"
if [ "$reports" -ne 0 ] || [ "$status" -ne 0 ]; then exit 1; fi
