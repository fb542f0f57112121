#!/usr/bin/env bash
# README command 1: install what is missing, build, run the main job on the embedded default.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh
scripts/build.sh
build/sdoslam demo --out "${SDOSLAM_DEMO_OUT:-sdoslam_demo}" "$@"
