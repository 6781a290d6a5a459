"""
Training runs on disk, read a window at a time: memory bounded whatever the data size.

``build_split`` streams each run's Parquet table once (pyarrow ``iter_batches``, a
chunk of ``CHUNK_ROWS`` rows at a time) into a raw float32 cache file,
``<cache>/<run_id>.f32``, row-major with the columns [z | c | z_true] that
``RunArrays.rows`` gives, and takes the normalization statistics and a bounded sample
of one-step pairs (for the physics fit) in the same pass. Windows are then read back
with ``os.pread`` of just their rows, so the process holds batches, never the dataset
(what the OS caches of the files is its page cache, not this process's memory), and
``hybrid_models.data.gather_windows`` cuts exactly the windows it cuts from memory.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
import os
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from hybrid_models.streaming import Moments, RowSample
from vessel_datasets.format import TRUE_SUFFIX, Dataset, DatasetError
from vessel_description import Vessel

CHUNK_ROWS = 65_536  # rows per Parquet batch and per sequential read (~4 MB at 16 columns)
DTYPE = np.float32
ITEM = np.dtype(DTYPE).itemsize


class RowFile:
    """``length`` float32 rows of ``width`` columns in a raw file."""

    def __init__(self, path: Path, width: int, length: int):
        self.path, self.width, self.length = Path(path), int(width), int(length)

    def rows(self, first: np.ndarray, count: int) -> np.ndarray:
        """Blocks (n, count, width) of rows ``first[i] .. first[i] + count - 1``."""
        out = np.empty((len(first), count, self.width), dtype=DTYPE)
        row_bytes = self.width * ITEM
        fd = os.open(self.path, os.O_RDONLY)
        try:
            for j, start in enumerate(np.asarray(first)):
                if start < 0 or start + count > self.length:
                    raise IndexError(f'{self.path}: rows {start}..{start + count} outside '
                                     f'0..{self.length}')
                raw = os.pread(fd, count * row_bytes, int(start) * row_bytes)
                out[j] = np.frombuffer(raw, dtype=DTYPE).reshape(count, self.width)
        finally:
            os.close(fd)
        return out

    def chunks(self) -> Iterator[np.ndarray]:
        """Yield the rows in order, ``CHUNK_ROWS`` at a time."""
        with open(self.path, 'rb') as f:
            while block := f.read(CHUNK_ROWS * self.width * ITEM):
                yield np.frombuffer(block, dtype=DTYPE).reshape(-1, self.width)


class RowWriter:
    """Append float32 rows to a file that appears under its name only when complete."""

    def __init__(self, path: Path | None):
        self.path = path
        self.tmp = None if path is None else path.with_name(path.name + '.tmp')
        self.file = None if path is None else open(self.tmp, 'wb')

    def write(self, rows: np.ndarray) -> None:
        """Append rows (a no-op for a writer without a path: a reading-only rank)."""
        if self.file is not None:
            self.file.write(np.ascontiguousarray(rows, dtype=DTYPE).tobytes())

    def close(self) -> None:
        """Finish the file (atomic rename)."""
        if self.file is not None:
            self.file.close()
            os.replace(self.tmp, self.path)


class RunFile(RowFile):
    """One cached run: rows [z | c | z_true] (``RunArrays.rows``' layout)."""

    def __init__(self, run_id: str, path: Path, n_state: int, n_control: int, length: int):
        super().__init__(path, 2 * n_state + n_control, length)
        self.run_id, self.n_state, self.n_control = run_id, n_state, n_control


@dataclass
class SplitStore:
    """The cached runs of one split and what the streaming pass learned of them."""

    runs: list[RunFile]
    state: Moments      # of z[t] over one-step inputs (all rows but each run's last)
    control: Moments    # of c[t], likewise
    pairs: RowSample    # rows [z_t | c_t | z_t+1]


def run_columns(ds: Dataset, run_id: str, spec: Vessel) -> list[str]:
    """Columns giving [z | c | z_true] (z again where the run has no noise-free truth)."""
    true_cols = [s + TRUE_SUFFIX for s in spec.state_names]
    entry = next(r for r in ds.manifest['runs'] if r['id'] == run_id)
    names = set(pq.read_schema(ds.root / entry['file']).names)
    truth = true_cols if set(true_cols) <= names else list(spec.state_names)
    return [*spec.state_names, *spec.control_names, *truth]


def stream_run(ds: Dataset, run_id: str, columns: list[str]) -> Iterator[np.ndarray]:
    """Yield a run's ``columns`` as float32 chunks, checked as ``Dataset.load`` checks."""
    entry = next(r for r in ds.manifest['runs'] if r['id'] == run_id)
    last_t = -np.inf
    table = pq.ParquetFile(ds.root / entry['file'])
    for batch in table.iter_batches(batch_size=CHUNK_ROWS, columns=['t', *columns]):
        values = np.stack([batch.column(c).to_numpy(zero_copy_only=False)
                           for c in columns], axis=1)
        t = batch.column('t').to_numpy(zero_copy_only=False)
        if not np.isfinite(values).all():
            raise DatasetError(f'run {run_id!r} has NaN/Inf in its state or control columns')
        if not (np.diff(np.concatenate([[last_t], t])) > 0).all():
            raise DatasetError(f"run {run_id!r}: column 't' is not strictly increasing")
        last_t = t[-1]
        yield values.astype(DTYPE)


MIRROR_SUFFIX = '~mirror'   # run id of a run's port/starboard mirror image


def mirror_rows(spec: Vessel):
    """Return the map of rows [z | c | z_true] onto their mirror image (vessel's ``mirror``)."""
    state_signs, sources, control_signs = spec.mirror_maps()
    ns = spec.n_state
    columns = np.concatenate([np.arange(ns), ns + np.asarray(sources, dtype=np.int64),
                              ns + len(sources) + np.arange(ns)])
    signs = np.asarray([*state_signs, *control_signs, *state_signs], dtype=DTYPE)
    return lambda rows: rows[..., columns] * signs


def build_split(ds: Dataset, split: str, spec: Vessel, cache: Path, sample_rows: int,
                seed: int, write: bool = True, mirror: bool = False) -> SplitStore:
    """
    Stream every run of ``split`` once: cache file, statistics, sample of one-step pairs.

    ``write=False`` (another process on this machine writes the cache) only computes.
    ``mirror`` adds each run's port/starboard mirror image as a run of its own
    (``<run_id>~mirror``, the vessel's ``mirror_maps``), statistics and pairs included.
    """
    ns, nc = spec.n_state, spec.n_control
    state, control, pairs = Moments(ns), Moments(nc), RowSample(sample_rows, seed)
    images = [('', None)] + ([(MIRROR_SUFFIX, mirror_rows(spec))] if mirror else [])
    runs = []
    for run_id in ds.run_ids(split):
        for suffix, image in images:
            path = cache / f'{run_id}{suffix}.f32'
            writer = RowWriter(path if write else None)
            prev, length = None, 0
            for block in stream_run(ds, run_id, run_columns(ds, run_id, spec)):
                block = block if image is None else image(block)
                writer.write(block)
                length += len(block)
                rows = block if prev is None else np.concatenate([prev, block])
                z, c = rows[:, :ns], rows[:, ns:ns + nc]
                state.add(z[:-1])
                control.add(c[:-1])
                pairs.add(np.concatenate([z[:-1], c[:-1], z[1:]], axis=1))
                prev = rows[-1:]
            writer.close()
            runs.append(RunFile(run_id + suffix, path, ns, nc, length))
    if not runs:
        raise ValueError(f'dataset {ds.root} has no runs in split {split!r}')
    return SplitStore(runs, state, control, pairs)
