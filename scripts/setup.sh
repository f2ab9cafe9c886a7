#!/usr/bin/env bash
# Sets up a fresh machine for along_route_localization and builds it.
# usage: scripts/setup.sh [--dry-run] [WORKSPACE]        default WORKSPACE: $HOME/along_route_ws
# Debian 12: installs ROS 1 from Debian's own packages. ROS Noetic in /opt/ros/noetic (Ubuntu 20.04):
# installs the package's dependencies with rosdep. Ubuntu 20.04 without Noetic: installs ros-noetic-ros-base
# when the ROS apt source (packages.ros.org) is configured, else says how to add it and stops. Any other
# system: says what is supported and stops. Then links this package into WORKSPACE/src and runs
# catkin_make. Extra CMake arguments can be passed in CATKIN_MAKE_ARGS.
#   --dry-run  print what would be installed and run, change nothing
# For tests: ALONG_ROUTE_OS_RELEASE (/etc/os-release), ALONG_ROUTE_ROS_ROOT (/opt/ros/noetic) and
# ALONG_ROUTE_APT_SOURCES (/etc/apt) name other files to read.
set -euo pipefail

dry_run=false
case "${1:-}" in
  -h | --help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "${BASH_SOURCE[0]}"; exit 0 ;;
  --dry-run) dry_run=true; shift ;;
  -*) echo "setup: unknown option '$1' (see setup.sh --help)" >&2; exit 2 ;;
esac

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
workspace="${1:-$HOME/along_route_ws}"
os_release="${ALONG_ROUTE_OS_RELEASE:-/etc/os-release}"
noetic="${ALONG_ROUTE_ROS_ROOT:-/opt/ros/noetic}"
apt_sources="${ALONG_ROUTE_APT_SOURCES:-/etc/apt}"
# Debian's ROS lives in /usr; a pyenv or venv python3 first on PATH lacks the ROS modules.
export PATH="/usr/bin:$PATH"

run() { if $dry_run; then echo "setup: would run: $*"; else "$@"; fi; }
as_root() { if [ "$(id -u)" -eq 0 ]; then run "$@"; else run sudo "$@"; fi; }
apt_install() {  # dpkg's lines are dropped (not apt's errors)
  if $dry_run; then as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@"
  else as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null; fi
}

os_field() {  # os_field NAME: a field of os-release, unquoted ("" when missing)
  sed -n "s/^$1=//p" "$os_release" | head -n 1 | tr -d '"'"'"
}
[ -r "$os_release" ] || { echo "setup: cannot read $os_release: which system is this? Supported: Debian 12, Ubuntu 20.04 + ROS Noetic" >&2; exit 1; }
os_id="$(os_field ID)"
os_version="$(os_field VERSION_ID)"
os_name="$(os_field PRETTY_NAME)"
os_name="${os_name:-$os_id $os_version}"

ros_apt_source_configured() {
  grep -rqsE '^[^#]*packages\.ros\.org/ros/ubuntu' "$apt_sources/sources.list" "$apt_sources/sources.list.d" 2>/dev/null
}

install_with_rosdep() {
  if $dry_run; then
    echo "setup: would run: source $noetic/setup.bash"
  else
    # shellcheck disable=SC1091
    set +u; source "$noetic/setup.bash"; set -u
  fi
  as_root apt-get update -qq
  apt_install python3-rosdep python3-catkin-tools || true
  [ -f /etc/ros/rosdep/sources.list.d/20-default.list ] || as_root rosdep init || true
  run rosdep update || true
  run rosdep install --from-paths "$here" --ignore-src -y
  apt_install ros-noetic-rostest ros-noetic-image-view libbenchmark-dev python3-matplotlib python3-opencv
}

if [ -f "$noetic/setup.bash" ]; then
  echo "setup: $os_name with ROS Noetic in $noetic: dependencies from rosdep"
  install_with_rosdep
elif [ "$os_id" = debian ]; then
  [ "$os_version" = 12 ] || echo "setup: $os_name: the package list below is Debian 12's (bookworm); other releases may name packages otherwise" >&2
  echo "setup: $os_name: ROS 1 from Debian's own packages"
  as_root apt-get update -qq
  apt_install \
    build-essential cmake catkin python3-catkin-pkg python3-empy python3-rospkg \
    ros-core-dev libnodeletlib-dev libnodelet-dev libimage-transport-dev libcv-bridge-dev librosbag-dev \
    libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure librostest-dev python3-rostest \
    rosbash libnodeletlib-tools ros-image-view libdiagnostic-updater-dev ros-nav-msgs libnav-msgs-dev ros-std-srvs libstd-srvs-dev \
    python3-rosbag python3-rosnode python3-rostopic python3-roslaunch python3-rosservice python3-rospy \
    python3-sensor-msgs python3-geometry-msgs python3-rosgraph-msgs python3-std-msgs python3-std-srvs python3-nav-msgs python3-diagnostic-msgs python3-nodelet \
    libopencv-dev libeigen3-dev libgtest-dev libbenchmark-dev clang libclang-rt-14-dev \
    python3-numpy python3-matplotlib python3-opencv python3-yaml
elif [ "$os_id" = ubuntu ] && [ "$os_version" = 20.04 ]; then
  if ros_apt_source_configured; then
    echo "setup: $os_name without ROS Noetic: installing ros-noetic-ros-base from the ROS apt source"
    as_root apt-get update -qq
    apt_install ros-noetic-ros-base
    install_with_rosdep
  else
    cat >&2 <<EOF
setup: $os_name has no ROS 1 packages of its own, and ROS Noetic is not installed ($noetic/setup.bash
is missing) nor is its apt source configured. Add the ROS apt source, then run this script again:

  sudo apt-get install -y curl gnupg lsb-release
  curl -sSL https://raw.githubusercontent.com/ros/rosdistro/master/ros.key | sudo gpg --dearmor -o /usr/share/keyrings/ros-archive-keyring.gpg
  echo "deb [signed-by=/usr/share/keyrings/ros-archive-keyring.gpg] http://packages.ros.org/ros/ubuntu focal main" | sudo tee /etc/apt/sources.list.d/ros1.list
  bash scripts/setup.sh $workspace

(see https://wiki.ros.org/noetic/Installation/Ubuntu). This script then installs ros-noetic-ros-base and
the package's dependencies with rosdep.
EOF
    exit 1
  fi
else
  echo "setup: $os_name is not supported: this script knows Debian 12 (ROS 1 from Debian's packages) and" \
    "Ubuntu 20.04 (ROS Noetic). With ROS Noetic installed elsewhere, source its setup.bash, link this" \
    "package into a catkin workspace's src/ and run catkin_make (rosdep install --from-paths src" \
    "--ignore-src installs the dependencies)." >&2
  exit 1
fi

if $dry_run; then
  echo "setup: would link $here into $workspace/src and run catkin_make there"
  exit 0
fi
mkdir -p "$workspace/src"
ln -sfn "$here" "$workspace/src/along_route_localization"
cd "$workspace"
# shellcheck disable=SC2086
catkin_make -j"$(nproc)" -DCMAKE_BUILD_TYPE=Release \
  -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 ${CATKIN_MAKE_ARGS:-} >"$workspace/build.log" 2>&1 \
  || { tail -n 60 "$workspace/build.log"; echo "setup: build failed (full log: $workspace/build.log)" >&2; exit 1; }
echo "setup: built along_route_localization in $workspace (source $workspace/devel/setup.bash)"
