"""
Error measures of multi-step quadrotor forecasts, as the nano-drone benchmark defines them.

Pure numpy and free of package imports, so that both the product and the bench-only
peers' environment (``offline/peers/``, run with ``.venv-bench``) can import this one
file. The benchmark is Busetto et al., "Nonlinear system identification for a nano-drone
benchmark", Control Engineering Practice 172 (2026) 106871; its measures are those of its
``utils/metrics_utils.py`` (``compute_errors``) as ``results/model_comparison.py`` applies
them.

Quantities, units and frames (a forecast is an array ``(B, H, ...)``: B windows, H steps,
step h = 1..H predicting the sample h steps after the window's initial state):

- position ``p``: world frame, m;
- velocity ``v``: world frame, m/s;
- attitude ``q``: unit quaternion ``(x, y, z, w)`` (scalar last), rotating body-frame
  vectors into the world frame (world-from-body), dimensionless;
- body rates ``w``: angular velocity in the body frame, rad/s.

The benchmark's definitions, per horizon step h (means over the windows):

- ``MAE_p,h = mean ||p_true - p_pred||`` (Euclidean norm, m), likewise ``MAE_v,h``
  (m/s) and ``MAE_w,h`` (rad/s): the mean of the error norms, not an RMSE;
- ``MAE_R,h = mean 2 atan2(||e_xyz||, e_w)`` (rad) with ``e = conj(q_true) * q_pred``
  (Hamilton product): the geodesic angle of the relative rotation. As in the benchmark the
  sign of ``e_w`` is kept, so a prediction whose quaternion has the opposite sign of the
  truth's scores ``2 pi - angle``; ``shortest=True`` gives the usual angle in [0, pi];
- the "simulation error" of a quantity: the sum of its MAE over h = 1..50.

The benchmark holds attitude as the so(3) logarithm (rotation vector, rad) and turns it
into quaternions with ``scipy``'s ``Rotation.from_rotvec``; ``rotvec_to_quat`` is that map
and ``quat_to_rotvec`` the logarithm as its data set computes it (pytorch3d's
``quaternion_to_axis_angle``: ``2 atan2(|v|, w) v / |v|`` scaled by the quaternion's norm,
with no sign canonicalisation).
"""

import numpy as np

QUANTITIES = ('position', 'velocity', 'attitude', 'body_rates')


def quat_conj(q):
    """Conjugate of quaternions ``(..., 4)`` in ``(x, y, z, w)`` order."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([-q[..., :3], q[..., 3:]], axis=-1)


def quat_multiply(a, b):
    """Hamilton product ``a * b`` of quaternions ``(..., 4)`` in ``(x, y, z, w)`` order."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    x1, y1, z1, w1 = np.moveaxis(a, -1, 0)
    x2, y2, z2, w2 = np.moveaxis(b, -1, 0)
    return np.stack([
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
    ], axis=-1)


def geodesic_angle(q_true, q_pred, shortest=False):
    """
    Angle (rad) of the rotation from ``q_true`` to ``q_pred``, ``(...)`` from ``(..., 4)``.

    The benchmark's ``2 atan2(||e_xyz||, e_w)`` of ``e = conj(q_true) * q_pred`` (in
    [0, 2 pi]); ``shortest=True`` folds it to [0, pi], the same for ``q`` and ``-q``.
    """
    e = quat_multiply(quat_conj(q_true), q_pred)
    w = np.abs(e[..., 3]) if shortest else e[..., 3]
    return 2.0 * np.arctan2(np.linalg.norm(e[..., :3], axis=-1), w)


def rotvec_to_quat(r):
    """
    Map rotation vectors ``(..., 3)`` (rad) to unit quaternions ``(..., 4)``, ``(x, y, z, w)``.

    The exponential map as ``scipy.spatial.transform.Rotation.from_rotvec`` computes it:
    ``(sin(a/2) r/a, cos(a/2))`` with ``a = |r|``, a Taylor series for small ``a``.
    """
    r = np.asarray(r, dtype=float)
    angle = np.linalg.norm(r, axis=-1, keepdims=True)
    small = angle <= 1e-3
    a2 = angle * angle
    safe = np.where(small, 1.0, angle)
    scale = np.where(small, 0.5 - a2 / 48.0 + a2 * a2 / 3840.0, np.sin(0.5 * safe) / safe)
    return np.concatenate([scale * r, np.cos(0.5 * angle)], axis=-1)


def quat_to_rotvec(q):
    """
    Rotation vectors ``(..., 3)`` (rad) of quaternions ``(..., 4)``, ``(x, y, z, w)``.

    The logarithm as the benchmark's data set takes it (pytorch3d's
    ``quaternion_to_axis_angle``): ``v * 2 h / sin(h)`` with ``h = atan2(|v|, w)``
    (``2 v`` at ``h = 0``). For a unit quaternion that is the axis times the angle; the
    quaternion is neither normalised nor sign-canonicalised first.
    """
    q = np.asarray(q, dtype=float)
    v = q[..., :3]
    half = np.arctan2(np.linalg.norm(v, axis=-1, keepdims=True), q[..., 3:])
    sinc = np.sinc(half / np.pi)  # sin(h) / h, 1 at h = 0
    return v * (2.0 / sinc)


def errors_per_step(truth, pred, shortest=False):
    """
    Error of each window and step: ``{quantity: (B, H)}`` from two dicts of arrays.

    ``truth`` and ``pred`` hold ``position`` and ``velocity`` ``(B, H, 3)`` (m, m/s, world),
    ``attitude`` ``(B, H, 4)`` (unit quaternions ``(x, y, z, w)``, world-from-body) and
    ``body_rates`` ``(B, H, 3)`` (rad/s, body); quantities missing from either are
    skipped. Position, velocity and body rates give the Euclidean norm of the difference,
    attitude the geodesic angle (rad, see ``geodesic_angle``).
    """
    out = {}
    for name in QUANTITIES:
        if name not in truth or name not in pred:
            continue
        t = np.asarray(truth[name], dtype=float)
        p = np.asarray(pred[name], dtype=float)
        if t.shape != p.shape:
            raise ValueError(f'{name}: truth {t.shape} and prediction {p.shape} differ')
        if name == 'attitude':
            out[name] = geodesic_angle(t, p, shortest=shortest)
        else:
            out[name] = np.linalg.norm(t - p, axis=-1)
    return out


def mae_per_step(errors):
    """Mean over the windows of each step's error: ``{quantity: (H,)}``, index 0 is h = 1."""
    return {name: np.asarray(e, dtype=float).mean(axis=0) for name, e in errors.items()}


def simulation_error(mae, steps=50):
    """Sum of the per-step MAE over h = 1..steps (the benchmark's "h = 1:50" column)."""
    out = {}
    for name, m in mae.items():
        m = np.asarray(m, dtype=float)
        if len(m) < steps:
            raise ValueError(f'{name}: {len(m)} steps, fewer than {steps}')
        out[name] = float(m[:steps].sum())
    return out


def benchmark_table_mae(first_truth, pred, shortest=False):
    """
    Per-step MAE exactly as the benchmark's ``compute_errors`` aligns truth and forecast.

    Its table keeps, for each window, only the truth one step ahead (``first_truth``, the
    dict of ``errors_per_step`` with arrays ``(B, ...)``) and takes the truth of step h of
    window i from window ``i + h - 1``'s, the windows of all test flights being one
    sequence; the last ``h - 1`` forecasts of step h are dropped. Within a flight that is
    the true state h steps ahead; across the junction of two flights it pairs a forecast
    with the next flight's first states (``h - 1`` such pairs per junction and step).
    ``pred`` arrays are ``(B, H, ...)``. Returns ``{quantity: (H,)}``.
    """
    out = {}
    for name in QUANTITIES:
        if name not in first_truth or name not in pred:
            continue
        t = np.asarray(first_truth[name], dtype=float)
        p = np.asarray(pred[name], dtype=float)
        n, steps = p.shape[:2]
        if t.shape[0] != n:
            raise ValueError(f'{name}: {t.shape[0]} truths for {n} windows')
        values = np.empty(steps)
        for h in range(1, steps + 1):
            tt = t[h - 1:]
            pp = p[:n - h + 1, h - 1]
            if name == 'attitude':
                e = geodesic_angle(tt, pp, shortest=shortest)
            else:
                e = np.linalg.norm(tt - pp, axis=-1)
            values[h - 1] = e.mean()
        out[name] = values
    return out
