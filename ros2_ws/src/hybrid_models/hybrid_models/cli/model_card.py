"""
Write a model card for a hybrid checkpoint: what it is, what it learned from, how good.

Evaluates the checkpoint with the compiled forecast engine (the code the predictor
node runs) on the test split of a dataset: forecasts over the vessel's horizon every
STRIDE samples of every test run, against the noise-free states where the dataset has
them, and the physics alone beside it at every quarter of the horizon. A dataset of
another vessel or rate is refused. Shows how the served relative threshold was chosen
on the validation runs. Writes MODEL_CARD.md and model_card.json.

example (the embedded default model):
  model_card.py MODELS/model.safetensors --dataset data/ship96 --out MODELS
  with MODELS = ros2_ws/src/hybrid_predictor/models/default
"""

import argparse
import json
from pathlib import Path
import sys

import numpy as np

from hybrid_models.bands import coverage, coverage_table
from hybrid_models.checkpoint_format import CheckpointError, read_header, vessel_of
from hybrid_models.cli.arguments import progress
from hybrid_models.cli.arguments import threshold as threshold_value
from hybrid_models.data import dataset_hash, evaluation_protocol, forecast_windows, load_runs
from hybrid_models.engine import Forecaster
from hybrid_models.metrics import forecast_metrics
from hybrid_models.selection import PHYSICS_ALONE
from vessel_datasets.format import DatasetError, read_dataset


def parse_args(argv=None):
    """Parse the command line."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('checkpoint', type=Path, help='hybrid model checkpoint (.safetensors)')
    parser.add_argument('--dataset', type=Path, required=True, help='dataset directory')
    parser.add_argument('--threshold', type=threshold_value, default=None,
                        help="relative threshold served (default: the checkpoint's own, "
                             "which set_threshold writes; 0: physics alone; 'none': "
                             'unbounded)')
    parser.add_argument('--horizon', type=int,
                        help="forecast steps (default: the vessel's horizon)")
    parser.add_argument('--stride', type=int,
                        help='samples between forecasts in a test run (default: horizon/7.5)')
    parser.add_argument('--out', type=Path, required=True, help='folder for the card')
    return parser.parse_args(argv)


def evaluate(engine: Forecaster, physics: Forecaster, dataset, horizon: int,
             stride: int) -> dict:
    """Forecast the test split with the engine and the physics alone; return metrics."""
    runs = load_runs(dataset, 'test', engine.spec)
    windows = forecast_windows(runs, engine.window, horizon, stride, target='true')
    problems = (windows.z_window, windows.c_window, windows.c_future)
    seconds = []
    predictions = engine.forecast_each(*problems, progress=progress('test forecasts'),
                                       seconds=seconds).hybrid
    physics_alone = physics.forecast_each(*problems, progress=progress('physics alone')
                                          ).hybrid
    metrics = forecast_metrics(predictions, windows.z_target, engine.spec)
    metrics['physics_alone'] = forecast_metrics(physics_alone, windows.z_target, engine.spec)
    metrics['latency_ms_p50'] = float(np.median(seconds) * 1e3)
    if engine.bands is not None:   # the bands promise the measured states: judged on them
        measured = forecast_windows(runs, engine.window, horizon, stride).z_target
        metrics['bands'] = coverage(engine.bands, predictions, measured, engine.spec)
    metrics['test_runs'] = len(runs)
    metrics['stride'] = stride
    return metrics


def profile_lines(spec, metrics: dict) -> list[str]:
    """Return the Markdown table of errors along the horizon, hybrid and physics alone."""
    hybrid, physics = metrics['profile'], metrics['physics_alone']['profile']
    head = ['after [s]', 'position [m]'] + [f'{s} [{u}]' for s, u in zip(
        spec.state_names, spec.state_units, strict=True)]
    lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    for i, seconds in enumerate(hybrid['seconds']):
        cells = [f'{seconds:g}', _pair(hybrid['position_m'][i], physics['position_m'][i])]
        cells += [_pair(hybrid['rmse'][s][i], physics['rmse'][s][i]) for s in spec.state_names]
        lines.append('| ' + ' | '.join(cells) + ' |')
    return lines


def _pair(hybrid, physics) -> str:
    return f'{_figure(hybrid)} ({_figure(physics)})'


def _figure(value) -> str:
    """Return a metric for a table; None (a diverged forecast) as 'diverged'."""
    return 'diverged' if value is None else f'{value:.4g}'


def band_lines(engine: Forecaster, metrics: dict) -> list[str]:
    """Return the calibrated bands at the reported steps and their coverage on the test runs."""
    bands, cover = engine.bands, metrics.get('bands')
    if bands is None or cover is None:
        return [f'None served: {engine.bands_note}.']
    return [f'From {bands.origin} against the measured states, at threshold '
            f'{bands.relative_threshold}; published with every forecast (docs/predictor.md). '
            'Width of each band (upper - lower; position: radius) and, in brackets, the '
            'fraction of the test forecasts above whose measured states it held:', '',
            *coverage_table(bands, cover, engine.spec)]


def selection_lines(config: dict) -> list[str]:
    """Return how the served threshold was chosen on validation (or that it was not)."""
    chosen = config.get('selection')
    if not chosen:
        return ['The served threshold was set by hand (`set_threshold`) or by the training '
                'config; it was not chosen on validation runs.']
    lines = [f"Chosen on the validation runs: threshold {chosen['relative_threshold']} "
             f"({chosen['reason']}). Validation score (sum over states of RMSE / std) of "
             f"the physics alone: {chosen['physics']['score']:.4g}.", '',
             '| threshold | validation score | worse than the physics alone at |',
             '|---|---|---|']
    for row in chosen['candidates']:
        worse = ', '.join(row['harms'][:3]) + (' ...' if len(row['harms']) > 3 else '')
        lines.append(f"| {row['relative_threshold']} | {row['score']:.4g} | "
                     f"{worse or 'no reported step'} |")
    return lines


def card_text(path: Path, config: dict, engine: Forecaster, metrics: dict,
              dataset) -> str:
    """Return the Markdown card."""
    run = config.get('training', {})
    model = run.get('model', {})
    data = config.get('dataset', {})
    states = engine.spec.state_names
    units = engine.spec.state_units
    traj = metrics['trajectory']
    provenance = dataset.manifest.get('provenance', {})
    lines = [
        f'# Model card: {config.get("name", path.stem)}',
        '',
        f'- **File**: `{path.name}` ({engine.model_id}), weights-only safetensors with a '
        'JSON config; loads without unpickling.',
        f'- **Model**: hybrid residual model (Baier et al.), physical part '
        f'`{model.get("physical", {}).get("kind")}`, {engine.cell.name.upper()} '
        f'{model.get("layers")} x {model.get("hidden")} with an initializer of the same '
        f'cells over a {engine.window}-sample window; {config.get("parameters")} trained '
        'parameters'
        + (f'; an ensemble of {len(config["ensemble"]["seeds"])} such hybrids (seeds '
           f'{config["ensemble"]["seeds"]}) on this physics, each step adding the mean of '
           f'their bounded corrections.' if config.get('ensemble') else '.'),
        f'- **Constraint**: the correction bounded to ± relative threshold x the physical '
        f"model's 95 % output range / 2; the checkpoint serves threshold "
        f'{engine.relative_threshold}, which gives bounds '
        + ', '.join(f'{s} {b:.4g} {u}' for s, b, u in zip(states, engine.bound, units,
                                                          strict=True)) + '.',
        f'- **Training data**: `{data.get("path")}` (sha256 `{str(data.get("sha256"))[:16]}`'
        f'...), {len(data.get("train_runs", []))} training runs; generated by '
        f'`{" ".join(provenance.get("command", [])) or provenance.get("tool", "?")}`.',
        f'- **Training**: {len(run.get("training", {}).get("phases", []))} phases '
        f'({", ".join(p["kind"] for p in run.get("training", {}).get("phases", []))}), '
        f'best epoch {config.get("best_epoch")} of {config.get("epochs")}, stopped by '
        f'"{config.get("stop_reason")}", {config.get("train_seconds", 0) / 60:.1f} min on 2 '
        'CPU cores.',
        '',
        f'## Test metrics ({metrics["n_forecasts"]} forecasts of {metrics["horizon"]} steps, '
        f'one every {metrics["stride"]} samples of {metrics["test_runs"]} test runs, against the '
        'noise-free states, true future controls)',
        '',
        f'Test runs from `{metrics["test_dataset"]["path"]}` (sha256 '
        f'`{metrics["test_dataset"]["sha256"][:16]}`...)'
        + ('.' if metrics['test_dataset']['sha256'] == data.get('sha256') else
           ': not the dataset the model was trained on (same simulator settings and seed '
           'give the same split; a changed simulator gives slightly different runs).'),
        '',
        '| ' + ' | '.join(f'{s} [{u}]' for s, u in zip(states, units, strict=True))
        + ' | trajectory [m] |',
        '|' + '---|' * (len(states) + 1),
        '| ' + ' | '.join(f'{metrics["rmse"][s]:.4g}' for s in states)
        + f' | {traj["mean"]:.3g} ± {traj["ci95"] or 0:.2g} |',
        '',
        f'Trajectory error: mean distance over the horizon with a 95 % CI over forecasts; '
        f'{traj["final_mean"]:.3g} m after {metrics["horizon"]} steps. One forecast takes '
        f'{metrics["latency_ms_p50"]:.1f} ms (p50, compiled engine, this machine).',
        '',
        '## Along the horizon (test runs): the hybrid, and in brackets its physics alone',
        '',
        *profile_lines(engine.spec, metrics),
        '',
        '## Calibrated forecast bands',
        '',
        *band_lines(engine, metrics),
        '',
        '## The served threshold',
        '',
        *selection_lines(config),
        '',
        'Regenerate with `python offline/model_card.py` (see its `--help`).',
    ]
    return '\n'.join(lines) + '\n'


def main(argv=None) -> int:
    """Evaluate and write the card; return the exit code."""
    args = parse_args(argv)
    try:
        config = read_header(args.checkpoint)
        dataset = read_dataset(args.dataset)
        dataset.vessel.check_compatible(vessel_of(config, args.checkpoint),
                                        f'checkpoint {args.checkpoint}')
        engine = Forecaster.from_checkpoint(args.checkpoint, args.threshold)
        physics = Forecaster.from_checkpoint(args.checkpoint, PHYSICS_ALONE)
        _, horizon, stride = evaluation_protocol(engine.spec, engine.window, args.horizon,
                                                 args.stride)
    except (CheckpointError, DatasetError, FileNotFoundError, TypeError, ValueError) as exc:
        print(f'model_card: error: {exc}', file=sys.stderr)
        return 2
    metrics = evaluate(engine, physics, dataset, horizon, stride)
    metrics['test_dataset'] = {'path': str(args.dataset), 'sha256': dataset_hash(args.dataset)}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'MODEL_CARD.md').write_text(
        card_text(args.checkpoint, config, engine, metrics, dataset))
    (args.out / 'model_card.json').write_text(json.dumps(
        {'checkpoint': args.checkpoint.name, 'model_id': engine.model_id,
         'relative_threshold': engine.relative_threshold, 'bound': engine.bound.tolist(),
         **metrics},
        indent=2))
    print(f'model_card: wrote {args.out / "MODEL_CARD.md"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
