"""
Proof of the departure WARN: the simulator with a concealed effect switched on mid-run.

The patrol boat's shipped scenario is simulated (vessel_physics) under its routine
operator, and the predictor's own judgement is fed every measured sample, as the node
feeds it: its skill tracker (``hybrid_predictor.core.live_skill`` with predictor.yaml's
defaults) behind ``hindsight``, which keeps a window every ``skill_forecast_period``
seconds and, as each scored step matures, has the shipped model forecast it again with
the controls and wind the operator applied up to that step (what the bands promise).
A concealed effect of vessel_diagnosis (hull fouling, a rudder offset) is switched on at
ONSET_S and comes in over RAMP_S (the scenario's ``extra_forces_from_s``, as the
simulator node takes it); the control run has none. Figures are printed (``-s``).
"""

from dataclasses import replace
import math

import numpy as np
import pytest

pytestmark = pytest.mark.slow

ONSET_S = 1800.0     # s of simulated time the effect starts at
RAMP_S = 60.0        # s over which it comes in fully
EFFECTS = {'fouling': 'vessel_diagnosis.concealed:hull_fouling',
           'rudder_offset': 'vessel_diagnosis.concealed:actuator_offset'}
TIMEOUT_S = 1800     # hours of simulation and thousands of forecasts: minutes of work


def departure_runs(effect: str | None, runs: int, hours: float, seed: int) -> list[dict]:
    """
    Simulate ``runs`` runs of ``hours``; return per run when the WARN was raised.

    Each entry: ``raised`` (s of simulated time of the first WARN, None if none),
    ``affected`` (the quantities and steps it named), ``final`` (those named at the
    end), ``warn_s`` the seconds of WARN in total, ``scored`` the steps scored.
    """
    from hybrid_models.engine import Forecaster
    from hybrid_predictor.core import live_skill, remade
    from hybrid_predictor.hindsight import Hindsight
    from hybrid_predictor.node import default_model_path
    from vessel_physics import frames
    from vessel_physics.simulation.config import default_config_path, load_simulation
    from vessel_physics.simulation.simulator import Simulator
    from vessel_ros_bridge.parameters import load_specs, package_config

    p = {s.name: s.default for s in load_specs(package_config('hybrid_predictor',
                                                              'predictor.yaml'))}
    engine = Forecaster.from_checkpoint(default_model_path())
    spec, window = engine.spec, engine.window
    horizon = spec.horizon
    cfg = load_simulation(default_config_path())
    if effect is not None:
        cfg = replace(cfg, extra_forces=EFFECTS[effect], extra_forces_from_s=ONSET_S,
                      extra_forces_ramp_s=RAMP_S)
    data = Simulator(cfg, n_runs=runs, seed=seed).run(hours * 3600.0)
    engine.warm_up(horizon, window=window, max_batch=1)
    out = []
    for j in range(runs):
        z = np.stack([data[c][j] for c in spec.state_names], axis=-1)
        c = np.stack([data[c][j] for c in spec.control_names], axis=-1)
        pose = np.stack([data[c][j] for c in ('x', 'y', 'psi')], axis=-1)
        t = data['t'][j]

        def remake(i, applied, z=z, c=c, pose=pose):
            """Return the forecast from the window ending at sample i, as the node re-makes it."""
            return remade(engine, spec, horizon, z[i + 1 - window:i + 1],
                          c[i + 1 - window:i + 1], tuple(pose[i]), applied)

        hindsight = Hindsight(live_skill(spec, horizon, p), remake)
        raised, affected, warn_s = None, (), 0.0
        # Measured as the node scores them: FLU states, ENU positions.
        flu = frames.states_frd_to_flu(z, spec.state_names)
        east, north, _ = frames.position_ned_to_enu(pose[:, 0], pose[:, 1])
        for i in range(window, len(t)):
            hindsight.add_measurement(t[i], flu[i], east[i], north[i], c[i])
            hindsight.keep(t[i], i)
            d = hindsight.skill.departure()
            warn_s += spec.dt * d.active
            if d.active and raised is None:
                raised, affected = float(t[i]), d.affected
        out.append({'raised': raised, 'affected': affected, 'warn_s': warn_s,
                    'final': hindsight.skill.departure().affected,
                    'scored': hindsight.skill.counts['steps_scored']})
    return out


def _name(affected) -> str:
    return ', '.join(f'{q}@{s}' for q, s, _ in affected)


@pytest.mark.timeout(TIMEOUT_S)
@pytest.mark.parametrize(('effect', 'named'), [('fouling', 'u'),
                                               ('rudder_offset', 'position')])
def test_a_concealed_effect_switched_on_mid_run_raises_the_warn(effect, named):
    runs = departure_runs(effect, runs=3, hours=1.5, seed=11)
    for r in runs:
        delay = math.nan if r['raised'] is None else r['raised'] - ONSET_S
        print(f'{effect}: WARN {delay:.0f} s after onset ({_name(r["affected"])}; at the '
              f'end {_name(r["final"])}), {r["warn_s"]:.0f} s of WARN, {r["scored"]} '
              f'steps scored')
    # raised after the onset, within half an hour of it (each step judged as it
    # matures), and still raised at the end
    assert all(r['raised'] is not None and ONSET_S < r['raised'] < ONSET_S + 1800.0
               for r in runs)
    assert all(any(q == named for q, _, _ in r['final']) for r in runs)


@pytest.mark.timeout(TIMEOUT_S)
def test_the_control_raises_no_warn_over_ten_simulated_hours():
    runs = departure_runs(None, runs=5, hours=2.0, seed=12)
    for r in runs:
        print(f'control: {r["warn_s"]:.0f} s of WARN, first at {r["raised"]} '
              f'({_name(r["affected"])}), {r["scored"]} steps scored')
    assert all(r['raised'] is None for r in runs)
    assert all(r['scored'] > 1000 for r in runs)
