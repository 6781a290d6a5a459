"""
Time alignment and alternative sources in a recording map.

A log whose position and velocities are stamped half a second after they were measured
(a filtering tracker) is made here from an exact track: the map checks must find the
lag, name the map entries and the delay_s that remove it, and the converted run must
equal the truth once the map carries them. A topic map may list alternative sources;
the first present in a bag wins, layouts of several entries together.
"""

import numpy as np
import pytest

from vessel_datasets import column_map, map_checks, pipeline, synthetic
from vessel_datasets.bag_source import find_bags
from vessel_datasets.readers.bags import bag_to_runs, convert_bag
from vessel_datasets.readers.tables import TableRecordings
from vessel_datasets.sources import ConversionError
from vessel_datasets.topic_map import parse_topic_map, topic_map_for
from vessel_description import load_vessel, parse_vessel

from .tracks import csv_table, trajectory

VESSEL = parse_vessel({
    'name': 'tracked_model', 'rate_hz': 10.0, 'window_s': 1.0, 'horizon_s': 5.0,
    'states': ['u', 'v', 'r'],
    'limits': {'u': [-1.0, 3.0], 'v': [-1.0, 1.0], 'r': [-1.0, 1.0]},
    'actuators': {'n': {'kind': 'propeller', 'range': [0.0, 100.0]},
                  'delta': {'kind': 'rudder', 'range': [-0.6, 0.6]}},
    'particulars': {'length_m': 2.0}})
DELAY_S = 0.5
BODY_MAP = {
    'sep': ',', 'header_row': True, 'time': {'column': 'time', 'unit': 's'},
    'velocity': {'frame': 'body', 'surge': 'u', 'sway': 'v'},
    'yaw_rate': {'column': 'r_deg', 'unit': 'deg/s'},
    'heading': {'column': 'hdg_deg', 'unit': 'deg'},
    'position': {'frame': 'ned', 'x': 'north_m', 'y': 'east_m'},
    'actuators': {'n': {'column': 'rpm', 'unit': 'rpm'},
                  'delta': {'column': 'rudder_deg', 'unit': 'deg', 'sign': -1}},
}


def lagging_log(path, truth):
    """Write the track with position and body velocities DELAY_S late (as a tracker does)."""
    table = csv_table(truth).assign(u=truth['u'], v=truth['v'])
    t = truth['t']
    for column, values in (('u', truth['u']), ('v', truth['v']), ('north_m', truth['x']),
                           ('east_m', truth['y'])):
        table[column] = np.interp(t - DELAY_S, t, values)
    table = table[t >= DELAY_S]  # before that the late fields have no sample yet
    table.to_csv(path, index=False, float_format='%.12g')
    return path


def convert(path, mapping):
    cmap = column_map.parse_column_map(mapping, VESSEL)
    (result,) = pipeline.convert_all([path], TableRecordings(cmap), cmap.topic_map,
                                     pipeline.Options.from_yaml())
    assert not result.error, result.error
    per_run = pipeline.run_checks([result], cmap.topic_map, False)
    pooled = map_checks.aggregate(per_run, map_checks.context_for(cmap.topic_map))
    return result, {c.name.split()[0]: c for c in pooled}


def test_a_delayed_field_is_found_and_the_map_entry_that_corrects_it_suggested(tmp_path):
    truth = trajectory(duration_s=120.0)
    path = lagging_log(tmp_path / 'tracked.csv', truth)
    _, checks = convert(path, BODY_MAP)
    timing = checks['timing']
    assert not timing.ok
    assert 'heading -0.50 s' in timing.message  # the heading runs 0.5 s ahead
    assert 'columns.velocity: delay_s: 0.5' in timing.message
    assert 'columns.position: delay_s: 0.5' in timing.message
    assert 'columns.yaw_rate' not in timing.message and 'columns.heading' not in timing.message
    assert not checks['course'].ok  # the lag turns the velocity off the track


def test_with_the_delay_in_the_map_the_run_is_the_truth_and_every_check_passes(tmp_path):
    truth = trajectory(duration_s=120.0)
    path = lagging_log(tmp_path / 'tracked.csv', truth)
    late = BODY_MAP | {'velocity': BODY_MAP['velocity'] | {'delay_s': DELAY_S},
                       'position': BODY_MAP['position'] | {'delay_s': DELAY_S}}
    result, checks = convert(path, late)
    assert all(c.ok for c in checks.values()), [c.line() for c in checks.values()]
    assert abs(checks['timing'].figure) < 0.1
    ((run_id, table),) = result.runs.items()
    start = result.run_sources[run_id]['start_ns'] / 1e9
    t = table['t'].to_numpy() + start
    for column in ('u', 'v', 'r'):
        np.testing.assert_allclose(table[column], np.interp(t, truth['t'], truth[column]),
                                   atol=1e-3, err_msg=column)
    # Positions are north/east of the run's start, measured at the same moments.
    x = np.interp(t, truth['t'], truth['x'])
    np.testing.assert_allclose(table['x'], x - x[0], atol=1e-3)


# ----------------------------------------------------------------- alternatives
SHIP = load_vessel('patrol_boat')


def with_alternatives(first, second):
    """Return the patrol boat's map with its propeller read from the first of two sources."""
    data = topic_map_for(SHIP).to_dict()
    data['actuators']['n'] = [first, second]
    return parse_topic_map(data, SHIP)


ACTUATORS = {'topic': '/vessel/actuators', 'field': 'velocity[propeller]'}
OTHER = {'topic': '/motors/feedback', 'field': 'rpm', 'scale': 0.10471975511965977}


def test_the_first_source_a_bag_has_wins_and_the_report_says_which(tmp_path):
    traj = synthetic.demo_trajectory(60)
    bag = synthetic.write_bag(tmp_path / 'bag', traj)
    (found,) = find_bags([bag])
    for topic_map in (with_alternatives(OTHER, ACTUATORS), with_alternatives(ACTUATORS, OTHER)):
        result = convert_bag(found, topic_map)
        assert result.error is None
        assert result.report['alternatives'] == {'actuators.n': '/vessel/actuators '
                                                                'velocity[propeller]'}
        (table,) = result.runs.values()
        np.testing.assert_allclose(table['n'], traj.columns['n'][:len(table)], atol=1e-9)
    with pytest.raises(ConversionError, match=r'needs /motors/feedback \(actuators.n\)'):
        bag_to_runs(bag, with_alternatives(OTHER, OTHER | {'field': 'x'}))


def test_alternatives_of_several_entries_are_taken_as_one_layout():
    data = topic_map_for(SHIP).to_dict()
    odom = data['body_velocity']['surge']
    # Layout 1: a recorder's /nav topics with their own delay; layout 2: the odometry.
    data['body_velocity']['surge'] = [{'topic': '/nav', 'field': 'u', 'delay_s': 0.3}, odom]
    data['actuators']['n'] = [{'topic': '/nav_act', 'field': 'n'}, ACTUATORS]
    topic_map = parse_topic_map(data, SHIP)
    used, chosen = topic_map.resolve({'/vessel/odom', '/vessel/actuators', '/vessel/wind'})
    assert chosen == {'body_velocity.surge': '/vessel/odom twist.twist.linear.x',
                      'actuators.n': '/vessel/actuators velocity[propeller]'}
    used, chosen = topic_map.resolve({'/nav', '/nav_act', '/vessel/odom', '/vessel/actuators',
                                      '/vessel/wind'})
    assert chosen['body_velocity.surge'] == '/nav u (delay 0.3 s)'
    assert {e.topic for e in used.entries if e.name in ('surge', 'n')} == {'/nav', '/nav_act'}
