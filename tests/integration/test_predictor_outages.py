"""
The predictor's /diagnostics through outages, over DDS, in both clock modes (#25).

Each test runs the outage benchmark's scenario (``offline/benchmarks/outage.py``): real
simulator and predictor processes in namespaces, one case after another done to boat1's
simulator. Under simulated time (the demo's default) a paused, killed or doubled /clock
used to leave /diagnostics at OK until the source came back; on the wall clock a paused
source was "stale" for ever and two vessels shared one status. Bounds: the watchdog
(3 s) plus one report (1 s) plus 2 s of scheduling on a loaded 2-core machine for an
ERROR; one window of the source's data plus start-up for a recovery.
"""

import pytest

from offline.benchmarks.outage import OK, outage

pytestmark = pytest.mark.ros

WATCHDOG_S = 3.0        # watchdog_timeout's default
REPORT_S = 1.0          # diagnostics_period's default
SLACK_S = 2.0           # scheduling of three processes on a loaded machine
MAX_AGE_S = 5.0         # max_age's default: staleness on the wall clock
RE_ANCHOR_S = 5.0       # re_anchor_after's default
SIM_WINDOW_S = 6.0      # the 60 s window at 10x real time
WALL_WINDOW_S = 60.0    # the 60 s window at real time
START_S = 10.0          # a restarted simulator's start-up


def by_case(result) -> dict:
    return {c['case']: c for c in result['cases']}


def said(case, text: str) -> bool:
    return any(text in m for m in case['error_messages'])


@pytest.mark.slow   # two outages and their recoveries on /clock (about 45 s)
def test_under_sim_time_a_paused_or_doubled_clock_is_error_and_recovers(tmp_path):
    result = outage(['pause', 'second-clock'], clock='sim', outage_s=6.0, watch_s=60.0,
                    log_dir=tmp_path)
    cases = by_case(result)
    assert result['status_keys'] == [['/boat1/predictor: forecast', 'boat1/patrol_boat']]

    pause = cases['pause']   # was: OK for the whole pause, ERROR only after it
    assert pause['time_to_error_s'] is not None, pause
    assert pause['time_to_error_s'] <= WATCHDOG_S + REPORT_S + SLACK_S, pause
    assert said(pause, '/boat1/odom accepted for') or said(pause, '/clock has not moved'), \
        pause
    assert pause['recovered_forecast_after_s'] <= SIM_WINDOW_S + SLACK_S, pause
    assert pause['recovered_ok_after_s'] is not None, pause

    clock2 = cases['second-clock']   # was: "newest state is 994807 s old", no cause
    assert clock2['time_to_error_s'] <= WATCHDOG_S + REPORT_S + SLACK_S, clock2
    assert said(clock2, '2 publishers on /clock (/boat1/simulator, /intruder/simulator)'), \
        clock2
    assert clock2['recovered_forecast_after_s'] <= SIM_WINDOW_S + START_S, clock2


@pytest.mark.slow  # about 40 s: a simulator killed under sim time and started again
def test_under_sim_time_a_killed_clock_is_error_and_a_rewound_one_recovers(tmp_path):
    kill = outage(['kill'], clock='sim', outage_s=8.0, watch_s=60.0,
                  log_dir=tmp_path)['cases'][0]   # was: OK until the new simulator ran
    assert kill['time_to_error_s'] <= WATCHDOG_S + REPORT_S + SLACK_S, kill
    assert kill['recovered_forecast_after_s'] <= START_S + SIM_WINDOW_S + SLACK_S, kill
    assert kill['recovered_ok_after_s'] is not None, kill


@pytest.mark.slow  # about 5 minutes: two vessels at real time, a 60 s window each
def test_on_the_wall_clock_two_vessels_keep_their_own_status_through_outages(tmp_path):
    result = outage(['second-clock', 'pause', 'kill'], clock='wall', outage_s=10.0,
                    watch_s=150.0, log_dir=tmp_path)
    cases = by_case(result)
    # One status per node and vessel, never shared.
    assert result['status_keys'] == [['/boat1/predictor: forecast', 'boat1/patrol_boat'],
                                     ['/boat2/predictor: forecast', 'boat2/patrol_boat']]
    for case in cases.values():
        assert case['other_vessels_worst_level'] == {'boat2': OK}, case

    clock2 = cases['second-clock']   # no node reads /clock: nothing changes
    assert clock2['levels_during_outage'] == [OK], clock2

    pause = cases['pause']   # was: "inputs stale ... 29.5 s old" for as long as watched
    assert pause['time_to_error_s'] <= MAX_AGE_S + REPORT_S + SLACK_S, pause
    assert said(pause, 'inputs stale') and said(pause, '/boat1/odom'), pause
    assert pause['recovered_forecast_after_s'] <= RE_ANCHOR_S + REPORT_S + SLACK_S, pause
    assert pause['recovered_no_error_after_s'] is not None, pause
    # WARN, naming the shift, for as long as the stamps stay behind.
    assert any('stamps of /boat1/odom' in m and "s behind the node's clock" in m
               for m in pause['messages_after']), pause['messages_after']

    kill = cases['kill']     # restarted on the wall clock again: back in one window
    assert kill['time_to_error_s'] <= MAX_AGE_S + REPORT_S + SLACK_S, kill
    assert kill['recovered_forecast_after_s'] <= START_S + WALL_WINDOW_S + RE_ANCHOR_S, kill
    logs = (tmp_path / 'boat1_predictor.log').read_text()
    assert '/boat1/odom' in logs and '/vessel/odom' not in logs
