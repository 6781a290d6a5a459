"""
docker/: what the image copies exists and every command it runs is in the workspace.

No Docker engine runs here, so the image is not built; these checks catch the ways the
files drift from the workspace: a renamed executable, a dropped parameter, a moved file.
"""

from pathlib import Path
import re
import shlex

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
DOCKER = REPO / 'docker'
INSTALL = REPO / 'ros2_ws' / 'install'
SRC = REPO / 'ros2_ws' / 'src'


def dockerfile_instructions():
    text = (DOCKER / 'Dockerfile').read_text().replace('\\\n', ' ')
    return [line.strip() for line in text.splitlines()
            if line.strip() and not line.strip().startswith('#')]


def compose_commands():
    services = yaml.safe_load((DOCKER / 'compose.yaml').read_text())['services']
    return {name: service['command'] for name, service in services.items()}


def test_the_image_builds_on_the_official_ros_2_jazzy_image():
    lines = dockerfile_instructions()
    assert 'ARG ROS_DISTRO=jazzy' in lines
    assert any(re.fullmatch(r'FROM ros:\$\{ROS_DISTRO\}-ros-base', line) for line in lines)


def test_everything_the_dockerfile_copies_exists():
    copies = [line.split()[1:-1] for line in dockerfile_instructions() if line.startswith('COPY')]
    assert copies
    for sources in copies:
        for source in sources:
            assert (REPO / source).exists(), f'Dockerfile copies missing {source}'
    entrypoint = DOCKER / 'entrypoint.sh'
    assert entrypoint.stat().st_mode & 0o111, 'entrypoint.sh must be executable'


def test_docker_pins_the_same_torch_as_the_project():
    pins = {line.split('==')[0]: line for line in
            (REPO / 'requirements' / 'docker.txt').read_text().splitlines() if '==' in line}
    assert pins['torch'] == (REPO / 'requirements' / 'torch.txt').read_text().split()[-1]


def declared_executables(package):
    text = (SRC / package / 'setup.py').read_text()
    return set(re.findall(r"'(\w+) = [\w.]+:\w+'", text))


def declared_parameters(package, spec):
    return set(yaml.safe_load((SRC / package / 'config' / spec).read_text()))


SPECS = {'ship_sim_node': 'simulator.yaml', 'hybrid_predictor': 'predictor.yaml'}


@pytest.mark.parametrize('service', ['simulator', 'predictor'])
def test_compose_runs_installed_executables_with_declared_parameters(service):
    command = compose_commands()[service]
    argv = command if isinstance(command, list) else shlex.split(command)
    assert argv[:2] == ['ros2', 'run'], argv
    package, executable = argv[2], argv[3]
    assert executable in declared_executables(package)
    installed = INSTALL / package / 'lib' / package / executable
    assert installed.is_file(), f'{installed}: build the workspace first'
    params = {argv[i + 1].split(':=')[0] for i, a in enumerate(argv) if a == '-p'}
    unknown = params - declared_parameters(package, SPECS[package]) - {'use_sim_time'}
    assert not unknown, f'{service} passes undeclared parameters {unknown}'


def test_dockerfile_default_command_is_the_predictor():
    cmd = next(line for line in dockerfile_instructions() if line.startswith('CMD'))
    assert '"ros2", "run", "hybrid_predictor", "predictor"' in cmd
