"""The hindsight guard of docs/results/real/analysis/hindsight_guard_probe.py: causal choices."""

from pathlib import Path
import sys

import numpy as np
import pytest

ANALYSIS = Path(__file__).resolve().parents[2] / 'docs' / 'results' / 'real' / 'analysis'


@pytest.fixture(scope='module')
def probe():
    sys.path.insert(0, str(ANALYSIS))
    try:
        import hindsight_guard_probe
        yield hindsight_guard_probe
    finally:
        sys.path.remove(str(ANALYSIS))


def figures_of(errors: dict[float, list[float]], gains) -> list[dict]:
    """Per gain, forecasts whose state and position errors are ``errors[gain]`` at 2 steps."""
    return [{'per_forecast': {k: np.repeat(np.array(errors[g], float)[:, None], 2, axis=1)
                              for k in ('state', 'position')}} for g in gains]


def test_each_forecast_is_served_by_what_its_own_run_has_already_shown(probe):
    gains = probe.GAINS
    # Run 0: the correction harms (every gain worse than the physics, in proportion to it).
    # Run 1: a half gain is best. Horizon 10 samples; forecasts every 5.
    run_index, t0 = np.array([0, 0, 0, 0, 1, 1, 1]), np.array([0, 5, 10, 15, 0, 5, 10])
    errors = {g: [1.0 + g] * 4 + [1.0 - g * (1.0 - g) * 2] * 3 for g in gains}
    choice = probe.guard_choices(figures_of(errors, gains), run_index, t0, horizon=10)
    served, physics, halfway = gains.index(1.0), gains.index(0.0), gains.index(0.5)
    # Nothing matured yet: the hybrid as trained; then only forecasts t0 + 10 <= t0' count,
    # and never another run's.
    assert choice.tolist() == [served, served, physics, physics, served, served, halfway]


def test_a_gain_worse_than_the_physics_at_any_step_is_not_admissible(probe):
    gains = probe.GAINS
    figures = figures_of({g: [1.0 - 0.5 * g, 0.0] for g in gains}, gains)
    # The full gain is best on the whole but worse than the physics in position at step 2.
    figures[gains.index(1.0)]['per_forecast']['position'][0, 1] = 5.0
    choice = probe.guard_choices(figures, np.zeros(2, int), np.array([0, 10]), horizon=10)
    assert choice[1] == gains.index(0.75)
