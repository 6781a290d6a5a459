"""Diagnose, augment, retrain, compare: the workflow's folds, physics and rows."""

import json
from pathlib import Path

from offline.benchmarks.toy import write_toy_dataset
from vessel_datasets.format import read_dataset
from vessel_diagnosis import cli_workflow
from vessel_diagnosis.workflow import AUGMENTED, LSTM, NOMINAL, augmented_physics_file
from vessel_physics.patrol import PRO_TERMS, SIMULATOR_TERMS

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config'
SHORT = ['training.progress=false', 'model.physical.substeps=1',
         'training.phases=[{kind: multistep, max_epochs: 1, patience: 1, lr: 0.003}]']


def physics_file(path: Path, terms) -> Path:
    path.write_text(json.dumps({'format': 'vessel-physics/1', 'vessel': 'nominal_vessel.yaml',
                                'terms': list(terms)}))
    return path


def test_the_diagnosis_of_a_fold_fits_its_training_runs_alone(tmp_path):
    from hybrid_models.studies.crossval import make_folds
    from vessel_diagnosis.recordings import load_recordings, split_holdout
    from vessel_diagnosis.workflow import diagnose_fold

    toy = read_dataset(write_toy_dataset(tmp_path / 'toy', n_runs=6, n_samples=260))
    fitted = {}

    def diagnose(argv):
        """Split the fold's view as the diagnosis does; note what it would fit and judge."""
        runs = load_recordings([argv[argv.index('--recordings') + 1]])
        diag, held, how = split_holdout(runs, 0.3, 0)
        fitted[len(fitted)] = ({r.run_id for r in diag}, {r.run_id for r in held}, how)
        return 0

    folds = make_folds(toy, tmp_path / 'folds', 3)
    for fold in folds:
        diagnose_fold(toy, fold, None, tmp_path / f'fold{fold.index}', diagnose)
        diag, held, how = fitted[fold.index]
        # The view holds every run; the fold's test runs are in it, marked unused.
        assert set(read_dataset(tmp_path / f'fold{fold.index}' / 'view').run_ids()) >= set(
            fold.test)
        assert diag == set(fold.train) and held == set(fold.val)
        assert not diag & set(fold.test) and how == 'the dataset test split'


def test_each_fold_is_diagnosed_without_its_test_runs_and_its_physics_retrained(
        tmp_path, monkeypatch):
    toy = write_toy_dataset(tmp_path / 'toy', n_runs=6, n_samples=260)
    nominal = physics_file(tmp_path / 'nominal.yaml', SIMULATOR_TERMS)
    seen = []

    def diagnose(argv):
        """Stand in for the diagnosis: note what it saw, write an augmented physics."""
        view = read_dataset(argv[argv.index('--recordings') + 1])
        out = Path(argv[argv.index('--out') + 1])
        out.mkdir(parents=True)
        seen.append((set(view.run_ids('train')), set(view.run_ids('test')),
                     argv[argv.index('--physics') + 1]))
        physics_file(out / 'augmented_physics.yaml', PRO_TERMS)
        (out / 'findings.json').write_text(json.dumps(
            {'augmented_physics': {'physics': 'augmented_physics.yaml'}}))
        print(f'found: a stand-in finding ({out / "report.md"})')   # as diagnose says
        return 0

    monkeypatch.setattr(cli_workflow.diagnose_cli, 'main', diagnose)
    out = tmp_path / 'wf'
    lstm = tmp_path / 'lstm.yaml'
    lstm.write_text((CONFIGS / 'smoke.yaml').read_text().replace('kind: hybrid', 'kind: lstm'))
    args = ['--dataset', str(toy), '--out', str(out), '--physics', str(nominal),
            '--hybrid', str(CONFIGS / 'smoke.yaml'), '--lstm', str(lstm), '--seeds', '1',
            '--horizon', '60', '--window', '20', '--stride', '60',
            '--threads', '1', '--jobs', '1']
    assert cli_workflow.main(args + sum((['--set', s] for s in SHORT), [])) == 0
    result = json.loads((out / 'results.json').read_text())
    folds = result['folds']
    for fold, (train, test, physics) in zip(folds, seen, strict=True):
        assert train == set(fold['train']) and test == set(fold['val'])
        assert not test & set(fold['test']) and physics == str(nominal)
    labels = [row['label'] for row in result['rows']]
    assert labels == [NOMINAL, AUGMENTED, LSTM, 'physics (nominal)',
                      'physics (augmented_physics)']
    for fold in folds:
        hybrid = out / 'runs' / AUGMENTED.replace(' ', '_') / f"fold{fold['index']}" / \
            'seed0' / 'config.yaml'
        assert 'augmented_physics.yaml' in hybrid.read_text()
        # It started from the hybrid on the nominal physics of its fold and seed.
        nominal_run = out / 'runs' / NOMINAL.replace(' ', '_') / f"fold{fold['index']}" / \
            'seed0' / 'model.safetensors'
        assert f'init_from: {nominal_run}' in hybrid.read_text()
    report = (out / 'report.md').read_text()
    assert 'a stand-in finding' in report and 'Do no harm' in report
    assert f'{out}/' not in report   # the folds' reports are named relative to it
    assert augmented_physics_file(out / 'folds' / 'fold0' / 'diagnosis').name == \
        'augmented_physics.yaml'
