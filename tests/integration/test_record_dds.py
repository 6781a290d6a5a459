"""
The recorder over real DDS: separate publisher and recorder processes on loopback.

Every message published before the stop signal must be in the bag, in order, and the
bag must read back with rosbags, the mcap library and the converter.
"""

import os
from pathlib import Path
import signal
import time

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest

from vessel_datasets.bag_source import BagReader, find_bags
from vessel_datasets.readers.bags import bag_to_runs
from vessel_datasets.topic_map import topic_map_for
from vessel_description import load_vessel

REPO = Path(__file__).resolve().parents[2]
RECORD = REPO / 'offline' / 'record.py'
PUBLISHER = Path(__file__).resolve().parent / 'nodes' / 'bag_test_publisher.py'
TOPICS = ('/vessel/odom', '/vessel/actuators', '/vessel/wind')
COUNT = 300

pytestmark = pytest.mark.ros


@pytest.fixture
def dds_env():
    """Give each test session a DDS domain of its own (40-59), loopback only."""
    return {'ROS_DOMAIN_ID': str(40 + os.getpid() % 20),
            'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}


def wait_for(process, text: str, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while text not in process.output():
        assert process.alive(), f'{process.name} exited early:\n{process.output()}'
        assert time.monotonic() < deadline, f'no {text!r} from {process.name}:\n' \
                                            f'{process.output()}'
        time.sleep(0.1)


def published_sequence(bag_dir: Path) -> dict[str, list[float]]:
    """Read the numbered field of every recorded message, per topic, in file order."""
    fields = {'/vessel/odom': lambda m: m.pose.pose.position.x,
              '/vessel/actuators': lambda m: m.velocity[0],
              '/vessel/wind': lambda m: m.vector.x}
    (bag,) = find_bags([bag_dir])
    out = {t: [] for t in TOPICS}
    with BagReader(bag) as reader:
        assert not reader.losses, reader.losses
        types = {t: reader.topics[t].msgtype for t in TOPICS}
        for topic, _, raw in reader.messages(TOPICS):
            msg = reader.typestore.deserialize_cdr(raw, types[topic])
            out[topic].append(float(fields[topic](msg)))
    return out


def record_and_publish(launcher, tmp_path, env, *record_args):
    bag = tmp_path / 'bag'
    recorder = launcher.start_script(RECORD, '--out', str(bag), '--progress-interval', '0.5',
                                     *record_args, name='record', env=env)
    wait_for(recorder, 'waiting for publishers', timeout=30)
    # The publisher starts sending once every topic has a subscriber: the recorder.
    publisher = launcher.start_script(PUBLISHER, '--count', str(COUNT), '--rate', '200',
                                      name='publisher', env=env)
    wait_for(publisher, f'published {COUNT}', timeout=30)
    return bag, recorder


def test_sigint_loses_nothing_and_splits_by_size(launcher, tmp_path, dds_env):
    bag, recorder = record_and_publish(launcher, tmp_path, dds_env, '--max-bag-size', '60000')
    assert launcher.stop(recorder) == 0  # SIGINT first
    out = recorder.output()
    assert 'stopping on SIGINT' in out and 'messages recorded' in out
    files = sorted(bag.glob('*.mcap'))
    assert len(files) > 1  # split by size
    assert published_sequence(bag) == {t: [float(i) for i in range(COUNT)] for t in TOPICS}
    # Another library decodes the files too (definitions embedded, CDR).
    with files[0].open('rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        topic, msg = next((c.topic, m) for _, c, _, m in reader.iter_decoded_messages())
    assert topic in TOPICS and msg.header.stamp.sec == 1000


def test_sigterm_closes_the_bag_and_it_converts(launcher, tmp_path, dds_env):
    bag, recorder = record_and_publish(launcher, tmp_path, dds_env)
    os.killpg(recorder.popen.pid, signal.SIGTERM)
    assert recorder.popen.wait(15) == 0
    assert 'stopping on SIGTERM' in recorder.output()
    assert (bag / 'metadata.yaml').is_file()
    assert published_sequence(bag) == {t: [float(i) for i in range(COUNT)] for t in TOPICS}
    # The publisher stamps message i at 1000 + i s: one 1 Hz run of COUNT samples.
    (table,) = bag_to_runs(bag, topic_map_for(load_vessel('patrol_boat'))).values()
    assert len(table) == COUNT
    assert table['n'].tolist() == [float(i) for i in range(COUNT)]


def test_no_publisher_is_a_clear_error(launcher, tmp_path, dds_env):
    recorder = launcher.start_script(RECORD, '--out', str(tmp_path / 'bag'), '--topics',
                                     '/nobody/here', '--wait', '1', name='record',
                                     env=dds_env)
    assert recorder.popen.wait(30) == 1
    assert 'error: no publisher on /nobody/here after 1 s' in recorder.output()
    assert not (tmp_path / 'bag').exists()
