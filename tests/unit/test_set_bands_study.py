"""set_bands --study: cross-validated bands from a study's out-of-fold forecasts."""

import json
from pathlib import Path
import shutil

import numpy as np
import pytest

from hybrid_models.cli import crossval
from hybrid_models.cli.set_bands import main as set_bands
from offline.benchmarks.toy import write_toy_dataset

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'
SHORT = ['training.progress=false', 'training.phases=[{kind: teacher, max_epochs: 1, '
         'patience: 1, lr: 0.005}, {kind: multistep, max_epochs: 1, patience: 1, lr: 0.003}]']
LABEL = 'tiny hybrid'
HORIZON = ['--horizon', '100']


@pytest.fixture(scope='module')
def study(tmp_path_factory):
    """Return a finished three-fold, two-seed study of tiny hybrids on six toy runs."""
    root = tmp_path_factory.mktemp('study')
    toy = write_toy_dataset(root / 'toy', n_runs=6, n_samples=260)
    out = root / 'cv'
    args = ['--dataset', str(toy), '--out', str(out), '--seeds', '2', '--folds', '3',
            '--model', f'{LABEL}={SMOKE}', '--horizon', '100', '--window', '20',
            '--threads', '1', '--jobs', '1', '--no-ensemble']
    assert crossval.main(args + sum((['--set', s] for s in SHORT), [])) == 0
    return out, toy


def model_of(out, fold=0, seed=0):
    return out / 'runs' / 'tiny_hybrid' / f'fold{fold}' / f'seed{seed}' / 'model.safetensors'


def test_study_bands_are_written_at_the_checkpoints_threshold_and_their_coverage_printed(
        study, tmp_path, capsys):
    from safetensors.numpy import load_file

    from hybrid_models.cli.model_card import main as model_card
    from hybrid_models.engine import Forecaster

    out, toy = study
    # The checkpoint given the bands: any hybrid of the recipe (here a fold's model).
    path = tmp_path / 'model.safetensors'
    shutil.copy(model_of(out), path)
    assert set_bands([str(path), '--study', str(out), '--model', LABEL, *HORIZON]) == 0
    printed = capsys.readouterr().out
    engine = Forecaster.from_checkpoint(path)
    bands = engine.bands
    assert bands is not None, engine.bands_note
    assert bands.relative_threshold == engine.relative_threshold
    assert bands.source['folds'] == 3 and bands.source['runs'] == 6
    assert bands.source['calibration'] == 'fold-robust'
    assert bands.source['seeds'] == 'all' and bands.source['model'] == LABEL
    assert bands.origin.startswith('cross-validated over 3 folds, ')
    assert bands.origin.endswith('quantile levels chosen leave-one-fold-out')
    assert f"{bands.source['forecasts']} forecasts of 6 runs" in bands.origin
    assert 'leave-one-fold-out' in printed and bands.origin in printed
    rows = [line for line in printed.splitlines() if line.startswith('| 0.')]
    assert len(rows) == 2 * 4          # two levels, four reported steps
    assert printed.count('held out (') == 3 and '0.9 band ' in printed
    before, after = load_file(str(model_of(out))), load_file(str(path))
    assert all(np.array_equal(before[k], after[k]) for k in before)
    # One seed's models: half the forecasts.
    one = tmp_path / 'one.safetensors'
    assert set_bands([str(path), '--study', str(out), '--model', LABEL, '--seed', '1',
                      *HORIZON, '--out', str(one)]) == 0
    assert 2 * Forecaster.from_checkpoint(one).bands.source['forecasts'] == \
        bands.source['forecasts']
    # The model card says where its bands came from.
    assert model_card([str(path), '--dataset', str(toy), '--horizon', '100',
                       '--out', str(tmp_path / 'card')]) == 0
    assert 'From cross-validated over 3 folds' in (tmp_path / 'card' / 'MODEL_CARD.md').read_text()


def test_out_of_fold_forecasts_are_served_at_the_given_threshold(study):
    from hybrid_models.checkpoint import load_model
    from hybrid_models.data import forecast_windows, load_runs
    from hybrid_models.evaluation import PhysicsOnly
    from hybrid_models.models import predict
    from hybrid_models.studies.crossval import out_of_fold_forecasts, read_study

    out, _ = study
    folds, _ = read_study(out)
    model, _ = load_model(model_of(out))
    held = out_of_fold_forecasts(out, LABEL, model.spec, 0.0, 20, 100, 10, [0])
    assert [h.fold for h in held] == [0, 1, 2]
    assert sorted(r for h in held for r in h.runs) == sorted(
        r for f in folds for r in f.test)
    windows = forecast_windows(load_runs(folds[0].path, 'test', model.spec), 20, 100, 10)
    # Threshold 0 serves the physics alone; the measured states are the targets.
    assert np.allclose(held[0].pred, predict(PhysicsOnly(model.physical), windows), atol=1e-5)
    assert np.array_equal(held[0].true, windows.z_target)
    unbounded = out_of_fold_forecasts(out, LABEL, model.spec, None, 20, 100, 10, [0])
    assert not np.allclose(unbounded[0].pred, held[0].pred, atol=1e-5)


def test_a_wrong_study_label_seed_or_vessel_is_refused_in_one_line(study, tmp_path, capsys):
    from hybrid_models.checkpoint_format import read_header, rewrite_config

    out, _ = study
    path = tmp_path / 'model.safetensors'
    shutil.copy(model_of(out), path)

    def refused(*extra) -> str:
        assert set_bands([str(path), *extra, *HORIZON]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1
        return err

    assert f"trained no model 'lstm'; it trained ['{LABEL}']" in refused(
        '--study', str(out), '--model', 'lstm')
    assert 'trained seeds [0, 1], not [7]' in refused(
        '--study', str(out), '--model', LABEL, '--seed', '7')
    assert 'holds no finished study' in refused('--study', str(tmp_path), '--model', LABEL)
    # A study of one fold (the dataset's own split) has no out-of-fold forecasts.
    one = tmp_path / 'one_fold'
    one.mkdir()
    result = json.loads((out / 'results.json').read_text())
    (one / 'results.json').write_text(json.dumps({**result, 'folds': result['folds'][:1]}))
    assert 'need at least 2 folds' in refused('--study', str(one), '--model', LABEL)
    # A checkpoint of another rate than the study's vessel.
    config = read_header(path)
    config['vehicle']['rate_hz'] = 2 * config['vehicle']['rate_hz']
    rewrite_config(path, config)
    assert 'rate_hz' in refused('--study', str(out), '--model', LABEL)
    with pytest.raises(SystemExit):
        set_bands([str(path), '--study', str(out)])
    with pytest.raises(SystemExit):
        set_bands([str(path), '--dataset', str(out), '--model', LABEL])
