"""The mode selector's half of `actaim2 bench models`: parameters, sample latency, training step.

Per selector kind (cgmvae = the paper's, cvae and vqvae = baselines), at the CPU default sizes
(z of the default encoder E on ring5: 1920 dimensions; 128 px views):
  * sample, batch 1: views -> per-view tokens -> cluster drawn from the prior -> eps
    (eval mode, no gradient): the cost the policy pays once per episode (target p50 <= 5 ms);
  * training step, batch 8: the selector loss (train/elbo.py), backward and an AdamW step.
Rows have the keys of :func:`actaim2.bench.models.bench_predictor`'s, so one table shows both.
"""
from __future__ import annotations

import torch

from actaim2.bench.models import result_row, time_calls

TARGET_SAMPLE_P50_MS = 5.0
SAMPLE_BATCH = 1
TRAIN_BATCH = 8


def bench_selector(kinds: tuple[str, ...] = ("cgmvae", "cvae", "vqvae"), config=None, resolution: int = 128,
                   device: str = "cpu", threads: int = 2, repeats: int = 100, train_repeats: int = 10,
                   seed: int = 0) -> list[dict]:
    """Rows for each selector kind; ``config`` is a SelectorConfig (None = the CPU default sizes)."""
    import dataclasses

    from actaim2.models.registry import build_selector
    from actaim2.models.selector_base import SelectorConfig
    from actaim2.train.config import ElboWeights
    from actaim2.train.elbo import selector_loss

    torch.set_num_threads(threads)
    dev = torch.device(device)
    base = config or SelectorConfig()
    rows = []
    for kind in kinds:
        torch.manual_seed(seed)
        cfg = dataclasses.replace(base, kind=kind)
        model = build_selector(cfg).to(dev).eval()
        params = sum(p.numel() for p in model.parameters())
        name = f"selector {kind} K{cfg.clusters} x{cfg.latent_dim} z{cfg.z_dim}"
        views = torch.rand(SAMPLE_BATCH, cfg.obs.views, cfg.obs.in_channels, resolution, resolution, device=dev)
        gen = torch.Generator(device=dev).manual_seed(seed)
        wall, cpu = time_calls(lambda: model.sample(views, None, gen), repeats, warmup=5, device=dev)
        target = TARGET_SAMPLE_P50_MS if dev.type == "cpu" and kind == "cgmvae" else None
        rows.append(result_row(name, "sample (views -> eps)", SAMPLE_BATCH, params, wall, cpu, target))

        model.train()
        optimiser = torch.optim.AdamW(model.parameters(), lr=1e-4)
        views = torch.rand(TRAIN_BATCH, cfg.obs.views, cfg.obs.in_channels, resolution, resolution, device=dev)
        eps = torch.randn(TRAIN_BATCH, cfg.z_dim, device=dev)

        def train_step():
            loss, _, _ = selector_loss(model, views, eps, ElboWeights())
            optimiser.zero_grad(set_to_none=True)
            loss.backward()
            optimiser.step()

        wall, cpu = time_calls(train_step, train_repeats, warmup=2, device=dev)
        rows.append(result_row(name, "training step", TRAIN_BATCH, params, wall, cpu, None))
    return rows
