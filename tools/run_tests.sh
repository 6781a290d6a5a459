#!/usr/bin/env bash
# Quality gates, then pytest. Arguments go to pytest; --lint-only stops after the gates;
# --slow runs the slow checks (make test-slow) the way the default suite runs the others.
# Run through tools/with_env.sh (make test does).
set -uo pipefail

echo '== ruff (pycodestyle, pyflakes, imports, pep257, naming, quotes)'
ruff check . || exit 1
echo '== ament_pep257 on the ROS packages'
report="$(ament_pep257 ros2_ws/src 2>&1)" || { grep -v '^checking ' <<<"$report"; exit 1; }
tail -n 1 <<<"$report"
[ "${1:-}" = "--lint-only" ] && exit 0

# A DDS domain of its own for this test session, so parallel sessions never cross.
export ROS_DOMAIN_ID="${TEST_ROS_DOMAIN_ID:-$((110 + $$ % 100))}"
# Compiled forecast programs (hybrid_models.engine) go to one cache in the build tree,
# not the user's home: the nodes the tests start compile the same ones, and each loads
# what another compiled. An empty value set by the caller keeps nothing.
export JAX_COMPILATION_CACHE_DIR="${JAX_COMPILATION_CACHE_DIR-$PWD/ros2_ws/build/jax_cache}"
pytest_run() {
  python -m pytest "$@"
  local rc=$?
  if [ "$rc" -eq 5 ]; then
    echo 'run_tests: error: pytest collected no tests; a suite that runs nothing does not pass' >&2
    return 1
  fi
  return "$rc"
}

echo "== pytest (ROS_DOMAIN_ID=$ROS_DOMAIN_ID, discovery $ROS_AUTOMATIC_DISCOVERY_RANGE)"
marker=()
if [ "${1:-}" = "--slow" ]; then
  shift
  marker=(-m slow)
  # The slow unit checks are long proofs that share a file's measurement (a module
  # fixture or cache): dealt out a file at a time, each measurement is made once.
  # (pytest-xdist's loadgroup, which would group tests across files, does nothing under
  # pytest 9.) In pytest-xdist's order (by number of tests) the real-data studies' 233 s
  # of torch training run last, alone; dealt out longest first they ran beside the
  # nanodrone's diagnosis and both slowed (319 s; the unit part 21.3 min against 19.8).
  dist=(--dist loadfile)
  longest=15
  # The slow integration checks wait on real-time clocks most of the time (one core's
  # worth of CPU over their 8.4 min at two files at a time): three at a time, the longest
  # waits first (tests/conftest.py), took 6.3 min, each check passing.
  live=3
  live_dist=(--dist loadfile --no-loadscope-reorder)
else
  dist=(--dist loadfile --no-loadscope-reorder)
  longest=8
  live=2
  live_dist=(--dist loadfile)
fi
# Other arguments (focused files, -m slow, ...) run as given, in one process.
[ "$#" -gt 0 ] && { pytest_run "${marker[@]}" "$@"; exit $?; }
# The whole default suite: the unit tests are CPU-bound numerics with no clock in their
# verdicts, so they share the cores (one process per core, a test file per process).
# The integration tests, after them, start live ROS graphs that mostly wait on their
# clocks: a few files at a time, each worker in a DDS domain of its own (conftest.py).
cores="$(python -c 'import os; print(len(os.sched_getaffinity(0)))')"
workers="$(( cores < 4 ? cores : 4 ))"
# Threads matched to cores: each unit worker's BLAS (numpy's and scipy's OpenBLAS) gets
# its share of the cores, not all of them. Two workers of two BLAS threads each on two
# cores spin against each other: diagnosis-heavy files took 14-16 % longer (31.4-31.9 s
# against 27.0-27.6 s for test_diagnosis_cases and _families, -n 2), and the nanodrone's
# diagnosis run whole took 172 and 180 s in the slow run before, 102 and 111 s after.
# torch's OpenMP threads are left as they are: one each made the short real-data
# trainings slower (52 s against 38 s). A caller's own setting is kept.
share="$(( cores / workers > 0 ? cores / workers : 1 ))"
# The slowest tests are listed at the end of each run: the suite must stay within its
# time budget (README), and CI's log then says where the time went.
(
  export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-$share}"
  pytest_run tests/unit "${marker[@]}" -n "$workers" "${dist[@]}" --durations="$longest"
)
unit=$?
pytest_run tests/integration "${marker[@]}" -n "$live" "${live_dist[@]}" --durations="$longest"
integration=$?
[ "$unit" -eq 0 ] && [ "$integration" -eq 0 ]
