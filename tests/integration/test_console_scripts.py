"""Every offline/*.py entry point is also an installed program: `ros2 run PACKAGE NAME`."""

from pathlib import Path
import subprocess

import pytest

from .conftest import installed_executable

REPO = Path(__file__).resolve().parents[2]

# offline/NAME.py -> the package whose console script NAME it runs.
PROGRAMS = {
    'train': 'hybrid_models',
    'evaluate': 'hybrid_models',
    'reproduce_table2': 'hybrid_models',
    'compare_physics': 'hybrid_models',
    'set_threshold': 'hybrid_models',
    'set_bands': 'hybrid_models',
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


@pytest.fixture(scope='module')
def helps():
    """Start every program's --help at once (each imports its stack: seconds apiece)."""
    started = {name: subprocess.Popen([str(installed_executable(package, name)), '--help'],
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                      text=True)
               for name, package in PROGRAMS.items()}
    yield started
    for popen in started.values():
        popen.kill()
        popen.communicate()


@pytest.mark.parametrize('name', sorted(PROGRAMS))
def test_installed_program_answers_help(helps, name):
    assert (REPO / 'offline' / f'{name}.py').is_file()
    out, err = helps[name].communicate(timeout=240)
    assert helps[name].returncode == 0, err[-2000:]
    assert out.startswith('usage:')


def test_every_thin_entry_point_is_listed():
    # An offline tool that imports a package's main is a program of that package.
    thin = {p.stem for p in (REPO / 'offline').glob('*.py') if 'import main' in p.read_text()}
    assert thin <= set(PROGRAMS)
