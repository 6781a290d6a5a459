"""The order in which a test session hands its files to parallel workers."""

from pathlib import Path

# The unit test files that take longest, longest first (seconds of a file's default
# tests, setup included, in one run on a 2-core machine, 2026-12-02: 43, 33, 30, 29, 28,
# 27, 25, 21, 18, 18, 18, 18, 17, 15, 12, 12, 10 of the 519 s all files took; measured
# with `pytest tests/unit -n 2 --dist loadfile --junitxml=FILE`, summed per file). They
# are collected ahead of the rest, and tools/run_tests.sh has pytest-xdist hand files to
# its workers in collection order (--no-loadscope-reorder; by default it orders them by
# their number of tests): a long file handed out last keeps one worker busy while the
# other idles (the real-data trainings' file, missing from an older list, once ran alone
# for the unit part's last 67 s).
#
# The default integration tests' time is mostly that of the live graphs they start, and
# two of the longest started together slowed each other (the suite took 245 s instead of
# 188-218 s): there pytest-xdist's own order stays.
LONGEST_FIRST = tuple(f'unit/test_{name}.py' for name in (
    'real_claims', 'diagnosis_multirotor', 'diagnosis_cases', 'crossval', 'models_engine',
    'training_launcher', 'diagnosis_families', 'training_distributed', 'real_training',
    'diagnosis_mmg', 'setup_script', 'simulate_cli', 'training_smoke',
    'multirotor_simulation', 'served_precision', 'set_bands_study', 'cross_bands'))
# The slow integration checks (make test-slow, three files at a time) wait on real-time
# clocks more than they compute: the files with the longest waits go out first. Dealt out
# in pytest-xdist's order, the wall-clock outages (3 min) once started after the others
# and the checks took 7.6 min; started first, 6.3 min.
SLOW_LIVE_FIRST = tuple(f'integration/test_{name}.py' for name in (
    'predictor_outages', 'bench_quick', 'ros2_launch'))
TESTS = Path(__file__).resolve().parent


def pytest_collection_modifyitems(config, items):
    """Put the longest files' tests first; within a file and among the rest keep the order."""
    first = LONGEST_FIRST + (SLOW_LIVE_FIRST if config.option.markexpr == 'slow' else ())
    rank = {name: i for i, name in enumerate(first)}

    def place(item) -> int:
        path = Path(str(item.path)).resolve()
        return rank.get(path.relative_to(TESTS).as_posix(), len(rank)) \
            if path.is_relative_to(TESTS) else len(rank)
    items.sort(key=place)
