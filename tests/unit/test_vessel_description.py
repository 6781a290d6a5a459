"""Vessel descriptions: the vector contract, one-line refusals, round trips."""

import copy

import pytest
import yaml

from vessel_description import VesselError, load_vessel, parse_vessel, shipped_vessels

SMALL = {
    'name': 'small_boat', 'rate_hz': 10.0, 'window_s': 5.0, 'horizon_s': 30.0,
    'states': ['u', 'v', 'r'],
    'actuators': {'rpm': {'kind': 'propeller', 'range': [-200.0, 200.0]},
                  'rudder': {'kind': 'rudder', 'unit': 'rad', 'range': [-0.6, 0.6]}},
    'particulars': {'length_m': 1.2},
}


def test_the_patrol_boat_file_gives_the_simulators_vectors():
    boat = load_vessel('patrol_boat')
    assert 'patrol_boat' in shipped_vessels()
    assert boat.state_names == ('u', 'v', 'p', 'r', 'phi')
    assert boat.control_names == ('n', 'delta_port', 'delta_stbd', 'wind_speed',
                                  'wind_dir_cos', 'wind_dir_sin')
    assert boat.control_units == ('rad/s', 'rad', 'rad', 'm/s', '1', '1')
    assert (boat.rate_hz, boat.window, boat.horizon) == (1.0, 60, 900)
    assert boat.dataset_columns[:9] == ('t', 'u', 'v', 'p', 'r', 'phi', 'psi', 'x', 'y')
    assert boat.length_m == 51.5 and boat.physics == 'nominal_vessel'


def test_a_3dof_vessel_without_wind_at_10_hz():
    boat = parse_vessel(SMALL)
    assert boat.state_names == ('u', 'v', 'r') and not boat.has_roll
    assert boat.control_names == ('rpm', 'rudder')
    assert boat.control_units == ('rad/s', 'rad')
    assert (boat.window, boat.horizon, boat.dt) == (50, 300, 0.1)
    assert boat.actuator('rpm').low == -200.0  # reversing is a declared range, not an error


def test_round_trip_through_a_manifest_or_checkpoint():
    boat = load_vessel('patrol_boat')
    again = parse_vessel(yaml.safe_load(yaml.safe_dump(boat.to_dict())), 'copy')
    assert again.to_dict() == boat.to_dict()
    boat.check_compatible(again, 'copy')


@pytest.mark.parametrize('edit, message', [
    (lambda d: d.pop('rate_hz'), "missing keys ['rate_hz']"),
    (lambda d: d.update(rate_hz=0), 'rate_hz must be a positive number'),
    (lambda d: d.update(states=['u', 'v']), "states lack ['r']"),
    (lambda d: d.update(states=['u', 'v', 'p', 'r']), 'roll needs both'),
    (lambda d: d.update(states=['v', 'u', 'r']), 'list states in the order'),
    (lambda d: d.update(states=['u', 'v', 'r', 'beta']), "unknown states ['beta']"),
    (lambda d: d['actuators']['rpm'].update(kind='jet'), "kind is 'jet'"),
    (lambda d: d['actuators']['rpm'].update(unit='rpm'), "unit is 'rpm'"),
    (lambda d: d['actuators']['rudder'].update(range=[0.6, -0.6]), 'low < high'),
    (lambda d: d['actuators'].update(u={'kind': 'other', 'unit': '1', 'range': [0, 1]}),
     'clash with states'),
    (lambda d: d.update(environment=['rain']), 'environment must list'),
    (lambda d: d.update(waters='tank'), "waters must be one of ['open', 'basin']"),
    (lambda d: d.update(particulars={'beam_m': 1.0}), 'at least length_m'),
    (lambda d: d.update(limits={'phi': [-1, 1]}), 'not a state of this vessel'),
    (lambda d: d.update(windows_s=3), "unknown keys ['windows_s']"),
    (lambda d: d.update(window_s=0.1), 'fewer than 2 samples'),
])
def test_malformed_descriptions_give_one_line(edit, message):
    data = copy.deepcopy(SMALL)
    edit(data)
    with pytest.raises(VesselError) as info:
        parse_vessel(data, 'test.yaml')
    assert message in str(info.value) and 'test.yaml' in str(info.value)
    assert '\n' not in str(info.value)


def test_waters_default_to_open_and_tank_vessels_say_basin():
    assert parse_vessel(SMALL).waters == 'open'
    assert load_vessel('patrol_boat').waters == 'open'
    for name in ('kvlcc2_hsva', 'snuboat'):
        vessel = load_vessel(name)
        assert vessel.waters == 'basin'
        assert parse_vessel(vessel.to_dict()).waters == 'basin'   # survives a manifest


def test_checkpoint_or_dataset_for_another_vessel_is_refused():
    boat = parse_vessel(SMALL)
    faster = parse_vessel({**SMALL, 'rate_hz': 20.0}, 'fast.yaml')
    with pytest.raises(VesselError, match=r'rate_hz 20.0 vs 10.0'):
        boat.check_compatible(faster, 'checkpoint m.safetensors')
    with pytest.raises(VesselError, match="made for vessel 'patrol_boat'"):
        boat.check_compatible(load_vessel('patrol_boat'), 'checkpoint m.safetensors')


def test_missing_and_broken_files(tmp_path):
    with pytest.raises(VesselError, match='not a shipped vessel'):
        load_vessel('no_such_boat')
    (tmp_path / 'bad.yaml').write_text('name: [1, 2')
    with pytest.raises(VesselError, match='not valid YAML'):
        load_vessel(tmp_path / 'bad.yaml')
