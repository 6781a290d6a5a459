"""
The recordings' own ambiguity about the controls between samples (issue 46's control case).

``Identifier.input_course_floor`` is how much predictions change between holding each
sample's controls over its period and their linear course; a kept-out term whose effect
on every state stays below it is not "found with certainty". Checked on the KVLCC2 MMG
physics with synthetic segments: no floor where the controls never change, a floor that
grows with the controls' steps, and with the sample period.
"""

from types import SimpleNamespace

import numpy as np

from vessel_description import load_vessel
from vessel_diagnosis.identify import Identifier, Point
from vessel_diagnosis.library import load_library
from vessel_diagnosis.predict import Predictor
from vessel_diagnosis.settings import load_settings
from vessel_physics.physics_file import load_physics

TANKER = load_vessel('kvlcc2_hsva')


def _segments(rudder_step: float, dt: float, n: int = 8, horizon: int = 4):
    rng = np.random.default_rng(0)
    z0 = np.tile([0.8, 0.0, 0.0], (n, 1)) + rng.normal(0, 0.005, (n, 3))
    c = np.zeros((n, horizon + 1, 2))
    c[..., 0] = 10.0                                     # propeller, rps
    c[:, :, 1] = rudder_step * (np.arange(horizon + 1) % 2)   # rudder flips each sample
    return SimpleNamespace(z0=z0, psi0=np.zeros(n), c=c, skip=0, dt=dt,
                           currents=lambda per_run: None)


def _floor(rudder_step: float, dt: float = 0.5) -> np.ndarray:
    nominal = load_physics(TANKER.physics, TANKER)
    settings = load_settings(family=nominal.family.name)
    identifier = Identifier(nominal, load_library(None, nominal.family), settings)
    seg = _segments(rudder_step, dt)
    linear = Predictor(nominal, dt, settings.regression.substeps).simulate(
        seg.z0, seg.psi0, seg.c)
    return identifier.input_course_floor(seg, Point({}), linear)


def test_no_floor_where_the_controls_do_not_change_between_samples():
    assert np.allclose(_floor(0.0), 0.0)


def test_the_floor_grows_with_the_controls_steps_and_the_sample_period():
    small, large = _floor(0.05), _floor(0.2)
    assert (small > 0).all() and (large > 2 * small).all()
    assert (_floor(0.2, dt=1.0) > large).all()


def test_holding_the_controls_is_the_linear_course_with_each_next_sample_equal():
    nominal = load_physics(TANKER.physics, TANKER)
    seg = _segments(0.2, 0.5)
    predictor = Predictor(nominal, seg.dt, 4)
    held = predictor.simulate(seg.z0, seg.psi0, seg.c, hold=True)
    # The hold of sample k over its period is a linear course from c_k to c_k.
    x = predictor._to_water(seg.z0, seg.psi0, None)
    first = predictor._to_ground(predictor._advance(x, seg.c[:, 0], seg.c[:, 0], None), None)
    assert np.allclose(held[:, 0], first)
    assert not np.allclose(held, predictor.simulate(seg.z0, seg.psi0, seg.c))


def test_a_term_below_the_floor_is_reported_as_such_not_as_found():
    from vessel_diagnosis.findings import kept_out_records, within_input_course_records
    from vessel_diagnosis.report import _within_input_course

    nominal = load_physics(TANKER.physics, TANKER)
    library = load_library(None, nominal.family)
    name = next(c.name for c in library.candidates if c.kind == 'parameter')
    info = {'coefficient': 0.01, 'ci95': (0.005, 0.015), 'ci95_noise': (0.006, 0.014),
            'heterogeneity': None, 'inclusion_probability': 0.98, 'held_out_gain': 0.002,
            'why': 'changes held-out forecasts too little', 'statistically_certain': True,
            'prediction_effect': [1e-4, 2e-5, 1e-6], 'input_course_floor': [3e-4, 1e-4, 1e-5],
            'above_input_course_floor': False, 'certain': False}
    ident = SimpleNamespace(kept_out={name: info})
    assert kept_out_records(ident, library, nominal) == []
    (record,) = within_input_course_records(ident, library, nominal)
    assert record['term'] == name and record['input_course_floor'] == [3e-4, 1e-4, 1e-5]
    lines = _within_input_course([record], ('u', 'v', 'r'))
    assert lines[0].startswith('Not reported as found') and f'`{name}`' in lines[2]
    info.update(above_input_course_floor=True, certain=True)
    assert [r['term'] for r in kept_out_records(ident, library, nominal)] == [name]
    assert within_input_course_records(ident, library, nominal) == []
