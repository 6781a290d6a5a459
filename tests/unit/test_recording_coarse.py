"""
Coarse columns: a log printed to three significant digits, and a GPS-only log.

The files are made here from exact tracks. A ship log whose time, position and heading
are printed to three significant digits (10 m position steps beyond 1 km, 1 deg
heading steps beyond 100 deg, 10 s time steps beyond 1000 s) must be named column by
column, and a right map must pass its checks on it -- judged at a scale the resolution
allows -- while a wrong one still fails. A log of GPS fixes (held between updates), a
whole-degree heading and a speed over ground in knots must import with body velocities
from its track.
"""

import numpy as np
import pandas as pd
import pytest

from vessel_datasets import column_map, map_checks, pipeline
from vessel_datasets.quantities import local_projection
from vessel_datasets.readers.tables import TableRecordings
from vessel_description import parse_vessel

from .tracks import KNOT, csv_table, trajectory

SHIP = parse_vessel({
    'name': 'tanker', 'rate_hz': 1.0, 'window_s': 60.0, 'horizon_s': 600.0,
    'states': ['u', 'v', 'r'],
    'limits': {'u': [-2.0, 10.0], 'v': [-3.0, 3.0], 'r': [-0.05, 0.05]},
    'actuators': {'n': {'kind': 'propeller', 'range': [0.0, 100.0]},
                  'delta': {'kind': 'rudder', 'range': [-0.6, 0.6]}},
    'particulars': {'length_m': 320.0}})
SHIP_MAP = {
    'sep': ',', 'header_row': True, 'rate_hz': 1.0,
    'velocity': {'frame': 'earth', 'north': 'vn_kn', 'east': 've_kn', 'unit': 'knots'},
    'yaw_rate': {'column': 'r_deg', 'unit': 'deg/s'},
    'heading': {'column': 'hdg_deg', 'unit': 'deg'},
    'position': {'frame': 'ned', 'x': 'north_m', 'y': 'east_m'},
    'actuators': {'n': {'column': 'rpm', 'unit': 'rpm'},
                  'delta': {'column': 'rudder_deg', 'unit': 'deg', 'sign': -1}},
}


def coarse_log(path):
    """Write a 320 m ship's 30-minute log at 1 Hz, every number printed to 3 digits."""
    truth = trajectory(duration_s=1800.0, rate_hz=1.0, speed=8.0, scale=20.0)
    table = csv_table(truth)
    table['hdg_deg'] %= 360.0  # 0..360 deg, as ships log it
    table.to_csv(path, index=False, float_format='%.3g')
    return path


def convert(path, mapping, vessel=SHIP):
    cmap = column_map.parse_column_map(mapping, vessel)
    (result,) = pipeline.convert_all([path], TableRecordings(cmap), cmap.topic_map,
                                     pipeline.Options.from_yaml())
    assert not result.error, result.error
    per_run = pipeline.run_checks([result], cmap.topic_map, False)
    ((_, checks),) = per_run.items()
    pooled = map_checks.aggregate(per_run, map_checks.context_for(cmap.topic_map))
    by_name = {c.name.split()[0]: c for c in checks}
    by_name.update({c.name.split()[0]: c for c in pooled if c.detail['kind'] in
                    map_checks.POOLED})
    return cmap, result, by_name


def test_a_quantised_log_is_named_column_by_column(tmp_path):
    path = coarse_log(tmp_path / 'tanker.csv')
    _, result, _ = convert(path, SHIP_MAP)
    notes = result.report['notes']
    assert any(n.startswith('columns.position (north_m, east_m) repeats') for n in notes)
    heading = next(n for n in notes if n.startswith('columns.heading (hdg_deg)'))
    assert "coarser than the vessel's 1 s sample period" in heading
    # The checks compare positions over seconds, not from one sample to the next.
    assert result.report['resolution']['position']['scale_s'] > 5.0
    assert result.report['resolution']['heading']['scale_s'] > 5.0
    # With the time column, printed as 1.0e3, 1.01e3 ...: too coarse for its rows.
    _, result, _ = convert(path, {k: v for k, v in SHIP_MAP.items() if k != 'rate_hz'}
                           | {'time': {'column': 'time', 'unit': 's'}})
    assert any(n.startswith('columns.time (time) repeats its previous value') and
               'give rate_hz' in n for n in result.report['notes'])
    assert result.report['duplicate_times'] > 700


def test_a_right_map_passes_on_coarse_data_and_a_wrong_one_still_fails(tmp_path):
    path = coarse_log(tmp_path / 'tanker.csv')
    cmap, result, checks = convert(path, SHIP_MAP)
    assert all(c.ok for c in checks.values()), [c.line() for c in checks.values()]
    assert checks['velocity'].figure is not None and checks['yaw_rate'].figure is not None
    # Judged sample by sample, the same right map would fail on the printing alone.
    ((run_id, table),) = result.runs.items()
    naive = {c.name.split()[0]: c for c in map_checks.consistency_checks(
        table, cmap.topic_map, map_checks.context_for(cmap.topic_map))}
    assert not naive['velocity'].ok or not naive['yaw_rate'].ok
    # A wrong unit or convention still fails at the coarse scale.
    _, _, knots = convert(path, SHIP_MAP | {'velocity': SHIP_MAP['velocity'] | {'unit': 'm/s'}})
    assert not knots['velocity'].ok and 'knots given as m/s' in knots['velocity'].message
    _, _, mirrored = convert(path, SHIP_MAP | {
        'heading': {'column': 'hdg_deg', 'unit': 'deg', 'convention': 'east_counterclockwise'}})
    assert not mirrored['yaw_rate'].ok and 'sign flip' in mirrored['yaw_rate'].message



def zigzag_log(path, rate_hz=7.4):
    """
    Write a ship's 10 min zig-zag logged at ``rate_hz``, every number printed to 3 digits.

    North runs to 4.8 km (10 m steps beyond 1 km) while east stays within a few hundred
    metres, finely printed: the steps differ by magnitude within one column pair.
    """
    t = np.arange(int(600 * rate_hz)) / rate_hz
    psi = np.radians(15.0) * np.sin(2 * np.pi * t / 150.0)
    r = np.gradient(psi, t)
    u, v = 8.0 - 0.3 * (psi / psi.max()) ** 2, -0.15 * np.sin(2 * np.pi * t / 150.0 + 0.3)
    north_dot = u * np.cos(psi) - v * np.sin(psi)
    east_dot = u * np.sin(psi) + v * np.cos(psi)
    north = np.concatenate([[0.0], np.cumsum(0.5 * (north_dot[1:] + north_dot[:-1]) / rate_hz)])
    east = np.concatenate([[0.0], np.cumsum(0.5 * (east_dot[1:] + east_dot[:-1]) / rate_hz)])
    pd.DataFrame({'time': t, 'vn_kn': north_dot / KNOT, 've_kn': east_dot / KNOT,
                  'r_deg': np.degrees(r), 'hdg_deg': np.degrees(psi) % 360.0,
                  'north_m': north, 'east_m': east, 'rpm': 90.0 + 0 * t,
                  'rudder_deg': -15.0 * np.sign(np.sin(2 * np.pi * t / 150.0 + 0.4))}
                 ).to_csv(path, index=False, float_format='%.3g')
    return path


def test_steps_that_grow_with_the_value_are_judged_where_they_are_coarsest(tmp_path):
    path = zigzag_log(tmp_path / 'zigzag.csv')
    zigzag_map = SHIP_MAP | {'rate_hz': 7.4}
    _, result, checks = convert(path, zigzag_map)
    position = result.report['resolution']['position']
    assert position['step'] >= 5.0, position   # the 10 m steps, not the fine ones near 0
    assert all(c.ok for c in checks.values()), [c.line() for c in checks.values()]
    # Earth-frame velocities mapped as body ones still fail on the same coarse track.
    _, _, body = convert(path, zigzag_map | {'velocity': {
        'frame': 'body', 'surge': 'vn_kn', 'sway': 've_kn', 'unit': 'knots'}})
    assert not body['course'].ok, body['course'].line()


# ----------------------------------------------------------------- GPS only
BOAT = parse_vessel({
    'name': 'gps_boat', 'rate_hz': 1.0, 'window_s': 5.0, 'horizon_s': 20.0,
    'states': ['u', 'v', 'r'],
    'limits': {'u': [-1.0, 3.0], 'v': [-1.0, 1.0], 'r': [-1.0, 1.0]},
    'actuators': {'n': {'kind': 'propeller', 'range': [0.0, 100.0]},
                  'delta': {'kind': 'rudder', 'range': [-0.6, 0.6]}},
    'particulars': {'length_m': 1.5}})
GPS_MAP = {
    'sep': ',', 'header_row': True, 'time': {'column': 'time', 'unit': 's'},
    'heading': {'column': 'heading', 'unit': 'deg'},
    'position': {'frame': 'latlon', 'lat': 'lat', 'lon': 'lon'},
    'speed_over_ground': {'column': 'speed', 'unit': 'knots'},
    'actuators': {'n': {'column': 'rpm', 'unit': 'rpm'},
                  'delta': {'column': 'rudder_deg', 'unit': 'deg', 'sign': -1}},
}
LAT0, LON0 = 26.0672, 119.1617


def gps_log(path):
    """Write rows every 0.5 s: a fix once a second (held), whole degrees, knots."""
    truth = trajectory(duration_s=240.0, rate_hz=2.0, speed=0.8, turn=0.5)
    table = csv_table(truth)
    fix = np.arange(len(table)) // 2 * 2  # each fix holds for the next row
    north, east = truth['x'][fix] - truth['x'][0], truth['y'][fix] - truth['y'][0]
    lon, lat = local_projection(LAT0, LON0).transform(east, north, direction='INVERSE')
    speed = np.hypot(truth['north_dot'], truth['east_dot'])[fix] / KNOT
    gps = pd.DataFrame({'time': truth['t'], 'lat': np.round(lat, 7), 'lon': np.round(lon, 7),
                        'speed': np.round(speed, 2),
                        'heading': np.round(np.degrees(truth['psi'])) % 360,
                        'rpm': table['rpm'], 'rudder_deg': table['rudder_deg']})
    gps.to_csv(path, index=False, float_format='%.10g')
    return truth, path


def test_a_gps_only_log_gives_body_velocities_from_its_track(tmp_path):
    truth, path = gps_log(tmp_path / 'gps.csv')
    cmap, result, checks = convert(path, GPS_MAP, BOAT)
    assert map_checks.context_for(cmap.topic_map).derived == ('r', 'track')
    assert all(c.ok for c in checks.values()), [c.line() for c in checks.values()]
    assert 'velocity' not in checks  # the track cannot be checked against itself
    assert checks['course'].figure is None and 'from the track' in checks['course'].message
    assert checks['speed'].figure is not None and abs(checks['speed'].figure - 1) < 0.05
    assert checks['heading'].figure is not None
    ((run_id, table),) = result.runs.items()
    start = result.run_sources[run_id]['start_ns'] / 1e9
    t = table['t'].to_numpy() + start
    inner = slice(5, -5)  # a smoothing spline is less sure at the ends of the track
    for column in ('u', 'v'):
        error = table[column].to_numpy() - np.interp(t, truth['t'], truth[column])
        assert np.median(np.abs(error[inner])) < 0.02, column
    drift = np.degrees(np.arctan2(table['v'], table['u']))[inner]
    true_drift = np.degrees(np.arctan2(truth['v'], truth['u']))
    assert np.abs(drift - np.interp(t, truth['t'], true_drift)[inner]).max() < 5.0


def test_a_gps_only_log_with_a_mirrored_heading_fails(tmp_path):
    _, path = gps_log(tmp_path / 'gps.csv')
    _, _, checks = convert(path, GPS_MAP | {'heading': {'column': 'heading', 'unit': 'deg',
                                                        'convention': 'east_counterclockwise'}},
                           BOAT)
    turn = checks['heading']
    assert not turn.ok and turn.figure < 0 and 'turns against the track' in turn.message


def test_a_smooth_float_track_is_not_coarse_wherever_its_speed_grows_with_its_values():
    """
    A motion-capture track in float32 at 10 Hz, faster where its values are larger.

    Each magnitude band's slowest changes are its motion, not a printed step: the
    snuboat's tracks were judged coarse for it, the position comparison smoothed longer
    and its lag moved from -0.07 s to -0.12 s (issue 46, defect 1).
    """
    from vessel_datasets import resolution

    t = np.arange(0.0, 120.0, 0.1)
    rng = np.random.default_rng(0)
    speed = 0.05 + 0.3 * (t / t[-1])                     # 0.05 to 0.35 m/s
    north = (5.0 + np.cumsum(speed) * 0.1 + 1e-4 * rng.normal(size=len(t)))
    east = (2.0 + 0.3 * np.sin(t / 20.0))
    track = np.column_stack([north, east]).astype(np.float32).astype(float)
    t_ns = np.round(t * 1e9).astype(np.int64)
    assert resolution.analyse('position', t_ns, track, 'm') is None
    # The same track printed in 1 cm steps is coarse: its changes are whole centimetres.
    printed = np.round(track * 100.0) / 100.0
    coarse = resolution.analyse('position', t_ns, printed, 'm')
    assert coarse is not None
    assert coarse.step / 0.01 == pytest.approx(round(coarse.step / 0.01), abs=1e-6)
