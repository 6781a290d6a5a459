"""The recorder's storage: split rosbag2 MCAP directories other tools can read."""

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
import yaml

from vessel_datasets import synthetic
from vessel_datasets.bag_source import BagReader, find_bags
from vessel_datasets.bag_writer import BagWriterError, SplitBagWriter

STORE = get_typestore(Stores.ROS2_JAZZY)
S = 1_000_000_000


def record(out, n=60, **limits):
    """Write n seconds of the simulator's topics, as the recorder would."""
    writer = SplitBagWriter(out, STORE, **limits)
    for topic, msgtype in synthetic.SIM_TOPICS.items():
        writer.add_topic(topic, msgtype)
    for topic, ns, msg in synthetic.sim_messages(synthetic.demo_trajectory(n), STORE):
        writer.write(topic, ns, bytes(STORE.serialize_cdr(msg, synthetic.SIM_TOPICS[topic])))
    writer.close()
    return writer


def test_splits_by_duration_and_lists_every_file(tmp_path):
    writer = record(tmp_path / 'trial', max_duration_ns=20 * S)
    assert [f.name for f in writer.files] == ['trial_0.mcap', 'trial_1.mcap', 'trial_2.mcap']
    info = yaml.safe_load((tmp_path / 'trial' / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']
    assert info['relative_file_paths'] == ['trial_0.mcap', 'trial_1.mcap', 'trial_2.mcap']
    assert info['message_count'] == 180
    assert {t['topic_metadata']['name']: t['message_count']
            for t in info['topics_with_message_count']} == {t: 60 for t in synthetic.SIM_TOPICS}
    assert info['duration']['nanoseconds'] == 59 * S
    assert sorted(p.name for p in (tmp_path / 'trial').iterdir()) == [
        'metadata.yaml', 'trial_0.mcap', 'trial_1.mcap', 'trial_2.mcap']
    # rosbags reads the directory as rosbag2 does.
    with AnyReader([tmp_path / 'trial']) as reader:
        assert reader.message_count == 180
        assert sum(1 for _ in reader.messages()) == 180


def test_splits_by_size(tmp_path):
    writer = record(tmp_path / 'sized', max_bytes=25_000)
    sizes = [f.stat().st_size for f in writer.files]
    assert len(sizes) > 2
    assert all(size <= 25_000 * 1.02 for size in sizes)  # the estimate is close


def test_files_decode_with_the_mcap_library(tmp_path):
    writer = record(tmp_path / 'x', n=5)
    with writer.files[0].open('rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        schemas = {s.name: s.encoding for s in reader.get_summary().schemas.values()}
        decoded = [(c.topic, m) for _, c, _, m in reader.iter_decoded_messages()]
    assert schemas == {m: 'ros2msg' for m in synthetic.SIM_TOPICS.values()}
    assert len(decoded) == 15
    odom = next(m for t, m in decoded if t == '/vessel/odom')
    assert odom.child_frame_id == 'base_link'


def test_unfinished_split_is_recovered_by_the_reader(tmp_path):
    """A recorder killed mid-split leaves complete files plus one unlisted and unclosed."""
    out = tmp_path / 'killed'
    writer = SplitBagWriter(out, STORE, max_duration_ns=20 * S)
    for topic, msgtype in synthetic.SIM_TOPICS.items():
        writer.add_topic(topic, msgtype)
    messages = list(synthetic.sim_messages(synthetic.demo_trajectory(30), STORE))
    for topic, ns, msg in messages:
        writer.write(topic, ns, bytes(STORE.serialize_cdr(msg, synthetic.SIM_TOPICS[topic])))
    writer._writer.storage.close_chunk()  # the open split reached the disk, no summary
    writer._writer.storage.bio.flush()
    (bag,) = find_bags([out])
    assert [f.name for f in bag.files] == ['killed_0.mcap', 'killed_1.mcap']
    with BagReader(bag) as reader:
        assert sum(1 for _ in reader.messages(reader.topics)) == 90
        assert any('no summary section' in line for line in reader.losses)
    writer._writer.storage.bio.close()


def test_refuses_a_non_empty_directory_and_unknown_types(tmp_path):
    (tmp_path / 'used').mkdir()
    (tmp_path / 'used' / 'x').write_text('x')
    with pytest.raises(BagWriterError, match='not empty'):
        SplitBagWriter(tmp_path / 'used', STORE)
    writer = SplitBagWriter(tmp_path / 'new', STORE)
    with pytest.raises(BagWriterError, match='no message definition for acme_msgs/msg/X'):
        writer.add_topic('/x', 'acme_msgs/msg/X')
    writer.close()
    info = yaml.safe_load((tmp_path / 'new' / 'metadata.yaml').read_text())
    assert info['rosbag2_bagfile_information']['message_count'] == 0
