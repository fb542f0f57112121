#!/usr/bin/env bash
# clang-format (Google style, .clang-format) over the C++ sources git knows, and nothing else.
set -euo pipefail
cd "$(dirname "$0")/.."
git ls-files -co --exclude-standard '*.h' '*.cc' | xargs clang-format -i
