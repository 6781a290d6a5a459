"""hybrid_models.ensemble: several corrections on one physics, served as one hybrid."""

from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from hybrid_models.checkpoint import load_model
from hybrid_models.data import forecast_windows, load_runs
from hybrid_models.engine import Forecaster
from hybrid_models.ensemble import EnsembleError, EnsembleHybrid, pack
from hybrid_models.models import build_model, predict
from hybrid_models.physical.identity import physics_identity
from hybrid_models.training import load_config, train
from hybrid_models.training.ensemble import serve_ensemble
from offline.benchmarks.toy import TOY_VESSEL, write_toy_dataset

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'
SHORT = ['training.progress=false', 'training.phases=[{kind: teacher, max_epochs: 1, '
         'patience: 1, lr: 0.005}, {kind: multistep, max_epochs: 2, patience: 2, lr: 0.003}]']


def hybrid(seed: int, physical=None):
    """Return a small untrained hybrid of the toy vessel, its head set from ``seed``."""
    torch.manual_seed(seed)
    model = build_model({'kind': 'hybrid', 'hidden': 8, 'layers': 1, 'dropout': 0.0,
                         'physical': physical or {'kind': 'lin'},
                         'correction_init': 'random'}, TOY_VESSEL)
    model.output_range.fill_(1.0)
    model.set_threshold(None)
    return model.eval()


def windows(n=6, horizon=30, seed=0):
    rng = np.random.default_rng(seed)
    s = TOY_VESSEL
    return (torch.as_tensor(rng.normal(size=(n, 10, s.n_state)), dtype=torch.float32),
            torch.as_tensor(rng.normal(size=(n, 10, s.n_control)), dtype=torch.float32),
            torch.as_tensor(rng.normal(size=(n, horizon, s.n_control)), dtype=torch.float32))


@torch.no_grad()
def test_each_step_adds_the_mean_of_the_members_bounded_corrections():
    members = [hybrid(seed) for seed in (1, 2, 3)]
    ensemble = pack(members)
    zw, cw, cf = windows()
    z, z_phy, residual = ensemble.forecast(zw, cw, cf, return_parts=True)
    # Step 1 starts from the same state for every member: the mean of their residuals.
    singles = [m.forecast(zw, cw, cf[:, :1], return_parts=True) for m in members]
    assert torch.allclose(residual[:, 0], torch.stack([r[:, 0] for _, _, r in singles]).mean(0),
                          atol=1e-6)
    assert torch.allclose(z, z_phy + residual)
    # Served at a threshold, every step stays within the bound: physics plus a known amount.
    ensemble.set_threshold(0.05)
    z, z_phy, residual = ensemble.forecast(zw, cw, cf, return_parts=True)
    assert (residual.abs() <= ensemble.bound + 1e-7).all()
    # Members that are one model: the ensemble forecasts what that model does.
    twin = pack([hybrid(7), hybrid(7)])
    assert torch.allclose(twin.forecast(zw, cw, cf), hybrid(7).forecast(zw, cw, cf), atol=1e-6)


def test_members_that_cannot_be_served_together_are_refused_in_one_line():
    with pytest.raises(EnsembleError, match='at least 2 members'):
        pack([hybrid(1)])
    other = hybrid(2, physical={'kind': 'min+lin'})
    with pytest.raises(EnsembleError) as refused:
        pack([hybrid(1), other])
    assert '\n' not in str(refused.value)
    lstm = build_model({'kind': 'lstm', 'hidden': 8, 'layers': 1}, TOY_VESSEL)
    with pytest.raises(EnsembleError, match='member 1 is a LSTMBaseline, not a hybrid'):
        pack([hybrid(1), lstm])


def test_one_physics_read_from_two_folders_is_one_physics(tmp_path):
    from vessel_description import load_vessel
    from vessel_physics.patrol import PRO_TERMS, SIMULATOR_TERMS

    ship = load_vessel('patrol_boat')

    def on_file(folder, terms, seed):
        path = tmp_path / folder / 'physics.yaml'
        path.parent.mkdir(exist_ok=True)
        path.write_text(yaml.safe_dump({'format': 'vessel-physics/1', 'terms': list(terms),
                                        'vessel': 'nominal_vessel.yaml'}))
        torch.manual_seed(seed)
        return build_model({'kind': 'hybrid', 'hidden': 8, 'layers': 1, 'dropout': 0.0,
                            'physical': {'kind': 'physics', 'physics': str(path)}}, ship)

    # A study's seeds trained before and after its folder was copied: one physics.
    before, after = on_file('study', PRO_TERMS, 1), on_file('copy', PRO_TERMS, 2)
    assert physics_identity(before.physical) == physics_identity(after.physical)
    assert len(pack([before, after]).members) == 2
    with pytest.raises(EnsembleError, match='member 1 corrects another physics'):
        pack([on_file('study', PRO_TERMS, 1), on_file('other', SIMULATOR_TERMS, 2)])


@pytest.fixture(scope='module')
def trained(tmp_path_factory):
    """Train an ensemble of 2 tiny hybrids with training.members: 2; return where."""
    root = tmp_path_factory.mktemp('ensemble')
    toy = write_toy_dataset(root / 'toy', n_runs=6, n_samples=260)
    cfg = load_config(SMOKE, SHORT + [f'dataset={toy}', 'training.members=2'])
    summary = train(cfg, root / 'out')
    return root, toy, summary


def test_training_members_gives_a_served_ensemble_chosen_on_validation(trained):
    root, toy, summary = trained
    model, config = load_model(root / 'out' / 'model.safetensors')
    assert isinstance(model, EnsembleHybrid) and len(model.members) == 2
    assert config['ensemble']['seeds'] == [0, 1]
    # Its own do-no-harm choice and bands, made on the members' validation runs.
    assert config['selection']['relative_threshold'] == model.relative_threshold
    assert config['bands'] is not None
    for i in range(2):
        member, member_config = load_model(root / 'out' / 'members' / f'member{i}' /
                                           'model.safetensors')
        assert member_config['training']['training']['seed'] == i
    # The compiled forecaster serves the checkpoint as torch forecasts it.
    spec = model.spec
    w = forecast_windows(load_runs(toy, 'test', spec), 20, 60, 40)
    torch_pred = predict(model, w)
    engine = Forecaster.from_checkpoint(root / 'out' / 'model.safetensors')
    assert engine.members == 2
    served = engine.forecast_each(w.z_window, w.c_window, w.c_future).hybrid
    assert np.allclose(served, torch_pred, rtol=1e-4, atol=1e-5)


def test_an_ensemble_is_chosen_on_the_dataset_its_members_were_trained_on(trained, tmp_path):
    root, _, _ = trained
    other = write_toy_dataset(tmp_path / 'other', n_runs=6, n_samples=260, seed=5)
    members = [root / 'out' / 'members' / f'member{i}' / 'model.safetensors' for i in (0, 1)]
    with pytest.raises(EnsembleError, match='is not the dataset the members were trained on'):
        serve_ensemble(members, other, tmp_path / 'ensemble.safetensors')


def test_the_ensemble_program_packs_checkpoints_and_refuses_one_member(trained, tmp_path,
                                                                        capsys):
    from hybrid_models.cli.ensemble import main

    root, toy, _ = trained
    members = [str(root / 'out' / 'members' / f'member{i}' / 'model.safetensors')
               for i in (0, 1)]
    out = tmp_path / 'e.safetensors'
    assert main(members + ['--dataset', str(toy), '--out', str(out)]) == 0
    assert '2 members, relative threshold' in capsys.readouterr().out
    assert isinstance(load_model(out)[0], EnsembleHybrid)
    assert main(members[:1] + ['--dataset', str(toy), '--out', str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == 'ensemble: error: an ensemble needs at least 2 members, got 1'
