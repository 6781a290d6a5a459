"""hybrid_predictor.input_window: a clean model window from messy asynchronous inputs."""

import math

import numpy as np
import pytest

from hybrid_predictor.input_window import InputWindow, Samples
from vessel_datasets.topic_map import parse_topic_map, topic_map_for
from vessel_datasets.topic_messages import channel_reader
from vessel_description import load_vessel

W, DT = 60, 1.0
BOAT = load_vessel('patrol_boat')
# The patrol boat's vectors from scalar fields in the model's own frames (NED/FRD), so
# channels equal the states: the window must give back exactly what went in.
SCALAR_MAP = parse_topic_map({
    'body_velocity': {'frame': 'frd', 'surge': {'topic': '/state', 'field': 'u'},
                      'sway': {'topic': '/state', 'field': 'v'},
                      'roll_rate': {'topic': '/state', 'field': 'p'},
                      'yaw_rate': {'topic': '/state', 'field': 'r'}},
    'attitude': {'frame': 'ned_frd', 'heading': {'topic': '/state', 'field': 'psi'},
                 'roll': {'topic': '/state', 'field': 'phi'}},
    'position': {'frame': 'ned', 'x': {'topic': '/state', 'field': 'x'},
                 'y': {'topic': '/state', 'field': 'y'}},
    'actuators': {name: {'topic': '/act', 'field': name} for name in BOAT.actuator_names},
    'wind': {'frame': 'frd', 'speed': {'topic': '/wind', 'field': 'speed'},
             'from_angle': {'topic': '/wind', 'field': 'angle'}},
}, BOAT)
CHANNEL = {'u': 'surge', 'v': 'sway', 'p': 'roll_rate', 'r': 'yaw_rate', 'phi': 'roll',
           'psi': 'heading', 'x': 'pos_x', 'y': 'pos_y'}


def state_at(t):
    # Smooth, known signals so interpolated values can be checked exactly.
    values = {'u': 5.0 + 0.01 * t, 'v': 0.1, 'p': 0.0, 'r': 0.01, 'phi': 0.02 * math.sin(t),
              'psi': 0.01 * t, 'x': 5.0 * t, 'y': 0.0}
    return {CHANNEL[k]: v for k, v in values.items()}


def actuators(**values):
    return {f'actuator.{k}': v for k, v in values.items()}


def fill(window, t0, t1, state_rate=1.0, control_rate=1.0):
    for t in np.arange(t0, t1 + 1e-9, 1.0 / state_rate):
        window.push('/state', float(t), state_at(float(t)))
    for t in np.arange(t0, t1 + 1e-9, 1.0 / control_rate):
        window.push('/act', float(t), actuators(n=90.0 + t, delta_port=0.01, delta_stbd=0.02))
        window.push('/wind', float(t), {'wind_speed': 3.0, 'wind_from_angle': 0.0})


def make():
    return InputWindow(SCALAR_MAP, window=W, dt=DT, max_gap=2.5, max_age=5.0)


def test_window_on_the_model_grid_from_10_hz_states_and_2_hz_controls():
    window = make()
    fill(window, 0.0, 100.05, state_rate=10.0, control_rate=2.0)
    result = window.assemble(now=100.5)
    assert result.ready and result.status == 'ok' and result.fill == 1.0
    assert result.states.shape == (W, 5) and result.controls.shape == (W, 6)
    grid = result.t_end - DT * np.arange(W - 1, -1, -1)
    np.testing.assert_allclose(result.states[:, 0], 5.0 + 0.01 * grid, atol=1e-9)
    # Zero-order hold: the newest actuator sample at or before each grid time.
    np.testing.assert_allclose(result.controls[:, 0], 90.0 + np.floor(grid * 2) / 2)
    assert result.pose[0] == pytest.approx(5.0 * result.t_end)


def test_heading_is_unwrapped_across_the_pi_boundary():
    window = make()
    for k in range(70):
        t = float(k)
        psi = math.remainder(math.pi - 0.5 + 0.02 * k, 2 * math.pi)  # crosses +pi
        window.push('/state', t, dict(state_at(t), heading=psi))
        window.push('/act', t, actuators(n=1.0, delta_port=0.0, delta_stbd=0.0))
        window.push('/wind', t, {'wind_speed': 1.0, 'wind_from_angle': 0.0})
    result = window.assemble(now=69.0)
    assert result.pose[2] == pytest.approx(math.pi - 0.5 + 0.02 * 69)


@pytest.mark.parametrize('t, values, counter', [
    (50.0, {'surge': float('nan')}, 'non_finite'),
    (float('inf'), {}, 'non_finite'),
    (100.0, {}, 'duplicate'),
    (42.0, {}, 'out_of_order'),
])
def test_bad_samples_are_rejected_counted_and_never_used(t, values, counter):
    window = make()
    fill(window, 0.0, 100.0)
    before = window.assemble(now=100.0)
    reason = window.push('/state', t, dict(state_at(100.0), **values))
    assert reason
    counts = window.streams['/state'].counts
    assert getattr(counts, counter) == 1 and counts.rejected == 1
    after = window.assemble(now=100.0)
    np.testing.assert_array_equal(before.states, after.states)


def test_partial_actuator_samples_complete_from_the_last_one():
    window = make()
    fill(window, 0.0, 100.0)
    assert window.push('/act', 100.5, actuators(delta_port=0.3)) is None
    assert window.streams['/act'].counts.incomplete == 0
    first = make()
    assert 'lacks' in first.push('/act', 0.0, actuators(delta_port=0.3))


def test_too_short_history_is_incomplete_with_the_fill_fraction():
    window = make()
    fill(window, 0.0, 29.0)
    result = window.assemble(now=29.0)
    assert not result.ready and result.status == 'incomplete'
    assert 'does not reach back' in result.reason
    assert result.fill == pytest.approx(30 / W)


def test_a_gap_in_the_states_makes_the_window_incomplete():
    window = make()
    fill(window, 0.0, 100.0)
    for t in (104.0, 105.0):     # 4 s of silence, more than max_gap
        window.push('/state', t, state_at(t))
    result = window.assemble(now=105.0)
    assert not result.ready and '/state gap of 4.0 s' in result.reason


def test_silent_controls_make_the_window_incomplete():
    window = make()
    fill(window, 0.0, 100.0)
    for t in range(101, 106):
        window.push('/state', float(t), state_at(float(t)))
    result = window.assemble(now=105.0)
    assert not result.ready and '/act silent' in result.reason


def test_old_data_is_stale():
    window = make()
    fill(window, 0.0, 100.0)
    result = window.assemble(now=120.0)
    assert not result.ready and result.status == 'stale' and '20.0 s old' in result.reason


def test_buffers_keep_only_what_a_window_needs():
    window = make()
    fill(window, 0.0, 2000.0, state_rate=10.0)
    samples = window.streams['/state']._samples
    assert len(samples) < 10 * (W + 5)
    # Bounded: compacted while at most half full, else doubled, so at most 4x the rows kept.
    assert len(samples._times) <= 4 * 10 * (W + 5)
    assert window.assemble(now=2000.0).ready


def test_samples_keep_their_order_through_drops_compaction_and_growth():
    samples = Samples(width=2, capacity=4)
    kept = []
    for k in range(40):
        samples.append(float(k), [k, -k])
        kept.append(k)
        if k % 3 == 2:                 # drop some: the buffer compacts instead of growing
            samples.drop_first()
            kept.pop(0)
    times, rows = samples.arrays()
    assert times.tolist() == [float(k) for k in kept]
    assert rows.tolist() == [[k, -k] for k in kept]
    assert samples.time(0) == kept[0] and samples.time(-1) == 39.0
    assert samples.last_row().tolist() == [39, -39]
    times[0] = -1.0                    # a copy: the caller cannot change the buffer
    assert samples.time(0) == kept[0]
    samples.clear()
    assert len(samples) == 0 and samples.arrays()[0].size == 0


@pytest.mark.parametrize('delays', [{}, {'surge': 2.0, 'sway': 2.0, 'position': 2.0}])
def test_the_window_equals_offline_conversion_of_the_same_messages(tmp_path, delays):
    """One preprocessing core: the online window matches the converter's dataset."""
    from vessel_datasets import synthetic
    from vessel_datasets.readers.bags import bag_to_runs

    data = topic_map_for(BOAT).to_dict()
    for name, delay in delays.items():  # fields stamped 2 s after they were measured
        entry = data['position'] if name == 'position' else data['body_velocity'][name]
        entry['delay_s'] = delay
    topic_map = parse_topic_map(data, BOAT)
    traj = synthetic.demo_trajectory(400, rate_hz=5.0)
    (table,) = bag_to_runs(synthetic.write_bag(tmp_path / 'bag', traj), topic_map).values()
    window = InputWindow(topic_map, window=W, dt=DT, max_gap=2.5, max_age=5.0)
    readers = {t: channel_reader(topic_map, t) for t in topic_map.topics}
    # The dataset's grid lies on whole seconds: end the online window on one too.
    end_ns = traj.t_ns[-1] // 10**9 * 10**9
    for topic, ns, msg in synthetic.sim_messages(traj):
        if ns <= end_ns:
            window.push(topic, ns * 1e-9, readers[topic](msg))
    result = window.assemble(now=end_ns * 1e-9)
    assert result.ready
    # Delayed fields end the window that much earlier, where the dataset ends too.
    assert result.t_end == pytest.approx(end_ns * 1e-9 - max(delays.values(), default=0.0))
    tail = table.iloc[-W:]
    np.testing.assert_allclose(result.states, tail[list(BOAT.state_names)], atol=1e-9)
    np.testing.assert_allclose(result.controls, tail[list(BOAT.control_names)], atol=1e-9)


def test_a_message_with_none_of_the_mapped_joints_is_malformed():
    from rosbags.typesys import Stores, get_typestore
    T = get_typestore(Stores.ROS2_JAZZY).types
    read = channel_reader(topic_map_for(BOAT), '/vessel/actuators')
    header = T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](sec=0, nanosec=0),
                                      frame_id='')
    partial = T['sensor_msgs/msg/JointState'](header=header, name=['rudder_port'],
                                              position=[0.2], velocity=[], effort=[])
    assert read(partial) == {'actuator.delta_port': 0.2}
    foreign = T['sensor_msgs/msg/JointState'](header=header, name=['thruster'],
                                              position=[1.0], velocity=[], effort=[])
    with pytest.raises(ValueError, match='carries none of the mapped fields'):
        read(foreign)


def test_a_window_until_a_scheduled_state_ends_there_though_newer_states_arrived():
    # The node forecasts the state whose actuators and wind it awaited; a newer state
    # that arrived meanwhile, before its own actuators, must not end that window.
    window = make()
    fill(window, 0.0, 80.0)
    window.push('/state', 81.0, state_at(81.0))   # its actuators and wind not yet here
    newest, scheduled = window.assemble(now=81.0), window.assemble(now=81.0, until=80.0)
    assert newest.t_end == 81.0 and scheduled.ready and scheduled.t_end == 80.0
    grid = 80.0 - DT * np.arange(W - 1, -1, -1)
    np.testing.assert_allclose(scheduled.states[:, 0], 5.0 + 0.01 * grid, atol=1e-9)
    np.testing.assert_allclose(scheduled.controls[:, 0], 90.0 + grid)
    assert scheduled.pose[0] == pytest.approx(5.0 * 80.0)
    # The newest window holds the 80 s actuators over 81 s: what offline conversion of
    # the complete messages would not give once the 81 s ones arrive.
    assert newest.controls[-1, 0] == 90.0 + 80.0


def test_samples_not_yet_scored_are_kept_and_a_longer_window_reaches_back_to_them():
    window = make()
    fill(window, 0.0, 100.0)
    window.keep_from(40.0, reach=100.0)       # scored up to 40 s; keep at most 100 s back
    fill(window, 101.0, 130.0)
    longer = window.assemble(now=130.0, since=40.0)
    assert longer.ready and len(longer.states) == 90       # 41 ... 130 s
    assert longer.states[0, 0] == pytest.approx(state_at(41.0)['surge'])
    assert np.array_equal(window.assemble(now=130.0).states, longer.states[-W:])
    # beyond the reach the samples go, the window alone stays
    fill(window, 131.0, 200.0)
    times, _ = window.streams['/state'].arrays()
    assert times[0] >= 200.0 - 100.0 - 1.0
    assert not window.assemble(now=200.0, since=40.0).ready
    window.keep_from(None, reach=100.0)
    fill(window, 201.0, 260.0)
    assert len(window.streams['/state'].arrays()[0]) <= W + 1 + 2.5 + 2   # keep_s, as before
