"""Mixed precision for the PPO update (``multion train --mixed-precision``).

``bf16`` runs the loss's forward pass under ``torch.autocast`` in bfloat16 (same exponent range
as float32, so no loss scaling); ``fp16`` in float16 with a ``GradScaler``, whose loss scale
is kept per optimizer across updates (a fresh scaler would skip the first steps of every
update while it finds the scale again). The parameters, the optimizer's state and the
gradients stay float32. ``off`` (the default) is plain float32: on a CPU autocast is slower
than float32 for this model's small matrices, so it is meant for GPUs.
"""

from __future__ import annotations

import contextlib
import weakref
from collections.abc import Iterator
from dataclasses import dataclass

import torch
from torch import Tensor

from multion.config.ranges import ConfigError

PRECISIONS = ("off", "bf16", "fp16")
_DTYPES = {"bf16": torch.bfloat16, "fp16": torch.float16}
_SCALERS: weakref.WeakKeyDictionary[torch.optim.Optimizer, torch.amp.GradScaler] = (
    weakref.WeakKeyDictionary()
)


@dataclass(frozen=True)
class UpdatePrecision:
    """How one PPO update computes its loss and applies its gradients."""

    device: torch.device
    dtype: torch.dtype | None
    """None: float32, no autocast."""
    scaler: torch.amp.GradScaler | None
    """fp16's loss scaler; None for bf16 and float32."""

    @contextlib.contextmanager
    def autocast(self) -> Iterator[None]:
        if self.dtype is None:
            yield
            return
        with torch.autocast(self.device.type, dtype=self.dtype):
            yield

    def backward(self, loss: Tensor) -> None:
        (loss if self.scaler is None else self.scaler.scale(loss)).backward()

    def unscale(self, optimizer: torch.optim.Optimizer) -> None:
        """Gradients back to their true size, before they are clipped."""
        if self.scaler is not None:
            self.scaler.unscale_(optimizer)

    def step(self, optimizer: torch.optim.Optimizer) -> None:
        """The optimizer's step (fp16: skipped when a gradient overflowed; the scale adapts)."""
        if self.scaler is None:
            optimizer.step()
            return
        self.scaler.step(optimizer)
        self.scaler.update()


def update_precision(
    mode: str, device: torch.device, optimizer: torch.optim.Optimizer
) -> UpdatePrecision:
    """The precision of ``--mixed-precision mode`` on ``device``, or a ``ConfigError`` naming
    the option and what it allows."""
    if mode not in PRECISIONS:
        raise ConfigError(f"--mixed-precision {mode!r}: one of {', '.join(PRECISIONS)}")
    if mode == "off":
        return UpdatePrecision(device, None, None)
    if mode == "fp16" and device.type != "cuda":
        raise ConfigError("--mixed-precision fp16 needs a CUDA device; on a CPU use bf16 or off")
    scaler = None
    if mode == "fp16":
        scaler = _SCALERS.get(optimizer)
        if scaler is None:
            scaler = _SCALERS[optimizer] = torch.amp.GradScaler(device.type)
    return UpdatePrecision(device, _DTYPES[mode], scaler)
