"""The departure benchmark's scenario: the shipped one with an effect from a given time."""

import pytest

from offline.benchmarks.departure import hook_of, scenario_with_effect
from vessel_physics.errors import ConfigError
from vessel_physics.simulation.config import load_simulation


def test_the_scenario_switches_the_named_effect_on_at_the_onset(tmp_path):
    path = scenario_with_effect('patrol_boat', hook_of('hull_fouling'), 1800.0, 60.0,
                                'passage', tmp_path)
    cfg = load_simulation(path)
    assert cfg.extra_forces == 'vessel_diagnosis.concealed:hull_fouling'
    assert (cfg.extra_forces_from_s, cfg.extra_forces_ramp_s) == (1800.0, 60.0)
    assert cfg.operator.turn_probability == 0.0 and cfg.operator.rudder_routine_rad == 0.02
    shipped = load_simulation(None, 'patrol_boat')
    assert cfg.wind == shipped.wind and cfg.noise == shipped.noise   # the rest is shipped


def test_the_control_has_no_effect_and_a_wrong_one_is_refused(tmp_path):
    assert hook_of('none') is None
    cfg = load_simulation(scenario_with_effect('patrol_boat', None, 1800.0, 60.0, 'shipped',
                                               tmp_path))
    assert cfg.extra_forces is None and cfg.extra_forces_from_s is None
    with pytest.raises(ConfigError, match='no callable'):
        scenario_with_effect('patrol_boat', hook_of('no_such_effect'), 1.0, 1.0, 'shipped',
                             tmp_path)
