"""Gumbel draws of the mode selector's cluster c.

The paper's appendix writes the categorical draw as c = one-hot(argmax_i(g_i + log pi_i)) with
g_i i.i.d. Gumbel(0, 1): the Gumbel-max trick, an exact draw from Multi(pi), which sampling
uses. Its relaxation, the Gumbel-softmax omega_i = softmax((log pi_i + g_i) / tau), lets a
gradient pass through a draw of c: training uses it on the *generative* path (c -> x ~ p(x|y,c,O)
-> eps, the path sampling takes; train/elbo.py), with the temperature annealed as in the
authors' code, tau = max(exp(-0.0139 epoch), 0.5). The ELBO's own c terms need no relaxation:
q(c | x, y, O) is analytic and their expectation over c is exact.
"""
from __future__ import annotations

import torch


def sample_gumbel(shape: torch.Size | tuple[int, ...], generator: torch.Generator | None = None,
                  device: torch.device | str | None = None, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """i.i.d. Gumbel(0, 1) noise, -log(-log U), with U kept away from 0 and 1."""
    u = torch.rand(shape, generator=generator, device=device, dtype=dtype)
    return -torch.log(-torch.log(u.clamp(torch.finfo(dtype).tiny, 1.0 - torch.finfo(dtype).eps)))


TEMPERATURE_RATE = 0.0139  # per epoch (authors' code)
TEMPERATURE_FLOOR = 0.5


def gumbel_temperature(epoch: float, rate: float = TEMPERATURE_RATE, floor: float = TEMPERATURE_FLOOR) -> float:
    """The annealed Gumbel-softmax temperature max(exp(-rate * epoch), floor): 1 at epoch 0."""
    return max(float(torch.exp(torch.tensor(-rate * epoch))), floor)


def gumbel_softmax(log_probs: torch.Tensor, temperature: float, gumbel: torch.Tensor) -> torch.Tensor:
    """Relaxed one-hot draw softmax((log_probs + gumbel) / temperature) over the last axis; its
    argmax is the Gumbel-max draw with the same noise."""
    return torch.softmax((log_probs + gumbel) / temperature, dim=-1)


def gumbel_max(log_probs: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
    """Exact categorical draw argmax(log_probs + g) over the last axis: indices, shape of ``log_probs`` minus that axis."""
    return (log_probs + sample_gumbel(log_probs.shape, generator, log_probs.device, log_probs.dtype)).argmax(dim=-1)
