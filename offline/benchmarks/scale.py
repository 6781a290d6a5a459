"""
Scaling out, measured in one run: training processes, training memory, conversion workers.

- Training throughput (predicted samples per second of the fit loop's own epoch times;
  start-up, imports and the run cache reported apart) of the smoke config, several
  epochs a phase, on 1 and on 2 CPU processes (torchrun, gloo), the machine's cores
  shared out: each of N processes gets cores / N intra-op threads; one process on one
  thread as a reference; and per GPU when one is present.
- Peak resident memory of a whole training (smoke config, one epoch a phase) on the
  default generated dataset and on one 10 times larger (the same runs ten times, with
  fresh measurement noise; written under the temporary directory, never kept).
- Bag-conversion throughput (messages per second) of a folder of bags with 1 (in the
  calling process, as ``--jobs 1``) and 2 worker processes, same bags, same run. The bags
  are copies of one generated recording (default an hour at 20 Hz, 216,000 messages,
  ~1.7 s to convert), so the same work each; sized so that starting the workers is
  small beside converting.

Goals: peak memory on the 10x dataset <= 1.5 x that on the default one; 2 conversion
workers >= 1.6 x as fast as 1.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import shutil
import socket
import subprocess
import sys
import tempfile
import time

import numpy as np
import torch

from vessel_datasets import synthetic
from vessel_datasets.format import read_dataset, write_dataset
from vessel_datasets.pipeline import Options, convert_all
from vessel_datasets.readers.bags import BagRecordings
from vessel_datasets.topic_map import topic_map_for
from vessel_description import load_vessel

from .toy import TOY_VESSEL, write_toy_dataset

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'
TRAIN = ROOT / 'offline' / 'train.py'
GOAL_MEMORY_RATIO = 1.5
GOAL_CONVERT_SPEEDUP = 1.6
SCALE = 10
NOISE = 0.01  # relative measurement noise that makes the copies of the 10x dataset differ
CPUS = os.cpu_count() or 1
# Prints the largest resident set of the command it runs (kB): a fresh process per
# measurement, since RUSAGE_CHILDREN keeps the maximum over all children ever waited for.
PEAK_RSS = ('import resource, subprocess, sys; done = subprocess.run(sys.argv[1:], '
            'stdout=subprocess.DEVNULL); print(done.returncode, '
            'resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)')


# A run that takes seconds to minutes, for CI (`bench.py --quick scale`): it shows the
# suite still runs end to end; its figures say nothing of the full run's.
QUICK = ('--runs', '5', '--samples', '400', '--epochs', '1', '--bags', '2', '--bag-minutes', '1')


def add_arguments(parser) -> None:
    """Command-line options of this suite."""
    parser.add_argument('--runs', type=int, default=8,
                        help='runs of the default generated dataset (default 8)')
    parser.add_argument('--samples', type=int, default=1800,
                        help='samples per run of the default dataset (default 1800, 1 Hz)')
    parser.add_argument('--epochs', type=int, default=4,
                        help='epochs a phase of the throughput trainings (default 4)')
    parser.add_argument('--bags', type=int, default=8, help='bags to convert (default 8)')
    parser.add_argument('--bag-minutes', type=float, default=60.0,
                        help='length of each bag (default 60 min)')
    parser.add_argument('--bag-rate', type=float, default=20.0, metavar='HZ',
                        help='publishing rate of each topic in the bags (default 20 Hz)')


def run(args) -> dict:
    """Generate the data, measure the three figures, return them with the goals."""
    with tempfile.TemporaryDirectory(prefix='bench_scale_') as tmp:
        tmp = Path(tmp)
        default = write_toy_dataset(tmp / 'default', n_runs=args.runs,
                                    n_samples=args.samples)
        large = scaled_dataset(default, tmp / 'large', SCALE)
        training = {f'{n}_cpu_processes': train_throughput(default, tmp / f'tp{n}', n, 'cpu',
                                                            args.epochs)
                    for n in (1, 2)}
        # Reference, not the comparison: one process on one thread.
        training['1_cpu_process_1_thread'] = train_throughput(default, tmp / 'tp1t', 1, 'cpu',
                                                              args.epochs, threads=1)
        if torch.cuda.is_available():
            training['per_gpu'] = train_throughput(default, tmp / 'gpu', 1, 'cuda',
                                                   args.epochs)
        two = training['2_cpu_processes']['samples_per_s']
        ratio = two / training['1_cpu_processes']['samples_per_s']
        # Against the faster single process too: a small LSTM can run slower on 2 threads.
        best_one = max(training[k]['samples_per_s']
                       for k in ('1_cpu_processes', '1_cpu_process_1_thread'))
        memory = {'default': peak_memory(default, tmp / 'm1'),
                  f'{SCALE}x': peak_memory(large, tmp / 'm10')}
        mem_ratio = memory[f'{SCALE}x']['peak_rss_mb'] / memory['default']['peak_rss_mb']
        bags = copied_bags(tmp / 'bags', args.bags, args.bag_minutes, args.bag_rate)
        convert = {f'{n}_workers': convert_throughput(bags, n) for n in (1, 2)}
        speedup = (convert['2_workers']['messages_per_s']
                   / convert['1_workers']['messages_per_s'])
    return {
        'suite': 'scale',
        'machine': {'cpus': os.cpu_count(), 'gpus': torch.cuda.device_count()},
        'training_throughput': {**training, 'ratio_2_to_1': ratio,
                                'ratio_2_to_fastest_1': two / best_one},
        'training_peak_memory': {**memory, 'ratio': mem_ratio},
        'conversion': {**convert, 'speedup_2_to_1': speedup},
        'goals': {'memory_ratio_max': GOAL_MEMORY_RATIO,
                  'memory_met': mem_ratio <= GOAL_MEMORY_RATIO,
                  'conversion_speedup_min': GOAL_CONVERT_SPEEDUP,
                  'conversion_met': speedup >= GOAL_CONVERT_SPEEDUP},
    }


def scaled_dataset(source: Path, out: Path, factor: int) -> Path:
    """Write every run of ``source`` ``factor`` times with fresh measurement noise."""
    ds = read_dataset(source)
    rng = np.random.default_rng(0)
    runs, split = {}, {name: [] for name in ('train', 'val', 'test')}
    states = list(TOY_VESSEL.state_names)
    for entry in ds.manifest['runs']:
        table = ds.load(entry['id'])
        scale = table[states].std().to_numpy()
        for k in range(factor):
            copy = table.copy()
            copy[states] = copy[states] + NOISE * scale * rng.standard_normal(
                (len(copy), len(states)))
            run_id = f"{entry['id']}_{k:02d}"
            runs[run_id] = copy
            split[entry['split']].append(run_id)
    write_dataset(out, runs, vessel=TOY_VESSEL, split=split,
                  provenance={'tool': 'offline/benchmarks/scale.py', 'from': str(source),
                              'factor': factor})
    return out


def copied_bags(folder: Path, count: int, minutes: float, rate_hz: float) -> list[Path]:
    """Write one recording of ``minutes`` at ``rate_hz`` and ``count - 1`` copies of it."""
    first = synthetic.write_bag(folder / 'bag0', synthetic.demo_trajectory(
        int(round(minutes * 60 * rate_hz)), rate_hz=rate_hz))
    return [first] + [Path(shutil.copytree(first, folder / f'bag{i}'))
                      for i in range(1, count)]


def phases(epochs: int) -> list[str]:
    """``--set`` values: both phases of the smoke config, ``epochs`` each, no early stop."""
    return [f'training.phases=[{{kind: teacher, max_epochs: {epochs}, patience: {epochs}, '
            f'lr: 0.005}}, {{kind: multistep, max_epochs: {epochs}, patience: {epochs}, '
            f'lr: 0.003}}]', 'training.progress=false']


def samples_per_epoch(dataset: Path, window: int) -> int:
    """Predicted samples in one epoch: every training sample after the window."""
    ds = read_dataset(dataset)
    return sum(max(0, r['n_samples'] - window) for r in ds.manifest['runs']
               if r['split'] == 'train')


def train_command(dataset: Path, out: Path, processes: int, device: str, epochs: int = 1,
                  threads: int = 1) -> list[str]:
    """Command line of one smoke training (torchrun for several processes)."""
    settings = [*phases(epochs), f'training.threads={threads}']
    tail = [str(TRAIN), str(SMOKE), '--dataset', str(dataset), '--out', str(out), '--quiet',
            '--device', device, *sum([['--set', s] for s in settings], [])]
    if processes == 1:
        return [sys.executable, *tail]
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        port = s.getsockname()[1]
    torchrun = Path(sys.executable).parent / 'torchrun'
    return [str(torchrun), f'--nproc_per_node={processes}', '--nnodes=1',
            '--master_addr=127.0.0.1', f'--master_port={port}', *tail]


def train_throughput(dataset: Path, out: Path, processes: int, device: str, epochs: int,
                     threads: int | None = None) -> dict:
    """Train, then read the fit loop's epoch times from the log (threads: cores / N)."""
    threads = threads or max(1, CPUS // processes)
    env = {**os.environ, 'GLOO_SOCKET_IFNAME': 'lo', 'OMP_NUM_THREADS': str(threads)}
    start = time.perf_counter()
    subprocess.run(train_command(dataset, out, processes, device, epochs, threads),
                   check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    epochs = trained_epochs((out / 'log.jsonl').read_text())
    seconds = sum(r['seconds'] for r in epochs)
    samples = samples_per_epoch(dataset, 20) * len(epochs)
    return {'processes': processes, 'threads_each': threads, 'device': device,
            'epochs': len(epochs), 'fit_seconds': seconds,
            'startup_and_rest_seconds': wall - seconds, 'samples_per_s': samples / seconds}


def trained_epochs(log_text: str) -> list[dict]:
    """
    Return the epochs of a training's log.jsonl that trained (each with its ``seconds``).

    The log's first line scores the physics alone before any training (phase kind
    ``reference``) and has no time of its own.
    """
    lines = [json.loads(line) for line in log_text.splitlines() if line.strip()]
    return [r for r in lines if r.get('phase_kind') != 'reference']


def peak_memory(dataset: Path, out: Path) -> dict:
    """Largest resident set of one whole training process on ``dataset``."""
    cmd = [sys.executable, '-c', PEAK_RSS, *train_command(dataset, out, 1, 'cpu')]
    code, kb = subprocess.run(cmd, capture_output=True, text=True, check=True,
                              env={**os.environ, 'OMP_NUM_THREADS': '1'}).stdout.split()
    if code != '0':
        raise RuntimeError(f'training on {dataset} failed (exit {code})')
    ds = read_dataset(dataset)
    return {'runs': len(ds.manifest['runs']),
            'samples': sum(r['n_samples'] for r in ds.manifest['runs']),
            'bytes_on_disk': sum((ds.root / r['file']).stat().st_size
                                 for r in ds.manifest['runs']),
            'peak_rss_mb': int(kb) / 1024}


def convert_throughput(bags: list[Path], workers: int) -> dict:
    """Convert every bag with ``workers`` processes (results kept in memory, not written)."""
    topic_map = topic_map_for(load_vessel(synthetic.SIM_VESSEL))
    opts = Options.from_yaml()
    start = time.perf_counter()
    results = convert_all(bags, BagRecordings(), topic_map, opts, jobs=workers)
    seconds = time.perf_counter() - start
    messages = sum(r.report['read'][0] for r in results)
    return {'workers': workers, 'bags': len(bags), 'messages': messages, 'seconds': seconds,
            'messages_per_s': messages / seconds}

