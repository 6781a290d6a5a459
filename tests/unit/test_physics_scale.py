"""
Scale-aware physics files: a file made for another length is refused, then scaled.

An MMG parameter file states the length it was made for; used with a vessel of
another length it is refused in one line naming both. The Froude-scaled file written
by scale_physics must then be the same hull: a zig-zag of the full-scale ship at
Froude-scaled speed, propeller rate and time step is the model's, scaled.
"""

import math

import numpy as np
import pytest

from hybrid_models.physical import build_physical
from vessel_description import load_vessel, parse_vessel
from vessel_physics.integrator import free_run
from vessel_physics.mmg import scale as scale_physics
from vessel_physics.physics_file import load_physics

FULL_M = 320.0


def build_mmg(vessel):
    return build_physical({'kind': 'mmg'}, vessel)


def tanker(length_m, physics):
    data = load_vessel('kvlcc2_hsva').to_dict()
    data.update(name='kvlcc2_full', physics=physics, recordings={},
                particulars={**data['particulars'], 'length_m': length_m})
    return parse_vessel(data)


def test_a_physics_file_for_another_length_is_refused_in_one_line():
    with pytest.raises(ValueError) as err:
        build_mmg(tanker(FULL_M, 'kvlcc2_hsva_mmg.yaml'))
    text = str(err.value)
    assert "made for L_pp 7 m, but vessel 'kvlcc2_full' is 320 m long" in text
    assert 'scale_physics kvlcc2_hsva_mmg.yaml --length 320' in text and '\n' not in text


def test_the_froude_scaled_file_is_the_same_hull_at_full_scale(tmp_path, capsys):
    out = tmp_path / 'kvlcc2_320.yaml'
    assert scale_physics.main(['kvlcc2_hsva_mmg', '--length', str(FULL_M), '--out',
                               str(out)]) == 0
    lam = FULL_M / 7.0
    assert f'propeller speeds and yaw rates x {1 / math.sqrt(lam):.4g}' in \
        capsys.readouterr().err
    small_ship = load_physics('kvlcc2_hsva_mmg')
    model = small_ship.params
    full_ship = build_mmg(tanker(FULL_M, str(out))).physics  # accepted for the 320 m vessel
    full = full_ship.params
    assert full.L_pp == pytest.approx(FULL_M) and full.D_p == pytest.approx(model.D_p * lam)
    assert full.mass == pytest.approx(model.mass * lam ** 3)
    assert (full.N_r, full.t_P, full.k_zz) == (model.N_r, model.t_P, model.k_zz)
    # A 20/20 zig-zag: model speed, shaft speed and step times sqrt(lambda), 1/sqrt, sqrt.
    dt, steps = 0.1, 600
    t = np.arange(steps) * dt
    delta = np.radians(20.0) * np.sign(np.sin(2 * math.pi * t / 60.0) + 1e-9)
    controls = np.stack([np.full(steps, 64.27), delta], axis=-1)
    z0 = np.array([1.18, 0.0, 0.0])
    small = free_run(small_ship.derivative, z0, controls, dt, substeps=4)
    root = math.sqrt(lam)
    big = free_run(full_ship.derivative, z0 * [root, root, 1 / root],
                   controls * [1 / root, 1.0], dt * root, substeps=4)
    np.testing.assert_allclose(big / [root, root, 1 / root], small, rtol=1e-6, atol=1e-9)
    assert np.abs(small[:, 2]).max() > 0.05  # the model turned: the comparison means something


def test_a_bad_target_is_one_line(tmp_path, capsys):
    assert scale_physics.main(['no_such_hull', '--length', '3', '--out',
                               str(tmp_path / 'x.yaml')]) == 2
    assert "no MMG parameter file 'no_such_hull.yaml'" in capsys.readouterr().err
