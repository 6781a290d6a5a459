"""
Acceptance on measured data nobody on this team produced (../shared/real), as a user runs it.

Skipped with a reason where that folder is absent; nothing from it is committed.
"""

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from vessel_datasets import bag_to_dataset, table_to_dataset
from vessel_datasets.format import read_dataset
from vessel_description import load_vessel

REAL = Path(__file__).resolve().parents[2].parent / 'shared' / 'real'
SNUBOAT_BAGS = ('FREE_RUNNING_TURNING_0813_202013', 'FREE_RUNNING_TURNING_0813_202530')
SILS_BAG = 'FREE_RUNNING_BANGBANG_0813_181925'  # the boat's simulator: /sils_motor_fb_data

pytestmark = pytest.mark.skipif(not REAL.is_dir(), reason=f'{REAL} (third-party recordings) '
                                                          f'is absent on this machine')


def test_humble_sqlite3_bags_with_custom_types_convert_from_a_msg_folder(tmp_path, capsys):
    bags = [str(REAL / 'snuboat' / 'bags' / name) for name in (*SNUBOAT_BAGS, SILS_BAG)]
    out = tmp_path / 'snuboat'
    # The lag is in the vessel file: every check passes without --accept-checks.
    assert bag_to_dataset.main([*bags, '--vessel', 'snuboat', '--out', str(out), '--quiet',
                                '--msg-dir', str(REAL / 'snuboat' / 'msg'),
                                '--msg-package', 'snumsg_pkg']) == 0
    err = capsys.readouterr().err
    assert 'all runs: check timing of position, heading, yaw_rate vs velocity' in err
    assert 'failed' not in err and f'{SILS_BAG}: alternatives taken: /sensor, ' \
        '/sils_motor_fb_data' in err
    manifest = json.loads((out / 'manifest.json').read_text())
    assert manifest['vessel']['name'] == 'snuboat' and manifest['rate_hz'] == 10.0
    assert len(manifest['runs']) == 3
    assert all(r['duration_s'] > 20 for r in manifest['runs'])
    sils = next(r for r in manifest['conversion']['recordings'] if r['name'] == SILS_BAG)
    assert sils['alternatives']['actuators.n_port'] == '/sils_motor_fb_data ctrl[0]'
    assert sils['alternatives']['body_velocity.surge'] == '/sensor vel[0]'  # no delay
    # Without the delays the timing check finds the lag and says what to write.
    plain = tmp_path / 'plain.yaml'
    topics = load_vessel('snuboat').recordings['topics']
    plain.write_text(yaml.safe_dump({g: {k: (v[0] if isinstance(v, list) else v)
                                         for k, v in entries.items()}
                                     for g, entries in topics.items()}).replace(
        'delay_s: 0.9', 'delay_s: 0.0'))
    assert bag_to_dataset.main([*bags[:2], '--vessel', 'snuboat', '--topic-map', str(plain),
                                '--out', str(tmp_path / 'x'), '--quiet', '--dry-run',
                                '--msg-dir', str(REAL / 'snuboat' / 'msg'),
                                '--msg-package', 'snumsg_pkg']) == 2
    err = capsys.readouterr().err
    assert 'topics.body_velocity.surge: delay_s: 0.9' in err
    # Without the message definitions the user is told where to give them.
    assert bag_to_dataset.main([bags[0], '--vessel', 'snuboat', '--out',
                                str(tmp_path / 'y'), '--quiet']) == 1
    assert '--msg-dir' in capsys.readouterr().err


def test_a_gps_only_log_imports_with_velocities_from_its_track(tmp_path, capsys):
    out = tmp_path / 'usv'
    assert table_to_dataset.main([str(REAL / 'usv' / 'turnningdata_xy.csv'), '--vessel',
                                  'usv', '--out', str(out), '--quiet', '--split',
                                  '1,0,0']) == 0
    err = capsys.readouterr().err
    assert 'check speed over ground vs the track: slope 0.9' in err  # knots, as mapped
    assert 'columns.heading (heading) repeats its previous value' in err
    (run,) = read_dataset(out).load_split('train').values()
    drift = np.degrees(np.arctan2(run['v'], run['u']))
    # A steady starboard turn (r > 0): the bow inside the circle, about 30 deg of drift.
    steady = run['t'] > 20
    assert (run['r'][steady] > 0).all() and -35 < np.median(drift[steady]) < -20


def test_tank_logs_import_with_the_established_map_and_refuse_the_vendor_list(tmp_path,
                                                                             capsys):
    logs = REAL / 'kvlcc2_hsva' / 'raw_data'
    out = tmp_path / 'kvlcc2'
    assert table_to_dataset.main([str(logs / 'HSVA_CPMC_KVLCC2_Z_10_05.dat'),
                                  str(logs / 'HSVA_CPMC_KVLCC2_Z_20_05.dat'),
                                  '--vessel', 'kvlcc2_hsva', '--out', str(out), '--quiet',
                                  '--split', '1,0,0']) == 0
    err = capsys.readouterr().err
    assert 'failed' not in err.lower() and 'yaw_rate vs d(heading)/dt: slope' in err
    # The vendor's column list: columns 5-6 are earth-frame velocities, not body ones.
    vendor = tmp_path / 'vendor.yaml'
    columns = dict(load_vessel('kvlcc2_hsva').recordings['columns'])
    velocity = columns['velocity']
    columns['velocity'] = {'frame': 'body', 'unit': velocity.get('unit', 'm/s'),
                           'surge': velocity['north'], 'sway': velocity['east']}
    vendor.write_text(yaml.safe_dump(columns))
    assert table_to_dataset.main([str(logs / 'HSVA_CPMC_KVLCC2_Z_20_05.dat'), '--vessel',
                                  'kvlcc2_hsva', '--column-map', str(vendor), '--out',
                                  str(tmp_path / 'vendor'), '--quiet', '--dry-run']) == 2
    assert 'course of velocity' in capsys.readouterr().err
