"""
Read and write the dataset format shared by simulation and recording conversion.

A dataset is a directory with ``manifest.json`` and one Parquet table per run in
``runs/``; docs/conventions.md documents the columns, units and frames. The manifest
carries the vessel description (vessel_description) whose vectors the runs hold: time,
its states, the pose (psi, x, y) and its controls. This module is the only code that
touches those files, so every producer (``offline/simulate.py``,
``offline/bag_to_dataset.py``, the table importer) and consumer (training, evaluation,
diagnosis) agrees.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
import json
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from vessel_datasets import carried_physics
from vessel_description import Vessel, VesselError

FORMAT = 'vessel-dataset/1'
MANIFEST = 'manifest.json'
RUNS_DIR = 'runs'

DEFAULT_FRACTIONS = (0.6, 0.1, 0.3)
SPLITS = ('train', 'val', 'test')
TRUE_SUFFIX = '_true'  # noise-free truth of a state or pose column (simulated data only)


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


def validate_run(run_id: str, table: pd.DataFrame, columns: Sequence[str]) -> None:
    """Raise DatasetError unless a run table has ``columns``, finite, with ordered time."""
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise DatasetError(f'run {run_id!r} lacks columns {missing}; it has '
                           f'{list(table.columns)}')
    if len(table) < 2:
        raise DatasetError(f'run {run_id!r} has {len(table)} samples; need at least 2')
    values = table[list(columns)].to_numpy(dtype=float)
    if not np.isfinite(values).all():
        bad = [c for c in columns if not np.isfinite(table[c].to_numpy(float)).all()]
        raise DatasetError(f'run {run_id!r} has NaN/Inf in {bad}')
    if not (np.diff(table['t'].to_numpy(float)) > 0).all():
        raise DatasetError(f"run {run_id!r}: column 't' is not strictly increasing")


def write_dataset(out_dir: str | os.PathLike, runs: Mapping[str, pd.DataFrame], *,
                  vessel: Vessel, provenance: Mapping, seed: int = 0,
                  fractions: Sequence[float] = DEFAULT_FRACTIONS,
                  split: Mapping[str, Iterable[str]] | None = None,
                  run_sources: Mapping[str, Mapping] | None = None,
                  extra: Mapping | None = None) -> Path:
    """
    Write runs of ``vessel`` and their manifest to ``out_dir``; return the manifest path.

    Runs are sampled at the vessel's rate; columns beyond its own are kept (documented
    as extra).
    ``split`` overrides the seeded 60/10/30 assignment with explicit run ids.
    ``run_sources`` gives per-run provenance (e.g. the bag and time span it came
    from). A physics file of the vessel's own (not a packaged one) is written into the
    dataset (``carried_physics``). The manifest is written last, through a temporary
    file, so a crash never leaves a directory that looks complete.
    """
    if not runs:
        raise DatasetError('no runs to write')
    out = Path(out_dir)
    (out / RUNS_DIR).mkdir(parents=True, exist_ok=True)
    for run_id, table in runs.items():
        validate_run(run_id, table, vessel.dataset_columns)
    vessel = carried_physics.carry(vessel, out)
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
    docs = column_docs(vessel)
    manifest = {
        'format': FORMAT,
        'rate_hz': float(vessel.rate_hz),
        'vessel': vessel.to_dict(),
        'state_columns': list(vessel.state_names),
        'control_columns': list(vessel.control_names),
        'columns': {c: docs.get(c, {'unit': '?', 'description': 'extra column'})
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


def column_docs(vessel: Vessel) -> dict[str, dict[str, str]]:
    """Return unit and meaning of every column a run of ``vessel`` may have."""
    docs = vessel.column_docs()
    for name in vessel.state_names + vessel.pose_names:
        docs[name + TRUE_SUFFIX] = {'unit': docs[name]['unit'],
                                    'description': f'noise-free truth of {name} '
                                                   f'(simulated data only)'}
    return docs


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

    @cached_property
    def vessel(self) -> Vessel:
        """Return the vessel description the runs were made for."""
        data = self.manifest.get('vessel')
        if data is None:
            raise DatasetError(f'{self.root}: the manifest names no vessel (a dataset made '
                               f'before vessel files); convert or simulate it again')
        try:
            vessel = Vessel.from_dict(data, source=f'{self.root / MANIFEST}')
        except VesselError as exc:
            raise DatasetError(str(exc)) from None
        if vessel.rate_hz != self.rate_hz:
            raise DatasetError(f'{self.root}: runs at {self.rate_hz} Hz, but its vessel '
                               f'{vessel.name!r} says {vessel.rate_hz} Hz')
        return vessel

    def run_ids(self, split: str | None = None) -> list[str]:
        """Run ids, all or those of one split ('train', 'val', 'test')."""
        if split is None:
            return [r['id'] for r in self.manifest['runs']]
        if split not in SPLITS:
            raise DatasetError(f'unknown split {split!r}; use one of {SPLITS}')
        return list(self.manifest['split'][split])

    def recordings(self) -> dict[str, list[str]]:
        """
        Return the run ids of every recording (bag, log file), by recording.

        Runs cut from one recording share its conditions, so splits and folds keep them
        together (the converters' ``source_run``, or the bag or file of older datasets);
        a run that names no source is a recording of its own.
        """
        out: dict[str, list[str]] = {}
        for entry in self.manifest['runs']:
            source = entry.get('source') or {}
            key = str(source.get('source_run') or source.get('bag') or source.get('file')
                      or entry['id'])
            out.setdefault(key, []).append(entry['id'])
        return out

    def load(self, run_id: str) -> pd.DataFrame:
        """Load one run's table."""
        entry = next((r for r in self.manifest['runs'] if r['id'] == run_id), None)
        if entry is None:
            raise DatasetError(f'{self.root}: no run {run_id!r}')
        table = pd.read_parquet(self.root / entry['file'])
        validate_run(run_id, table, self.vessel.dataset_columns)
        return table

    def load_split(self, split: str) -> dict[str, pd.DataFrame]:
        """Load every run of one split, keyed by run id."""
        return {r: self.load(r) for r in self.run_ids(split)}


def resplit(dataset: Dataset, out_dir: str | os.PathLike,
            split: Mapping[str, Iterable[str]], note: str = '') -> Dataset:
    """
    Write a view of ``dataset`` with another split; return it.

    The view is a manifest whose runs are symbolic links to the dataset's own files, so
    it costs no copy; runs the split does not name are 'unused'. ``note`` says why (it is
    kept in the manifest's provenance beside the original's).
    """
    ids = {name: sorted(split.get(name, ())) for name in SPLITS}
    known = set(dataset.run_ids())
    named = [r for runs in ids.values() for r in runs]
    if unknown := sorted(set(named) - known):
        raise DatasetError(f'{dataset.root}: no runs {unknown}')
    if len(named) != len(set(named)):
        raise DatasetError('a run is named in more than one split')
    out = Path(out_dir)
    (out / RUNS_DIR).mkdir(parents=True, exist_ok=True)
    split_of = {r: name for name, runs in ids.items() for r in runs}
    manifest = json.loads(json.dumps(dataset.manifest))
    for entry in manifest['runs']:
        link = out / entry['file']
        link.unlink(missing_ok=True)
        link.symlink_to((dataset.root / entry['file']).resolve())
        entry['split'] = split_of.get(entry['id'], 'unused')
    manifest['split'] = {**manifest['split'], **ids}
    carried_physics.carry_into_view(dataset.vessel, dataset.root, out)
    manifest['provenance'] = {'resplit_of': str(dataset.root), 'note': note,
                              'original': manifest.get('provenance', {})}
    path = out / MANIFEST
    tmp = path.with_suffix('.json.tmp')
    tmp.write_text(json.dumps(manifest, indent=2))
    tmp.replace(path)
    return read_dataset(out)


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
