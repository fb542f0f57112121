#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan) into build-fuzz/ and runs each for
# SDOSLAM_FUZZ_SECONDS (default 60) from its seed corpus in fuzz/corpus/<target>/, two at a time.
# New inputs go to a scratch corpus, never into the repository; a finding (crash, leak,
# uncaught exception, timeout) is kept in build-fuzz/findings/ and fails the script.
#   scripts/fuzz.sh                 # all targets, 60 s each
#   scripts/fuzz.sh trajectory 600  # one target, ten minutes
# The mutation seed is fixed (SDOSLAM_FUZZ_SEED, default 1) so that CI explores the same inputs
# at every commit and a finding there can be replayed; SDOSLAM_FUZZ_SEED=0 lets libFuzzer pick
# a new seed per run, for long local hunts.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${2:-${SDOSLAM_FUZZ_SECONDS:-60}}
seed=${SDOSLAM_FUZZ_SEED:-1}
all=(trajectory tum_lists config detections masks manifest)
targets=("${1:-${all[@]}}")
[ "${1:-}" = "" ] && targets=("${all[@]}")

# -O1 and line tables only (CMakeLists.txt), as libFuzzer's documentation builds: the readers
# are small, and CI builds the libraries they live in a second time here (131 -> 108 s on 2 cores).
# A unity build, as scripts/build.sh: 93 -> 82 s, and 136 -> 86 s of CPU.
# SDOSLAM_FUZZ_OPT overrides -O1: CI's 5 s per target gain little from speed, and at -O0 the
# build takes about 40 s less on 2 cores (the targets run about half as many inputs).
opt=${SDOSLAM_FUZZ_OPT:--O1}
CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="$opt -DNDEBUG" -DSDOSLAM_FUZZ=ON -DCMAKE_UNITY_BUILD=ON >/dev/null
cmake --build build-fuzz -j "$(nproc 2>/dev/null || echo 2)" \
  --target $(printf '%s_fuzz ' "${targets[@]}")
mkdir -p build-fuzz/findings

run_one() {
  local t=$1 scratch
  scratch=$(mktemp -d)
  # Our readers parse small text files: 64 KiB inputs and 10 s per input are generous.
  local seeds=("fuzz/corpus/$t")
  [ "$t" = config ] && seeds+=(configs)  # the shipped configs seed the config reader
  if build-fuzz/fuzz/"${t}"_fuzz "$scratch" "${seeds[@]}" -max_total_time="$seconds" -seed="$seed" \
      -max_len=65536 -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
      -artifact_prefix="build-fuzz/findings/${t}-" >"build-fuzz/${t}.log" 2>&1; then
    echo "fuzz ${t}: $(grep -o 'stat::number_of_executed_units: *[0-9]*' "build-fuzz/${t}.log" |
      grep -o '[0-9]*$') inputs in ${seconds} s, no finding"
    rm -rf "$scratch"
  else
    echo "fuzz ${t}: FINDING (build-fuzz/${t}.log, build-fuzz/findings/)" >&2
    tail -40 "build-fuzz/${t}.log" >&2
    rm -rf "$scratch"
    return 1
  fi
}

status=0
pids=()
for t in "${targets[@]}"; do
  run_one "$t" &
  pids+=($!)
  if [ ${#pids[@]} -ge 2 ]; then
    wait "${pids[0]}" || status=1
    pids=("${pids[@]:1}")
  fi
done
for p in "${pids[@]}"; do wait "$p" || status=1; done
exit $status
