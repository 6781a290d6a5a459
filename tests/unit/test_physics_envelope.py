"""hybrid_models.physical.envelope: a fitted physics that leaves the vessel's limits is named."""

from dataclasses import replace

import numpy as np

from hybrid_models.data import load_runs
from hybrid_models.physical.envelope import envelope_escapes, escape_warning
from hybrid_models.physical.regression import RegressionModel
from offline.benchmarks.toy import TOY_VESSEL, write_linear_dataset


def fitted(tmp_path):
    """
    Return a Lin physics fitted on the toy's linear runs, its rows, and a vessel.

    The vessel's limits are the runs' own range widened by that range on both sides: the
    toy's states are abstract, its file's limits do not hold them.
    """
    data = write_linear_dataset(tmp_path / 'linear')
    runs = load_runs(data, 'train', TOY_VESSEL)
    z = np.concatenate([r.z[:-1] for r in runs])
    c = np.concatenate([r.c[:-1] for r in runs])
    zn = np.concatenate([r.z[1:] for r in runs])
    low, high = z.min(axis=0), z.max(axis=0)
    vessel = replace(TOY_VESSEL, limits={
        s: (float(lo - (hi - lo)), float(hi + (hi - lo)))
        for s, lo, hi in zip(TOY_VESSEL.state_names, low, high, strict=True)})
    return RegressionModel(vessel, 'lin').fit(z, c, zn), z, c, vessel


def test_a_stable_physics_stays_inside_and_an_unstable_one_is_named(tmp_path):
    model, z, c, vessel = fitted(tmp_path)
    stable = envelope_escapes(model, vessel, z, c, horizon=200)
    assert stable['checked'] and stable['rollouts'] == 64 and stable['escaped'] == 0
    assert escape_warning(stable) is None
    # The same model with the yaw rate's own gain above one: r grows until it leaves.
    weight = model.arrays()['weight'].copy()
    r = TOY_VESSEL.state_names.index('r')
    weight[r, model.features.names.index('r')] = 1.2
    model.load_arrays({**model.arrays(), 'weight': weight})
    unstable = envelope_escapes(model, vessel, z, c, horizon=200)
    assert unstable['escaped'] > 32 and unstable['example']['state'] == 'r'
    low, high = vessel.limits['r']
    assert not low <= unstable['example']['value'] <= high
    assert 0 < unstable['example']['after_s'] <= 200 * vessel.dt
    warning = escape_warning(unstable)
    assert warning.startswith("physics check: the fitted physics leaves the vessel's limits")
    assert f"in {unstable['escaped']} of 64 roll-outs" in warning and 'r ' in warning
    assert escape_warning(unstable, 'damp it').endswith('training runs; damp it')


def test_a_vessel_without_limits_is_not_checked(tmp_path):
    model, z, c, vessel = fitted(tmp_path)
    bare = replace(vessel, limits={})
    result = envelope_escapes(model, bare, z, c, horizon=10)
    assert result == {'checked': False, 'reason': 'the vessel file gives no state limits'}
    assert escape_warning(result) is None
