"""
Acceptance on measured data nobody on this team produced (../shared/real), as a user runs it.

Skipped with a reason where that folder is absent; nothing from it is committed.
"""

import json
from pathlib import Path

import pytest
import yaml

from vessel_datasets import bag_to_dataset, table_to_dataset
from vessel_description import load_vessel

REAL = Path(__file__).resolve().parents[2].parent / 'shared' / 'real'
SNUBOAT_BAGS = ('FREE_RUNNING_TURNING_0813_202013', 'FREE_RUNNING_TURNING_0813_202530')

pytestmark = pytest.mark.skipif(not REAL.is_dir(), reason=f'{REAL} (third-party recordings) '
                                                          f'is absent on this machine')


def test_humble_sqlite3_bags_with_custom_types_convert_from_a_msg_folder(tmp_path, capsys):
    bags = [str(REAL / 'snuboat' / 'bags' / name) for name in SNUBOAT_BAGS]
    out = tmp_path / 'snuboat'
    assert bag_to_dataset.main([*bags, '--vessel', 'snuboat', '--out', str(out), '--quiet',
                                '--msg-dir', str(REAL / 'snuboat' / 'msg'),
                                '--msg-package', 'snumsg_pkg', '--accept-checks']) == 0
    err = capsys.readouterr().err
    assert 'check velocity vs d(position)/dt: slope' in err
    manifest = json.loads((out / 'manifest.json').read_text())
    assert manifest['vessel']['name'] == 'snuboat' and manifest['rate_hz'] == 10.0
    assert len(manifest['runs']) == 2
    assert all(r['duration_s'] > 100 for r in manifest['runs'])
    # Without the message definitions the user is told where to give them.
    assert bag_to_dataset.main([bags[0], '--vessel', 'snuboat', '--out',
                                str(tmp_path / 'x'), '--quiet']) == 1
    assert '--msg-dir' in capsys.readouterr().err


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
