"""Where a training run computes: the device (``auto``, ``cpu``, ``cuda``) and mixed precision.

:func:`resolve_device` turns :attr:`TrainConfig.device
<wovenskin.training.config.TrainConfig.device>` into a :class:`torch.device`: ``auto`` is
CUDA when ``torch.cuda.is_available()``, else the CPU; ``cuda`` on a machine without CUDA
is one :class:`~wovenskin.errors.ConfigError`.  In a distributed run each process takes
the GPU of its ``LOCAL_RANK`` (``cuda:LOCAL_RANK``).

:class:`Precision` is the mixed-precision policy of one run (:attr:`TrainConfig.amp`):

- ``auto`` (default): bfloat16 on a GPU that supports it, float16 on an older one, off on
  the CPU;
- ``bf16`` / ``fp16``: that type under :func:`torch.autocast` (CUDA only: asking for it on
  the CPU is a ``ConfigError``); float16 adds a :class:`torch.amp.GradScaler` so small
  gradients do not underflow (bfloat16 has float32's range and needs none);
- ``off``: float32 throughout.

Only the training forward pass and loss run under autocast; weights, optimiser state and
validation stay float32.  On the CPU nothing changes: no autocast, no scaler, the same
operations in the same order as before devices existed, so CPU runs keep their exact
determinism.  :func:`cpu_copy` gives the network as CPU weights, which is how every
checkpoint and ONNX graph is saved (they load on any machine).
"""

from __future__ import annotations

import contextlib
import copy
import itertools
from collections.abc import Iterable
from dataclasses import dataclass

import torch
from torch import nn

from wovenskin.errors import ConfigError

CLIP_NORM = 1.0
"""Gradients are clipped to this global norm (after unscaling, under float16)."""
_DTYPES = {"bf16": torch.bfloat16, "fp16": torch.float16}


def resolve_device(name: str, local_rank: int = 0) -> torch.device:
    """The device ``name`` (``auto``, ``cpu`` or ``cuda``) means on this machine.

    On CUDA the device is ``cuda:local_rank``; a rank beyond the GPUs present is refused.
    """
    if name not in ("auto", "cpu", "cuda"):
        raise ConfigError(f"unknown device {name!r}: choose auto, cpu or cuda")
    if name == "cpu" or (name == "auto" and not torch.cuda.is_available()):
        return torch.device("cpu")
    if not torch.cuda.is_available():
        raise ConfigError(
            f"--device cuda: no CUDA GPU is available to this torch {torch.__version__} "
            "(use --device cpu or auto)"
        )
    count = torch.cuda.device_count()
    if local_rank >= count:
        raise ConfigError(
            f"process LOCAL_RANK={local_rank} has no GPU of its own: this machine has {count} "
            "(start at most that many processes per node)"
        )
    return torch.device("cuda", local_rank)


def amp_dtype(amp: str, device: torch.device) -> torch.dtype | None:
    """The autocast type of ``amp`` on ``device``; None for float32 throughout."""
    if amp not in ("auto", "off", "bf16", "fp16"):
        raise ConfigError(f"unknown mixed precision {amp!r}: choose auto, off, bf16 or fp16")
    if amp == "off" or (amp == "auto" and device.type != "cuda"):
        return None
    if device.type != "cuda":
        raise ConfigError(f"--amp {amp} needs a CUDA device; on the CPU training runs in float32")
    if amp == "auto":
        return torch.bfloat16 if torch.cuda.is_bf16_supported() else torch.float16
    return _DTYPES[amp]


@dataclass
class Precision:
    """The device and mixed-precision policy of one run, and the optimiser step under it."""

    device: torch.device
    dtype: torch.dtype | None = None
    scaler: torch.amp.GradScaler | None = None

    @classmethod
    def of(cls, device: torch.device, amp: str) -> Precision:
        dtype = amp_dtype(amp, device)
        scaler = torch.amp.GradScaler("cuda") if dtype == torch.float16 else None
        return cls(device, dtype, scaler)

    @property
    def name(self) -> str:
        """``off``, ``bf16`` or ``fp16``."""
        return {None: "off", torch.bfloat16: "bf16", torch.float16: "fp16"}[self.dtype]

    def autocast(self) -> contextlib.AbstractContextManager:
        """Autocast to :attr:`dtype` on the device, or nothing when mixed precision is off."""
        if self.dtype is None:
            return contextlib.nullcontext()
        return torch.autocast(device_type=self.device.type, dtype=self.dtype)

    def step(
        self,
        loss: torch.Tensor,
        optimizer: torch.optim.Optimizer,
        parameters: Iterable[nn.Parameter],
    ) -> None:
        """Backward pass, gradient clipping (:data:`CLIP_NORM`) and one optimiser step."""
        if self.scaler is None:
            loss.backward()
            nn.utils.clip_grad_norm_(parameters, CLIP_NORM)
            optimizer.step()
            return
        self.scaler.scale(loss).backward()
        self.scaler.unscale_(optimizer)
        nn.utils.clip_grad_norm_(parameters, CLIP_NORM)
        self.scaler.step(optimizer)  # skipped when the gradients overflowed
        self.scaler.update()


def cpu_copy(module: nn.Module) -> nn.Module:
    """``module`` with CPU weights: itself when it is already there, else a CPU copy."""
    if module_device(module).type == "cpu":
        return module
    return copy.deepcopy(module).cpu()


def module_device(module: nn.Module) -> torch.device:
    """The device of ``module``'s first parameter or buffer (the CPU when it has none)."""
    first = next(itertools.chain(module.parameters(), module.buffers()), None)
    return torch.device("cpu") if first is None else first.device
