"""
Tabular logs to datasets, and the map checks that catch a wrong column map.

Every file is made here from a smooth turning trajectory with exact kinematics, written
in the units and frames a towing tank or a logger would use; the import must give the
truth back, and each deliberately wrong map must be named by its check.
"""

import math
from pathlib import Path
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import yaml

from vessel_datasets import column_map as columns
from vessel_datasets import format as fmt
from vessel_datasets import map_checks, pipeline, table_to_dataset
from vessel_datasets.readers.tables import TableRecordings
from vessel_datasets.sources import sha256
from vessel_description import parse_vessel

from .tracks import KNOT, RATE_HZ, csv_table, trajectory

REPO = Path(__file__).resolve().parents[2]
DEG = math.pi / 180.0
VESSEL_DATA = {
    'name': 'tank_model', 'rate_hz': RATE_HZ, 'window_s': 1.0, 'horizon_s': 5.0,
    'states': ['u', 'v', 'r'],
    'limits': {'u': [-1.0, 3.0], 'v': [-1.0, 1.0], 'r': [-1.0, 1.0]},
    'actuators': {'n': {'kind': 'propeller', 'range': [0.0, 100.0]},
                  'delta': {'kind': 'rudder', 'range': [-0.6, 0.6]}},
    'particulars': {'length_m': 3.0},
}
VESSEL = parse_vessel(VESSEL_DATA)

# The CSV below: earth-frame velocities in knots, angles in degrees, shaft speed in rpm,
# rudder positive to port (the opposite of the vessel's).
CSV_MAP = {
    'sep': ',', 'header_row': True,
    'time': {'column': 'time', 'unit': 's'},
    'velocity': {'frame': 'earth', 'north': 'vn_kn', 'east': 've_kn', 'unit': 'knots'},
    'yaw_rate': {'column': 'r_deg', 'unit': 'deg/s'},
    'heading': {'column': 'hdg_deg', 'unit': 'deg', 'convention': 'north_clockwise'},
    'position': {'frame': 'ned', 'x': 'north_m', 'y': 'east_m', 'unit': 'm'},
    'actuators': {'n': {'column': 'rpm', 'unit': 'rpm'},
                  'delta': {'column': 'rudder_deg', 'unit': 'deg', 'sign': -1}},
}


def write_csv(path, table):
    table.to_csv(path, index=False, float_format='%.12g')
    return path


def convert(path, mapping, **opts):
    cmap = columns.parse_column_map(mapping, VESSEL)
    results = pipeline.convert_all([path], TableRecordings(cmap), cmap.topic_map,
                                   pipeline.Options.from_yaml(**opts))
    return cmap, results


def import_one(path, mapping, **opts):
    cmap, results = convert(path, mapping, **opts)
    assert not results[0].error, results[0].error
    return cmap, results


def only_run(results):
    ((run_id, table),) = [kv for r in results for kv in r.runs.items()]
    return run_id, table


def checks_of(path, mapping, refuse_spikes=False):
    """Return the checks of the single run of a file, by the first word of their name."""
    cmap, results = import_one(path, mapping)
    ((_, checks),) = pipeline.run_checks(results, cmap.topic_map, refuse_spikes).items()
    return {c.name.split()[0]: c for c in checks}


def pooled(path, mapping):
    """Return the checks of a file's runs judged together, by first word."""
    cmap, results = import_one(path, mapping)
    per_run = pipeline.run_checks(results, cmap.topic_map, False)
    ctx = map_checks.context_for(cmap.topic_map)
    return {c.name.split()[0]: c for c in map_checks.aggregate(per_run, ctx)}


def assert_truth(table, truth, atol=1e-6, step=1):
    for col in ('u', 'v', 'r', 'psi', 'n', 'delta'):
        np.testing.assert_allclose(table[col], truth[col][::step][:len(table)], atol=atol,
                                   rtol=0, err_msg=col)
    for col in ('x', 'y'):
        ref = truth[col][::step][:len(table)]
        np.testing.assert_allclose(table[col], ref - ref[0], atol=atol, rtol=0, err_msg=col)


# ----------------------------------------------------------------- imports
def test_csv_in_degrees_knots_and_earth_frame_gives_the_truth(tmp_path):
    truth = trajectory()
    path = write_csv(tmp_path / 'trial.csv', csv_table(truth))
    _, results = import_one(path, CSV_MAP)
    run_id, table = only_run(results)
    assert run_id == 'trial'
    assert list(table.columns) == list(VESSEL.dataset_columns)
    assert len(table) == len(truth['t'])
    np.testing.assert_allclose(table['t'], truth['t'], atol=1e-12)
    # The heading was wrapped at 180 deg in the file and comes back unwrapped.
    assert table['psi'].max() > math.pi
    assert_truth(table, truth)


def test_whitespace_dat_with_title_lines_is_resampled_to_the_vessel_rate(tmp_path):
    truth = trajectory(rate_hz=40.0)
    body = np.column_stack([truth['t'], truth['x'], truth['y'], truth['psi'], truth['u'],
                            truth['v'], truth['r'], truth['n'] / (2 * math.pi),
                            truth['delta']])
    text = 'Model test\nZ10\u00b0/10\u00b0 starting to port\nTime series\n\n' + '\n'.join(
        '  '.join(f'{x:.12g}' for x in row) for row in body) + '\n'
    path = tmp_path / 'Z_10_10.dat'
    path.write_bytes(text.encode('cp1252'))
    mapping = {
        'format': 'delimited', 'sep': 'whitespace', 'skip_lines': 4, 'encoding': 'cp1252',
        'names': ['time', 'x0', 'y0', 'psi', 'u', 'v', 'r', 'rev', 'rudder'],
        'time': {'column': 'time', 'unit': 's'},
        'velocity': {'frame': 'body', 'surge': 'u', 'sway': 'v'},
        'yaw_rate': 'r', 'heading': 'psi',
        'position': {'frame': 'ned', 'x': 'x0', 'y': 'y0'},
        'actuators': {'n': {'column': 'rev', 'unit': 'rps'}, 'delta': 'rudder'},
    }
    _, results = import_one(path, mapping)
    _, table = only_run(results)
    assert len(table) == (len(truth['t']) + 1) // 2  # 40 Hz -> 20 Hz
    assert_truth(table, truth, step=2)


def test_a_constant_rate_file_needs_no_time_column(tmp_path):
    truth = trajectory(duration_s=20.0)
    path = write_csv(tmp_path / 'rate.csv', csv_table(truth).drop(columns='time'))
    mapping = {k: v for k, v in CSV_MAP.items() if k != 'time'} | {'rate_hz': RATE_HZ}
    _, results = import_one(path, mapping)
    _, table = only_run(results)
    np.testing.assert_allclose(table['t'], truth['t'], atol=1e-12)
    assert_truth(table, truth)


def test_without_a_yaw_rate_column_the_heading_is_differentiated(tmp_path):
    truth = trajectory(duration_s=20.0)
    path = write_csv(tmp_path / 'noyaw.csv', csv_table(truth).drop(columns='r_deg'))
    mapping = {k: v for k, v in CSV_MAP.items() if k != 'yaw_rate'}
    cmap, results = import_one(path, mapping)
    assert map_checks.context_for(cmap.topic_map).derived == ('r',)
    _, table = only_run(results)
    np.testing.assert_allclose(table['r'][1:-1], truth['r'][1:-1], atol=1e-4)
    ((_, checks),) = pipeline.run_checks(results, cmap.topic_map, False).items()
    yaw = next(c for c in checks if c.name.startswith('yaw_rate'))
    assert yaw.ok and yaw.figure is None and 'differentiated' in yaw.message


def test_a_run_column_gives_one_run_per_value(tmp_path):
    first, second = trajectory(duration_s=30.0), trajectory(duration_s=20.0)
    both = pd.concat([csv_table(first).assign(run='A'), csv_table(second).assign(run='B 2')])
    path = write_csv(tmp_path / 'day1.csv', both)
    _, results = import_one(path, CSV_MAP | {'run': 'run'})
    runs = results[0].runs
    assert sorted(runs) == ['day1-A', 'day1-B_2']
    assert_truth(runs['day1-A'], first)
    assert_truth(runs['day1-B_2'], second)
    assert results[0].run_sources['day1-B_2']['run'] == 'B 2'


def test_time_gaps_split_runs_and_nan_rows_are_dropped(tmp_path):
    truth = trajectory(duration_s=60.0)
    table = csv_table(truth)
    table.loc[100, 'r_deg'] = np.nan  # one missing value: interpolated over
    table = table.drop(index=range(600, 700))  # 5 s missing: two runs
    path = write_csv(tmp_path / 'gappy.csv', table)
    _, results = import_one(path, CSV_MAP)
    report = results[0].report
    assert sorted(results[0].runs) == ['gappy-000', 'gappy-001']
    assert report['nan'] == {'r_deg': 1}
    (gap,) = report['gaps']
    assert gap['sources'] == 'all' and gap['duration_s'] == pytest.approx(5.05)
    r = results[0].runs['gappy-000']['r'].to_numpy()
    assert abs(r[100] - truth['r'][100]) < 1e-4


# ----------------------------------------------------------------- map checks
def test_the_right_map_passes_every_check(tmp_path):
    path = write_csv(tmp_path / 'trial.csv', csv_table(trajectory()))
    checks = checks_of(path, CSV_MAP)
    assert set(checks) == {'velocity', 'timing', 'course', 'heading', 'drift', 'yaw_rate',
                           'spikes'}
    assert all(c.ok for c in checks.values()), [c.line() for c in checks.values()]
    assert checks['velocity'].figure == pytest.approx(1.0, abs=1e-3)
    assert checks['yaw_rate'].figure == pytest.approx(1.0, abs=1e-2)


def test_yaw_rate_in_deg_per_s_mapped_as_rad_per_s_is_named(tmp_path):
    path = write_csv(tmp_path / 'trial.csv', csv_table(trajectory()))
    checks = checks_of(path, CSV_MAP | {'yaw_rate': {'column': 'r_deg', 'unit': 'rad/s'}})
    yaw = checks['yaw_rate']
    assert not yaw.ok and yaw.figure == pytest.approx(180 / math.pi, rel=0.02)
    assert 'deg/s given as rad/s' in yaw.message and yaw.suspect == 'columns.yaw_rate'
    assert yaw.line().startswith('check yaw_rate vs d(heading)/dt: slope 57.')
    # So many samples beyond r's range are no spikes: they are kept, and the check fails.
    assert not checks['spikes'].ok and 'too many for spikes' in checks['spikes'].message


def test_earth_velocities_mapped_as_body_are_flagged(tmp_path):
    table = csv_table(trajectory())
    table['vn_kn'] *= KNOT
    table['ve_kn'] *= KNOT
    path = write_csv(tmp_path / 'trial.csv', table)
    wrong = CSV_MAP | {'velocity': {'frame': 'body', 'surge': 'vn_kn', 'sway': 've_kn'}}
    checks = checks_of(path, wrong)
    course = checks['course']
    assert not course.ok and course.figure > 10
    assert course.suspect == 'columns.velocity' and 'mapped as body' in course.message
    right = CSV_MAP | {'velocity': {'frame': 'earth', 'north': 'vn_kn', 'east': 've_kn'}}
    assert all(c.ok for c in checks_of(path, right).values())


def test_knots_mapped_as_m_per_s_are_named(tmp_path):
    path = write_csv(tmp_path / 'trial.csv', csv_table(trajectory()))
    wrong = CSV_MAP | {'velocity': CSV_MAP['velocity'] | {'unit': 'm/s'}}
    velocity = checks_of(path, wrong)['velocity']
    assert not velocity.ok and velocity.figure == pytest.approx(1 / KNOT, rel=0.01)
    assert 'knots given as m/s' in velocity.message
    assert velocity.suspect == 'columns.velocity'


def test_a_wrong_heading_convention_is_flagged(tmp_path):
    path = write_csv(tmp_path / 'trial.csv', csv_table(trajectory()))
    wrong = CSV_MAP | {'heading': CSV_MAP['heading'] | {'convention': 'east_counterclockwise'}}
    checks = checks_of(path, wrong)
    yaw = checks['yaw_rate']
    assert not yaw.ok and yaw.figure == pytest.approx(-1.0, abs=0.02)
    assert 'sign flip' in yaw.message and 'columns.heading' in yaw.message
    # Without the yaw rate, the heading's turn against the track's still says it.
    turn = pooled(path, {k: v for k, v in wrong.items() if k != 'yaw_rate'})['heading']
    assert not turn.ok and turn.figure < 0 and turn.suspect == 'columns.heading'
    assert 'turns against the track' in turn.message


def test_a_wrong_heading_convention_with_body_velocities_fails_the_velocity_check():
    truth = trajectory()
    vessel_cols = {c: truth[c] for c in ('u', 'v', 'r', 'n', 'delta')}
    run = pd.DataFrame({'t': truth['t'], **vessel_cols, 'psi': math.pi / 2 - truth['psi'],
                        'x': truth['x'], 'y': truth['y']})
    topic_map = columns.parse_column_map(
        CSV_MAP | {'velocity': {'frame': 'body', 'surge': 'u', 'sway': 'v'}}, VESSEL).topic_map
    checks = {c.name.split()[0]: c for c in map_checks.consistency_checks(
        run, topic_map, map_checks.context_for(topic_map))}
    assert not checks['velocity'].ok and not checks['course'].ok
    assert not checks['yaw_rate'].ok and 'columns.heading' in checks['yaw_rate'].message


def test_spikes_are_counted_and_dropped(tmp_path):
    truth = trajectory()
    table = csv_table(truth)
    table.loc[200, 'r_deg'] = np.degrees(-25.6)  # -25.6 rad/s with r limited to [-1, 1]
    table.loc[300, 'rpm'] = -50.0  # astern, with n limited to [0, 100]
    path = write_csv(tmp_path / 'spiky.csv', table)
    cmap, results = import_one(path, CSV_MAP)
    _, run = only_run(results)
    spikes = results[0].report['spikes']
    assert spikes['r'] == {'out_of_range': 1, 'jumps': 0, 'dropped': 1}
    assert spikes['n'] == {'out_of_range': 1, 'jumps': 0, 'dropped': 1}
    # Dropped before resampling: r is interpolated from its neighbours, n held.
    assert abs(run['r'][200] - truth['r'][200]) < 1e-4
    assert run['n'][300] == pytest.approx(truth['n'][299])
    ((_, checks),) = pipeline.run_checks(results, cmap.topic_map, False).items()
    spike = checks[-1]
    assert spike.ok and spike.figure == 2 and 'dropped' in spike.message
    ((_, refused),) = pipeline.run_checks(results, cmap.topic_map, True).items()
    assert not refused[-1].ok and 'refused' in refused[-1].message


def test_a_single_sample_jump_within_range_is_dropped(tmp_path):
    table = csv_table(trajectory())
    table.loc[500, 'vn_kn'] += 1.5 / KNOT  # a 1.5 m/s glitch, inside u's range
    path = write_csv(tmp_path / 'jump.csv', table)
    _, results = import_one(path, CSV_MAP)
    assert results[0].report['spikes']['u']['jumps'] == 1


# ----------------------------------------------------------------- errors
def test_a_missing_column_is_one_line_naming_the_columns(tmp_path):
    path = write_csv(tmp_path / 'trial.csv', csv_table(trajectory(duration_s=12.0)))
    _, (result,) = convert(path, CSV_MAP | {'yaw_rate': {'column': 'yaw', 'unit': 'deg/s'}})
    assert result.error == (f"{path}: columns.yaw_rate names column 'yaw', which the file "
                            f'lacks; it has time, vn_kn, ve_kn, r_deg, hdg_deg, north_m, '
                            f'east_m, rpm, rudder_deg')


@pytest.mark.parametrize('change, message', [
    ({'yaw_rate': {'column': 'r_deg', 'unit': 'deg/sec'}},
     "yaw_rate.unit 'deg/sec' is not a known rate unit; use one of rad/s, deg/s, rpm, rps"),
    ({'colour': 'red'}, "unknown keys ['colour']"),
    ({'velocity': {'frame': 'earth', 'north': 'vn_kn', 'unit': 'knots'}},
     "velocity (frame earth) lacks 'east'"),
    ({'heading': {'column': 'hdg_deg', 'convention': 'compass'}},
     "heading.convention is 'compass'"),
    ({'roll': 'r_deg'}, "maps 'roll', but vessel 'tank_model' models no roll"),
    ({'rate_hz': 20}, 'give either time'),
])
def test_map_errors_are_one_line(change, message):
    with pytest.raises(columns.ColumnMapError) as err:
        columns.parse_column_map(CSV_MAP | change, VESSEL)
    assert message in str(err.value) and '\n' not in str(err.value)


# ----------------------------------------------------------------- command line
@pytest.fixture
def vessel_file(tmp_path):
    path = tmp_path / 'tank_model.yaml'
    path.write_text(yaml.safe_dump({**VESSEL_DATA, 'recordings': {'columns': CSV_MAP}}))
    return path


def test_cli_writes_a_dataset_with_whole_run_holdouts(tmp_path, vessel_file, capsys):
    files = tmp_path / 'logs'
    files.mkdir()
    for i in range(4):
        write_csv(files / f'run{i}.csv', csv_table(trajectory(duration_s=15.0 + i)))
    out = tmp_path / 'dataset'
    argv = [str(files), '--vessel', str(vessel_file), '--out', str(out), '--holdout', 'run2',
            '--val', 'run0', '--quiet']
    assert table_to_dataset.main(argv) == 0
    err = capsys.readouterr().err
    assert 'run1: 321 rows -> 1 run(s), 321 samples' in err  # 16 s at 20 Hz
    assert 'all runs: check yaw_rate vs d(heading)/dt: slope 1.00' in err
    dataset = fmt.read_dataset(out)
    assert dataset.run_ids('test') == ['run2'] and dataset.run_ids('val') == ['run0']
    assert dataset.run_ids('train') == ['run1', 'run3']
    manifest = dataset.manifest
    sources = manifest['provenance']['sources']
    assert [s['sha256'] for s in sources] == [sha256(files / f'run{i}.csv') for i in range(4)]
    assert manifest['provenance']['config']['map']['velocity']['unit'] == 'knots'
    assert manifest['checks']['ok'] and len(manifest['checks']['runs']) == 4
    assert dataset.load('run3')['u'].iloc[0] == pytest.approx(1.2)

    # An existing dataset is kept unless asked; an unknown hold-out is one line.
    assert table_to_dataset.main(argv) == 2
    assert table_to_dataset.main(argv + ['--overwrite', '--holdout', 'run9']) == 2
    assert 'run9: no such run; runs are run0, run1, run2, run3' in capsys.readouterr().err


def test_cli_refuses_a_map_that_fails_its_checks(tmp_path, vessel_file, capsys):
    path = write_csv(tmp_path / 'trial.csv', csv_table(trajectory(duration_s=20.0)))
    wrong = tmp_path / 'wrong.yaml'
    wrong.write_text(yaml.safe_dump(
        CSV_MAP | {'yaw_rate': {'column': 'r_deg', 'unit': 'rad/s'}}))
    argv = [str(path), '--vessel', str(vessel_file), '--column-map', str(wrong), '--out',
            str(tmp_path / 'd1'), '--quiet']
    assert table_to_dataset.main(argv) == 2
    err = capsys.readouterr().err
    assert 'deg/s given as rad/s (map entry columns.yaw_rate)' in err
    assert 'error: map checks failed' in err
    assert not (tmp_path / 'd1' / fmt.MANIFEST).exists()
    assert table_to_dataset.main(argv + ['--accept-checks']) == 0
    manifest = fmt.read_dataset(tmp_path / 'd1').manifest
    assert not manifest['checks']['ok']
    assert 'yaw_rate vs d(heading)/dt' in manifest['checks']['failed']


def test_cli_refuse_spikes(tmp_path, vessel_file, capsys):
    table = csv_table(trajectory(duration_s=20.0))
    table.loc[50, 'rpm'] = -50.0
    path = write_csv(tmp_path / 'spiky.csv', table)
    argv = [str(path), '--vessel', str(vessel_file), '--out', str(tmp_path / 'd'), '--quiet',
            '--dry-run']
    assert table_to_dataset.main(argv) == 0
    assert table_to_dataset.main(argv + ['--refuse-spikes', '--accept-checks']) == 2
    assert 'n: 1 outside [0, 100] -> 1 samples refused' in capsys.readouterr().err


def test_cli_help_runs_as_a_script():
    done = subprocess.run([sys.executable, str(REPO / 'offline' / 'table_to_dataset.py'),
                           '--help'], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and '--column-map' in done.stdout
