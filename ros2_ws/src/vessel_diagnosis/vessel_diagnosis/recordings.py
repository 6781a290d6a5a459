"""
Recordings as arrays: datasets or rosbag2 recordings, and the held-out split.

``load_recordings(paths)`` accepts dataset directories (``vessel_datasets.format``) and
recordings that ``vessel_datasets.pipeline`` can read (rosbag2 MCAP directories or files,
with the default topic map or a given one). Every failure is a ``RecordingsError`` whose
message is one line saying what is missing and what it is needed for.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from vessel_datasets.format import MANIFEST, DatasetError, read_dataset, split_runs
from vessel_datasets.topic_map import topic_map_for
from vessel_description import Vessel, VesselError, load_vessel

# The diagnosis' physics family is the 4-DOF patrol-boat model (vessel_physics), so it
# diagnoses recordings with that vessel's vectors; others are refused with one line.
DIAGNOSED_VESSEL = load_vessel('patrol_boat')
STATE_COLUMNS = DIAGNOSED_VESSEL.state_names
CONTROL_COLUMNS = DIAGNOSED_VESSEL.control_names
REQUIRED = ('t',) + STATE_COLUMNS + ('psi',) + CONTROL_COLUMNS
WHY = {  # what each group of columns is needed for (for error messages)
    'u': 'body velocities (/vessel/odom twist)', 'v': 'body velocities (/vessel/odom twist)',
    'p': 'body rates (/vessel/odom twist)', 'r': 'body rates (/vessel/odom twist)',
    'phi': 'attitude (/vessel/odom orientation)', 'psi': 'attitude (/vessel/odom orientation)',
    'n': 'actuators (/vessel/actuators)', 'delta_port': 'actuators (/vessel/actuators)',
    'delta_stbd': 'actuators (/vessel/actuators)', 'wind_speed': 'wind (/vessel/wind)',
    'wind_dir_cos': 'wind (/vessel/wind)', 'wind_dir_sin': 'wind (/vessel/wind)',
    't': 'time stamps',
}


class RecordingsError(ValueError):
    """Recordings cannot be used; the message is one line saying why."""


@dataclass
class Run:
    """One run at a fixed rate: measured states, heading, controls, optional truth."""

    run_id: str
    t: np.ndarray                 # (T,) s
    z: np.ndarray                 # (T, 5) u, v (m/s), p, r (rad/s), phi (rad); FRD
    psi: np.ndarray               # (T,) heading (rad, NED, unwrapped)
    c: np.ndarray                 # (T, 6) n, delta_port, delta_stbd, wind speed, cos, sin
    z_true: np.ndarray | None = None   # (T, 5) noise-free states (simulated data only)
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


def run_from_table(run_id: str, table: pd.DataFrame, split: str = 'unused',
                   info: dict | None = None) -> Run:
    """Build a Run from a dataset table; RecordingsError if columns are missing."""
    missing = [c for c in REQUIRED if c not in table.columns]
    if missing:
        needs = sorted({WHY[c] for c in missing})
        raise RecordingsError(f'run {run_id!r} lacks {", ".join(missing)}: the diagnosis needs '
                              f'{"; ".join(needs)}')
    values = table[list(REQUIRED)].to_numpy(float)
    if not np.isfinite(values).all():
        bad = [c for c in REQUIRED if not np.isfinite(table[c].to_numpy(float)).all()]
        raise RecordingsError(f'run {run_id!r} has NaN/Inf in {", ".join(bad)}')
    true_cols = [s + '_true' for s in STATE_COLUMNS]
    z_true = (table[true_cols].to_numpy(float)
              if all(c in table.columns for c in true_cols) else None)
    return Run(run_id, table['t'].to_numpy(float), table[list(STATE_COLUMNS)].to_numpy(float),
               table['psi'].to_numpy(float), table[list(CONTROL_COLUMNS)].to_numpy(float),
               z_true, split, dict(info or {}))


def _load_dataset(path: Path) -> list[Run]:
    try:
        ds = read_dataset(path)
        DIAGNOSED_VESSEL.check_compatible(ds.vessel, f'dataset {path}')
        entries = {r['id']: r for r in ds.manifest['runs']}
        return [run_from_table(rid, ds.load(rid), entries[rid].get('split', 'unused'),
                               entries[rid].get('source', {})) for rid in ds.run_ids()]
    except VesselError as exc:
        raise RecordingsError(f"{exc}; the diagnosis models the patrol boat's physics "
                              f'only') from None
    except (DatasetError, OSError, KeyError) as exc:
        raise RecordingsError(f'{path}: cannot read the dataset ({exc})') from None


def _load_bag(path: Path, topic_map=None) -> list[Run]:
    from vessel_datasets.bag_source import BagError
    from vessel_datasets.readers.bags import bag_to_runs
    from vessel_datasets.sources import ConversionError
    try:
        tables = bag_to_runs(path, topic_map or topic_map_for(DIAGNOSED_VESSEL))
    except (ConversionError, BagError, OSError, ValueError) as exc:
        text = ' '.join(str(exc).split())
        raise RecordingsError(f'{path}: cannot convert the recording: {text}') from None
    if not tables:
        raise RecordingsError(f'{path}: the recording holds no run (no stretch where every '
                              f'needed topic has samples)')
    return [run_from_table(rid, table, 'unused', {'bag': str(path)})
            for rid, table in tables.items()]


def load_recordings(paths: Iterable[str | Path], topic_map=None) -> list[Run]:
    """Load every run of the given dataset directories and recordings."""
    runs: list[Run] = []
    for path in map(Path, paths):
        if not path.exists():
            raise RecordingsError(f'{path}: no such file or directory')
        if (path / MANIFEST).is_file():
            runs += _load_dataset(path)
        else:
            runs += _load_bag(path, topic_map)
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


def recordings_vessel(paths: Iterable[str | Path], given: Vessel | None = None) -> Vessel:
    """
    Return the vessel description the recordings come from.

    ``given`` (offline/diagnose.py --vessel) when set, else the description the datasets
    carry; bags carry none and are read with the diagnosed vessel's topic map, so its
    description is theirs. It must have the diagnosed vessel's vectors and rate.
    """
    found: dict[str, Vessel] = {}
    if given is None:
        for path in map(Path, paths):
            if (path / MANIFEST).is_file():
                vessel = read_dataset(path).vessel
                found.setdefault(repr(vessel.to_dict()), vessel)
            else:
                found.setdefault(repr(DIAGNOSED_VESSEL.to_dict()), DIAGNOSED_VESSEL)
        if len(found) > 1:
            raise RecordingsError('the recordings carry different vessel descriptions ('
                                  + ', '.join(v.source for v in found.values())
                                  + '); name the one they come from with --vessel')
        given = next(iter(found.values()), DIAGNOSED_VESSEL)
    try:
        DIAGNOSED_VESSEL.check_compatible(given, 'the vessel file')
    except VesselError as exc:
        raise RecordingsError(f"{exc}; the diagnosis models the patrol boat's physics "
                              f'only') from None
    return given


def split_holdout(runs: Sequence[Run], fraction: float, seed: int
                  ) -> tuple[list[Run], list[Run], str]:
    """
    Return (diagnosis runs, held-out runs, how they were chosen).

    A dataset's own test split is used when it has test runs and others; otherwise a
    seeded share ``fraction`` of the runs is held out, and with a single run its last
    ``fraction`` of samples.
    """
    test = [r for r in runs if r.split == 'test']
    if test and len(test) < len(runs):
        return [r for r in runs if r.split != 'test'], test, 'the dataset test split'
    if len(runs) >= 2:
        split = split_runs([r.run_id for r in runs], seed, (1.0 - fraction, 0.0, fraction))
        held = set(split['test'])
        return ([r for r in runs if r.run_id not in held], [r for r in runs if r.run_id in held],
                f'a seeded {fraction:.0%} of the runs (seed {seed})')
    run = runs[0]
    cut = int(round(run.length * (1.0 - fraction)))
    return ([run.piece(0, cut, '', 'train')], [run.piece(cut, run.length, '-heldout', 'test')],
            f'the last {fraction:.0%} of the only run')


def signal_ranges(runs: Sequence[Run]) -> dict[str, dict[str, float]]:
    """Range and within-run spread (mean of per-run std) of the signals that excite physics."""
    def signals(run: Run) -> dict[str, np.ndarray]:
        return {'speed_mps': run.z[:, 0],
                'shaft_speed_rpm': run.c[:, 0] * 60.0 / (2.0 * np.pi),
                'rudder_deg': np.degrees(0.5 * (run.c[:, 1] + run.c[:, 2])),
                'yaw_rate_deg_s': np.degrees(run.z[:, 3]),
                'wind_speed_mps': run.c[:, 3]}
    per_run = [signals(r) for r in runs]
    out = {}
    for name in per_run[0]:
        values = np.concatenate([s[name] for s in per_run])
        out[name] = {'min': float(np.min(values)), 'max': float(np.max(values)),
                     'std_within_runs': float(np.mean([np.std(s[name]) for s in per_run]))}
    return out
