#!/usr/bin/env python3
"""
Demo: run the simulator node faster than real time and show what it publishes.

Starts the installed ``ship_sim_node simulator`` executable as a separate process (as
``ros2 run`` would), listens on /vessel/odom, /vessel/actuators and /vessel/wind over
DDS on this machine only, then prints a summary and writes a PNG of the track and the
states. Every process it starts is stopped on exit, also on Ctrl-C.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

REPO = Path(__file__).resolve().parents[1]
INSTALL = REPO / 'ros2_ws' / 'install'


def parse_args(argv=None):
    """Parse the command line."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--minutes', type=float, default=10.0,
                        help='simulated minutes to watch (default 10)')
    parser.add_argument('--speed-up', type=float, default=60.0,
                        help='real-time factor of the simulator (default 60)')
    parser.add_argument('--seed', type=int, default=1, help='simulation seed (default 1)')
    parser.add_argument('--out', type=Path, default=REPO / 'out' / 'demo',
                        help='folder for the PNG (default out/demo)')
    args = parser.parse_args(argv)
    if args.minutes <= 0 or not 0.01 <= args.speed_up <= 1000:
        parser.error('--minutes must be > 0 and --speed-up within [0.01, 1000]')
    return args


def start_simulator(seed: int, speed_up: float) -> subprocess.Popen:
    """Start the installed simulator executable in its own process group."""
    exe = INSTALL / 'ship_sim_node' / 'lib' / 'ship_sim_node' / 'simulator'
    if not exe.is_file():
        sys.exit(f'demo: error: {exe} is missing; run `make setup` first')
    return subprocess.Popen(
        [str(exe), '--ros-args', '-p', f'seed:={seed}', '-p', f'real_time_factor:={speed_up}',
         '-p', 'publish_truth:=true', '--log-level', 'warn'],
        start_new_session=True)


def stop(process: subprocess.Popen) -> None:
    """Stop a process group: SIGINT, then SIGKILL if it does not go."""
    if process.poll() is None:
        os.killpg(process.pid, signal.SIGINT)
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()


def collect(seconds: float, speed_up: float):
    """Listen to the simulator's topics until `seconds` of simulated time have arrived."""
    from geometry_msgs.msg import Vector3Stamped
    from nav_msgs.msg import Odometry
    import rclpy
    from sensor_msgs.msg import JointState
    from vessel_ros_bridge import messages as m

    rclpy.init()
    node = rclpy.create_node('demo_listener')
    rows = {'odom': [], 'actuators': [], 'wind': []}
    node.create_subscription(Odometry, m.ODOM_TRUE_TOPIC, lambda msg: rows['odom'].append(
        (m.seconds_from_stamp(msg.header.stamp), m.state_from_odometry(msg))), 100)
    node.create_subscription(JointState, m.ACTUATORS_TOPIC, lambda msg: rows['actuators'].append(
        m.actuators_from_joint_state(msg)), 100)
    node.create_subscription(Vector3Stamped, m.WIND_TOPIC, lambda msg: rows['wind'].append(
        m.measurement_from_wind(msg)), 100)
    deadline = time.monotonic() + 30.0 + 2.0 * seconds / speed_up
    last_report = 0.0
    try:
        while time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
            have = len(rows['odom'])
            if have >= seconds:
                break
            if time.monotonic() - last_report > 2.0:
                print(f'\r  received {have}/{int(seconds)} simulated seconds', end='',
                      file=sys.stderr, flush=True)
                last_report = time.monotonic()
    finally:
        print(file=sys.stderr)
        node.destroy_node()
        rclpy.try_shutdown()
    return rows


def summarize(rows) -> str:
    """Return a human summary of the received run."""
    states = [s for _, s in rows['odom']]
    if len(states) < 2:
        return 'no data arrived'
    speed = [math.hypot(s['u'], s['v']) for s in states]
    distance = math.hypot(states[-1]['x'] - states[0]['x'], states[-1]['y'] - states[0]['y'])
    roll = [abs(math.degrees(s['phi'])) for s in states]
    rpm = [a['n'] * 60 / (2 * math.pi) for a in rows['actuators'] if 'n' in a]
    wind = [w['wind_speed'] for w in rows['wind']]
    lines = [
        f'  simulated time      {len(states)} s ({len(states) / 60:.1f} min)',
        f'  speed over ground   mean {sum(speed) / len(speed):.2f} m/s, '
        f'range {min(speed):.2f}-{max(speed):.2f} m/s',
        f'  distance made good  {distance:.0f} m',
        f'  roll angle          max {max(roll):.2f} deg',
        f'  shaft speed         {min(rpm):.0f}-{max(rpm):.0f} rpm' if rpm else '',
        f'  true wind           mean {sum(wind) / len(wind):.1f} m/s' if wind else '',
    ]
    return '\n'.join(line for line in lines if line)


def plot(rows, path: Path) -> None:
    """Write a PNG of the track (NED, north up) and the five model states over time."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    t0 = rows['odom'][0][0]
    t = [ts - t0 for ts, _ in rows['odom']]
    states = [s for _, s in rows['odom']]
    fig = plt.figure(figsize=(12, 7), constrained_layout=True)
    grid = fig.add_gridspec(5, 2)
    track = fig.add_subplot(grid[:, 0])
    track.plot([s['y'] for s in states], [s['x'] for s in states])
    track.plot(states[0]['y'], states[0]['x'], 'go', label='start')
    track.set(xlabel='east (m)', ylabel='north (m)', title='track (noise-free)', aspect='equal')
    track.legend()
    labels = {'u': 'u (m/s)', 'v': 'v (m/s)', 'p': 'p (rad/s)', 'r': 'r (rad/s)',
              'phi': 'phi (rad)'}
    for i, (key, label) in enumerate(labels.items()):
        ax = fig.add_subplot(grid[i, 1])
        ax.plot(t, [s[key] for s in states], lw=0.8)
        ax.set_ylabel(label)
        if i == len(labels) - 1:
            ax.set_xlabel('simulated time (s)')
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    """Run the demo; return the exit code."""
    args = parse_args(argv)
    seconds = args.minutes * 60.0
    print(f'demo: simulator at {args.speed_up:g}x real time, watching {args.minutes:g} '
          f'simulated minutes (about {seconds / args.speed_up:.0f} s)')
    simulator = start_simulator(args.seed, args.speed_up)
    try:
        rows = collect(seconds, args.speed_up)
    finally:
        stop(simulator)
    if len(rows['odom']) < 2:
        print('demo: error: the simulator published nothing; see its output above',
              file=sys.stderr)
        return 1
    print('demo: what the simulator published\n' + summarize(rows))
    png = args.out / 'simulator.png'
    plot(rows, png)
    print(f'demo: wrote {png}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
