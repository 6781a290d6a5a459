"""
Tracks with exact kinematics for the recording tests, and the tables loggers make of them.

``trajectory`` integrates a smooth turning run in model units; ``csv_table`` writes it
the way a logger would (degrees, knots, rpm, earth frame, rudder positive to port).
``spatial_flight`` is a 6-DOF vehicle's flight (NED/FRD) for the multirotor recordings.
"""

import math

import numpy as np
import pandas as pd

from vessel_physics.integrator import attitude_rates, body_to_ned

KNOT = 1852.0 / 3600.0
RATE_HZ = 20.0


def trajectory(duration_s=60.0, rate_hz=RATE_HZ, speed=1.2, scale=1.0, turn=1.0):
    """
    Return a turning run in model units: psi spans 23..195 deg, so it wraps at 180.

    ``speed`` is the mean surge (m/s); ``scale`` stretches time (a ship ``scale`` times
    slower to turn, its rates divided by it); ``turn`` scales the yaw rate.
    """
    fine = 100  # position integrated on a 100x finer grid by the trapezoid rule
    tf = np.arange(int(round(duration_s * rate_hz * fine)) + 1) / (rate_hz * fine)
    ts = tf / scale
    u = speed * (1 + np.sin(2 * math.pi * ts / 30) / 6)
    v = speed / 15 * np.sin(2 * math.pi * ts / 20 + 1.0)
    r = turn / scale * (0.05 + 0.15 * np.sin(2 * math.pi * ts / 40))
    psi = 0.4 + turn * (0.05 * ts + 0.15 * 40 / (2 * math.pi) * (1 - np.cos(2 * math.pi
                                                                            * ts / 40)))
    north_dot = u * np.cos(psi) - v * np.sin(psi)
    east_dot = u * np.sin(psi) + v * np.cos(psi)
    dt = tf[1] - tf[0]
    x = np.concatenate([[0.0], np.cumsum(0.5 * dt * (north_dot[1:] + north_dot[:-1]))])
    y = np.concatenate([[0.0], np.cumsum(0.5 * dt * (east_dot[1:] + east_dot[:-1]))])
    every = slice(None, None, fine)
    t = np.arange(len(tf[every])) / rate_hz
    n = np.where(t < duration_s / 2, 60.0, 70.0)
    delta = 0.2 * np.sign(np.sin(2 * math.pi * t / (20 * scale) + 0.1))
    return {'t': t, 'u': u[every], 'v': v[every], 'r': r[every], 'psi': psi[every],
            'x': x[every] + 5.0, 'y': y[every] - 3.0, 'north_dot': north_dot[every],
            'east_dot': east_dot[every], 'n': n, 'delta': delta}


def csv_table(truth):
    """Return the trajectory as a logger's table (degrees, knots, rpm, earth frame)."""
    heading = (np.degrees(truth['psi']) + 180.0) % 360.0 - 180.0  # wrapped, as logged
    return pd.DataFrame({
        'time': truth['t'], 'vn_kn': truth['north_dot'] / KNOT,
        've_kn': truth['east_dot'] / KNOT, 'r_deg': np.degrees(truth['r']),
        'hdg_deg': heading, 'north_m': truth['x'], 'east_m': truth['y'],
        'rpm': truth['n'] * 60 / (2 * math.pi), 'rudder_deg': -np.degrees(truth['delta'])})


def spatial_flight(seconds=30.0, seed=0, rate_hz=100.0, fine=10):
    """
    Return a smooth 6-DOF flight (NED/FRD truth), integrated ``fine`` times finer.

    Body rates and velocities are sums of sinusoids; the attitude follows the rates and
    the position the velocity turned by the attitude (integrator's kinematics).
    """
    rng = np.random.default_rng(seed)
    n = int(seconds * rate_hz) * fine + 1
    t = np.arange(n) / (rate_hz * fine)

    def signal(amplitude):
        freq, phase = rng.uniform(0.2, 1.5, 3), rng.uniform(0, 2 * np.pi, 3)
        return amplitude * np.sum([np.sin(2 * np.pi * f * t + ph) for f, ph in
                                   zip(freq, phase, strict=True)], axis=0) / 3

    u, v, w = signal(2.0), signal(2.0), signal(0.5)
    p, q, r = signal(2.0), signal(2.0), signal(0.8)
    phi, theta, psi = np.zeros(n), np.zeros(n), np.zeros(n)
    pos = np.zeros((3, n))
    h = 1.0 / (rate_hz * fine)
    for k in range(n - 1):
        rates = attitude_rates(p[k], q[k], r[k], phi[k], theta[k])
        phi[k + 1], theta[k + 1], psi[k + 1] = (phi[k] + h * rates[0], theta[k] + h * rates[1],
                                                psi[k] + h * rates[2])
        pos[:, k + 1] = pos[:, k] + h * np.array(body_to_ned(u[k], v[k], w[k], phi[k],
                                                             theta[k], psi[k]))
    every = slice(None, None, fine)
    truth = {'t': t[every], 'u': u[every], 'v': v[every], 'w': w[every], 'p': p[every],
             'q': q[every], 'r': r[every], 'phi': phi[every], 'theta': theta[every],
             'psi': psi[every], 'x': pos[0, every], 'y': pos[1, every], 'z': pos[2, every]}
    truth['motors'] = [1600 + 200 * np.sin(2 * np.pi * (0.3 + 0.1 * i) * truth['t'])
                       for i in range(4)]
    return truth
