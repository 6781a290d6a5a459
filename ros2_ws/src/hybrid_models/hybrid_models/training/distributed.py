"""
Data-parallel training over processes: torch.distributed, launched by torchrun.

Started without torchrun, training is one process of world size 1 and no process group
exists. Under ``torchrun`` (which sets ``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK`` and the
rendezvous address) every process joins one group, gloo on CPU and NCCL on GPUs, and the
fit loop wraps the model in DistributedDataParallel.

The batch rule: ``training.batch_size`` is the GLOBAL batch. All ranks draw the same
epoch permutation; each global batch is dealt round-robin (rank r takes rows r, r+N,
...), each rank weights its mean loss by its share of the rows, and DDP's gradient
average is then exactly the one-process gradient of that global batch. So the learning
rate is NOT scaled with the number of processes: one config trains the same model, to
float rounding, on 1 or N processes. A global batch with fewer rows than processes (an
epoch's last one at most) cannot be dealt and is skipped.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import os

import numpy as np
import torch
from torch import nn
import torch.distributed as dist

DEVICES = ('auto', 'cpu', 'cuda')


class DeviceError(ValueError):
    """The requested device does not exist on this machine."""


def resolve_device(choice: str, local_rank: int = 0) -> torch.device:
    """Return the device for ``choice`` (auto: a GPU when one is present, else the CPU)."""
    if choice not in DEVICES:
        raise DeviceError(f'device must be one of {DEVICES}, got {choice!r}')
    has_gpu = torch.cuda.is_available() and torch.cuda.device_count() > 0
    if choice == 'cuda' and not has_gpu:
        raise DeviceError('--device cuda: no CUDA GPU is visible to torch on this machine')
    if choice == 'cpu' or not has_gpu:
        return torch.device('cpu')
    return torch.device('cuda', local_rank % torch.cuda.device_count())


@dataclass(frozen=True)
class Shard:
    """Which rows of each global batch this process trains on."""

    rank: int = 0
    world: int = 1

    def deal(self, rows: np.ndarray) -> tuple[np.ndarray, float] | None:
        """
        Return (this rank's rows, loss weight) of a global batch; None to skip it.

        The weight ``len(mine) * world / len(rows)`` makes DDP's mean of the ranks'
        gradients the gradient of the mean loss over all ``rows`` (1.0 on one process).
        """
        if len(rows) < self.world:
            return None
        mine = rows[self.rank::self.world]
        return mine, len(mine) * self.world / len(rows)


@dataclass(frozen=True)
class Group:
    """This process's place in the training job (rank 0 of 1 without torchrun)."""

    rank: int = 0
    world: int = 1
    local_rank: int = 0
    device: torch.device = field(default_factory=lambda: torch.device('cpu'))

    @property
    def main(self) -> bool:
        """Return True on the one process that writes files and prints."""
        return self.rank == 0

    @property
    def shard(self) -> Shard:
        """Return the batch split of this rank."""
        return Shard(self.rank, self.world)

    def sum(self, values: list[float]) -> list[float]:
        """Sum ``values`` over all ranks (float64; NaN anywhere gives NaN everywhere)."""
        if self.world == 1:
            return list(values)
        t = torch.tensor(values, dtype=torch.float64, device=self.device)
        dist.all_reduce(t, op=dist.ReduceOp.SUM)
        return t.tolist()

    def max(self, value: float) -> float:
        """Largest ``value`` over all ranks (so decisions taken on it agree)."""
        if self.world == 1:
            return value
        t = torch.tensor([value], dtype=torch.float64, device=self.device)
        dist.all_reduce(t, op=dist.ReduceOp.MAX)
        return float(t.item())

    def barrier(self) -> None:
        """Wait for every rank."""
        if self.world > 1:
            dist.barrier()

    def wrap(self, module: nn.Module) -> nn.Module:
        """Wrap ``module`` in DistributedDataParallel on several processes (else as is)."""
        if self.world == 1:
            return module
        ids = [self.device.index] if self.device.type == 'cuda' else None
        return nn.parallel.DistributedDataParallel(module, device_ids=ids)


def launched_by_torchrun() -> bool:
    """Return True when torchrun (or another launcher) set the process-group variables."""
    return all(k in os.environ for k in ('RANK', 'WORLD_SIZE', 'MASTER_ADDR', 'MASTER_PORT'))


def join(device: str = 'auto') -> Group:
    """
    Return this process's group, joining torch.distributed when launched by torchrun.

    The backend follows the device: NCCL for CUDA, gloo for the CPU.
    """
    if not launched_by_torchrun() or int(os.environ['WORLD_SIZE']) == 1:
        return Group(device=resolve_device(device))
    rank, world = int(os.environ['RANK']), int(os.environ['WORLD_SIZE'])
    local_rank = int(os.environ.get('LOCAL_RANK', 0))
    dev = resolve_device(device, local_rank)
    if dev.type == 'cuda':
        torch.cuda.set_device(dev)
    if not dist.is_initialized():
        dist.init_process_group('nccl' if dev.type == 'cuda' else 'gloo')
    return Group(rank, world, local_rank, dev)


def leave(group: Group) -> None:
    """Leave the process group (after a last barrier, so no rank exits early)."""
    if group.world > 1 and dist.is_initialized():
        dist.barrier()
        dist.destroy_process_group()
