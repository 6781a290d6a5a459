"""
A tiny synthetic vessel-like dataset for tests and benchmarks (not a ship model; not shipped).

Five states and six controls with the ship's names and roughly its magnitudes: surge
follows shaft speed, the rudders turn and sway the hull, roll is a lightly damped
oscillator excited by sway and a sinusoidal "wave". It exists so that the learning
layer can be exercised in seconds without the vessel simulator.

``write_linear_dataset`` is its opposite: states that follow a linear map of state and
control exactly, without noise, so the Lin physics explains them and nothing is left
for a learned correction (the do-no-harm tests).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from vessel_datasets.format import write_dataset
from vessel_description import load_vessel

SUBSTEPS = 10
# Same vectors and rate as the simulator's vessel: the toy stands in for its datasets.
TOY_VESSEL = load_vessel('patrol_boat')


def _rates(x: np.ndarray, c: np.ndarray, wave: float) -> np.ndarray:
    u, v, p, r, phi = x
    n, dp, ds, ws, wc, wsn = c
    delta = 0.5 * (dp + ds)
    return np.array([
        0.08 * (0.08 * n - u) - 0.002 * u * abs(u) - 0.002 * ws * wc,
        -0.3 * v + 0.4 * u * delta + 0.01 * ws * wsn + 0.2 * u * r,
        -0.22 * p - 1.21 * phi + 0.05 * v + wave,
        -0.4 * r - 0.08 * u * delta - 0.02 * v * abs(v),
        p,
    ])


def _controls(rng: np.random.Generator, n: int) -> np.ndarray:
    def steps(lo, hi, hold):
        k = int(np.ceil(n / hold)) + 1
        levels = rng.uniform(lo, hi, k)
        return np.repeat(levels, hold)[:n]
    shaft = np.convolve(steps(60.0, 100.0, 120), np.ones(20) / 20, mode='same')
    rudder = np.clip(steps(-0.05, 0.05, 45), -0.05, 0.05)
    wind = 2.0 + 0.5 * np.sin(np.arange(n) / 200 + rng.uniform(0, 6))
    angle = rng.uniform(-np.pi, np.pi) + 0.2 * np.sin(np.arange(n) / 300)
    return np.stack([shaft, rudder, rudder, wind, np.cos(angle), np.sin(angle)], axis=1)


def simulate_toy_run(rng: np.random.Generator, n_samples: int, noise: float = 0.02
                     ) -> pd.DataFrame:
    """One run as a dataset table (1 Hz), with noisy states and ``_true`` columns."""
    c = _controls(rng, n_samples)
    x = np.array([0.08 * c[0, 0], 0.0, 0.0, 0.0, 0.0])
    wave_amp, wave_w = rng.uniform(0.005, 0.02), rng.uniform(0.5, 0.9)
    states = np.empty((n_samples, 5))
    h = 1.0 / SUBSTEPS
    for t in range(n_samples):
        states[t] = x
        for k in range(SUBSTEPS):
            tau = t + k * h
            wave = [wave_amp * np.sin(wave_w * (tau + d)) for d in (0, h / 2, h)]
            k1 = _rates(x, c[t], wave[0])
            k2 = _rates(x + h / 2 * k1, c[t], wave[1])
            k3 = _rates(x + h / 2 * k2, c[t], wave[1])
            k4 = _rates(x + h * k3, c[t], wave[2])
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    scale = np.array([1.0, 0.3, 0.01, 0.005, 0.01])
    measured = states + noise * scale * rng.standard_normal(states.shape)
    table = {'t': np.arange(n_samples, dtype=float)}
    for i, name in enumerate(TOY_VESSEL.state_names):
        table[name] = measured[:, i]
        table[name + '_true'] = states[:, i]
    psi = np.cumsum(states[:, 3])
    table.update({'psi': psi, 'x': np.cumsum(states[:, 0] * np.cos(psi)),
                  'y': np.cumsum(states[:, 0] * np.sin(psi))})
    for i, name in enumerate(TOY_VESSEL.control_names):
        table[name] = c[:, i]
    return pd.DataFrame(table)


def write_toy_dataset(out_dir: str | Path, n_runs: int = 10, n_samples: int = 600,
                      seed: int = 0) -> Path:
    """Write a toy dataset directory; returns its path."""
    rng = np.random.default_rng(seed)
    runs = {f'toy_{i:03d}': simulate_toy_run(rng, n_samples) for i in range(n_runs)}
    write_dataset(out_dir, runs, vessel=TOY_VESSEL, seed=seed,
                  provenance={'tool': 'offline.benchmarks.toy', 'seed': seed})
    return Path(out_dir)


def write_linear_dataset(out_dir: str | Path, n_runs: int = 8, n_samples: int = 300,
                         seed: int = 0) -> Path:
    """Write runs of z_{t+1} = A z_t + B c_t + d (noise-free; the toy's controls)."""
    rng = np.random.default_rng(seed)
    n_state, n_control = TOY_VESSEL.n_state, TOY_VESSEL.n_control
    a = np.diag([0.9, 0.8, 0.7, 0.85, 0.95]) + 0.02 * rng.standard_normal((n_state,) * 2)
    b = 0.01 * rng.standard_normal((n_state, n_control))
    d = 0.01 * rng.standard_normal(n_state)
    runs = {}
    for i in range(n_runs):
        c = _controls(rng, n_samples)
        z = np.zeros((n_samples, n_state))
        z[0] = 0.1 * rng.standard_normal(n_state)
        for t in range(n_samples - 1):
            z[t + 1] = a @ z[t] + b @ c[t] + d
        table = {'t': np.arange(n_samples, dtype=float), 'psi': np.cumsum(z[:, 3]),
                 'x': np.cumsum(z[:, 0]), 'y': np.cumsum(z[:, 1])}
        table.update({name: z[:, j] for j, name in enumerate(TOY_VESSEL.state_names)})
        table.update({name: c[:, j] for j, name in enumerate(TOY_VESSEL.control_names)})
        runs[f'linear_{i:03d}'] = pd.DataFrame(table)
    write_dataset(out_dir, runs, vessel=TOY_VESSEL, seed=seed,
                  provenance={'tool': 'offline.benchmarks.toy.write_linear_dataset', 'seed': seed})
    return Path(out_dir)
