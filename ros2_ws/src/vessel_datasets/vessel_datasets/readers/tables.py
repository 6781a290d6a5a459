"""
The table reader: CSV, whitespace-separated .dat, ..., Parquet -> timed channels.

A column map (``column_map``) says how to read the files and which column gives each
quantity. Each file is one recording; a run column splits it into runs by value. Rows
are timed by the time column (or numbered at ``rate_hz``); a time not after the newest
one is dropped and counted as repeated (jitter, duplicated rows), a time more than the
max gap before it starts a new stretch (a restarted clock). A time column that repeats
itself in many rows is printed too coarsely for the data: one line says so and what to
do. Non-numbers become NaN and are counted; the pipeline drops them per channel.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .. import resolution
from ..column_map import TABLE, ColumnMap
from ..sources import ConversionError, Part, Recording, find_files, samples
from ..topic_map import TopicMap

SUFFIXES = {'delimited': ('.csv', '.dat', '.txt', '.tsv', '.log'), 'parquet': ('.parquet',)}


class TableRecordings:
    """Reader of text tables (``sources.Reader``) by a column map's format."""

    tool = 'table_to_dataset'
    section = 'columns'

    def __init__(self, column_map: ColumnMap, pattern: str | None = None):
        self.column_map = column_map
        self.pattern = pattern

    def find(self, paths: Iterable[str | os.PathLike]) -> list[Recording]:
        """Files given, and the table files in folders given (``pattern`` or suffixes)."""
        fmt = self.column_map.table.format
        return find_files(paths, SUFFIXES[fmt], f'{fmt} table files', self.pattern)

    def config(self) -> dict[str, Any]:
        """Return the file pattern (for the manifest; the map is recorded anyway)."""
        return {'glob': self.pattern}

    def read(self, recording: Recording, topic_map: TopicMap, opts, report: dict,
             progress: Callable[[int], None] | None) -> tuple[list[Part], TopicMap]:
        """Read one file's mapped columns; raise ConversionError (one line)."""
        cmap = self.column_map
        table = read_table(recording.path, cmap)
        report.update(rows=len(table), read=[len(table), 'rows'], nan={}, duplicate_times=0,
                      time_restarts=0)
        data = {c: _numeric(table[c]) for c in cmap.columns if c != cmap.table.run}
        report['nan'] = {c: int((~np.isfinite(v)).sum()) for c, v in data.items()
                         if (~np.isfinite(v)).any()}
        if cmap.table.run:
            keys = table[cmap.table.run].astype(str).str.strip()
            groups = [(k, np.nonzero((keys == k).to_numpy())[0]) for k in dict.fromkeys(keys)]
        else:
            groups = [(None, np.arange(len(table)))]
        leaves = topic_map.leaves()
        parts = []
        for key, rows in groups:
            t = (cmap.table.time.factor * data[cmap.table.time.column][rows]
                 if cmap.table.time else np.arange(len(rows)) / cmap.table.rate_hz)
            _note_time(t, cmap, report)
            keep, segment = _time_order(t, opts.max_gap_s, report)
            for seg in np.unique(segment[keep]):
                pos = np.nonzero(keep & (segment == seg))[0]
                idx = rows[pos]
                t_ns = np.round(t[pos] * 1e9).astype(np.int64)
                columns = {leaf.path: data[leaf.path][idx] for leaf in leaves}
                parts.append(Part([samples(TABLE, t_ns, columns, leaves, topic_map, report)],
                                  key))
        if progress is not None:
            progress(1)
        return parts, topic_map


def read_table(path: str | os.PathLike, cmap: ColumnMap) -> pd.DataFrame:
    """Read one file as the column map says; raise ConversionError (one line) when it cannot."""
    path = Path(path)
    fmt = cmap.table
    if fmt.format == 'parquet':
        return _checked(path, _read_parquet(path), cmap)
    sep = r'\s+' if fmt.sep == 'whitespace' else fmt.sep
    try:
        table = pd.read_csv(path, sep=sep, skiprows=fmt.skip_lines,
                            header=0 if fmt.header_row else None, encoding=fmt.encoding,
                            index_col=False, skip_blank_lines=True)
    except UnicodeDecodeError as exc:
        raise ConversionError(f'{path}: not {fmt.encoding} text ({exc.reason} at byte '
                              f'{exc.start}); set columns.encoding') from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, OSError) as exc:
        raise ConversionError(f'{path}: cannot read as a {fmt.sep!r}-separated table after '
                              f'{fmt.skip_lines} skipped lines ({str(exc).splitlines()[0]})'
                              ) from None
    if fmt.names:
        if table.shape[1] != len(fmt.names):
            raise ConversionError(f'{path}: the table has {table.shape[1]} columns, but '
                                  f'columns.names lists {len(fmt.names)}')
        table.columns = list(fmt.names)
    elif fmt.header_row:
        table.columns = [str(c).strip() for c in table.columns]
    else:
        table.columns = [f'col{i + 1}' for i in range(table.shape[1])]
    return _checked(path, table, cmap)


def _read_parquet(path: Path) -> pd.DataFrame:
    """Read a Parquet file's table (its own column names and types)."""
    try:
        return pd.read_parquet(path)
    except (OSError, ValueError) as exc:   # pyarrow's ArrowInvalid is a ValueError
        raise ConversionError(f'{path}: cannot read as a Parquet table '
                              f'({str(exc).splitlines()[0]})') from None


def _checked(path: Path, table: pd.DataFrame, cmap: ColumnMap) -> pd.DataFrame:
    """Return the table, refused in one line when it lacks a column the map names."""
    missing = [c for c in cmap.columns if c not in table.columns]
    if missing:
        raise ConversionError(f'{path}: {cmap.label_of(missing[0])} names column '
                              f'{missing[0]!r}, which the file lacks; it has '
                              f'{", ".join(map(str, table.columns))}')
    return table


def _numeric(series: pd.Series) -> np.ndarray:
    if pd.api.types.is_numeric_dtype(series):
        return series.to_numpy(dtype=float)
    return pd.to_numeric(series, errors='coerce').to_numpy(dtype=float)


def _note_time(t: np.ndarray, cmap: ColumnMap, report: dict) -> None:
    """Say once when the time column repeats itself: printed too coarsely for its rows."""
    if cmap.table.time is None or any(n.startswith('columns.time') for n in report['notes']):
        return
    res = resolution.analyse('time', np.arange(len(t)) * 10 ** 9, t, 's')
    if res is not None and res.repeats >= resolution.MIN_REPEAT_SHARE:
        report['notes'].append(
            f'columns.time ({cmap.table.time.column}) repeats its previous value in '
            f'{100 * res.repeats:.0f} % of the rows and advances in steps of {res.step:g} s: '
            f'printed too coarsely for its rows, whose repeated times are dropped (give '
            f'rate_hz instead of time if the rows are equally spaced)')


def _time_order(t: np.ndarray, max_gap_s: float, report: dict) -> tuple[np.ndarray, np.ndarray]:
    """
    Rows to keep and their segment number.

    NaN times and times not after the newest are dropped (duplicates, jitter); a time
    more than ``max_gap_s`` before the newest starts a new segment (a restarted clock).
    """
    keep = np.zeros(len(t), bool)
    segment = np.zeros(len(t), int)
    newest, seg = -math.inf, 0
    for i, ti in enumerate(t):
        if not math.isfinite(ti):
            continue
        if ti < newest - max_gap_s:
            seg += 1
            report['time_restarts'] += 1
        elif ti <= newest:
            report['duplicate_times'] += 1
            continue
        newest = ti
        keep[i], segment[i] = True, seg
    return keep, segment
