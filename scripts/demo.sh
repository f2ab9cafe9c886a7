#!/usr/bin/env bash
# One command on a fresh machine: install and build (scripts/setup.sh), then run the teach-and-repeat
# demo (scripts/run_demo) on a synthetic route the package renders itself.
#   scripts/demo.sh [WORKSPACE] [OUTPUT_DIR]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
workspace="${1:-$HOME/along_route_ws}"
bash "$here/scripts/setup.sh" "$workspace"
set +u
# shellcheck disable=SC1091
source "$workspace/devel/setup.bash"
set -u
exec bash "$here/scripts/run_demo" "${2:-/tmp/along_route_demo}"
