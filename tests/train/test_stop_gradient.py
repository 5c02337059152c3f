"""The joint phase's stop-gradient: L_action must not reach the selector (paper: P(a | o, sg[eps]))."""
from __future__ import annotations

import numpy as np
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.models.obs_encoder import ObsEncoderConfig
from actaim2.models.selector_base import SelectorConfig
from actaim2.train.config import TrainConfig
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from synthetic import PLACEMENT, make_dataset

TINY = TrainConfig(
    selector=SelectorConfig(z_tokens=4, width=32, blocks=1, decoder_layers=1, latent_dim=8, y_dim=8,
                            obs=ObsEncoderConfig(input_resolution=16, widths=(8, 16), token_dim=16)),
    predictor=dict(patch=8, width=32, layers_within=1, layers_across=1, heads=2, dropout=0.0), augment=False,
)


def test_action_loss_has_exactly_zero_gradient_on_the_selector(tmp_path):
    data, _ = make_dataset(6, resolution=32, seed=1)
    trainer = Trainer(TINY, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    items = data.keyframes()[:8]
    action, elbo, _ = trainer.losses("joint", data, items)
    action.backward(retain_graph=True)
    grads = [p.grad for p in trainer.selector.parameters()]
    assert all(g is None or torch.count_nonzero(g) == 0 for g in grads)
    assert any(p.grad is not None and torch.count_nonzero(p.grad) > 0 for p in trainer.predictor.parameters())
    # The selector does learn in the joint phase - through its own loss.
    elbo.backward()
    assert sum(int(torch.count_nonzero(p.grad)) for p in trainer.selector.parameters() if p.grad is not None) > 0
    assert np.isfinite(action.item()) and np.isfinite(elbo.item())
