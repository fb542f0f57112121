#!/usr/bin/env bash
# Renders an HTML report (e.g. the demo's report.html) in headless Chromium and saves a
# screenshot, to look at the page as a user's browser shows it. A developer's check: CI does not
# need Chromium and install_deps.sh does not install it (Debian: apt-get install chromium).
# Usage: scripts/check_report.sh REPORT.html OUT.png [WIDTH,HEIGHT]   (default 1280,2000)
set -euo pipefail
if [ $# -lt 2 ] || [ $# -gt 3 ]; then
  echo "usage: $0 REPORT.html OUT.png [WIDTH,HEIGHT]" >&2
  exit 2
fi
report=$1
screenshot=$2
size=${3:-1280,2000}
if [ ! -f "$report" ]; then
  echo "error: no report at $report" >&2
  exit 1
fi
browser=$(command -v chromium || command -v chromium-browser || true)
if [ -z "$browser" ]; then
  echo "error: chromium not found; install it to check reports (Debian: apt-get install chromium)" >&2
  exit 1
fi
# A throw-away profile: nothing is read from or left in the user's own.
profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
mkdir -p "$(dirname "$screenshot")"
out=$(realpath "$screenshot")
rm -f "$out"
# --no-sandbox: Chromium refuses to run as root (containers) with its sandbox on.
"$browser" --headless --no-sandbox --disable-gpu --hide-scrollbars --no-first-run \
  --user-data-dir="$profile" --window-size="$size" --screenshot="$out" \
  "file://$(realpath "$report")" 2>"$profile/chromium.log" || {
  cat "$profile/chromium.log" >&2
  echo "error: chromium failed to render $report" >&2
  exit 1
}
if [ ! -s "$out" ]; then
  cat "$profile/chromium.log" >&2
  echo "error: chromium wrote no screenshot to $out" >&2
  exit 1
fi
echo "screenshot of $report ($size) in $out"
