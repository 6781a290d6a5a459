"""
Runs as arrays, and the forecast windows cut from them.

Indexing used everywhere in this package (one sample period per index):

- a forecast starts at index ``t0``; its initialization window is ``z[t0-W:t0]`` and
  ``c[t0-W:t0]`` (W = window, e.g. 60 samples);
- it predicts ``z[t0:t0+H]`` (H = horizon), step k from ``z[t0+k-1]`` (the last
  window sample for k = 0) and the control held over that step, ``c[t0+k-1]``;
- so the forecast's controls are ``c[t0-1:t0-1+H]``: the control applied over the
  sample period that ends at each predicted sample.
"""

from __future__ import annotations

from dataclasses import dataclass
import hashlib
from pathlib import Path

import numpy as np

from vessel_datasets.format import Dataset, read_dataset
from vessel_description import Vessel


@dataclass
class RunArrays:
    """One run: measured states, controls and (if simulated) noise-free states."""

    run_id: str
    z: np.ndarray        # (T, n_state) measured, model units
    c: np.ndarray        # (T, n_control)
    z_true: np.ndarray   # (T, n_state) noise-free where the dataset has it, else = z

    @property
    def length(self) -> int:
        """Return the number of samples."""
        return len(self.z)

    @property
    def n_state(self) -> int:
        """Return the number of states."""
        return self.z.shape[1]

    def rows(self, first: np.ndarray, count: int) -> np.ndarray:
        """Blocks (n, count, D) of rows ``first[i] + k``, columns [z | c | z_true]."""
        idx = np.asarray(first)[:, None] + np.arange(count)
        return np.concatenate([self.z[idx], self.c[idx], self.z_true[idx]], axis=-1)


@dataclass
class Windows:
    """A batch of forecast problems cut from runs (see the module docstring)."""

    z_window: np.ndarray   # (B, W, n_state)
    c_window: np.ndarray   # (B, W, n_control)
    c_future: np.ndarray   # (B, H, n_control), c[t0-1:t0-1+H]
    z_target: np.ndarray   # (B, H, n_state), z[t0:t0+H] (measured or true)
    run_index: np.ndarray  # (B,) index into the run list
    t0: np.ndarray         # (B,) first predicted index

    def __len__(self) -> int:
        return len(self.t0)

    def subset(self, idx) -> Windows:
        """Rows ``idx`` of every field."""
        return Windows(*(getattr(self, f)[idx] for f in self.__dataclass_fields__))

    def tiled(self, times: int) -> Windows:
        """Every row ``times`` over, block after block (rows of block j: j B .. (j + 1) B)."""
        return Windows(*(np.concatenate([getattr(self, f)] * times)
                         for f in self.__dataclass_fields__))


def load_runs(dataset: Dataset | str | Path, split: str, spec: Vessel) -> list[RunArrays]:
    """Load every run of ``split`` as float32 arrays in the vehicle's vector order."""
    ds = dataset if isinstance(dataset, Dataset) else read_dataset(dataset)
    runs = []
    for run_id, table in ds.load_split(split).items():
        z = table[list(spec.state_names)].to_numpy(np.float32)
        true_cols = [s + '_true' for s in spec.state_names]
        has_true = all(col in table.columns for col in true_cols)
        z_true = table[true_cols].to_numpy(np.float32) if has_true else z.copy()
        c = table[list(spec.control_names)].to_numpy(np.float32)
        runs.append(RunArrays(run_id, z, c, z_true))
    if not runs:
        raise ValueError(f'dataset {ds.root} has no runs in split {split!r}')
    return runs


def checked_vessel(dataset: Dataset | str | Path, checkpoints: list[tuple[object, dict]],
                   names: list | None = None) -> Vessel:
    """
    Return the dataset's vessel, refused unless every checkpoint was made for the same one.

    ``checkpoints`` are (model, config) pairs as ``load_model`` returns them; a model
    trained at another rate or on other vectors is refused with one line.
    """
    ds = dataset if isinstance(dataset, Dataset) else read_dataset(dataset)
    vessel = ds.vessel
    for i, (_, cfg) in enumerate(checkpoints):
        label = f'checkpoint {names[i]}' if names else f'checkpoint {i}'
        vessel.check_compatible(Vessel.from_dict(cfg['vehicle'], source=label),
                                label)
    return vessel


def dataset_hash(dataset: Dataset | str | Path) -> str:
    """SHA-256 over the manifest and every run file (identifies the training data)."""
    ds = dataset if isinstance(dataset, Dataset) else read_dataset(dataset)
    digest = hashlib.sha256((ds.root / 'manifest.json').read_bytes())
    for entry in sorted(ds.manifest['runs'], key=lambda r: r['id']):
        digest.update((ds.root / entry['file']).read_bytes())
    return digest.hexdigest()


def forecast_starts(length: int, window: int, horizon: int, stride: int,
                    offset: int = 0) -> np.ndarray:
    """First predicted indices t0 = window + offset + k*stride with t0 + horizon <= length."""
    last = length - horizon
    first = window + offset
    if last < first:
        return np.zeros(0, dtype=np.int64)
    return np.arange(first, last + 1, stride, dtype=np.int64)


def window_index(starts: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Return (run index, t0) of every start, run by run: the order of ``cut_windows``."""
    ri = [np.full(len(t0), i, dtype=np.int64) for i, t0 in enumerate(starts)]
    return (np.concatenate(ri) if ri else np.zeros(0, np.int64),
            np.concatenate(starts) if starts else np.zeros(0, np.int64))


def gather_windows(runs: list, run_index: np.ndarray, t0: np.ndarray, window: int,
                   horizon: int, target: str = 'measured') -> Windows:
    """
    Cut the forecast problems (run_index[j], t0[j]), in that order (module docstring).

    ``runs`` are ``RunArrays`` in memory or ``run_store.RunFile`` on disk: anything with
    ``rows(first, count)`` giving [z | c | z_true] blocks and ``n_state``. Target
    'measured' or 'true'.
    """
    if target not in ('measured', 'true'):
        raise ValueError(f"target must be 'measured' or 'true', got {target!r}")
    if len(t0) == 0:
        raise ValueError(f'no run is long enough for window {window} + horizon {horizon}')
    blocks = None
    for i in np.unique(run_index):
        at = np.flatnonzero(run_index == i)
        part = runs[i].rows(t0[at] - window, window + horizon)
        if blocks is None:
            blocks = np.empty((len(t0),) + part.shape[1:], dtype=part.dtype)
        blocks[at] = part
    ns = runs[int(run_index[0])].n_state
    nc = blocks.shape[2] - 2 * ns
    state = slice(ns + nc, None) if target == 'true' else slice(0, ns)
    # Step k predicts z[t0+k] from c[t0+k-1]: the controls start one row before t0.
    fields = (blocks[:, :window, :ns], blocks[:, :window, ns:ns + nc],
              blocks[:, window - 1:window - 1 + horizon, ns:ns + nc],
              blocks[:, window:, state])
    return Windows(*(np.ascontiguousarray(f) for f in fields), np.asarray(run_index),
                   np.asarray(t0))


def cut_windows(runs: list, starts: list[np.ndarray], window: int, horizon: int,
                target: str = 'measured') -> Windows:
    """Gather forecast problems at ``starts[i]`` of run ``i``; target 'measured' or 'true'."""
    return gather_windows(runs, *window_index(starts), window, horizon, target)


def evaluation_protocol(vessel, window: int | None = None, horizon: int | None = None,
                        stride: int | None = None) -> tuple[int, int, int]:
    """
    Window, horizon and stride (samples) of test forecasts; None takes the vessel's.

    Forecasts start every horizon/7.5 samples: 120 for the paper's 900 s at 1 Hz.
    """
    window = int(window if window is not None else vessel.window)
    horizon = int(horizon if horizon is not None else vessel.horizon)
    stride = int(stride if stride is not None else max(1, round(horizon / 7.5)))
    if min(window, horizon, stride) < 1:
        raise ValueError(f'window, horizon and stride must be at least 1 sample, got '
                          f'{window}, {horizon}, {stride}')
    return window, horizon, stride


def forecast_windows(runs: list, window: int, horizon: int, stride: int,
                     target: str = 'measured') -> Windows:
    """Cut evaluation forecasts: one every ``stride`` samples across each run."""
    starts = [forecast_starts(r.length, window, horizon, stride) for r in runs]
    return cut_windows(runs, starts, window, horizon, target)


def tiling_starts(runs: list, window: int, length: int, offset: int) -> list[np.ndarray]:
    """Return the first predicted indices of ``tiling_windows``, run by run."""
    return [forecast_starts(r.length, window, length, length, offset) for r in runs]


def tiling_windows(runs: list, window: int, length: int, offset: int) -> Windows:
    """
    Training sequences whose predicted spans tile each run from ``window + offset``.

    Predicted spans ``[t0, t0+length)`` are back to back, so one epoch predicts every
    sample once except the first ``offset`` after the window and a tail shorter than
    ``length``; drawing ``offset`` afresh each epoch covers all of ``[window, T)``.
    """
    return cut_windows(runs, tiling_starts(runs, window, length, offset), window, length,
                       'measured')


def one_step_pairs(runs: list[RunArrays]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All (z_t, c_t, z_{t+1}) pairs of measured data, stacked over runs."""
    z = np.concatenate([r.z[:-1] for r in runs])
    c = np.concatenate([r.c[:-1] for r in runs])
    z_next = np.concatenate([r.z[1:] for r in runs])
    return z, c, z_next
