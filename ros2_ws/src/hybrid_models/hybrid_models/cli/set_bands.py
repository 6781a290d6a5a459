r"""
Give a hybrid checkpoint calibrated forecast bands: from validation runs, or cross-validated.

    set_bands MODEL.safetensors --dataset DATA            # in place
    set_bands MODEL.safetensors --dataset DATA --out B.safetensors
    set_bands MODEL.safetensors --study STUDY --model LABEL [--seed S]

Training writes bands into every hybrid checkpoint it makes (``hybrid_models.bands``);
this program gives them to a checkpoint made before, or again after ``set_threshold``
(bands hold only at the threshold they were computed for). Either way the forecasts are
made at the checkpoint's served threshold, one every STRIDE samples over the vessel's
horizon, against the measured states, and the bands are written into the checkpoint's
config; the weights are kept bit for bit. A dataset or study of another vessel or rate
is refused.

--dataset: the checkpoint itself forecasts the dataset's validation runs (with the
compiled engine); a dataset whose validation runs the model was trained on is refused.
The bands are only as good as those few runs stand for the vessel's other manoeuvres.

--study: for a vessel recorded in few runs (a handful of validation runs do not stand
for the others). STUDY is a finished cross-validated study (``crossval --folds K``)
with a hybrid LABEL trained on every fold; each fold's LABEL models (every seed, or
--seed) forecast that fold's held-out runs, all served at the checkpoint's threshold,
and these out-of-fold forecasts of every recording, pooled, calibrate the bands. They
hold for a model of LABEL's recipe, e.g. MODEL trained on all runs, served at that
threshold. By default each band edge is taken at the quantile level whose
leave-one-fold-out coverage reaches the nominal level (--calibration fold-robust, see
hybrid_models.cross_bands: recordings are not alike, and pooled quantiles fall short on
the folds a model mispredicts). Also prints their honest coverage: calibrated
leave-one-fold-out (on the other folds' forecasts, level choice included, measured on
this fold's, pooled), per level, state and reported step. What it promises is that
coverage, not the nominal level.
"""

import argparse
from pathlib import Path
import sys

from hybrid_models.bands import LEVELS, Bands, BandsError, calibrate, coverage_table
from hybrid_models.checkpoint_format import (
    CheckpointError,
    read_header,
    rewrite_config,
    vessel_of,
)
from hybrid_models.cli.arguments import progress
from hybrid_models.cross_bands import (
    CALIBRATIONS,
    cross_calibrate,
    held_out_coverage,
    least_covered,
)
from hybrid_models.data import dataset_hash, evaluation_protocol, forecast_windows, load_runs
from hybrid_models.engine import Forecaster
from hybrid_models.studies.crossval import out_of_fold_forecasts
from vessel_datasets.format import DatasetError, read_dataset

STRIDE_PER_HORIZON = 30   # default stride: horizon / 30, as training's bands


def parse_args(argv=None):
    """Parse the command line."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('checkpoint', type=Path, help='hybrid checkpoint (.safetensors)')
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument('--dataset', type=Path,
                        help='dataset whose validation runs calibrate the bands')
    source.add_argument('--study', type=Path,
                        help='cross-validated study whose out-of-fold forecasts calibrate '
                             'the bands (a vessel recorded in few runs)')
    parser.add_argument('--model', metavar='LABEL',
                        help="with --study: the study's hybrid whose fold models forecast")
    parser.add_argument('--seed', type=int,
                        help="with --study: only this seed's models (default: every seed)")
    parser.add_argument('--horizon', type=int,
                        help="forecast steps calibrated (default: the vessel's horizon)")
    parser.add_argument('--stride', type=int,
                        help='samples between forecasts in a run (default: horizon / 30)')
    parser.add_argument('--levels', type=float, nargs='+', default=list(LEVELS),
                        help='band levels in (0, 1) (default 0.5 0.9)')
    parser.add_argument('--calibration', choices=CALIBRATIONS, default='fold-robust',
                        help='--study: quantile levels chosen leave-one-fold-out '
                             '(fold-robust, default) or the nominal levels on the pooled '
                             'forecasts (pooled)')
    parser.add_argument('--out', type=Path, help='write here instead of in place')
    args = parser.parse_args(argv)
    if args.study is not None and args.model is None:
        parser.error('--study needs --model LABEL')
    if args.study is None and (args.model is not None or args.seed is not None):
        parser.error('--model and --seed go with --study')
    return args


def validation_runs(config: dict, dataset, checkpoint: Path) -> list:
    """Return the dataset's validation runs; refuse runs the model was trained on."""
    trained = set(config.get('dataset', {}).get('train_runs', []))
    runs = dataset.manifest['split']['val']
    seen = sorted(trained.intersection(runs))
    if seen:
        raise ValueError(f'{checkpoint} was trained on validation runs {seen[:5]} of '
                         f'{dataset.root}: their forecasts would give too narrow bands')
    return runs


def protocol(engine: Forecaster, horizon: int | None, stride: int | None) -> tuple[int, int]:
    """Return the horizon and stride of calibration forecasts (None: the defaults)."""
    _, horizon, _ = evaluation_protocol(engine.spec, engine.window, horizon)
    return horizon, stride or max(1, horizon // STRIDE_PER_HORIZON)


def set_bands(checkpoint: Path, dataset_dir: Path, horizon: int | None, stride: int | None,
              levels, out: Path | None) -> Bands:
    """Compute and write the bands; return them."""
    config = read_header(checkpoint)
    dataset = read_dataset(dataset_dir)
    dataset.vessel.check_compatible(vessel_of(config, checkpoint), f'checkpoint {checkpoint}')
    run_ids = validation_runs(config, dataset, checkpoint)
    engine = Forecaster.from_checkpoint(checkpoint)
    horizon, stride = protocol(engine, horizon, stride)
    runs = load_runs(dataset, 'val', engine.spec)
    windows = forecast_windows(runs, engine.window, horizon, stride)
    pred = engine.forecast_each(windows.z_window, windows.c_window, windows.c_future,
                                progress=progress('validation forecasts')).hybrid
    bands = calibrate(pred, windows.z_target, engine.spec, engine.relative_threshold, levels,
                      source={'split': 'val', 'runs': len(run_ids), 'stride': stride,
                              'target': 'measured', 'dataset': str(dataset_dir),
                              'dataset_sha256': dataset_hash(dataset)})
    rewrite_config(checkpoint, {**config, 'bands': bands.to_dict()}, out)
    return bands


def set_study_bands(checkpoint: Path, study: Path, label: str, seed: int | None,
                    horizon: int | None, stride: int | None, levels,
                    out: Path | None, calibration: str = 'fold-robust'
                    ) -> tuple[Bands, list[str]]:
    """Compute and write cross-validated bands; return them and their coverage table."""
    config = read_header(checkpoint)
    engine = Forecaster.from_checkpoint(checkpoint)
    horizon, stride = protocol(engine, horizon, stride)
    threshold = engine.relative_threshold
    held_out = out_of_fold_forecasts(study, label, engine.spec, threshold, engine.window,
                                     horizon, stride, None if seed is None else [seed],
                                     lambda m: print(f'set_bands: {m}', file=sys.stderr))
    bands = cross_calibrate(held_out, engine.spec, threshold, levels, source={
        'stride': stride, 'target': 'measured', 'study': str(study), 'model': label,
        'seeds': 'all' if seed is None else [seed]}, calibration=calibration)
    cover = held_out_coverage(held_out, engine.spec, threshold, levels, calibration)
    rewrite_config(checkpoint, {**config, 'bands': bands.to_dict()}, out)
    table = [f'Bands {bands.origin}: width (upper - lower; position: radius) and, in '
             f'brackets, the fraction of forecasts they held leave-one-fold-out '
             f"({cover['forecasts']} forecasts):", '',
             *coverage_table(bands, cover, engine.spec), '']
    for fold in cover['per_fold']:
        least = [f'{level:g} band {name} after {step * engine.spec.dt:g} s: {fraction:.2f}'
                 for level in bands.levels
                 for fraction, name, step in [least_covered(fold, level)]]
        table.append(f"Fold {fold['fold']} held out ({fold['forecasts']} forecasts), least "
                     f"covered: {'; '.join(least)}")
    return bands, table


def main(argv=None) -> int:
    """Parse arguments, compute the bands and write them; return the exit code."""
    args = parse_args(argv)
    try:
        if args.study is None:
            bands = set_bands(args.checkpoint, args.dataset, args.horizon, args.stride,
                              args.levels, args.out)
        else:
            bands, table = set_study_bands(args.checkpoint, args.study, args.model, args.seed,
                                           args.horizon, args.stride, args.levels, args.out,
                                           args.calibration)
            print('\n'.join(table))
    except (BandsError, CheckpointError, DatasetError, FileNotFoundError, ValueError) as exc:
        print(f'set_bands: error: {exc}', file=sys.stderr)
        return 2
    widest, last = len(bands.levels) - 1, len(bands.steps) - 1
    widths = {name: round(float(bands.upper[widest, last, i] - bands.lower[widest, last, i]), 6)
              for i, name in enumerate(bands.state_names)}
    print(f'set_bands: {args.out or args.checkpoint}: bands at levels {list(bands.levels)} '
          f'from {bands.origin}; widest {bands.levels[-1]:g} band at step {bands.horizon}: '
          f'{widths}, position {bands.position[widest, last]:.4g} m')
    return 0


if __name__ == '__main__':
    sys.exit(main())
