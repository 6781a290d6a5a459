"""The diagnosis knows what can exist: candidates follow the vessel file, and its scale."""

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from vessel_datasets import synthetic
from vessel_datasets.format import write_dataset
from vessel_description import load_vessel
from vessel_diagnosis import cli as diagnose
from vessel_diagnosis.admissible import admissible
from vessel_diagnosis.library import load_library
from vessel_diagnosis.recordings import Run
from vessel_diagnosis.scale import ScaleError, check_scale
from vessel_diagnosis.settings import load_settings
from vessel_physics.patrol import FAMILY as PATROL

SHIP = load_vessel('patrol_boat')
LIBRARY = load_library(None, PATROL)
SCALE = load_settings().scale_check
MODEL_SCALE = 50.0     # Froude scaling: speeds / sqrt(scale), rates * sqrt(scale)
STATES = ('u', 'v', 'p', 'r', 'phi')


def _excluded(vessel):
    library, exclusions = admissible(LIBRARY, vessel, PATROL)
    by_category = {e.category: e for e in exclusions}
    assert len(by_category) == len(exclusions)                 # one line per category
    assert set(library.by_name) | {n for e in exclusions for n in e.candidates} == set(
        LIBRARY.by_name)
    return library, by_category


def test_the_patrol_boat_can_have_every_candidate():
    library, excluded = _excluded(SHIP)
    assert excluded == {} and library.candidates == LIBRARY.candidates


def test_no_wind_terms_without_wind():
    library, excluded = _excluded(replace(SHIP, environment=()))
    wind = [c.name for c in LIBRARY.candidates if c.category == 'wind']
    assert set(excluded) == {'wind'} and list(excluded['wind'].candidates) == wind
    assert 'declares no wind' in excluded['wind'].line()
    assert not any('wind_speed' in c.requires for c in library.candidates)


def test_no_current_in_a_basin():
    library, excluded = _excluded(replace(SHIP, waters='basin'))
    assert set(excluded) == {'current'} and not library.has_current
    assert excluded['current'].line() == ('current: current not tried: the vessel file says '
                                          'the recordings come from a basin (waters: basin)')


def test_no_roll_terms_without_roll_and_everything_at_once_for_a_tank_model():
    tank = replace(SHIP, states=('u', 'v', 'r'), environment=(), waters='basin')
    library, excluded = _excluded(tank)
    assert set(excluded) == {'wind', 'current', 'roll_damping', 'restoring', 'added_mass',
                             'static_bias'}
    assert excluded['added_mass'].candidates == ('Kpdot',)
    assert excluded['static_bias'].candidates == ('roll_bias',)
    assert all(set(c.dofs) != {'K'} for c in library.candidates)
    assert {'resistance', 'hull_damping', 'propulsion', 'actuator_bias'} <= {
        c.category for c in library.candidates}
    for exclusion in excluded.values():
        assert '\n' not in exclusion.line()


def _froude(scale: float) -> dict[str, float]:
    """Return the factor of each state of a model ``scale`` times smaller (Froude)."""
    root = np.sqrt(scale)
    return {'u': 1 / root, 'v': 1 / root, 'p': root, 'r': root, 'phi': 1.0}


def _run(scale: float = 1.0, seconds: int = 2000) -> Run:
    """Return the demo trajectory, Froude-scaled down by ``scale`` (1: full scale)."""
    traj = synthetic.demo_trajectory(seconds)
    factor = _froude(scale)
    z = np.stack([traj.columns[s] * factor[s] for s in STATES], axis=1)
    t = np.arange(seconds, dtype=float)
    return Run('trial', t, z, traj.columns['psi'], np.zeros((seconds, 6)))


def _model(vessel, scale):
    """Return the vessel file of a model of ``vessel`` at ``scale``."""
    factor = _froude(scale)
    return replace(vessel, particulars={'length_m': vessel.length_m / scale},
                   limits={s: (lo * factor[s], hi * factor[s])
                           for s, (lo, hi) in vessel.limits.items() if s in factor})


def test_scale_check_is_quiet_when_recordings_and_vessel_file_agree():
    figures = check_scale([_run()], SHIP, SCALE)
    assert figures['froude'] < 0.5 and figures['turning_rate'] < 1.0
    model = check_scale([_run(MODEL_SCALE)], _model(SHIP, MODEL_SCALE), SCALE)
    assert model['froude'] == pytest.approx(figures['froude'])            # Froude scaling
    assert model['turning_rate'] == pytest.approx(figures['turning_rate'])


def test_scale_check_refuses_model_scale_recordings_with_a_full_scale_vessel_file():
    with pytest.raises(ScaleError) as info:
        check_scale([_run(MODEL_SCALE)], SHIP, SCALE)
    message = str(info.value)
    assert 'turns of' in message and 'length_m 51.5' in message
    assert '--skip-scale-check' in message and '\n' not in message


def test_scale_check_refuses_full_scale_recordings_with_a_model_vessel_file():
    with pytest.raises(ScaleError) as info:
        check_scale([_run()], _model(SHIP, MODEL_SCALE), SCALE)
    assert 'u leaves its limits' in str(info.value)
    tiny = replace(SHIP, particulars={'length_m': 0.1})     # Fn 4: faster than any hull
    with pytest.raises(ScaleError, match='Froude number'):
        check_scale([_run()], tiny, SCALE)


def _model_scale_dataset(tmp_path, seconds):
    run = _run(MODEL_SCALE, seconds)
    traj = synthetic.demo_trajectory(seconds)
    columns = {c: traj.columns[c] for c in SHIP.dataset_columns[1:]}
    columns.update({s: run.z[:, i] for i, s in enumerate(STATES)})
    table = pd.DataFrame({'t': run.t, **columns})
    write_dataset(tmp_path / 'ds', {'trial': table}, vessel=SHIP, provenance={'tool': 'test'})
    return tmp_path / 'ds'


def test_cli_refuses_a_mismatched_scale_in_one_line_unless_told_to_skip(capsys, tmp_path):
    dataset = _model_scale_dataset(tmp_path, 600)
    out = tmp_path / 'out'
    argv = ['--recordings', str(dataset), '--physics', 'patrol_vessel.yaml', '--out',
            str(out), '--quiet']
    code = diagnose.main(argv)
    err = capsys.readouterr().err
    assert code == diagnose.EXIT_INPUT and err.count('\n') == 1
    assert err.startswith("diagnose.py: error: the recordings do not fit the scale of vessel "
                          "'patrol_boat'")
    assert not (out / 'findings.json').exists()
    # Skipped, the same recordings get as far as the next check (too short).
    assert diagnose.main(argv + ['--skip-scale-check']) == diagnose.EXIT_INSUFFICIENT
    assert 'needs at least' in capsys.readouterr().err
