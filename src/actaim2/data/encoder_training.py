"""Train the project's default image encoder E: an RGB-D autoencoder on robot-hidden observations.

Self-supervised: the loss is reconstruction of the camera pictures, so no DoF value or success
label is used. Training data are the O_init / O_final pictures of the training split only, so
the encoder never sees unseen instances or held-out categories. Small enough to train on two
CPU cores in a few minutes.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
import torch
import torch.nn.functional as F

from actaim2.data.encoder import ConvAutoencoder, ImageEncoder


def train_autoencoder(
    data: torch.Tensor,
    steps: int = 800,
    batch_size: int = 32,
    lr: float = 2e-3,
    seed: int = 0,
    progress: Callable[[int, float], None] | None = None,
) -> tuple[ImageEncoder, list[float]]:
    """Fit the autoencoder; returns E (its encoder half) and the loss per step.

    ``data`` are pictures prepared by ``ImageEncoder.preprocess`` with the autoencoder spec,
    (N, 4, H, W); callers build it in pieces so raw images never pile up in memory.
    """
    if len(data) == 0:
        raise ValueError("no pictures to train the encoder on")
    torch.manual_seed(seed)
    ae = ConvAutoencoder()
    encoder = ImageEncoder.autoencoder(ae)
    rng = np.random.default_rng(seed)
    opt = torch.optim.Adam(ae.parameters(), lr=lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, steps)
    losses = []
    ae.train()
    for step in range(steps):
        batch = data[torch.from_numpy(rng.integers(0, len(data), size=min(batch_size, len(data))))]
        loss = F.mse_loss(ae(batch), batch)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        losses.append(loss.item())
        if progress is not None:
            progress(step, losses[-1])
    ae.eval()
    return encoder.eval(), losses
