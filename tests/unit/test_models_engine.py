"""hybrid_models.engine: the compiled forecast equals the torch model's forecast."""

import json
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
import torch

from hybrid_models.engine import Forecaster, platform_devices
from hybrid_models.models import build_model
from hybrid_models.recurrent import CELLS
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')

W, H = 12, 40


def make_model(physical, threshold, mode='tanh', seed=0, cell='lstm'):
    """Build a hybrid with plausible normalization (``physical``: a kind or a config)."""
    torch.manual_seed(seed)
    physical_cfg = physical if isinstance(physical, dict) else {'kind': physical,
                                                                 'substeps': 2}
    physical = physical_cfg['kind']
    cfg = {'kind': 'hybrid', 'cell': cell, 'hidden': 16, 'layers': 2, 'dropout': 0.0,
           'bound_mode': mode, 'physical': physical_cfg}
    model = build_model(cfg, SHIP)
    rng = np.random.default_rng(seed)
    with torch.no_grad():
        model.state_mean.copy_(torch.tensor([6.0, 0.0, 0.0, 0.0, 0.0]))
        model.state_std.copy_(torch.tensor([1.0, 0.2, 0.01, 0.005, 0.02]))
        model.control_mean.copy_(torch.tensor([80.0, 0.0, 0.0, 3.0, 0.0, 0.0]))
        model.control_std.copy_(torch.tensor([10.0, 0.05, 0.05, 1.0, 0.7, 0.7]))
        model.residual_std.copy_(torch.tensor([0.02, 0.02, 0.002, 0.001, 0.002]))
        model.output_range.copy_(torch.tensor([4.0, 1.0, 0.05, 0.02, 0.1]))
        regression = getattr(model.physical, 'regression', None)
        if physical in ('lin', 'hyd'):
            regression = model.physical
        if regression is not None:
            weight = rng.normal(scale=1e-4, size=tuple(regression.weight.shape))
            if physical == 'lin':   # a stable linear model: z' = z mostly
                weight[:, 6:] += np.eye(5)
            regression.weight.copy_(torch.as_tensor(weight))
    model.set_threshold(threshold)
    return model.eval()


def inputs(batch, seed=1):
    rng = np.random.default_rng(seed)
    z = np.tile([6.5, 0.05, 0.0, -0.002, 0.01], (W, 1)) + rng.normal(scale=0.01, size=(W, 5))
    c = np.tile([85.0, 0.02, 0.02, 3.0, 0.6, 0.8], (W, 1))
    future = np.tile(c[-1], (batch, H, 1))
    future[:, :, 1:3] += rng.normal(scale=0.02, size=(batch, 1, 2))
    return z, c, future


def torch_forecast(model, z, c, future, dtype):
    model = model.to(dtype)
    t = lambda a: torch.as_tensor(a, dtype=dtype)  # noqa: E731
    batch = future.shape[0]
    with torch.no_grad():
        out, phys, _ = model.forecast(t(np.tile(z, (batch, 1, 1))),
                                      t(np.tile(c, (batch, 1, 1))), t(future),
                                      return_parts=True)
    return out.double().numpy(), phys.double().numpy()


@pytest.mark.parametrize('physical', ['pro+lin', 'min', 'lin', 'hyd'])
def test_engine_matches_the_torch_model_in_double_precision(physical):
    model = make_model(physical, threshold=0.15)
    z, c, future = inputs(batch=3)
    expected, expected_phys = torch_forecast(model, z, c, future, torch.float64)
    engine = Forecaster.from_model(model, dtype=np.float64)
    got = engine.forecast(z, c, future)
    assert got.hybrid.shape == (3, H, 5)
    np.testing.assert_allclose(got.hybrid, expected, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(got.physics, expected_phys, rtol=1e-9, atol=1e-11)


def test_engine_in_float32_stays_close_and_respects_the_bound():
    model = make_model('pro+lin', threshold=0.05, mode='clamp')
    z, c, future = inputs(batch=4)
    expected, _ = torch_forecast(model, z, c, future, torch.float64)
    got = Forecaster.from_model(make_model('pro+lin', threshold=0.05, mode='clamp')).forecast(
        z, c, future)
    scale = np.abs(expected).max(axis=(0, 1)) + 1e-3
    assert np.max(np.abs(got.hybrid - expected) / scale) < 1e-3
    bound = model.bound.double().numpy()
    assert np.all(np.abs(got.hybrid - got.physics) <= bound * (1 + 1e-6))


def test_unconstrained_model_passes_the_residual_through():
    model = make_model('min', threshold=None)
    z, c, future = inputs(batch=1)
    expected, _ = torch_forecast(model, z, c, future, torch.float64)
    got = Forecaster.from_model(model, dtype=np.float64).forecast(z, c, future[0])
    np.testing.assert_allclose(got.hybrid, expected, rtol=1e-9, atol=1e-11)


SPLIT_CHECK = """
import json, sys
import numpy as np
from hybrid_models.engine import Forecaster
from tests.unit.test_models_engine import inputs, make_model
engine = Forecaster.from_model(make_model('pro+lin', threshold=0.15), dtype=np.float64)
z, c, future = inputs(batch=64)
batch = engine.forecast(z, c, future)
alone = [engine.forecast(z, c, future[k]) for k in (0, 31, 32, 63)]
# Each shard's program runs where its parameters are: NumPy inputs follow them there.
placed = [sorted(d.id for d in engine._compiled(
    engine._device_params[k], z, c, future[:32], np.zeros(32, bool),
    turning=False)['hybrid'].devices()) for k in range(len(engine.devices))]
print(json.dumps({
    'devices': len(engine.devices), 'shards': engine._shards(64), 'placed': placed,
    'device_ids': [d.id for d in engine.devices],
    'max_diff': max(float(np.abs(batch.hybrid[k] - a.hybrid[0]).max()) + float(np.abs(
        batch.physics[k] - a.physics[0]).max()) for k, a in zip((0, 31, 32, 63), alone))}))
"""


def test_batches_use_every_core_and_give_each_plan_its_own_forecast():
    # A fresh interpreter: the engine sets XLA's host device count before jax starts.
    root = Path(__file__).resolve().parents[2]
    env = {k: v for k, v in os.environ.items() if k != 'XLA_FLAGS'}
    env['PYTHONPATH'] = os.pathsep.join(p for p in sys.path if p)   # pytest's pythonpath
    out = subprocess.run([sys.executable, '-c', SPLIT_CHECK], capture_output=True, text=True,
                         cwd=root, env=env, timeout=240)
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    cores = len(os.sched_getaffinity(0))
    assert result['devices'] == cores
    assert result['shards'] == min(cores, 64 // 8)
    assert result['placed'] == [[i] for i in result['device_ids']]
    assert result['max_diff'] < 1e-9


def test_the_threshold_has_one_meaning():
    model = make_model('pro+lin', threshold=0.15)
    z, c, future = inputs(batch=2)
    served = Forecaster.from_model(model, dtype=np.float64)          # None: the model's own
    assert served.relative_threshold == 0.15
    np.testing.assert_allclose(served.bound, model.bound.double().numpy())
    wider = Forecaster.from_model(model, relative_threshold=0.3, dtype=np.float64)
    np.testing.assert_allclose(wider.bound, 0.3 * model.output_range.double().numpy() / 2)
    physics = Forecaster.from_model(model, relative_threshold=0.0, dtype=np.float64)
    got = physics.forecast(z, c, future)
    np.testing.assert_array_equal(got.hybrid, got.physics)     # 0: the physics alone
    assert np.abs(wider.forecast(z, c, future).hybrid - got.physics).max() > 0
    with pytest.raises(ValueError, match='>= 0'):
        Forecaster.from_model(model, relative_threshold=-0.1)


@pytest.mark.parametrize('cell', list(CELLS))
def test_every_recurrent_cell_is_served_from_its_checkpoint_as_trained(tmp_path, cell):
    from hybrid_models.checkpoint import save_checkpoint

    # The cell travels in the checkpoint's description: a GRU read as an LSTM would fail.
    model = make_model('pro+lin', threshold=0.15, cell=cell)
    path = save_checkpoint(tmp_path / f'{cell}.safetensors', model, {
        'model': model.describe(), 'vehicle': SHIP.to_dict()})
    served = Forecaster.from_checkpoint(path, dtype=np.float64)
    assert served.cell.name == cell
    z, c, future = inputs(batch=3)
    expected, expected_phys = torch_forecast(model, z, c, future, torch.float64)
    got = served.forecast(z, c, future)
    np.testing.assert_allclose(got.hybrid, expected, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(got.physics, expected_phys, rtol=1e-9, atol=1e-11)
    assert np.abs(got.hybrid - got.physics).max() > 1e-6   # the correction is not nil


def test_a_checkpoint_serves_the_threshold_written_into_it(tmp_path):
    from hybrid_models.checkpoint import save_checkpoint
    from hybrid_models.cli.set_threshold import main as set_threshold

    model = make_model('hyd', threshold=None)
    path = save_checkpoint(tmp_path / 'm.safetensors', model, {
        'model': model.describe(), 'vehicle': SHIP.to_dict()})
    assert Forecaster.from_checkpoint(path).relative_threshold is None
    assert np.isinf(Forecaster.from_checkpoint(path).bound).all()
    assert set_threshold([str(path), '0.2']) == 0
    served = Forecaster.from_checkpoint(path, dtype=np.float64)
    assert served.relative_threshold == 0.2
    np.testing.assert_allclose(served.bound, 0.2 * model.output_range.double().numpy() / 2)
    z, c, future = inputs(batch=2)
    model.set_threshold(0.2)
    expected, _ = torch_forecast(model, z, c, future, torch.float64)
    np.testing.assert_allclose(served.forecast(z, c, future).hybrid, expected, rtol=1e-6)
    with pytest.raises(SystemExit):                     # argparse refuses it in one line
        set_threshold([str(path), '-1'])


TORCH_FREE_CHECK = """
import json, sys
import numpy as np
import hybrid_predictor.node as node
import hybrid_models.cli.model_card      # evaluates with the forecaster, torch-free too
from hybrid_models.engine import Forecaster
engine = Forecaster.from_checkpoint(node.default_model_path())
w = engine.window
out = engine.forecast(np.tile([6.0, 0.0, 0.0, 0.0, 0.0], (w, 1)),
                      np.tile([85.0, 0.0, 0.0, 3.0, 0.6, 0.8], (w, 1)),
                      np.tile([85.0, 0.0, 0.0, 3.0, 0.6, 0.8], (1, 30, 1)))
print(json.dumps({'torch': sorted(m for m in sys.modules if m.split('.')[0] == 'torch')[:3],
                  'threshold': engine.relative_threshold,
                  'finite': bool(np.isfinite(out.hybrid).all())}))
"""


def test_the_predictor_serves_the_shipped_model_without_importing_torch():
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(p for p in sys.path if p)}
    out = subprocess.run([sys.executable, '-c', TORCH_FREE_CHECK], capture_output=True,
                         text=True, cwd=root, env=env, timeout=240)
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result == {'torch': [], 'threshold': 0.15, 'finite': True}


CACHE_CHECK = """
import numpy as np
import hybrid_predictor.node as node
from hybrid_models.engine import Forecaster
engine = Forecaster.from_checkpoint(node.default_model_path())
w = engine.window
engine.forecast(np.tile([6.0, 0.0, 0.0, 0.0, 0.0], (w, 1)),
                np.tile([85.0, 0.0, 0.0, 3.0, 0.6, 0.8], (w, 1)),
                np.tile([85.0, 0.0, 0.0, 3.0, 0.6, 0.8], (1, 5, 1)))
"""


def test_compiled_programs_are_kept_for_the_next_process_unless_turned_off(tmp_path):
    root = Path(__file__).resolve().parents[2]
    env = {k: v for k, v in os.environ.items() if k != 'JAX_COMPILATION_CACHE_DIR'}
    env['PYTHONPATH'] = os.pathsep.join(p for p in sys.path if p)

    def forecast_in_a_new_process(**settings):
        out = subprocess.run([sys.executable, '-c', CACHE_CHECK], capture_output=True,
                             text=True, cwd=root, env={**env, **settings}, timeout=240)
        assert out.returncode == 0, out.stderr[-2000:]

    # By default in the user's cache directory; the second process compiles nothing anew.
    kept = tmp_path / 'home_cache' / 'hybrid_models' / 'jax'
    forecast_in_a_new_process(XDG_CACHE_HOME=str(tmp_path / 'home_cache'))
    def programs():
        return {p.name: p.stat().st_mtime_ns for p in kept.glob('jit_*-cache')}

    first = programs()
    assert first
    forecast_in_a_new_process(XDG_CACHE_HOME=str(tmp_path / 'home_cache'))
    assert programs() == first   # loaded, not compiled and written again
    # jax's own variable: empty turns it off.
    forecast_in_a_new_process(XDG_CACHE_HOME=str(tmp_path / 'off'), JAX_COMPILATION_CACHE_DIR='')
    assert not (tmp_path / 'off').exists()


def _gpu_absent() -> str:
    """Return why no GPU forecast can be made here ('' when jax sees a GPU)."""
    try:
        platform_devices('gpu')
    except ValueError as exc:
        return str(exc)
    return ''


def test_an_unknown_or_absent_compute_platform_is_refused_in_one_line():
    model = make_model('min', threshold=0.15)
    with pytest.raises(ValueError, match=r"^unknown compute platform 'tpu'; known: cpu, gpu$"):
        Forecaster.from_model(model, platform='tpu')
    if _gpu_absent():
        with pytest.raises(ValueError) as refused:
            Forecaster.from_model(model, platform='gpu')
        assert str(refused.value).startswith("compute platform 'gpu': jax ")
        assert 'tools/setup.sh gpu' in str(refused.value) and '\n' not in str(refused.value)


def test_the_gpu_program_at_full_precision_forecasts_as_the_cpu_program():
    """The program a GPU runs (float32 products at full precision), run on the CPU here."""
    import jax

    engine = Forecaster.from_model(make_model('hyd', threshold=0.15))
    z, c, future = inputs(batch=4)
    args = (engine._device_params[0], z.astype(np.float32), c.astype(np.float32),
            future.astype(np.float32), np.zeros(4, bool))
    plain = engine._compiled(*args, turning=False)
    full = jax.jit(engine._full_precision, static_argnames='turning')(*args, turning=False)
    assert plain.keys() == full.keys()
    for name in plain:
        np.testing.assert_array_equal(np.asarray(plain[name]), np.asarray(full[name]))


@pytest.mark.skipif(bool(_gpu_absent()), reason=_gpu_absent() or 'a GPU is present')
def test_a_gpu_forecasts_as_the_cpu_within_float32_rounding():
    model = make_model('hyd', threshold=0.15)
    cpu, gpu = (Forecaster.from_model(model, platform=p) for p in ('cpu', 'gpu'))
    assert gpu.platform == 'gpu' and gpu.devices[0].platform == 'gpu'
    z, c, future = inputs(batch=16)
    on_cpu, on_gpu = cpu.forecast(z, c, future), gpu.forecast(z, c, future)
    scale = np.abs(on_cpu.hybrid).max(axis=(0, 1)) + 1e-6
    assert np.all(np.abs(on_gpu.hybrid - on_cpu.hybrid).max(axis=(0, 1)) <= 1e-4 * scale)
