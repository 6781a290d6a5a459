"""
The peer benchmark: other identification tools on exactly our splits, windows and measures.

A study of ours (``offline/crossval.py``: QLag, the LSTM, the hybrid and its physics on
the dataset's own split or on folds; or ``offline/reproduce_table3.py``'s, on the
dataset's own split) fixes the training, validation and test runs of
every fold and the test protocol (window, horizon, stride, noise-free targets). For each
fold this module writes one problem (``offline/peers/peer_io.py``: the fold's training
runs, its validation forecasts with measured targets, its test windows without targets),
runs each peer's adapter on it in the bench-only environment (``.venv-bench``; the
product never imports a peer), and scores the answers with ``forecast_metrics`` against
the truth the study's rows were scored on: pooled over folds, one row per peer (mean ±
sd over its seeds when it is stochastic), beside the study's own rows.
"""

from __future__ import annotations

from dataclasses import dataclass
import hashlib
import json
from pathlib import Path
import subprocess
import sys
import time

import numpy as np

from hybrid_models.checkpoint import CheckpointError, read_header
from hybrid_models.data import evaluation_protocol, forecast_windows, load_runs
from hybrid_models.evaluation import seed_row
from hybrid_models.metrics import forecast_metrics
from hybrid_models.studies import table3
from hybrid_models.studies.crossval import MODEL_FILE, Fold, read_study, run_dir
from vessel_datasets.format import read_dataset

PEER_DIR = Path('offline') / 'peers'
# The adapters: name -> (script under offline/peers, what it is).
PEERS = {
    'narx': ('narx.py', 'NARX (SysIdentPy)'),
    'sindy': ('sindy.py', 'SINDYc (PySINDy)'),
    'deepsysid-lstm': ('deepsysid_lstm.py', 'LSTM+init (deepsysid)'),
}


class PeerStudyError(Exception):
    """A failure of the peer study, said in one line."""


def _load_peer_io(root: Path):
    """Import offline/peers/peer_io.py (pure numpy) from the repository."""
    import importlib.util
    path = root / PEER_DIR / 'peer_io.py'
    spec = importlib.util.spec_from_file_location('peer_io', path)
    if spec is None or not path.exists():
        raise PeerStudyError(f'{path} is missing: run from the repository')
    if 'peer_io' in sys.modules:
        return sys.modules['peer_io']
    module = importlib.util.module_from_spec(spec)
    sys.modules['peer_io'] = module
    spec.loader.exec_module(module)
    return module


@dataclass
class FoldProblem:
    """A fold's problem file and the truth its answers are scored against."""

    index: int
    path: Path
    truth: np.ndarray
    sha256: str


def _digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def study_folds(study: Path, dataset: Path | None = None) -> tuple[list, dict]:
    """
    Return the folds of a finished study and its results.

    A crossval study names its folds; a Table 3 study (reproduce_table3's results.json)
    is one fold, the dataset it names (or ``dataset``) with its own split. Without a
    study (None), the dataset's own split under the vehicle's protocol, with no rows of
    ours (the peers alone).
    """
    if study is None:
        ds = read_dataset(dataset)
        split = ds.manifest['split']
        window, horizon, stride = evaluation_protocol(ds.vessel)
        return [Fold(0, ds.root, *(tuple(split[k]) for k in ('train', 'val', 'test')))], {
            'protocol': {'window': window, 'horizon': horizon, 'stride': stride,
                         'target': 'true', 'seeds': []}, 'rows': []}
    path = Path(study) / 'results.json'
    try:
        result = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise PeerStudyError(f'{study} holds no finished study: {exc}') from None
    if 'folds' in result:
        return read_study(study)[0], result
    if 'dataset' not in result or 'protocol' not in result:
        raise PeerStudyError(f'{path} is neither a crossval nor a Table 3 study')
    ds = read_dataset(dataset or result['dataset']['path'])
    split = ds.manifest['split']
    # Its protocol describes the target in words; its test windows took table3.TARGET.
    result = {**result, 'protocol': {**result['protocol'], 'target': table3.TARGET}}
    return [Fold(0, ds.root, *(tuple(split[k]) for k in ('train', 'val', 'test')))], result


def write_problems(study: Path, work: Path, seeds: list[int], root: Path,
                   dataset: Path | None = None) -> tuple[list, dict]:
    """Write every fold's problem under ``work``; return (FoldProblems, the study's results)."""
    peer_io = _load_peer_io(root)
    folds, result = study_folds(study, dataset)
    proto = result['protocol']
    window, horizon, stride = proto['window'], proto['horizon'], proto['stride']
    problems = []
    for fold in folds:
        spec = read_dataset(fold.path).vessel
        runs = {s: load_runs(fold.path, s, spec) for s in ('train', 'val', 'test')}
        test = forecast_windows(runs['test'], window, horizon, stride, proto['target'])
        try:
            val = forecast_windows(runs['val'], window, horizon, stride, 'measured')
        except ValueError:
            # Validation runs shorter than window + horizon: forecasts every sample.
            val = forecast_windows(runs['val'], window, horizon, 1, 'measured')
        path = work / f'fold{fold.index}' / 'problem.npz'
        path.parent.mkdir(parents=True, exist_ok=True)
        peer_io.write_problem(
            path, state_names=spec.state_names, control_names=spec.control_names,
            dt=spec.dt, window=window, horizon=horizon, seeds=seeds,
            train=[(r.z, r.c) for r in runs['train']], val=[(r.z, r.c) for r in runs['val']],
            val_windows={'z_window': val.z_window, 'c_window': val.c_window,
                         'c_future': val.c_future, 'z_target': val.z_target},
            test_windows={'z_window': test.z_window, 'c_window': test.c_window,
                          'c_future': test.c_future})
        problems.append(FoldProblem(fold.index, path, test.z_target, _digest(path)))
    return problems, result


def run_adapter(peer: str, problem: FoldProblem, work: Path, bench_python: Path, root: Path,
                quick: bool = False, say=print, options: tuple = ()) -> Path:
    """
    Run one peer on one fold (kept when its answer to the same problem exists); its answer.

    A failing adapter raises PeerStudyError with the adapter's own one-line error.
    """
    script, _ = PEERS[peer]
    answer = work / f'fold{problem.index}' / f'{peer}.npz'
    stamp = answer.with_suffix('.problem-sha256')
    # Kept only for the same problem, adapter code and options.
    key = ' '.join([problem.sha256, _digest(root / PEER_DIR / script)[:16],
                    _digest(root / PEER_DIR / 'peer_io.py')[:16],
                    *(['--quick'] if quick else []), *options])
    if answer.exists() and stamp.exists() and stamp.read_text().strip() == key:
        say(f'{peer} fold {problem.index}: kept')
        return answer
    cmd = [str(bench_python), str(root / PEER_DIR / script), '--problem', str(problem.path),
           '--out', str(answer)] + (['--quick'] if quick else []) + list(options)
    say(f'{peer} fold {problem.index}: running')
    t0 = time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    log = answer.with_suffix('.log')
    log.write_text(proc.stderr)
    if proc.returncode != 0:
        lines = [x for x in proc.stderr.strip().splitlines() if x.strip()]
        raise PeerStudyError(lines[-1] if lines else f'{script} exited {proc.returncode}')
    stamp.write_text(key + '\n')
    say(f'{peer} fold {problem.index}: done in {time.monotonic() - t0:.0f} s')
    return answer


def peer_row(peer: str, problems: list[FoldProblem], answers: list[Path], spec, scale,
             root: Path) -> dict:
    """Score one peer's answers, pooled over folds as the study pools its rows."""
    peer_io = _load_peer_io(root)
    read = [peer_io.read_answer(a) for a in answers]
    true = np.concatenate([p.truth for p in problems])
    n_seeds = min(len(a['seeds']) for a in read)
    metrics = []
    for s in range(n_seeds):
        pred = np.concatenate([a['pred'][s] for a in read])
        if pred.shape != true.shape:
            raise PeerStudyError(f'{peer}: forecasts {pred.shape}, truth {true.shape}')
        metrics.append(forecast_metrics(pred, true, spec, state_std=scale))
    label = f'peer: {PEERS[peer][1]}'
    row = seed_row(label, metrics) if n_seeds > 1 else {
        'label': label, 'seeds': 1, 'metrics': metrics[0], 'spread': None}
    row['per_seed_metrics'] = metrics
    # Each fold alone (a kind of manoeuvre held out, say), its diverged forecasts counted:
    # one forecast of thousands that diverges makes the pooled row "diverged".
    row['per_fold'] = [_fold_figures(p, a, spec) for p, a in zip(problems, read, strict=True)]
    row['peer'] = peer
    row['fit_seconds'] = [[float(x) for x in a['fit_seconds']] for a in read]
    row['forecast_seconds'] = [[float(x) for x in a['forecast_seconds']] for a in read]
    row['meta'] = [a['meta'] for a in read]
    return row


def _fold_figures(problem: FoldProblem, answer: dict, spec) -> dict:
    """One fold's trajectory error and error at the horizon per seed, diverged counted."""
    out = {'fold': problem.index, 'forecasts': len(problem.truth), 'trajectory': [],
           'final': [], 'diverged': []}
    for pred in answer['pred']:
        ok = np.isfinite(pred).all(axis=(1, 2))
        out['diverged'].append(int((~ok).sum()))
        m = forecast_metrics(pred[ok], problem.truth[ok], spec) if ok.any() else None
        out['trajectory'].append(None if m is None else m['trajectory']['mean'])
        out['final'].append(None if m is None else m['trajectory']['final_mean'])
    return out


def fold_table(summary: dict) -> str:
    """
    Each peer per fold: error at the horizon (m), mean ± sd over seeds, diverged.

    Empty for a single fold where no forecast diverged (the pooled table says it all).
    """
    peers_rows = [r for r in summary['rows'] if r.get('per_fold')]
    diverged = any(sum(f['diverged']) for r in peers_rows for f in r['per_fold'])
    if not peers_rows or (len(summary['folds']) < 2 and not diverged):
        return ''
    folds = summary['folds']
    lines = ['| peer | ' + ' | '.join(f'fold {i} ({n} forecasts): at the horizon [m]'
                                      for i, n in enumerate(
                                          f['forecasts'] for f in peers_rows[0]['per_fold']))
             + ' |', '|' + '---|' * (len(folds) + 1)]
    for r in peers_rows:
        cells = []
        for f in r['per_fold']:
            vals = [v for v in f['final'] if v is not None]
            cell = _pm(float(np.mean(vals)) if vals else None,
                       float(np.std(vals, ddof=1)) if len(vals) > 1 else None, 2)
            if sum(f['diverged']):
                cell += f" ({sum(f['diverged'])} diverged)"
            cells.append(cell)
        lines.append(f"| {r['label']} | " + ' | '.join(cells) + ' |')
    return '\n'.join(lines) + '\n'


def _fit_seconds(study: Path, result: dict, label: str, folds: list) -> list | None:
    """Our model's training time per fold and seed from its checkpoints (None: unknown)."""
    if 'folds' not in result:   # a Table 3 study: its rows say
        row = next(r for r in result['rows'] if r['label'] == label)
        seconds = row.get('train_seconds') or []
        return [[float(x) for x in seconds]] if seconds and None not in seconds else None
    out = []
    for fold in folds:
        per = []
        for s in result['protocol']['seeds']:
            try:
                header = read_header(run_dir(study, label, fold, s) / MODEL_FILE)
            except (CheckpointError, FileNotFoundError):
                return None
            seconds = header.get('train_seconds')
            if seconds is None:
                # QLag's checkpoint has no training time: its training process's wall time
                # (start-up included), from the run directory's first and last files.
                d = run_dir(study, label, fold, s)
                seconds = (d / MODEL_FILE).stat().st_mtime - (d / 'config.yaml').stat().st_mtime
            per.append(float(seconds))
        out.append(per)
    return out


def study(study_dir: Path | None, out: Path, peers: list[str], seeds: list[int],
          work: Path | None,
          bench_python: Path, root: Path, quick: bool = False, title: str | None = None,
          say=lambda m: print(m, file=sys.stderr), options: dict | None = None,
          dataset: Path | None = None) -> dict:
    """Run every peer on every fold of ``study_dir``; write results.json and table.md."""
    unknown = [p for p in peers if p not in PEERS]
    if unknown:
        raise PeerStudyError(f'unknown peer {unknown[0]!r} (known: {", ".join(PEERS)})')
    if not bench_python.exists():
        raise PeerStudyError(f'{bench_python} is missing: make the bench environment first '
                             '(tools/setup.sh bench)')
    work = work or out / 'work'
    problems, result = write_problems(study_dir, work, seeds, root, dataset)
    folds, _ = study_folds(study_dir, dataset)
    spec = read_dataset(folds[0].path).vessel
    true = np.concatenate([p.truth for p in problems])
    scale = true.reshape(-1, true.shape[-1]).std(axis=0)
    rows = []
    for peer in peers:
        extra = tuple((options or {}).get(peer, ()))
        answers = [run_adapter(peer, p, work, bench_python, root, quick, say, extra)
                   for p in problems]
        rows.append(peer_row(peer, problems, answers, spec, scale, root))
    ours = []
    for row in result['rows']:
        mine = dict(row)
        if 'per_seed_metrics' in row or row.get('kind') == 'model':
            mine['fit_seconds'] = _fit_seconds(study_dir, result, row['label'], folds)
        ours.append(mine)
    out.mkdir(parents=True, exist_ok=True)
    summary = {'title': title or read_dataset(folds[0].path).vessel.name,
               'study': None if study_dir is None else str(study_dir),
               'protocol': result['protocol'],
               'folds': result.get('folds') or [f.describe() for f in folds],
               'problems': [{'fold': p.index, 'sha256': p.sha256} for p in problems],
               'state_names': list(spec.state_names), 'rows': rows + ours,
               'peers': peers, 'quick': quick, 'options': options or {}}
    (out / 'results.json').write_text(json.dumps(summary, indent=1))
    folds_table = fold_table(summary)
    (out / 'table.md').write_text(table(summary) + ('\n' + folds_table if folds_table else ''))
    return summary


def _pm(mean, sd, digits: int) -> str:
    if mean is None:
        return 'diverged'
    return f'{mean:.{digits}f}' + ('' if sd is None else f' ± {sd:.{digits}f}')


def _metres(values) -> int:
    """Decimals of distances: two below 10 m, one below 100 m, none above."""
    finite = [v for v in values if v is not None and np.isfinite(v)]
    top = max(finite) if finite else 0.0
    return 2 if top < 10 else 1 if top < 100 else 0


def _digits(values) -> int:
    finite = [abs(v) for v in values if v is not None and np.isfinite(v) and v != 0]
    if not finite:
        return 3
    return max(2, min(6, 2 - int(np.floor(np.log10(min(finite))))))


def _seconds(row: dict) -> str:
    fits = row.get('fit_seconds')
    if not fits:
        return '—'
    per_seed = np.asarray(fits, np.float64).sum(axis=0)   # all folds of one seed
    digits = 1 if per_seed.mean() < 10 else 0
    if len(per_seed) == 1:
        return f'{per_seed[0]:.{digits}f}'
    return f'{per_seed.mean():.{digits}f} ± {per_seed.std(ddof=1):.{digits}f}'


def table(summary: dict) -> str:
    """Return one dataset's table: per-state RMSE, trajectory, profile, fit time."""
    states = summary['state_names']
    rows = summary['rows']
    digits = {s: _digits([r['metrics']['rmse'].get(s) for r in rows]) for s in states}
    head = ('| model | ' + ' | '.join(f'{s} RMSE' for s in states)
            + ' | trajectory error [m] | error at the horizon [m] | seeds | fit time [s] |')
    lines = [head, '|' + '---|' * (len(states) + 5)]
    metres = _metres([r['metrics']['trajectory']['final_mean'] for r in rows])
    for r in rows:
        m, sd = r['metrics'], r.get('spread') or {}
        sd_rmse = sd.get('rmse') or {}
        sd_traj = sd.get('trajectory') or {}
        cells = [_pm(m['rmse'].get(s), sd_rmse.get(s), digits[s]) for s in states]
        traj = _pm(m['trajectory']['mean'], sd_traj.get('mean'), metres)
        final = _pm(m['trajectory']['final_mean'], sd_traj.get('final_mean'), metres)
        if m.get('diverged') and m['trajectory']['mean'] is None:
            traj = final = 'diverged'
        label = r['label'] if r.get('peer') else f"ours: {r['label']}"
        lines.append(f'| {label} | ' + ' | '.join(cells)
                     + f" | {traj} | {final} | {r.get('seeds', 1)} | {_seconds(r)} |")
    lines += ['', profile_table(summary)]
    return '\n'.join(lines) + '\n'


def profile_table(summary: dict) -> str:
    """Mean position error at the reported horizon steps, every row."""
    rows = summary['rows']
    prof0 = rows[0]['metrics']['profile']
    lines = ['| model | ' + ' | '.join(f'position error at {t:g} s [m]'
                                       for t in prof0['seconds'])
             + ' |', '|' + '---|' * (len(prof0['steps']) + 1)]
    metres = _metres([v for r in rows for v in r['metrics']['profile']['position_m']])
    for r in rows:
        prof = r['metrics']['profile']
        sd = ((r.get('spread') or {}).get('profile') or {}).get('position_m') or [
            None] * len(prof['steps'])
        cells = [_pm(v, s, metres) for v, s in zip(prof['position_m'], sd, strict=True)]
        label = r['label'] if r.get('peer') else f"ours: {r['label']}"
        lines.append(f'| {label} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)
