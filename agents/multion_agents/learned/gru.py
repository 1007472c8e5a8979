"""The GRU recurrence with episode resets, with a hand-written backward pass.

Autograd through a step-by-step GRU computes and accumulates a full ``(3H, H)`` weight
gradient at every step; on a CPU this dominated the PPO update. :class:`MaskedGRU` keeps the
per-step work to element-wise operations and one small product for the hidden-state gradient,
and forms the weight gradient once, as a single matrix product over all steps.

The equations are ``nn.GRU``'s (gates r, z, n in that order), and the input projection
``W_ih x + b_ih`` is computed by the caller for all steps at once.
"""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor


class MaskedGRU(torch.autograd.Function):
    """``hs = MaskedGRU.apply(gates_x, h0, keep, w_hh, b_hh)``.

    ``gates_x`` (T, B, 3H) is the input projection, ``h0`` (B, H) the initial state, ``keep``
    (T, B) is 0 where an episode starts (the state is cleared before that step) and 1 elsewhere.
    Returns the hidden states ``hs`` (T, B, H) after every step.
    """

    @staticmethod
    def forward(
        ctx: Any, gates_x: Tensor, h0: Tensor, keep: Tensor, w_hh: Tensor, b_hh: Tensor
    ) -> Tensor:
        steps = gates_x.shape[0]
        hidden = h0
        outputs, previous, resets, updates, candidates, h_news = [], [], [], [], [], []
        for t in range(steps):
            hidden = hidden * keep[t][:, None]
            gates_h = torch.addmm(b_hh, hidden, w_hh.t())
            x_r, x_z, x_n = gates_x[t].chunk(3, dim=1)
            h_r, h_z, h_n = gates_h.chunk(3, dim=1)
            reset = torch.sigmoid(x_r + h_r)
            update = torch.sigmoid(x_z + h_z)
            candidate = torch.tanh(x_n + reset * h_n)
            previous.append(hidden)
            resets.append(reset)
            updates.append(update)
            candidates.append(candidate)
            h_news.append(h_n)
            hidden = (1.0 - update) * candidate + update * hidden
            outputs.append(hidden)
        ctx.save_for_backward(
            keep,
            w_hh,
            torch.stack(previous),
            torch.stack(resets),
            torch.stack(updates),
            torch.stack(candidates),
            torch.stack(h_news),
        )
        return torch.stack(outputs)

    @staticmethod
    def backward(ctx: Any, grad_outputs: Tensor) -> tuple[Tensor | None, ...]:
        keep, w_hh, previous, resets, updates, candidates, h_news = ctx.saved_tensors
        steps = grad_outputs.shape[0]
        grad_gates_x = grad_outputs.new_empty(*grad_outputs.shape[:2], 3 * grad_outputs.shape[2])
        grad_gates_h = torch.empty_like(grad_gates_x)
        grad_next = torch.zeros_like(grad_outputs[0])
        for t in reversed(range(steps)):
            grad_h = grad_outputs[t] + grad_next
            reset, update, candidate, h_n = resets[t], updates[t], candidates[t], h_news[t]
            grad_candidate = grad_h * (1.0 - update)
            grad_update = grad_h * (previous[t] - candidate)
            grad_previous = grad_h * update
            grad_a_n = grad_candidate * (1.0 - candidate * candidate)
            grad_a_z = grad_update * update * (1.0 - update)
            grad_a_r = grad_a_n * h_n * reset * (1.0 - reset)
            grad_gates_x[t] = torch.cat([grad_a_r, grad_a_z, grad_a_n], dim=1)
            grad_gates_h[t] = torch.cat([grad_a_r, grad_a_z, grad_a_n * reset], dim=1)
            grad_previous = grad_previous + grad_gates_h[t] @ w_hh
            grad_next = grad_previous * keep[t][:, None]
        flat_gates = grad_gates_h.reshape(-1, grad_gates_h.shape[2])
        grad_w = flat_gates.t() @ previous.reshape(-1, previous.shape[2])
        grad_b = flat_gates.sum(dim=0)
        return grad_gates_x, grad_next, None, grad_w, grad_b
