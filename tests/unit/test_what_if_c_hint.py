"""The retry time a "busy" answer gives (what_if_c.door.Hint, the door's own in C)."""

import pytest
from what_if_c.door import Hint


def test_refused_clients_are_spread_one_service_time_apart_after_the_running_one():
    hint = Hint(longest=10.0, smoothing=1.0)
    hint.admitted(0.0)
    hint.finished(0.0, 0.5)                # one answer: the service time is 0.5 s
    hint.admitted(1.0)                     # the running request, expected done at 1.5
    assert hint.refused(1.1) == pytest.approx(0.4)
    assert hint.refused(1.1) == pytest.approx(0.9)
    assert hint.refused(1.2) == pytest.approx(1.3)   # 2.5 s, a third place in line


def test_a_request_waiting_behind_another_starts_its_service_when_that_one_finishes():
    hint = Hint(longest=10.0, smoothing=1.0)
    hint.admitted(0.0)
    hint.admitted(0.1)                     # waits its turn behind the first
    hint.finished(0.0, 1.0)
    hint.finished(0.1, 2.0)                # served from 1.0 to 2.0, not from 0.1
    assert hint.service_time == pytest.approx(1.0)


def test_hints_never_exceed_the_longest_however_many_were_refused():
    hint = Hint(longest=2.0, smoothing=1.0)
    hint.admitted(0.0)
    hint.finished(0.0, 0.5)
    hint.admitted(1.0)
    hints = [hint.refused(1.0) for _ in range(20)]
    assert max(hints) == pytest.approx(2.0) and hints == sorted(hints)


def test_old_hints_do_not_push_new_clients_back():
    hint = Hint(longest=10.0, smoothing=1.0)
    hint.admitted(0.0)
    hint.finished(0.0, 0.5)
    hint.admitted(1.0)
    for _ in range(5):
        hint.refused(1.0)                  # booked until 3.5 s
    hint.finished(1.0, 1.5)
    hint.admitted(20.0)                    # long after every booked time
    assert hint.refused(20.1) == pytest.approx(0.4)


def test_before_any_answer_the_running_request_is_taken_as_half_done():
    hint = Hint(longest=10.0)
    hint.admitted(0.0)
    assert hint.refused(0.6) == pytest.approx(0.6)


def test_nothing_admitted_means_retry_at_once_and_bad_settings_are_refused():
    assert Hint(longest=1.0).refused(5.0) == 0.0
    with pytest.raises(ValueError, match='longest'):
        Hint(longest=0.0)
    with pytest.raises(ValueError, match='smoothing'):
        Hint(longest=1.0, smoothing=0.0)


def test_service_time_is_a_running_mean():
    hint = Hint(longest=10.0, smoothing=0.5)
    for start, end in ((0.0, 1.0), (2.0, 5.0)):
        hint.admitted(start)
        hint.finished(start, end)
    assert hint.service_time == pytest.approx(2.0)
