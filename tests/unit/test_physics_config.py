"""Simulation configuration: defaults, and one clear line for every bad key or value."""

from pathlib import Path

import pytest
import yaml

from vessel_physics.errors import ConfigError
from vessel_physics.files import config_dir, display_name, find_file
from vessel_physics.patrol.params import params_from_dict
from vessel_physics.physics_file import load_physics
from vessel_physics.simulation.config import (
    default_config_path,
    defaults,
    load_hook,
    load_simulation,
)

load_config = load_simulation


def keys(tree: dict, prefix: str = '') -> set[str]:
    """Every key of a nested mapping, dotted (a mapping of values counts as one key)."""
    out = set()
    for key, value in tree.items():
        if isinstance(value, dict) and key not in ('std', 'actuators'):
            out |= keys(value, f'{prefix}{key}.')
        else:
            out.add(prefix + key)
    return out


def error_of(source) -> str:
    with pytest.raises(ConfigError) as info:
        load_config(source)
    message = str(info.value)
    assert '\n' not in message, message
    return message


def test_default_file_spells_out_every_key():
    data = yaml.safe_load(default_config_path().read_text())
    assert keys(data) == keys(defaults())
    assert load_config() == load_config({})


@pytest.mark.parametrize('source, words', [
    ({'wavs': {}}, ['wavs', "did you mean 'waves'"]),
    ({'waves': {'hs': [1, 2]}}, ['waves.hs', "did you mean 'hs_m'"]),
    ({'noise': {'std': {'rr': 0.1}}}, ['noise.std.rr', "did you mean 'r'"]),
    ({'dt': 0.5}, ['dt', '0 < value <= 0.1 (s)', '0.5']),
    ({'dt': 0.07}, ['dt', 'whole steps']),
    ({'waves': {'hs_m': [3, 1]}}, ['waves.hs_m', '[lo, hi]', '0 <= lo <= hi <= 15 (m)']),
    ({'waves': {'components': 2.5}}, ['waves.components', 'an integer']),
    ({'wind': {'force_scale': True}}, ['wind.force_scale', 'a number']),
    ({'wind': {'enabled': 'yes'}}, ['wind.enabled', 'true or false']),
    ({'operator': {'shaft_speed_rpm': [366, 5000]}}, ['operator.shaft_speed_rpm', '1000] rpm']),
    ({'wind': 3}, ['wind', 'expected a mapping']),
    ({'vessel': 'no_such_vessel'}, ['vessel', 'no_such_vessel', 'not a shipped vessel']),
    ({'vessel': 'patrol_vessel.yaml'}, ['vessel', 'a physics or parameter file',
                                        'physics: patrol_vessel.yaml']),
    ({'vessel': 'kvlcc2_hsva', 'waves': {'enabled': True}}, ['waves.enabled', 'feels no waves']),
    ({'extra_forces': 'nodots'}, ['extra_forces', "'module:function'"]),
    ({'extra_forces': 'no_such_module_xyz:f'}, ['extra_forces', 'cannot import',
                                                 'no_such_module_xyz']),
    ({'extra_forces': 'math:no_such_function'}, ['extra_forces', 'no callable']),
])
def test_invalid_config_is_one_clear_line(source, words):
    message = error_of(source)
    for word in words:
        assert word in message, message


def test_bad_yaml_files(tmp_path):
    missing = error_of(tmp_path / 'missing.yaml')
    assert 'missing.yaml' in missing and 'cannot read' in missing
    bad = tmp_path / 'bad.yaml'
    bad.write_text('dt: [1, 2\n')
    assert 'not valid YAML' in error_of(bad)
    listy = tmp_path / 'list.yaml'
    listy.write_text('- 1\n- 2\n')
    assert 'expected a mapping' in error_of(listy)


def test_user_file_overrides_and_finds_physics_beside_it(tmp_path):
    (tmp_path / 'my_vessel.yaml').write_text(
        (config_dir() / 'patrol_vessel.yaml').read_text().replace('GM: 1.1 ', 'GM: 1.2 '))
    cfg_file = tmp_path / 'sim.yaml'
    cfg_file.write_text('physics: my_vessel.yaml\nwaves:\n  hs_m: [1.0, 1.5]\n')
    cfg = load_config(cfg_file)
    assert cfg.params.GM == 1.2 and cfg.vessel.name == 'patrol_boat'
    assert cfg.waves.hs_m == (1.0, 1.5)
    assert cfg.waves.gamma == 3.3                       # untouched default
    assert cfg.to_dict()['waves']['hs_m'] == [1.0, 1.5]


def test_hook_loader_returns_the_callable():
    import math
    assert load_hook('math:cos') is math.cos


def test_vessels_load_and_differ_where_the_paper_says():
    true, nominal = (load_physics(n).params for n in ('patrol_vessel', 'nominal_vessel'))
    differ = {k for k in true.__dataclass_fields__
              if getattr(true, k) != getattr(nominal, k)}
    assert differ == {'name', 'rho', 'm', 'displacement', 'GM', 'Ixx', 'Izz', 'Yvdot', 'Kpdot',
                      'Nrdot', 'Xvr', 'Kphiphiphi'}


def test_vessel_file_errors_are_one_line(tmp_path):
    good = yaml.safe_load((config_dir() / 'patrol_vessel.yaml').read_text())
    cases = [
        ({**good, 'Xuu': 1.0}, "did you mean 'Xauu'"),
        ({k: v for k, v in good.items() if k != 'Kp'}, "missing parameters ['Kp']"),
        ({**good, 'Ixx': '2.3763e6'}, 'write 1.0e+6'),
        ({**good, 'm': 500000.0}, 'rho * displacement'),
        ({**good, 'B': -1.0}, 'B: must be > 0'),
        ({**good, 'wake_fraction': 1.5}, 'wake_fraction'),
    ]
    for data, words in cases:
        with pytest.raises(ConfigError) as info:
            params_from_dict(data)
        assert words in str(info.value) and '\n' not in str(info.value)
    with pytest.raises(ConfigError, match='no such file'):
        load_physics(Path(tmp_path) / 'nope.yaml')


def test_a_packaged_file_is_found_by_the_name_reports_give_it(tmp_path, monkeypatch):
    packaged = config_dir() / 'kvlcc2_hsva_mmg.yaml'
    name = display_name(packaged)
    assert name == 'vessel_physics/config/kvlcc2_hsva_mmg.yaml'
    monkeypatch.chdir(tmp_path)                # not found by the working directory
    assert find_file(name) == packaged
    assert find_file(name[:-len('.yaml')]) == packaged
