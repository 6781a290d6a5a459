"""The library, batched predictions, settings and the bootstrap-lasso estimator."""

import numpy as np
import pytest

from vessel_diagnosis.library import LibraryError, froude_power
from vessel_diagnosis.library import load_library as load_family_library
from vessel_diagnosis.predict import Predictor
from vessel_diagnosis.selection import BootstrapLasso, effective_sample_ratio
from vessel_diagnosis.settings import SettingsError, load_settings
from vessel_physics.families import FAMILIES
from vessel_physics.patrol import FAMILY
from vessel_physics.patrol.family import parameter_unit
from vessel_physics.physics_file import load_physics

PHYSICS = load_physics('patrol_vessel')


def load_library(path=None):
    return load_family_library(path, FAMILY)


def test_parameter_units_follow_the_textbook_names():
    assert parameter_unit('Xauu') == 'N m^-2 s^2'
    assert parameter_unit('Nrar') == 'N m s^2 rad^-2'
    assert parameter_unit('Kp') == 'N m s rad^-1'
    assert parameter_unit('Yvdot') == 'kg'


def test_froude_powers_of_units():
    assert froude_power('N') == 3 and froude_power('N m') == 4
    assert froude_power('N s/m') == 2.5 and froude_power('N m^-2 s^2') == 2
    assert froude_power('m/s') == 0.5 and froude_power('rad') == 0
    assert froude_power('1 (fraction of the term)') == 0


@pytest.mark.parametrize('family', sorted(FAMILIES))
def test_every_family_has_a_library_of_its_own_terms(family):
    library = load_family_library(None, FAMILIES[family])
    assert library.family == family and len(library.candidates) >= 10
    # Absolute sizes follow Froude's law: a vessel twice as long, forces 8 times.
    double = library.scaled_to(2.0 * library.reference_length_m)
    for before, after in zip(library.candidates, double.candidates, strict=True):
        ratio = (after.absolute_scale or after.scale) / before.scale
        assert ratio == pytest.approx(2.0 ** froude_power(before.unit))


def test_default_library_loads_and_covers_the_categories():
    library = load_library()
    categories = {c.category for c in library.candidates}
    assert {'resistance', 'hull_damping', 'roll_damping', 'restoring', 'added_mass', 'wind',
            'current', 'actuator_bias', 'propulsion', 'static_bias'} <= categories
    assert library.has_current


def test_bad_library_fails_with_one_line(tmp_path):
    path = tmp_path / 'lib.yaml'
    path.write_text('candidates:\n  - {name: a, kind: parameter, parameter: Xuau, '
                    'category: resistance, scale: 0.1}\n')
    with pytest.raises(LibraryError, match="unknown parameter 'Xuau' \\(did you mean 'Xauu'"):
        load_library(path)


def test_bad_settings_fail_with_one_line(tmp_path):
    path = tmp_path / 's.yaml'
    path.write_text('selection: {bootstrapp: 10}\n')
    with pytest.raises(SettingsError, match='selection.bootstrapp: unknown key \\(did you'):
        load_settings(path)


def test_batched_variants_equal_separate_predictions():
    library = load_library()
    physics = PHYSICS
    rng = np.random.default_rng(0)
    n, horizon = 5, 6
    z0 = np.column_stack([rng.uniform(3, 8, n), rng.normal(0, 0.2, n), rng.normal(0, 0.01, n),
                          rng.normal(0, 0.01, n), rng.normal(0, 0.01, n)])
    psi0 = rng.uniform(0, 6, n)
    c = np.tile(np.array([80.0, 0.05, 0.04, 6.0, 0.6, 0.8]), (n, horizon + 1, 1))
    names = ['Xauu', 'Yvdot', 'GM', 'wake_fraction', 'relative_wind_sway', 'rudder_offset']
    steps = [10.0, 5000.0, 0.01, 0.01, 5.0, 0.001]
    variants = [library.variant(library.by_name[k], physics, s)
                for k, s in zip(names, steps, strict=True)]
    predictor = Predictor(physics, 1.0, 2)
    batched = predictor.simulate_variants(z0, psi0, c, None, variants)
    np.testing.assert_allclose(batched[0], predictor.simulate(z0, psi0, c), rtol=1e-12)
    for i, (name, step) in enumerate(zip(names, steps, strict=True)):
        moved = library.apply(physics, {name: step})
        alone = Predictor(moved, 1.0, 2).simulate(z0, psi0, c)
        np.testing.assert_allclose(batched[i + 1], alone, rtol=1e-9, atol=1e-12)


def test_current_offsets_ground_from_water_velocity():
    physics = PHYSICS
    z = np.array([[6.0, 0.0, 0.0, 0.0, 0.0]])
    c = np.array([[80.0, 0.0, 0.0, 0.0, 1.0, 0.0]])
    still = Predictor(physics).one_step(z, np.zeros(1), c, c)
    # A following current of 0.5 m/s: the hull sees 5.5 m/s, less drag, the ship speeds up.
    current = Predictor(physics).one_step(z, np.zeros(1), c, c, np.array([[0.5, 0.0]]))
    assert current[0, 0] > still[0, 0]


def _blocks(n, size):
    return np.arange(n) // size


def test_bootstrap_lasso_finds_the_true_columns_and_covers_them():
    rng = np.random.default_rng(1)
    n, k = 4000, 12
    X = rng.normal(size=(n, k))
    truth = np.zeros(k)
    truth[[2, 7]] = [0.5, -0.3]
    y = X @ truth + rng.normal(size=n)
    model = BootstrapLasso(n_bootstrap=60, threshold=0.8).fit(
        X, y, _blocks(n, 100), [f'c{i}' for i in range(k)])
    assert list(np.flatnonzero(model.support_)) == [2, 7]
    assert model.inclusion_probability_[[2, 7]].min() == 1.0
    assert model.inclusion_probability_[np.setdiff1d(np.arange(k), [2, 7])].max() < 0.5
    for j in (2, 7):
        lo, hi = model.ci95_[j]
        assert lo < truth[j] < hi
    np.testing.assert_allclose(model.predict(X[:3]), X[:3] @ model.coef_)
    assert list(model.feature_names_in_[model.support_]) == ['c2', 'c7']


def test_bootstrap_lasso_selects_nothing_in_noise():
    rng = np.random.default_rng(2)
    X = rng.normal(size=(3000, 10))
    y = rng.normal(size=3000)
    model = BootstrapLasso(n_bootstrap=60).fit(X, y, _blocks(3000, 100))
    assert not model.support_.any()


def test_effective_sample_ratio():
    rng = np.random.default_rng(3)
    white = rng.normal(size=20000)
    assert effective_sample_ratio(white) == pytest.approx(1.0, abs=0.05)
    ar = np.zeros(20000)
    for i in range(1, len(ar)):
        ar[i] = 0.9 * ar[i - 1] + white[i]
    # AR(1) with a = 0.9: n_eff / n = (1 - a) / (1 + a) = 0.053
    assert effective_sample_ratio(ar) == pytest.approx(0.053, abs=0.02)
