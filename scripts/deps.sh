#!/usr/bin/env bash
# Installs the Debian 12 packages npfkct needs, if any are missing. Sourced by the other scripts.
set -euo pipefail

# What building npfkct-server needs and nothing else (the Docker images' build stage). The server
# reads and writes HTTP itself (server/src/http_front.cc); libbrotli-dev and zlib1g-dev compress
# its responses as clients accept (brotli, gzip); libcpp-httplib-dev is the C++ tests' client.
NPFKCT_BUILD_PACKAGES=(
  build-essential cmake pkg-config
  libeigen3-dev libcli11-dev
  nlohmann-json3-dev rapidjson-dev libcpp-httplib-dev libcurl4-openssl-dev libspdlog-dev libvalijson-dev
  zlib1g-dev libbrotli-dev
  libopencv-dev libpcl-dev libtorch-dev libopenblas0-pthread
  liburdfdom-dev liborocos-kdl-dev
)
# What a built npfkct-server needs to run: the shared libraries it links (readelf -d) and curl
# for the health check (the Docker images' runtime stage: no compiler, no -dev package, no ROS,
# no test tool; tests/test_docker.py checks the list). Keep in step with NPFKCT_BUILD_PACKAGES.
NPFKCT_RUNTIME_PACKAGES=(
  libspdlog1.10 libfmt9 libbrotli1 zlib1g libopenblas0-pthread libtorch1.13
  libopencv-core406 libopencv-imgproc406 libopencv-imgcodecs406 libopencv-features2d406
  libopencv-calib3d406
  libpcl-common1.13 libpcl-kdtree1.13 libpcl-search1.13 libpcl-filters1.13 libpcl-features1.13
  libpcl-segmentation1.13
  liburdfdom-model3.0 libconsole-bridge1.0 liborocos-kdl1.5
  curl ca-certificates
)
NPFKCT_PACKAGES=(
  "${NPFKCT_BUILD_PACKAGES[@]}" ccache curl jq libgtest-dev libgmock-dev
  python3 python3-requests python3-pytest python3-jsonschema python3-yaml
  python3-venv python3-setuptools python3-wheel
  # bench/lightdark_optimum.py (the SimpleLightDark reference) solves with numpy.
  python3-numpy
  # The Debian packages (cpack -G DEB: dpkg-shlibdeps) and the fresh root they are tested on.
  dpkg-dev mmdebstrap
  ros-core-dev python3-rospy python3-rosgraph python3-roslaunch
  python3-std-msgs python3-sensor-msgs python3-geometry-msgs python3-nav-msgs
  # clients/ros/npfkct_ros: catkin and genmsg/genpy generate its messages and actions (from
  # std/geometry/trajectory/actionlib msgs); actionlib and tf2_ros run it; it publishes
  # visualization_msgs markers.
  catkin ros-message-generation ros-message-runtime python3-genpy
  ros-trajectory-msgs ros-actionlib-msgs python3-trajectory-msgs python3-actionlib-msgs
  python3-actionlib python3-tf2-ros python3-visualization-msgs
)

# Fleet mode (--store postgresql://...): the PostgreSQL client library the store is built with.
# Not needed by a single-machine server, which builds without it.
NPFKCT_STORE_PACKAGES=(libpq-dev)
# ... and what a server built with it needs to run (deploy/Dockerfile.replica's runtime stage).
NPFKCT_STORE_RUNTIME_PACKAGES=(libpq5)
# What the fleet and deployment tests run besides (tests/test_fleet.py, tests/test_deploy.py): a
# throwaway PostgreSQL cluster, nginx, docker-compose to check deploy/compose.yaml; Node.js and
# npm for the Kubernetes manifests' validator (tests/k8s) and the OpenAPI checks (tests/js).
NPFKCT_FLEET_TEST_PACKAGES=(postgresql postgresql-client nginx docker-compose)
# The web console's browser test (tests/test_console.py): Debian's Chromium, headless.
NPFKCT_BROWSER_TEST_PACKAGES=(chromium)

# Installs the packages given that are not installed yet.
npfkct_install_packages() {
  local missing=()
  for p in "$@"; do
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

# What building and running npfkct-server on one machine needs (scripts/run.sh).
npfkct_install_deps() {
  npfkct_install_packages "${NPFKCT_PACKAGES[@]}"
}

# What scripts/test.sh needs on top: the store's library and the fleet tests' programs. Node.js
# is looked for as a command, so that a Node.js installed from elsewhere (with its own npm) is
# used as it is.
npfkct_install_test_deps() {
  npfkct_install_packages "${NPFKCT_STORE_PACKAGES[@]}" "${NPFKCT_FLEET_TEST_PACKAGES[@]}" \
    "${NPFKCT_BROWSER_TEST_PACKAGES[@]}"
  if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
    npfkct_install_packages nodejs npm
  fi
}

npfkct_build() {
  local build_dir="$1"
  shift
  cmake -S "$NPFKCT_ROOT" -B "$build_dir" -DCMAKE_BUILD_TYPE=Release "$@"
  cmake --build "$build_dir" -j "$(nproc)"
}

# The start of every script that runs a built program: installs what is missing, then builds the
# targets given (default: every target) in BUILD_DIR (default build/), printing the build's
# progress lines to stderr (a first build takes several minutes on 2 cores). Needs NPFKCT_ROOT.
# Usage: npfkct_prepare [target...]
npfkct_prepare() {
  npfkct_install_deps
  BUILD_DIR="${BUILD_DIR:-$NPFKCT_ROOT/build}"
  local configure_log
  configure_log="$(mktemp)"
  if ! cmake -S "$NPFKCT_ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release >"$configure_log" 2>&1
  then
    cat "$configure_log" >&2
    rm -f "$configure_log"
    return 1
  fi
  rm -f "$configure_log"
  local targets=()
  for t in "$@"; do targets+=(--target "$t"); done
  echo "npfkct: building ${*:-every target} in $BUILD_DIR" >&2
  # The build's own progress ("[ 42%] Building ..."), on stderr so that stdout stays the job's.
  cmake --build "$BUILD_DIR" -j "$(nproc)" "${targets[@]}" >&2
}

# Writes the npfkct-scenegen scene of each seed to DIR/gen-SEED.json (DIR is created) and lists
# the files in the array SCENE_FILES, in the seeds' order. Needs BUILD_DIR (npfkct_prepare).
# Env: SCENE_VERSION (npfkct-scenegen --version: 1, the default, or 2).
# Usage: npfkct_generate_scenes DIR SEED...
npfkct_generate_scenes() {
  local dir="$1"
  shift
  mkdir -p "$dir"
  SCENE_FILES=()
  for seed in "$@"; do
    "$BUILD_DIR/bin/npfkct-scenegen" --version "${SCENE_VERSION:-1}" --seed "$seed" \
      >"$dir/gen-$seed.json"
    SCENE_FILES+=("$dir/gen-$seed.json")
  done
}

# The arguments of the resumable benchmark scripts: [--run NAME] [--cpu-ms MS] [--trials N]
# [--commit]. Sets RUN (default run1), CPU_MS, TRIALS and COMMIT (0; 1 with --commit, which
# npfkct_bench_cell reads); --help prints lines 2 to HELP_END of the calling script.
# Usage: npfkct_bench_args DEFAULT_CPU_MS DEFAULT_TRIALS HELP_END "$@"
npfkct_bench_args() {
  RUN=run1
  CPU_MS="$1"
  TRIALS="$2"
  COMMIT=0
  local help_end="$3"
  shift 3
  while [ $# -gt 0 ]; do
    case "$1" in
      --run) RUN="$2"; shift 2 ;;
      --cpu-ms) CPU_MS="$2"; shift 2 ;;
      --trials) TRIALS="$2"; shift 2 ;;
      --commit) COMMIT=1; shift ;;
      -h|--help) sed -n "2,${help_end}p" "$0"; exit 0 ;;
      *) echo "$(basename "$0"): unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
  done
}

# One row of a resumable benchmark table: a cell DIR/SCENE.jsonl for every file in SCENE_FILES
# (SCENE: the file's name without .json and without a gen- prefix), each npfkct-bench run with
# the given arguments at TRIALS trials and CPU_MS per step, seed 1. Needs npfkct_bench_args.
# Usage: npfkct_bench_row DIR npfkct-bench-arguments...
npfkct_bench_row() {
  local dir="$1" file scene
  shift
  for file in "${SCENE_FILES[@]}"; do
    scene="$(basename "$file" .json)"
    npfkct_bench_cell "$dir/${scene#gen-}.jsonl" "$TRIALS" --scenario "$file" "$@" \
      --trials "$TRIALS" --cpu-ms "$CPU_MS" --threads "$(nproc)" --seed 1
  done
}

# One cell of a resumable benchmark table: runs npfkct-bench with the given arguments and stores
# its JSON line in FILE, unless FILE already holds a finished run of TRIALS trials. The line is
# written to a temporary file first, so an interrupted run leaves no half cell. With COMMIT=1 the
# finished cell is committed to git at once. Needs BUILD_DIR and NPFKCT_ROOT.
# Usage: npfkct_bench_cell FILE TRIALS npfkct-bench-arguments...
npfkct_bench_cell() {
  local file="$1" trials="$2"
  shift 2
  if [ -s "$file" ] && python3 -c "import json,sys; d=json.loads(open(sys.argv[1]).readline()); \
sys.exit(0 if d.get('trials') == int(sys.argv[2]) and not d.get('failed_trials') else 1)" \
    "$file" "$trials" 2>/dev/null; then
    echo "done already: ${file#"$NPFKCT_ROOT"/}" >&2
    return 0
  fi
  mkdir -p "$(dirname "$file")"
  echo "running: ${file#"$NPFKCT_ROOT"/}" >&2
  "$BUILD_DIR/bin/npfkct-bench" "$@" >"$file.tmp"
  # Record the commit the numbers were measured at (dirty: with uncommitted changes).
  local commit
  commit="$(git -C "$NPFKCT_ROOT" rev-parse --short HEAD 2>/dev/null || echo unknown)"
  if ! git -C "$NPFKCT_ROOT" diff --quiet HEAD -- ':!bench/results' 2>/dev/null; then
    commit="$commit-dirty"
  fi
  python3 -c "import json,sys; d=json.loads(open(sys.argv[1]).readline()); d['commit']=sys.argv[2]; \
d['machine']='$(nproc) cores, '+open('/proc/cpuinfo').read().split('model name')[1].split(':')[1].split(chr(10))[0].strip(); \
open(sys.argv[1],'w').write(json.dumps(d)+chr(10))" "$file.tmp" "$commit"
  mv "$file.tmp" "$file"
  if [ "${COMMIT:-0}" = 1 ]; then
    git -C "$NPFKCT_ROOT" add "$file"
    git -C "$NPFKCT_ROOT" commit -q -m "bench: ${file#"$NPFKCT_ROOT"/}" -- "$file"
  fi
}
