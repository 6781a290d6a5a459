"""
Recordings as arrays in a vessel's own vectors: datasets or bags, and the held-out split.

``load_recordings(paths, vessel)`` accepts dataset directories (``vessel_datasets.format``)
and recordings that ``vessel_datasets.pipeline`` can read (rosbag2 MCAP directories or
files, with the vessel file's topic map or a given one). The vessel is the one the
datasets carry, or the one given (``--vessel``); bags carry none and need it. Every
failure -- a missing column, a NaN in one run, a dataset that cannot be read -- is a
``RecordingsError`` whose message is one line saying what is wrong and where.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from vessel_datasets.format import MANIFEST, DatasetError, read_dataset, split_runs
from vessel_datasets.topic_map import topic_map_for
from vessel_description import Vessel, VesselError


class RecordingsError(ValueError):
    """Recordings cannot be used; the message is one line saying why."""


@dataclass
class Run:
    """One run at a fixed rate in the vessel's vectors: states, heading, controls, truth."""

    run_id: str
    t: np.ndarray                 # (T,) s
    z: np.ndarray                 # (T, n_state) the vessel's states (FRD, SI)
    psi: np.ndarray               # (T,) heading (rad, NED, unwrapped)
    c: np.ndarray                 # (T, n_control) actuators, then environment columns
    z_true: np.ndarray | None = None   # (T, n_state) noise-free states (simulated data only)
    split: str = 'unused'
    info: dict = field(default_factory=dict)

    @property
    def length(self) -> int:
        """Return the number of samples."""
        return len(self.t)

    @property
    def dt(self) -> float:
        """Return the sample period (s)."""
        return float(np.median(np.diff(self.t))) if len(self.t) > 1 else 1.0

    def piece(self, start: int, stop: int, suffix: str, split: str) -> Run:
        """Return samples [start, stop) as a run of its own."""
        sl = slice(start, stop)
        return replace(self, run_id=self.run_id + suffix, t=self.t[sl] - self.t[start],
                       z=self.z[sl], psi=self.psi[sl], c=self.c[sl],
                       z_true=None if self.z_true is None else self.z_true[sl], split=split)


def run_from_table(run_id: str, table: pd.DataFrame, vessel: Vessel, split: str = 'unused',
                   info: dict | None = None, where: str = '') -> Run:
    """Build a Run from a dataset table; RecordingsError (one line) if it is unusable."""
    required = ('t',) + vessel.state_names + ('psi',) + vessel.control_names
    missing = [c for c in required if c not in table.columns]
    if missing:
        raise RecordingsError(f'{where}run {run_id!r} lacks the columns {", ".join(missing)} '
                              f'that vessel {vessel.name!r} has')
    values = table[list(required)].to_numpy(float)
    if not np.isfinite(values).all():
        bad = [c for c in required if not np.isfinite(table[c].to_numpy(float)).all()]
        rows = int((~np.isfinite(values)).any(axis=1).sum())
        raise RecordingsError(f'{where}run {run_id!r} has NaN or Inf in {", ".join(bad)} '
                              f'({rows} of {len(table)} samples): repair or drop the run '
                              f'before diagnosing')
    true_cols = [s + '_true' for s in vessel.state_names]
    z_true = (table[true_cols].to_numpy(float)
              if all(c in table.columns for c in true_cols) else None)
    return Run(run_id, table['t'].to_numpy(float), table[list(vessel.state_names)].to_numpy(
        float), table['psi'].to_numpy(float), table[list(vessel.control_names)].to_numpy(float),
        z_true, split, dict(info or {}))


def dataset_vessel(path: Path) -> Vessel:
    """Return the vessel description a dataset carries; one line if it cannot be read."""
    try:
        return read_dataset(path).vessel
    except (DatasetError, OSError, VesselError) as exc:
        raise RecordingsError(f'{path}: cannot read the dataset ({exc})') from None


def _load_dataset(path: Path, vessel: Vessel) -> list[Run]:
    try:
        ds = read_dataset(path)
        vessel.check_compatible(ds.vessel, f'dataset {path}')
        entries = {r['id']: r for r in ds.manifest['runs']}
        runs = []
        for rid in ds.run_ids():
            runs.append(run_from_table(rid, ds.load(rid), vessel,
                                       entries[rid].get('split', 'unused'),
                                       entries[rid].get('source', {}), f'{path}: '))
        return runs
    except VesselError as exc:
        raise RecordingsError(str(exc)) from None
    except (DatasetError, OSError, KeyError) as exc:
        raise RecordingsError(f'{path}: cannot read the dataset ({exc})') from None


def _load_bag(path: Path, vessel: Vessel, topic_map=None) -> list[Run]:
    from vessel_datasets.bag_source import BagError
    from vessel_datasets.readers.bags import bag_to_runs
    from vessel_datasets.sources import ConversionError
    try:
        tables = bag_to_runs(path, topic_map or topic_map_for(vessel))
    except (ConversionError, BagError, OSError, ValueError) as exc:
        text = ' '.join(str(exc).split())
        raise RecordingsError(f'{path}: cannot convert the recording: {text}') from None
    if not tables:
        raise RecordingsError(f'{path}: the recording holds no run (no stretch where every '
                              f'needed topic has samples)')
    return [run_from_table(rid, table, vessel, 'unused', {'bag': str(path)}, f'{path}: ')
            for rid, table in tables.items()]


def recordings_vessel(paths: Iterable[str | Path], given: Vessel | None = None) -> Vessel:
    """
    Return the vessel description the recordings come from.

    ``given`` (offline/diagnose.py --vessel) when set, else the one the datasets carry
    (all the same); bags carry none, so recordings of bags alone need ``given``.
    """
    paths = [Path(p) for p in paths]
    for path in paths:
        if not path.exists():
            raise RecordingsError(f'{path}: no such file or directory')
    if given is not None:
        return given
    found: dict[str, Vessel] = {}
    for path in paths:
        if (path / MANIFEST).is_file():
            vessel = dataset_vessel(path)
            found.setdefault(repr(vessel.to_dict()), vessel)
    if len(found) > 1:
        raise RecordingsError('the recordings carry different vessel descriptions ('
                              + ', '.join(v.source for v in found.values())
                              + '); name the one they come from with --vessel')
    if not found:
        raise RecordingsError('bags carry no vessel description: name the vessel file they '
                              'were recorded from with --vessel')
    return next(iter(found.values()))


def load_recordings(paths: Iterable[str | Path], vessel: Vessel | None = None,
                    topic_map=None) -> list[Run]:
    """Load every run of the given dataset directories and recordings, in ``vessel``'s vectors."""
    paths = [Path(p) for p in paths]
    for path in paths:
        if not path.exists():
            raise RecordingsError(f'{path}: no such file or directory')
    vessel = recordings_vessel(paths, vessel)
    runs: list[Run] = []
    for path in paths:
        if (path / MANIFEST).is_file():
            runs += _load_dataset(path, vessel)
        else:
            runs += _load_bag(path, vessel, topic_map)
    ids = [r.run_id for r in runs]
    if len(set(ids)) != len(ids):
        raise RecordingsError(f'run ids repeat across the recordings: '
                              f'{sorted({i for i in ids if ids.count(i) > 1})}')
    if not runs:
        raise RecordingsError('no runs in the recordings')
    rates = {round(1.0 / r.dt, 6) for r in runs if r.length > 1}
    if len(rates) > 1:
        raise RecordingsError(f'runs have different sample rates {sorted(rates)} Hz; '
                              f'convert them at one rate')
    return runs


def split_holdout(runs: Sequence[Run], fraction: float, seed: int
                  ) -> tuple[list[Run], list[Run], str]:
    """
    Return (diagnosis runs, held-out runs, how they were chosen).

    A dataset's own test split is used when it has test runs and training or validation
    runs: those are diagnosed, and runs its split leaves unused are not (a fold's view
    marks the fold's test runs so: fitting on them would leak them into the physics).
    Otherwise a seeded share ``fraction`` of the runs is held out, and with a single run
    its last ``fraction`` of samples.
    """
    test = [r for r in runs if r.split == 'test']
    fitted = [r for r in runs if r.split in ('train', 'val')]
    if test and fitted:
        return fitted, test, 'the dataset test split'
    if len(runs) >= 2:
        split = split_runs([r.run_id for r in runs], seed, (1.0 - fraction, 0.0, fraction))
        held = set(split['test'])
        return ([r for r in runs if r.run_id not in held], [r for r in runs if r.run_id in held],
                f'a seeded {fraction:.0%} of the runs (seed {seed})')
    run = runs[0]
    cut = int(round(run.length * (1.0 - fraction)))
    return ([run.piece(0, cut, '', 'train')], [run.piece(cut, run.length, '-heldout', 'test')],
            f'the last {fraction:.0%} of the only run')


def signal_ranges(runs: Sequence[Run], vessel: Vessel) -> dict[str, dict[str, float]]:
    """Range and within-run spread (mean of per-run std) of what excites the physics."""
    def signals(run: Run) -> dict[str, np.ndarray]:
        out = {'speed_mps': run.z[:, vessel.state_index('u')],
               'yaw_rate_deg_s': np.degrees(run.z[:, vessel.state_index('r')])}
        for a in vessel.actuators:
            values = run.c[:, vessel.control_index(a.name)]
            out[f'{a.name}_{a.unit}'] = values
        if 'wind' in vessel.environment:
            out['wind_speed_mps'] = run.c[:, vessel.control_index('wind_speed')]
        return out
    per_run = [signals(r) for r in runs]
    out = {}
    for name in per_run[0]:
        values = np.concatenate([s[name] for s in per_run])
        out[name] = {'min': float(np.min(values)), 'max': float(np.max(values)),
                     'std_within_runs': float(np.mean([np.std(s[name]) for s in per_run]))}
    return out
