"""The Table-2 script end to end on toy data with tiny configs (slow: minutes)."""

import json
from pathlib import Path
import subprocess
import sys

import pytest

from hybrid_models.toy import write_toy_dataset

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_reproduce_table2_smoke_writes_table_figures_and_claims(tmp_path):
    toy = write_toy_dataset(tmp_path / 'toy', n_runs=6, n_samples=300)
    out = tmp_path / 'results'
    cmd = [sys.executable, str(ROOT / 'offline' / 'reproduce_table2.py'), '--dataset',
           str(toy), '--out', str(out), '--smoke']
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=1200)
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads((out / 'results.json').read_text())
    labels = {row['label'] for row in result['rows']}
    assert {'QLag', 'LSTM', 'Min-1P', 'Pro+Hyd-2P'} <= labels
    assert set(result['claims']) == {'2P_beats_1P', 'best_hybrid_vs_baselines',
                                     'threshold_costs_no_accuracy',
                                     'bound_placement_at_15pct'}
    for name in ('REPORT.md', 'table.md', 'rmse_vs_threshold.png'):
        assert (out / name).stat().st_size > 0
    # A second run keeps every finished model instead of training again.
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0
    trainings = json.loads((out / 'results.json').read_text())['trainings']
    assert all(t['status'] == 'kept' for t in trainings)
