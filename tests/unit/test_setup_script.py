"""tools/setup.sh: each bad situation ends in one clear line, a broken venv is repaired."""

import os
from pathlib import Path
import subprocess
import sys

import pytest

REPO = Path(__file__).resolve().parents[2]
SETUP = REPO / 'tools' / 'setup.sh'


def run_setup(stage, env_overrides, timeout=240):
    env = {k: v for k, v in os.environ.items() if not k.startswith(('PIP_', 'VIRTUAL_ENV'))}
    env.update(env_overrides)
    return subprocess.run(['bash', str(SETUP), stage], capture_output=True, text=True,
                          env=env, timeout=timeout)


def error_lines(stderr):
    return [line for line in stderr.splitlines() if line.startswith('setup: error:')]


def test_wrong_python_version_is_one_clear_line(tmp_path):
    fake = tmp_path / 'python3.9'
    fake.write_text('#!/bin/sh\necho "3.9"\n')
    fake.chmod(0o755)
    result = run_setup('python', {'PYTHON': str(fake), 'VENV': str(tmp_path / 'venv')})
    assert result.returncode != 0
    lines = error_lines(result.stderr)
    assert len(lines) == 1, result.stderr
    assert 'Python 3.11 is required' in lines[0] and str(fake) in lines[0]


def test_broken_half_made_venv_is_repaired_not_fatal(tmp_path):
    venv = tmp_path / 'venv'
    (venv / 'bin').mkdir(parents=True)
    (venv / 'pyvenv.cfg').write_text('home = /nowhere\n')
    (venv / 'bin' / 'python').write_text('#!/bin/sh\nexit 127\n')
    (venv / 'bin' / 'python').chmod(0o755)
    result = run_setup('venv', {'PYTHON': sys.executable if sys.version_info[:2] == (3, 11)
                                else 'python3.11', 'VENV': str(venv)})
    assert result.returncode == 0, result.stderr
    assert 'repairing' in result.stderr and 'does not run' in result.stderr
    check = subprocess.run([str(venv / 'bin' / 'python'), '-m', 'pip', '--version'],
                           capture_output=True, text=True)
    assert check.returncode == 0


def test_no_network_to_the_registry_is_one_clear_line(tmp_path):
    # Port 9 (discard) on loopback refuses connections: a registry that cannot be reached.
    result = run_setup('deps', {'VENV': str(tmp_path / 'venv'),
                                'PIP_CONFIG_FILE': os.devnull,
                                'PIP_INDEX_URL': 'http://127.0.0.1:9/simple',
                                'PIP_FIND_LINKS': ''})
    assert result.returncode != 0
    lines = error_lines(result.stderr)
    assert len(lines) == 1, result.stderr
    assert 'no network to the package registry' in lines[0]
    assert '127.0.0.1:9' in lines[0]


@pytest.mark.parametrize('stage', ['bogus'])
def test_unknown_stage_is_rejected(stage):
    result = run_setup(stage, {})
    assert result.returncode != 0 and 'unknown stage' in error_lines(result.stderr)[0]


def test_the_gpu_stage_without_an_nvidia_gpu_is_one_clear_line_and_installs_nothing(tmp_path):
    fake = tmp_path / 'nvidia-smi'      # the driver's tool, finding no GPU
    fake.write_text('#!/bin/sh\necho "No devices were found"\nexit 6\n')
    fake.chmod(0o755)
    venv = tmp_path / 'venv'
    result = run_setup('gpu', {'PATH': f'{tmp_path}:{os.environ["PATH"]}', 'VENV': str(venv)})
    assert result.returncode != 0
    assert error_lines(result.stderr) == ['setup: error: no NVIDIA GPU here (nvidia-smi lists '
                                          'none): the forecasts run on the CPU'], result.stderr
    assert not venv.exists()


def test_two_stages_run_at_once_and_either_ones_failure_fails_the_pair(tmp_path):
    # `make test`'s set-up builds the workspace and the test-only tools at the same time.
    marks = tmp_path / 'marks'
    script = f"""
        source {SETUP}
        slow_ok() {{ echo start-ok >>{marks}; sleep 1; echo end-ok >>{marks}; }}
        slow_fail() {{ echo start-fail >>{marks}; sleep 1; echo end-fail >>{marks}; return 3; }}
        both slow_ok slow_ok && echo pair-ok
        both slow_ok slow_fail || echo pair-failed-$?
        both slow_fail slow_ok || echo pair-failed-$?
    """
    result = subprocess.run(['bash', '-c', script], capture_output=True, text=True,
                            timeout=60)
    assert result.stdout.split() == ['pair-ok', 'pair-failed-3', 'pair-failed-3']
    events = marks.read_text().split()
    # Each pair's two stages started before either ended.
    for pair in range(3):
        assert all(e.startswith('start') for e in events[4 * pair:4 * pair + 2]), events


def test_a_stage_is_remade_when_its_own_code_changes_and_not_for_anothers():
    # Stamped with the whole script, an edit to the build reinstalled every environment.
    script = f"""
        source {SETUP}
        before="$(bench_hash) $(rostools_hash)"
        eval "$(declare -f stage_build | sed 's/colcon build/colcon build --symlink-install/')"
        echo "$before" "$(bench_hash) $(rostools_hash)"
        eval "$(declare -f stage_bench | sed 's/about a minute/about two minutes/')"
        echo "$(bench_hash) $(rostools_hash)"
    """
    result = subprocess.run(['bash', '-c', script], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 0, result.stderr
    (bench, rostools, bench_after_build, rostools_after_build), (bench_edited, rostools_kept) = (
        line.split() for line in result.stdout.splitlines())
    assert (bench_after_build, rostools_after_build) == (bench, rostools)
    assert bench_edited != bench and rostools_kept == rostools


def test_help_is_the_header_comment_and_nothing_after_it():
    result = run_setup('--help', {})
    assert result.returncode == 0
    lines = result.stdout.splitlines()
    assert lines[0].startswith('Idempotent set-up')
    assert lines[-1] == 'Each failure ends with one line starting "setup: error:".'
    stages = 'all|python|venv|deps|fixups|build|rostools|test|bench|gpu|lock'
    assert f'Usage: tools/setup.sh [{stages}]' in lines
