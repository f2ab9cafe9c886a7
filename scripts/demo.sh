#!/usr/bin/env bash
# One command on a fresh machine: install and build (scripts/setup.sh), then run the teach-and-repeat
# demo (scripts/run_demo) on a synthetic route the package renders itself.
# usage: scripts/demo.sh [WORKSPACE] [OUTPUT_DIR]
# With --closed-loop: the closed-loop demo instead (scripts/run_closed_loop): the simulator drives the
# route while teach.launch records it, then the route follower drives it again from 1 m to the side and
# 10 deg turned, and the taught commands are replayed without the camera for comparison; writes the plot
# OUTPUT_DIR/seed1/closed_loop_+1m+10deg.png (default OUTPUT_DIR: /tmp/along_route_closed_loop).
#   scripts/demo.sh --closed-loop [WORKSPACE] [OUTPUT_DIR]
case "${1:-}" in  # --help prints the comment above; another "-..." is refused before anything is done
  -h | --help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "${BASH_SOURCE[0]}"; exit 0 ;;
  --closed-loop) ;;
  -*) echo "demo.sh: unknown option '$1' (see demo.sh --help)" >&2; exit 2 ;;
esac
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
closed_loop=false
if [ "${1:-}" = "--closed-loop" ]; then closed_loop=true; shift; fi
workspace="${1:-$HOME/along_route_ws}"
bash "$here/scripts/setup.sh" "$workspace"
set +u
# shellcheck disable=SC1091
source "$workspace/devel/setup.bash"
set -u
if $closed_loop; then
  exec /usr/bin/python3 "$here/scripts/run_closed_loop" --output "${2:-/tmp/along_route_closed_loop}" --open-loop
fi
exec bash "$here/scripts/run_demo" "${2:-/tmp/along_route_demo}"
