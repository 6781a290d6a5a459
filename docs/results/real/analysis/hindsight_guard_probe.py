"""
Measure whether a correction faded by its own hindsight would do no harm on unseen kinds.

Usage:  tools/with_env.sh python docs/results/real/analysis/hindsight_guard_probe.py \
            STUDY LABEL [OUT]
STUDY is the --out folder of ``offline/crossval.py --fold-by ...``, LABEL one of its
hybrids; the table goes to stdout and, with OUT, to OUT/hindsight_guard_probe.md and
OUT/hindsight_guard_probe.json.

Issue #47 asked for a correction that fades towards the physics where it was not
trained. ``unseen_kind_probe.py`` found that neither the inputs' novelty nor the seeds'
disagreement marks the forecasts where the hybrid harms, and that the bound is inactive
there (the served threshold and a tenth of it give the same errors). What is left is the
vessel's own evidence: a forecast's errors are known one horizon after it was made.

This probe serves, along each held-out run, the correction scaled by a gain g of
``GAINS`` (the step adds g times the bounded residual; g = 0 is the physics alone,
g = 1 the hybrid as trained), chosen before each forecast by the validation rule of
``hybrid_models.selection`` applied to the forecasts of the same run whose horizon has
already passed (hindsight, with the controls then applied): the gains whose mean
position and state errors are no worse than the physics alone's at every reported step
are admissible, and the one of lowest state error is served. Before the first forecast
has matured the hybrid is served as trained (g = 1). Per seed, and for the seeds'
ensemble (mean of the members' corrections), pooled over the folds: the state and
position errors at the reported steps served as trained, guarded and by the physics
alone, each against the physics alone by ``selection.harms`` (as the study judges), and
the share of forecasts served at each gain.
"""

from __future__ import annotations

from contextlib import ExitStack, contextmanager
import json
from pathlib import Path
import sys

import numpy as np
from unseen_kind_probe import ensemble_forecast  # beside this script

from hybrid_models.checkpoint import load_model
from hybrid_models.data import forecast_windows, load_runs
from hybrid_models.evaluation import PhysicsOnly
from hybrid_models.metrics import StepErrors
from hybrid_models.models import predict
from hybrid_models.selection import forecast_figures, harms
from hybrid_models.studies.crossval import read_study, run_dir
from hybrid_models.training.train import MODEL_FILE
from vessel_datasets.format import read_dataset

GAINS = (0.0, 0.25, 0.5, 0.75, 1.0)   # of the correction; 0 is the physics alone
ENSEMBLE = 'ensemble'


@contextmanager
def gained(model, gain: float):
    """Serve ``model`` with its residual scaled by ``gain`` inside the ``with`` block."""
    own = model.residual_std.clone()
    model.residual_std.mul_(gain)
    try:
        yield model
    finally:
        model.residual_std.copy_(own)


def guard_choices(figures: list[dict], run_index: np.ndarray, t0: np.ndarray,
                  horizon: int) -> np.ndarray:
    """
    Return the gain index served for each forecast, from its run's matured forecasts.

    ``figures[g]['per_forecast']`` holds each forecast's state and position errors at the
    reported steps when served at ``GAINS[g]``; forecast i is of run ``run_index[i]``,
    its first step at sample ``t0[i]``, and matured for forecast j of the same run when
    t0[i] + horizon <= t0[j].
    """
    physics, served = GAINS.index(0.0), GAINS.index(1.0)
    choice = np.full(len(t0), served)
    for i in range(len(t0)):
        known = (run_index == run_index[i]) & (t0 + horizon <= t0[i])
        if not known.any():
            continue
        mean = [{k: f['per_forecast'][k][known].mean(axis=0) for k in ('state', 'position')}
                for f in figures]
        admissible = [g for g in range(len(GAINS)) if all(
            (mean[g][k] <= mean[physics][k]).all() for k in ('state', 'position'))]
        choice[i] = min(admissible, key=lambda g: (mean[g]['state'].sum(), -GAINS[g]))
    return choice


def probe(study: Path, label: str) -> dict:
    """Return, per seed and for the ensemble, the pooled figures served three ways."""
    folds, result = read_study(study)
    protocol = result['protocol']
    spec = read_dataset(folds[0].path).vessel
    horizon = protocol['horizon']
    seeds = [*protocol['seeds'], ENSEMBLE]
    served = {s: {'trained': [], 'guarded': [], 'physics': []} for s in seeds}
    shares = {s: np.zeros(len(GAINS)) for s in seeds}
    truth = []
    for fold in folds:
        test = load_runs(fold.path, 'test', spec)
        windows = forecast_windows(test, protocol['window'], horizon, protocol['stride'],
                                   protocol['target'])
        truth.append(windows.z_target)
        members = [load_model(run_dir(study, label, fold, seed) / MODEL_FILE)[0].eval()
                   for seed in protocol['seeds']]
        physics = predict(PhysicsOnly(members[-1].physical), windows)
        scale = windows.z_target.reshape(-1, spec.n_state).std(axis=0)
        for seed in seeds:
            chosen = members if seed == ENSEMBLE else [members[seeds.index(seed)]]
            preds = []
            for gain in GAINS:
                with ExitStack() as stack:
                    for m in chosen:
                        stack.enter_context(gained(m, gain))
                    preds.append(ensemble_forecast(chosen, windows)[0] if seed == ENSEMBLE
                                 else predict(chosen[0], windows))
            figures = [forecast_figures(p, windows.z_target, spec, scale, windows.run_index)
                       for p in preds]
            choice = guard_choices(figures, windows.run_index, windows.t0, horizon)
            stacked = np.stack(preds)
            served[seed]['trained'].append(preds[GAINS.index(1.0)])
            served[seed]['guarded'].append(stacked[choice, np.arange(len(windows))])
            served[seed]['physics'].append(physics)
            shares[seed] += np.bincount(choice, minlength=len(GAINS))
        print(f'fold {fold.index} done', file=sys.stderr, flush=True)
    true = np.concatenate(truth)
    scale = true.reshape(-1, spec.n_state).std(axis=0)
    out = {'gains': list(GAINS), 'horizon': horizon, 'seeds': {}}
    for seed in seeds:
        profiles = {way: StepErrors.of(np.concatenate(p), true, spec).profile(
            spec, state_std=scale) for way, p in served[seed].items()}
        out['seeds'][str(seed)] = {
            'profiles': profiles,
            'harms_vs_physics': {way: harms(profiles[way], profiles['physics'])
                                 for way in ('trained', 'guarded')},
            'gain_shares': (shares[seed] / shares[seed].sum()).tolist()}
    return out


def markdown(result: dict) -> str:
    """Return the probe's figures as Markdown: per seed, errors at the reported steps."""
    any_seed = next(iter(result['seeds'].values()))
    seconds = any_seed['profiles']['physics']['seconds']
    lines = ['| seed | served | ' + ' | '.join(f'state / position at {s:g} s' for s in seconds)
             + ' | worse than the physics alone at | forecasts per gain ' +
             '/'.join(f'{g:g}' for g in result['gains']) + ' |',
             '|---|---|' + '---|' * len(seconds) + '---|---|']
    for seed, r in result['seeds'].items():
        for way in ('trained', 'guarded', 'physics'):
            p = r['profiles'][way]
            cells = ' | '.join(_pair(s, x) for s, x in zip(p['normalized'], p['position_m'],
                                                           strict=True))
            worse = r['harms_vs_physics'].get(way)
            harm = '' if worse is None else ('nowhere' if not worse else '; '.join(worse))
            gains = '/'.join(f'{x:.0%}' for x in r['gain_shares']) if way == 'guarded' else ''
            lines.append(f'| {seed} | {way} | {cells} | {harm} | {gains} |')
    return '\n'.join(lines) + '\n'


def _pair(state: float | None, position: float | None) -> str:
    if state is None or position is None:
        return 'diverged'
    return f'{state:.3f} / {position:.2f} m'


def main(argv: list[str]) -> int:
    """Print (and with OUT write) the probe's table for one hybrid of a by-kind study."""
    if len(argv) not in (2, 3):
        print(__doc__, file=sys.stderr)
        return 2
    result = probe(Path(argv[0]), argv[1])
    table = markdown(result)
    print(table)
    if len(argv) == 3:
        out = Path(argv[2])
        out.mkdir(parents=True, exist_ok=True)
        (out / 'hindsight_guard_probe.md').write_text(table)
        (out / 'hindsight_guard_probe.json').write_text(json.dumps(result, indent=1) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
