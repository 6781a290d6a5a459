"""
Scaling out, measured in one run: training processes, training memory, conversion workers.

- Training throughput (predicted samples per second of wall time in the fit loop) of
  the smoke config on 1 and on 2 CPU processes (torchrun, gloo, one thread each), and
  per GPU when one is present.
- Peak resident memory of a whole training (smoke config, one epoch a phase) on the
  default generated dataset and on one 10 times larger (the same runs ten times, with
  fresh measurement noise; written under the temporary directory, never kept).
- Bag-conversion throughput (messages per second) of a folder of bags with 1 and 2
  worker processes.

Goals: peak memory on the 10x dataset <= 1.5 x that on the default one; 2 conversion
workers >= 1.6 x as fast as 1.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import socket
import subprocess
import sys
import tempfile
import time

import numpy as np
import torch

from hybrid_models.toy import TOY_VESSEL, write_toy_dataset
from vessel_datasets import synthetic
from vessel_datasets.convert import Options, convert_bags
from vessel_datasets.format import read_dataset, write_dataset
from vessel_datasets.topic_map import topic_map_for
from vessel_description import load_vessel

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'
TRAIN = ROOT / 'offline' / 'train.py'
GOAL_MEMORY_RATIO = 1.5
GOAL_CONVERT_SPEEDUP = 1.6
SCALE = 10
NOISE = 0.01  # relative measurement noise that makes the copies of the 10x dataset differ
ONE_EPOCH_EACH = ['training.phases=[{kind: teacher, max_epochs: 1, patience: 1, lr: 0.005},'
                  ' {kind: multistep, max_epochs: 1, patience: 1, lr: 0.003}]',
                  'training.progress=false']
# Prints the largest resident set of the command it runs (kB): a fresh process per
# measurement, since RUSAGE_CHILDREN keeps the maximum over all children ever waited for.
PEAK_RSS = ('import resource, subprocess, sys; done = subprocess.run(sys.argv[1:], '
            'stdout=subprocess.DEVNULL); print(done.returncode, '
            'resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)')


def add_arguments(parser) -> None:
    """Command-line options of this suite."""
    parser.add_argument('--runs', type=int, default=8,
                        help='runs of the default generated dataset (default 8)')
    parser.add_argument('--samples', type=int, default=1800,
                        help='samples per run of the default dataset (default 1800, 1 Hz)')
    parser.add_argument('--bags', type=int, default=4, help='bags to convert (default 4)')
    parser.add_argument('--bag-hours', type=float, default=2.0,
                        help='length of each bag (default 2 h at 1 Hz)')


def run(args) -> dict:
    """Generate the data, measure the three figures, return them with the goals."""
    with tempfile.TemporaryDirectory(prefix='bench_scale_') as tmp:
        tmp = Path(tmp)
        default = write_toy_dataset(tmp / 'default', n_runs=args.runs,
                                    n_samples=args.samples)
        large = scaled_dataset(default, tmp / 'large', SCALE)
        training = {f'{n}_cpu_processes': train_throughput(default, tmp / f'tp{n}', n, 'cpu')
                    for n in (1, 2)}
        if torch.cuda.is_available():
            training['per_gpu'] = train_throughput(default, tmp / 'gpu', 1, 'cuda')
        ratio = (training['2_cpu_processes']['samples_per_s']
                 / training['1_cpu_processes']['samples_per_s'])
        memory = {'default': peak_memory(default, tmp / 'm1'),
                  f'{SCALE}x': peak_memory(large, tmp / 'm10')}
        mem_ratio = memory[f'{SCALE}x']['peak_rss_mb'] / memory['default']['peak_rss_mb']
        bags = [synthetic.write_bag(tmp / f'bag{i}', synthetic.demo_trajectory(
            int(args.bag_hours * 3600), seed=i)) for i in range(args.bags)]
        convert = {f'{n}_workers': convert_throughput(bags, n) for n in (1, 2)}
        speedup = (convert['2_workers']['messages_per_s']
                   / convert['1_workers']['messages_per_s'])
    return {
        'suite': 'scale',
        'machine': {'cpus': os.cpu_count(), 'gpus': torch.cuda.device_count()},
        'training_throughput': {**training, 'ratio_2_to_1': ratio},
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


def samples_per_epoch(dataset: Path, window: int) -> int:
    """Predicted samples in one epoch: every training sample after the window."""
    ds = read_dataset(dataset)
    return sum(max(0, r['n_samples'] - window) for r in ds.manifest['runs']
               if r['split'] == 'train')


def train_command(dataset: Path, out: Path, processes: int, device: str) -> list[str]:
    """Command line of one smoke training (torchrun for several processes)."""
    tail = [str(TRAIN), str(SMOKE), '--dataset', str(dataset), '--out', str(out), '--quiet',
            '--device', device, *sum([['--set', s] for s in ONE_EPOCH_EACH], [])]
    if processes == 1:
        return [sys.executable, *tail]
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        port = s.getsockname()[1]
    torchrun = Path(sys.executable).parent / 'torchrun'
    return [str(torchrun), f'--nproc_per_node={processes}', '--nnodes=1',
            '--master_addr=127.0.0.1', f'--master_port={port}', *tail]


def train_throughput(dataset: Path, out: Path, processes: int, device: str) -> dict:
    """Train, then read the fit loop's own epoch times from the log."""
    env = {**os.environ, 'GLOO_SOCKET_IFNAME': 'lo', 'OMP_NUM_THREADS': '1'}
    start = time.perf_counter()
    subprocess.run(train_command(dataset, out, processes, device), check=True, env=env,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    log = [json.loads(line) for line in (out / 'log.jsonl').read_text().splitlines()]
    seconds = sum(r['seconds'] for r in log)
    samples = samples_per_epoch(dataset, 20) * len(log)
    return {'processes': processes, 'device': device, 'epochs': len(log),
            'fit_seconds': seconds, 'wall_seconds_with_startup': wall,
            'samples_per_s': samples / seconds}


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
    results = convert_bags(bags, topic_map, opts, jobs=workers)
    seconds = time.perf_counter() - start
    messages = sum(r.report['messages_read'] for r in results)
    return {'workers': workers, 'bags': len(bags), 'messages': messages, 'seconds': seconds,
            'messages_per_s': messages / seconds}

