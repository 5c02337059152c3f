"""Mode discovery end to end on a synthetic set with two modes per observation (tests/train/synthetic.py).

The training loop pretrains the CGMVAE and the predictor (fixed seed, fixed step counts: 150 +
285 steps, measured 20-22 s of CPU, 52-64 s wall at load average 10 on 2 cores; the issue's
bound is 90 s). Then:
  * every mode is the majority outcome of at least one cluster of q(c | x, y, O),
  * every used cluster is >= 80% pure,
  * eps sampled from a mode-0 cluster and from a mode-1 cluster move the predictor's position
    argmax to the side of the object that mode touches.
"""
from __future__ import annotations

import time

import numpy as np
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.models.obs_encoder import ObsEncoderConfig
from actaim2.models.predictor import decode_action, proprio_features
from actaim2.models.selector_base import SelectorConfig
from actaim2.train.config import PhaseConfig, TrainConfig
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from synthetic import PLACEMENT, make_dataset

CONFIG = TrainConfig(
    seed=0,
    phases=("selector", "predictor"),
    selector=SelectorConfig(z_tokens=4, width=128, blocks=1, decoder_layers=2, latent_dim=16, y_dim=16,
                            obs=ObsEncoderConfig(input_resolution=16, widths=(16, 32), token_dim=32)),
    predictor=dict(patch=8, width=64, layers_within=1, layers_across=1, heads=4, dropout=0.0),
    selector_phase=PhaseConfig(epochs=60, batch_size=64, lr=2e-3),
    predictor_phase=PhaseConfig(epochs=15, batch_size=32, lr=2e-3),
    augment=False, log_every=1000, checkpoint_minutes=1e6,
)


def test_clusters_are_modes_and_eps_moves_the_action(tmp_path):
    torch.manual_seed(0)
    data, modes = make_dataset(160, resolution=32, seed=0)
    start, cpu = time.monotonic(), time.process_time()
    trainer = Trainer(CONFIG, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    trainer.run()
    print(f"training took {time.monotonic() - start:.1f} s wall, {time.process_time() - cpu:.1f} s CPU")
    selector, predictor = trainer.selector.eval(), trainer.predictor.eval()

    views, z = data.selector_batch(np.arange(len(data)))
    clusters = selector.assign_clusters(views, selector.standardise(z)).numpy()
    majority = {}
    for k in np.unique(clusters):
        members = modes[clusters == k]
        counts = np.bincount(members, minlength=2)
        assert counts.max() / counts.sum() >= 0.8, f"cluster {k} is {counts} (mode 0, mode 1): not 80% pure"
        majority[k] = int(counts.argmax())
    assert set(majority.values()) == {0, 1}, f"cluster majorities {majority} do not cover both modes"

    # Same observations, eps from a mode-0 cluster vs a mode-1 cluster: the position must move to that side.
    obs = torch.from_numpy(np.asarray(data.key_views[:40, 1], dtype=np.float32))
    proprio = proprio_features(torch.zeros(40, dtype=torch.bool), torch.ones(40, dtype=torch.long))
    k0 = max((k for k in majority if majority[k] == 0), key=lambda k: (clusters == k).sum())
    k1 = max((k for k in majority if majority[k] == 1), key=lambda k: (clusters == k).sum())
    gen = torch.Generator().manual_seed(0)
    init = views[:40]
    with torch.no_grad():
        out0 = predictor(obs, selector.sample(init, int(k0), gen).eps, proprio)
        out1 = predictor(obs, selector.sample(init, int(k1), gen).eps, proprio)
    argmax0 = out0.heatmaps.flatten(2).argmax(-1)
    argmax1 = out1.heatmaps.flatten(2).argmax(-1)
    assert (argmax0 != argmax1).any(dim=1).float().mean() >= 0.9  # eps moves the argmax
    x0 = decode_action(out0, PLACEMENT).position[:, 0].numpy()
    x1 = decode_action(out1, PLACEMENT).position[:, 0].numpy()
    centre_x = data.keyposes[:40, 1, 0] - np.where(modes[:40] == 0, -0.09, 0.09)  # the box centre
    assert np.mean(x0 < centre_x) >= 0.8 and np.mean(x1 > centre_x) >= 0.8  # mode 0 -> -x side, mode 1 -> +x side
