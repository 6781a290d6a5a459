"""Port/starboard mirror images: declared per vessel, right for symmetric physics, trained on."""

import copy
from dataclasses import asdict
import json

import numpy as np
import pytest

from hybrid_models.physical import build_physical
from hybrid_models.run_store import MIRROR_SUFFIX, build_split, mirror_rows
from offline.benchmarks.toy import TOY_VESSEL, write_toy_dataset
from vessel_datasets.format import read_dataset
from vessel_description import VesselError, load_vessel, parse_vessel
from vessel_physics.physics_file import load_physics

TWIN = load_vessel('snuboat')
KVLCC2 = load_vessel('kvlcc2_hsva')


def declared(vessel, mirror):
    data = copy.deepcopy(vessel.to_dict())
    data['mirror'] = mirror
    return parse_vessel(data, 'test')


@pytest.mark.parametrize('mirror, message', [
    ({'n_port': 'n_stbd', 'n_stbd': 'n_port'}, 'must give every actuator'),
    ({'n_port': 'delta_port', 'n_stbd': 'n_stbd', 'delta_port': '-delta_stbd',
      'delta_stbd': '-delta_port'}, 'is a rudder, not a propeller'),
    ({'n_port': 'n_stbd', 'n_stbd': 'n_port', 'delta_port': '-delta_stbd',
      'delta_stbd': 'delta_port'}, 'the mirror of the mirror'),
    ({'n_port': 'n_stbd', 'n_stbd': 'n_port', 'delta_port': '-rudder',
      'delta_stbd': '-delta_port'}, 'is not an actuator'),
])
def test_a_mirror_declaration_is_refused_in_one_line_unless_it_is_an_involution(
        mirror, message):
    with pytest.raises(VesselError, match=message):
        declared(TWIN, mirror)


def test_a_vessel_without_a_declaration_has_no_mirror_image():
    with pytest.raises(VesselError, match='declares no mirror image'):
        KVLCC2.mirror_maps()


def test_the_twin_screw_image_swaps_sides_and_flips_sway_yaw_and_rudders():
    image = mirror_rows(TWIN)
    # [u, v, r | n_port, n_stbd, delta_port, delta_stbd | u, v, r true]
    row = np.array([1.0, 0.2, 0.3, 10.0, 20.0, 0.1, 0.15, 1.1, 0.21, 0.31], np.float32)
    np.testing.assert_allclose(
        image(row), [1.0, -0.2, -0.3, 20.0, 10.0, -0.15, -0.1, 1.1, -0.21, -0.31])
    np.testing.assert_array_equal(image(image(row)), row)


def test_wind_from_port_becomes_wind_from_starboard():
    boat = declared(TOY_VESSEL, {'n': 'n', 'delta_port': '-delta_stbd',
                                 'delta_stbd': '-delta_port'})
    _, sources, signs = boat.mirror_maps()
    c = np.array([80.0, 0.1, 0.2, 5.0, 0.6, 0.8])
    np.testing.assert_allclose(c[sources] * signs, [80.0, -0.2, -0.1, 5.0, 0.6, -0.8])


def mmg_forecasts(symmetric: bool):
    """Feed back three seconds of a KVLCC2 MMG forecast and of its mirror image."""
    ship = declared(KVLCC2, {'n': 'n', 'delta': '-delta'})
    values = asdict(load_physics(KVLCC2.physics, KVLCC2).params)
    if symmetric:   # one wake and one flow-straightening coefficient for both sides
        values['gamma_R_minus'] = values['gamma_R_plus']
        values['C_2_minus'] = values['C_2_plus']
    physics = build_physical({'kind': 'mmg', 'substeps': 2, 'mmg': values}, ship)
    rng = np.random.default_rng(0)
    z = np.column_stack([rng.uniform(0.8, 1.2, 20), rng.uniform(-0.05, 0.05, 20),
                         rng.uniform(-0.02, 0.02, 20)])
    c = np.column_stack([np.full(20, 64.3), rng.uniform(-0.6, 0.6, 20)])
    state_signs, sources, signs = ship.mirror_maps()
    z_m, c_m = z * state_signs, c[:, sources] * np.asarray(signs)
    for _ in range(30):
        z, z_m = physics(z, c), physics(z_m, c_m)
    return z * state_signs, z_m


def test_mirrored_data_gives_the_mirrored_forecast_of_a_symmetric_physics():
    # The MMG standard model with the same coefficients for inflow from port and from
    # starboard is symmetric about the centre plane: the forecast of the mirror image of
    # a manoeuvre is the mirror image of its forecast.
    mirrored, of_mirror = mmg_forecasts(symmetric=True)
    np.testing.assert_allclose(of_mirror, mirrored, rtol=1e-12, atol=1e-14)


def test_the_single_screw_kvlcc2_is_not_symmetric_so_its_file_declares_no_mirror():
    # Its published wake (C_2) and flow straightening (gamma_R) differ for inflow from
    # port and starboard (the propeller's sense of rotation): a mirrored zig-zag is not
    # one the ship sails.
    mirrored, of_mirror = mmg_forecasts(symmetric=False)
    assert np.abs(of_mirror - mirrored).max() > 1e-5
    assert KVLCC2.mirror is None


def test_training_runs_gain_their_mirror_images_and_symmetric_statistics(tmp_path):
    boat = declared(TOY_VESSEL, {'n': 'n', 'delta_port': '-delta_stbd',
                                 'delta_stbd': '-delta_port'})
    ds = read_dataset(write_toy_dataset(tmp_path / 'toy', n_runs=3, n_samples=120))
    cache = tmp_path / 'cache'
    cache.mkdir()
    store = build_split(ds, 'train', boat, cache, 10_000, 0, mirror=True)
    ids = [r.run_id for r in store.runs]
    assert ids[1::2] == [i + MIRROR_SUFFIX for i in ids[0::2]]
    first, image = store.runs[0], store.runs[1]
    np.testing.assert_allclose(image.rows(np.array([0]), first.length)[0],
                               mirror_rows(boat)(first.rows(np.array([0]), first.length)[0]))
    mean = store.state.normalizer().mean
    assert abs(mean[boat.state_index('v')]) < 1e-6 and abs(mean[boat.state_index('r')]) < 1e-6
    assert json.dumps(boat.to_dict()['mirror'])   # the declaration travels with the vessel
