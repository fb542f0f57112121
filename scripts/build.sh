#!/usr/bin/env bash
# Configures and builds sdoslam (Release) into build/. Used by demo.sh and test.sh.
# A unity build (8 sources compiled as one): each source spent most of its time parsing the
# same OpenCV, Eigen and Ceres headers, and a clean build on 2 cores took 519 s. Its
# compile_commands.json names the unity files, so clang-tidy wants a plain build:
#   SDOSLAM_UNITY_BUILD=OFF scripts/build.sh
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DCMAKE_UNITY_BUILD="${SDOSLAM_UNITY_BUILD:-ON}" \
  ${SDOSLAM_CMAKE_ARGS:-} >/dev/null
cmake --build build -j "$jobs"
