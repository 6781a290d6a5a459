"""
Simulator node -> recorder over DDS -> converter reproduces the batch simulator.

The node runs seed 5, run 1; offline/record.py records its topics into an MCAP bag as
a separate process; the converter turns the bag into run tables; those must equal the
batch simulator's run 1 of seed 5 on the same samples, within the resampling tolerance
(the node publishes on whole simulated seconds, so the 1 Hz grid meets them exactly).
"""

from pathlib import Path

import numpy as np
import pytest

from vessel_description import load_vessel

from .conftest import spin_until

SHIP = load_vessel('patrol_boat')

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[2]
RECORD = REPO / 'offline' / 'record.py'
START = 2000.0  # stamp of simulated t = 0
TOLERANCE = 1e-9


def test_node_to_bag_to_dataset_matches_the_batch_simulator(launcher, ros_node, tmp_path):
    from nav_msgs.msg import Odometry

    from vessel_datasets.bag_source import find_bags
    from vessel_datasets.readers.bags import convert_bag
    from vessel_datasets.topic_map import topic_map_for
    from vessel_physics.simulation.config import load_simulation as load_config
    from vessel_physics.simulation.simulator import Simulator

    bag_dir = tmp_path / 'bag'
    recorder = launcher.start_script(RECORD, '--out', str(bag_dir), name='record')
    seen = []
    ros_node.create_subscription(Odometry, '/vessel/odom', seen.append, 50)
    launcher.start_node('ship_sim_node', 'simulator', '--ros-args', '-p', 'seed:=5',
                        '-p', 'run_index:=1', '-p', f'start_time:={START}',
                        '-p', 'real_time_factor:=20.0')
    assert spin_until(ros_node, lambda: len(seen) >= 90, 60), 'the simulator did not publish'
    assert launcher.stop(recorder) == 0, recorder.output()

    [bag] = find_bags([bag_dir])
    result = convert_bag(bag, topic_map_for(SHIP))
    assert result.error is None, result.error
    assert len(result.runs) == 1, result.report
    [(run_id, table)] = result.runs.items()
    first = int(round(result.run_sources[run_id]['start_ns'] * 1e-9 - START))
    assert len(table) >= 60

    n = first + len(table) - 1
    batch = Simulator(load_config(), n_runs=2, seed=5).run(n)
    k = np.arange(first, first + len(table))
    expected = {key: batch[key][1, k] for key in ('u', 'v', 'p', 'r', 'phi', 'n',
                                                  'delta_port', 'delta_stbd', 'wind_speed',
                                                  'wind_dir_cos', 'wind_dir_sin')}
    # The converter puts each run's start at the origin and its first heading in [-pi, pi].
    expected['x'] = batch['x'][1, k] - batch['x'][1, first]
    expected['y'] = batch['y'][1, k] - batch['y'][1, first]
    psi = batch['psi'][1, k]
    expected['psi'] = psi - 2 * np.pi * np.round(psi[0] / (2 * np.pi))
    for key, values in expected.items():
        np.testing.assert_allclose(table[key].to_numpy(), values, atol=TOLERANCE, rtol=0,
                                   err_msg=key)
    np.testing.assert_allclose(table['t'].to_numpy(), np.arange(len(table), dtype=float))
