"""
The suite as ROS users run it: `ros2 launch`, namespaces, `ros2 run`, and the ros2 CLI.

The `ros2` CLI and launch are the real jazzy sources installed by `tools/setup.sh
rostools` (test-only, tools/with_rostools.sh); each launch file is started with `ros2
launch` and what arrives over DDS is checked, in namespaces of the tests' own.
"""

from __future__ import annotations

import math
import subprocess

import pytest
import yaml

from .conftest import REPO, child_environment, spin_until

pytestmark = pytest.mark.ros

WITH_ROSTOOLS = REPO / 'tools' / 'with_rostools.sh'
ROSTOOLS_STAMP = REPO / '.venv-rostools' / '.rostools-hash'
CLI_TIMEOUT_S = 60.0      # one ros2 CLI call; it waits for discovery, slower under load
FORECAST_WAIT_S = 150.0   # the predictor compiles its model before the first forecast
FAST = '20.0'             # real-time factor: a 60 s window fills in 3 s
# No daemon (it would outlive the test); the CLI's own node waits this long (s) for
# discovery instead of the default half second, which misses nodes on a loaded machine.
DIRECT = ('--no-daemon', '--spin-time', '5.0')


@pytest.fixture
def ros2():
    """Run one `ros2 ...` command to its end; return the finished process."""
    if not ROSTOOLS_STAMP.is_file():
        pytest.fail('no ros2 CLI: run `tools/setup.sh rostools` (make test does)')

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([str(WITH_ROSTOOLS), 'ros2', *args], capture_output=True,
                              text=True, timeout=CLI_TIMEOUT_S, cwd=REPO,
                              env=child_environment())

    yield run
    # Verbs without --no-daemon (echo, service call) spawn the CLI's daemon, which
    # would outlive the test session.
    run('daemon', 'stop')


def said(result: subprocess.CompletedProcess) -> str:
    """Return what a CLI call printed, stdout then stderr."""
    return result.stdout + result.stderr


def ros2_launch(launcher, package: str, launch_file: str, *args: str, name: str):
    """Start `ros2 launch PACKAGE FILE ARGS`; it is stopped at teardown like a node."""
    return launcher.start([str(WITH_ROSTOOLS), 'ros2', 'launch', package, launch_file, *args],
                          name, supervisor=True)


def keep(node, msg_type, topic: str, depth: int = 50) -> list:
    """Subscribe and return the list the messages are appended to."""
    received = []
    node.create_subscription(msg_type, topic, received.append, depth)
    return received


def test_simulator_launch_moves_every_topic_and_frame_into_its_namespace(
        launcher, ros_node, ros2):
    from nav_msgs.msg import Odometry

    odom = keep(ros_node, Odometry, '/boat7/odom')
    ros2_launch(launcher, 'ship_sim_node', 'simulator.launch.py', 'namespace:=boat7',
                'frame_prefix:=boat7/', f'real_time_factor:={FAST}', name='sim_launch')
    assert spin_until(ros_node, lambda: len(odom) >= 3, 60), 'nothing on /boat7/odom'
    assert (odom[-1].header.frame_id, odom[-1].child_frame_id) == ('boat7/odom',
                                                                   'boat7/base_link')

    listed = ros2('topic', 'list', *DIRECT)
    assert listed.returncode == 0, listed.stderr
    topics = set(listed.stdout.split())
    assert {'/boat7/odom', '/boat7/actuators', '/boat7/wind', '/boat7/cmd'} <= topics
    assert not any(t.startswith('/vessel/') for t in topics), topics
    echo = ros2('topic', 'echo', '--once', '/boat7/wind', 'geometry_msgs/msg/Vector3Stamped')
    assert echo.returncode == 0, echo.stderr
    assert yaml.safe_load(echo.stdout.split('---')[0])['header']['frame_id'] == 'boat7/base_link'
    nodes = ros2('node', 'list', *DIRECT)
    assert '/boat7/simulator' in nodes.stdout.split(), nodes.stdout + nodes.stderr


@pytest.mark.slow   # a simulator and a launched predictor (about 20 s)
def test_predictor_launch_with_arguments_follows_a_simulator_moved_by_ros2_run(
        launcher, ros_node, ros2):
    from hybrid_predictor_interfaces.msg import Forecast

    forecasts = keep(ros_node, Forecast, '/p1/forecast', 10)
    executables = ros2('pkg', 'executables', 'hybrid_predictor')
    assert 'hybrid_predictor predictor' in executables.stdout, executables.stderr
    model = (REPO / 'ros2_ws' / 'install' / 'hybrid_predictor' / 'share' / 'hybrid_predictor'
             / 'models' / 'default' / 'model.safetensors')
    ros2_launch(launcher, 'hybrid_predictor', 'predictor.launch.py', 'namespace:=p1',
                'vessel:=patrol_boat', f'model_path:={model}', 'relative_threshold:=0.1',
                'frame_prefix:=p1/', 'use_sim_time:=true', name='predictor_launch')
    # A faster-than-real-time simulator's stamps run ahead of the wall clock, which the
    # predictor refuses as future samples: it follows the simulator's /clock instead.
    # `ros2 run` expects Ctrl-C on its whole process group, as the launcher sends it.
    launcher.start([str(WITH_ROSTOOLS), 'ros2', 'run', 'ship_sim_node', 'simulator',
                    '--ros-args', '-r', '__ns:=/p1', '-p', f'real_time_factor:={FAST}'],
                   'sim_run')
    assert spin_until(ros_node, lambda: forecasts, FORECAST_WAIT_S), 'no /p1/forecast'
    assert forecasts[-1].header.frame_id == 'p1/odom'
    assert forecasts[-1].child_frame_id == 'p1/base_link'
    assert forecasts[-1].vessel == 'patrol_boat'
    # The shipped bands hold at 0.15, not at the 0.1 asked for: none, and why.
    assert not forecasts[-1].band_levels and 'not at the served 0.1' in \
        forecasts[-1].band_note

    threshold = said(ros2('param', 'get', *DIRECT, '/p1/predictor',
                          'relative_threshold'))
    assert threshold.split() == ['Double', 'value', 'is:', '0.1'], threshold


@pytest.mark.slow   # the whole demo launch with the recorder (about 80 s)
def test_demo_launch_answers_the_cli_and_records_its_namespace(
        launcher, ros_node, ros2, tmp_path):
    from hybrid_predictor_interfaces.msg import Forecast

    forecasts = keep(ros_node, Forecast, '/demo1/forecast', 10)
    bag = tmp_path / 'bag'
    # On sim time the predictor's max_age (5 s) is simulated seconds: at 5x real time
    # the service keeps a second of wall-clock slack for a loaded machine.
    demo = ros2_launch(launcher, 'vessel_bringup', 'demo.launch.py', 'namespace:=demo1',
                       'real_time_factor:=5.0', f'record:={bag}', name='demo_launch')
    assert spin_until(ros_node, lambda: forecasts, FORECAST_WAIT_S), 'no /demo1/forecast'

    echo = ros2('topic', 'echo', '--once', '/demo1/forecast',
                'hybrid_predictor_interfaces/msg/Forecast', '--field', 'vessel')
    assert echo.returncode == 0 and 'patrol_boat' in echo.stdout, echo.stderr

    horizon = forecasts[-1].horizon
    plan = {'control_names': ['n', 'delta_port', 'delta_stbd'],
            'control_units': ['rad/s', 'rad', 'rad'], 'values': [80.0, 0.05, 0.05] * horizon}
    request = yaml.safe_dump({'plans': [plan]}, default_flow_style=True, width=math.inf)
    for _ in range(3):   # a window gone stale under load is refused; nothing else is
        call = ros2('service', 'call', '/demo1/predictor/predict',
                    'hybrid_predictor_interfaces/srv/Predict', request)
        assert call.returncode == 0, call.stderr
        if 'success=True' in call.stdout:
            break
        assert "message='no forecast: newest state is" in call.stdout, call.stdout[-2000:]
    assert 'success=True' in call.stdout, call.stdout[-2000:]

    accepted = said(ros2('param', 'set', *DIRECT, '/demo1/predictor',
                         'forecast_period', '2.0'))
    assert accepted.strip() == 'Set parameter successful', accepted
    read_back = said(ros2('param', 'get', *DIRECT, '/demo1/predictor',
                          'forecast_period'))
    assert read_back.split() == ['Double', 'value', 'is:', '2.0'], read_back
    # The CLI reports the node's refusal (on stderr) and exits 0, as ros2param does.
    refused = said(ros2('param', 'set', *DIRECT, '/demo1/predictor',
                        'relative_threshold', '0.3'))
    assert refused.startswith('Setting parameter failed') and 'read-only' in refused, refused
    unset = said(ros2('param', 'get', *DIRECT, '/demo1/predictor', 'relative_threshold'))
    assert unset.strip() == 'Parameter not set', unset      # served: the checkpoint's own
    names = ros2('param', 'list', *DIRECT, '/demo1/predictor')
    assert {'relative_threshold', 'use_sim_time'} <= set(names.stdout.split()), names.stdout

    assert launcher.stop(demo) == 0, demo.output()[-3000:]
    metadata = yaml.safe_load((bag / 'metadata.yaml').read_text())
    counts = {t['topic_metadata']['name']: t['message_count'] for t in
              metadata['rosbag2_bagfile_information']['topics_with_message_count']}
    assert set(counts) == {'/demo1/odom', '/demo1/actuators', '/demo1/wind'}, counts
    assert min(counts.values()) > 0, counts


# Two model compilations at once: 60-90 s on 2 cores; kept out of the default run.
@pytest.mark.slow
def test_two_vessels_on_one_graph_each_forecast_only_their_own(launcher, ros_node):
    from nav_msgs.msg import Odometry

    from hybrid_predictor_interfaces.msg import Forecast
    from vessel_ros_bridge.messages import seconds_from_stamp

    boats = ('boat1', 'boat2')
    odom = {b: keep(ros_node, Odometry, f'/{b}/odom', 500) for b in boats}
    forecasts = {b: keep(ros_node, Forecast, f'/{b}/forecast', 10) for b in boats}
    ros2_launch(launcher, 'vessel_bringup', 'two_vessels.launch.py', name='two_vessels')
    assert spin_until(ros_node, lambda: all(len(forecasts[b]) >= 2 for b in boats),
                      FORECAST_WAIT_S), {b: len(f) for b, f in forecasts.items()}

    for own, other in (boats, boats[::-1]):
        for names in (ros_node.get_subscriptions_info_by_topic(f'/{own}/odom'),
                      ros_node.get_publishers_info_by_topic(f'/{own}/forecast')):
            assert {i.node_namespace for i in names if i.node_name != ros_node.get_name()} \
                == {f'/{own}'}
        own_poses = {seconds_from_stamp(o.header.stamp): o.pose.pose.position
                     for o in odom[own]}
        other_stamps = {seconds_from_stamp(o.header.stamp) for o in odom[other]}
        for forecast in forecasts[own]:
            assert forecast.header.frame_id == f'{own}/odom'
            t_end = seconds_from_stamp(forecast.header.stamp)
            # A forecast starts from a state of its own vessel, never the other's.
            assert t_end in own_poses and t_end not in other_stamps
            start = own_poses[t_end]
            # One 1 s step at cruising speed from the pose it started from.
            assert math.hypot(forecast.x[0] - start.x, forecast.y[0] - start.y) < 15.0
