#!/usr/bin/env bash
# Installs the Debian 12 packages certislam builds against, only those that are missing.
set -euo pipefail

PACKAGES=(
  cmake g++ clang clang-format clang-tidy pkg-config git ccache python3
  libeigen3-dev libsuitesparse-dev libboost-dev
  libprotobuf-dev protobuf-compiler libzmq3-dev cppzmq-dev libsodium-dev
  libgtest-dev libgmock-dev libbenchmark-dev libspectra-dev
  libpcl-dev mpi-default-dev libnanoflann-dev libopenvdb-dev libtbb-dev libceres-dev
  libcli11-dev nlohmann-json3-dev libyaml-cpp-dev libclang-rt-14-dev iproute2
  librosbag-storage-dev libsensor-msgs-dev libnav-msgs-dev pluginlib-dev libament-index-cpp-dev
  ros-core-dev libroscpp-dev libtf2-ros-dev libvisualization-msgs-dev librosbag-dev
  python3-rosmaster python3-rostopic python3-rosbag python3-rospy python3-std-msgs python3-geometry-msgs python3-nav-msgs
  libzstd-dev pybind11-dev python3-numpy
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "install-deps: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
