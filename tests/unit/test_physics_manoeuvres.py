"""Standard manoeuvres of the true patrol vessel: plausible figures, printed with -s."""

import math

import numpy as np
import pytest

from vessel_physics.simulation.config import load_simulation as load_config
from vessel_physics.simulation.operator import RPM
from vessel_physics.simulation.simulator import Simulator

CALM = {'wind': {'enabled': False}, 'waves': {'enabled': False},
        'noise': {'enabled': False}, 'operator': {'enabled': False}, 'warmup_s': 0.0}
SERVICE_RPM = 900.0
LPP = 51.5


def calm_sim(n_runs=1, rate_hz=1.0):
    return Simulator(load_config({**CALM, 'output_rate_hz': rate_hz}), n_runs=n_runs)


def approach(sim, rpm=SERVICE_RPM, seconds=0):
    """Put the vessel on a straight course at the steady speed of ``rpm``."""
    sim.set_state(u=0.0, v=0, p=0, r=0, phi=0, psi=0, x=0, y=0, n=rpm * RPM,
                  delta_port=0, delta_stbd=0)
    periods = int(seconds * sim.config.output_rate_hz)
    for _ in range(periods):
        sim.advance({'n': rpm * RPM, 'delta_port': 0.0, 'delta_stbd': 0.0})
    sim.set_state(psi=0, x=0, y=0)


def test_steady_speed_rises_with_shaft_speed():
    rpm = np.array([366.0, 500.0, 600.0, 700.0, 800.0, SERVICE_RPM, 980.0])
    sim = calm_sim(len(rpm))
    approach(sim)
    for _ in range(400):
        s = sim.advance({'n': rpm * RPM, 'delta_port': 0.0, 'delta_stbd': 0.0})
    speed = s['u_true']
    print('\nsteady speed (m/s) vs shaft speed (rpm):',
          {int(n): round(float(u), 2) for n, u in zip(rpm, speed, strict=True)})
    assert np.all(np.diff(speed) > 0)
    assert speed[rpm == SERVICE_RPM][0] == pytest.approx(8.0, abs=0.1)
    assert 2.5 < speed[0] < 4.0 and speed[-1] < 9.5
    assert np.all(np.abs(s['v_true']) < 1e-6) and np.all(np.abs(s['r_true']) < 1e-9)


def test_turning_circle_at_35_degrees():
    sim = calm_sim()
    approach(sim, seconds=200)
    u0 = sim.state['u'][0]
    rudder = math.radians(35.0)
    track = []
    for _ in range(450):
        s = sim.advance({'n': SERVICE_RPM * RPM, 'delta_port': rudder, 'delta_stbd': rudder})
        track.append((s['x_true'][0], s['y_true'][0], s['psi_true'][0], s['u_true'][0],
                      s['r_true'][0], s['phi_true'][0]))
    x, y, psi, u, r, phi = np.array(track).T
    assert np.all(np.diff(psi) < 0)                       # positive rudder: turn to port
    i90 = np.argmax(psi <= -math.pi / 2)
    i180 = np.argmax(psi <= -math.pi)
    advance, transfer, tactical = x[i90], -y[i90], -y[i180]
    steady_diameter = 2 * u[-1] / abs(r[-1])
    print(f'\nturning circle at 35 deg from {u0:.2f} m/s: advance {advance:.0f} m '
          f'({advance / LPP:.2f} L), transfer {transfer:.0f} m, tactical diameter '
          f'{tactical:.0f} m ({tactical / LPP:.2f} L), steady diameter {steady_diameter:.0f} m '
          f'({steady_diameter / LPP:.2f} L), speed loss {1 - u[-1] / u0:.0%}, '
          f'steady heel {math.degrees(phi[-1]):.2f} deg')
    assert 2.0 < tactical / LPP < 6.0
    assert 2.0 < advance / LPP < 4.5                      # IMO: advance < 4.5 L
    assert 0.05 < 1 - u[-1] / u0 < 0.4
    assert phi[-1] > 0                                    # heels outward (to starboard)


def test_zigzag_10_10():
    sim = calm_sim(rate_hz=10.0)
    approach(sim, seconds=100)
    delta = math.radians(10.0)
    order, heading, switches = delta, [], []
    for i in range(2000):
        s = sim.advance({'n': SERVICE_RPM * RPM, 'delta_port': order, 'delta_stbd': order})
        psi = s['psi_true'][0]
        heading.append(psi)
        # A positive rudder turns the bow to port (psi < 0): counter-rudder at -10 deg.
        if order > 0 and psi <= -delta or order < 0 and psi >= delta:
            order = -order
            switches.append(i)
    heading = np.degrees(np.array(heading))
    overshoots = [np.abs(heading[a:b]).max() - 10.0
                  for a, b in zip(switches, switches[1:] + [len(heading)], strict=True)]
    period = np.diff(switches[::2]).mean() / 10.0
    print(f'\nzig-zag 10/10: first overshoot {overshoots[0]:.2f} deg, second '
          f'{overshoots[1]:.2f} deg, time to first execute {switches[0] / 10:.1f} s, '
          f'period {period:.1f} s')
    assert len(switches) >= 4
    assert 0.5 < overshoots[0] < 8.0 and 0.5 < overshoots[1] < 10.0
    assert 5.0 < switches[0] / 10 < 30.0


@pytest.mark.parametrize('speed, rpm', [(0.0, 0.0), (8.0, SERVICE_RPM)])
def test_roll_free_decay_period(speed, rpm):
    sim = calm_sim(rate_hz=10.0)
    sim.set_state(u=speed, v=0, p=0, r=0, phi=0.1, psi=0, n=rpm * RPM, delta_port=0,
                  delta_stbd=0)
    phi = np.array([sim.advance({'n': rpm * RPM, 'delta_port': 0.0, 'delta_stbd': 0.0})
                    ['phi_true'][0] for _ in range(400)])
    down = np.flatnonzero((phi[:-1] > 0) & (phi[1:] <= 0))
    # Interpolate the zero crossings for a period finer than the 0.1 s samples.
    times = (down + phi[down] / (phi[down] - phi[down + 1])) / 10.0
    period = np.diff(times).mean()
    peaks = [phi[a:b].max() for a, b in zip(down[:-1], down[1:], strict=True)]
    zeta = np.log(peaks[0] / peaks[1]) / (2 * math.pi)
    print(f'\nroll free decay at {speed} m/s: period {period:.2f} s, '
          f'damping ratio {zeta:.3f}')
    assert 5.0 < period < 6.0
    assert 0.02 < zeta < 0.3
    assert abs(phi[-1]) < 0.02
