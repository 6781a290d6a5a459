"""
Bags as users have them: Humble sqlite3 bags of custom types that carry no definitions.

The definitions come from folders of .msg files (--msg-dir), laid out as packages or
flat with --msg-package, or from interface packages installed here; a bag's own
definitions win over both.
"""

import os
from pathlib import Path
import pickle
import sqlite3
import subprocess
import sys

import numpy as np
import pytest
from rosbags.interfaces import MessageDefinitionFormat
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
import yaml

from vessel_datasets.bag_source import (
    BagReader,
    MessageDefinitionError,
    MessageDefinitions,
    build_typestore,
    find_bags,
)
from vessel_datasets.fields import FieldError, check_path
from vessel_datasets.readers.bags import convert_bag
from vessel_datasets.topic_map import parse_topic_map, topic_map_for
from vessel_description import load_vessel

REPO = Path(__file__).resolve().parents[2]
SHIP = load_vessel('patrol_boat')
POSE = 'float32 x\nfloat32 y\nfloat32 theta  # rad\n'
# A relative name (Pose2D) and an array of the nested custom type.
ARRAY = ('builtin_interfaces/Time tick\nfloat32[] pose\nPose2D origin\n'
         'acme_msgs/Pose2D[] poses\n')
MSGS = {'Pose2D': POSE, 'Pose2DArray': ARRAY}
TYPE = 'acme_msgs/msg/Pose2DArray'
TOPIC = '/acme/poses'
N = 5
S = 1_000_000_000
T0 = 1_700_000_000 * S


def writer_store():
    """Return the typestore the 'robot' had: Jazzy plus its own package."""
    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in MSGS.items():
        store.register(get_types_from_msg(text, f'acme_msgs/msg/{name}'))
    return store


def message(store, i):
    T = store.types
    pose = T['acme_msgs/msg/Pose2D']
    return T[TYPE](tick=T['builtin_interfaces/msg/Time'](sec=T0 // S + i, nanosec=250),
                   pose=np.array([i + 0.5, -i, 0.25 * i], dtype=np.float32),
                   origin=pose(x=float(i), y=2.0, theta=0.5),
                   poses=[pose(x=1.0, y=float(i), theta=0.0)] * 2)


def write_humble_bag(path: Path) -> Path:
    """
    Write a sqlite3 bag as rosbag2 Humble does: schema 3, metadata version 5, no definitions.

    rosbags writes the newer layout (a message_definitions table, type hashes), so the
    file is changed back to Humble's afterwards. Besides the custom topic it holds the
    two other topics of the patrol boat's topic map, without messages.
    """
    store = writer_store()
    with Writer(path, version=8, storage_plugin=StoragePlugin.SQLITE3) as w:
        conn = w.add_connection(TOPIC, TYPE, msgdef='', rihs01='RIHS01_' + '0' * 64)
        for topic in ('/vessel/odom', '/vessel/actuators'):
            w.add_connection(topic, {'/vessel/odom': 'nav_msgs/msg/Odometry',
                                     '/vessel/actuators': 'sensor_msgs/msg/JointState'}[topic],
                             msgdef='', rihs01='RIHS01_' + '0' * 64)
        for i in range(N):
            w.write(conn, T0 + i * S, store.serialize_cdr(message(store, i), TYPE))
    db = next(path.glob('*.db3'))
    with sqlite3.connect(db) as con:
        con.executescript("""
            DROP TABLE message_definitions;
            ALTER TABLE topics DROP COLUMN type_description_hash;
            UPDATE schema SET schema_version = 3, ros_distro = 'humble';
        """)
    con.close()
    meta_path = path / 'metadata.yaml'
    meta = yaml.safe_load(meta_path.read_text())
    info = meta['rosbag2_bagfile_information']
    info['version'] = 5
    for key in ('custom_data', 'ros_distro'):
        info.pop(key, None)
    for t in info['topics_with_message_count']:
        t['topic_metadata'].pop('type_description_hash', None)
    meta_path.write_text(yaml.safe_dump(meta))
    return path


@pytest.fixture(scope='module')
def humble_bag(tmp_path_factory):
    """One Humble-style sqlite3 bag of N custom messages, shared by the tests."""
    (bag,) = find_bags([write_humble_bag(tmp_path_factory.mktemp('bags') / 'humble')])
    return bag


def msg_folder(root: Path, layout: str = 'packages', names=tuple(MSGS)) -> Path:
    """Write the .msg files as <root>/acme_msgs/msg/*.msg, or flat in <root>."""
    folder = root / 'acme_msgs' / 'msg' if layout == 'packages' else root
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        (folder / f'{name}.msg').write_text(MSGS[name])
    return root


def assert_decodes(bag, definitions):
    """Every message decodes to what was written; field paths check against the type."""
    with BagReader(bag, definitions) as reader:
        info = reader.topics[TOPIC]
        assert (info.msgtype, info.count, info.problem) == (TYPE, N, None)
        msgs = [reader.typestore.deserialize_cdr(raw, TYPE)
                for _, _, raw in reader.messages([TOPIC])]
        defs = reader.typestore.fielddefs
    assert len(msgs) == N
    for i, msg in enumerate(msgs):
        assert (msg.tick.sec, msg.tick.nanosec) == (T0 // S + i, 250)
        np.testing.assert_array_equal(msg.pose, np.float32([i + 0.5, -i, 0.25 * i]))
        assert (msg.origin.x, msg.origin.y, msg.origin.theta) == (i, 2.0, 0.5)
        assert [p.y for p in msg.poses] == [i, i]
    check_path(defs, TYPE, 'pose[0]')
    check_path(defs, TYPE, 'origin.theta')
    check_path(defs, TYPE, 'tick.sec')
    with pytest.raises(FieldError):
        check_path(defs, TYPE, 'origin.z')


def test_the_humble_bag_really_carries_no_definitions(humble_bag):
    db = humble_bag.files[0]
    assert db.suffix == '.db3'
    with Reader(db) as reader:
        assert {c.msgdef.format for c in reader.connections} == {MessageDefinitionFormat.NONE}
    with Reader(humble_bag.path) as reader:  # metadata.yaml version 5 reads too
        assert reader.message_count == N
    with BagReader(humble_bag) as reader:
        assert reader.losses == []
        assert reader.topics[TOPIC].count == N
        assert '--msg-dir' in reader.topics[TOPIC].problem
        assert reader.topics['/vessel/odom'].problem is None  # a ROS 2 Jazzy type


def test_without_msg_dir_the_error_names_the_type_and_the_flag(humble_bag):
    data = topic_map_for(SHIP).to_dict()
    data['wind']['velocity']['topic'] = TOPIC
    result = convert_bag(humble_bag, parse_topic_map(data, SHIP))
    assert result.error == (
        f'{humble_bag.path}: topic {TOPIC} has type {TYPE}, which has no definition in the '
        'bag or in an installed package and is not a ROS 2 Jazzy type (give its .msg file '
        'with --msg-dir DIR); it cannot be read')


@pytest.mark.parametrize('where', ['root', 'package', 'workspace'])
def test_msg_dir_laid_out_as_packages(humble_bag, tmp_path, where):
    root = msg_folder(tmp_path / 'src')
    given = {'root': root, 'package': root / 'acme_msgs',
             'workspace': tmp_path}[where]  # <ws>/src/acme_msgs/msg/*.msg
    definitions = MessageDefinitions([given])
    assert set(definitions.types) == {TYPE, 'acme_msgs/msg/Pose2D'}
    assert_decodes(humble_bag, definitions)
    # Worker processes (--jobs) receive it pickled.
    assert_decodes(humble_bag, pickle.loads(pickle.dumps(definitions)))


def test_flat_folder_with_a_package_name(humble_bag, tmp_path):
    flat = msg_folder(tmp_path / 'msg', layout='flat')
    assert_decodes(humble_bag, MessageDefinitions([flat], package='acme_msgs'))


def test_flat_folder_without_a_package_name_is_one_line(tmp_path):
    flat = msg_folder(tmp_path / 'msg', layout='flat')
    with pytest.raises(MessageDefinitionError) as err:
        MessageDefinitions([flat])
    assert str(err.value) == (f'{flat / "Pose2D.msg"}: no package name for this message (it '
                              'is not in a <pkg>/msg/ folder); give one with --msg-package '
                              'NAME')


def test_unusable_folders_are_one_line(tmp_path):
    with pytest.raises(MessageDefinitionError, match='no such directory'):
        MessageDefinitions([tmp_path / 'nowhere'])
    (tmp_path / 'empty').mkdir()
    with pytest.raises(MessageDefinitionError, match='no .msg files inside'):
        MessageDefinitions([tmp_path / 'empty'])
    bad = tmp_path / 'bad' / 'acme_msgs' / 'msg'
    bad.mkdir(parents=True)
    (bad / 'Broken.msg').write_text('# a comment\nfloat32[ x\n')
    with pytest.raises(MessageDefinitionError) as err:
        MessageDefinitions([tmp_path / 'bad'])
    assert str(err.value) == (f'{bad / "Broken.msg"}: not a valid definition of '
                              "acme_msgs/msg/Broken (cannot parse line 2: 'float32[ x')")


def test_a_missing_nested_type_is_named(humble_bag, tmp_path):
    only_array = msg_folder(tmp_path / 'defs', names=('Pose2DArray',))
    with BagReader(humble_bag, MessageDefinitions([only_array])) as reader:
        assert reader.topics[TOPIC].problem == (
            'uses acme_msgs/msg/Pose2D, which has no definition in the bag, the --msg-dir '
            'folders or an installed package and is not a ROS 2 Jazzy type')


def test_a_wrong_package_from_the_layout_is_pointed_out(humble_bag, tmp_path):
    folder = tmp_path / 'boat' / 'msg'  # --msg-dir boat: the package would be 'boat'
    folder.mkdir(parents=True)
    for name, text in MSGS.items():
        (folder / f'{name}.msg').write_text(text)
    with BagReader(humble_bag, MessageDefinitions([tmp_path / 'boat'])) as reader:
        problem = reader.topics[TOPIC].problem
    assert f'({folder / "Pose2DArray.msg"} defines boat/msg/Pose2DArray; ' in problem


def test_the_bag_own_definition_wins(tmp_path):
    path = tmp_path / 'embedded'
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg('uint32 range_mm\n', 'acme_msgs/msg/Ping'))
    with Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        conn = w.add_connection('/sonar', 'acme_msgs/msg/Ping', typestore=store)
        w.write(conn, T0, store.serialize_cdr(store.types['acme_msgs/msg/Ping'](range_mm=7),
                                              'acme_msgs/msg/Ping'))
    folder = tmp_path / 'defs' / 'acme_msgs' / 'msg'
    folder.mkdir(parents=True)
    (folder / 'Ping.msg').write_text('float64 range_m\n')
    (bag,) = find_bags([path])
    with BagReader(bag, MessageDefinitions([tmp_path / 'defs'])) as reader:
        assert reader.topics['/sonar'].problem is None
        raw = next(r for _, _, r in reader.messages(['/sonar']))
        assert reader.typestore.deserialize_cdr(raw, 'acme_msgs/msg/Ping').range_mm == 7


@pytest.fixture
def installed_package(tmp_path, monkeypatch):
    """Install an interface package 'acme_installed' as colcon does; put it on sys.path."""
    prefix = tmp_path / 'install'
    site = prefix / 'lib' / 'python3.11' / 'site-packages'
    (site / 'acme_installed' / 'msg').mkdir(parents=True)
    (site / 'acme_installed' / '__init__.py').write_text('')
    (site / 'acme_installed' / 'msg' / '__init__.py').write_text('')
    share = prefix / 'share' / 'acme_installed' / 'msg'
    share.mkdir(parents=True)
    (share / 'Reading.msg').write_text('std_msgs/Header header\nfloat64 value  # m\n')
    monkeypatch.syspath_prepend(str(site))
    return 'acme_installed/msg/Reading'


@pytest.mark.parametrize('ament_index', [True, False])
def test_installed_interface_packages_are_used(installed_package, monkeypatch, ament_index):
    if not ament_index:  # the fallback: share/ beside the Python package
        monkeypatch.setitem(sys.modules, 'ament_index_python', None)
        monkeypatch.setitem(sys.modules, 'ament_index_python.packages', None)
    store, problems = build_typestore({}, {installed_package})
    assert problems == {}
    check_path(store.fielddefs, installed_package, 'value')
    check_path(store.fielddefs, installed_package, 'header.stamp.sec')


def test_msg_dir_wins_over_installed_packages(installed_package, tmp_path):
    folder = tmp_path / 'defs' / 'acme_installed' / 'msg'
    folder.mkdir(parents=True)
    (folder / 'Reading.msg').write_text('int32 count\n')
    store, problems = build_typestore({}, {installed_package},
                                      MessageDefinitions([tmp_path / 'defs']))
    assert problems == {}
    assert [name for name, _ in store.fielddefs[installed_package][1]] == ['count']


def test_a_package_built_in_this_workspace_is_found():
    pytest.importorskip('hybrid_predictor_interfaces')
    store, problems = build_typestore({}, {'hybrid_predictor_interfaces/msg/Forecast'})
    assert problems == {}
    check_path(store.fielddefs, 'hybrid_predictor_interfaces/msg/Forecast', 'x[0]')


def test_cli_help_shows_the_flags():
    # The source tree first, as for these tests (not a possibly older colcon install).
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(sys.path)}
    done = subprocess.run([sys.executable, str(REPO / 'offline' / 'bag_to_dataset.py'),
                           '--help'], capture_output=True, text=True, timeout=60, env=env)
    assert done.returncode == 0, done.stderr
    assert '--msg-dir DIR' in done.stdout and '--msg-package NAME' in done.stdout
