"""Training on several processes (GPUs or machines) through torch.distributed.

**Launching.** ``torchrun --nproc-per-node N -m wovenskin.cli train --data DS ...`` (or
``python -m torch.distributed.run ...``; several machines: ``--nnodes`` and a rendezvous
endpoint, as torchrun documents) starts N copies of the command.  torchrun gives each one
``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK``, ``MASTER_ADDR`` and ``MASTER_PORT``;
:func:`session` reads them, initialises the default process group -- NCCL when the run's
device is CUDA, gloo on the CPU -- and destroys it at the end.  Without those variables, or
with ``WORLD_SIZE=1``, every function here is the identity of one process and the trainer
runs exactly as it does without torch.distributed.

**The contract between ranks** (``W`` processes, rank ``r``), as
:func:`~wovenskin.training.train.train_model` keeps it:

- *Data.* Every epoch draws one seeded permutation of the training windows, the same on
  every rank.  :func:`shard` cuts it to a multiple of ``W`` (the last ``N mod W`` windows
  of that epoch's order sit the epoch out: fewer than ``W``, a different few each epoch)
  and gives rank ``r`` every ``W``-th window from position ``r``.  The shares are
  disjoint, together they are the cut permutation, and they have one length, so every
  rank runs the same number of batches (DDP needs every rank at every all-reduce).
- *Batch.* ``batch_size`` is the global batch: each rank steps on ``batch_size / W``
  windows (:func:`rank_batch_size`; a batch size ``W`` does not divide is refused) and DDP
  averages the gradients, so every optimiser step sees ``batch_size`` windows, as in one
  process: rank ``r``'s k-th batch is the strided share of the one-process k-th batch of
  the cut permutation.  The learning-rate schedule counts the same steps.
- *Weights.* :func:`wrap` puts the model in ``DistributedDataParallel``, which broadcasts
  rank 0's weights and buffers (the fitted input scale) at wrapping; after every step all
  ranks hold the same weights.
- *Randomness.* Augmentation and dropout draw from ``(seed, epoch, rank)``; rank 0 keeps
  the one-process streams.
- *Validation.* Each rank scores every ``W``-th validation window from position ``r``;
  :func:`gather_scores` reassembles them in order on every rank, so all compute the same
  metrics.  Training loss and accuracy are summed over ranks (:func:`all_sum`).
- *Decisions.* Rank 0's epoch record (which sets the best epoch and early stopping) and
  its time-budget decision reach every rank through :func:`from_main`: ranks stop together.
- *Files.* Only rank 0 (:attr:`Ranks.is_main`) writes the checkpoint, ONNX graph,
  ``training_state.pt`` and history; the state a ``--resume`` continues and ``--init-from``
  weights are read by rank 0 and broadcast (an error there is raised on every rank), so
  the output directory needs to exist only where rank 0 runs; the data set must be
  readable by every rank.  The command line prints progress on rank 0 only.

Resuming a run with another number of processes is allowed (the saved state has one
set of weights) but replays the epochs differently: exact replay needs the same ``W``.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
import torch
import torch.distributed as dist
from torch import nn

from wovenskin.errors import ConfigError, WovenskinError
from wovenskin.training.device import resolve_device

T = TypeVar("T")
ENV_KEYS = ("RANK", "WORLD_SIZE", "LOCAL_RANK")
"""The variables torchrun sets in every process it starts (besides the master address)."""


@dataclass(frozen=True)
class Ranks:
    """Where this process stands among the processes of one run."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0

    @property
    def is_main(self) -> bool:
        """Rank 0: the process that writes files and prints."""
        return self.rank == 0

    @property
    def active(self) -> bool:
        """More than one process: collectives are needed."""
        return self.world_size > 1


SINGLE = Ranks()


def env_ranks(environ: Mapping[str, str] | None = None) -> Ranks | None:
    """The ranks torchrun set in ``environ`` (default ``os.environ``); None when unset.

    Some but not all of :data:`ENV_KEYS`, or values that are not ranks of the world, are
    one :class:`ConfigError`.
    """
    environ = os.environ if environ is None else environ
    present = [key for key in ENV_KEYS if key in environ]
    if not present:
        return None
    if len(present) != len(ENV_KEYS):
        missing = ", ".join(key for key in ENV_KEYS if key not in environ)
        raise ConfigError(f"distributed run: {missing} not set (launch with torchrun)")
    try:
        rank, world, local = (int(environ[key]) for key in ENV_KEYS)
    except ValueError:
        values = ", ".join(f"{key}={environ[key]!r}" for key in ENV_KEYS)
        raise ConfigError(f"distributed run: {values} are not whole numbers") from None
    if world < 1 or not 0 <= rank < world or local < 0:
        raise ConfigError(
            f"distributed run: RANK={rank}, WORLD_SIZE={world}, LOCAL_RANK={local} "
            "is not a rank of the world"
        )
    return Ranks(rank, world, local)


def launched(environ: Mapping[str, str] | None = None) -> bool:
    """Whether this process is one of several started by torchrun."""
    ranks = env_ranks(environ)
    return ranks is not None and ranks.active


def current() -> Ranks:
    """This process's ranks in the initialised default group (:data:`SINGLE` without one)."""
    if not (dist.is_available() and dist.is_initialized()):
        return SINGLE
    ranks = env_ranks()
    local = ranks.local_rank if ranks is not None else 0
    return Ranks(dist.get_rank(), dist.get_world_size(), local)


@contextlib.contextmanager
def session(device: str) -> Iterator[Ranks]:
    """The process group of a torchrun launch for the lifetime of the block.

    ``device`` (``auto``, ``cpu``, ``cuda``) chooses the backend: NCCL when it resolves to
    CUDA (each process on the GPU of its ``LOCAL_RANK``), gloo otherwise.  Not launched by
    torchrun (or one process): yields :data:`SINGLE` and initialises nothing.  A group
    someone else initialised is used as it is and left to them.
    """
    ranks = env_ranks()
    if ranks is None or not ranks.active:
        yield SINGLE
        return
    if dist.is_initialized():
        yield current()
        return
    missing = [key for key in ("MASTER_ADDR", "MASTER_PORT") if key not in os.environ]
    if missing:
        raise ConfigError(f"distributed run: {' and '.join(missing)} not set (torchrun sets them)")
    where = resolve_device(device, ranks.local_rank)
    if where.type == "cuda":
        torch.cuda.set_device(where)
    backend = "nccl" if where.type == "cuda" else "gloo"
    dist.init_process_group(backend, rank=ranks.rank, world_size=ranks.world_size)
    try:
        yield ranks
    finally:
        dist.destroy_process_group()


def rank_batch_size(batch_size: int, ranks: Ranks) -> int:
    """Windows per step on each rank: the global ``batch_size`` split evenly over ranks."""
    if batch_size % ranks.world_size:
        raise ConfigError(
            f"batch size {batch_size} does not split evenly over {ranks.world_size} "
            f"processes: give a multiple of {ranks.world_size} (it is the global batch)"
        )
    return batch_size // ranks.world_size


def shard(order: np.ndarray, ranks: Ranks) -> np.ndarray:
    """Rank ``r``'s share of an epoch's window order: every ``W``-th from position ``r`` of
    the order cut to a multiple of ``W`` (see the module docstring)."""
    usable = order.size - order.size % ranks.world_size
    return order[:usable][ranks.rank :: ranks.world_size]


def steps_per_epoch(n_train: int, batch_size: int, ranks: Ranks) -> int:
    """Optimiser steps in one epoch, the same on every rank."""
    share = (n_train - n_train % ranks.world_size) // ranks.world_size
    return -(-share // rank_batch_size(batch_size, ranks))


def wrap(model: nn.Module, ranks: Ranks) -> nn.Module:
    """``model`` in ``DistributedDataParallel`` when several processes train, else itself."""
    if not ranks.active:
        return model
    device = next(model.parameters()).device
    device_ids = [device.index] if device.type == "cuda" else None
    return nn.parallel.DistributedDataParallel(model, device_ids=device_ids)


def from_main(ranks: Ranks, compute: Callable[[], T]) -> T:
    """``compute()`` run on rank 0 and its result broadcast to every rank.

    A :class:`~wovenskin.errors.WovenskinError` it raises is raised on every rank (rank 0:
    the error itself; the others: a :class:`ConfigError` with its message), so no rank
    waits for a broadcast that never comes.
    """
    if not ranks.active:
        return compute()
    box: list[object] = [None]
    error: WovenskinError | None = None
    if ranks.is_main:
        try:
            box = [("ok", compute())]
        except WovenskinError as exc:
            error = exc
            box = [("error", str(exc))]
    dist.broadcast_object_list(box, src=0)
    kind, value = box[0]  # type: ignore[misc]
    if kind == "error":
        raise error if error is not None else ConfigError(str(value))
    return value  # type: ignore[return-value]


def main_value(ranks: Ranks, value: T) -> T:
    """Rank 0's ``value`` on every rank (a decision all must share)."""
    return from_main(ranks, lambda: value)


def unwrap(model: nn.Module) -> nn.Module:
    """The network inside a ``DistributedDataParallel`` wrapper (else ``model`` itself)."""
    if isinstance(model, nn.parallel.DistributedDataParallel):
        return model.module
    return model


def _collective_device() -> torch.device:
    if dist.get_backend() == "nccl":
        return torch.device("cuda", torch.cuda.current_device())
    return torch.device("cpu")


def all_sum(values: Sequence[float], ranks: Ranks) -> list[float]:
    """Each of ``values`` summed over all ranks (float64)."""
    if not ranks.active:
        return list(values)
    tensor = torch.tensor(values, dtype=torch.float64, device=_collective_device())
    dist.all_reduce(tensor)
    return tensor.cpu().tolist()


def share_of(indices: np.ndarray, ranks: Ranks) -> np.ndarray:
    """Rank ``r``'s share of windows to score: every ``W``-th from position ``r``."""
    return indices[ranks.rank :: ranks.world_size]


def gather_scores(scores: np.ndarray, n: int, ranks: Ranks) -> np.ndarray:
    """The ``(n, K)`` scores of all windows from each rank's :func:`share_of` scores."""
    if not ranks.active:
        return scores
    parts: list[np.ndarray | None] = [None] * ranks.world_size
    dist.all_gather_object(parts, scores)
    full = np.empty((n, scores.shape[1]), dtype=scores.dtype)
    for rank, part in enumerate(parts):
        full[rank :: ranks.world_size] = part
    return full


def barrier(ranks: Ranks) -> None:
    """Wait until every rank gets here."""
    if ranks.active:
        dist.barrier()
