#!/usr/bin/env python3
r"""
Validate the nano-drone benchmark adapter against the paper's own figures.

    .venv-bench/bin/python offline/peers/nanodrone_benchmark_table.py \
        [--shared ../shared/real] [--repo SNAPSHOT] [--work out/peers/nanodrone] \
        [--doc docs/results/nanodrone/benchmark_models.md]

Runs offline/peers/nanodrone_benchmark.py (all four models and the naive baseline) on the
benchmark's three test flights as the shared parquet files hold them (melon runs 1, 4
and 5 of 17 Oct 2025), once as they are and once low-pass filtered as the benchmark's
later processing filters its CSV files, scores both exactly as its
``results/model_comparison.py`` does (``quadrotor_measures.benchmark_table_mae``) and
puts the tables, beside the figures its ``results/model_comparison.ipynb`` printed,
between the markers of the --doc file (and on stdout).
"""

import argparse
import json
from pathlib import Path
import re
import subprocess
import sys

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import nanodrone_benchmark as adapter  # noqa: E402

measures = adapter.measures
TEST_FLIGHTS = ('train/melon_20251017_run1', 'train/melon_20251017_run4',
                'test/melon_20251017_run5')
MODELS = ('naive', 'physics', 'mlp', 'hybrid', 'lstm')
PAPER_NAMES = {'naive': 'Naïve', 'physics': 'Physics', 'mlp': 'MLP', 'hybrid': 'Hybrid',
               'lstm': 'LSTM'}
STEPS = (1, 10, 25, 50)
UNITS = {'position': 'm', 'velocity': 'm/s', 'attitude': 'rad', 'body_rates': 'rad/s'}
BEGIN = '<!-- validation table: begin (offline/peers/nanodrone_benchmark_table.py) -->'
END = '<!-- validation table: end -->'
# The benchmark's later processing (its csv_to_processed notebook) filters every signal
# with a 4th-order zero-phase Butterworth low-pass at these cutoffs (Hz); attitude through
# its so(3) log.
CUTOFFS = {'position': 10.0, 'velocity': 18.0, 'body_rates': 18.0, 'motors': 20.0,
           'attitude': 12.0}


def published(snapshot):
    """{model: 16 figures} of the table the benchmark's comparison notebook printed."""
    notebook = json.loads(snapshot.read('results/model_comparison.ipynb'))
    text = ''
    for cell in notebook['cells']:
        for output in cell.get('outputs', []):
            text += ''.join(output.get('text', []))
    rows = {}
    for key, name in PAPER_NAMES.items():
        match = re.search(rf'^{re.escape(name)} &(.*?)\\\\', text, flags=re.M)
        if not match:
            raise adapter.AdapterError(f"no {name} row in the notebook's printed table")
        cells = [re.sub(r'\\textbf\{([^}]*)\}', r'\1', c).strip()
                 for c in match.group(1).split('&')]
        rows[key] = [float(c) for c in cells]
    return rows


def low_pass(frame, path):
    """Write the flight low-pass filtered as the benchmark's processing does, as CSV."""
    from scipy.signal import butter, sosfiltfilt  # noqa: PLC0415

    def lp(values, cutoff):
        return sosfiltfilt(butter(4, cutoff, btype='low', fs=100.0, output='sos'), values,
                           axis=0)

    frame = frame.copy()
    frame[['x', 'y', 'z']] = lp(frame[['x', 'y', 'z']].to_numpy(float), CUTOFFS['position'])
    for cols, key in ((['vx', 'vy', 'vz'], 'velocity'), (['wx', 'wy', 'wz'], 'body_rates')):
        frame[cols] = lp(frame[cols].to_numpy(float), CUTOFFS[key])
    rads = frame[[f'm{i}_erpm' for i in range(1, 5)]].to_numpy(float) * adapter.ERPM_TO_RADS
    rads = lp(rads, CUTOFFS['motors'])
    for i in range(4):
        frame[f'm{i + 1}_rads'] = rads[:, i]
    quat = frame[['qx', 'qy', 'qz', 'qw']].to_numpy(float)
    rotvec = lp(measures.quat_to_rotvec(quat / np.linalg.norm(quat, axis=1, keepdims=True)),
                CUTOFFS['attitude'])
    frame[['qx', 'qy', 'qz', 'qw']] = measures.rotvec_to_quat(rotvec)
    frame.to_csv(path, index=False)


def forecast(flights, out, repo):
    """Run the adapter (this interpreter) on the flights, all models, into out (.npz)."""
    command = [sys.executable, str(HERE / 'nanodrone_benchmark.py'), '--flights',
               *map(str, flights), '--models', ','.join(MODELS), '--out', str(out),
               '--repo', str(repo)]
    if subprocess.run(command).returncode != 0:
        raise adapter.AdapterError('the adapter failed (its error is above)')
    return np.load(out)


def score(data, names):
    """{model: {quantity: (H,)}} scored as the benchmark's comparison does."""
    first = {q: np.concatenate([data[f'{n}.truth.{q}'][:, 0] for n in names])
             for q in measures.QUANTITIES}
    table = {}
    for model in MODELS:
        pred = {q: np.concatenate([data[f'{n}.{model}.{q}'] for n in names])
                for q in measures.QUANTITIES}
        table[model] = measures.benchmark_table_mae(first, pred)
    return table


def markdown(paper, ours_raw, ours_filtered):
    """Write the four tables, one per quantity."""
    lines = []
    for qi, quantity in enumerate(measures.QUANTITIES):
        unit = UNITS[quantity]
        label = quantity.replace('_', ' ')
        lines += [f'**{label}** (mean error per step, {unit}; '
                  f'h = 1:50 is the sum over steps 1..50)', '',
                  '| model | figures | h = 1 | h = 10 | h = 25 | h = 50 | h = 1:50 |',
                  '| --- | --- | ---: | ---: | ---: | ---: | ---: |']
        for model in MODELS:
            p = paper[model][4 * qi:4 * qi + 4]
            lines.append(f'| {PAPER_NAMES[model]} | paper | {p[0]:.4f} | {p[1]:.4f} | — | '
                         f'{p[2]:.4f} | {p[3]:.4f} |')
            for tag, table in (('ours, shared flights', ours_raw),
                               ('ours, low-passed', ours_filtered)):
                v = table[model][quantity]
                cells = ' | '.join(f'{v[h - 1]:.4f}' for h in STEPS)
                lines.append(f'| | {tag} | {cells} | {v[:50].sum():.4f} |')
        lines.append('')
    return '\n'.join(lines)


def agreement(paper, table):
    """Largest relative difference to the paper, per model, over h = 10, 50 and the sums."""
    out = {}
    for model in MODELS:
        worst = 0.0
        for qi, quantity in enumerate(measures.QUANTITIES):
            v = table[model][quantity]
            p = paper[model][4 * qi:4 * qi + 4]
            for ours, theirs in ((v[9], p[1]), (v[49], p[2]), (v[:50].sum(), p[3])):
                worst = max(worst, abs(ours - theirs) / theirs)
        out[model] = worst
    return out


def main(argv=None):
    """Derive the validation tables; a failure is one line and exit status 2."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--shared', default=str(adapter.REPO_ROOT.parent / 'shared' / 'real'),
                        help='the shared real recordings (default %(default)s)')
    parser.add_argument('--repo', default=str(adapter.DEFAULT_SNAPSHOT),
                        help='snapshot of the benchmark repository (default %(default)s)')
    parser.add_argument('--work', default=str(adapter.REPO_ROOT / 'out' / 'peers' / 'nanodrone'),
                        help='where the forecasts go (default %(default)s)')
    parser.add_argument('--doc', default=str(adapter.REPO_ROOT / 'docs' / 'results'
                                             / 'nanodrone' / 'benchmark_models.md'),
                        help='the note whose marked section gets the tables')
    args = parser.parse_args(argv)
    try:
        import pandas as pd  # noqa: PLC0415
        snapshot = adapter.Snapshot(args.repo)
        paper = published(snapshot)
        flights = [Path(args.shared) / 'nanodrone' / f'{f}.parquet' for f in TEST_FLIGHTS]
        missing = [str(f) for f in flights if not f.is_file()]
        if missing:
            raise adapter.AdapterError(f'no flight {missing[0]}')
        work = Path(args.work)
        work.mkdir(parents=True, exist_ok=True)
        names = [f.stem for f in flights]
        raw = forecast(flights, work / 'raw.npz', args.repo)
        filtered_paths = []
        for flight in flights:
            path = work / f'{flight.stem}.csv'
            low_pass(pd.read_parquet(flight), path)
            filtered_paths.append(path)
        filtered = forecast(filtered_paths, work / 'low_passed.npz', args.repo)
        ours_raw, ours_filtered = score(raw, names), score(filtered, names)
        near_raw, near_filtered = agreement(paper, ours_raw), agreement(paper, ours_filtered)
        summary = ['Largest relative difference to the paper over h = 10, h = 50 and h = 1:50 '
                   '(all four quantities):', '',
                   '| model | shared flights | low-passed |', '| --- | ---: | ---: |']
        summary += [f'| {PAPER_NAMES[m]} | {100 * near_raw[m]:.1f} % | '
                    f'{100 * near_filtered[m]:.1f} % |' for m in MODELS]
        body = '\n'.join([
            f'Benchmark snapshot {snapshot.commit[:12]}; flights '
            + ', '.join(f'`{f}.parquet`' for f in TEST_FLIGHTS) + ' (in that order); '
            f'{sum(len(raw[f"{n}.start"]) for n in names)} windows of 50 steps. Command:', '',
            '    .venv-bench/bin/python offline/peers/nanodrone_benchmark_table.py', '',
            *summary, '', markdown(paper, ours_raw, ours_filtered)])
        print(body)
        doc = Path(args.doc)
        if doc.is_file():
            text = doc.read_text()
            if BEGIN in text and END in text:
                head, rest = text.split(BEGIN, 1)
                _, tail = rest.split(END, 1)
                doc.write_text(f'{head}{BEGIN}\n{body}\n{END}{tail}')
                print(f'[table] updated {doc}', file=sys.stderr)
        return 0
    except (adapter.AdapterError, OSError, ValueError, KeyError) as exc:
        print(f'nanodrone_benchmark_table: error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
