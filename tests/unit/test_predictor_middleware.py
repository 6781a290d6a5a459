"""hybrid_predictor.middleware: the service's Fast DDS profile, unless the user set one."""

from pathlib import Path
import xml.etree.ElementTree as ET

import pytest

from hybrid_predictor.middleware import PROFILE_FILE, use_service_profile

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
    policies = {(p.tag.split('}')[1], p.get('profile_name')):
                p.find('f:historyMemoryPolicy', NS).text for p in profiles}
    assert policies[('publisher', 'service')] == 'DYNAMIC'
    assert policies[('subscriber', 'service')] == 'DYNAMIC'
    defaults = [p for p in profiles if p.get('is_default_profile') == 'true']
    # rmw_fastrtps' own choices for everything else (its README).
    assert {p.find('f:historyMemoryPolicy', NS).text for p in defaults} == {
        'PREALLOCATED_WITH_REALLOC'}
    publisher = next(p for p in defaults if p.tag.endswith('publisher'))
    assert publisher.find('f:qos/f:publishMode/f:kind', NS).text == 'ASYNCHRONOUS'


SIMULATOR = Path(__file__).resolve().parents[2] / 'ros2_ws/src/ship_sim_node/config'


@pytest.mark.parametrize('profile', [CONFIG / PROFILE_FILE, SIMULATOR / 'fastdds_simulator.xml'])
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
