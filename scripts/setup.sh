#!/usr/bin/env bash
# Sets up a fresh machine for along_route_localization and builds it.
#   scripts/setup.sh [WORKSPACE]        default WORKSPACE: $HOME/along_route_ws
# Debian 12: installs ROS 1 from Debian's own packages. Ubuntu 20.04 with ROS Noetic in /opt/ros/noetic:
# installs the package's dependencies with rosdep. Then links this package into WORKSPACE/src and runs
# catkin_make. Extra CMake arguments can be passed in CATKIN_MAKE_ARGS.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
workspace="${1:-$HOME/along_route_ws}"
# Debian's ROS lives in /usr; a pyenv or venv python3 first on PATH lacks the ROS modules.
export PATH="/usr/bin:$PATH"

as_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }

if [ -f /opt/ros/noetic/setup.bash ]; then
  # shellcheck disable=SC1091
  set +u; source /opt/ros/noetic/setup.bash; set -u
  as_root apt-get update -qq
  as_root apt-get install -y -qq python3-rosdep python3-catkin-tools >/dev/null || true
  [ -f /etc/ros/rosdep/sources.list.d/20-default.list ] || as_root rosdep init || true
  rosdep update >/dev/null || true
  rosdep install --from-paths "$here" --ignore-src -y
  as_root apt-get install -y -qq ros-noetic-rostest ros-noetic-image-view libbenchmark-dev python3-matplotlib python3-opencv >/dev/null
else
  as_root apt-get update -qq
  DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -qq --no-install-recommends \
    build-essential cmake catkin python3-catkin-pkg python3-empy python3-rospkg \
    ros-core-dev libnodeletlib-dev libnodelet-dev libimage-transport-dev libcv-bridge-dev librosbag-dev \
    libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure librostest-dev python3-rostest \
    rosbash libnodeletlib-tools ros-image-view libdiagnostic-updater-dev ros-nav-msgs libnav-msgs-dev ros-std-srvs libstd-srvs-dev \
    python3-rosbag python3-rosnode python3-rostopic python3-roslaunch python3-rosservice python3-rospy \
    python3-sensor-msgs python3-geometry-msgs python3-rosgraph-msgs python3-std-msgs python3-std-srvs python3-nav-msgs python3-diagnostic-msgs python3-nodelet \
    libopencv-dev libeigen3-dev libgtest-dev libbenchmark-dev clang libclang-rt-14-dev \
    python3-numpy python3-matplotlib python3-opencv python3-yaml >/dev/null
fi

mkdir -p "$workspace/src"
ln -sfn "$here" "$workspace/src/along_route_localization"
cd "$workspace"
# shellcheck disable=SC2086
catkin_make -j"$(nproc)" -DCMAKE_BUILD_TYPE=Release \
  -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 ${CATKIN_MAKE_ARGS:-} >"$workspace/build.log" 2>&1 \
  || { tail -n 60 "$workspace/build.log"; echo "setup: build failed (full log: $workspace/build.log)" >&2; exit 1; }
echo "setup: built along_route_localization in $workspace (source $workspace/devel/setup.bash)"
