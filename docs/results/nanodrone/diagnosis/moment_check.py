#!/usr/bin/env python3
"""
Do the measured rotor speeds predict the body's angular accelerations? Per flight.

    python docs/results/nanodrone/diagnosis/moment_check.py DATASET [--physics FILE]

For each flight of a converted dataset (docs/results/nanodrone/run.sh WORK convert makes
WORK/paper_ds), the angular accelerations the physics gives from the measured state and
rotor speeds (its moments through its inertia) against those of the gyro (the rates'
central differences), both averaged over 0.5 s: the standard deviation of each and their
correlation, per axis (p, q, r). docs/results/nanodrone/diagnosis.md quotes the table:
what the diagnosis' ``rotor_moments`` -1.03 stands for.
"""

import argparse
import sys

import numpy as np

from vessel_datasets.format import read_dataset
from vessel_physics.physics_file import load_physics

AVERAGE_S = 0.5


def main(argv=None) -> int:
    """Print the table (module docstring); return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('dataset')
    parser.add_argument('--physics', help="physics file (default: the vessel file's)")
    args = parser.parse_args(argv)
    ds = read_dataset(args.dataset)
    vessel = ds.vessel
    physics = load_physics(args.physics or vessel.physics, vessel)
    minv_t = np.linalg.inv(physics.mass_matrix()).T
    width = int(round(AVERAGE_S * vessel.rate_hz))
    kernel = np.ones(width) / width
    rates = [vessel.state_index(s) for s in ('p', 'q', 'r')]
    print('| flight | axis | model std (rad/s^2) | gyro std (rad/s^2) | correlation |')
    print('|---|---|---|---|---|')
    for run in ds.run_ids():
        table = ds.load(run)
        z = table[list(vessel.state_names)].to_numpy(float)
        c = table[list(vessel.control_names)].to_numpy(float)
        model = physics.force(z, c) @ minv_t
        gyro = np.gradient(z[:, rates], vessel.dt, axis=0)
        for j, axis in enumerate('pqr'):
            a = np.convolve(model[:, 3 + j], kernel, 'valid')
            b = np.convolve(gyro[:, j], kernel, 'valid')
            print(f'| {run} | {axis} | {a.std():.1f} | {b.std():.1f} | '
                  f'{np.corrcoef(a, b)[0, 1]:+.2f} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
