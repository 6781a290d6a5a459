r"""
Give a hybrid checkpoint calibrated forecast bands, from a dataset's validation runs.

    set_bands MODEL.safetensors --dataset DATA            # in place
    set_bands MODEL.safetensors --dataset DATA --out B.safetensors

Training writes bands into every hybrid checkpoint it makes (``hybrid_models.bands``);
this program gives them to a checkpoint made before, or again after ``set_threshold``
(bands hold only at the threshold they were computed for). It forecasts every
validation run of the dataset with the compiled engine at the checkpoint's served
threshold, one forecast every STRIDE samples over the vessel's horizon, against the
measured states, and writes the bands into the checkpoint's config; the weights are
kept bit for bit. A dataset of another vessel or rate is refused, and so is one whose
validation runs the model was trained on.
"""

import argparse
from pathlib import Path
import sys

from hybrid_models.bands import LEVELS, BandsError, calibrate
from hybrid_models.checkpoint_format import (
    CheckpointError,
    read_header,
    rewrite_config,
    vessel_of,
)
from hybrid_models.cli.arguments import progress
from hybrid_models.data import dataset_hash, evaluation_protocol, forecast_windows, load_runs
from hybrid_models.engine import Forecaster
from vessel_datasets.format import DatasetError, read_dataset

STRIDE_PER_HORIZON = 30   # default stride: horizon / 30, as training's bands


def parse_args(argv=None):
    """Parse the command line."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('checkpoint', type=Path, help='hybrid checkpoint (.safetensors)')
    parser.add_argument('--dataset', type=Path, required=True,
                        help='dataset whose validation runs calibrate the bands')
    parser.add_argument('--horizon', type=int,
                        help="forecast steps calibrated (default: the vessel's horizon)")
    parser.add_argument('--stride', type=int,
                        help='samples between forecasts in a run (default: horizon / 30)')
    parser.add_argument('--levels', type=float, nargs='+', default=list(LEVELS),
                        help='band levels in (0, 1) (default 0.5 0.9)')
    parser.add_argument('--out', type=Path, help='write here instead of in place')
    return parser.parse_args(argv)


def validation_runs(config: dict, dataset, checkpoint: Path) -> list:
    """Return the dataset's validation runs; refuse runs the model was trained on."""
    trained = set(config.get('dataset', {}).get('train_runs', []))
    runs = dataset.manifest['split']['val']
    seen = sorted(trained.intersection(runs))
    if seen:
        raise ValueError(f'{checkpoint} was trained on validation runs {seen[:5]} of '
                         f'{dataset.root}: their forecasts would give too narrow bands')
    return runs


def set_bands(checkpoint: Path, dataset_dir: Path, horizon: int | None, stride: int | None,
              levels, out: Path | None) -> dict:
    """Compute and write the bands; return their config entry."""
    config = read_header(checkpoint)
    dataset = read_dataset(dataset_dir)
    dataset.vessel.check_compatible(vessel_of(config, checkpoint), f'checkpoint {checkpoint}')
    run_ids = validation_runs(config, dataset, checkpoint)
    engine = Forecaster.from_checkpoint(checkpoint)
    _, horizon, _ = evaluation_protocol(engine.spec, engine.window, horizon)
    stride = stride or max(1, horizon // STRIDE_PER_HORIZON)
    runs = load_runs(dataset, 'val', engine.spec)
    windows = forecast_windows(runs, engine.window, horizon, stride)
    pred = engine.forecast_each(windows.z_window, windows.c_window, windows.c_future,
                                progress=progress('validation forecasts')).hybrid
    bands = calibrate(pred, windows.z_target, engine.spec, engine.relative_threshold, levels,
                      source={'split': 'val', 'runs': len(run_ids), 'stride': stride,
                              'target': 'measured', 'dataset': str(dataset_dir),
                              'dataset_sha256': dataset_hash(dataset)})
    entry = bands.to_dict()
    rewrite_config(checkpoint, {**config, 'bands': entry}, out)
    return entry


def main(argv=None) -> int:
    """Parse arguments, compute the bands and write them; return the exit code."""
    args = parse_args(argv)
    try:
        entry = set_bands(args.checkpoint, args.dataset, args.horizon, args.stride,
                          args.levels, args.out)
    except (BandsError, CheckpointError, DatasetError, FileNotFoundError, ValueError) as exc:
        print(f'set_bands: error: {exc}', file=sys.stderr)
        return 2
    last = len(entry['steps']) - 1
    widths = {name: round(entry['upper'][-1][last][i] - entry['lower'][-1][last][i], 6)
              for i, name in enumerate(entry['state_names'])}
    print(f"set_bands: {args.out or args.checkpoint}: bands at levels {entry['levels']} from "
          f"{entry['source']['forecasts']} validation forecasts; widest "
          f"{entry['levels'][-1]:g} band at step {entry['steps'][last]}: {widths}, position "
          f"{entry['position_m'][-1][last]:.4g} m")
    return 0


if __name__ == '__main__':
    sys.exit(main())
