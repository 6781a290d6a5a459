"""
One step of the hybrid model, written once against the Array API.

Torch training (``nets.HybridModel``, with autograd) and the compiled jax forecaster
(``engine.Forecaster``, which only adds scan, jit and sharding) both run this code:

    z_phy  = physical(z_t, c_t)
    y, s   = LSTM stack((c_t - c_mean) / c_std, (z_phy - z_mean) / z_std; s)
    res    = bound((y W_head + b_head) * residual_std)
    z_t+1  = z_phy + res

An ensemble (``ensemble_step``) is K such corrections on one physics: every member's
LSTM reads the same z_phy, and the step adds the mean of their bounded residuals, so
the ensemble is still the physics plus a bounded amount.

The LSTM cell is torch.nn.LSTM's (gate order i, f, g, o; b = b_ih + b_hh). Weights come
from a torch state dict's names (``lstm.weight_ih_l0``, ``head.weight``, ...) through
``step_weights``, whatever the array type: torch parameters during training, numpy
arrays read from a checkpoint when serving. The recurrent state is a pair of tuples,
(h per layer, c per layer), each (B, hidden).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from hybrid_models.bound import apply_bound
from vessel_physics.arrays import namespace

ENSEMBLE_KIND = 'hybrid_ensemble'   # a checkpoint's model kind for K members on one physics
NORMALIZATION = ('state_mean', 'state_std', 'control_mean', 'control_std', 'residual_std')


def lstm_layers(state: Mapping, prefix: str, layers: int) -> tuple:
    """Return per layer (W_ih^T, W_hh^T, b_ih + b_hh) of the LSTM ``prefix`` in ``state``."""
    return tuple((state[f'{prefix}.weight_ih_l{k}'].T, state[f'{prefix}.weight_hh_l{k}'].T,
                  state[f'{prefix}.bias_ih_l{k}'] + state[f'{prefix}.bias_hh_l{k}'])
                 for k in range(layers))


def step_weights(state: Mapping, layers: int) -> dict:
    """Return what ``hybrid_step`` reads, from a hybrid model's state dict (any arrays)."""
    weights = {name: state[name] for name in NORMALIZATION}
    weights.update(head_w=state['head.weight'].T, head_b=state['head.bias'],
                   bound=state['bound'], lstm=lstm_layers(state, 'lstm', layers))
    return weights


def lstm_stack(x, recurrent: tuple, layers: tuple, between: Callable | None = None):
    """
    Advance a stacked LSTM by one sample; return (output of the top layer, new state).

    ``between`` is applied to the output of every layer but the last (torch's dropout
    between stacked layers during training; nothing when serving).
    """
    xp = namespace(x)
    hs, cs = recurrent
    new_h, new_c = [], []
    for k, (w_ih, w_hh, bias) in enumerate(layers):
        if k and between is not None:
            x = between(x)
        gates = x @ w_ih + hs[k] @ w_hh + bias
        hidden = gates.shape[-1] // 4
        i, f, g, o = (gates[..., j * hidden:(j + 1) * hidden] for j in range(4))
        c = _sigmoid(xp, f) * cs[k] + _sigmoid(xp, i) * xp.tanh(g)
        x = _sigmoid(xp, o) * xp.tanh(c)
        new_h.append(x)
        new_c.append(c)
    return x, (tuple(new_h), tuple(new_c))


def _sigmoid(xp, x):
    # The Array API has no sigmoid; 1/2 (1 + tanh(x/2)) is exact and never overflows.
    return 0.5 * (1.0 + xp.tanh(0.5 * x))


def hybrid_step(weights: Mapping, physical: Callable, z, c, recurrent: tuple,
                bound_mode: str | None, between: Callable | None = None, bound=None):
    """
    One sample period: return (z_next, z_phy, residual, recurrent state).

    z (B, n_state) and c (B, n_control) in the vessel's units; ``physical(z, c)`` is the
    physical model's one-period map; ``bound_mode`` None leaves the residual unbounded
    (training without the constraint), otherwise ``bound`` (this step's half-widths;
    default ``weights['bound']``) limits it.
    """
    z_phy = physical(z, c)
    residual, recurrent = correction(weights, z_phy, c, recurrent, bound_mode, between, bound)
    return z_phy + residual, z_phy, residual, recurrent


def ensemble_step(members: tuple, physical: Callable, z, c, recurrents: tuple,
                  bound_mode: str | None, bound=None):
    """
    One sample period of K hybrids on one physics: return (z_next, z_phy, residual, states).

    ``members`` holds each member's ``step_weights``, ``recurrents`` each member's
    recurrent state; the residual is the mean of the members' bounded residuals.
    """
    z_phy = physical(z, c)
    residuals, states = [], []
    for weights, recurrent in zip(members, recurrents, strict=True):
        residual, recurrent = correction(weights, z_phy, c, recurrent, bound_mode, None, bound)
        residuals.append(residual)
        states.append(recurrent)
    residual = sum(residuals[1:], residuals[0]) / len(residuals)
    return z_phy + residual, z_phy, residual, tuple(states)


def correction(weights: Mapping, z_phy, c, recurrent: tuple, bound_mode: str | None,
               between: Callable | None = None, bound=None):
    """Return one member's bounded residual (state units) and its new recurrent state."""
    xp = namespace(z_phy, c)
    x = xp.concat([(c - weights['control_mean']) / weights['control_std'],
                   (z_phy - weights['state_mean']) / weights['state_std']], axis=-1)
    y, recurrent = lstm_stack(x, recurrent, weights['lstm'], between)
    return bounded_residual(y, weights, bound_mode, bound), recurrent


def bounded_residual(y, weights: Mapping, bound_mode: str | None, bound=None):
    """Return the LSTM output's residual in state units (..., n_state), bounded."""
    residual = (y @ weights['head_w'] + weights['head_b']) * weights['residual_std']
    if bound_mode is None:
        return residual
    return apply_bound(residual, weights['bound'] if bound is None else bound, bound_mode)
