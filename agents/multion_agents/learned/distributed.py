"""DD-PPO's plumbing: ranks from ``torchrun``, gradient averaging, weight broadcast and checks,
and the device and cores each rank uses."""

from __future__ import annotations

import hashlib
import os

import torch
import torch.distributed as dist
from torch import nn

from multion.config.ranges import ConfigError


def init_distributed(device: torch.device) -> tuple[int, int]:
    """(rank, world size): from torchrun's environment, or (0, 1) for a single process."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world <= 1:
        return 0, 1
    if not dist.is_initialized():
        dist.init_process_group(backend="nccl" if device.type == "cuda" else "gloo")
    return dist.get_rank(), dist.get_world_size()


def average_gradients(policy: nn.Module) -> None:
    """All-reduce the gradients (one flat buffer) and divide by the number of ranks."""
    if not (dist.is_available() and dist.is_initialized()) or dist.get_world_size() == 1:
        return
    grads: list[torch.Tensor] = []
    for p in policy.parameters():
        if not p.requires_grad:
            continue
        if p.grad is None:  # parameters a model did not use this step still take part in the sum
            p.grad = torch.zeros_like(p)
        grads.append(p.grad)
    flat = torch.cat([g.reshape(-1) for g in grads])
    dist.all_reduce(flat)
    flat /= dist.get_world_size()
    offset = 0
    for g in grads:
        g.copy_(flat[offset : offset + g.numel()].view_as(g))
        offset += g.numel()


def weights_digest(policy: nn.Module) -> str:
    """SHA-256 of the weights, to check that DD-PPO ranks hold the same model."""
    digest = hashlib.sha256()
    for name, tensor in sorted(policy.state_dict().items()):
        digest.update(name.encode())
        digest.update(tensor.detach().cpu().contiguous().numpy().tobytes())
    return digest.hexdigest()


def broadcast_parameters(policy: nn.Module) -> None:
    """Copy rank 0's weights to every rank."""
    if dist.is_available() and dist.is_initialized():
        for tensor in policy.state_dict().values():
            dist.broadcast(tensor, src=0)


def sum_over_ranks(values: list[float], device: torch.device) -> list[float]:
    """Element-wise sums over DD-PPO ranks (on ``device``: NCCL reduces CUDA tensors only)."""
    if not (dist.is_available() and dist.is_initialized()):
        return values
    tensor = torch.tensor(values, dtype=torch.float64, device=device)
    dist.all_reduce(tensor)
    return tensor.tolist()


def cores_per_rank() -> int:
    """This machine's cores shared among the torchrun ranks it runs."""
    ranks_here = int(os.environ.get("LOCAL_WORLD_SIZE", "1"))
    return max(1, len(os.sched_getaffinity(0)) // ranks_here)


def select_device(name: str) -> torch.device:
    """The torch device of ``--device``: ``auto`` is CUDA when torch sees a GPU. A plain
    ``cuda`` under torchrun is this rank's GPU (``LOCAL_RANK``, wrapped around the GPUs)."""
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    try:
        device = torch.device(name)
    except RuntimeError:
        raise ConfigError(f"--device {name!r}: expected cpu, cuda, cuda:N or auto") from None
    if device.type == "cuda":
        if not torch.cuda.is_available():
            raise ConfigError(
                f"--device {name}: torch sees no CUDA GPU (a CPU build of torch, or no driver)"
            )
        if device.index is None:
            local_rank = int(os.environ.get("LOCAL_RANK", "0"))
            device = torch.device("cuda", local_rank % torch.cuda.device_count())
        torch.cuda.set_device(device)
    return device
