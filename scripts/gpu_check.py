#!/usr/bin/env python3
"""One prepared GPU check of the learned policy: run with plain `python` + torch.

    python scripts/gpu_check.py            # on a machine with CUDA (torch preinstalled, no network)
    python scripts/gpu_check.py --cpu      # the same code path on the CPU, small sizes (local test)

What it does, printing one JSON summary at the end:
  1. moves the action predictor (CPU default and RVT size) and the CGMVAE selector to the device,
     at the sizes of cpu_default.yaml / gpu_rvt.yaml (eps: 16 whitened principal components of z,
     fitted by an SVD on the device, checked to come out whitened); forward + backward under bf16
     autocast, checks losses and gradients are finite and that the bf16 loss agrees with the fp32
     loss;
  2. predictor training throughput (samples/s) at batch 64, and inference latency p50/p99 at
     batch 1 (forward + coarse-to-fine 3-D decode), with mode guidance too (models/mode_guidance.py,
     its decode on the device checked against the CPU's on the same logits); selector training
     throughput and sample latency;
  3. DDP: with >= 2 GPUs, two NCCL ranks on half-batches vs one process on the full batch
     (gradient equality); with one GPU, a 1-rank NCCL process group and an all-reduce.
The project venv is not needed: ``src/`` is put on sys.path. Modules the check does not use
but that the library imports at top level (yaml, scipy's Rotation) are replaced by stubs when
missing - only for this check; the stubs raise if anything calls them.
"""
from __future__ import annotations

import argparse
import json
import os
import socket
import sys
import time
import types
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))


def _stub_missing_modules() -> list[str]:
    """Stand-ins for optional imports absent on a bare GPU machine; returns what was stubbed."""
    stubbed = []

    def unavailable(name):
        def fail(*_a, **_k):
            raise RuntimeError(f"{name} is not installed on this machine (stubbed by gpu_check)")
        return fail

    try:
        import yaml  # noqa: F401
    except ImportError:
        mod = types.ModuleType("yaml")
        mod.safe_load = mod.safe_dump = unavailable("yaml")
        sys.modules["yaml"] = mod
        stubbed.append("yaml")
    try:
        from scipy.spatial.transform import Rotation  # noqa: F401
    except ImportError:
        for name in ("scipy", "scipy.spatial", "scipy.spatial.transform"):
            sys.modules[name] = types.ModuleType(name)
        sys.modules["scipy.spatial.transform"].Rotation = type("Rotation", (), {"__getattr__": unavailable("scipy")})
        stubbed.append("scipy")
    for name in ("tqdm", "safetensors"):
        try:
            __import__(name)
        except ImportError:
            stubbed.append(f"{name} (absent, unused here)")
    return stubbed


STUBBED = _stub_missing_modules()

import numpy as np  # noqa: E402
import torch  # noqa: E402
import torch.distributed as dist  # noqa: E402
import torch.multiprocessing as mp  # noqa: E402

from actaim2.models.mode_guidance import guide, with_reference  # noqa: E402
from actaim2.models.obs_encoder import ObsEncoderConfig  # noqa: E402
from actaim2.models.predictor import (  # noqa: E402
    ActionPredictor,
    PredictorConfig,
    proprio_features,
)
from actaim2.models.registry import build_selector  # noqa: E402
from actaim2.models.selector_base import SelectorConfig  # noqa: E402
from actaim2.models.view_geometry import decode_points, heatmap_targets  # noqa: E402
from actaim2.train.action_loss import ActionTargets, action_loss  # noqa: E402
from actaim2.train.config import ElboWeights  # noqa: E402
from actaim2.train.elbo import selector_loss  # noqa: E402

Z_DIM = 1920  # z of the default encoder E on ring5
EPS_DIM, Z_TOKENS = 16, 4  # selector.eps_dim / z_tokens of cpu_default.yaml and gpu_rvt.yaml
FIT_TRAJECTORIES = 48  # stand-in training set for fit_statistics (more than EPS_DIM)


def _sync(dev: torch.device) -> None:
    if dev.type == "cuda":
        torch.cuda.synchronize(dev)


def _timed(fn, repeats: int, warmup: int, dev: torch.device) -> np.ndarray:
    out = []
    for i in range(warmup + repeats):
        _sync(dev)
        start = time.perf_counter()
        fn()
        _sync(dev)
        if i >= warmup:
            out.append((time.perf_counter() - start) * 1e3)
    return np.array(out)


def _predictor_batch(config: PredictorConfig, batch: int, dev: torch.device, seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    views = torch.rand(batch, config.views, config.in_channels, config.image_size, config.image_size, generator=g)
    eps = torch.randn(batch, config.embedding_dim, generator=g)
    proprio = proprio_features(torch.zeros(batch), torch.randint(0, 4, (batch,), generator=g))
    points = torch.rand(batch, 3, generator=g) * 1.6 - 0.8  # cube frame
    targets = ActionTargets(heatmap_targets(points, config.image_size), torch.randint(0, config.rotation_bins, (batch, 3), generator=g),
                            torch.randint(0, 2, (batch,), generator=g))
    move = lambda t: None if t is None else t.to(dev)  # noqa: E731  (depth targets: single-view only)
    return move(views), move(eps), move(proprio), ActionTargets(*map(move, targets))


def check_predictor(name: str, config: PredictorConfig, dev: torch.device, batch: int, repeats: int) -> dict:
    torch.manual_seed(0)
    model = ActionPredictor(config).to(dev)
    views, eps, proprio, targets = _predictor_batch(config, batch, dev)
    model.train()
    with torch.autocast(dev.type, dtype=torch.bfloat16):
        loss_bf16, _ = action_loss(model(views, eps, proprio), targets)
    loss_bf16.backward()
    grads_finite = all(torch.isfinite(p.grad).all().item() for p in model.parameters() if p.grad is not None)
    model.zero_grad(set_to_none=True)
    model.eval()  # dropout off for the fp32 / bf16 comparison
    with torch.no_grad():
        loss_fp32 = action_loss(model(views, eps, proprio), targets)[0].item()
        with torch.autocast(dev.type, dtype=torch.bfloat16):
            loss_bf16_eval = action_loss(model(views, eps, proprio), targets)[0].item()
    model.train()
    optimiser = torch.optim.AdamW(model.parameters(), lr=1e-4)

    def step():
        with torch.autocast(dev.type, dtype=torch.bfloat16):
            loss, _ = action_loss(model(views, eps, proprio), targets)
        optimiser.zero_grad(set_to_none=True)
        loss.backward()
        optimiser.step()

    train_ms = _timed(step, repeats, 3, dev)
    model.eval()
    one = tuple(t[:1] for t in (views, eps, proprio))

    def infer():
        with torch.inference_mode(), torch.autocast(dev.type, dtype=torch.bfloat16):
            decode_points(model(*one).heatmaps.float())

    infer_ms = _timed(infer, max(repeats * 3, 10), 5, dev)

    def guided_out():  # mode guidance: the eps row and the mean-mode row in one batch of 2
        return model(one[0].expand(2, -1, -1, -1, -1), with_reference(one[1]), one[2].expand(2, -1))

    def infer_guided():
        with torch.inference_mode(), torch.autocast(dev.type, dtype=torch.bfloat16):
            decode_points(guide(guided_out(), 2.0).heatmaps)

    guided_ms = _timed(infer_guided, max(repeats * 3, 10), 5, dev)
    with torch.inference_mode():  # the guidance and decode on the device against the same logits on the CPU
        raw = guided_out()
        on_device = decode_points(guide(raw, 2.0).heatmaps)
        on_cpu = decode_points(guide(type(raw)(*(None if t is None else t.cpu() for t in raw)), 2.0).heatmaps)
    guided_cell_error = float((on_device.cpu() - on_cpu).abs().max()) * config.image_size / 2  # cube [-1, 1] -> cells
    return {
        "model": name, "params_M": round(sum(p.numel() for p in model.parameters()) / 1e6, 3),
        "loss_bf16_train": round(loss_bf16.item(), 4), "loss_fp32_eval": round(loss_fp32, 4),
        "loss_bf16_eval": round(loss_bf16_eval, 4),
        "bf16_fp32_rel_diff": round(abs(loss_bf16_eval - loss_fp32) / abs(loss_fp32), 5),
        "grads_finite": grads_finite, "train_batch": batch,
        "train_samples_per_s": round(batch * 1e3 / float(np.median(train_ms)), 1),
        "train_step_p50_ms": round(float(np.median(train_ms)), 2),
        "infer_b1_p50_ms": round(float(np.percentile(infer_ms, 50)), 3),
        "infer_b1_p99_ms": round(float(np.percentile(infer_ms, 99)), 3),
        "infer_guided_b1_p50_ms": round(float(np.percentile(guided_ms, 50)), 3),
        "guided_decode_device_vs_cpu_cells": round(guided_cell_error, 3),
    }


def check_selector(name: str, config: SelectorConfig, resolution: int, dev: torch.device, batch: int, repeats: int) -> dict:
    torch.manual_seed(0)
    model = build_selector(config).to(dev)
    g = torch.Generator(device=dev).manual_seed(0)
    mixing = torch.randn(config.z_dim, config.z_dim // 8, device=dev, generator=g)  # a correlated z, as E's is
    z = torch.randn(FIT_TRAJECTORIES + batch, config.z_dim // 8, device=dev, generator=g) @ mixing.T
    views = torch.rand(FIT_TRAJECTORIES + batch, 5, 8, resolution, resolution, device=dev, generator=g)
    model.fit_statistics(views[:FIT_TRAJECTORIES], z[:FIT_TRAJECTORIES])  # the SVD of the eps basis runs here
    fitted = model.standardise(z[:FIT_TRAJECTORIES])
    whitening_error = float((torch.cov(fitted.T) - torch.eye(config.eps_size, device=dev)).abs().max())
    views, eps = views[FIT_TRAJECTORIES:], model.standardise(z[FIT_TRAJECTORIES:])
    noise = model.draw_noise(batch, torch.Generator(device=dev).manual_seed(0), dev)
    with torch.autocast(dev.type, dtype=torch.bfloat16):
        loss_bf16, _, metrics = selector_loss(model, views, eps, ElboWeights(), noise)
    loss_bf16.backward()
    grads_finite = all(torch.isfinite(p.grad).all().item() for p in model.parameters() if p.grad is not None)
    with torch.no_grad():
        loss_fp32 = selector_loss(model, views, eps, ElboWeights(), noise)[0].item()
    optimiser = torch.optim.AdamW(model.parameters(), lr=1e-4)

    def step():
        with torch.autocast(dev.type, dtype=torch.bfloat16):
            loss, _, _ = selector_loss(model, views, eps, ElboWeights())
        optimiser.zero_grad(set_to_none=True)
        loss.backward()
        optimiser.step()

    train_ms = _timed(step, repeats, 3, dev)
    model.eval()
    gen = torch.Generator(device=dev).manual_seed(0)
    sample_ms = _timed(lambda: model.sample(views[:1], None, gen), max(repeats * 3, 10), 5, dev)
    return {
        "model": name, "params_M": round(sum(p.numel() for p in model.parameters()) / 1e6, 3),
        "loss_bf16": round(loss_bf16.item(), 3), "loss_fp32": round(loss_fp32, 3),
        "bf16_fp32_rel_diff": round(abs(loss_bf16.item() - loss_fp32) / abs(loss_fp32), 5),
        "grads_finite": grads_finite, "clusters_used": metrics.get("clusters_used"), "train_batch": batch,
        "eps_size": config.eps_size, "eps_whitening_max_error": round(whitening_error, 5),
        "train_samples_per_s": round(batch * 1e3 / float(np.median(train_ms)), 1),
        "sample_b1_p50_ms": round(float(np.percentile(sample_ms, 50)), 3),
        "sample_b1_p99_ms": round(float(np.percentile(sample_ms, 99)), 3),
    }


def _ddp_rank(rank: int, world: int, port: int, backend: str, out: str, small: bool) -> None:
    """Gradient of the predictor on this rank's half of one batch (world 2) or the full batch (world 1)."""
    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port))
    dist.init_process_group(backend, rank=rank, world_size=world)
    dev = torch.device("cuda", rank) if backend == "nccl" else torch.device("cpu")
    if dev.type == "cuda":
        torch.cuda.set_device(dev)
    config = PredictorConfig(embedding_dim=64, image_size=32 if small else 64, patch=8, width=64, layers_within=1,
                             layers_across=1, heads=4, dropout=0.0)
    torch.manual_seed(0)
    model = torch.nn.parallel.DistributedDataParallel(ActionPredictor(config).to(dev),
                                                      device_ids=[dev.index] if dev.type == "cuda" else None)
    views, eps, proprio, targets = _predictor_batch(config, 8, dev)
    share = torch.arange(8).tensor_split(world)[rank].to(dev)
    loss, _ = action_loss(model(views[share], eps[share], proprio[share]), ActionTargets(*(None if t is None else t[share] for t in targets)))
    loss.backward()
    if rank == 0:
        torch.save({n: p.grad.detach().cpu() for n, p in model.module.named_parameters()}, out)
    dist.destroy_process_group()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def check_ddp(dev: torch.device, tmp: Path, small: bool) -> dict:
    backend = "nccl" if dev.type == "cuda" else "gloo"
    gpus = torch.cuda.device_count() if dev.type == "cuda" else 0
    if dev.type == "cuda" and gpus < 2:  # one GPU: can NCCL form a group and reduce at all?
        os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(_free_port()))
        dist.init_process_group("nccl", rank=0, world_size=1)
        x = torch.ones(4, device=dev)
        dist.all_reduce(x)
        ok = bool(torch.equal(x, torch.ones(4, device=dev)))
        dist.destroy_process_group()
        return {"kind": "1-rank NCCL init + all_reduce", "backend": backend, "gpus": gpus, "ok": ok}
    single, double = tmp / "ddp_single.pt", tmp / "ddp_double.pt"
    mp.spawn(_ddp_rank, args=(1, _free_port(), backend, str(single), small), nprocs=1, join=True)
    mp.spawn(_ddp_rank, args=(2, _free_port(), backend, str(double), small), nprocs=2, join=True)
    a, b = torch.load(single, weights_only=True), torch.load(double, weights_only=True)
    worst = max(float((a[k] - b[k]).abs().max()) for k in a)
    tol = 1e-5 if backend == "gloo" else 1e-4  # GPU kernels may reduce in another order
    return {"kind": "2-rank DDP vs full batch", "backend": backend, "gpus": gpus, "max_abs_grad_diff": worst,
            "tolerance": tol, "ok": worst <= tol}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("--cpu", action="store_true", help="run on the CPU with small sizes (local test of this script)")
    parser.add_argument("--repeats", type=int, default=10, help="timed training steps per model")
    parser.add_argument("--skip-ddp", action="store_true")
    args = parser.parse_args()
    if not args.cpu and not torch.cuda.is_available():
        print(json.dumps({"error": "no CUDA device visible to torch; use --cpu for a local run"}))
        return 2
    dev = torch.device("cpu" if args.cpu else "cuda")
    if args.cpu:
        torch.set_num_threads(1)
    batch, repeats = (4, 2) if args.cpu else (64, args.repeats)
    summary: dict = {
        "torch": torch.__version__, "cuda": torch.version.cuda, "device": torch.cuda.get_device_name(0) if dev.type == "cuda" else "cpu",
        "gpus": torch.cuda.device_count(), "stubbed_modules": STUBBED, "predictor": [], "selector": [],
    }
    start = time.monotonic()
    cpu_default = PredictorConfig(embedding_dim=EPS_DIM)
    rvt = PredictorConfig.rvt_size(EPS_DIM, image_size=128 if args.cpu else 224)
    summary["predictor"].append(check_predictor("predictor cpu-default 128px w128 L2+2", cpu_default, dev, batch, repeats))
    summary["predictor"].append(check_predictor(f"predictor rvt-size {rvt.image_size}px w512 L4+4", rvt, dev,
                                                2 if args.cpu else batch, 1 if args.cpu else repeats))
    cpu_selector = SelectorConfig(eps_dim=EPS_DIM, z_tokens=Z_TOKENS)
    summary["selector"].append(check_selector("selector cgmvae cpu-default", cpu_selector, 128, dev, batch, repeats))
    gpu_selector = SelectorConfig(eps_dim=EPS_DIM, z_tokens=Z_TOKENS, width=512, blocks=4, decoder_heads=8,
                                  obs=ObsEncoderConfig(input_resolution=128, widths=(32, 64, 128, 128), token_dim=128))
    summary["selector"].append(check_selector("selector cgmvae gpu-size", gpu_selector, 128, dev, batch, repeats))
    if not args.skip_ddp:
        tmp = Path(os.environ.get("OUT", "/tmp"))
        tmp.mkdir(parents=True, exist_ok=True)
        summary["ddp"] = check_ddp(dev, tmp, args.cpu)
    summary["seconds"] = round(time.monotonic() - start, 1)
    finite = all(r["grads_finite"] for r in summary["predictor"] + summary["selector"])
    guided = all(r["guided_decode_device_vs_cpu_cells"] <= 1.0 for r in summary["predictor"])
    agree = all(r["bf16_fp32_rel_diff"] < 0.05 for r in summary["predictor"] + summary["selector"])
    whitened = all(r["eps_whitening_max_error"] < 1e-3 for r in summary["selector"])
    summary["ok"] = finite and agree and whitened and guided and summary.get("ddp", {"ok": True})["ok"]
    print(json.dumps(summary, indent=2))
    return 0 if summary["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
