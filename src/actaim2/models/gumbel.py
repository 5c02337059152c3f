"""Gumbel-max draws of the mode selector's cluster c ~ Multi(pi).

The paper's appendix writes the categorical draw as c = one-hot(argmax_i(g_i + log pi_i)) with
g_i i.i.d. Gumbel(0, 1): the Gumbel-max trick, an exact draw from Multi(pi). The paper then
relaxes it (Gumbel-softmax, temperature tau) so that gradients can pass through c. In this
implementation no gradient has to pass through a draw of c: q(c | x, y, O) is computed by
Bayes' rule and the ELBO takes exact expectations over c (train/elbo.py), so the relaxation and
its annealed temperature (the authors' max(exp(-0.0139 epoch), 0.5)) have no role left and are
not kept; the hard draw is what sampling uses.
"""
from __future__ import annotations

import torch


def sample_gumbel(shape: torch.Size | tuple[int, ...], generator: torch.Generator | None = None,
                  device: torch.device | str | None = None, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """i.i.d. Gumbel(0, 1) noise, -log(-log U), with U kept away from 0 and 1."""
    u = torch.rand(shape, generator=generator, device=device, dtype=dtype)
    return -torch.log(-torch.log(u.clamp(torch.finfo(dtype).tiny, 1.0 - torch.finfo(dtype).eps)))


def gumbel_max(log_probs: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
    """Exact categorical draw argmax(log_probs + g) over the last axis: indices, shape of ``log_probs`` minus that axis."""
    return (log_probs + sample_gumbel(log_probs.shape, generator, log_probs.device, log_probs.dtype)).argmax(dim=-1)
