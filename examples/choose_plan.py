#!/usr/bin/env python3
"""
A controller's first step: sample candidate plans, forecast them, pick one by cost and risk.

The choice is plain Python on the fields of ``hybrid_predictor_interfaces/Forecast``
(``x``, ``y``: the ENU track; ``band_levels``, ``band_position_radius``: the calibrated
radius around it), so it runs on the service's answers as on any objects with those
fields. Only ``main`` speaks ROS: it asks the running predictor's ``~/predict`` for
the forecasts of all candidates in one batch.

    ros2 launch vessel_bringup demo.launch.py          # or any running predictor
    python examples/choose_plan.py --goal 300 200     # goal in odom (ENU), m

Cost of a plan = distance (m) from the goal to the forecast's last position
+ risk_weight x the radius (m) within which the vessel ends up with probability
``level`` (the calibrated band). A risk weight of 0 trusts the forecast's mean track;
1 judges a plan by its worst case at that level.
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np


def candidate_plans(vessel, horizon: int, count: int, seed: int = 0) -> list[np.ndarray]:
    """
    Return ``count`` plans (horizon, actuators) in the vessel's actuators, in their units.

    Each holds one random set-point per actuator inside its declared range for the
    whole horizon (the simplest sampler; an MPC would perturb its previous plan).
    """
    rng = np.random.default_rng(seed)
    low = np.array([a.low for a in vessel.actuators])
    high = np.array([a.high for a in vessel.actuators])
    return [np.tile(rng.uniform(low, high), (horizon, 1)) for _ in range(count)]


def band_radius(forecast, level: float) -> np.ndarray:
    """Return the forecast's calibrated position radius (m) per step at ``level``."""
    levels = list(forecast.band_levels)
    if level not in levels:
        raise ValueError(f'the forecast has bands at {levels}, not at {level} '
                         f'({forecast.band_note or "no bands"})')
    radii = np.reshape(forecast.band_position_radius, (len(levels), forecast.horizon))
    return radii[levels.index(level)]


def plan_cost(forecast, goal: tuple[float, float], risk_weight: float,
              level: float = 0.9) -> float:
    """Return the distance to the goal at the horizon's end plus the weighted band radius."""
    miss = math.hypot(forecast.x[-1] - goal[0], forecast.y[-1] - goal[1])
    return miss + risk_weight * float(band_radius(forecast, level)[-1])


def choose(forecasts, goal: tuple[float, float], risk_weight: float,
           level: float = 0.9) -> tuple[int, list[float]]:
    """Return the index of the cheapest forecast's plan, and every plan's cost."""
    costs = [plan_cost(f, goal, risk_weight, level) for f in forecasts]
    return int(np.argmin(costs)), costs


def main(argv=None) -> int:
    """Ask the running predictor for forecasts of sampled plans; print the chosen one."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--goal', type=float, nargs=2, required=True, metavar=('X', 'Y'),
                        help='goal position in the forecast frame (odom, ENU), m')
    parser.add_argument('--plans', type=int, default=16, help='candidate plans (default 16)')
    parser.add_argument('--risk-weight', type=float, default=0.5,
                        help='weight of the 90 %% radius in the cost (default 0.5)')
    parser.add_argument('--vessel', default='patrol_boat', help='vessel file or name')
    parser.add_argument('--service', default='/vessel/predictor/predict')
    args = parser.parse_args(argv)

    import os

    import rclpy

    from hybrid_predictor.middleware import use_client_profile
    from hybrid_predictor.plan_message import control_plan
    from hybrid_predictor.what_if_client import ask
    from hybrid_predictor_interfaces.srv import Predict
    from vessel_description import load_vessel

    vessel = load_vessel(args.vessel)
    plans = candidate_plans(vessel, vessel.horizon, args.plans)
    use_client_profile(os.environ)   # room for the request in shared memory (before init)
    rclpy.init()
    node = rclpy.create_node('choose_plan')
    try:
        client = node.create_client(Predict, args.service)
        if not client.wait_for_service(timeout_sec=30.0):
            print(f'choose_plan: error: no service {args.service}', file=sys.stderr)
            return 2
        request = Predict.Request(plans=[control_plan(vessel, p, plan_id=f'candidate-{i}')
                                         for i, p in enumerate(plans)])
        answer = ask(node, client, request, timeout=60.0)   # busy: comes back as told
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    if answer is None or not answer.success:
        print(f'choose_plan: error: {answer.message if answer else "no answer"}',
              file=sys.stderr)
        return 2
    best, costs = choose(answer.forecasts, tuple(args.goal), args.risk_weight)
    print(f'chose candidate-{best} of {len(costs)}: cost {costs[best]:.1f} m, set-points '
          + ', '.join(f'{name} {value:.3g} {unit}' for name, value, unit in zip(
              vessel.actuator_names, plans[best][0], vessel.control_units, strict=False)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
