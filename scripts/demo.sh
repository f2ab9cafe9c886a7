#!/usr/bin/env bash
# One command on a fresh machine: install and build (scripts/setup.sh), then run the teach-and-repeat
# demo (scripts/run_demo) on a synthetic route the package renders itself.
# usage: scripts/demo.sh [WORKSPACE] [OUTPUT_DIR]
case "${1:-}" in  # --help prints the comment above; another "-..." is refused before anything is done
  -h | --help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "${BASH_SOURCE[0]}"; exit 0 ;;
  -*) echo "demo.sh: unknown option '$1' (see demo.sh --help)" >&2; exit 2 ;;
esac
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
workspace="${1:-$HOME/along_route_ws}"
bash "$here/scripts/setup.sh" "$workspace"
set +u
# shellcheck disable=SC1091
source "$workspace/devel/setup.bash"
set -u
exec bash "$here/scripts/run_demo" "${2:-/tmp/along_route_demo}"
