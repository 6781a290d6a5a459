"""
Read and write the dataset format shared by simulation and bag conversion.

A dataset is a directory with ``manifest.json`` and one Parquet table per run in
``runs/``; docs/conventions.md documents the columns, units and frames. This module is
the only code that touches those files, so every producer (``offline/simulate.py``,
``offline/bag_to_dataset.py``) and consumer (training, evaluation, diagnosis) agrees.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
import json
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

FORMAT = 'vessel-dataset/1'
MANIFEST = 'manifest.json'
RUNS_DIR = 'runs'

STATE_COLUMNS = ('u', 'v', 'p', 'r', 'phi')
CONTROL_COLUMNS = ('n', 'delta_port', 'delta_stbd', 'wind_speed', 'wind_dir_cos',
                   'wind_dir_sin')
POSE_COLUMNS = ('psi', 'x', 'y')
REQUIRED_COLUMNS = ('t',) + STATE_COLUMNS + POSE_COLUMNS + CONTROL_COLUMNS
DEFAULT_FRACTIONS = (0.6, 0.1, 0.3)
SPLITS = ('train', 'val', 'test')

COLUMN_DOCS: dict[str, dict[str, str]] = {
    't': {'unit': 's', 'description': "time since the run's first sample"},
    'u': {'unit': 'm/s', 'description': 'surge velocity, body frame FRD'},
    'v': {'unit': 'm/s', 'description': 'sway velocity, body frame FRD (starboard +)'},
    'p': {'unit': 'rad/s', 'description': 'roll rate, body frame FRD'},
    'r': {'unit': 'rad/s', 'description': 'yaw rate, body frame FRD (turn to starboard +)'},
    'phi': {'unit': 'rad', 'description': 'roll angle (starboard down +)'},
    'psi': {'unit': 'rad', 'description': 'heading from north towards east, unwrapped'},
    'x': {'unit': 'm', 'description': "position north of the run's start (NED)"},
    'y': {'unit': 'm', 'description': "position east of the run's start (NED)"},
    'n': {'unit': 'rad/s', 'description': 'shaft speed of both rudder-propellers'},
    'delta_port': {'unit': 'rad',
                   'description': 'port rudder-propeller angle (thrust to starboard +)'},
    'delta_stbd': {'unit': 'rad',
                   'description': 'starboard rudder-propeller angle (thrust to starboard +)'},
    'wind_speed': {'unit': 'm/s', 'description': 'measured true wind speed'},
    'wind_dir_cos': {'unit': '1',
                     'description': 'cos of the angle the wind comes from, rel. to the bow'},
    'wind_dir_sin': {'unit': '1',
                     'description': 'sin of that angle (wind from starboard +)'},
}
for _state in STATE_COLUMNS + POSE_COLUMNS:
    COLUMN_DOCS[_state + '_true'] = {
        'unit': COLUMN_DOCS[_state]['unit'],
        'description': 'noise-free truth of ' + _state + ' (simulated data only)',
    }


class DatasetError(ValueError):
    """A dataset directory or table does not follow the format."""


def split_runs(run_ids: Sequence[str], seed: int,
               fractions: Sequence[float] = DEFAULT_FRACTIONS) -> dict[str, list[str]]:
    """
    Assign whole runs to train/val/test by a seeded shuffle.

    Counts are rounded so that they sum to the number of runs and every split with a
    positive fraction gets at least one run when there are enough runs.
    """
    if len(fractions) != 3 or any(f < 0 for f in fractions) or not math.isclose(
            sum(fractions), 1.0, abs_tol=1e-9):
        raise DatasetError(f'split fractions must be three non-negative numbers summing '
                           f'to 1, got {list(fractions)}')
    ids = sorted(run_ids)
    order = np.random.default_rng(seed).permutation(len(ids))
    counts = _split_counts(len(ids), fractions)
    out: dict[str, list[str]] = {}
    start = 0
    for name, count in zip(SPLITS, counts, strict=True):
        out[name] = sorted(ids[i] for i in order[start:start + count])
        start += count
    return out


def _split_counts(n: int, fractions: Sequence[float]) -> list[int]:
    raw = [f * n for f in fractions]
    counts = [int(math.floor(x)) for x in raw]
    # Largest remainders get the leftover runs (96 runs give 57/10/29).
    for i in sorted(range(3), key=lambda k: raw[k] - counts[k], reverse=True):
        if sum(counts) == n:
            break
        counts[i] += 1
    if n >= 3:
        for i in range(3):
            if fractions[i] > 0 and counts[i] == 0:
                donor = int(np.argmax(counts))
                counts[donor] -= 1
                counts[i] += 1
    return counts


def validate_run(run_id: str, table: pd.DataFrame) -> None:
    """Raise DatasetError unless a run table has the required, finite, ordered columns."""
    missing = [c for c in REQUIRED_COLUMNS if c not in table.columns]
    if missing:
        raise DatasetError(f'run {run_id!r} lacks columns {missing}; it has '
                           f'{list(table.columns)}')
    if len(table) < 2:
        raise DatasetError(f'run {run_id!r} has {len(table)} samples; need at least 2')
    values = table[list(REQUIRED_COLUMNS)].to_numpy(dtype=float)
    if not np.isfinite(values).all():
        bad = [c for c in REQUIRED_COLUMNS if not np.isfinite(table[c].to_numpy(float)).all()]
        raise DatasetError(f'run {run_id!r} has NaN/Inf in {bad}')
    if not (np.diff(table['t'].to_numpy(float)) > 0).all():
        raise DatasetError(f"run {run_id!r}: column 't' is not strictly increasing")


def write_dataset(out_dir: str | os.PathLike, runs: Mapping[str, pd.DataFrame], *,
                  rate_hz: float, provenance: Mapping, seed: int = 0,
                  fractions: Sequence[float] = DEFAULT_FRACTIONS,
                  split: Mapping[str, Iterable[str]] | None = None,
                  run_sources: Mapping[str, Mapping] | None = None,
                  extra: Mapping | None = None) -> Path:
    """
    Write runs and their manifest to ``out_dir``; return the manifest path.

    ``split`` overrides the seeded 60/10/30 assignment with explicit run ids.
    ``run_sources`` gives per-run provenance (e.g. the bag and time span it came
    from). The manifest is written last, through a temporary file, so a crash never
    leaves a directory that looks complete.
    """
    if not runs:
        raise DatasetError('no runs to write')
    out = Path(out_dir)
    (out / RUNS_DIR).mkdir(parents=True, exist_ok=True)
    for run_id, table in runs.items():
        validate_run(run_id, table)
    if split is None:
        split_ids = split_runs(list(runs), seed, fractions)
    else:
        split_ids = {name: sorted(split.get(name, ())) for name in SPLITS}
        assigned = [r for ids in split_ids.values() for r in ids]
        unknown = sorted(set(assigned) - set(runs))
        if unknown or len(assigned) != len(set(assigned)):
            raise DatasetError(f'explicit split names unknown or repeated runs: {unknown}')
    split_of = {r: name for name, ids in split_ids.items() for r in ids}
    entries = []
    columns: set[str] = set()
    for run_id in sorted(runs):
        table = runs[run_id]
        rel = f'{RUNS_DIR}/{run_id}.parquet'
        table.reset_index(drop=True).to_parquet(out / rel, index=False)
        columns.update(table.columns)
        entries.append({
            'id': run_id,
            'file': rel,
            'n_samples': int(len(table)),
            'duration_s': float(table['t'].iloc[-1] - table['t'].iloc[0]),
            'split': split_of.get(run_id, 'unused'),
            'source': dict((run_sources or {}).get(run_id, {})),
        })
    manifest = {
        'format': FORMAT,
        'rate_hz': float(rate_hz),
        'state_columns': list(STATE_COLUMNS),
        'control_columns': list(CONTROL_COLUMNS),
        'columns': {c: COLUMN_DOCS.get(c, {'unit': '?', 'description': 'extra column'})
                    for c in sorted(columns)},
        'runs': entries,
        'split': {'seed': int(seed), 'fractions': [float(f) for f in fractions],
                  **split_ids},
        'provenance': dict(provenance),
        **dict(extra or {}),
    }
    path = out / MANIFEST
    tmp = path.with_suffix('.json.tmp')
    tmp.write_text(json.dumps(manifest, indent=2, sort_keys=False, default=_json_default))
    tmp.replace(path)
    return path


def _json_default(value):
    if isinstance(value, (np.integer, np.floating)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f'cannot store {type(value).__name__} in a manifest')


@dataclass
class Dataset:
    """A dataset on disk: its manifest and lazy access to its run tables."""

    root: Path
    manifest: dict

    @property
    def rate_hz(self) -> float:
        """Return the sampling rate of every run (Hz)."""
        return float(self.manifest['rate_hz'])

    def run_ids(self, split: str | None = None) -> list[str]:
        """Run ids, all or those of one split ('train', 'val', 'test')."""
        if split is None:
            return [r['id'] for r in self.manifest['runs']]
        if split not in SPLITS:
            raise DatasetError(f'unknown split {split!r}; use one of {SPLITS}')
        return list(self.manifest['split'][split])

    def load(self, run_id: str) -> pd.DataFrame:
        """Load one run's table."""
        entry = next((r for r in self.manifest['runs'] if r['id'] == run_id), None)
        if entry is None:
            raise DatasetError(f'{self.root}: no run {run_id!r}')
        table = pd.read_parquet(self.root / entry['file'])
        validate_run(run_id, table)
        return table

    def load_split(self, split: str) -> dict[str, pd.DataFrame]:
        """Load every run of one split, keyed by run id."""
        return {r: self.load(r) for r in self.run_ids(split)}


def read_dataset(path: str | os.PathLike) -> Dataset:
    """Open a dataset directory, checking its manifest."""
    root = Path(path)
    manifest_path = root / MANIFEST
    if not manifest_path.is_file():
        raise DatasetError(f'{root}: not a dataset (no {MANIFEST})')
    try:
        manifest = json.loads(manifest_path.read_text())
    except json.JSONDecodeError as exc:
        raise DatasetError(f'{manifest_path}: unreadable manifest ({exc})') from None
    if manifest.get('format') != FORMAT:
        raise DatasetError(f'{manifest_path}: format {manifest.get("format")!r}, '
                           f'expected {FORMAT!r}')
    return Dataset(root=root, manifest=manifest)
