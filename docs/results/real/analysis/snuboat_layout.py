"""
Establish the array layout of the snuboat rosbag2 recordings from the data.

Usage:  .venv/bin/python docs/results/real/analysis/snuboat_layout.py [REAL_DIR]
REAL_DIR defaults to ../shared/real relative to the repository root.
Prints the figures quoted in docs/results/real/snuboat_layout.md (takes ~10 s).
"""
import collections
from pathlib import Path
import sys

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

REPO = Path(__file__).resolve().parents[4]
REAL = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / '..' / 'shared' / 'real'
SNU = REAL / 'snuboat'
H = 0.05  # resampling step [s] for lag analysis


def wrap(a):
    """Wrap an angle [rad] to [-pi, pi)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


def typestore():
    """Return the ROS 2 Humble typestore extended with the snumsg_pkg messages."""
    ts = get_typestore(Stores.ROS2_HUMBLE)
    types = {}
    for f in sorted((SNU / 'msg').glob('*.msg')):
        types.update(get_types_from_msg(f.read_text(), f'snumsg_pkg/msg/{f.stem}'))
    ts.register(types)
    return ts


def read_bag(path, ts):
    """Read one bag into arrays of /sensor, /cmd and /fb times, ticks and values."""
    rows = collections.defaultdict(list)
    with Reader(path) as reader:
        for con, t_log, raw in reader.messages():
            m = ts.deserialize_cdr(raw, con.msgtype)
            tick = m.tick.sec + 1e-9 * m.tick.nanosec
            if con.topic == '/sensor':
                rows['sensor'].append((t_log * 1e-9, tick, m.status, m.pose.copy(), m.vel.copy()))
            else:
                rows[con.topic.split('_')[1]].append((t_log * 1e-9, tick, m.ctrl.copy()))
    out = {}
    for k in ('sensor', 'cmd', 'fb'):
        r = rows.get(k, [])
        out[k + '_t'] = np.array([x[0] for x in r])
        out[k + '_tick'] = np.array([x[1] for x in r])
    out['status'] = [x[2] for x in rows.get('sensor', [])]
    out['lens'] = collections.Counter((len(x[3]), len(x[4])) for x in rows.get('sensor', []))
    out['lens'].update((len(x[2]),) for k in ('cmd', 'fb') for x in rows.get(k, []))
    out['pose'] = np.array([x[3] for x in rows.get('sensor', [])], float).reshape(-1, 6)
    out['vel'] = np.array([x[4] for x in rows.get('sensor', [])], float).reshape(-1, 6)
    for k in ('cmd', 'fb'):
        out[k] = np.array([x[2] for x in rows.get(k, [])], float).reshape(-1, 4)
    return out


def clean(b):
    """Return valid motion-capture samples: no exact duplicates, status '01', finite pose."""
    P, V, t = b['pose'], b['vel'], b['sensor_t']
    if len(t) == 0:
        return t, P, V
    keep = np.r_[True, ~np.all(P[1:] == P[:-1], axis=1)]
    keep &= (np.array(b['status']) == '01') & np.isfinite(P).all(1)
    return t[keep], P[keep], V[keep]


def moving(b):
    """Return whether a bag has >= 100 valid samples and > 2 m of travel."""
    t, P, _ = clean(b)
    return len(t) >= 100 and np.ptp(P[:, 0]) + np.ptp(P[:, 1]) > 2


def steady_segments(b, min_len=6.0, skip=4.0):
    """
    Yield (fb row, sensor mask, clean samples) for constant-feedback stretches.

    A stretch is one where the feedback propeller speed and rudder angle are constant.
    """
    t, P, V = clean(b)
    F, tf = b['fb'], b['fb_t']
    key = np.round(F[:, [0, 2]])
    cut = np.r_[0, np.where(np.any(np.diff(key, axis=0) != 0, axis=1))[0] + 1, len(F)]
    for a, e in zip(cut[:-1], cut[1:], strict=True):
        if tf[e - 1] - tf[a] >= min_len:
            m = (t > tf[a] + skip) & (t <= tf[e - 1]) & np.isfinite(V[:, 5])
            if m.sum() >= 10:
                yield F[a], m, (t, P, V)


def inventory(bags):
    """Print array lengths, status strings and a bag classification; return usable bags."""
    print('== 1. inventory')
    lens = collections.Counter()
    for b in bags.values():
        lens.update(b['lens'])
    print('array lengths (pose, vel) / (ctrl,):', dict(lens))
    status = collections.Counter(s for b in bags.values() for s in b['status'])
    print('status strings:', dict(status))
    cls = collections.defaultdict(list)
    for name, b in bags.items():
        t, P, _ = clean(b)
        dur = t[-1] - t[0] if len(t) > 1 else 0.0
        st = set(b['status'])
        if len(b['sensor_t']) == 0:
            c = 'empty (no /sensor)'
        elif st & {'040', '041'}:
            c = 'SILS status 04x (simulation / sensor off)'
        elif len(t) < 20:
            c = 'no valid tracking (pose NaN or < 20 samples)'
        elif not moving(b) or dur < 20:
            c = 'short or not moving (< 20 s valid or < 2 m travelled)'
        elif len(b['fb']) == 0 or np.all(b['fb'][:, 0] == 0):
            c = 'moving but no propeller feedback'
        else:
            c = 'usable'
        cls[c].append((name, dur))
    for c, v in cls.items():
        print(f'{c}: {len(v)} bags, valid duration total {sum(d for _, d in v):.0f} s')
    use = sorted(cls['usable'], key=lambda x: x[0])
    print('usable:', ', '.join(f"{n.replace('FREE_RUNNING_', '')} ({d:.0f}s)" for n, d in use))
    return [n for n, _ in use]


def timing(bags):
    """Print message rates, log-time vs tick offsets, gaps and repeated poses."""
    print('== 2. timing')
    for k in ('sensor', 'cmd', 'fb'):
        rates, offs, gaps = [], [], 0
        for b in bags.values():
            t = b[k + '_t']
            if len(t) > 20:
                rates.append((len(t) - 1) / (t[-1] - t[0]))
                offs.append((t - b[k + '_tick']) * 1e3)
                gaps += int(np.sum(np.diff(t) > 0.3))
        o = np.concatenate(offs)
        print(f'/{k}: rate median {np.median(rates):.2f} Hz '
              f'(min {min(rates):.2f}, max {max(rates):.2f}); '
              f'log time - tick: median {np.median(o):.2f} ms, p99 {np.percentile(o, 99):.2f} ms, '
              f'max {o.max():.0f} ms; gaps > 0.3 s: {gaps}')
    dup = {n: np.mean(np.all(b['pose'][1:] == b['pose'][:-1], axis=1))
           for n, b in bags.items() if len(b['sensor_t']) > 50
           and (len(b['sensor_t']) - 1) / (b['sensor_t'][-1] - b['sensor_t'][0]) > 15}
    print(f'bags with /sensor at ~20 Hz: {len(dup)}; '
          f'fraction of messages repeating the previous pose '
          f'exactly: {np.round(sorted(dup.values()), 2)}')


def pose_vel(bags, use):
    """Print checks of the pose and vel layout: frames, heading lag, rates, flips."""
    print('== 3. pose / vel')
    P = np.concatenate([b['pose'] for b in bags.values()])
    V = np.concatenate([b['vel'] for b in bags.values()])
    print(f'messages {len(P)}; NaN per pose element {np.isnan(P).sum(0)}; '
          f'per vel element {np.isnan(V).sum(0)}')
    m = np.isfinite(P[:, 2]) & np.isfinite(V[:, 2])
    print(f'vel[2] == pose[2] exactly in {np.sum(P[m, 2] == V[m, 2])}/{m.sum()} finite messages')
    lags, ku, kv, e0, eb = [], [], [], [], []
    straight, sgn, ndt, spikes, kp, kq = [], [0, 0], [], 0, [], []
    for n in use:
        t, P, V = clean(bags[n])
        psi_u = np.unwrap(P[:, 5])
        # (a) lag between heading and position-derived quantities
        tg = np.arange(t[0] + 3, t[-1], H)
        x, y = np.interp(tg, t, P[:, 0]), np.interp(tg, t, P[:, 1])
        u, v = np.interp(tg, t, V[:, 0]), np.interp(tg, t, V[:, 1])
        dx, dy = np.gradient(x, H), np.gradient(y, H)
        mv = (np.hypot(dx, dy) > 0.15) & np.isfinite(u) & np.isfinite(v)
        err, fits = [], []
        for L in range(31):
            ps = np.interp(tg - L * H, t, psi_u)
            ub, vb = np.cos(ps) * dx + np.sin(ps) * dy, -np.sin(ps) * dx + np.cos(ps) * dy
            err.append(np.sqrt(np.mean((ub[mv] - u[mv]) ** 2 + (vb[mv] - v[mv]) ** 2)))
            fits.append((np.dot(ub[mv], u[mv]) / np.dot(u[mv], u[mv]),
                         np.dot(vb[mv], v[mv]) / np.dot(v[mv], v[mv])))
        best = int(np.argmin(err))
        lags.append(best * H), ku.append(fits[best][0]), kv.append(fits[best][1])
        e0.append(err[0]), eb.append(err[best])
        # (b) course vs (delayed) heading on straight runs; turning direction in turns
        dx, dy = np.gradient(P[:, 0], t), np.gradient(P[:, 1], t)
        crs = np.arctan2(dy, dx)
        rr = np.gradient(psi_u, t)
        quiet = np.array([np.all(np.abs(rr[(t > ti - 2.5) & (t <= ti)]) < 0.05) for ti in t])
        ms = quiet & (np.hypot(dx, dy) > 0.2) & (t > t[0] + 3)
        straight.append(np.degrees(wrap(crs - np.interp(t - 0.9, t, psi_u)))[ms])
        dcrs = np.gradient(np.unwrap(crs), t)
        mt = (np.hypot(dx, dy) > 0.2) & (np.abs(rr) > 0.1) & (np.abs(dcrs) > 0.05)
        sgn[0] += int(np.sum(np.sign(dcrs[mt]) == np.sign(rr[mt])))
        sgn[1] += int(mt.sum())
        # (c) vel[5] vs backward difference of the heading;
        #     vel[3], vel[4] vs derivatives of roll, pitch
        rb = np.r_[np.nan, np.diff(psi_u) / np.diff(t)]
        ok = np.isfinite(V[:, 5]) & np.isfinite(rb)
        ndt.append(np.abs(V[ok, 5] - rb[ok]))
        spikes += int(np.sum(np.abs(V[:, 5]) > 1.5))
        for i, lst in ((3, kp), (4, kq)):
            ok = np.isfinite(V[:, i])
            d = np.gradient(P[:, i], t)
            lst.append(np.corrcoef(d[ok], V[ok, i])[0, 1])
    print(f'best delay of heading to match vel[0:2] with rotated d(x,y)/dt: '
          f'median {np.median(lags):.2f} s '
          f'(IQR {np.percentile(lags, 25):.2f}-{np.percentile(lags, 75):.2f}, {len(lags)} bags); '
          f'rms error {np.median(e0):.3f} m/s at 0 s -> {np.median(eb):.3f} m/s at best; '
          f'regression slope u {np.median(ku):.3f}, v {np.median(kv):.3f}')
    s = np.concatenate(straight)
    print(f'straight runs (|r|<0.05 rad/s for 2.5 s, >0.2 m/s): '
          f'{len(s)} samples in {len(straight)} bags, '
          f'atan2(dy,dx) - pose[5](t-0.9s): median {np.median(s):+.2f} deg, '
          f'median |.| {np.median(np.abs(s)):.2f} deg, '
          f'p90 |.| {np.percentile(np.abs(s), 90):.1f} deg')
    print(f'turning samples where course rate and heading rate have the same sign: '
          f'{sgn[0]}/{sgn[1]}')
    d = np.concatenate(ndt)
    print(f'|vel[5] - backward diff(pose[5])/dt|: median {np.median(d):.4f} rad/s, '
          f'p99 {np.percentile(d, 99):.4f}; '
          f'|vel[5]| > 1.5 rad/s: {spikes} samples')
    print(f'corr(vel[3], d pose[3]/dt) median {np.median(kp):.2f}; '
          f'corr(vel[4], d pose[4]/dt) median {np.median(kq):.2f}')
    ang, zero = 0, 0
    for b in bags.values():
        t, P, _ = clean(b)
        ang += int(np.sum((np.abs(P[:, 3]) > 0.2) | (np.abs(P[:, 4]) > 0.2)))
        zero += int(np.sum(np.all(b['pose'] == 0, axis=1)))
    print(f'valid samples with |roll| or |pitch| > 0.2 rad (tracking flips): {ang}; '
          f'messages with an all-zero pose: {zero}')


def controls(bags, use):
    """Print checks of the cmd / fb ctrl layout, reversing, slew, delay and signs."""
    print('== 4. ctrl')
    C = np.concatenate([b['cmd'] for b in bags.values()])
    F = np.concatenate([b['fb'] for b in bags.values()])
    for k, A in (('cmd', C), ('fb', F)):
        print(f'{k}: {len(A)} msgs, ctrl[0]==ctrl[1] in {np.sum(A[:, 0] == A[:, 1])}, '
              f'max|ctrl[0]-ctrl[1]| {np.nanmax(np.abs(A[:, 0] - A[:, 1])):.3f}, '
              f'max|ctrl[2]-ctrl[3]| {np.nanmax(np.abs(A[:, 2] - A[:, 3])):.3f}, '
              f'NaN per element {np.isnan(A).sum(0)}, '
              f'min {np.round(np.nanmin(A, 0), 1)}, max {np.round(np.nanmax(A, 0), 1)}, '
              f'ctrl[0] < 0: {np.sum(A[:, 0] < 0)} (< -30: {np.sum(A[:, 0] < -30)})')
    print('cmd propeller set-points:',
          dict(sorted(collections.Counter(np.round(C[:, 0], 1)).items())))
    print('cmd rudder set-points:',
          dict(sorted(collections.Counter(np.round(C[np.isfinite(C[:, 2]), 2])).items())))
    # reversing: negative feedback while the command is positive
    for n, b in bags.items():
        Fb, tf = b['fb'], b['fb_t']
        neg = Fb[:, 0] < -30
        if neg.sum() >= 5:
            i = np.where(neg)[0]
            T0 = b['sensor_t'][0] if len(b['sensor_t']) else tf[0]
            c = np.interp(tf[i[0]], b['cmd_t'], b['cmd'][:, 0]) if len(b['cmd']) else np.nan
            tt, P, V = clean(b)
            u = [np.nanmedian(V[(tt > a) & (tt < a + 1), 0])
                 if np.any((tt > a) & (tt < a + 1)) else np.nan
                 for a in (tf[i[0]] - 1, tf[i[-1]] - 1)]
            print(f"  fb < -30 in {n.replace('FREE_RUNNING_', ''):20s} "
                  f"{tf[i[0]] - T0:5.1f}-{tf[i[-1]] - T0:5.1f} s "
                  f"of {tf[-1] - T0:5.1f} s ({neg.sum()} msgs), cmd there {c:.1f}, "
                  f"u {u[0]:.2f} -> {u[1]:.2f} m/s")
    # feedback rudder slew rate and response delay to command steps
    slew, delay = [], []
    for n in use:
        b = bags[n]
        Fb, tf, Cm, tc = b['fb'], b['fb_t'], b['cmd'], b['cmd_t']
        d = np.diff(Fb[:, 2]) / np.diff(tf)
        slew += list(np.abs(d[np.abs(d) > 0.5]))
        for j in np.where(np.abs(np.diff(Cm[:, 0])) > 0.5)[0]:
            k = np.searchsorted(tf, tc[j + 1])
            hit = np.where(np.abs(Fb[k:k + 20, 0] - Cm[j + 1, 0]) < 0.1)[0]
            if len(hit):
                delay.append(tf[k + hit[0]] - tc[j + 1])
    print(f'fb rudder slew: median {np.median(slew):.2f} deg/s; '
          f'fb propeller reaches a new set-point '
          f'{np.median(delay):.2f} s after the command '
          f'(median of {len(delay)} steps, max {np.max(delay):.2f} s)')
    # rudder sign vs steady yaw rate; roll sign in turns; squat
    tab, roll, dz = collections.defaultdict(list), [0, 0], []
    for n in use:
        b = bags[n]
        _, P0, _ = clean(b)
        for f, m, (_t, P, V) in steady_segments(b):
            r = np.median(V[m, 5])
            tab[int(round(f[2]))].append(r)
            if abs(r) > 0.05:
                roll[0] += int(np.sign(np.median(P[m, 3])) == -np.sign(r))
                roll[1] += 1
            dz.append(np.median(P[m, 2]) - np.median(P0[:5, 2]))
    print('steady segments (fb constant >= 6 s, first 4 s skipped): fb rudder -> median vel[5]')
    for k in sorted(tab):
        v = np.array(tab[k])
        print(f'  rudder {k:+3d} deg: r = {np.median(v):+.3f} rad/s '
              f'({np.degrees(np.median(v)):+.1f} deg/s), '
              f'{len(v)} segments, sign(r) == sign(rudder) in {np.sum(np.sign(v) == np.sign(k))}')
    print(f'turning segments with roll of opposite sign to r '
          f'(outward heel if r>0 = starboard turn): '
          f'{roll[0]}/{roll[1]}; pose[2] increase vs start while moving: '
          f'median {1e3 * np.median(dz):.1f} mm, '
          f'positive in {np.mean(np.array(dz) > 0):.0%}')


def main():
    """Read all bags and print the layout checks."""
    ts = typestore()
    dirs = sorted(p for p in (SNU / 'bags').iterdir() if (p / 'metadata.yaml').exists())
    bags = {d.name: read_bag(d, ts) for d in dirs}
    print(f"{len(bags)} bags in {SNU / 'bags'}")
    use = inventory(bags)
    timing(bags)
    pose_vel(bags, use)
    controls(bags, use)


if __name__ == '__main__':
    main()
