"""
Verify the column layout of the HSVA KVLCC2 zig-zag files (SIMMAN 2008) from the data.

Usage:  .venv/bin/python docs/results/real/analysis/kvlcc2_columns.py [REAL_DIR]
REAL_DIR defaults to ../shared/real relative to the repository root.
Prints the figures quoted in docs/results/real/kvlcc2_columns.md.
"""
from pathlib import Path
import sys

import numpy as np

REPO = Path(__file__).resolve().parents[4]
REAL = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / '..' / 'shared' / 'real'
RAW = REAL / 'kvlcc2_hsva' / 'raw_data'
VENDOR = ['time', 'x0', 'y0', 'psi', 'u', 'v', 'p', 'r', 'delta', 'rev', 'thrust', 'torque']
D, RHO, G = 0.204, 1000.0, 9.81  # propeller diameter (ship_data.yml), fresh water
GM, KXX = 0.125, 0.372 * 1.2688  # from the HSVA test report (KVLCC2), kxx incl. added inertia


def load(f):
    """Return the title line and the numeric table of one HSVA .dat file."""
    with open(f, encoding='cp1252') as fh:
        title = [next(fh).strip() for _ in range(4)][2]
    return title, np.loadtxt(f, skiprows=4, encoding='cp1252')


def rms(a):
    """Return the root mean square of an array."""
    return float(np.sqrt(np.mean(np.square(a))))


def lowpass(x, n=61):
    """Smooth a signal with an n-sample moving average."""
    return np.convolve(x, np.ones(n) / n, 'same')


def r2(y, cols):
    """Fit y by least squares on cols plus a constant; return R^2 and the coefficients."""
    A = np.column_stack(cols + [np.ones_like(y)])
    k, *_ = np.linalg.lstsq(A, y, rcond=None)
    return 1 - np.var(y - A @ k) / np.var(y), k


def ow_J(col, val):
    """Return the advance ratio J at which open-water column col equals val."""
    ow = np.genfromtxt(REAL / 'kvlcc2_hsva' / 'open_water_characteristics.csv',
                       delimiter=',', names=True)
    return float(np.interp(val, ow[col][::-1], ow['J'][::-1]))


def main():
    """Print the column-layout checks for all zig-zag runs."""
    files = sorted(RAW.glob('*.dat'))
    print(f'{len(files)} files in {RAW}')
    hdr = ('run', 'N', 'T[s]', 'dt', 'rms(c5-dx/dt)', 'rms(c5-u_body)', 'rms(c6-dy/dt)',
           'rms(c6-v_body)', 'slope dpsi/dt~c7', 'corr', 'c8 period[s]', 'R2 heel', 'R2 rate',
           '1st rudder', '1st dpsi')
    print(' | '.join(hdr))
    const = set()
    for f in files:
        title, a = load(f)
        t, x, y, psi, c5, c6, c7, c8, delta, rev, thrust, torque = a.T
        const |= {VENDOR[i] for i in range(12) if np.ptp(a[:, i]) == 0}
        dt = np.unique(np.round(np.diff(t), 6))
        dx, dy = np.gradient(x, t), np.gradient(y, t)
        ps = np.radians(psi)
        u_body = np.cos(ps) * dx + np.sin(ps) * dy
        v_body = -np.sin(ps) * dx + np.cos(ps) * dy
        dpsi = np.gradient(psi, t)
        slope = np.dot(dpsi, c7) / np.dot(c7, c7)
        corr = np.corrcoef(dpsi, c7)[0, 1]
        # column 8: roll angle?  spectrum peak of the high-passed signal, static-heel model
        hp = (c8 - lowpass(c8, 201))[200:-200]
        S = np.abs(np.fft.rfft(hp)) ** 2
        fr = np.fft.rfftfreq(len(hp), dt[0])
        band = (fr > 0.2) & (fr < 1.0)
        period = 1 / fr[band][np.argmax(S[band])]
        U = np.hypot(c5, c6)
        s = slice(100, -100)
        r2_heel, k_heel = r2(lowpass(c8)[s], [delta[s], (c7 * U)[s]])
        r2_rate, _ = r2(lowpass(c8)[s], [np.gradient(delta, t)[s], np.gradient(c7, t)[s]])
        i0 = int(np.argmax(np.abs(delta) > 0.5))
        k = i0 + int(np.argmax(np.abs(psi[i0:] - psi[i0]) > 1.0))
        print(f'{f.stem[17:]:9s} {len(t):5d} {t[-1]:6.1f} {dt} {rms(c5 - dx):.4f} '
              f'{rms(c5 - u_body):.3f} {rms(c6 - dy):.4f} '
              f'{rms(c6 - v_body):.3f} {slope:.3f} {corr:.4f} {period:.2f} {r2_heel:.2f} '
              f'(k_delta={k_heel[0]:+.4f}, k_rU={k_heel[1]:+.3f}) {r2_rate:.2f} '
              f'{np.sign(delta[i0]):+.0f}@{t[i0]:.2f}s {np.sign(psi[k] - psi[i0]):+.0f}  '
              f'[{title}]')
    print('constant columns (vendor names):', sorted(const))
    rate = [np.percentile(np.abs(np.gradient(load(f)[1][:, 8], 0.05)), 99) for f in files]
    dmax = [np.abs(load(f)[1][:, 8]).max() for f in files]
    print(f'rudder rate p99 |d delta/dt| {min(rate):.1f}-{max(rate):.1f} deg/s '
          f'(report helm rate 15.8 deg/s); '
          f'max |delta| per run {np.round(dmax, 2)}')
    # plausibility of units with the first second of one run (straight, steady)
    _, a = load(RAW / 'HSVA_CPMC_KVLCC2_Z_10_10_S.dat')
    u0, n, T, Q = a[:20, 4].mean(), a[0, 9], a[:20, 10].mean(), a[:20, 11].mean()
    KT, KQ = T / (RHO * n**2 * D**4), Q / (RHO * n**2 * D**5)
    J_T, J_Q = ow_J('Kt', KT), ow_J('10Kq', 10 * KQ)
    print(f'u0={u0:.3f} m/s -> full scale {u0 * np.sqrt(45.7) / 0.5144:.1f} kn; '
          f'rev={n} -> {n * 60:.0f} rpm (report: 614 rpm model)')
    print(f'thrust {T:.1f} N, torque {Q:.3f} Nm -> '
          f'KT={KT:.3f} (J={J_T:.3f}, w={1 - J_T * n * D / u0:.2f}), '
          f'10KQ={10 * KQ:.3f} (J={J_Q:.3f}, w={1 - J_Q * n * D / u0:.2f}); ship_data w_p0=0.40')
    print(f'expected roll period 2*pi*kxx/sqrt(g*GM) = {2 * np.pi * KXX / np.sqrt(G * GM):.2f} s')
    # course vs heading: heading leads course in turns (drift), both turn the same way
    lead, tot = 0, 0
    for f in files:
        _, a = load(f)
        t, x, y, psi, c7 = a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 6]
        crs = np.degrees(np.arctan2(np.gradient(y, t), np.gradient(x, t)))
        m = np.abs(c7) > 1.0
        lead += np.sum(np.sign(psi[m] - crs[m]) == np.sign(c7[m]))
        tot += m.sum()
    print(f'|r|>1 deg/s: sign(psi - course) == sign(r) in {lead}/{tot} samples '
          f'(psi measured x->y, deg)')


if __name__ == '__main__':
    main()
