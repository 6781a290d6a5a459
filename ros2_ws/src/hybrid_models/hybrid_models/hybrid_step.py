"""
One step of the hybrid model, written once against the Array API.

Torch training (``nets.HybridModel``, with autograd) and the compiled jax forecaster
(``engine.Forecaster``, which only adds scan, jit and sharding) both run this code:

    z_phy  = physical(z_t, c_t)
    y, s   = cells((c_t - c_mean) / c_std, (z_phy - z_mean) / z_std; s)
    res    = bound((y W_head + b_head) * residual_std)
    z_t+1  = z_phy + res

(the bound scaled by the share available at the step's input for a model served with
the novelty fade, ``hybrid_models.novelty``).

An ensemble (``ensemble_step``) is K such corrections on one physics: every member's
recurrent stack reads the same z_phy, and the step adds the mean of their bounded residuals, so
the ensemble is still the physics plus a bounded amount.

The recurrent cell (LSTM or GRU) and its state are ``hybrid_models.recurrent``'s. Weights
come from a torch state dict's names (``lstm.weight_ih_l0``, ``head.weight``, ...; the
predictor stack keeps the paper's name whatever its cell) through ``step_weights``,
whatever the array type: torch parameters during training, numpy arrays read from a
checkpoint when serving.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from hybrid_models.bound import apply_bound
from hybrid_models.novelty import available
from hybrid_models.recurrent import layer_weights, stack_step
from vessel_physics.arrays import namespace

ENSEMBLE_KIND = 'hybrid_ensemble'   # a checkpoint's model kind for K members on one physics
NORMALIZATION = ('state_mean', 'state_std', 'control_mean', 'control_std', 'residual_std')


def step_weights(cell, state: Mapping, layers: int, novelty: Mapping | None = None) -> dict:
    """
    Return what ``hybrid_step`` reads, from a hybrid model's state dict (any arrays).

    ``novelty``: ``Novelty.weights()`` of a model served with the fade, else None.
    """
    weights = {name: state[name] for name in NORMALIZATION}
    weights.update(head_w=state['head.weight'].T, head_b=state['head.bias'],
                   bound=state['bound'], recurrent=layer_weights(cell, state, 'lstm', layers))
    if novelty is not None:
        weights['novelty'] = novelty
    return weights


def hybrid_step(cell, weights: Mapping, physical: Callable, z, c, recurrent: tuple,
                bound_mode: str | None, between: Callable | None = None, bound=None):
    """
    One sample period: return (z_next, z_phy, residual, recurrent state).

    z (B, n_state) and c (B, n_control) in the vessel's units; ``physical(z, c)`` is the
    physical model's one-period map; ``bound_mode`` None leaves the residual unbounded
    (training without the constraint), otherwise ``bound`` (this step's half-widths;
    default ``weights['bound']``) limits it.
    """
    z_phy = physical(z, c)
    residual, recurrent = correction(cell, weights, z_phy, c, recurrent, bound_mode, between,
                                     bound)
    return z_phy + residual, z_phy, residual, recurrent


def ensemble_step(cell, members: tuple, physical: Callable, z, c, recurrents: tuple,
                  bound_mode: str | None, bound=None):
    """
    One sample period of K hybrids on one physics: return (z_next, z_phy, residual, states).

    ``members`` holds each member's ``step_weights``, ``recurrents`` each member's
    recurrent state; the residual is the mean of the members' bounded residuals.
    """
    z_phy = physical(z, c)
    residuals, states = [], []
    for weights, recurrent in zip(members, recurrents, strict=True):
        residual, recurrent = correction(cell, weights, z_phy, c, recurrent, bound_mode, None,
                                         bound)
        residuals.append(residual)
        states.append(recurrent)
    residual = sum(residuals[1:], residuals[0]) / len(residuals)
    return z_phy + residual, z_phy, residual, tuple(states)


def correction_input(weights: Mapping, z_phy, c):
    """Return what the correction reads, the normalised (c, z_phy) (..., n_control + n_state)."""
    xp = namespace(z_phy, c)
    return xp.concat([(c - weights['control_mean']) / weights['control_std'],
                      (z_phy - weights['state_mean']) / weights['state_std']], axis=-1)


def correction(cell, weights: Mapping, z_phy, c, recurrent: tuple, bound_mode: str | None,
               between: Callable | None = None, bound=None):
    """
    Return one member's bounded residual (state units) and its new recurrent state.

    Weights with ``novelty`` (a model served with the fade, ``hybrid_models.novelty``)
    scale the bound by the share available at this step's input.
    """
    x = correction_input(weights, z_phy, c)
    y, recurrent = stack_step(cell, x, recurrent, weights['recurrent'], between)
    if bound_mode is not None and 'novelty' in weights:
        bound = (weights['bound'] if bound is None else bound) * available(x, weights['novelty'])
    return bounded_residual(y, weights, bound_mode, bound), recurrent


def bounded_residual(y, weights: Mapping, bound_mode: str | None, bound=None):
    """Return the recurrent output's residual in state units (..., n_state), bounded."""
    residual = (y @ weights['head_w'] + weights['head_b']) * weights['residual_std']
    if bound_mode is None:
        return residual
    return apply_bound(residual, weights['bound'] if bound is None else bound, bound_mode)
