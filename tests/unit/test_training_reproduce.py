"""The reproduce_table2 program end to end on toy data with tiny configs (slow: minutes)."""

import json

import pytest

from hybrid_models.cli import reproduce_table2
from hybrid_models.toy import write_toy_dataset


@pytest.mark.slow
def test_reproduce_table2_smoke_writes_table_figures_and_claims(tmp_path, capsys):
    toy = write_toy_dataset(tmp_path / 'toy', n_runs=6, n_samples=300)
    out = tmp_path / 'results'
    argv = ['--dataset', str(toy), '--out', str(out), '--smoke']
    code = reproduce_table2.main(argv)
    assert code == 0, capsys.readouterr().err[-2000:]
    result = json.loads((out / 'results.json').read_text())
    labels = {row['label'] for row in result['rows']}
    assert {'QLag', 'LSTM', 'Min-1P', 'Pro+Hyd-2P'} <= labels
    assert set(result['claims']) == {'2P_beats_1P', 'best_hybrid_vs_baselines',
                                     'threshold_costs_no_accuracy',
                                     'bound_placement_at_15pct'}
    for name in ('REPORT.md', 'table.md', 'rmse_vs_threshold.png'):
        assert (out / name).stat().st_size > 0
    # A second run keeps every finished model instead of training again.
    assert reproduce_table2.main(argv) == 0
    trainings = json.loads((out / 'results.json').read_text())['trainings']
    assert all(t['status'] == 'kept' for t in trainings)
