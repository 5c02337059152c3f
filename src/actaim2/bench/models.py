"""The action predictor's half of `actaim2 bench models`: size, latency, training step, augmentation.

:func:`bench_predictor` returns one dict per measurement (keys: ``model``, ``measure``,
``batch``, ``params``, ``p50_ms``, ``p99_ms``, ``cpu_p50_ms``, ``samples_per_s``, ``n``,
``target``, ``met``, ``load``); :func:`markdown_table` prints any such rows, the selector's too.

Measurements (targets on 2 cores):
  * forward + decode, batch 1: eval mode, views -> heatmaps, rotation and gripper logits -> the
    keypose, the coarse-to-fine 3-D decode included (p50 <= 20 ms); the same with mode guidance
    (:mod:`actaim2.models.mode_guidance`: a second row fed the mean mode, in the same batch);
  * training step, batch 8: targets (heatmaps, rotation bins) + forward + L_action + backward +
    AdamW step (p50 <= 300 ms); data loading and augmentation are not included;
  * augmentation, per sample: views read back into a cloud, moved and re-rendered
    (:mod:`actaim2.models.augment`), on views of a synthetic floor-and-box scene whose floor
    fills the top view (the row names the number of occupied pixels, i.e. points).

Inputs are random tensors of the right shapes: speed does not depend on their values. Other
jobs on the machine stretch wall times; ``cpu_p50_ms`` is this process's CPU time per call,
and the 1-minute load average is recorded per row.
"""
from __future__ import annotations

import os
import time

import numpy as np
import torch

TARGET_FORWARD_P50_MS = 20.0
TARGET_TRAIN_STEP_P50_MS = 300.0
FORWARD_BATCH = 1
TRAIN_BATCH = 8


def time_calls(fn, repeats: int, warmup: int, device: torch.device) -> tuple[np.ndarray, np.ndarray]:
    """Wall and process-CPU milliseconds of ``fn()`` over ``repeats`` calls after ``warmup``."""
    wall, cpu = [], []
    for i in range(warmup + repeats):
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        start, start_cpu = time.perf_counter(), time.process_time()
        fn()
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        if i >= warmup:
            wall.append((time.perf_counter() - start) * 1e3)
            cpu.append((time.process_time() - start_cpu) * 1e3)
    return np.array(wall), np.array(cpu)


def result_row(model: str, measure: str, batch: int, params: int, wall: np.ndarray, cpu: np.ndarray, target: float | None) -> dict:
    p50, p99 = np.percentile(wall, [50, 99])
    return {
        "model": model,
        "measure": measure,
        "batch": batch,
        "params": params,
        "p50_ms": float(p50),
        "p99_ms": float(p99),
        "cpu_p50_ms": float(np.percentile(cpu, 50)),
        "samples_per_s": float(batch * 1e3 / p50),
        "n": len(wall),
        "target": f"p50 <= {target:g} ms" if target is not None else "",
        "met": bool(p50 <= target) if target is not None else None,
        "load": os.getloadavg()[0],
    }


def _synthetic_views(resolution: int, placement) -> np.ndarray:
    """Views of a floor filling the cube's footprint and a 30 x 40 x 30 cm box, 3 mm samples."""
    from actaim2.perception.ortho_views import render_views

    cx, cy, _ = placement.center
    h = placement.half_extent
    s = np.arange(-h, h, 0.003)
    floor = np.stack(np.meshgrid(s + cx, s + cy, [0.0], indexing="ij"), -1).reshape(-1, 3)
    t = np.arange(0.0, 1.0, 0.01)
    u, v = np.meshgrid(t, t, indexing="ij")
    faces = [
        np.stack([cx - 0.15 + 0.3 * u, cy - 0.2 + 0.4 * v, np.full_like(u, 0.3)], -1),
        np.stack([np.full_like(u, cx - 0.15), cy - 0.2 + 0.4 * u, 0.3 * v], -1),
        np.stack([cx - 0.15 + 0.3 * u, np.full_like(u, cy - 0.2), 0.3 * v], -1),
    ]
    xyz = np.concatenate([floor] + [f.reshape(-1, 3) for f in faces]).astype(np.float32)
    rgb = np.random.default_rng(0).integers(0, 256, (len(xyz), 3), dtype=np.uint8)
    return render_views(xyz, rgb, placement.center, placement.half_extent, resolution)


def bench_predictor(
    config=None,
    device: str = "cpu",
    threads: int = 2,
    repeats: int = 50,
    train_repeats: int = 10,
    augment_repeats: int = 20,
    train_batch: int = TRAIN_BATCH,
    bf16: bool = False,
    seed: int = 0,
) -> list[dict]:
    """Rows for the action predictor (``config``: a PredictorConfig; None = the CPU default).

    ``threads`` sets torch's CPU threads; ``bf16`` runs forward and loss under bfloat16 autocast
    (GPU); ``train_batch`` other than 8 measures throughput (the target is for 8). Augmentation
    runs on the CPU (it is part of the data path); ``augment_repeats=0`` skips it.
    """
    from actaim2.data.encoder import AE_LATENT, AUTOENCODER_SPEC
    from actaim2.models.augment import augment
    from actaim2.models.mode_guidance import guide, with_reference
    from actaim2.models.predictor import (
        ActionPredictor,
        PredictorConfig,
        decode_action,
        proprio_features,
    )
    from actaim2.models.view_geometry import CubePlacement
    from actaim2.perception.fusion import FusionConfig
    from actaim2.train.action_loss import action_loss, action_targets

    torch.set_num_threads(threads)
    torch.manual_seed(seed)
    dev = torch.device(device)
    if config is None:  # eps as large as z of the default encoder E on the five-camera ring5 rig
        config = PredictorConfig(embedding_dim=5 * AE_LATENT * AUTOENCODER_SPEC.pool[0] * AUTOENCODER_SPEC.pool[1])
    placement = CubePlacement.of(FusionConfig())
    model = ActionPredictor(config).to(dev)
    params = model.parameter_count()
    name = f"predictor {config.image_size}px w{config.width} L{config.layers_within}+{config.layers_across}"
    size = config.image_size
    autocast = torch.autocast(dev.type, dtype=torch.bfloat16, enabled=bf16)

    def inputs(batch: int):
        views = torch.rand(batch, config.views, config.in_channels, size, size, device=dev)
        eps = torch.randn(batch, config.embedding_dim, device=dev)
        proprio = proprio_features(torch.zeros(batch, device=dev), torch.ones(batch, dtype=torch.long, device=dev))
        return views, eps, proprio

    rows = []
    model.eval()
    views, eps, proprio = inputs(FORWARD_BATCH)

    def forward_decode():
        with torch.inference_mode(), autocast:
            decode_action(model(views, eps, proprio), placement, config.view_index, config.decode_sigma_px)

    wall, cpu = time_calls(forward_decode, repeats, warmup=5, device=dev)
    target = TARGET_FORWARD_P50_MS if dev.type == "cpu" else None  # the targets are for 2 CPU cores
    rows.append(result_row(name, "forward + 3-D decode", FORWARD_BATCH, params, wall, cpu, target))

    def guided_decode():  # mode guidance: the eps row and the mean-mode row in one batch of 2
        with torch.inference_mode(), autocast:
            out = model(views.expand(2, -1, -1, -1, -1), with_reference(eps), proprio.expand(2, -1))
            decode_action(guide(out, 2.0), placement, config.view_index, config.decode_sigma_px)

    wall, cpu = time_calls(guided_decode, repeats, warmup=5, device=dev)
    rows.append(result_row(name, "forward + mode guidance + 3-D decode", FORWARD_BATCH, params, wall, cpu, target))

    model.train()
    optimiser = torch.optim.AdamW(model.parameters(), lr=1e-4)
    views, eps, proprio = inputs(train_batch)
    rng = np.random.default_rng(seed)
    quat = torch.from_numpy(rng.normal(size=(train_batch, 4))).float()
    position = placement.to_world(torch.from_numpy(rng.uniform(-0.9, 0.9, (train_batch, 3))).float())
    keyposes = torch.cat([position, quat / quat.norm(dim=1, keepdim=True), torch.ones(train_batch, 1)], dim=1)

    def train_step():
        targets = action_targets(keyposes, placement, size, view=config.view_index)
        targets = type(targets)(*(None if t is None else t.to(dev) for t in targets))
        with autocast:
            loss, _ = action_loss(model(views, eps, proprio), targets)
        optimiser.zero_grad(set_to_none=True)
        loss.backward()
        optimiser.step()

    wall, cpu = time_calls(train_step, train_repeats, warmup=2, device=dev)
    target = TARGET_TRAIN_STEP_P50_MS if train_batch == TRAIN_BATCH and dev.type == "cpu" else None
    rows.append(result_row(name, "training step", train_batch, params, wall, cpu, target))
    if augment_repeats <= 0:
        return rows

    scene = _synthetic_views(size, placement)
    keypose = keyposes[0].double().numpy()
    wall, cpu = time_calls(lambda: augment(scene, keypose, placement, rng), augment_repeats, warmup=2, device=torch.device("cpu"))
    rows.append(result_row(f"augmentation {size}px, {int((scene[:, -1] > 0).sum())} points", "per sample (CPU)", 1, 0, wall, cpu, None))
    return rows


def markdown_table(rows: list[dict]) -> str:
    """The rows of :func:`bench_predictor` (or rows with the same keys) as a markdown table."""
    lines = [
        "| model | measure | batch | params | p50 ms | p99 ms | CPU p50 ms | samples/s | n | load | target |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        verdict = f"{r['target']}: {'met' if r['met'] else 'MISSED'}" if r["target"] else ""
        params = f"{r['params'] / 1e6:.2f} M" if r["params"] else ""
        lines.append(
            f"| {r['model']} | {r['measure']} | {r['batch']} | {params} | {r['p50_ms']:.1f} | {r['p99_ms']:.1f} | "
            f"{r['cpu_p50_ms']:.1f} | {r['samples_per_s']:.0f} | {r['n']} | {r['load']:.2f} | {verdict} |"
        )
    return "\n".join(lines)
