"""Every offline/*.py entry point is also an installed program: `ros2 run PACKAGE NAME`."""

import json
from pathlib import Path
import subprocess
import sys

import pytest

from .conftest import installed_executable

REPO = Path(__file__).resolve().parents[2]

# offline/NAME.py -> the package whose console script NAME it runs.
PROGRAMS = {
    'train': 'hybrid_models',
    'evaluate': 'hybrid_models',
    'reproduce_table2': 'hybrid_models',
    'reproduce_table3': 'hybrid_models',
    'peer_benchmark': 'hybrid_models',
    'compare_physics': 'hybrid_models',
    'set_threshold': 'hybrid_models',
    'set_bands': 'hybrid_models',
    'set_novelty': 'hybrid_models',
    'model_card': 'hybrid_models',
    'crossval': 'hybrid_models',
    'ensemble': 'hybrid_models',
    'simulate': 'vessel_datasets',
    'bag_to_dataset': 'vessel_datasets',
    'table_to_dataset': 'vessel_datasets',
    'log_to_dataset': 'vessel_datasets',
    'scale_physics': 'vessel_physics',
    'diagnose': 'vessel_diagnosis',
    'simulate_scenario': 'vessel_diagnosis',
    'workflow': 'vessel_diagnosis',
    'record': 'vessel_recorder',
    'demo': 'vessel_bringup',
    're_forecast': 'hybrid_predictor',
}

# Runs each installed script file as __main__ with --help, in one interpreter: twenty
# interpreters would import torch twenty times (a minute of CPU) to print twenty usages.
RUN_EACH_HELP = """
import contextlib, io, json, runpy, sys
answers = {}
for name, path in json.loads(sys.argv[1]).items():
    out, err, code = io.StringIO(), io.StringIO(), 0
    sys.argv = [path, '--help']
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            runpy.run_path(path, run_name='__main__')
        except SystemExit as stop:
            code = stop.code
        except Exception as error:  # one broken program must not hide the others
            code = repr(error)
    answers[name] = {'code': code, 'out': out.getvalue(), 'err': err.getvalue()[-2000:]}
print(json.dumps(answers))
"""


@pytest.fixture(scope='module')
def helps():
    """Return every installed program's --help answer: {name: {code, out, err}}."""
    paths = {name: str(installed_executable(package, name))
             for name, package in PROGRAMS.items()}
    done = subprocess.run([sys.executable, '-c', RUN_EACH_HELP, json.dumps(paths)],
                          capture_output=True, text=True, timeout=240, check=True)
    return json.loads(done.stdout.splitlines()[-1])


@pytest.mark.parametrize('name', sorted(PROGRAMS))
def test_installed_program_answers_help(helps, name):
    assert (REPO / 'offline' / f'{name}.py').is_file()
    script = installed_executable(PROGRAMS[name], name)
    interpreter = script.read_text().splitlines()[0].removeprefix('#!')
    assert Path(interpreter).is_file(), f'{script} starts {interpreter}, which is missing'
    answer = helps[name]
    assert answer['code'] in (0, None), answer['err']
    assert answer['out'].startswith('usage:')


def test_an_installed_program_runs_as_its_own_process():
    # The scripts above ran inside one interpreter; this one is started as ros2 run does.
    script = installed_executable('hybrid_predictor', 're_forecast')
    done = subprocess.run([str(script), '--help'], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith('usage:')


def test_every_thin_entry_point_is_listed():
    # An offline tool that imports a package's main is a program of that package.
    thin = {p.stem for p in (REPO / 'offline').glob('*.py') if 'import main' in p.read_text()}
    assert thin <= set(PROGRAMS)
