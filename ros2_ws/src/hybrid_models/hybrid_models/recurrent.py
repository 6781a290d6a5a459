"""
The recurrent cell of the learned part, written once: its weights, its step, its state.

A cell is used three ways, and each is defined here:

- trained by torch's fused module (``torch_stack``: ``nn.LSTM`` or ``nn.GRU``,
  ``batch_first``) for the initializer's pass over the window, the LSTM baseline and
  teacher forcing;
- stepped one sample at a time against the Array API (``stack_step``): the hybrid's
  fed-back steps in torch and the served forecast in JAX (``hybrid_models.engine``)
  run this code;
- its state handed from the first to the second (``from_torch``).

The step reads the weights by the torch module's state-dict names (``weight_ih_l0``,
``bias_hh_l1``, ...; ``layer_weights``), so a checkpoint is served exactly as it was
trained. A recurrent state is a tuple of components (LSTM: h and c; GRU: h), each a
tuple of one (B, hidden) array per layer.

A new cell: a class with ``name``, ``torch_module``, ``gates``, ``components``,
``weights`` and ``layer``, listed in ``CELLS``; ``tests/unit/test_models_engine.py``
then checks that its served forecast equals the trained one in double precision.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from vessel_physics.arrays import namespace


def _sigmoid(xp, x):
    # The Array API has no sigmoid; 1/2 (1 + tanh(x/2)) is exact and never overflows.
    return 0.5 * (1.0 + xp.tanh(0.5 * x))


class LSTM:
    """
    torch.nn.LSTM's cell (Hochreiter & Schmidhuber 1997), gate order i, f, g, o.

    c' = sigma(f) c + sigma(i) tanh(g), h' = sigma(o) tanh(c'), the gates being
    x W_ih^T + h W_hh^T + b_ih + b_hh; the state is (h, c).
    """

    name = 'lstm'
    torch_module = 'LSTM'
    gates = 4
    components = 2

    @staticmethod
    def weights(w_ih, w_hh, b_ih, b_hh) -> tuple:
        """Return one layer's step weights from its torch parameters."""
        return w_ih.T, w_hh.T, b_ih + b_hh

    @staticmethod
    def layer(x, state: tuple, weights: tuple):
        """Advance one layer: return (its output h', its state (h', c'))."""
        xp = namespace(x)
        (h, c), (w_ih, w_hh, bias) = state, weights
        gates = x @ w_ih + h @ w_hh + bias
        n = gates.shape[-1] // 4
        i, f, g, o = (gates[..., j * n:(j + 1) * n] for j in range(4))
        c = _sigmoid(xp, f) * c + _sigmoid(xp, i) * xp.tanh(g)
        h = _sigmoid(xp, o) * xp.tanh(c)
        return h, (h, c)


class GRU:
    """
    torch.nn.GRU's cell (Cho et al. 2014), gate order r, z, n.

    r = sigma(x W_ir + b_ir + h W_hr + b_hr), z likewise, n = tanh(x W_in + b_in +
    r (h W_hn + b_hn)), h' = (1 - z) n + z h; the state is (h,). Three gates to the
    LSTM's four: a quarter fewer multiply-adds per step.
    """

    name = 'gru'
    torch_module = 'GRU'
    gates = 3
    components = 1

    @staticmethod
    def weights(w_ih, w_hh, b_ih, b_hh) -> tuple:
        """Return one layer's step weights, the biases apart: r scales b_hn only."""
        return w_ih.T, w_hh.T, b_ih, b_hh

    @staticmethod
    def layer(x, state: tuple, weights: tuple):
        """Advance one layer: return (its output h', its state (h',))."""
        xp = namespace(x)
        (h,), (w_ih, w_hh, b_ih, b_hh) = state, weights
        from_x, from_h = x @ w_ih + b_ih, h @ w_hh + b_hh
        n = from_x.shape[-1] // 3
        r = _sigmoid(xp, from_x[..., :n] + from_h[..., :n])
        z = _sigmoid(xp, from_x[..., n:2 * n] + from_h[..., n:2 * n])
        candidate = xp.tanh(from_x[..., 2 * n:] + r * from_h[..., 2 * n:])
        h = (1.0 - z) * candidate + z * h
        return h, (h,)


CELLS = {cell.name: cell for cell in (LSTM, GRU)}


def cell_of(name: str):
    """Return the cell called ``name`` (ValueError in one line if there is none)."""
    try:
        return CELLS[name]
    except (KeyError, TypeError):
        raise ValueError(f'unknown recurrent cell {name!r}; use one of '
                         f'{", ".join(CELLS)}') from None


def torch_stack(cell, n_in: int, hidden: int, layers: int, dropout: float):
    """Return torch's fused module of ``layers`` stacked cells (``batch_first``)."""
    # Imported here: the served forecast (engine) uses this module without torch.
    from torch import nn
    # torch applies dropout only between stacked layers, and warns when there is none.
    return getattr(nn, cell.torch_module)(n_in, hidden, layers, batch_first=True,
                                          dropout=dropout if layers > 1 else 0.0)


def layer_weights(cell, state: Mapping, prefix: str, layers: int) -> tuple:
    """Return per layer the step weights of the torch module ``prefix`` in a state dict."""
    return tuple(cell.weights(*(state[f'{prefix}.{name}_l{k}'] for name in
                                ('weight_ih', 'weight_hh', 'bias_ih', 'bias_hh')))
                 for k in range(layers))


def stack_step(cell, x, recurrent: tuple, layers: tuple, between: Callable | None = None):
    """
    Advance the stacked cells by one sample; return (output of the top layer, new state).

    ``between`` is applied to the output of every layer but the last (torch's dropout
    between stacked layers during training; nothing when serving).
    """
    new = []
    for k, weights in enumerate(layers):
        if k and between is not None:
            x = between(x)
        x, state = cell.layer(x, tuple(part[k] for part in recurrent), weights)
        new.append(state)
    return x, tuple(zip(*new, strict=True))


def from_torch(cell, final) -> tuple:
    """Return the step's state from the fused module's final state (each (layers, B, H))."""
    parts = final if cell.components > 1 else (final,)
    return tuple(tuple(part[k] for k in range(part.shape[0])) for part in parts)


def zeros(cell, xp, batch: int, layers: tuple, dtype) -> tuple:
    """Return the zero state of the stacked cells whose step weights are ``layers``."""
    hidden = layers[0][1].shape[0]   # W_hh^T is (hidden, gates * hidden)
    return tuple(tuple(xp.zeros((batch, hidden), dtype=dtype) for _ in layers)
                 for _ in range(cell.components))


def map_state(fn: Callable, recurrent: tuple) -> tuple:
    """Apply ``fn`` to every array of a recurrent state."""
    return tuple(tuple(fn(a) for a in part) for part in recurrent)


def step_flops(cell, n_in: int, hidden: int, layers: int) -> int:
    """Multiply-add FLOPs (2 per MAC) of one step of the stacked cells' matrix products."""
    return sum(2 * cell.gates * hidden * ((n_in if k == 0 else hidden) + hidden)
               for k in range(layers))
