#!/usr/bin/env bash
# Runs the package under the sanitizers and fuzzes its input paths:
# usage: scripts/run_sanitizers.sh [WORKDIR]        default WORKDIR: /tmp/along_route_sanitizers
#
#  1. ASan + UBSan: test_core and test_map_io built in WORKDIR/ws_asan (leaks checked).
#  2. TSan, built in WORKDIR/ws_tsan: test_map_io and two drivers for the threaded parts:
#     test/sanitizers/tsan_parallel.cpp (the parallel global search, cv::parallel_for_) and
#     test/sanitizers/tsan_map_recorder.cpp (the map recorder nodelet's writer thread; own rosmaster).
#     Not test_core: what it runs in parallel (its own parallel branches, OpenCV's resize) runs on
#     OpenCV's TBB pool, whose hand-over ThreadSanitizer cannot see (it reports races that are not there).
#  3. libFuzzer (clang, ASan + UBSan): test/fuzz/fuzz_map_loader.cpp (readMap) and
#     test/fuzz/fuzz_image_input.cpp (Preprocessor + Localizer), FUZZ_SECONDS (60) each, both at once,
#     from seeds written at run time by test/fuzz/fuzz_seeds.cpp. Installs clang when it is missing and
#     we are root; skips this stage otherwise.
# Build directories are kept in WORKDIR and reused. Suppressions (third-party code only) are in
# test/sanitizers/. Exit status 0 only when every check passed with no sanitizer report; the last line
# is "sanitizers: N passed, M failed".
case "${1:-}" in  # --help prints the comment above; another "-..." is refused before anything is done
  -h | --help) sed -n '2,/^[^#]/s/^# \{0,1\}//p' "${BASH_SOURCE[0]}"; exit 0 ;;
  -*) echo "run_sanitizers.sh: unknown option '$1' (see run_sanitizers.sh --help)" >&2; exit 2 ;;
esac
set -uo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
workdir="${1:-/tmp/along_route_sanitizers}"
fuzz_seconds="${FUZZ_SECONDS:-60}"
export PATH="/usr/bin:$PATH"
jobs=$(( $(nproc) < 2 ? $(nproc) : 2 ))
supp="$here/test/sanitizers"
mkdir -p "$workdir"
workdir="$(cd "$workdir" && pwd)"
# Ubuntu 20.04 with ROS Noetic in /opt/ros/noetic (untested here); Debian's ROS lives in /usr.
ros_prefix=""
if [ -f /opt/ros/noetic/setup.bash ]; then
  set +u
  # shellcheck disable=SC1091
  source /opt/ros/noetic/setup.bash
  set -u
  ros_prefix=/opt/ros/noetic
fi
ros_cflags=()
ros_ldflags=()
if [ -n "$ros_prefix" ]; then
  ros_cflags=(-I"$ros_prefix/include")
  ros_ldflags=(-L"$ros_prefix/lib" -Wl,-rpath,"$ros_prefix/lib")
fi

passed=0
failed=0
skipped=()
failures=()
pass() { passed=$((passed + 1)); echo "  PASS $1"; }
fail() { failed=$((failed + 1)); failures+=("$1"); echo "  FAIL $1: $2"; }
stage_start=0
begin() { stage_start=$(date +%s); echo "=== $1"; }
end() { echo "    ($1: $(( $(date +%s) - stage_start )) s)"; }

# Sanitizer reports in a log (ASan, LSan, UBSan, TSan); libFuzzer failures show in the exit status.
count_reports() {
  grep -cE '^(==[0-9]+==ERROR: (AddressSanitizer|LeakSanitizer)|WARNING: ThreadSanitizer|SUMMARY: UndefinedBehaviorSanitizer)|runtime error: ' "$1"
}

# run_check NAME LOG COMMAND...: runs a test program; fails on a non-zero exit or any sanitizer report.
run_check() {
  local name="$1" log="$2"
  shift 2
  "$@" >"$log" 2>&1
  local status=$? reports
  reports=$(count_reports "$log")
  if [ "$status" -eq 0 ] && [ "$reports" -eq 0 ]; then
    pass "$name ($(grep -E '^\[  PASSED  \]' "$log" | tail -n 1 | sed 's/^\[  PASSED  \] //'))"
  elif [ "$reports" -gt 0 ]; then
    fail "$name" "$reports sanitizer report(s), exit $status (log: $log)"
    grep -E -A 12 'ERROR: (Address|Leak)Sanitizer|WARNING: ThreadSanitizer|runtime error: ' "$log" | head -n 60
  else
    fail "$name" "exit $status, no sanitizer report (a test failed; log: $log)"
    grep -E '^\[  FAILED  \]|Failure$|^Expected|actual' "$log" | head -n 20
  fi
}

# build_ws WS "FLAGS" TARGETS...: the package linked into WS/src, built with the sanitizer FLAGS.
build_ws() {
  local ws="$1" flags="$2"
  shift 2
  mkdir -p "$ws/src"
  ln -sfn "$here" "$ws/src/along_route_localization"
  local link_flags
  link_flags="$(echo "$flags" | grep -oE -- '-fsanitize=[^ ]+')"
  # The Nordland folder as CMakeLists.txt finds it, given explicitly: a reused build directory must not
  # keep the path of an earlier clone.
  local nordland
  nordland="$(cd "$here/.." && pwd -P)/shared/data/nordland"
  ( cd "$ws" && catkin_make -j"$jobs" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCATKIN_ENABLE_TESTING=ON \
      "-DALONG_ROUTE_NORDLAND_DIR=$nordland" \
      "-DCMAKE_CXX_FLAGS=$flags" "-DCMAKE_C_FLAGS=$flags" \
      "-DCMAKE_EXE_LINKER_FLAGS=$link_flags" "-DCMAKE_SHARED_LINKER_FLAGS=$link_flags" \
      -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 "$@" ) >"$ws/build.log" 2>&1
}

# ---------------------------------------------------------------------------------------- ASan + UBSan
begin "ASan + UBSan: test_core, test_map_io"
ws_asan="$workdir/ws_asan"
if build_ws "$ws_asan" "-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=all" \
    test_core test_map_io; then
  end "build"
  bin="$ws_asan/devel/lib/along_route_localization"
  lsan_options="report_objects=1"
  [ -f "$supp/lsan.supp" ] && lsan_options="$lsan_options:suppressions=$supp/lsan.supp"
  for test in test_core test_map_io; do
    ASAN_OPTIONS=detect_leaks=1:halt_on_error=1:detect_stack_use_after_return=1:check_initialization_order=1 \
      LSAN_OPTIONS="$lsan_options" UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
      run_check "asan+ubsan $test" "$ws_asan/$test.log" "$bin/$test"
  done
else
  tail -n 40 "$ws_asan/build.log"
  fail "asan+ubsan build" "catkin_make failed (log: $ws_asan/build.log)"
fi
end "ASan + UBSan"

# ------------------------------------------------------------------------------------------------- TSan
begin "TSan: test_map_io, parallel search, map recorder writer thread"
ws_tsan="$workdir/ws_tsan"
tsan_flags="-fsanitize=thread -fno-omit-frame-pointer"
if build_ws "$ws_tsan" "$tsan_flags" test_map_io along_route_localization_nodelets; then
  end "build"
  lib="$ws_tsan/devel/lib"
  bin="$lib/along_route_localization"
  # The core and the package's own libraries, ThreadSanitizer-built: a gtest driver per threaded part.
  # tsan_parallel plugs a std::thread backend into cv::parallel_for_ (cv::parallel::ParallelForAPI,
  # OpenCV >= 4.5.2; Noetic's 4.2 has none, and its TBB / pthreads pool is not instrumented).
  drivers=(tsan_map_recorder)
  parallel_driver=false
  if pkg-config --atleast-version=4.5.2 opencv4; then
    drivers=(tsan_parallel tsan_map_recorder)
    parallel_driver=true
  else
    echo "  SKIP tsan parallel search: OpenCV $(pkg-config --modversion opencv4) has no pluggable parallel_for_" \
         "backend (needs 4.5.2); test_core checks compareMany's and the online DTW's parallel results"
    skipped+=("tsan parallel search (OpenCV < 4.5.2)")
  fi
  drivers_ok=true
  for driver in "${drivers[@]}"; do
    # shellcheck disable=SC2046
    g++ -std=c++14 -O2 -g -Wall -Wextra $tsan_flags -I"$here/include" -I"$here/src" -I"$ws_tsan/devel/include" \
      "${ros_cflags[@]+"${ros_cflags[@]}"}" $(pkg-config --cflags opencv4) \
      "$here/test/sanitizers/$driver.cpp" -o "$ws_tsan/$driver" -L"$lib" -Wl,-rpath,"$lib" \
      "${ros_ldflags[@]+"${ros_ldflags[@]}"}" \
      -lalong_route_localization_ros -lalong_route_localization_core -lnodeletlib -lroscpp -lrosconsole \
      -lroscpp_serialization -lrostime -lcpp_common -lboost_system -lopencv_core -lgtest -pthread \
      >"$ws_tsan/$driver.build.log" 2>&1 \
      || { cat "$ws_tsan/$driver.build.log"; fail "tsan $driver build" "g++ failed"; drivers_ok=false; }
  done
  export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 history_size=4 print_suppressions=1 suppressions=$supp/tsan.supp"
  run_check "tsan test_map_io" "$ws_tsan/test_map_io.log" "$bin/test_map_io"
  if [ "$drivers_ok" = true ]; then
    if [ "$parallel_driver" = true ]; then
      run_check "tsan parallel search" "$ws_tsan/tsan_parallel.log" "$ws_tsan/tsan_parallel"
    fi
    # The nodelet runs inside ROS's libraries, which are not instrumented: their boost::shared_ptr counts
    # and mutexes are partly handled in code ThreadSanitizer does not see. Data races stay reported (with
    # the ROS-internal ones in tsan_ros.supp); lock-order and mutex-misuse reports are off for this driver.
    port=$(( 20000 + RANDOM % 20000 ))
    while (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null; do port=$(( 20000 + RANDOM % 20000 )); done
    ros_env=(ROS_MASTER_URI="http://localhost:$port" ROS_HOSTNAME=localhost ROS_LOG_DIR="$workdir/ros_log")
    env "${ros_env[@]}" rosmaster --core -p "$port" >"$ws_tsan/rosmaster.log" 2>&1 &
    master=$!
    cat "$supp/tsan.supp" "$supp/tsan_ros.supp" >"$ws_tsan/tsan_ros.supp"
    # shellcheck disable=SC2016
    run_check "tsan map recorder writer thread" "$ws_tsan/tsan_map_recorder.log" env "${ros_env[@]}" \
      TSAN_OPTIONS="halt_on_error=1 print_suppressions=1 report_mutex_bugs=0 detect_deadlocks=0 suppressions=$ws_tsan/tsan_ros.supp" \
      bash -c 'set +u; source "$1/devel/setup.bash"; exec timeout 120 "$1/tsan_map_recorder"' _ "$ws_tsan"
    kill "$master" 2>/dev/null
    wait "$master" 2>/dev/null
  fi
  unset TSAN_OPTIONS
else
  tail -n 40 "$ws_tsan/build.log"
  fail "tsan build" "catkin_make failed (log: $ws_tsan/build.log)"
fi
end "TSan"

# --------------------------------------------------------------------------------------------- libFuzzer
begin "libFuzzer: map loader, image input (${fuzz_seconds} s each)"
fuzz="$workdir/fuzz"
have_clang=true
fuzzer_runtime() { clang++ -print-file-name=libclang_rt.fuzzer-x86_64.a 2>/dev/null; }
if ! command -v clang++ >/dev/null 2>&1 || [ ! -f "$(fuzzer_runtime)" ]; then
  if [ "$(id -u)" -eq 0 ]; then
    # Debian 12 ships libFuzzer in libclang-rt-14-dev; Ubuntu 20.04's clang (10) has it in its own packages.
    clang_packages=(clang)
    if apt-cache show libclang-rt-14-dev >/dev/null 2>&1; then
      clang_packages+=(libclang-rt-14-dev)
    fi
    echo "  installing ${clang_packages[*]} (libFuzzer)"
    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
        "${clang_packages[@]}"; } >"$workdir/apt.log" 2>&1 || { tail -n 20 "$workdir/apt.log"; have_clang=false; }
  else
    have_clang=false
  fi
fi
if [ "$have_clang" != true ] || ! command -v clang++ >/dev/null 2>&1 || [ ! -f "$(fuzzer_runtime)" ]; then
  echo "  SKIP libFuzzer: clang++ with libFuzzer (Debian: clang libclang-rt-14-dev) is missing and cannot be" \
       "installed here (not root, or apt failed)"
  skipped+=("libFuzzer (no clang)")
else
  mkdir -p "$fuzz/obj" "$fuzz/seeds/map" "$fuzz/seeds/image" "$fuzz/corpus/map_loader" \
    "$fuzz/corpus/image_input" "$fuzz/artifacts" "$fuzz/tmp"
  cat >"$fuzz/Makefile" <<'MAKE'
# Generated by scripts/run_sanitizers.sh: the core, the map file code and the fuzz targets, with clang.
SAN := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
, := ,
# Debian puts some ROS headers in their own folders (what catkin adds with find_package).
ROS_INCLUDES := $(addprefix -I,$(wildcard /usr/include/pluginlib /usr/include/class_loader /usr/include/xmlrpcpp \
  /usr/include/ament_index_cpp /usr/include/rcpputils /usr/include/rcutils $(ROS_PREFIX)/include))
# GENERATED: the package's generated message headers (map_io reads and writes KeyframeMotion), from the
# ASan workspace above.
CXXFLAGS := -std=c++14 -O1 -g -Wall -Wextra $(SAN) -fsanitize=fuzzer-no-link -I$(PKG)/include -I$(PKG)/src \
  -I$(GENERATED) $(ROS_INCLUDES) \
  $(shell pkg-config --cflags opencv4) -MMD -MP
LIBS := $(if $(ROS_PREFIX),-L$(ROS_PREFIX)/lib -Wl$(,)-rpath$(,)$(ROS_PREFIX)/lib) -lrosbag -lrosbag_storage -lroscpp -lrosconsole -lroscpp_serialization -lrostime -lcpp_common \
  -lconsole_bridge -lboost_system -lopencv_imgproc -lopencv_core -pthread
CORE := $(patsubst $(PKG)/src/core/%.cpp,obj/%.o,$(wildcard $(PKG)/src/core/*.cpp))

all: fuzz_map_loader fuzz_image_input fuzz_seeds
obj/%.o: $(PKG)/src/core/%.cpp
	clang++ $(CXXFLAGS) -c $< -o $@
obj/map_io.o: $(PKG)/src/glue/map_io.cpp
	clang++ $(CXXFLAGS) -c $< -o $@
obj/%.o: $(PKG)/test/fuzz/%.cpp
	clang++ $(CXXFLAGS) -c $< -o $@
fuzz_map_loader: obj/fuzz_map_loader.o obj/map_io.o $(CORE)
	clang++ $(SAN) -fsanitize=fuzzer $^ -o $@ $(LIBS)
fuzz_image_input: obj/fuzz_image_input.o $(CORE)
	clang++ $(SAN) -fsanitize=fuzzer $^ -o $@ $(LIBS)
fuzz_seeds: obj/fuzz_seeds.o obj/map_io.o $(CORE)
	clang++ $(SAN) $^ -o $@ $(LIBS)
-include $(wildcard obj/*.d)
MAKE
  if make -C "$fuzz" -j"$jobs" PKG="$here" ROS_PREFIX="$ros_prefix" GENERATED="$ws_asan/devel/include" \
      >"$fuzz/build.log" 2>&1; then
    end "build"
    export ASAN_OPTIONS=detect_leaks=1:halt_on_error=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
    [ -f "$supp/lsan.supp" ] && export LSAN_OPTIONS="suppressions=$supp/lsan.supp"
    rm -f "$fuzz"/seeds/map/* "$fuzz"/seeds/image/*
    if ! "$fuzz/fuzz_seeds" "$fuzz/seeds/map" "$fuzz/seeds/image" >"$fuzz/seeds.log" 2>&1; then
      cat "$fuzz/seeds.log"
      fail "fuzz seeds" "fuzz_seeds failed"
    else
      pids=()
      for target in map_loader image_input; do
        seeds="$fuzz/seeds/image"
        [ "$target" = map_loader ] && seeds="$fuzz/seeds/map"
        FUZZ_TMPDIR="$fuzz/tmp" "$fuzz/fuzz_$target" -max_total_time="$fuzz_seconds" -timeout=20 \
          -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 -artifact_prefix="$fuzz/artifacts/${target}-" \
          "$fuzz/corpus/$target" "$seeds" >"$fuzz/$target.log" 2>&1 &
        pids+=($!)
      done
      i=0
      for target in map_loader image_input; do
        wait "${pids[$i]}"
        status=$?
        i=$((i + 1))
        log="$fuzz/$target.log"
        runs=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' || echo "?")
        if [ "$status" -eq 0 ] && [ "$(count_reports "$log")" -eq 0 ]; then
          pass "fuzz $target ($runs inputs, corpus $(find "$fuzz/corpus/$target" -type f | wc -l) files)"
        else
          fail "fuzz $target" "exit $status after $runs inputs (log: $log; reproducer: $(ls -t "$fuzz/artifacts/${target}-"* 2>/dev/null | head -n 1))"
          grep -E -B 2 -A 25 'ERROR: (Address|Leak)Sanitizer|runtime error: |ERROR: libFuzzer|terminate called|uncaught' "$log" | head -n 60
        fi
      done
    fi
    unset ASAN_OPTIONS UBSAN_OPTIONS LSAN_OPTIONS
  else
    tail -n 40 "$fuzz/build.log"
    fail "fuzz build" "clang build failed (log: $fuzz/build.log)"
  fi
fi
end "libFuzzer"

echo "=== summary"
for f in "${failures[@]+"${failures[@]}"}"; do echo "  failed: $f"; done
for s in "${skipped[@]+"${skipped[@]}"}"; do echo "  skipped: $s"; done
echo "sanitizers: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
