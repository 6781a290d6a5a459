"""
Reading what real life hands us, from real files.

Truncated files, lost metadata, unknown and custom types, and bags from another writer
(the mcap library).
"""

import dataclasses
from pathlib import Path
import shutil

from mcap.reader import make_reader
from mcap_ros2.writer import Writer as McapRos2Writer
import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from vessel_datasets import synthetic
from vessel_datasets.bag_source import BagError, BagReader, find_bags
from vessel_datasets.readers.bags import bag_to_runs, convert_bag
from vessel_datasets.topic_map import topic_map_for
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')

STORE = get_typestore(Stores.ROS2_JAZZY)
RECORD_HEADER = 9  # MCAP record: opcode (1) + length (8)


@pytest.fixture(scope='module')
def long_bag(tmp_path_factory):
    """Write a real recording of two chunks (rosbags closes one at 1 MiB), 3 x 2000 messages."""
    return synthetic.write_bag(tmp_path_factory.mktemp('bags') / 'long',
                               synthetic.demo_trajectory(2000))


def mcap_file(bag: Path) -> Path:
    return next(bag.glob('*.mcap'))


def chunk_layout(path: Path):
    """Chunk indexes of an intact MCAP file, and its messages' record ends per chunk."""
    with path.open('rb') as f:
        summary = make_reader(f).get_summary()
    return sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)


def messages_before(path: Path, chunk, cut: int) -> int:
    """How many of an uncompressed chunk's messages lie wholly before byte ``cut``."""
    with path.open('rb') as f:
        f.seek(chunk.chunk_start_offset + RECORD_HEADER + 8 + 8 + 8 + 4)
        n = int.from_bytes(f.read(4), 'little')
        records_start = f.tell() + n + 8
        data = path.read_bytes()[records_start:cut]
    count, pos = 0, 0
    while pos + RECORD_HEADER <= len(data):
        length = int.from_bytes(data[pos + 1:pos + 9], 'little')
        if pos + RECORD_HEADER + length > len(data):
            break
        count += data[pos] == 0x05
        pos += RECORD_HEADER + length
    return count


def count_messages(bag_path) -> int:
    (bag,) = find_bags([bag_path])
    with BagReader(bag) as reader:
        return sum(1 for _ in reader.messages(reader.topics))


def test_intact_bag_reads_every_message(long_bag):
    assert count_messages(long_bag) == 6000


def test_truncated_mid_chunk_recovers_everything_before_the_cut(long_bag, tmp_path):
    src = mcap_file(long_bag)
    chunks = chunk_layout(src)
    assert len(chunks) == 2
    second = chunks[1]
    cut = second.chunk_start_offset + second.chunk_length // 2
    bag = tmp_path / 'cut'
    bag.mkdir()
    (bag / src.name).write_bytes(src.read_bytes()[:cut])  # the recorder died here
    first_chunk = messages_before(src, chunks[0],
                                  chunks[0].chunk_start_offset + chunks[0].chunk_length)
    expected = first_chunk + messages_before(src, second, cut)

    (found,) = find_bags([bag])
    with BagReader(found) as reader:
        got = sum(1 for _ in reader.messages(reader.topics))
        losses = reader.losses
    assert got == expected
    assert 0 < got - first_chunk < 2000  # part of the cut chunk was recovered
    text = '\n'.join(losses)
    assert 'no summary section' in text
    assert f'chunk at byte {second.chunk_start_offset} (uncompressed' in text
    assert 'cut short by the end of the file' in text
    assert f'recovered {got - first_chunk} message(s)' in text

    # And it still converts: one run up to the cut.
    runs = bag_to_runs(bag, topic_map_for(SHIP))
    assert len(runs) == 1
    assert 600 < len(next(iter(runs.values()))) < 2000


def test_cut_inside_the_first_record_leaves_nothing_usable(long_bag, tmp_path):
    src = mcap_file(long_bag)
    first = chunk_layout(src)[0]
    bag = tmp_path / 'stub.mcap'
    bag.write_bytes(src.read_bytes()[:first.chunk_start_offset + 20])
    (found,) = find_bags([bag])
    result = convert_bag(found, topic_map_for(SHIP))
    assert result.error and 'which the bag lacks' in result.error
    assert any('cut short' in line for line in result.report['losses'])


def test_directory_without_metadata_reads_its_split_files(tmp_path):
    traj = synthetic.demo_trajectory(120)
    parts = []
    for i, (lo, hi) in enumerate(((0, 60), (60, 120))):
        part = synthetic.Trajectory(traj.t_ns[lo:hi],
                                    {k: v[lo:hi] for k, v in traj.columns.items()})
        written = synthetic.write_bag(tmp_path / f'w{i}', part)
        parts.append(mcap_file(written))
    bag = tmp_path / 'rosbag2_crashed'
    bag.mkdir()
    for i, part in enumerate(parts):
        shutil.copy(part, bag / f'rosbag2_crashed_{i}.mcap')
    (found,) = find_bags([bag])
    assert [f.name for f in found.files] == ['rosbag2_crashed_0.mcap', 'rosbag2_crashed_1.mcap']
    assert any('no metadata.yaml' in n for n in found.notes)
    runs = bag_to_runs(bag, topic_map_for(SHIP), min_run_s=10)
    assert [len(r) for r in runs.values()] == [120]  # one run across the file boundary


def test_folder_of_bags_and_bad_paths(tmp_path, long_bag):
    shutil.copytree(long_bag, tmp_path / 'fleet' / 'a')
    shutil.copy(mcap_file(long_bag), tmp_path / 'fleet' / 'loose.mcap')
    bags = find_bags([tmp_path / 'fleet'])
    assert sorted(b.name for b in bags) == ['a', 'loose']
    with pytest.raises(BagError, match='no such file'):
        find_bags([tmp_path / 'missing'])
    (tmp_path / 'empty').mkdir()
    with pytest.raises(BagError, match='no rosbag2 directory'):
        find_bags([tmp_path / 'empty'])
    (tmp_path / 'notes.txt').write_text('x')
    with pytest.raises(BagError, match='not a bag file'):
        find_bags([tmp_path / 'notes.txt'])


def test_a_folder_of_links_to_bags_finds_every_bag_once(tmp_path, long_bag):
    """A campaign gathered by symbolic links converts like its bags given one by one."""
    shutil.copytree(long_bag, tmp_path / 'store' / 'run1')
    shutil.copytree(long_bag, tmp_path / 'store' / 'run2')
    campaign = tmp_path / 'campaign'
    campaign.mkdir()
    for name in ('run1', 'run2'):
        (campaign / name).symlink_to(tmp_path / 'store' / name, target_is_directory=True)
    (campaign / 'again').symlink_to(tmp_path / 'store' / 'run1', target_is_directory=True)
    (campaign / 'loop').symlink_to(campaign, target_is_directory=True)   # a link back up
    bags = find_bags([campaign])
    # 'again' is run1 once more: the first link in name order is kept.
    assert sorted(b.name for b in bags) == ['again', 'run2']


def test_not_an_mcap_file(tmp_path):
    bad = tmp_path / 'junk.mcap'
    bad.write_bytes(b'this is not a bag' * 10)
    (found,) = find_bags([bad])
    result = convert_bag(found, topic_map_for(SHIP))
    assert any('not an MCAP file' in line for line in result.report['losses'])
    assert result.error


def _write_with_extra_topic(path, msgtype, msgdef, rihs01):
    traj = synthetic.demo_trajectory(30)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {t: w.add_connection(t, m, typestore=STORE)
                 for t, m in synthetic.SIM_TOPICS.items()}
        extra = w.add_connection('/sonar/ping', msgtype, msgdef=msgdef, rihs01=rihs01)
        for topic, ns, msg in synthetic.sim_messages(traj, STORE):
            w.write(conns[topic], ns, STORE.serialize_cdr(msg, synthetic.SIM_TOPICS[topic]))
            w.write(extra, ns, b'\x00\x01\x00\x00\x07\x00\x00\x00')
    return path


def test_unknown_type_gives_one_line_and_the_rest_converts(tmp_path):
    bag = _write_with_extra_topic(tmp_path / 'unknown', 'acme_msgs/msg/Ping', '',
                                  'RIHS01_' + '0' * 64)
    (found,) = find_bags([bag])
    result = convert_bag(found, topic_map_for(SHIP))
    assert result.error is None and len(result.runs) == 1
    notes = [n for n in result.report['notes'] if '/sonar/ping' in n]
    assert notes == ['topic /sonar/ping has type acme_msgs/msg/Ping, which has no definition '
                     'in the bag or in an installed package and is not a ROS 2 Jazzy type '
                     '(give its .msg file with --msg-dir DIR); its messages are skipped']


def test_custom_type_with_embedded_definition_is_decoded(tmp_path):
    bag = _write_with_extra_topic(tmp_path / 'custom', 'acme_msgs/msg/Ping',
                                  'uint32 range_mm\n', 'RIHS01_' + '1' * 64)
    (found,) = find_bags([bag])
    with BagReader(found) as reader:
        assert reader.topics['/sonar/ping'].problem is None
        raw = next(r for t, _, r in reader.messages(['/sonar/ping']))
        assert reader.typestore.deserialize_cdr(raw, 'acme_msgs/msg/Ping').range_mm == 7


def _to_plain(value):
    """Turn a rosbags message into the dicts and lists mcap-ros2-support encodes."""
    if dataclasses.is_dataclass(value):
        return {f.name: _to_plain(getattr(value, f.name)) for f in dataclasses.fields(value)
                if f.name != '__msgtype__'}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, list):
        return [_to_plain(v) for v in value]
    return value


def rosbag2_msgdef(msgtype: str) -> str:
    """Give the definition text as rosbag2 embeds it (builtin_interfaces/Time spelled out)."""
    text = STORE.generate_msgdef(msgtype)[0].replace('\ntime stamp\n',
                                                     '\nbuiltin_interfaces/Time stamp\n')
    return text + '=' * 80 + '\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n'


def write_with_mcap_library(path: Path, traj) -> Path:
    """Write the recording with mcap-ros2-support (zstd chunks, CRCs), bare .mcap."""
    with path.open('wb') as f:
        writer = McapRos2Writer(f)
        schemas = {t: writer.register_msgdef(m, rosbag2_msgdef(m))
                   for t, m in synthetic.SIM_TOPICS.items()}
        for topic, ns, msg in synthetic.sim_messages(traj, STORE):
            writer.write_message(topic, schemas[topic], _to_plain(msg), log_time=ns + 1000,
                                 publish_time=ns)
        writer.finish()
    return path


def test_bag_from_another_writer_converts_like_our_own(tmp_path):
    traj = synthetic.demo_trajectory(300)
    ours = bag_to_runs(synthetic.write_bag(tmp_path / 'ours', traj), topic_map_for(SHIP))
    theirs = bag_to_runs(write_with_mcap_library(tmp_path / 'theirs.mcap', traj),
                         topic_map_for(SHIP))
    assert len(ours) == len(theirs) == 1
    a, b = next(iter(ours.values())), next(iter(theirs.values()))
    assert a.shape == b.shape == (300, 15)
    assert np.array_equal(a.to_numpy(), b.to_numpy())


def test_truncated_zstd_chunk_from_another_writer(tmp_path):
    src = write_with_mcap_library(tmp_path / 'full.mcap', synthetic.demo_trajectory(4000))
    chunks = chunk_layout(src)
    assert chunks[0].compression == 'zstd'
    cut = chunks[-1].chunk_start_offset + chunks[-1].chunk_length * 3 // 4
    data = src.read_bytes()
    whole = tmp_path / 'whole_chunks.mcap'  # only the chunks before the cut one
    whole.write_bytes(data[:chunks[-1].chunk_start_offset])
    baseline = count_messages(whole)
    bag = tmp_path / 'cut.mcap'
    bag.write_bytes(data[:cut])
    (found,) = find_bags([bag])
    with BagReader(found) as reader:
        got = sum(1 for _ in reader.messages(reader.topics))
        text = '\n'.join(reader.losses)
    assert 'zstd' in text and 'cut short by the end of the file' in text
    assert baseline < got < count_messages(src)
    # zstd decodes whole blocks (<= 128 KiB): what they hold of the cut chunk is back.
    assert f'recovered {got - baseline} message(s)' in text


def test_corrupt_chunk_is_skipped_and_reported(tmp_path):
    src = write_with_mcap_library(tmp_path / 'full.mcap', synthetic.demo_trajectory(4000))
    chunks = chunk_layout(src)
    data = bytearray(src.read_bytes())
    data[chunks[1].chunk_start_offset + chunks[1].chunk_length // 2] ^= 0xFF
    bag = tmp_path / 'flipped.mcap'
    bag.write_bytes(bytes(data))
    (found,) = find_bags([bag])
    result = convert_bag(found, topic_map_for(SHIP))
    assert result.error is None
    assert any(f'chunk at byte {chunks[1].chunk_start_offset} (zstd' in line
               and 'its messages are lost' in line for line in result.report['losses'])
    # The chunks before and after the corrupt one still give runs; a gap separates them.
    assert len(result.runs) == 2 and len(result.report['gaps']) == 3
