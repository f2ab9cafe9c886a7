#!/usr/bin/env bash
# Builds the package with its tests and runs them all: core gtests, rostests (real roscore, nodelet
# manager, launch files and rosbag play), launch-file checks and the Python tool tests.
# usage: scripts/run_tests.sh [WORKSPACE]     default WORKSPACE: $HOME/along_route_ws (built by scripts/setup.sh)
# Exit status 0 only when every test passed. Real Nordland frames are read from ../shared/data/nordland
# beside this repository when present; the tests that need them skip with a message otherwise.
case "${1:-}" in  # --help prints the comment above; another "-..." is refused before anything is done
  -h | --help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "${BASH_SOURCE[0]}"; exit 0 ;;
  -*) echo "run_tests.sh: unknown option '$1' (see run_tests.sh --help)" >&2; exit 2 ;;
esac
set -uo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
workspace="${1:-$HOME/along_route_ws}"
export PATH="/usr/bin:$PATH"
[ -d "$workspace/src" ] || { echo "run_tests: no workspace at $workspace: run scripts/setup.sh first" >&2; exit 2; }
ln -sfn "$here" "$workspace/src/along_route_localization"
cd "$workspace"
if [ -f /opt/ros/noetic/setup.bash ]; then set +u; source /opt/ros/noetic/setup.bash; set -u; fi

# shellcheck disable=SC2086
catkin_make -j"$(nproc)" -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 \
  ${CATKIN_MAKE_ARGS:-} tests >"$workspace/build_tests.log" 2>&1 \
  || { tail -n 80 "$workspace/build_tests.log"; echo "run_tests: build failed" >&2; exit 1; }
rm -rf build/test_results
catkin_make -j1 run_tests >"$workspace/run_tests.log" 2>&1
set +u; source devel/setup.bash; set -u

# Python tool tests (unittest); the runner prints "ran failed skipped" as its last line.
py_log="$workspace/python_tests.log"
( cd "$here" && /usr/bin/python3 - <<'PY'
import sys, unittest
result = unittest.TextTestRunner(verbosity=1).run(unittest.defaultTestLoader.discover('test/python', top_level_dir='test/python'))
print(result.testsRun, len(result.failures) + len(result.errors), len(result.skipped))
sys.exit(0 if result.wasSuccessful() else 1)
PY
) >"$py_log" 2>&1
py_status=$?
read -r py_ran py_failed py_skipped < <(tail -n 1 "$py_log" | grep -E '^[0-9]+ [0-9]+ [0-9]+$' || echo "0 1 0")

echo "=== test results"
catkin_test_results --verbose build/test_results | grep -vE '^$' | tail -n 40
summary=$(catkin_test_results build/test_results | tail -n 1)
echo "$summary"
echo "python: ran $py_ran, failed $py_failed, skipped $py_skipped"
if [ "$py_status" -ne 0 ]; then tail -n 40 "$py_log"; fi

# Each test once, from the XML files the test programs wrote (script_support.count_test_results): a rostest's
# own cases, not the wrapper catkin_test_results counts, whose one case passes even when the test node failed.
read -r c_tests c_fail c_skip < <(PYTHONPATH="$here/src" /usr/bin/python3 -c \
  'import sys; from along_route_localization.script_support import count_test_results as c; print(*c(sys.argv[1]))' \
  "$workspace/build/test_results" || echo "0 1 0")
total=$((c_tests + py_ran))
failed=$((c_fail + py_failed))
skipped=$((c_skip + py_skipped))
passed=$((total - failed - skipped))
catkin_test_results build/test_results >/dev/null 2>&1
catkin_status=$?
echo "tests: $passed passed, $failed failed, $skipped skipped"
if [ "$failed" -ne 0 ] || [ "$catkin_status" -ne 0 ] || [ "$py_status" -ne 0 ] || [ "$total" -eq 0 ]; then
  exit 1
fi
exit 0
