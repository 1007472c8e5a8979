"""The GRU recurrence with episode resets, with a hand-written backward pass.

Autograd through a step-by-step GRU computes and accumulates a full ``(3H, H)`` weight
gradient at every step; on a CPU this dominated the PPO update. :class:`MaskedGRU` keeps the
per-step work to element-wise operations and one small product for the hidden-state gradient,
and forms the weight gradient once, as a single matrix product over all steps. Every per-step
result is written into tensors allocated once for the whole sequence, and steps where no
episode starts skip the reset.

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
        steps, batch, width = gates_x.shape
        size = width // 3
        # which steps clear a state: read on the CPU only (elsewhere it would wait for the
        # device; every step then multiplies, as before)
        on_cpu = keep.device.type == "cpu"
        clears = (keep == 0).any(dim=1).tolist() if on_cpu else [True] * steps
        outputs = gates_x.new_empty(steps, batch, size)
        previous = torch.empty_like(outputs)
        gates = torch.empty_like(gates_x)  # r, z, n after their non-linearities
        h_news = torch.empty_like(outputs)
        w_t = w_hh.t()
        hidden = h0
        for t in range(steps):
            if clears[t]:
                hidden = hidden * keep[t][:, None]
            previous[t] = hidden
            gates_h = torch.addmm(b_hh, hidden, w_t)
            h_n = gates_h[:, 2 * size :]
            h_news[t] = h_n
            reset_update = gates[t, :, : 2 * size]
            torch.sigmoid(gates_x[t, :, : 2 * size] + gates_h[:, : 2 * size], out=reset_update)
            reset, update = reset_update[:, :size], reset_update[:, size:]
            candidate = gates[t, :, 2 * size :]
            torch.tanh(gates_x[t, :, 2 * size :] + reset * h_n, out=candidate)
            hidden = torch.addcmul(candidate, update, hidden - candidate, out=outputs[t])
        ctx.save_for_backward(keep, w_hh, previous, gates, h_news)
        ctx.clears = clears
        return outputs

    @staticmethod
    def backward(ctx: Any, grad_outputs: Tensor) -> tuple[Tensor | None, ...]:
        keep, w_hh, previous, gates, h_news = ctx.saved_tensors
        clears: list[bool] = ctx.clears
        steps, _, size = grad_outputs.shape
        grad_gates_x = torch.empty_like(gates)
        grad_gates_h = torch.empty_like(gates)
        grad_next = torch.zeros_like(grad_outputs[0])
        for t in reversed(range(steps)):
            grad_h = grad_outputs[t] + grad_next
            reset, update = gates[t, :, :size], gates[t, :, size : 2 * size]
            candidate, h_n = gates[t, :, 2 * size :], h_news[t]
            grad_a_n = grad_h * (1.0 - update) * (1.0 - candidate * candidate)
            grad_a_z = grad_h * (previous[t] - candidate) * update * (1.0 - update)
            grad_a_r = grad_a_n * h_n * reset * (1.0 - reset)
            grad_gates_x[t, :, :size] = grad_a_r
            grad_gates_x[t, :, size : 2 * size] = grad_a_z
            grad_gates_x[t, :, 2 * size :] = grad_a_n
            grad_gates_h[t, :, : 2 * size] = grad_gates_x[t, :, : 2 * size]
            torch.mul(grad_a_n, reset, out=grad_gates_h[t, :, 2 * size :])
            grad_next = torch.addmm(grad_h * update, grad_gates_h[t], w_hh)
            if clears[t]:
                grad_next = grad_next * keep[t][:, None]
        flat_gates = grad_gates_h.reshape(-1, grad_gates_h.shape[2])
        grad_w = flat_gates.t() @ previous.reshape(-1, size)
        grad_b = flat_gates.sum(dim=0)
        return grad_gates_x, grad_next, None, grad_w, grad_b
