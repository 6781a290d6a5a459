"""offline/benchmarks/what_if.py: what feeds the predictor before a planner's what-if is timed."""

from pathlib import Path
import sys

import numpy as np
import pandas as pd
import pytest

from vessel_datasets.format import write_dataset
from vessel_description import load_vessel

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / 'offline'))
from benchmarks.what_if import SECONDS, fed_samples, mid_range  # noqa: E402


def _run(vessel, rows, offset):
    t = np.arange(rows) * vessel.dt
    table = {name: np.full(rows, offset) for name in vessel.dataset_columns}
    table['t'] = t
    return pd.DataFrame(table)[list(vessel.dataset_columns)]


def test_a_recording_feeds_the_first_rows_of_its_longest_test_run(tmp_path):
    vessel = load_vessel('snuboat')
    runs = {'short': _run(vessel, SECONDS // 2, 1.0), 'long': _run(vessel, 2 * SECONDS, 2.0),
            'trained': _run(vessel, 3 * SECONDS, 3.0)}
    write_dataset(tmp_path, runs, vessel=vessel, provenance={'tool': 'test'},
                  split={'train': ['trained'], 'test': ['short', 'long']})
    fed = fed_samples(vessel, tmp_path)
    assert len(fed) == SECONDS
    assert [row['t'] for row in fed] == pytest.approx(np.arange(SECONDS) * vessel.dt)
    assert {row['u'] for row in fed} == {2.0}
    with pytest.raises(SystemExit) as refused:
        fed_samples(load_vessel('patrol_boat'), tmp_path)
    assert str(refused.value) == (f"what-if: {tmp_path} is a recording of 'snuboat'; the "
                                  "model serves 'patrol_boat'")
    with pytest.raises(SystemExit) as refused:
        fed_samples(vessel, tmp_path / 'absent')
    assert str(refused.value).startswith('what-if: ') and '\n' not in str(refused.value)


def test_a_vessel_the_simulator_cannot_run_needs_a_recording_and_says_so():
    with pytest.raises(SystemExit) as refused:
        fed_samples(load_vessel('snuboat'), None)
    line = str(refused.value)
    assert '\n' not in line and line.endswith('give a recording of it (--what-if-dataset)')


def test_a_simulated_run_is_fed_with_the_actuators_held():
    vessel = load_vessel('patrol_boat')
    held = mid_range(vessel)
    assert held == {a: 0.5 * (vessel.actuator(a).low + vessel.actuator(a).high)
                    for a in vessel.actuator_names}
    fed = fed_samples(vessel, None)
    assert len(fed) == SECONDS and all(isinstance(v, float) for v in fed[-1].values())
    assert fed[-1][vessel.actuator_names[0]] == pytest.approx(held[vessel.actuator_names[0]],
                                                             rel=0.05)
