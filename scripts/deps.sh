#!/usr/bin/env bash
# Installs the Debian 12 packages npfkct needs, if any are missing. Sourced by the other scripts.
set -euo pipefail

NPFKCT_PACKAGES=(
  build-essential cmake pkg-config ccache curl
  libeigen3-dev libgtest-dev libgmock-dev libcli11-dev
  nlohmann-json3-dev libcpp-httplib-dev libspdlog-dev libvalijson-dev zlib1g-dev
  libopencv-dev libpcl-dev libtorch-dev libopenblas0-pthread
  python3 python3-requests python3-pytest python3-jsonschema python3-yaml
  ros-core-dev python3-rospy python3-rosgraph python3-roslaunch
  python3-std-msgs python3-sensor-msgs python3-geometry-msgs
)

npfkct_install_deps() {
  local missing=()
  for p in "${NPFKCT_PACKAGES[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
      missing+=("$p")
    fi
  done
  if [ ${#missing[@]} -eq 0 ]; then
    return 0
  fi
  echo "npfkct: installing ${missing[*]}" >&2
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${missing[@]}"
}

npfkct_build() {
  local build_dir="$1"
  shift
  cmake -S "$NPFKCT_ROOT" -B "$build_dir" -DCMAKE_BUILD_TYPE=Release "$@"
  cmake --build "$build_dir" -j "$(nproc)"
}

# The start of every script that runs a built program: installs what is missing, then builds
# BUILD_DIR (default build/) quietly. Needs NPFKCT_ROOT.
npfkct_prepare() {
  npfkct_install_deps
  BUILD_DIR="${BUILD_DIR:-$NPFKCT_ROOT/build}"
  npfkct_build "$BUILD_DIR" >/dev/null
}
