"""
The diagnosis names a concealed effect blind in every family, and nothing in a control.

Each scenario of vessel_diagnosis/config/scenarios.yaml for the KVLCC2 (MMG family) and
the Otter (Fossen family) is simulated small (6 runs of 2 and 3.3 minutes) and identified
with the nominal physics that lacks the effect. The intervals must contain the value the
simulator was given. The full-size proof with held-out improvements is
test_diagnosis_proof.py; the patrol boat's scenarios are test_diagnosis_cases.py.
"""

import json

import numpy as np
import pytest

from vessel_description import load_vessel
from vessel_diagnosis.library import load_library
from vessel_diagnosis.pipeline import name_missing_physics
from vessel_diagnosis.recordings import load_recordings
from vessel_diagnosis.scenarios import load_scenario, load_scenario_file, simulate_scenario
from vessel_diagnosis.settings import load_settings
from vessel_physics.families import FAMILIES

RUNS = 6
SECONDS = {'kvlcc2_hsva': 120.0, 'otter': 200.0}
EFFECTS = load_scenario_file()['effects']


@pytest.mark.parametrize('name', sorted(FAMILIES))
def test_every_family_brings_its_candidate_library_in_its_own_folder(name):
    family = FAMILIES[name]
    folder = family.diagnosis_candidates.parent
    assert (folder / 'family.py').is_file() and folder.name == name
    library = load_library(None, family)
    assert library.family == name and library.candidates
    # a candidate names a term or a parameter of this family, never another's
    for c in library.candidates:
        assert c.kind == 'current' or c.target in family.terms or \
            c.target in family.parameter_names(), c


@pytest.fixture(scope='module')
def identified(tmp_path_factory):
    cache = {}

    def run(vessel, name):
        if (vessel, name) not in cache:
            out = simulate_scenario(name, tmp_path_factory.mktemp(f'{vessel}_{name}'),
                                    runs=RUNS, hours=SECONDS[vessel] / 3600.0, seed=11,
                                    vessel=vessel)
            scenario = load_scenario(name, vessel=vessel)
            family = scenario.nominal.family
            settings = load_settings(overrides={'selection': {'bootstrap': 50, 'rounds': 2}},
                                     family=family.name)
            named = name_missing_physics(load_recordings([out]), scenario.nominal, settings,
                                         load_library(None, family), load_vessel(vessel))
            cache[vessel, name] = (scenario, named, out)
        return cache[vessel, name]
    return run


def _only(named, category):
    """Return the one finding, of ``category``, with an interval that excludes zero."""
    assert named.status == 'findings', named.records
    assert [r['category'] for r in named.records] == [category], named.records
    record = named.records[0]
    lo, hi = record['ci95']
    assert lo <= record['coefficient'] <= hi and not lo <= 0.0 <= hi
    return record


# The Otter's control is a scenario of its own (12 s); the KVLCC2's here and the patrol
# boat's (test_diagnosis_cases.py) run by default.
@pytest.mark.parametrize('vessel', ['kvlcc2_hsva', pytest.param('otter', marks=pytest.mark.slow)])
def test_control_reports_nothing(identified, vessel):
    _, named, _ = identified(vessel, 'control')
    assert named.status == 'nothing_significant'
    assert named.records == [] and named.kept_out == []


def test_kvlcc2_rudder_offset_is_the_offset_it_was_given(identified):
    scenario, named, _ = identified('kvlcc2_hsva', 'rudder_offset')
    record = _only(named, scenario.expect[0])
    truth = scenario.simulation.physics.parameter(record['term'])
    lo, hi = record['ci95']
    assert record['term'] == 'delta_0' and lo <= truth <= hi, (truth, record)


@pytest.mark.slow       # the KVLCC2's default case is the rudder offset
def test_kvlcc2_added_resistance_is_thirty_percent_of_r0(identified):
    scenario, named, _ = identified('kvlcc2_hsva', 'resistance')
    record = _only(named, scenario.expect[0])
    nominal = scenario.nominal.parameter(record['term'])     # the change over the nominal
    lo, hi = (v / nominal for v in record['ci95'])
    assert record['term'] == 'R_0' and lo <= EFFECTS['added_resistance']['share'] <= hi


def test_otter_weak_thruster_is_the_share_it_lost(identified):
    scenario, named, _ = identified('otter', 'weak_thruster')
    record = _only(named, scenario.expect[0])
    lo, hi = record['ci95']
    loss = EFFECTS['actuator_share']['share'] - 1.0       # the relative thrust change
    assert record['term'] == 'port_thrust' and lo <= loss <= hi, record


@pytest.mark.slow       # the Otter's default case is the weak thruster
def test_otter_current_is_estimated_per_run(identified):
    _, named, out = identified('otter', 'current')
    record = _only(named, 'current')
    runs = json.loads((out / 'manifest.json').read_text())['runs']
    sources = {run['id']: run['source'] for run in runs}
    for run, estimate in record['per_run'].items():
        truth = sources[run]
        assert estimate['speed'] == pytest.approx(truth['current_speed_mps'], abs=0.05)
        to = np.arctan2(estimate['east'], estimate['north'])
        assert abs(np.angle(np.exp(1j * (to - truth['current_direction_rad'])))) < 0.2
