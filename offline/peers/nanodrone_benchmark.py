#!/usr/bin/env python3
r"""
Run the nano-drone benchmark's reference models as peers: open-loop forecasts to an .npz.

    .venv-bench/bin/python offline/peers/nanodrone_benchmark.py \
        --flights ../shared/real/nanodrone/test/melon_20251017_run5.parquet \
        --out out/peers/melon_run5.npz [--horizon 50] [--stride 1] \
        [--models physics,mlp,hybrid,lstm] [--repo SNAPSHOT] [--commit HEAD]

Runs in the bench-only environment (``tools/setup.sh bench``), never in the product's.
The benchmark is Busetto et al., "Nonlinear system identification for a nano-drone
benchmark", CEP 2026 (repository idsia-robotics/nanodrone-sysid-benchmark). Its model
files are read from a snapshot of that repository (a bare git directory, read with
``git show``, or a checked-out tree), in memory; nothing of theirs is copied here.

For every flight (the shared parquet files, with motor speeds in eRPM, or the benchmark's
own CSV files, with ``m*_rads``) and every ``--stride``-th start row k (k + H < rows) each
model forecasts rows k+1..k+H from the state of row k and the motor speeds of rows
k..k+H-1, as the benchmark's ``QuadDataset`` windows them. What the benchmark does, and
where this adapter must differ, is in docs/results/nanodrone/benchmark_models.md:

- physics: their rigid-body model with RK4 (``PhysQuadModel``, the parameters of their
  ``test/test_physics.py``; it has no weights). Their ONNX export of it is not used: it
  was made for timing with other parameters (m = 0.032 kg).
- mlp: their ``out/export/residual/residual.onnx`` run by onnxruntime (equal to
  ``out/models/residual_random_square_chirp.pt``), scaled by ``scalers/residual_...``.
- hybrid: physics + MLP residual from ``out/models/phys+res_random_square_chirp.pt``
  (its ONNX export holds an untrained residual and unit scalers: a timing artefact).
- lstm: ``out/models/lstm_v2_random_square_chirp.pt`` as of commit 5ba5fc5, the one the
  paper's table scores (``--lstm head``: HEAD's ``lstm_random_square_chirp.pt``, a later
  run saved at epoch 8); its ONNX pair is untrained and carries no recurrent state.
- naive (optional): the state held constant, the benchmark's baseline.

The .npz holds ``flights`` (the names), and per flight ``NAME.start`` (parquet row of each
window's initial state) and ``NAME.MODEL.QUANTITY`` arrays (B, H, ...) for MODEL in the
models run and ``truth``: ``position`` (world, m), ``velocity`` (world, m/s), ``attitude``
(unit quaternion x, y, z, w, world-from-body), ``body_rates`` (body, rad/s). A JSON file
beside it (same name, .json) says what was run: model files and their SHA-256, the
repository commit, the preprocessing.
"""

import argparse
import collections
import hashlib
import importlib.util
import io
import json
import os
from pathlib import Path
import pickle
import subprocess
import sys
import time
import zipfile

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_SNAPSHOT = REPO_ROOT.parent / '.mirror' / 'idsia-robotics+nanodrone-sysid-benchmark' \
    / 'repo'
REPOSITORY = 'idsia-robotics/nanodrone-sysid-benchmark'
MODELS = ('physics', 'mlp', 'hybrid', 'lstm')
ALL_MODELS = MODELS + ('naive',)
# eRPM -> rad/s as the benchmark's processing converts motor speeds (its
# csv_to_processed notebook, convert_erpm_to_rads): 2 pi / (6 * 60).
ERPM_TO_RADS = 2.0 * np.pi / (6.0 * 60.0)
# The physics model's parameters as the benchmark evaluates it (test/test_physics.py and
# test/test_phys+res.py; arm, Kt, Kc are PhysQuadModel's defaults).
PHYSICS = {
    'g': 9.81, 'm': 0.045, 'J_diag': [2.3951e-5, 2.3951e-5, 3.2347e-6],
    'thrust_to_weight': 2.0, 'max_torque': [1e-2, 1e-2, 3e-3],
    'arm_length': 0.0353, 'Kt': 3.72e-08, 'Kc': 7.74e-12, 'dt': 0.01,
}
FILES = {
    'mlp': ('out/export/residual/residual.onnx',
            'scalers/residual_random_square_chirp/x_scaler.pkl',
            'scalers/residual_random_square_chirp/u_scaler.pkl'),
    'mlp_weights': ('out/models/residual_random_square_chirp.pt',),
    'hybrid': ('out/models/phys+res_random_square_chirp.pt',
               'scalers/phys+res_random_square_chirp/x_scaler.pkl',
               'scalers/phys+res_random_square_chirp/u_scaler.pkl'),
    'lstm': ('out/models/lstm_random_square_chirp.pt',
             'scalers/lstm_random_square_chirp/x_scaler.pkl',
             'scalers/lstm_random_square_chirp/u_scaler.pkl'),
    # The LSTM whose forecasts the paper's table scores: lstm_v2, removed from the
    # repository in 3365188 (HEAD's lstm_random_square_chirp.pt is a later run stopped at
    # epoch 8); read at the last commit that has it, with its scalers of that commit.
    'lstm_published': ('out/models/lstm_v2_random_square_chirp.pt',
                       'scalers/lstm_v2_random_square_chirp/x_scaler.pkl',
                       'scalers/lstm_v2_random_square_chirp/u_scaler.pkl'),
}
LSTM_PUBLISHED_COMMIT = '5ba5fc5f82415c69d3954423534b91aa3a5b84fe'
F32 = np.float32


class AdapterError(Exception):
    """A failure explained in one line."""


def load_measures():
    """Import hybrid_models/quadrotor_measures.py by its path (pure numpy, no package)."""
    path = REPO_ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'hybrid_models' \
        / 'quadrotor_measures.py'
    spec = importlib.util.spec_from_file_location('quadrotor_measures', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


measures = load_measures()


def progress(message):
    """Say how far the work is, on stderr."""
    print(f'[nanodrone_benchmark] {message}', file=sys.stderr, flush=True)


# --- the benchmark's files ------------------------------------------------------------------
class Snapshot:
    """Files of the benchmark's repository: a bare git directory at a commit, or a tree."""

    def __init__(self, path, commit='HEAD'):
        self.path = Path(path)
        self.read_files = {}
        if not self.path.exists():
            raise AdapterError(f'no snapshot of the benchmark at {self.path} (give --repo)')
        if (self.path / 'models' / 'models.py').is_file():
            self.bare = False
            self.commit = self._git('rev-parse', 'HEAD', check=False) or 'work tree'
        else:
            self.bare = True
            self.commit = self._git('rev-parse', '--verify', f'{commit}^{{commit}}')

    def _git(self, *args, check=True):
        where = ['--git-dir', str(self.path)] if self.bare_guess() else ['-C', str(self.path)]
        result = subprocess.run(['git', *where, *args], capture_output=True)
        if result.returncode != 0:
            if not check:
                return None
            raise AdapterError(f'git {" ".join(args)} in {self.path} failed: '
                               f'{result.stderr.decode(errors="replace").strip()}')
        return result.stdout.decode().strip()

    def bare_guess(self):
        """Whether the snapshot is a bare git directory (no models/ tree)."""
        return not (self.path / 'models' / 'models.py').is_file()

    def read(self, rel, commit=None):
        """Bytes of a file of the benchmark (at ``commit``, else the snapshot's), recorded."""
        if self.bare or commit:
            where = ['--git-dir', str(self.path)] if self.bare else ['-C', str(self.path)]
            commit = commit or self.commit
            result = subprocess.run(['git', *where, 'show', f'{commit}:{rel}'],
                                    capture_output=True)
            if result.returncode != 0:
                raise AdapterError(f'{rel} is not in the snapshot at {commit[:12]}')
            data = result.stdout
            if commit != self.commit:
                rel = f'{commit}:{rel}'
        else:
            try:
                data = (self.path / rel).read_bytes()
            except OSError as exc:
                raise AdapterError(f'cannot read {rel} of the benchmark: {exc}') from exc
        if data.startswith(b'version https://git-lfs.github.com/spec/'):
            raise AdapterError(f'{rel} is a Git LFS pointer in the snapshot, not the file')
        self.read_files[rel] = hashlib.sha256(data).hexdigest()
        return data


def load_torch_checkpoint(data):
    """
    Load the tensors and plain values of a torch.save zip archive as numpy, without torch.

    Only OrderedDict, float/long/double storages and _rebuild_tensor_v2 are accepted:
    anything else in the pickle is refused.
    """
    archive = zipfile.ZipFile(io.BytesIO(data))
    pickles = [n for n in archive.namelist() if n.endswith('/data.pkl')]
    if len(pickles) != 1:
        raise AdapterError('not a torch checkpoint (no single data.pkl)')
    root = pickles[0][:-len('data.pkl')]
    dtypes = {'FloatStorage': np.float32, 'DoubleStorage': np.float64,
              'LongStorage': np.int64, 'IntStorage': np.int32}

    def rebuild(storage, offset, size, stride, *_):
        if not size:
            return np.array(storage[offset])
        view = np.lib.stride_tricks.as_strided(
            storage[offset:], shape=tuple(size),
            strides=tuple(s * storage.itemsize for s in stride))
        return np.array(view)

    class Unpickler(pickle.Unpickler):
        def find_class(self, module, name):
            if (module, name) == ('collections', 'OrderedDict'):
                return collections.OrderedDict
            if (module, name) == ('torch._utils', '_rebuild_tensor_v2'):
                return rebuild
            if module == 'torch' and name in dtypes:
                return dtypes[name]
            raise AdapterError(f'checkpoint refers to {module}.{name}, which is not loaded')

        def persistent_load(self, pid):
            _, dtype, key, _, numel = pid
            return np.frombuffer(archive.read(f'{root}data/{key}'), dtype=dtype)[:numel]

    return Unpickler(archive.open(pickles[0])).load()


def load_scaler(data):
    """(mean_, scale_) of a joblib-pickled sklearn StandardScaler, float64."""
    import joblib  # noqa: PLC0415 - only the models that need scalers pay for it
    scaler = joblib.load(io.BytesIO(data))
    return np.asarray(scaler.mean_, dtype=float), np.asarray(scaler.scale_, dtype=float)


# --- flights, as the benchmark's QuadDataset takes them -----------------------------------
def read_flight(path, normalize_quaternions=True):
    """
    State (N, 12) float32, quaternions (N, 4) and motor speeds (N, 4) rad/s of a flight.

    State: x y z (m), vx vy vz (m/s), the so(3) log of qx qy qz qw (rad; pytorch3d's
    map, see quadrotor_measures.quat_to_rotvec), wx wy wz (rad/s): the on-board estimate's
    columns. Motors: m*_rads, or m*_erpm times 2 pi / 360.
    """
    import pandas as pd  # noqa: PLC0415
    path = Path(path)
    try:
        frame = pd.read_parquet(path) if path.suffix == '.parquet' else pd.read_csv(path)
    except Exception as exc:  # noqa: BLE001 - any reader failure is one line
        raise AdapterError(f'cannot read flight {path}: {exc}') from exc
    need = ['x', 'y', 'z', 'vx', 'vy', 'vz', 'qx', 'qy', 'qz', 'qw', 'wx', 'wy', 'wz']
    missing = [c for c in need if c not in frame.columns]
    if missing:
        raise AdapterError(f'{path.name}: no column {", ".join(missing)}')
    if all(f'm{i}_rads' in frame.columns for i in range(1, 5)):
        motors = frame[[f'm{i}_rads' for i in range(1, 5)]].to_numpy(float)
        motor_source = 'm*_rads'
    elif all(f'm{i}_erpm' in frame.columns for i in range(1, 5)):
        motors = frame[[f'm{i}_erpm' for i in range(1, 5)]].to_numpy(float) * ERPM_TO_RADS
        motor_source = 'm*_erpm * 2 pi / 360'
    else:
        raise AdapterError(f'{path.name}: no motor speeds (m1_rads.. or m1_erpm..)')
    quat = frame[['qx', 'qy', 'qz', 'qw']].to_numpy(float).astype(F32)
    if normalize_quaternions:
        quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    rotvec = measures.quat_to_rotvec(quat.astype(F32).astype(float))
    state = np.hstack([frame[['x', 'y', 'z']].to_numpy(float), frame[['vx', 'vy', 'vz']]
                       .to_numpy(float), rotvec, frame[['wx', 'wy', 'wz']].to_numpy(float)])
    state = state.astype(F32)
    if not np.all(np.isfinite(state)) or not np.all(np.isfinite(motors)):
        raise AdapterError(f'{path.name}: missing values in the state or motor columns')
    return {'state': state, 'motors': motors.astype(F32), 'rows': len(frame),
            'motor_source': motor_source, 'quat_norm': [float(np.linalg.norm(
                frame[['qx', 'qy', 'qz', 'qw']].to_numpy(float), axis=1).min()), float(
                np.linalg.norm(frame[['qx', 'qy', 'qz', 'qw']].to_numpy(float), axis=1).max())]}


def windows(flight, horizon, stride):
    """Start rows, initial states (B, 12), controls (B, H, 4) and true states (B, H, 12)."""
    n = flight['rows']
    if n <= horizon:
        raise AdapterError(f'a flight of {n} rows is too short for {horizon} steps')
    start = np.arange(0, n - horizon, stride)
    steps = start[:, None] + np.arange(horizon)[None, :]
    return start, flight['state'][start], flight['motors'][steps], flight['state'][steps + 1]


# --- the models, in numpy (float32, as the benchmark runs them in torch) -------------------
def axis_angle_to_quat(r):
    """Pytorch3d's axis_angle_to_quaternion, returned (x, y, z, w)."""
    angle = np.linalg.norm(r, axis=-1, keepdims=True)
    return np.concatenate([r * (0.5 * np.sinc(angle * 0.5 / np.pi)), np.cos(angle * 0.5)],
                          axis=-1).astype(r.dtype)


def quat_log(q):
    """Pytorch3d's quaternion_to_axis_angle of (x, y, z, w) quaternions."""
    v = q[..., :3]
    half = np.arctan2(np.linalg.norm(v, axis=-1, keepdims=True), q[..., 3:])
    return (v / (0.5 * np.sinc(half / np.pi))).astype(q.dtype)


class Physics:
    """The benchmark's rigid-body model: thrust and torques from rotor speeds, RK4."""

    def __init__(self, params=PHYSICS, max_torque=None):
        self.p = params
        self.m = F32(params['m'])
        self.g = F32(params['g'])
        self.t_max = F32(params['thrust_to_weight'] * params['m'] * params['g'])
        self.max_torque = np.asarray(max_torque if max_torque is not None
                                     else params['max_torque'], dtype=F32)
        self.gravity = np.array([0.0, 0.0, params['g']], dtype=F32)
        self.dt = F32(params['dt'])

    def controls(self, u):
        """Normalised thrust and torques (B, 4) from rotor speeds (B, 4) rad/s."""
        p = self.p
        w2 = u * u
        thrust = F32(p['Kt']) * w2.sum(axis=1)
        ka = F32(p['Kt'] * p['arm_length'])
        tau = np.stack([ka * ((w2[:, 2] + w2[:, 3]) - (w2[:, 0] + w2[:, 1])),
                        ka * ((w2[:, 1] + w2[:, 2]) - (w2[:, 0] + w2[:, 3])),
                        F32(p['Kc']) * ((w2[:, 0] + w2[:, 2]) - (w2[:, 1] + w2[:, 3]))], axis=1)
        return np.concatenate([(thrust / self.t_max)[:, None], tau / self.max_torque], axis=1)

    @staticmethod
    def rotate(q, v):
        """Rotate body vectors v (B, 3) by quaternions q (B, 4; x, y, z, w) into the world."""
        qv, qw = q[:, :3], q[:, 3:4]
        t = 2 * np.cross(qv, v)
        return v + qw * t + np.cross(qv, t)

    @staticmethod
    def quat_rate(q, w):
        """Quaternion derivative (B, 4) for body rates w (B, 3)."""
        qv, qw = q[:, :3], q[:, 3:4]
        return np.concatenate([0.5 * (qw * w + np.cross(qv, w)),
                               -0.5 * (qv * w).sum(axis=1, keepdims=True)], axis=1)

    def derivatives(self, vel, quat, omega, u):
        """Time derivatives of position, velocity, quaternion and body rates."""
        thrust_norm = np.clip(u[:, 0], 0.0, 1.0)
        thrust_body = np.zeros_like(vel)
        thrust_body[:, 2] = thrust_norm * self.t_max
        acc = (self.rotate(quat, thrust_body) - self.m * self.gravity) / self.m
        # Their model multiplies the angular acceleration by 0.0: the body rates are held.
        return vel, acc, self.quat_rate(quat, omega), np.zeros_like(omega)

    @staticmethod
    def unit(q):
        """Quaternions scaled to unit length."""
        return q / np.maximum(np.linalg.norm(q, axis=1, keepdims=True), F32(1e-12))

    def step(self, x, u):
        """Next state (B, 12) from the state (B, 12; so(3) log) and rotor speeds (B, 4)."""
        dt = self.dt
        c = self.controls(u)
        pos, vel, omega = x[:, 0:3], x[:, 3:6], x[:, 9:12]
        quat = axis_angle_to_quat(x[:, 6:9])
        v1, a1, q1, w1 = self.derivatives(vel, quat, omega, c)
        v2, a2, q2, w2 = self.derivatives(vel + 0.5 * dt * a1,
                                          self.unit(quat + 0.5 * dt * q1),
                                          omega + 0.5 * dt * w1, c)
        v3, a3, q3, w3 = self.derivatives(vel + 0.5 * dt * a2,
                                          self.unit(quat + 0.5 * dt * q2),
                                          omega + 0.5 * dt * w2, c)
        v4, a4, q4, w4 = self.derivatives(vel + dt * a3, self.unit(quat + dt * q3),
                                          omega + dt * w3, c)
        pos = pos + (dt / 6) * (v1 + 2 * v2 + 2 * v3 + v4)
        vel = vel + (dt / 6) * (a1 + 2 * a2 + 2 * a3 + a4)
        omega = omega + (dt / 6) * (w1 + 2 * w2 + 2 * w3 + w4)
        quat = self.unit(quat + (dt / 6) * (q1 + 2 * q2 + 2 * q3 + q4))
        return np.concatenate([pos, vel, quat_log(quat), omega], axis=1).astype(F32)

    def rollout(self, x0, u):
        """Forecast states (B, H, 12) from initial states (B, 12) and rotor speeds (B, H, 4)."""
        x, out = x0, np.empty(u.shape[:2] + (12,), dtype=F32)
        for t in range(u.shape[1]):
            x = self.step(x, u[:, t])
            out[:, t] = x
        return out


def mlp(weights, prefix, xu):
    """Their residual MLP: Linear+ReLU blocks (mlp.0, .2, ...) then the out layer."""
    h = xu
    i = 0
    while f'{prefix}mlp.{i}.weight' in weights:
        h = np.maximum(h @ weights[f'{prefix}mlp.{i}.weight'].T + weights[f'{prefix}mlp.{i}.bias'],
                       0)
        i += 2
    return h @ weights[f'{prefix}out.weight'].T + weights[f'{prefix}out.bias']


def normalize(x, scaler):
    """Scale as sklearn's StandardScaler.transform on float32 data, back to float32."""
    mean, scale = scaler
    return ((x.astype(float) - mean) / scale).astype(F32)


def denormalize(x, scaler):
    """Undo ``normalize`` (float32, as sklearn's inverse_transform of float32 data)."""
    mean, scale = scaler
    return x.astype(F32) * scale.astype(F32) + mean.astype(F32)


class MlpOnnx:
    """Their MLP export (batch 1), x_{k+1} = x_k + f(x_k, u_k) in scaled units."""

    def __init__(self, snapshot, engine):
        onnx_path, x_path, u_path = FILES['mlp']
        self.x_scaler = load_scaler(snapshot.read(x_path))
        self.u_scaler = load_scaler(snapshot.read(u_path))
        self.engine = engine
        if engine == 'onnx':
            import onnxruntime as ort  # noqa: PLC0415
            options = ort.SessionOptions()
            options.intra_op_num_threads = 1
            options.inter_op_num_threads = 1
            self.session = ort.InferenceSession(snapshot.read(onnx_path), options,
                                                providers=['CPUExecutionProvider'])
        else:
            self.weights = load_torch_checkpoint(
                snapshot.read(FILES['mlp_weights'][0]))['model_state']

    def rollout(self, x0, u):
        """Forecast states (B, H, 12) from initial states (B, 12) and rotor speeds (B, H, 4)."""
        x = normalize(x0, self.x_scaler)
        un = normalize(u, self.u_scaler)
        b, steps = u.shape[:2]
        out = np.empty((b, steps, 12), dtype=F32)
        if self.engine == 'onnx':
            run = self.session.run
            report = max(2000, b // 10)
            for i in range(b):
                xi = x[i:i + 1]
                for t in range(steps):
                    xi = run(None, {'x0': xi, 'u': un[i:i + 1, t:t + 1]})[0][:, 0]
                    out[i, t] = xi[0]
                if (i + 1) % report == 0:
                    progress(f'  mlp (onnxruntime, one window at a time): {i + 1}/{b}')
        else:
            for t in range(steps):
                x = (x + mlp(self.weights, '', np.concatenate([x, un[:, t]], axis=1))) \
                    .astype(F32)
                out[:, t] = x
        return denormalize(out, self.x_scaler)


class Hybrid:
    """Physics + MLP residual: x_{k+1} = phys(x_k, u_k) + f(x_k, u_k), scaled."""

    def __init__(self, snapshot):
        ckpt_path, x_path, u_path = FILES['hybrid']
        ckpt = load_torch_checkpoint(snapshot.read(ckpt_path))
        self.w = ckpt['model_state']
        self.x_scaler = load_scaler(snapshot.read(x_path))
        self.u_scaler = load_scaler(snapshot.read(u_path))
        self.physics = Physics(max_torque=self.w['phys.max_torque'])
        self.config = ckpt.get('config')

    def rollout(self, x0, u):
        """Forecast states (B, H, 12) from initial states (B, 12) and rotor speeds (B, H, 4)."""
        w = self.w
        x = normalize(x0, self.x_scaler)
        un = normalize(u, self.u_scaler)
        out = np.empty(u.shape[:2] + (12,), dtype=F32)
        for t in range(u.shape[1]):
            x_real = x * w['x_scale'] + w['x_mean']
            u_real = un[:, t] * w['u_scale'] + w['u_mean']
            phys = (self.physics.step(x_real, u_real) - w['x_mean']) / w['x_scale']
            step = phys + mlp(w, 'neural.', np.concatenate([x, un[:, t]], axis=1))
            x = (step if np.all(np.isfinite(step)) else phys).astype(F32)
            out[:, t] = x
        return denormalize(out, self.x_scaler)


class Lstm:
    """Their LSTM: (h0, c0) from x0, an LSTM over the controls, x_t = x0 + sum of dx."""

    def __init__(self, snapshot, which='published'):
        commit = LSTM_PUBLISHED_COMMIT if which == 'published' else None
        ckpt_path, x_path, u_path = FILES['lstm_published' if which == 'published' else 'lstm']
        ckpt = load_torch_checkpoint(snapshot.read(ckpt_path, commit))
        self.w = ckpt['model_state']
        self.config = ckpt.get('config')
        if (self.config or {}).get('num_layers', 1) != 1:
            raise AdapterError(f'LSTM of {self.config["num_layers"]} layers not handled')
        self.x_scaler = load_scaler(snapshot.read(x_path, commit))
        self.u_scaler = load_scaler(snapshot.read(u_path, commit))

    def rollout(self, x0, u):
        """Forecast states (B, H, 12) from initial states (B, 12) and rotor speeds (B, H, 4)."""
        w = self.w
        x = normalize(x0, self.x_scaler)
        un = normalize(u, self.u_scaler)
        h = np.tanh(x @ w['h0_net.0.weight'].T + w['h0_net.0.bias'])
        c = np.tanh(x @ w['c0_net.0.weight'].T + w['c0_net.0.bias'])
        hidden = h.shape[1]
        out = np.empty(u.shape[:2] + (12,), dtype=F32)
        total = x.copy()

        def sigmoid(z):
            return 1 / (1 + np.exp(-z))

        for t in range(u.shape[1]):
            gates = un[:, t] @ w['lstm.weight_ih_l0'].T + w['lstm.bias_ih_l0'] \
                + h @ w['lstm.weight_hh_l0'].T + w['lstm.bias_hh_l0']
            i, f, g, o = (gates[:, k * hidden:(k + 1) * hidden] for k in range(4))
            c = sigmoid(f) * c + sigmoid(i) * np.tanh(g)
            h = sigmoid(o) * np.tanh(c)
            z = h - h.mean(axis=1, keepdims=True)
            z = z / np.sqrt((z * z).mean(axis=1, keepdims=True) + F32(1e-5))
            z = z * w['post_ln.weight'] + w['post_ln.bias']
            z = np.maximum(z @ w['post_mlp.0.weight'].T + w['post_mlp.0.bias'], 0)
            total = (total + z @ w['out.weight'].T + w['out.bias']).astype(F32)
            out[:, t] = total
        return denormalize(out, self.x_scaler)


class Naive:
    """The benchmark's baseline: the initial state held."""

    def rollout(self, x0, u):
        """Repeat the initial states (B, 12) over the H steps of u (B, H, 4)."""
        return np.repeat(x0[:, None], u.shape[1], axis=1)


def quantities(states):
    """Position, velocity, attitude quaternion (x, y, z, w) and body rates of (B, H, 12)."""
    s = states.astype(float)
    return {'position': s[..., 0:3], 'velocity': s[..., 3:6],
            'attitude': measures.rotvec_to_quat(s[..., 6:9]), 'body_rates': s[..., 9:12]}


def build_models(names, snapshot, mlp_engine, lstm='published'):
    """Build the models named, their files read from the snapshot."""
    built = {}
    for name in names:
        if name == 'physics':
            built[name] = Physics()
        elif name == 'mlp':
            built[name] = MlpOnnx(snapshot, mlp_engine)
        elif name == 'hybrid':
            built[name] = Hybrid(snapshot)
        elif name == 'lstm':
            built[name] = Lstm(snapshot, lstm)
        elif name == 'naive':
            built[name] = Naive()
    return built


def sha256_file(path):
    """SHA-256 of a file, hex."""
    digest = hashlib.sha256()
    with open(path, 'rb') as handle:
        for block in iter(lambda: handle.read(1 << 20), b''):
            digest.update(block)
    return digest.hexdigest()


def run(args):
    """Forecast every flight with every model; write the .npz and its JSON."""
    names = [m.strip() for m in args.models.split(',') if m.strip()]
    unknown = [m for m in names if m not in ALL_MODELS]
    if unknown or not names:
        raise AdapterError(f'unknown model {", ".join(unknown) or "(none)"}; '
                           f'choose from {", ".join(ALL_MODELS)}')
    if args.horizon < 1 or args.stride < 1:
        raise AdapterError('--horizon and --stride must be at least 1')
    snapshot = Snapshot(args.repo, args.commit)
    models = build_models(names, snapshot, args.mlp_engine, args.lstm)
    arrays = {}
    tags = []
    flights_meta = []
    for path in args.flights:
        flight = read_flight(path, normalize_quaternions=not args.raw_quaternions)
        tag = Path(path).stem
        while tag in tags:
            tag += '_'
        tags.append(tag)
        start, x0, u, truth = windows(flight, args.horizon, args.stride)
        progress(f'{tag}: {flight["rows"]} rows, {len(start)} windows of {args.horizon} steps')
        arrays[f'{tag}.start'] = start.astype(np.int64)
        for quantity, value in quantities(truth).items():
            arrays[f'{tag}.truth.{quantity}'] = value
        for name, model in models.items():
            began = time.monotonic()
            pred = model.rollout(x0, u)
            if not np.all(np.isfinite(pred)):
                progress(f'  {name}: some forecasts are not finite')
            for quantity, value in quantities(pred).items():
                arrays[f'{tag}.{name}.{quantity}'] = value
            progress(f'  {name}: {time.monotonic() - began:.1f} s')
        flights_meta.append({'name': tag, 'path': str(path), 'sha256': sha256_file(path),
                             'rows': flight['rows'], 'windows': len(start),
                             'motors': flight['motor_source'],
                             'quaternion_norm_range': flight['quat_norm']})
    arrays['flights'] = np.array(tags)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, **arrays)
    meta = {
        'benchmark': {'repository': REPOSITORY, 'commit': snapshot.commit,
                      'snapshot': str(snapshot.path),
                      'paper': 'Busetto et al., Nonlinear system identification for a nano-'
                               'drone benchmark, Control Engineering Practice 172 (2026) '
                               '106871'},
        'models': names,
        'model_files_sha256': snapshot.read_files,
        'mlp_engine': args.mlp_engine if 'mlp' in names else None,
        'lstm_checkpoint': (f'{LSTM_PUBLISHED_COMMIT}:{FILES["lstm_published"][0]}'
                            if args.lstm == 'published' else FILES['lstm'][0])
        if 'lstm' in names else None,
        'physics_parameters': PHYSICS,
        'horizon': args.horizon, 'stride': args.stride,
        'preprocessing': {
            'state': 'x y z (m, world), vx vy vz (m/s, world), so(3) log of qx qy qz qw '
                     '(rad, pytorch3d quaternion_to_axis_angle), wx wy wz (rad/s, body): '
                     'the on-board estimate columns; float32',
            'quaternions': 'raw columns' if args.raw_quaternions
            else 'normalised to unit length before the log',
            'motors': 'm*_rads, or m*_erpm * 2 pi / (6 * 60) (rad/s)',
            'scaling': "each model's own StandardScaler pickles (x: 12 states, u: 4 motors)",
            'windows': 'start k in range(0, rows - H, stride); state of row k, motors of rows '
                       'k..k+H-1, truth rows k+1..k+H',
            'outputs': 'attitude: scipy from_rotvec of the so(3) log, (x, y, z, w), '
                       'world-from-body',
        },
        'flights': flights_meta,
        'npz': str(out),
        'command': ' '.join([Path(sys.argv[0]).name, *sys.argv[1:]]),
    }
    out.with_suffix('.json').write_text(json.dumps(meta, indent=2) + '\n')
    progress(f'wrote {out} and {out.with_suffix(".json")}')
    return 0


def parse_args(argv=None):
    """Parse the command line."""
    parser = argparse.ArgumentParser(
        description="Run the nano-drone benchmark's reference models (physics, MLP, hybrid, "
                    'LSTM) on flights: open-loop forecasts to an .npz and a JSON of what ran.')
    parser.add_argument('--flights', nargs='+', required=True,
                        help='parquet (m*_erpm) or benchmark CSV (m*_rads) flight files')
    parser.add_argument('--out', required=True, help='the .npz to write (a .json beside it)')
    parser.add_argument('--horizon', type=int, default=50, help='steps per forecast (50)')
    parser.add_argument('--stride', type=int, default=1,
                        help='a forecast from every STRIDE-th row (1)')
    parser.add_argument('--models', default=','.join(MODELS),
                        help=f'comma-separated, from {", ".join(ALL_MODELS)} '
                             f'(default {",".join(MODELS)})')
    parser.add_argument('--repo', default=os.environ.get('NANODRONE_BENCHMARK_REPO',
                                                         str(DEFAULT_SNAPSHOT)),
                        help='the benchmark repository: a bare git directory or a checked-out '
                             'tree (default $NANODRONE_BENCHMARK_REPO or %(default)s)')
    parser.add_argument('--commit', default='HEAD', help='commit of a bare snapshot (HEAD)')
    parser.add_argument('--mlp-engine', choices=('onnx', 'numpy'), default='onnx',
                        help='the MLP from their ONNX export via onnxruntime (default), or '
                             'from their checkpoint in numpy (the same weights, faster)')
    parser.add_argument('--lstm', choices=('published', 'head'), default='published',
                        help='the LSTM the paper scores (lstm_v2, at commit '
                             f"{LSTM_PUBLISHED_COMMIT[:7]}; default) or the snapshot's own "
                             'out/models/lstm_random_square_chirp.pt')
    parser.add_argument('--raw-quaternions', action='store_true',
                        help='take the quaternion columns as they are, not normalised')
    return parser.parse_args(argv)


def main(argv=None):
    """Run; a failure is one line on stderr and exit status 2."""
    args = parse_args(argv)
    try:
        return run(args)
    except (AdapterError, OSError, ValueError, KeyError) as exc:
        print(f'nanodrone_benchmark: error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
