"""hybrid_predictor.middleware: the service's Fast DDS profile, unless the user set one."""

from pathlib import Path
import xml.etree.ElementTree as ET

import pytest
import yaml

from hybrid_predictor.middleware import (
    CLIENT_PROFILE_FILE,
    PROFILE_FILE,
    use_client_profile,
    use_service_profile,
)

CONFIG = Path(__file__).resolve().parents[2] / 'ros2_ws/src/hybrid_predictor/config'
NS = {'f': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}


def test_fast_dds_gets_the_shipped_profile():
    env = {}
    note = use_service_profile(env, CONFIG)
    assert env == {'FASTRTPS_DEFAULT_PROFILES_FILE': str(CONFIG / PROFILE_FILE),
                   'RMW_FASTRTPS_USE_QOS_FROM_XML': '1'}
    assert PROFILE_FILE in note


@pytest.mark.parametrize('name', ['FASTRTPS_DEFAULT_PROFILES_FILE',
                                  'FASTDDS_DEFAULT_PROFILES_FILE',
                                  'RMW_FASTRTPS_USE_QOS_FROM_XML'])
def test_a_users_own_fast_dds_configuration_is_left_alone(name):
    env = {name: '/etc/my_profile.xml'}
    note = use_service_profile(env, CONFIG)
    assert env == {name: '/etc/my_profile.xml'}
    assert name in note


def test_another_middleware_is_left_alone():
    env = {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'}
    use_service_profile(env, CONFIG)
    assert env == {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'}


def test_a_missing_profile_is_one_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match='missing from the install'):
        use_service_profile({}, tmp_path)


def test_only_the_service_endpoints_get_dynamic_history_memory():
    profiles = ET.parse(CONFIG / PROFILE_FILE).getroot().find('f:profiles', NS)
    endpoints = [p for p in profiles if p.tag.split('}')[1] in ('publisher', 'subscriber')]
    policies = {(p.tag.split('}')[1], p.get('profile_name')):
                p.find('f:historyMemoryPolicy', NS).text for p in endpoints}
    assert policies[('publisher', 'service')] == 'DYNAMIC'
    assert policies[('subscriber', 'service')] == 'DYNAMIC'
    defaults = [p for p in endpoints if p.get('is_default_profile') == 'true']
    # rmw_fastrtps' own choices for everything else (its README).
    assert {p.find('f:historyMemoryPolicy', NS).text for p in defaults} == {
        'PREALLOCATED_WITH_REALLOC'}
    publisher = next(p for p in defaults if p.tag.endswith('publisher'))
    assert publisher.find('f:qos/f:publishMode/f:kind', NS).text == 'ASYNCHRONOUS'


SIMULATOR = Path(__file__).resolve().parents[2] / 'ros2_ws/src/ship_sim_node/config'


@pytest.mark.parametrize('profile', [CONFIG / PROFILE_FILE, CONFIG / CLIENT_PROFILE_FILE,
                                     SIMULATOR / 'fastdds_simulator.xml'])
def test_every_shipped_writer_repairs_a_lost_sample_within_a_tenth_of_a_second(profile):
    # Fast DDS's default heartbeat (3 s) held a topic back 3.2-4.2 s after one lost sample.
    profiles = ET.parse(profile).getroot().find('f:profiles', NS)
    writers = [p for p in profiles if p.tag.endswith('publisher')]
    assert writers and any(p.get('is_default_profile') == 'true' for p in writers)
    for writer in writers:
        period = writer.find('f:times/f:heartbeatPeriod', NS)
        assert (int(period.find('f:sec', NS).text), int(period.find('f:nanosec', NS).text)) \
            == (0, 100_000_000), writer.get('profile_name')


def test_the_simulator_takes_its_profile_without_the_predictors_qos_from_xml():
    from vessel_ros_bridge.middleware import use_profile

    env = {}
    note = use_profile(env, SIMULATOR / 'fastdds_simulator.xml', 'heartbeats every 0.1 s')
    assert env == {'FASTRTPS_DEFAULT_PROFILES_FILE': str(SIMULATOR / 'fastdds_simulator.xml')}
    assert note.endswith('heartbeats every 0.1 s')


# The largest what-if answer: 64 plans, every step of 900 (the middleware module's 6 MB).
LARGEST_ANSWER_BYTES = 6e6


@pytest.mark.parametrize('profile', [PROFILE_FILE, CLIENT_PROFILE_FILE])
def test_what_if_traffic_has_room_in_shared_memory_and_other_hosts_keep_udp(profile):
    # With Fast DDS's 512 kB segment, a burst of requests or answers overwrote buffers
    # not read yet: each lost sample waited 80-230 ms for its repair.
    profiles = ET.parse(CONFIG / profile).getroot().find('f:profiles', NS)
    descriptors = {d.find('f:transport_id', NS).text: d
                   for d in profiles.find('f:transport_descriptors', NS)}
    participant = next(p for p in profiles if p.tag.endswith('participant')
                       and p.get('is_default_profile') == 'true')
    used = [t.text for t in participant.find('f:rtps/f:userTransports', NS)]
    kinds = {descriptors[t].find('f:type', NS).text: descriptors[t] for t in used}
    # The built-in pair, replaced as a pair: a predictor on another host is still heard.
    assert sorted(kinds) == ['SHM', 'UDPv4']
    assert participant.find('f:rtps/f:useBuiltinTransports', NS).text == 'false'
    capacity = yaml.safe_load((CONFIG / 'predictor.yaml').read_text())['service_capacity']
    segment = int(kinds['SHM'].find('f:segment_size', NS).text)
    assert segment >= capacity['default'] * LARGEST_ANSWER_BYTES


def test_a_client_gets_its_profile_without_the_predictors_qos_from_xml():
    env = {}
    note = use_client_profile(env, CONFIG)
    assert env == {'FASTRTPS_DEFAULT_PROFILES_FILE': str(CONFIG / CLIENT_PROFILE_FILE)}
    assert 'shared-memory' in note
    mine = {'FASTDDS_DEFAULT_PROFILES_FILE': '/etc/my_profile.xml'}
    use_client_profile(mine, CONFIG)
    assert mine == {'FASTDDS_DEFAULT_PROFILES_FILE': '/etc/my_profile.xml'}


@pytest.mark.parametrize(('use', 'profile'), [(use_service_profile, PROFILE_FILE),
                                               (use_client_profile, CLIENT_PROFILE_FILE)])
def test_without_a_directory_both_use_the_installed_packages_profile(use, profile):
    env = {}
    use(env)
    path = Path(env['FASTRTPS_DEFAULT_PROFILES_FILE'])
    assert path.name == profile and path.is_file()
    assert path.parent.parent.name == 'hybrid_predictor'     # share/hybrid_predictor/config
