"""Multi-process training through torchrun: DDP with gloo on CPU, NCCL on CUDA.

``torchrun --nproc-per-node N -m actaim2.cli train ...`` sets RANK / WORLD_SIZE / LOCAL_RANK;
a plain run is world size 1 and touches no process group. Every rank draws the same global
batch (the batch RNG is seeded identically) and takes its own contiguous slice of it, so N
ranks on B / N samples each average to the gradient of the full batch of B (the losses are
batch means; tests/train/test_ddp.py checks it with 2 gloo ranks). Multi-GPU runs are untested
here (no GPU on the development machines); one CUDA rank is checked by scripts/gpu_check.py.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import torch
import torch.distributed as dist
from torch.nn.parallel import DistributedDataParallel

from actaim2.artifact.device import choose_device


@dataclass(frozen=True)
class DistContext:
    rank: int
    world_size: int
    local_rank: int
    device: torch.device

    @property
    def is_main(self) -> bool:
        return self.rank == 0

    @property
    def distributed(self) -> bool:
        return self.world_size > 1


def set_cpu_threads(threads: int) -> None:
    """torch's intra-op CPU threads; 0 keeps torch's default (one per core). On a machine busy with
    other work, threads beyond the free cores spin in OpenMP instead of computing: `actaim2
    validate` took 2062 s beside a 2-worker evaluation on 2 cores, 197 s alone, and beside two busy
    processes 569 s on one thread against more than 700 s on two (docs/training.md)."""
    if threads > 0:
        torch.set_num_threads(threads)


def init_distributed(preference: str = "auto") -> DistContext:
    """Join torchrun's process group when WORLD_SIZE > 1 (backend by device); a single process otherwise."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    rank, local = int(os.environ.get("RANK", "0")), int(os.environ.get("LOCAL_RANK", "0"))
    device = choose_device(preference, local)
    if world > 1 and not dist.is_initialized():
        if device.type == "cuda":
            torch.cuda.set_device(device)
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo", rank=rank, world_size=world)
    return DistContext(rank, world, local, device)


def wrap(module: torch.nn.Module, ctx: DistContext) -> torch.nn.Module:
    """DDP around ``module`` when distributed (gradients averaged over ranks), the module itself otherwise."""
    if not ctx.distributed:
        return module
    return DistributedDataParallel(module, device_ids=[ctx.device.index] if ctx.device.type == "cuda" else None)


def rank_slice(rows: np.ndarray, ctx: DistContext) -> np.ndarray:
    """This rank's contiguous share of a global batch (sizes differ by at most one)."""
    return np.array_split(rows, ctx.world_size)[ctx.rank]


def shutdown() -> None:
    """Leave the process group together, at the end of a normal run.

    The barrier keeps a rank that finishes first (rank 0 saving its checkpoint, say) from tearing
    down its gloo connections while a peer still reads from them: that race aborted a rank
    (SIGABRT, "terminate called without an active exception") once in a loaded CI run.
    """
    if dist.is_initialized():
        dist.barrier()
        dist.destroy_process_group()
