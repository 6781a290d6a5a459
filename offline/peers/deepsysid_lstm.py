#!/usr/bin/env python3
r"""
deepsysid as a peer: Baier et al.'s own LSTM with a separate initializer (LSTMInitModel).

    .venv-bench/bin/python offline/peers/deepsysid_lstm.py --problem P.npz --out A.npz \\
        [--quick] [--epochs-scale 1.0]

Reads a problem of ``peer_io`` and runs deepsysid's ``LSTMInitModel`` as its authors'
library does (its ``train`` and ``simulate``, unmodified, from tools/bench/vendor): an
initializer LSTM trained one step ahead on (control, state) sequences, whose hidden state
starts a predictor LSTM trained on sequences of controls. Their convention pairs control
row t with state row t (the control that led to it); ours pairs it with the state it
starts from, so the runs are handed over as (c[:-1], z[1:]), and a window's initializer
sees exactly our window's states and controls (their ``simulate`` drops the first
initial control and appends the first horizon control).

Settings: their patrol-ship experiment's (``examples/patrolship.json``): dropout 0.25,
sequence length 50, batch 256, learning rate 0.0025, 400 initializer and 800 predictor
epochs, no gradient clipping; the loss 'mse' only (their 'msge' is defective: it
differences the truth against the prediction, REFERENCES.md). Batches are
``min(256, sequences // 4)`` (at least 8): their loader drops the last partial batch, so
256 would leave a small set without a single batch. Grid (theirs is recurrent_dim
{64, 128, 192, 256} x layers {2, 3, 4}): recurrent_dim {64, 128} x 2 layers, seed 0, the
lowest validation score (sum over states of RMSE / training std over the validation
windows, open loop) wins; that point is then trained with every seed of the problem.
``--epochs-scale`` scales both epoch counts (stated in the answer's meta). One thread.
A control that is constant over the training runs (the KVLCC2 tank tests' shaft speed) is
left out: deepsysid divides by each control's standard deviation unguarded, and a zero
turns every forecast into NaN; it carries nothing a model trained on those runs could
use.
"""

from __future__ import annotations

import logging
import random
import sys

import numpy as np
import peer_io

NAME = 'deepsysid-lstm'
STATIC = {'dropout': 0.25, 'sequence_length': 50, 'batch_size': 256, 'learning_rate': 0.0025,
          'epochs_initializer': 400, 'epochs_predictor': 800, 'loss': 'mse'}
DEFAULT = {'recurrent_dim': 64, 'num_recurrent_layers': 2}
GRID = [{'recurrent_dim': d, 'num_recurrent_layers': 2} for d in (64, 128)]


def _import():
    # deepsysid's hybrid module names np.infty (removed in numpy 2.0) as a default value;
    # the recurrent models import fine, but the package's import chain may reach it.
    if not hasattr(np, 'infty'):
        np.infty = np.inf
    import torch
    torch.set_num_threads(1)
    logging.getLogger('deepsysid').setLevel(logging.WARNING)
    from deepsysid.models.recurrent import (
        LSTMInitModel,
        SeparateInitializerRecurrentNetworkModelConfig,
    )
    return torch, LSTMInitModel, SeparateInitializerRecurrentNetworkModelConfig


def _sequences(runs: list, length: int) -> int:
    return sum(max(0, (len(z) - 1 - (2 * length + 1)) // length) for z, _ in runs)


def fit(problem: peer_io.Problem, point: dict, seed: int, scale_epochs: float):
    """Train one LSTMInitModel on the training runs; return it and its settings."""
    torch, model_class, config_class = _import()
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)
    static = settings(problem, scale_epochs)
    keep = constant_free(problem.train)
    config = config_class(device_name='cpu',
                          control_names=[n for n, k in zip(problem.control_names, keep,
                                                           strict=True) if k],
                          state_names=problem.state_names, time_delta=problem.dt,
                          **static, **point)
    model = model_class(config)
    model.train([c[:-1, keep] for _, c in problem.train], [z[1:] for z, _ in problem.train])
    model.peer_controls = keep
    return model, static


def settings(problem: peer_io.Problem, scale_epochs: float) -> dict:
    """Their static settings for this problem: the batch fitted to it, the epochs scaled."""
    static = dict(STATIC)
    static['batch_size'] = int(max(8, min(256, _sequences(problem.train,
                                                          STATIC['sequence_length']) // 4)))
    for key in ('epochs_initializer', 'epochs_predictor'):
        static[key] = max(1, int(round(STATIC[key] * scale_epochs)))
    return static


def constant_free(runs: list) -> np.ndarray:
    """Return the mask of the controls that vary over the runs."""
    return np.concatenate([c for _, c in runs]).std(axis=0) > 0


def forecast(model, windows: dict) -> np.ndarray:
    """Open-loop forecasts (B, H, n) by deepsysid's simulate, one window at a time."""
    zw, cw, cf = (np.asarray(windows[k], np.float64) for k in peer_io.WINDOW_FIELDS)
    cw, cf = cw[..., model.peer_controls], cf[..., model.peer_controls]
    out = np.empty(cf.shape[:2] + (zw.shape[2],))
    for b in range(len(zw)):
        initial_control = np.concatenate([cw[b, :1], cw[b, :-1]])   # row 0 is dropped
        out[b] = model.simulate(initial_control, zw[b], cf[b])
    return peer_io.limited(out)


def solve(problem: peer_io.Problem, args, say) -> dict:
    """Tune on validation with seed 0, then train the chosen point with every seed."""
    grid = [DEFAULT] if args.quick else GRID
    seeds = problem.seeds

    def fit_first(point):
        model, static = fit(problem, point, seeds[0], args.epochs_scale)
        return model, {'batch_size': static['batch_size']}

    tuned = peer_io.tune(grid, fit_first, forecast, problem, say)
    preds, fits, fcs = [], [], []
    for i, seed in enumerate(seeds):
        if i == 0:
            model, seconds = tuned.model, tuned.fit_seconds
        else:
            (model, _), seconds = peer_io.timed(fit, problem, tuned.point, seed,
                                                args.epochs_scale)
        pred, forecast_seconds = peer_io.timed(forecast, model, problem.test_windows)
        preds.append(pred)
        fits.append(seconds)
        fcs.append(forecast_seconds)
        say(f'seed {seed}: trained in {seconds:.0f} s, forecast in {fcs[-1]:.1f} s')
    return {'pred': np.stack(preds), 'seeds': seeds, 'fit_seconds': fits,
            'forecast_seconds': fcs,
            'meta': {'peer': 'deepsysid LSTMInitModel (Baier et al.)',
                     'package': 'deepsysid', 'version': '0.1.24 (commit 6b0001c)',
                     'static': settings(problem, args.epochs_scale),
                     'epochs_scale': args.epochs_scale,
                     'defaults': DEFAULT, 'grid': tuned.grid, 'chosen': tuned.point,
                     'tuning_seconds': tuned.seconds, 'stochastic': True,
                     'controls_left_out': [n for n, k in zip(
                         problem.control_names, constant_free(problem.train), strict=True)
                         if not k]}}


def main(argv=None) -> int:
    """Add --epochs-scale to the common arguments and run."""
    p = peer_io.parser(NAME, __doc__)
    p.add_argument('--epochs-scale', type=float, default=1.0,
                   help='factor on their 400 / 800 epochs (default 1: theirs)')
    args = p.parse_args(argv)
    if not args.epochs_scale > 0:
        p.error('--epochs-scale must be > 0')
    return peer_io.run(NAME, __doc__, solve, argv, args=args)


if __name__ == '__main__':
    sys.exit(main())
