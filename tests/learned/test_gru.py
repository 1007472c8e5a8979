"""The hand-written GRU backward matches autograd through ``nn.GRU`` exactly (float64)."""

import torch
from torch import nn

from multion_agents.learned.gru import MaskedGRU


def test_masked_gru_matches_nn_gru_with_resets_forward_and_backward() -> None:
    torch.manual_seed(0)
    steps, batch, inputs, hidden = 7, 3, 5, 4
    gru = nn.GRU(inputs, hidden).double()
    x = torch.randn(steps, batch, inputs, dtype=torch.float64, requires_grad=True)
    h0 = torch.randn(batch, hidden, dtype=torch.float64, requires_grad=True)
    start = torch.zeros(steps, batch, dtype=torch.float64)
    start[3, 1] = start[5, 0] = 1.0  # two episodes start mid-sequence
    outputs, h = [], h0
    for t in range(steps):
        h = h * (1 - start[t])[:, None]
        h = gru(x[t : t + 1], h[None])[1][0]
        outputs.append(h)
    reference = torch.stack(outputs)
    gates = nn.functional.linear(x, gru.weight_ih_l0, gru.bias_ih_l0)
    mine = MaskedGRU.apply(gates, h0, 1 - start, gru.weight_hh_l0, gru.bias_hh_l0)
    assert torch.allclose(mine, reference)
    weights = torch.randn_like(reference)
    wrt = [x, h0, gru.weight_hh_l0, gru.bias_hh_l0, gru.weight_ih_l0]
    expected = torch.autograd.grad((reference * weights).sum(), wrt)
    got = torch.autograd.grad((mine * weights).sum(), wrt, retain_graph=True)
    for a, b in zip(expected, got, strict=True):
        assert torch.allclose(a, b)
    # a reset cuts the gradient: nothing after step 3 reaches env 1's initial state
    later = torch.autograd.grad(mine[3:, 1].sum(), h0, retain_graph=True)[0]
    assert torch.count_nonzero(later[1]) == 0
