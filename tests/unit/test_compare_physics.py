"""offline/simulate_scenario.py and the compare_physics program end to end on tiny data."""

import json
import os
from pathlib import Path
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from hybrid_models.cli import compare_physics

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'


def run(script, *args):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    return subprocess.run([sys.executable, str(ROOT / 'offline' / script), *map(str, args)],
                          capture_output=True, text=True, env=env, timeout=600)


def compare(capsys, *args):
    """Run compare_physics in this process; return its exit code and output as run() does."""
    try:
        code = compare_physics.main([str(a) for a in args])
    except SystemExit as exc:  # argparse's usage errors
        code = exc.code
    out, err = capsys.readouterr()
    return SimpleNamespace(returncode=code, stdout=out, stderr=err)


@pytest.fixture(scope='module')
def fouled(tmp_path_factory):
    """Simulate a fouled hull; write its nominal physics and a resistance correction."""
    out = tmp_path_factory.mktemp('fouling')
    result = run('simulate_scenario.py', '--scenario', 'fouling', '--runs', 5, '--hours',
                 0.1, '--seed', 2, '--out', out / 'data')
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)['nominal_physics'] == str(out / 'data' /
                                                              'nominal_physics.yaml')
    nominal = yaml.safe_load((out / 'data' / 'nominal_physics.yaml').read_text())
    # What the diagnosis finds for this effect (docs/diagnosis.md): more surge resistance.
    augmented = dict(nominal, extra_terms=[
        {'term': 'surge_linear', 'dofs': 'X', 'coefficient': -900.0}])
    (out / 'augmented.yaml').write_text(yaml.safe_dump(augmented))
    return out


@pytest.mark.slow   # two hybrids trained on a simulated fouling campaign (about a minute)
def test_the_same_hybrid_on_better_physics(fouled, capsys):
    out = fouled / 'results'
    result = compare(capsys, '--dataset', fouled / 'data', '--physics',
                     f'nominal={fouled / "data" / "nominal_physics.yaml"}',
                     f'augmented={fouled / "augmented.yaml"}', '--out', out, '--config',
                     SMOKE, '--window', 20, '--horizon', 60, '--stride', 60, '--thresholds',
                     0.05, 0.5)
    assert result.returncode == 0, result.stderr[-3000:]
    assert 'augmented: threshold for the nominal accuracy' in result.stdout
    res = json.loads((out / 'results.json').read_text())
    models = res['evaluation']['models']
    assert set(models) == {'nominal', 'augmented'} and res['reference'] == 'nominal'
    for sweep in (m['sweep'] for m in models.values()):
        assert [r['relative_threshold'] for r in sweep] == [0.0, None, 0.05, 0.5]
    # Threshold 0 is the physics alone; the resistance correction makes it more accurate.
    physics_only = {label: m['sweep'][0] for label, m in models.items()}
    assert (physics_only['augmented']['trajectory']['mean']
            < physics_only['nominal']['trajectory']['mean'])
    assert physics_only['augmented']['rmse']['u'] < physics_only['nominal']['rmse']['u']
    need = res['needed_thresholds']
    for label in models:
        assert set(need[label]) == {'for_reference_accuracy', 'for_own_unconstrained_accuracy',
                                    'for_reference_per_state', 'for_reference_trajectory'}
        assert set(need[label]['for_reference_per_state']) == {'u', 'v', 'p', 'r', 'phi'}
        assert need[label]['for_own_unconstrained_accuracy'] in (0.0, 0.05, 0.5, None)
    # The checkpoints carry their physics: the augmented one has the extra term inline.
    stored = yaml.safe_load((out / 'runs' / 'augmented' / 'config.yaml').read_text())
    assert stored['model']['physical']['kind'] == 'physics'
    report = (out / 'report.md').read_text()
    assert '| augmented | `augmented.yaml` |' in report
    assert '| physics | u | v | p | r | phi | trajectory |' in report
    assert (out / 'threshold_comparison.png').stat().st_size > 10_000
    assert np.isfinite(models['augmented']['output_range']).all()


@pytest.mark.parametrize('args, code, words', [
    (['--physics', 'a=missing.yaml', 'b=missing.yaml'], 1, "missing.yaml': no such file"),
    (['--physics', 'only=x.yaml'], 2, 'at least two physics'),
    (['--physics', 'noequals', 'b=x.yaml'], 2, 'LABEL=FILE'),
])
def test_bad_input_is_one_clear_line(tmp_path, capsys, args, code, words):
    result = compare(capsys, '--dataset', tmp_path, '--out', tmp_path / 'o', *args)
    assert result.returncode == code
    assert words in result.stderr
    assert 'Traceback' not in result.stderr


def test_unknown_scenario_is_refused(tmp_path):
    result = run('simulate_scenario.py', '--scenario', 'kraken', '--out', tmp_path / 'x')
    assert result.returncode == 1
    assert "unknown scenario 'kraken'" in result.stderr and 'fouling' in result.stderr


def test_a_shipped_vessel_given_by_its_file_has_its_scenarios(tmp_path, capsys):
    """--vessel PATH of a shipped vessel's file is that vessel (it said 'no scenarios')."""
    import yaml

    from vessel_description.vessel import vessels_dir
    from vessel_diagnosis.cli_scenario import main as simulate_scenario

    path = vessels_dir() / 'otter.yaml'
    code = simulate_scenario(['--vessel', str(path), '--scenario', 'kraken', '--out',
                              str(tmp_path / 'x')])
    said = capsys.readouterr().err
    assert code == 1 and "unknown scenario 'kraken' of vessel otter" in said
    # A file that only shares the name describes another vessel: refused, in one line.
    data = yaml.safe_load(path.read_text())
    data['rate_hz'] = 5.0
    (tmp_path / 'otter.yaml').write_text(yaml.safe_dump(data))
    code = simulate_scenario(['--vessel', str(tmp_path / 'otter.yaml'), '--scenario',
                              'weak_thruster', '--out', str(tmp_path / 'y')])
    said = capsys.readouterr().err
    assert code == 1 and 'differs from the shipped vessel' in said and said.count('\n') == 1


def test_results_name_the_repositorys_physics_files_relative_to_it(tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)
    _, inside = compare_physics.labelled_physics(f'nominal={SMOKE}')
    assert compare_physics._shown(inside) == str(SMOKE.relative_to(ROOT))
    _, outside = compare_physics.labelled_physics(f'mine={tmp_path / "p.yaml"}')
    assert compare_physics._shown(outside) == str((tmp_path / 'p.yaml').resolve())
