"""Two models of a study seed by seed: the paired figures, and the workflow's section."""

import numpy as np
import pytest
from scipy import stats

from hybrid_models.studies.paired import compare, paired_rows, paired_table
from vessel_diagnosis.workflow import AUGMENTED, NOMINAL, seed_by_seed


def row(label, finals, means):
    return {'label': label, 'per_seed_metrics': [
        {'trajectory': {'final_mean': f, 'mean': m}} for f, m in zip(finals, means, strict=True)]}


def test_the_paired_figures_are_those_of_the_differences_seed_by_seed():
    first, second = np.array([1.0, 1.4, 1.2, 0.9]), np.array([1.1, 1.3, 1.5, 1.0])
    c = compare(first, second)
    diff = first - second
    assert c['first_ahead'] == 3 and c['seeds'] == 4
    assert c['mean_difference'] == pytest.approx(diff.mean())
    assert c['standard_error'] == pytest.approx(diff.std(ddof=1) / 2)
    assert c['t_test_p'] == pytest.approx(stats.ttest_1samp(diff, 0.0).pvalue)
    assert c['sign_test_p'] == pytest.approx(stats.binomtest(3, 4).pvalue)
    # One seed: a difference, no spread and no t-test.
    alone = compare(first[:1], second[:1])
    assert alone['standard_error'] is None and alone['t_test_p'] is None


def test_rows_without_pairs_are_refused_and_the_table_has_a_line_per_figure():
    a = row('a', [1.0, 1.2, 1.1], [0.3, 0.4, 0.35])
    b = row('b', [1.1, 1.3, 1.0], [0.4, 0.4, 0.3])
    result = paired_rows(a, b)
    assert set(result) == {'at the horizon [m]', 'trajectory over the horizon [m]'}
    assert result['trajectory over the horizon [m]']['first'] == [0.3, 0.4, 0.35]
    table = paired_table(result)
    assert len(table) == 4 and '| at the horizon [m] | 1.00 / 1.10, ' in table[2]
    assert '2 of 3' in table[2]
    with pytest.raises(ValueError, match='3 and 2 seeds'):
        paired_rows(a, row('c', [1.0, 1.1], [0.3, 0.3]))


def test_the_workflow_reports_its_two_hybrids_seed_by_seed_from_two_seeds_on():
    rows = [row(NOMINAL, [1.4, 1.3], [0.5, 0.4]), row(AUGMENTED, [1.2, 1.35], [0.4, 0.45]),
            {'label': 'physics (nominal)'}]
    paired, section = seed_by_seed(rows)
    assert paired['at the horizon [m]']['first'] == [1.2, 1.35]     # the augmented one
    assert section[0] == f'## Seed by seed: {AUGMENTED} (first) against {NOMINAL}'
    assert any(line.startswith('| at the horizon [m] | 1.20 / 1.40, 1.35 / 1.30 | 1 of 2')
               for line in section)
    one_seed = [row(NOMINAL, [1.4], [0.5]), row(AUGMENTED, [1.2], [0.4])]
    assert seed_by_seed(one_seed) == (None, [])
    assert seed_by_seed(rows[:1]) == (None, [])
