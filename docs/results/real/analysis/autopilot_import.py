"""
Describe a real ArduSub DataFlash log and draw what its import holds.

Usage:  tools/with_env.sh python docs/results/real/analysis/autopilot_import.py LOG DATASET [OUT]
LOG is the .BIN file, DATASET its import by docs/results/real/autopilot/run.sh, OUT
defaults to docs/results/real/autopilot. Prints the figures quoted in
docs/results/real/autopilot_import.md (messages and rates, the vehicle's parameters the
map uses, arming, the spread of every mapped quantity) and writes OUT/import.png: the
EKF's position, heading, body velocities, yaw rate and thrust commands over time.
"""
from collections import Counter
from pathlib import Path
import sys

import matplotlib
import numpy as np

from vessel_datasets.format import read_dataset

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402 - after the backend is chosen
from pymavlink.DFReader import DFReader_binary  # noqa: E402 - after the backend, as above

REPO = Path(__file__).resolve().parents[4]
LOG = Path(sys.argv[1])
DATASET = Path(sys.argv[2])
OUT = Path(sys.argv[3]) if len(sys.argv) > 3 else REPO / 'docs' / 'results' / 'real' / 'autopilot'
MAPPED = ('ATT', 'XKF1', 'IMU', 'RCOU')
PARAMS = ('FRAME_CONFIG', 'MOT_PWM_MIN', 'MOT_PWM_MAX', 'GPS_TYPE', 'EK3_SRC1_POSXY',
          'EK3_SRC1_VELXY', 'LOG_DISARMED') + tuple(f'MOT_{i}_DIRECTION' for i in range(1, 7)) \
    + tuple(f'SERVO{i}_FUNCTION' for i in range(1, 7))

log = DFReader_binary(str(LOG), zero_time_base=True)
counts, first, last, params, events = Counter(), {}, {}, {}, []
while (m := log.recv_msg()) is not None:
    kind = m.get_type()
    counts[kind] += 1
    us = getattr(m, 'TimeUS', None)
    if us is not None:
        first.setdefault(kind, us)
        last[kind] = us
    if kind == 'PARM':
        params[m.Name] = m.Value
    elif kind in ('MSG', 'MODE', 'ARM'):
        events.append(f'{us / 1e6:8.2f} s {kind} ' + ', '.join(
            f'{k}={v}' for k, v in m.to_dict().items() if k not in ('mavpackettype', 'TimeUS')))
start = min(first.values())
print(f'{LOG.name}: {sum(counts.values())} messages of {len(counts)} types, '
      f'{(max(last.values()) - start) / 1e6:.1f} s of boot time '
      f'{start / 1e6:.1f}..{max(last.values()) / 1e6:.1f} s')
print('no GPS, POS or other position message' if not {'GPS', 'POS'} & set(counts)
      else f'position messages: {sorted({"GPS", "POS"} & set(counts))}')
for kind in MAPPED:
    span = (last[kind] - first[kind]) / 1e6
    print(f'  {kind}: {counts[kind]} messages, {(counts[kind] - 1) / span:.1f} Hz')
print('parameters the map and this account use: ' + ', '.join(
    f'{k} {params[k]:g}' for k in PARAMS if k in params))
print('events:')
for line in events:
    print('  ' + line)

dataset = read_dataset(DATASET)
(run,) = dataset.load_split('train').values()
print(f'import: {len(run)} samples at {dataset.manifest["vessel"]["rate_hz"]:g} Hz, '
      f'{run["t"].iloc[-1]:.1f} s')
spread = {
    'u (m/s)': run['u'], 'v (m/s)': run['v'], 'r (deg/s)': np.degrees(run['r']),
    'psi (deg)': np.degrees(run['psi']), 'x (m)': run['x'], 'y (m)': run['y'],
    **{f'{m} (1)': run[m] for m in (f'motor{i}' for i in range(1, 7))}}
for name, values in spread.items():
    print(f'  {name:10s} min {values.min():+.4f}  max {values.max():+.4f}  '
          f'rms about the mean {values.std():.4f}')

fig, ax = plt.subplots(4, 1, figsize=(8, 9), sharex=True)
ax[0].plot(run['t'], run['x'], label='x (north)')
ax[0].plot(run['t'], run['y'], label='y (east)')
ax[0].set_ylabel('EKF position, m')
ax[1].plot(run['t'], np.degrees(run['psi']))
ax[1].set_ylabel('heading, deg')
ax[2].plot(run['t'], run['u'], label='u')
ax[2].plot(run['t'], run['v'], label='v')
ax[2].plot(run['t'], run['r'], label='r (rad/s)')
ax[2].set_ylabel('body velocities')
for i in range(1, 7):
    ax[3].plot(run['t'], run[f'motor{i}'], label=f'motor{i}')
ax[3].set_ylabel('thrust command, -1..1')
ax[3].set_xlabel('t, s (from the start of the run)')
for a in ax:
    a.grid(True, alpha=0.3)
    if a.get_legend_handles_labels()[0]:
        a.legend(loc='upper right', fontsize=8, ncol=3)
fig.suptitle(f'{LOG.name} (ArduSub) as imported: a vehicle standing still')
fig.tight_layout()
fig.savefig(OUT / 'import.png', dpi=90)
