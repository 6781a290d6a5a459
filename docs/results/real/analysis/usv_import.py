"""
Establish the USV turning test's columns from the data, and draw its imported track.

Usage:  tools/with_env.sh python docs/results/real/analysis/usv_import.py DATASET [REAL_DIR] [OUT]
DATASET is the import of docs/results/real/usv/run.sh; REAL_DIR defaults to
../shared/real relative to the repository root, OUT to docs/results/real/usv.
Prints the figures quoted in docs/results/real/usv_import.md and writes
OUT/track_heading_drift.png: the track with the bow's direction, heading and course
over time, and the drift angle the converter derived.
"""
from pathlib import Path
import sys

import matplotlib
import numpy as np
import pandas as pd

from vessel_datasets.format import read_dataset
from vessel_datasets.quantities import latlon_to_local

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402 - after the backend is chosen

REPO = Path(__file__).resolve().parents[4]
DATASET = Path(sys.argv[1])
REAL = Path(sys.argv[2]) if len(sys.argv) > 2 else REPO / '..' / 'shared' / 'real'
OUT = Path(sys.argv[3]) if len(sys.argv) > 3 else REPO / 'docs' / 'results' / 'real' / 'usv'
KNOT = 1852.0 / 3600.0


raw = pd.read_csv(REAL / 'usv' / 'turnningdata_xy.csv')
t = raw['time'].to_numpy()
steps = np.diff(t)
print(f'rows {len(raw)}, {t[-1]:.0f} s; time steps {steps.min():.2f}-{steps.max():.2f} s, '
      f'median {np.median(steps):.2f} s')
# Printed to 6-7 decimals; compare at 1e-8 deg so float print noise is no change.
fix = (raw['lat'].round(8).diff() != 0) | (raw['lon'].round(8).diff() != 0)
north, east = latlon_to_local(raw['lat'], raw['lon'])
print(f'lat/lon: the position changes in {fix.mean():.0%} of the rows, in steps of 1e-6 deg '
      f'(0.11 m; some rows carry a half step, 5e-7: values between two fixes)')
print(f'heading: deg, 0-360, whole degrees in {np.mean(raw["heading"] % 1 == 0):.0%} of the '
      f'rows; psi column = unwrapped heading in rad: max |psi - unwrap(radians(heading))| '
      f'{np.abs(raw["psi"] - np.unwrap(np.radians(raw["heading"]))).max():.2e} rad')
turning = t > 5
print(f'rudder while turning (t > 5 s): median {raw["rudder"][turning].median():.0f} deg, '
      f'positive in {np.mean(raw["rudder"][turning] > 0):.0%} of the rows, while the '
      f'heading increases (starboard); ruddercommand constant {raw["ruddercommand"].iloc[0]:g}')

dataset = read_dataset(DATASET)
(run,) = dataset.load_split('train').values()
start = dataset.manifest['runs'][0]['source']['start_ns'] / 1e9
drift = np.degrees(np.arctan2(run['v'], run['u']))
steady = run['t'] > 20
ground = np.hypot(run['u'], run['v'])  # the track's speed (the converter's spline)
logged = np.interp(run['t'] + start, t, raw['speed'])
ratio = np.median(logged[steady] / ground[steady])
print(f'speed column / track speed (t > 20 s): median {ratio:.3f}; knots per m/s '
      f'{1 / KNOT:.3f}, km/h per m/s 3.6: the column is in knots '
      f'({abs(ratio * KNOT - 1):.1%} off)')
rate = np.gradient(np.unwrap(run['psi']), run['t'])
course_rate = np.gradient(np.unwrap(np.arctan2(np.gradient(run['y']), np.gradient(run['x']))),
                          run['t'])
agree = np.mean(np.sign(rate[steady]) == np.sign(course_rate[steady]))
print(f'heading and track turn the same way (t > 20 s): {agree:.0%} of the samples, both '
      f'clockwise (increasing): heading north_clockwise')
print(f'imported: {len(run)} samples at 1 Hz; u {run["u"][steady].median():.3f} m/s, '
      f'v {run["v"][steady].median():.3f} m/s, r {np.degrees(run["r"][steady]).median():.2f} '
      f'deg/s (median, t > 20 s); drift angle atan2(v, u) median '
      f'{np.median(drift[steady]):.1f} deg (10-90 %: {np.percentile(drift[steady], 10):.1f} to '
      f'{np.percentile(drift[steady], 90):.1f}); turning radius U/r median '
      f'{np.median(np.hypot(run["u"], run["v"])[steady] / run["r"][steady]):.1f} m')

fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
ax = axes[0]
ax.plot(run['y'], run['x'], color='0.6', lw=1, label='track (1 Hz, from the fixes)')
ax.scatter(east - east[0], north - north[0], s=6, color='k', label='GPS positions (rows)')
every = slice(None, None, 6)
psi = run['psi'].to_numpy()[every]
ax.quiver(run['y'][every], run['x'][every], np.sin(psi), np.cos(psi), color='tab:blue',
          scale=25, width=0.004, label='bow direction (heading)')
ax.set(xlabel='east (m)', ylabel='north (m)', aspect='equal', title='track and heading')
ax.legend(fontsize=8, loc='lower left')
ax = axes[1]
heading_deg = np.degrees(np.unwrap(run['psi']))
track_course = np.degrees(np.unwrap(np.arctan2(np.gradient(run['y']), np.gradient(run['x']))))
track_course += 360.0 * np.round((heading_deg[0] - track_course[0]) / 360.0)
ax.plot(run['t'], heading_deg, label='heading', color='tab:blue')
ax.plot(run['t'], track_course, label='course over ground (track)', color='tab:orange')
ax.set(xlabel='t (s)', ylabel='deg (unwrapped)', title='heading and course')
ax.legend(fontsize=8)
ax = axes[2]
ax.plot(run['t'], drift, color='tab:red')
ax.axhline(0, color='0.7', lw=0.8)
ax.set(xlabel='t (s)', ylabel='atan2(v, u) (deg)',
       title='drift angle from track and heading')
fig.suptitle('USV turning test (GPS, compass and rudder only): body velocities from the '
             'track', fontsize=11)
fig.tight_layout()
OUT.mkdir(parents=True, exist_ok=True)
fig.savefig(OUT / 'track_heading_drift.png', dpi=110)
print(f'wrote {OUT / "track_heading_drift.png"}')
