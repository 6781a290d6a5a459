"""Feature maps: every Blanke term against its formula, masks by name."""

import numpy as np
import pytest
import torch

from hybrid_models.physical.features import BLANKE_TERMS, DOF_TERMS, FeatureMap
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')

Z = torch.tensor([[7.0, -0.4, 0.03, -0.02, 0.05],
                  [-2.0, 0.3, -0.01, 0.04, -0.1]], dtype=torch.float64)
C = torch.tensor([[80.0, 0.01, 0.02, 3.0, 0.6, 0.8],
                  [60.0, -0.03, -0.01, 1.0, -1.0, 0.0]], dtype=torch.float64)


def by_hand(z):
    u, v, p, r, phi = z
    return {
        '|u|u': u * abs(u), 'vr': v * r, 'rr': r * r, 'pr': p * r,
        '|u|v': abs(u) * v, 'ur': u * r, 'v|v|': v * abs(v), 'v|r|': v * abs(r),
        'r|v|': r * abs(v), 'phi|uv|': phi * abs(u * v), 'phi|ur|': phi * abs(u * r),
        'phiuu': phi * u * u, '|u|p': abs(u) * p, 'p|p|': p * abs(p),
        'phi^3': phi ** 3, '|u|r': abs(u) * r, 'r|r|': r * abs(r),
        'phiu|r|': phi * u * abs(r), 'phiu|u|': phi * u * abs(u),
    }


def test_every_blanke_feature_matches_its_formula():
    fm = FeatureMap(SHIP, 'hyd')
    out = fm.array_features(Z, C).numpy()
    assert len(fm.names) == len(set(fm.names)) == 11 + len(BLANKE_TERMS)
    for row in range(2):
        expected = by_hand(Z[row].tolist())
        assert set(expected) == set(BLANKE_TERMS)
        for name, value in expected.items():
            assert out[row, fm.names.index(name)] == pytest.approx(value, rel=1e-12), name
        # Linear part: controls first, then states, by name.
        for i, name in enumerate(SHIP.control_names):
            assert out[row, fm.names.index(name)] == C[row, i]
        for i, name in enumerate(SHIP.state_names):
            assert out[row, fm.names.index(name)] == Z[row, i]


def test_dof_terms_follow_the_patrol_vessel_equations():
    # Perez, Ross & Fossen 2006 force expressions (shared/REFERENCES.md).
    assert set(DOF_TERMS['X']) == {'|u|u', 'vr', 'rr', 'pr'}
    assert set(DOF_TERMS['Y']) == {'|u|v', 'ur', 'v|v|', 'v|r|', 'r|v|', 'phi|uv|',
                                   'phi|ur|', 'phiuu'}
    assert set(DOF_TERMS['K']) == set(DOF_TERMS['Y']) | {'|u|p', 'p|p|', 'phi^3'}
    assert set(DOF_TERMS['N']) == {'|u|v', 'ur', 'r|v|', 'phi|uv|', '|u|r', 'r|r|',
                                   'phiu|r|', 'phiu|u|'}


@pytest.mark.parametrize('mode', ['diagonal', 'coupled'])
def test_masks_select_features_by_name(mode):
    fm = FeatureMap(SHIP, 'hyd', masks=mode)
    linear = set(SHIP.control_names) | set(SHIP.state_names)
    dofs = {'diagonal': {'u': 'X', 'v': 'Y', 'p': 'K', 'r': 'N', 'phi': ''},
            'coupled': {'u': 'X', 'v': 'YKN', 'p': 'YKN', 'r': 'YKN', 'phi': 'YKN'}}[mode]
    mask = fm.mask_matrix()
    for i, state in enumerate(SHIP.state_names):
        expected = linear | {t for d in dofs[state] for t in DOF_TERMS[d]}
        assert set(fm.masks[state]) == expected
        # The boolean matrix marks exactly those columns, wherever they sit.
        assert {fm.names[j] for j in np.flatnonzero(mask[i])} == expected


def test_lin_and_qua_names_and_values():
    lin = FeatureMap(SHIP, 'lin')
    assert lin.names == SHIP.control_names + SHIP.state_names
    qua = FeatureMap(SHIP, 'qua')
    out = qua.array_features(Z, C)
    assert out.shape == (2, 22)
    j = qua.names.index('n^2')
    assert out[0, j] == 6400.0
    assert qua.names.index('phi^2') == 21 and out[1, 21] == pytest.approx(0.01)
    assert all(set(qua.masks[s]) == set(qua.names) for s in SHIP.state_names)


def test_unknown_kinds_are_refused():
    with pytest.raises(ValueError, match='feature map'):
        FeatureMap(SHIP, 'cubic')
    with pytest.raises(ValueError, match='mask mode'):
        FeatureMap(SHIP, 'hyd', masks='shifted')
