"""6-DOF recordings through the one pipeline: a Parquet flight, its map checks, refusals."""

import copy
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vessel_datasets.column_map import ColumnMapError, parse_column_map
from vessel_datasets.map_checks import aggregate, check_run, context_for
from vessel_datasets.pipeline import Options, convert
from vessel_datasets.readers.tables import TableRecordings
from vessel_description import load_vessel, parse_vessel
from vessel_physics import frames
from vessel_physics.integrator import body_to_ned

from .tracks import spatial_flight as flight

REAL = Path(__file__).resolve().parents[2].parent / 'shared' / 'real' / 'nanodrone'


def as_recorded(truth):
    """Return the flight as the nanodrone benchmark's tables give it: ENU, FLU, eRPM."""
    north, east, down = body_to_ned(truth['u'], truth['v'], truth['w'], truth['phi'],
                                    truth['theta'], truth['psi'])
    x, y, z = frames.position_ned_to_enu(truth['x'], truth['y'], truth['z'])
    qx, qy, qz, qw = frames.orientation_ned_to_enu(truth['phi'], truth['psi'], truth['theta'])
    roll, pitch, yaw = frames.euler_from_quaternion(qx, qy, qz, qw)
    wx, wy, wz = frames.body_frd_to_flu(truth['p'], truth['q'], truth['r'])
    table = {'t': truth['t'], 'x': x, 'y': y, 'z': z + 1.0, 'vx': east, 'vy': north,
             'vz': -down, 'roll': roll, 'pitch': pitch, 'yaw': yaw, 'wx': wx, 'wy': wy,
             'wz': wz}
    for i, speed in enumerate(truth['motors']):
        table[f'm{i + 1}_erpm'] = speed * 6 * 60 / (2 * math.pi)
    return pd.DataFrame(table)


@pytest.fixture(scope='module')
def vehicle():
    return load_vessel('crazyflie_brushless')


def map_of(vehicle, **changes):
    columns = copy.deepcopy(vehicle.recordings['columns'])
    columns.update(changes)
    return parse_column_map(columns, vehicle)


def converted(tmp_path, vehicle, table, cmap=None, name='flight'):
    path = tmp_path / f'{name}.parquet'
    table.to_parquet(path)
    cmap = cmap or map_of(vehicle)
    reader = TableRecordings(cmap)
    result = convert(reader.find([path])[0], reader, cmap.topic_map, Options())
    assert result.error is None, result.error
    (run_id, run), = result.runs.items()
    return run, result, cmap


def checks_of(result, cmap):
    ctx = context_for(cmap.topic_map, interval_s=0.01)
    per_run = {rid: check_run(run, cmap.topic_map, ctx,
                              result.context[rid]['spikes'])
               for rid, run in result.runs.items()}
    return per_run, aggregate(per_run, ctx)


def test_a_parquet_flight_imports_into_the_model_frames_exactly(tmp_path, vehicle):
    truth = flight()
    run, _, _ = converted(tmp_path, vehicle, as_recorded(truth))
    assert tuple(run.columns) == vehicle.dataset_columns
    for state in ('u', 'v', 'w', 'p', 'q', 'r', 'phi', 'theta', 'psi'):
        np.testing.assert_allclose(run[state], truth[state], atol=1e-9, err_msg=state)
    for axis in ('x', 'y', 'z'):
        np.testing.assert_allclose(run[axis], truth[axis] - truth[axis][0], atol=1e-9)
    # Electrical rpm of six pole pairs, read as rpm / 6, become shaft rad/s.
    np.testing.assert_allclose(run['m3'], truth['motors'][2], rtol=1e-12)


def test_every_map_check_passes_on_a_right_map_and_none_is_skipped(tmp_path, vehicle):
    run, result, cmap = converted(tmp_path, vehicle, as_recorded(flight()))
    per_run, pooled = checks_of(result, cmap)
    lines = [c.line() for c in per_run['flight']]
    assert all(c.ok for c in per_run['flight']), lines
    judged = {c.name: c for c in pooled}
    for name in ('velocity vs d(position)/dt', 'vertical velocity vs d(z)/dt',
                 'course of velocity vs of d(position)/dt', 'yaw_rate vs d(heading)/dt',
                 'roll_rate vs d(roll)/dt', 'pitch_rate vs d(pitch)/dt'):
        assert judged[name].ok and judged[name].figure is not None, judged[name].line()
    assert judged['velocity vs d(position)/dt'].figure == pytest.approx(1.0, abs=0.01)
    # The hull's checks do not apply to a vehicle that flies sideways: said, not failed.
    hull = {c.name: c.message for c in per_run['flight']}
    assert 'need not point where it flies' in hull['heading rate vs course rate']


@pytest.mark.parametrize('changes, failing', [
    ({'velocity': {'frame': 'earth', 'north': 'vx', 'east': 'vy',
                   'down': {'column': 'vz', 'sign': -1}}},
     'course of velocity vs of d(position)/dt'),                     # axes swapped
    ({'velocity': {'frame': 'earth', 'north': 'vy', 'east': 'vx', 'down': 'vz'}},
     'vertical velocity vs d(z)/dt'),                                # up read as down
    ({'pitch': {'column': 'pitch', 'sign': -1}}, 'pitch_rate vs d(pitch)/dt'),
    ({'yaw_rate': {'column': 'wz', 'unit': 'deg/s', 'sign': -1}},
     'yaw_rate vs d(heading)/dt'),                                   # rad/s read as deg/s
])
def test_a_wrong_map_fails_the_check_that_names_it(tmp_path, vehicle, changes, failing):
    cmap = map_of(vehicle, **changes)
    run, result, cmap = converted(tmp_path, vehicle, as_recorded(flight()), cmap)
    _, pooled = checks_of(result, cmap)
    verdict = {c.name: c for c in pooled}
    assert not verdict[failing].ok, verdict[failing].line()


def test_a_six_dof_column_map_refuses_what_it_cannot_read(vehicle):
    columns = vehicle.recordings['columns']
    with pytest.raises(ColumnMapError, match="missing 'pitch_rate'"):
        parse_column_map({k: v for k, v in columns.items() if k != 'pitch_rate'}, vehicle)
    with pytest.raises(ColumnMapError, match='lacks .down.'):
        parse_column_map({**columns, 'velocity': {'frame': 'earth', 'north': 'vy',
                                                  'east': 'vx'}}, vehicle)
    with pytest.raises(ColumnMapError, match='delimited text only'):
        parse_column_map({**columns, 'sep': ','}, vehicle)
    with pytest.raises(ColumnMapError, match='scale must be a positive number'):
        parse_column_map({**columns, 'actuators': {**columns['actuators'], 'm1': {
            'column': 'm1_erpm', 'unit': 'rpm', 'scale': -6}}}, vehicle)
    boat = parse_vessel({'name': 'boat', 'rate_hz': 1.0, 'window_s': 5, 'horizon_s': 10,
                         'states': ['u', 'v', 'r'], 'particulars': {'length_m': 5.0},
                         'actuators': {'n': {'kind': 'propeller', 'range': [0, 10]}}})
    with pytest.raises(ColumnMapError, match="maps 'pitch', but vessel 'boat' models no pitch"):
        parse_column_map({'time': 't', 'heading': 'h', 'pitch': 'p',
                          'position': {'frame': 'ned', 'x': 'x', 'y': 'y'},
                          'actuators': {'n': 'n'}}, boat)


def test_a_parquet_file_that_is_not_one_is_refused_in_one_line(tmp_path, vehicle):
    bad = tmp_path / 'broken.parquet'
    bad.write_text('not a table')
    cmap = map_of(vehicle)
    reader = TableRecordings(cmap)
    result = convert(reader.find([bad])[0], reader, cmap.topic_map, Options())
    assert 'cannot read as a Parquet table' in result.error and '\n' not in result.error


@pytest.mark.skipif(not REAL.is_dir(), reason=f'{REAL} is absent (third-party flights)')
def test_the_real_flights_pass_the_map_checks_on_the_moving_craft(vehicle):
    """The benchmark's flights with the shipped map: every check judged, and passed."""
    files = sorted(REAL.glob('*/*.parquet'))
    good = [f for f in files if not f.stem.endswith('_na')]
    cmap = map_of(vehicle)
    reader = TableRecordings(cmap)
    per_run = {}
    for f in good[::4]:   # five flights of each kind's mix keep this under ten seconds
        result = convert(reader.find([f])[0], reader, cmap.topic_map, Options())
        assert result.error is None, result.error
        per_run.update({rid: check_run(run, cmap.topic_map, context_for(
            cmap.topic_map, interval_s=0.01), result.context[rid]['spikes'])
            for rid, run in result.runs.items()})
    pooled = {c.name: c for c in aggregate(per_run, context_for(cmap.topic_map))}
    assert all(c.ok for checks in per_run.values() for c in checks), [
        c.line() for checks in per_run.values() for c in checks if not c.ok]
    for name in ('velocity vs d(position)/dt', 'vertical velocity vs d(z)/dt',
                 'course of velocity vs of d(position)/dt', 'roll_rate vs d(roll)/dt',
                 'pitch_rate vs d(pitch)/dt', 'yaw_rate vs d(heading)/dt'):
        assert pooled[name].ok and pooled[name].figure is not None, pooled[name].line()
    # The flight whose motion capture stopped (its name ends in _na) is refused.
    broken = [f for f in files if f.stem.endswith('_na')][0]
    result = convert(reader.find([broken])[0], reader, cmap.topic_map, Options())
    checks = [c for rid, run in result.runs.items() for c in check_run(
        run, cmap.topic_map, context_for(cmap.topic_map), result.context[rid]['spikes'])]
    assert not {c.name: c for c in checks}['velocity vs d(position)/dt'].ok
