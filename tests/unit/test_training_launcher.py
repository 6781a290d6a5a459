"""A tool's trainings forked from its launcher: the same models, their own logs, no orphans."""

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from safetensors.numpy import load_file

from hybrid_models.training import load_config, train
from hybrid_models.training.jobs import launcher, train_job
from offline.benchmarks.toy import write_toy_dataset
from tests.processes import gone_within

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'
SHORT = ['training.progress=false', 'training.phases=[{kind: teacher, max_epochs: 2, '
         'patience: 2, lr: 0.005}, {kind: multistep, max_epochs: 1, patience: 1, lr: 0.003}]']


def test_a_launched_training_is_the_training_of_one_process_and_reports_its_failure(tmp_path):
    toy = write_toy_dataset(tmp_path / 'toy', n_runs=4, n_samples=200)
    overrides = [f'dataset={toy}', 'training.seed=3', *SHORT]
    results = [train_job(f'run{i}', SMOKE, overrides, tmp_path / f'run{i}') for i in (0, 1)]
    assert [r['status'] for r in results] == ['ok', 'ok']
    assert launcher().alive()   # one launcher served both
    train(load_config(SMOKE, overrides), tmp_path / 'here')
    here = load_file(str(tmp_path / 'here' / 'model.safetensors'))
    for i in (0, 1):
        launched = load_file(str(tmp_path / f'run{i}' / 'model.safetensors'))
        assert launched.keys() == here.keys()
        assert all((launched[k] == here[k]).all() for k in here)
        log = (tmp_path / f'run{i}' / 'train.log').read_text()
        assert '"stop_reason": "all phases done"' in log
    # A training that fails says so, and its reason is in its log; the launcher carries on.
    bad = train_job('bad', SMOKE, [f'dataset={toy}', 'training.no_such_key=1'], tmp_path / 'bad')
    assert bad['status'].startswith('failed (exit 2, see ')
    assert 'no_such_key' in (tmp_path / 'bad' / 'train.log').read_text()
    assert train_job('again', SMOKE, overrides, tmp_path / 'again')['status'] == 'ok'


def test_a_training_ends_with_the_tool_that_started_it(tmp_path):
    toy = write_toy_dataset(tmp_path / 'toy', n_runs=4, n_samples=200)
    log = tmp_path / 'run' / 'train.log'
    log.parent.mkdir()
    argv = [str(SMOKE), '--out', str(log.parent), '--set', f'dataset={toy}', '--set',
            'training.phases=[{kind: teacher, max_epochs: 100000, patience: 100000, '
            'lr: 0.005}]']
    # A stand-in tool starts an endless training through its launcher, then is killed.
    tool = subprocess.Popen([sys.executable, '-c', (
        'from hybrid_models.training.jobs import launcher\n'
        'starter = launcher()\n'
        f'pid, ended = starter.start({argv!r}, {str(log)!r})\n'
        'print(starter.proc.pid, pid, flush=True)\n'
        'ended.result()\n')], stdout=subprocess.PIPE, text=True)
    pids = dict(zip(('launcher', 'training'), map(int, tool.stdout.readline().split()),
                    strict=True))
    deadline = time.monotonic() + 60
    while 'epoch' not in (log.read_text() if log.exists() else ''):   # under way
        assert time.monotonic() < deadline and tool.poll() is None, 'the training never started'
        time.sleep(0.05)
    tool.send_signal(signal.SIGKILL)
    tool.wait()
    # A process that died but was not yet reaped by init counts as gone.
    for what, pid in pids.items():
        if not gone_within(pid, 10):
            os.kill(pid, signal.SIGKILL)
            raise AssertionError(f'the {what} outlived the tool that started it')


def test_a_launcher_first_used_by_a_pool_worker_outlives_the_pool(tmp_path):
    """The kernel's parent-death signal follows the forking thread: issue 50's table 2 smoke."""
    toy = write_toy_dataset(tmp_path / 'toy', n_runs=4, n_samples=200)
    overrides = [f'dataset={toy}', *SHORT]
    # A fresh tool process: its first training starts the launcher from a pool worker,
    # the next one comes after the pool is gone (as reproduce_table2's bound variant).
    script = (
        'import sys\n'
        'from concurrent.futures import ThreadPoolExecutor\n'
        'from pathlib import Path\n'
        'from hybrid_models.training.jobs import train_job\n'
        f'smoke, out, overrides = {str(SMOKE)!r}, Path({str(tmp_path)!r}), {overrides!r}\n'
        'with ThreadPoolExecutor(1) as pool:\n'
        "    first = pool.submit(train_job, 'in_pool', smoke, overrides, out / 'a').result()\n"
        "after = train_job('after_pool', smoke, overrides, out / 'b')\n"
        "print(first['status'], '|', after['status'])\n")
    done = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == 'ok | ok', done.stdout
