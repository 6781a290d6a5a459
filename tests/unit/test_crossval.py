"""Seeds and folds of whole recordings: every recording held out once, rows over seeds."""

import json
from pathlib import Path
import shutil

import pytest

from hybrid_models.checkpoint import load_model
from hybrid_models.cli import crossval
from hybrid_models.studies.crossval import Fold, ModelPlan, make_folds
from offline.benchmarks.toy import write_toy_dataset
from vessel_datasets.format import DatasetError, read_dataset, resplit

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'
SHORT = ['training.progress=false', 'training.phases=[{kind: teacher, max_epochs: 1, '
         'patience: 1, lr: 0.005}, {kind: multistep, max_epochs: 1, patience: 1, lr: 0.003}]']


@pytest.fixture(scope='module')
def toy(tmp_path_factory):
    return write_toy_dataset(tmp_path_factory.mktemp('toy'), n_runs=6, n_samples=260)


def test_a_view_resplits_without_copying_and_refuses_unknown_runs(toy, tmp_path):
    ds = read_dataset(toy)
    ids = ds.run_ids()
    view = resplit(ds, tmp_path / 'view', {'train': ids[:4], 'test': ids[4:5]}, 'a test')
    assert view.run_ids('test') == ids[4:5] and view.run_ids('val') == []
    assert (tmp_path / 'view' / 'runs' / f'{ids[0]}.parquet').is_symlink()
    assert view.load(ids[0]).equals(ds.load(ids[0]))
    assert [r['split'] for r in view.manifest['runs']].count('unused') == 1
    with pytest.raises(DatasetError, match='no runs'):
        resplit(ds, tmp_path / 'bad', {'train': ['nope']})


def test_folds_hold_every_recording_out_once_and_keep_recordings_whole(toy, tmp_path):
    toy = Path(shutil.copytree(toy, tmp_path / 'toy'))
    manifest = json.loads((toy / 'manifest.json').read_text())
    # Two runs cut from one recording: they must share a fold.
    manifest['runs'][0]['source'] = manifest['runs'][1]['source'] = {'bag': 'same.mcap'}
    (toy / 'manifest.json').write_text(json.dumps(manifest))
    ds = read_dataset(toy)
    assert len(ds.recordings()) == 5
    folds = make_folds(ds, tmp_path, 3, seed=1)
    tested = [r for f in folds for r in f.test]
    assert sorted(tested) == sorted(ds.run_ids())
    first, second = manifest['runs'][0]['id'], manifest['runs'][1]['id']
    for f in folds:
        assert not set(f.test) & (set(f.train) | set(f.val)) and f.val
        assert (first in f.test) == (second in f.test)
        assert (first in f.train) == (second in f.train)
    with pytest.raises(ValueError, match='folds must be between 2 and the 5'):
        make_folds(ds, tmp_path, 6)


def test_crossval_trains_every_seed_and_fold_and_pools_their_forecasts(toy, tmp_path):
    out = tmp_path / 'cv'
    args = ['--dataset', str(toy), '--out', str(out), '--seeds', '2', '--folds', '2',
            '--model', f'hybrid={SMOKE}', '--horizon', '100', '--window', '20',
            '--stride', '60', '--threads', '1', '--jobs', '1']
    assert crossval.main(args + sum((['--set', s] for s in SHORT), [])) == 0
    result = json.loads((out / 'results.json').read_text())
    assert result['protocol']['folds'] == 2 and result['protocol']['seeds'] == [0, 1]
    hybrid, ensemble, physics = result['rows']
    assert hybrid['seeds'] == 2 and len(hybrid['per_seed']) == 2
    assert hybrid['physics'] == [physics['label']] == ['lin physics']
    assert len(hybrid['harms_vs_physics']) == 2
    # Each fold's seeds are also served as one ensemble, checked against the same physics.
    assert ensemble['label'] == 'hybrid, ensemble of 2 seeds'
    assert ensemble['physics'] == hybrid['physics'] and len(ensemble['harms_vs_physics']) == 1
    assert ensemble['metrics']['n_forecasts'] == physics['metrics']['n_forecasts']
    for fold in (0, 1):
        model, config = load_model(out / 'runs' / 'hybrid' / f'fold{fold}' / 'ensemble' /
                                   'model.safetensors')
        assert len(model.members) == 2 and config['selection'] is not None
    tested = [r for f in result['folds'] for r in f['test']]
    assert sorted(tested) == sorted(read_dataset(toy).run_ids())
    assert result['protocol']['n_forecasts'] == physics['metrics']['n_forecasts']
    for name in ('report.md', 'table.md', 'position_error_over_horizon.png'):
        assert (out / name).stat().st_size > 0
    assert 'Do no harm' in (out / 'report.md').read_text()
    # A second call keeps the finished trainings instead of training again.
    assert crossval.main(args + sum((['--set', s] for s in SHORT), [])) == 0
    trained = json.loads((out / 'results.json').read_text())['trainings']
    assert {t['status'] for t in trained} == {'kept'}
    # A call with more seeds trains only the new ones and packs the ensembles again
    # (a finished ensemble of the former seeds is not kept under the new label).
    more = args.copy()
    more[more.index('--seeds') + 1] = '3'
    assert crossval.main(more + sum((['--set', s] for s in SHORT), [])) == 0
    result = json.loads((out / 'results.json').read_text())
    assert sorted((t['label'], t['status']) for t in result['trainings']) == sorted(
        [(f'hybrid/fold{f}/seed{s}', 'kept') for f in (0, 1) for s in (0, 1)]
        + [(f'hybrid/fold{f}/seed2', 'ok') for f in (0, 1)])
    assert result['rows'][1]['label'] == 'hybrid, ensemble of 3 seeds'
    for fold in (0, 1):
        model, config = load_model(out / 'runs' / 'hybrid' / f'fold{fold}' / 'ensemble' /
                                   'model.safetensors')
        assert len(model.members) == 3 and config['ensemble']['seeds'] == [0, 1, 2]


def physics_file(tmp_path, name, terms):
    path = tmp_path / f'{name}.yaml'
    path.write_text(json.dumps({'format': 'vessel-physics/1', 'vessel': 'nominal_vessel.yaml',
                                'terms': terms}))
    return path


def test_evaluate_gives_each_distinct_physics_its_row_and_seeds_one_row(toy, tmp_path):
    from hybrid_models.cli import evaluate
    from hybrid_models.training import load_config, train
    from vessel_physics.patrol import PRO_TERMS, SIMULATOR_TERMS
    files = {'nominal': physics_file(tmp_path, 'nominal', list(SIMULATOR_TERMS)),
             'reduced': physics_file(tmp_path, 'reduced', list(PRO_TERMS))}
    runs = []
    for label, path, seed in (('a', files['nominal'], 0), ('b', files['reduced'], 0),
                              ('b', files['reduced'], 1)):
        out = tmp_path / f'{label}{seed}'
        train(load_config(SMOKE, [f'dataset={toy}', 'model.physical.kind=physics',
                                  f'model.physical.physics={path}', 'model.physical.substeps=1',
                                  f'training.seed={seed}', *SHORT]), out)
        runs.append((label, out))
    results = tmp_path / 'results'
    assert evaluate.main([str(out) for _, out in runs] + [
        '--labels', *[label for label, _ in runs], '--dataset', str(toy), '--out',
        str(results), '--horizon', '60', '--window', '20', '--stride', '60',
        '--physics-only', '--threads', '1']) == 0
    rows = json.loads((results / 'results.json').read_text())['rows']
    labels = [row['label'] for row in rows]
    assert labels == ['a', 'physics (nominal)', 'b', 'physics (reduced)']
    assert rows[2]['seeds'] == 2 and len(rows[2]['per_seed']) == 2
    assert rows[0]['physics'] == ['physics (nominal)'] and len(rows[2]['harms_vs_physics']) == 2
    assert rows[1]['metrics']['rmse'] != rows[3]['metrics']['rmse']
    table = (results / 'table.md').read_text()
    assert '| b |' in table and ' ± ' in table.split('| b |')[1].splitlines()[0]


def test_folds_by_kind_hold_out_each_kind_and_always_train_on_the_unmatched(toy, tmp_path):
    toy = Path(shutil.copytree(toy, tmp_path / 'toy'))
    manifest = json.loads((toy / 'manifest.json').read_text())
    kinds = ['ZIGZAG_1', 'ZIGZAG_2', 'TURN_1', 'TURN_2', 'FREE_1', 'FREE_2']
    for entry, kind in zip(manifest['runs'], kinds, strict=True):
        entry['source'] = {'source_run': kind}
    (toy / 'manifest.json').write_text(json.dumps(manifest))
    ds = read_dataset(toy)
    ids = {kind: entry['id'] for entry, kind in zip(manifest['runs'], kinds, strict=True)}
    folds = make_folds(ds, tmp_path, None, fold_by='ZIGZAG|TURN')
    assert [set(f.test) for f in folds] == [{ids['TURN_1'], ids['TURN_2']},
                                            {ids['ZIGZAG_1'], ids['ZIGZAG_2']}]
    for f in folds:
        assert {ids['FREE_1'], ids['FREE_2']} <= set(f.train) | set(f.val)
    with pytest.raises(ValueError, match='needs at least 2'):
        make_folds(ds, tmp_path, None, fold_by='FREE')


def test_two_physics_of_one_name_are_told_apart_by_their_model():
    from hybrid_models.physical.identity import physics_label

    taken = set()
    for owner in ('hybrid', 'hybrid, no mirror images'):
        taken.add(physics_label('hyd physics', 'f' * 16, owner, taken))
    assert taken == {'hyd physics', 'hyd physics (of hybrid, no mirror images)'}
    # The same model's seeds fitted on other data: the fingerprint decides.
    assert physics_label('hyd physics', '1774de' + '0' * 10, 'hybrid, no mirror images',
                         taken) == 'hyd physics (of hybrid, no mirror images) [1774de]'


def test_folds_validate_on_runs_long_enough_for_a_forecast(toy, tmp_path):
    import copy

    from hybrid_models.studies.crossval import make_folds
    from vessel_datasets.format import Dataset, read_dataset

    ds = read_dataset(toy)
    manifest = copy.deepcopy(ds.manifest)
    for entry in manifest['runs'][::2]:   # every other run too short to validate on
        entry['n_samples'] = 100
    ds = Dataset(ds.root, manifest)
    lengths = {r['id']: r['n_samples'] for r in manifest['runs']}
    for seed in range(4):
        for fold in make_folds(ds, tmp_path / str(seed), 3, seed=seed, min_val_samples=200):
            assert max(lengths[run] for run in fold.val) >= 200, (seed, fold.val)
    with pytest.raises(ValueError, match='to validate on'):
        make_folds(ds, tmp_path / 'x', 2, min_val_samples=261)


def test_folds_balanced_by_samples_deal_long_recordings_apart(toy, tmp_path):
    import copy

    from vessel_datasets.format import Dataset, read_dataset

    ds = read_dataset(toy)
    manifest = copy.deepcopy(ds.manifest)
    # Two long recordings among four short ones: dealt by count, a seed can put both
    # long ones into one fold; dealt by samples (the default), never.
    lengths = [2000, 1900, 300, 280, 260, 250]
    for entry, n in zip(manifest['runs'], lengths, strict=True):
        entry['n_samples'] = n
    ds = Dataset(ds.root, manifest)
    long_ones = {e['id'] for e in manifest['runs'][:2]}

    def totals(folds):
        size = {e['id']: e['n_samples'] for e in manifest['runs']}
        return sorted(sum(size[r] for r in f.test) for f in folds)

    by_count = [make_folds(ds, tmp_path / f'c{seed}', 3, seed=seed, balance='recordings')
                for seed in range(8)]
    assert any(long_ones <= set(f.test) for folds in by_count for f in folds)
    for seed in range(8):
        folds = make_folds(ds, tmp_path / f's{seed}', 3, seed=seed)   # the default
        assert sorted(r for f in folds for r in f.test) == sorted(ds.run_ids())
        assert not any(long_ones <= set(f.test) for f in folds)
        # Greedy longest-first: {2000}, {1900}, {300, 280, 260, 250} -> 2000/1900/1090.
        assert totals(folds) == [1090, 1900, 2000], seed
    with pytest.raises(ValueError, match='balance must be'):
        make_folds(ds, tmp_path / 'bad', 3, balance='runs')


def test_a_model_that_starts_from_another_trains_after_it_from_its_checkpoint(
        tmp_path, monkeypatch):
    from hybrid_models.studies import crossval as studies

    folds = [Fold(k, tmp_path / f'fold{k}', (), (), ()) for k in range(2)]
    started, finished = [], []

    def train_job(label, config, overrides, out):
        started.append((label, list(overrides), len(finished)))
        finished.append(label)
        return {'label': label, 'status': 'trained', 'dir': str(out)}

    monkeypatch.setattr(studies, 'train_job', train_job)
    models = [ModelPlan('warm', tmp_path / 'c.yaml', start_from='base'),
              ModelPlan('base', tmp_path / 'c.yaml')]
    studies.train_plan(models, folds, [0, 1], tmp_path / 'out', jobs=2, say=lambda m: None)
    order = [label.split('/')[0] for label, _, _ in started]
    assert order.count('base') == order.count('warm') == 4
    # Every base training had finished before the first warm one started.
    first_warm = order.index('warm')
    assert set(order[:first_warm]) == {'base'} and started[first_warm][2] == 4
    for label, overrides, _ in started:
        name, fold, seed = label.split('/')
        start = [o for o in overrides if o.startswith('training.init_from=')]
        if name == 'warm':
            assert start == [f'training.init_from={tmp_path}/out/runs/base/{fold}/{seed}/'
                             f'model.safetensors']
        else:
            assert start == []
    with pytest.raises(ValueError, match="start_from 'nowhere' is not a model of the plan"):
        studies.train_plan([ModelPlan('x', tmp_path / 'c.yaml', start_from='nowhere')],
                           folds, [0], tmp_path / 'out', say=lambda m: None)


def test_a_fold_that_could_spare_a_second_validation_run_is_warned_of(tmp_path, capsys):
    toy = write_toy_dataset(tmp_path / 'toy10', n_runs=10, n_samples=260)
    base = ['--dataset', str(toy), '--out', str(tmp_path / 'cv'), '--folds', '2',
            '--model', f'hybrid={SMOKE}', '--horizon', '100', '--window', '20']
    folds = crossval.folds_of(read_dataset(toy), crossval.build_parser().parse_args(base))
    assert [len(f.val) for f in folds] == [1, 1]
    warning = capsys.readouterr().err
    assert 'fold(s) 0, 1 validate on one recording' in warning
    suggested = warning.split('--val-fraction ')[1].split()[0]
    folds = crossval.folds_of(read_dataset(toy), crossval.build_parser().parse_args(
        base + ['--val-fraction', suggested]))
    assert [len(f.val) for f in folds] == [2, 2]
    assert 'validate on one recording' not in capsys.readouterr().err
