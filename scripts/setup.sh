#!/usr/bin/env bash
# Installs what RACK-RT needs on Debian bookworm (as root), then configures and
# builds a Release tree in build/. Safe to run again: installs only what is missing.
#
#   scripts/setup.sh            # install + build
#   RACK_BUILD_DIR=out scripts/setup.sh
#   RACK_WERROR=ON scripts/setup.sh   # warnings fail the build (what CI does: .ci/run)
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(
  build-essential cmake pkg-config git
  liblcm-dev liblcm-bin libglib2.0-dev   # TiMS between hosts (LCM 1.3 has no CMake config)
  libzstd-dev                            # TiMS/LCM: optional compression of large messages per link
  libsodium-dev                          # TiMS/LCM: authenticated links (keyed BLAKE2b MAC per packet)
  libyaml-cpp-dev                        # host files
  libyaml-dev                            # tools (rack_client): the network a host file names, without yaml-cpp
  dpkg-dev                               # cpack -G DEB: dpkg-shlibdeps finds the package dependencies
  libgtest-dev libgmock-dev              # tests
  clang-14 libclang-rt-14-dev llvm-14    # fuzzing: libFuzzer, ASan/UBSan runtimes, llvm-symbolizer (tests/fuzz/run)
  libbenchmark-dev rt-tests stress-ng strace  # benchmarks and their references (cyclictest); strace: RPC system calls
  libdw-dev libelf-dev                   # backtrace symbolisation (elfutils)
  iproute2                               # network namespaces in the integration tests
  python3 python3-matplotlib             # bench/run writes RESULTS.md and its plots
  libmrpt-slam-dev libmrpt-maps-dev libmrpt-obs-dev libmrpt-poses-dev libmrpt-bayes-dev
  mrpt-common                            # MCL and rawlog replay (MRPT 2.5); datasets for bench
  zlib1g-dev                             # gzip: bench/data/carmen logs (bench_mcl_real, MCL recovery tests); rawlogs inflated with a size limit
  libopencv-dev                          # Camera component (OpenCV VideoCapture), linked PRIVATE there only
  libopencv-contrib-dev                  # ObjRecogCamera: ArUco (cv::aruco is in contrib in OpenCV 4.6)
  libpcl-dev                             # Scan3D: voxel grid, outlier removal, RANSAC, range image (PRIVATE there)
  can-utils                              # cansend/candump: vcan tests and CAN debugging on robots
  libboost-dev libboost-system-dev       # rack-gui: HTTP/WebSocket server (Boost.Beast)
  nlohmann-json3-dev                     # rack-gui: its WebSocket protocol (JSON)
  chromium                               # rack-gui's end-to-end test (headless, driven by Playwright)
  graphviz                               # rackctl graph --format svg (dot)
  clang-format-14 clang-tidy-14          # code style: scripts/format.sh, scripts/tidy.sh (ctest format_check, tidy_naming)
)
# rack-gui's front end is built with node/npm: Debian's, unless a node is installed already.
command -v node >/dev/null 2>&1 || packages+=(nodejs)
command -v npm >/dev/null 2>&1 || packages+=(npm)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  if [[ $(id -u) -ne 0 ]]; then
    echo "setup: missing packages: ${missing[*]}; run as root (or: sudo apt-get install ${missing[*]})" >&2
    exit 1
  fi
  echo "setup: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  # Wait for another apt/dpkg (unattended upgrades, a parallel build) instead of failing.
  apt-get -o DPkg::Lock::Timeout=600 update -q
  apt-get -o DPkg::Lock::Timeout=600 install -y -q --no-install-recommends "${missing[@]}"
fi

# LCM multicast needs a route for 224.0.0.0/4; a machine without a default route
# (a bare container, a robot computer without uplink) has none: use loopback then.
if ! ip route get 239.255.76.67 >/dev/null 2>&1; then
  if [[ $(id -u) -eq 0 ]]; then
    ip link set lo up
    ip route add 224.0.0.0/4 dev lo
    echo "setup: no multicast route: added 224.0.0.0/4 on lo"
  else
    echo "setup: WARNING: no route for multicast (LCM): ip route add 224.0.0.0/4 dev lo" >&2
  fi
fi

build=${RACK_BUILD_DIR:-build}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DRACK_WERROR="${RACK_WERROR:-OFF}" >/dev/null
cmake --build "$build" -j"$(nproc)"
# rack-gui's front end (tools/gui/web): packages pinned by package-lock.json, built into
# tools/gui/web/dist, which rack-gui serves (nothing is loaded from the internet at run time).
(cd tools/gui/web && npm ci --no-audit --no-fund && npm run build)
# rack-foxglove (tools/foxglove): the Foxglove WebSocket bridge and MCAP recorder and
# player, on npm's maintained packages (@foxglove/ws-protocol, @mcap/core, ...), pinned
# by its package-lock.json.
(cd tools/foxglove && npm ci --no-audit --no-fund)
# The trace test's loader (tests/trace_check): Chrome DevTools' trace engine, which
# reads rackctl trace's files as the Performance panel does; pinned by package-lock.json.
(cd tests/trace_check && npm ci --no-audit --no-fund)
echo "setup: built in $build/"
