"""The test session's longest-first list names test files that exist."""

from tests.conftest import LONGEST_FIRST, TESTS


def test_every_file_of_the_longest_first_list_exists_once():
    files = {p.relative_to(TESTS).as_posix() for p in TESTS.glob('*/test_*.py')}
    missing = [name for name in LONGEST_FIRST if name not in files]
    assert not missing, f'tests/conftest.py LONGEST_FIRST names missing files {missing}'
    assert len(set(LONGEST_FIRST)) == len(LONGEST_FIRST)
