"""DDP: two gloo ranks on half-batches average to the single-process gradient of the full batch.

Two processes on loopback (MASTER_ADDR=127.0.0.1) run the training loop's own batch slicing
(``rank_slice``) and DDP wrapping (``wrap``) for the predictor phase and for the selector's
ELBO; the selector's reparameterisation noise is drawn for the full batch and sliced, as the
loop's draws are per-sample identical across ranks only through explicit noise.
"""
from __future__ import annotations

import os
import socket

import numpy as np
import torch
import torch.multiprocessing as mp

from actaim2.artifact.checkpoint import perception_record
from actaim2.train.distributed import init_distributed, rank_slice, shutdown, wrap
from actaim2.train.elbo import selector_loss
from actaim2.train.loop import Trainer
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY

BATCH = 8


def _gradients(rank: int, world: int, out: str) -> None:
    """Selector and predictor gradients of this rank's share of one global batch, saved to ``out``."""
    torch.set_num_threads(1)
    if world > 1:  # a spawned rank (the single-process reference runs in pytest's own process)
        os.environ.update(RANK=str(rank), WORLD_SIZE=str(world), LOCAL_RANK=str(rank))
    ctx = init_distributed("cpu")
    data, _ = make_dataset(4, resolution=32, seed=2)
    trainer = Trainer(TINY, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", f"{out}.d",
                      ctx, show_progress=False)
    items = data.keyframes()[:BATCH]
    predictor = wrap(trainer.predictor, ctx)
    loss, _ = trainer.loss("predictor", data, rank_slice(items, ctx), {trainer.predictor: predictor})
    loss.backward()

    selector = wrap(trainer.selector, ctx)
    rows = np.arange(BATCH) % len(data)
    noise = trainer.selector.draw_noise(BATCH, torch.Generator().manual_seed(7))
    mine = rank_slice(np.arange(BATCH), ctx)
    views, z = data.selector_batch(rows[mine])
    elbo, _, _ = selector_loss(selector, views, trainer.selector.standardise(z), TINY.elbo,
                               {k: v[torch.from_numpy(mine)] for k, v in noise.items()})
    elbo.backward()
    grads = {f"predictor.{n}": p.grad.clone() for n, p in trainer.predictor.named_parameters() if p.grad is not None}
    grads.update({f"selector.{n}": p.grad.clone() for n, p in trainer.selector.named_parameters() if p.grad is not None})
    if rank == 0:
        torch.save(grads, out)
    shutdown()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_two_gloo_ranks_match_the_full_batch_gradient(tmp_path, monkeypatch):
    monkeypatch.setenv("MASTER_ADDR", "127.0.0.1")
    monkeypatch.setenv("MASTER_PORT", str(_free_port()))
    single, double = str(tmp_path / "single.pt"), str(tmp_path / "double.pt")
    _gradients(0, 1, single)
    mp.spawn(_gradients, args=(2, double), nprocs=2, join=True)
    a, b = torch.load(single, weights_only=True), torch.load(double, weights_only=True)
    assert a.keys() == b.keys() and any(k.startswith("selector.") for k in a) and any(k.startswith("predictor.") for k in a)
    for name in a:
        torch.testing.assert_close(b[name], a[name], atol=1e-5, rtol=0, msg=lambda m: f"{name}: {m}")
