#!/usr/bin/env bash
# Installs the Debian packages sdoslam needs, and only those that are missing.
# Idempotent: a second run installs nothing and takes about a second.
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  libopencv-dev libopencv-contrib-dev  # ORB, DIS flow, ximgproc, dnn (ONNX)
  libeigen3-dev libceres-dev           # maths and all optimisation
  libyaml-cpp-dev libcli11-dev libspdlog-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev libtbb-dev
  libssl-dev                           # SHA-256 of result files (manifest.json)
  libdeflate-dev                       # inflating PNG images (io/png_reader.cc)
  clang libclang-rt-dev                # libFuzzer targets (scripts/fuzz.sh)
  pybind11-dev python3-pybind11        # the Python module (build/python)...
  python3-dev python3-numpy            # ... its headers and arrays
  python3-pytest                       # ... and its tests
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install_deps: installing ${missing[*]}"
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then
    sudo_cmd=(sudo)
  else
    echo "install_deps: need root (or sudo) to install: ${missing[*]}" >&2
    exit 1
  fi
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -q
"${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
