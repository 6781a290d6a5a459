r"""
Where cross-validated bands miss: per held-out run, the error at one step against the band.

Usage:  tools/with_env.sh python docs/results/real/analysis/band_misses.py \
            CHECKPOINT STUDY LABEL SEED [SECONDS]

CHECKPOINT holds bands given by ``offline/set_bands.py CHECKPOINT --study STUDY --model
LABEL --seed SEED`` (docs/results/real/bands.md). Every fold's LABEL model of SEED
forecasts its held-out runs again as set_bands did (the checkpoint's threshold, window,
vessel horizon and stride); for each run with forecasts this prints, at SECONDS ahead
(default: the first reported step), the forecasts, per state the mean and the standard
deviation of measured - forecast and the fraction inside the widest band: a run whose
errors are offset beyond the band though their spread fits in it is one the bands
cannot learn from the other recordings.
"""

from __future__ import annotations

import sys

from hybrid_models.bands import coverage
from hybrid_models.cli.set_bands import protocol
from hybrid_models.data import forecast_windows, load_runs
from hybrid_models.engine import Forecaster
from hybrid_models.metrics import reported_steps
from hybrid_models.studies.crossval import out_of_fold_forecasts, read_study


def main(argv: list[str]) -> int:
    """Print the Markdown table of band misses per held-out run; return the exit code."""
    if len(argv) not in (4, 5):
        print(__doc__, file=sys.stderr)
        return 2
    checkpoint, study, label, seed = argv[0], argv[1], argv[2], int(argv[3])
    engine = Forecaster.from_checkpoint(checkpoint)
    if engine.bands is None:
        print(f'band_misses: error: {engine.bands_note}', file=sys.stderr)
        return 2
    spec, bands = engine.spec, engine.bands
    horizon, stride = protocol(engine, None, None)
    step = (round(float(argv[4]) / spec.dt) if len(argv) == 5
            else reported_steps(horizon)[0])
    held = out_of_fold_forecasts(study, label, spec, engine.relative_threshold,
                                 engine.window, horizon, stride, [seed])
    level = len(bands.levels) - 1
    names = spec.state_names
    print(f'{bands.levels[level]:g} band after {step * spec.dt:g} s; per state: mean and '
          f'sd of measured - forecast, fraction inside the band', '', sep='\n')
    print('| fold | run | forecasts | ' + ' | '.join(names) + ' |')
    print('|' + '---|' * (3 + len(names)))
    for fold, out in zip(read_study(study)[0], held, strict=True):
        runs = load_runs(fold.path, 'test', spec)
        windows = forecast_windows(runs, engine.window, horizon, stride)
        error = (out.true - out.pred)[:, step - 1]
        for i, run in enumerate(runs):
            mine = windows.run_index == i
            if not mine.any():
                continue
            inside = coverage(bands, out.pred[mine], out.true[mine], spec, [step])['states']
            cells = [f'{error[mine, j].mean():+.3f} ± {error[mine, j].std():.3f} '
                     f'({inside[name][level][0]:.2f})' for j, name in enumerate(names)]
            print(f'| {fold.index} | {run.run_id} | {int(mine.sum())} | '
                  + ' | '.join(cells) + ' |')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
