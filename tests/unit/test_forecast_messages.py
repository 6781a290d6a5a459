"""hybrid_predictor.forecast_messages: a batch of Forecast messages from published arrays."""

from array import array

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from what_if_c.door import response_cdr

from hybrid_predictor.forecast_messages import (
    Assumed,
    Served,
    forecast_batch,
    forecast_messages,
    no_steps,
)
from hybrid_predictor.forecasting import Published
from hybrid_predictor_interfaces.msg import Forecast
from hybrid_predictor_interfaces.srv import Predict
from vessel_description import load_vessel
from vessel_ros_bridge import messages

B, K, LEVELS = 3, 7, (0.5, 0.9)


def _batch(rng, vessel):
    n = vessel.n_state
    hybrid = rng.normal(size=(B, K, n))
    return Published(steps=np.arange(K), hybrid=hybrid, physics=rng.normal(size=(B, K, n)),
                     x=rng.normal(size=(B, K)), y=rng.normal(size=(B, K)),
                     heading=rng.normal(size=(B, K)), z=None,
                     band_lower=hybrid[:, None] - 1.0 - rng.random((B, len(LEVELS), K, n)),
                     band_upper=hybrid[:, None] + 1.0 + rng.random((B, len(LEVELS), K, n)),
                     band_radius=rng.random((len(LEVELS), K)),
                     bound_available=rng.random((B, K)))


def _field_by_field(served, t_end, arrays, i, assumed):
    """One message as a reader of the message's definition would fill it."""
    spec = served.spec
    msg = Forecast()
    msg.header.stamp = messages.stamp_from_seconds(t_end)
    msg.header.frame_id = served.world_frame
    msg.child_frame_id = served.body_frame
    msg.step_period, msg.horizon = spec.dt, K
    msg.state_names, msg.state_units = list(spec.state_names), list(spec.state_units)
    msg.vessel = spec.name
    msg.control_names, msg.control_units = list(spec.control_names), list(spec.control_units)
    for name in ('hybrid', 'physics', 'x', 'y', 'heading', 'band_lower', 'band_upper',
                 'bound_available'):
        setattr(msg, name, array('d', getattr(arrays, name)[i].ravel().tolist()))
    msg.band_position_radius = array('d', arrays.band_radius.ravel().tolist())
    msg.band_levels, msg.band_note = list(LEVELS), served.band_note
    msg.residual_bound = array('d', served.residual_bound.tolist())
    msg.model_id, msg.relative_threshold, msg.bounded = served.model_id, 0.2, True
    msg.controls_assumed, msg.plan_id = assumed.controls, assumed.plan_id
    if assumed.plan_stamp is not None:
        msg.plan_stamp = assumed.plan_stamp
    return msg


def _served_and_assumed(rng, vessel):
    served = Served(vessel, 'odom', 'base_link', 'model@1', rng.random(vessel.n_state), 0.2,
                    True, LEVELS, 'calibrated on 3 runs')
    assumed = [Assumed(Forecast.CONTROLS_PLAN, f'plan-{i}', messages.stamp_from_seconds(i + 0.5))
               for i in range(B - 1)] + [Assumed()]
    return served, assumed


def test_each_message_carries_its_own_forecast_and_the_batch_alike():
    vessel = load_vessel('patrol_boat')
    rng = np.random.default_rng(0)
    arrays = _batch(rng, vessel)
    served, assumed = _served_and_assumed(rng, vessel)
    out = forecast_messages(served, 123.25, arrays, assumed)
    assert len(out) == B
    for i, msg in enumerate(out):
        assert msg == _field_by_field(served, 123.25, arrays, i, assumed[i]), i
        assert deserialize_message(serialize_message(msg), Forecast) == msg
    # A field replaced in one message (a withheld forecast) is replaced in that one alone.
    no_steps(out[0])
    assert out[0].horizon == 0 and len(out[0].hybrid) == len(out[0].bound_available) == 0
    assert out[1].horizon == K and list(out[1].hybrid) == arrays.hybrid[1].ravel().tolist()
    assert out[2].plan_id == '' and out[1].plan_id == 'plan-1'


def test_the_door_writes_the_batch_in_c_as_the_messages_say():
    vessel = load_vessel('patrol_boat')
    rng = np.random.default_rng(1)
    served, assumed = _served_and_assumed(rng, vessel)
    batch = forecast_batch(served, 7.5, _batch(rng, vessel), assumed, stride=2,
                           emptied=[False, True, False])
    out = batch.messages()
    assert out[1].horizon == 0 and len(out[1].band_position_radius) == 0 == len(out[1].x)
    assert out[1].plan_id == 'plan-1' and out[0].plan_stamp.nanosec == 500_000_000
    withheld = ['', 'non-finite values', '']
    answer = Predict.Response(success=True, message='2 forecasts', forecasts=out,
                              withheld=withheld)
    # Every field of every message, the emptied one's and the held one's too.
    written = deserialize_message(response_cdr('2 forecasts', withheld, batch),
                                  Predict.Response)
    assert written == answer
    assert list(written.forecasts[2].hybrid) == batch.rows['hybrid'][2].tolist()


@pytest.mark.parametrize('change, says', [
    (dict(rows={'hybrid': np.zeros((B + 1, 4))}), "hybrid must be 2-D 'd' with 3 rows"),
    (dict(rows={'speed': np.zeros((B, 4))}), "'speed' is no step row of a Forecast"),
    (dict(rows={'x': np.zeros((B, 4), np.float32)}), "x must be 2-D 'd'"),
    (dict(plan_ids=['a']), 'plan_ids must be a list of 3 str'),
    (dict(template=Predict.Response()), 'template must be a'),
])
def test_a_malformed_batch_is_refused_in_one_line(change, says):
    import dataclasses

    vessel = load_vessel('patrol_boat')
    rng = np.random.default_rng(2)
    served, assumed = _served_and_assumed(rng, vessel)
    batch = dataclasses.replace(forecast_batch(served, 7.5, _batch(rng, vessel), assumed),
                                **change)
    with pytest.raises((TypeError, ValueError), match=says):
        response_cdr('', [''] * B, batch)


@pytest.mark.parametrize('stride', [1, 2])
def test_published_bands_are_the_frd_bands_turned_into_flu(stride):
    from types import SimpleNamespace

    from hybrid_predictor.forecasting import published
    from vessel_physics import frames

    vessel = load_vessel('patrol_boat')   # v, p, r change sign in FLU; u, phi do not
    rng = np.random.default_rng(3)
    n, h = vessel.n_state, 6
    hybrid = rng.normal(size=(B, h, n))
    offsets = np.sort(rng.normal(size=(2, len(LEVELS), h, n)), axis=0)
    offsets[:, :, -1] = np.nan   # beyond the calibrated horizon
    radius = rng.random((len(LEVELS), h))
    bands = SimpleNamespace(at=lambda horizon: (offsets[0], offsets[1], radius))
    out = published(vessel, (0.0, 0.0, 0.0), hybrid, hybrid, bands, stride)
    keep = slice(stride - 1, None, stride)
    want = frames.interval_frd_to_flu(hybrid[:, None] + offsets[0], hybrid[:, None] + offsets[1],
                                      vessel.state_names)
    np.testing.assert_array_equal(out.band_lower, want[0][:, :, keep])   # to the bit
    np.testing.assert_array_equal(out.band_upper, want[1][:, :, keep])
    np.testing.assert_array_equal(out.band_radius, radius[:, keep])
