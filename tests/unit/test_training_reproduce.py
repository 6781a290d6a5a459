"""The reproduce_table2 program end to end on toy data with tiny configs (slow: minutes)."""

import json

import pytest

from hybrid_models.cli import reproduce_table2
from offline.benchmarks.toy import write_toy_dataset


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
    # A second run keeps every finished model instead of training again, and their
    # evaluation instead of evaluating again (it took a minute under load: issue 50).
    capsys.readouterr()
    assert reproduce_table2.main(argv) == 0
    assert 'evaluation kept' in capsys.readouterr().err
    again = json.loads((out / 'results.json').read_text())
    assert all(t['status'] == 'kept' for t in again['trainings'])
    assert again['rows'] == result['rows']


def test_an_evaluation_is_kept_only_while_its_models_dataset_and_arguments_are_unchanged(
        tmp_path):
    from hybrid_models.studies.table2 import evaluation_fingerprint, kept_evaluation

    toy = write_toy_dataset(tmp_path / 'toy', n_runs=3, n_samples=50)
    model = tmp_path / 'model.safetensors'
    model.write_bytes(b'weights')
    fingerprint = evaluation_fingerprint([model], toy, ['--horizon', '100'])
    results = tmp_path / 'results.json'
    assert not kept_evaluation(results, fingerprint)             # none yet
    results.write_text(json.dumps({'evaluation_fingerprint': fingerprint}))
    assert kept_evaluation(results, fingerprint)
    assert evaluation_fingerprint([model], toy, ['--horizon', '50']) != fingerprint
    run = toy / json.loads((toy / 'manifest.json').read_text())['runs'][0]['file']
    run.write_bytes(run.read_bytes() + b' ')      # a run changed, its manifest not
    changed = evaluation_fingerprint([model], toy, ['--horizon', '100'])
    assert changed != fingerprint
    model.write_bytes(b'weights, trained on')
    assert evaluation_fingerprint([model], toy, ['--horizon', '100']) != changed
    results.write_text('{not json')
    assert not kept_evaluation(results, fingerprint)
