"""ActionPredictor: shapes, decoding, loss, gradients, and that eps steers a trained-a-little model."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from actaim2.models.predictor import (
    PROPRIO_DIM,
    ActionPredictor,
    PredictorConfig,
    PredictorOutput,
    decode_action,
    proprio_features,
)
from actaim2.models.rotation_bins import grasp_geodesic_deg
from actaim2.models.view_geometry import CubePlacement
from actaim2.perception.ortho_views import CHANNELS, VIEWS
from actaim2.train.action_loss import action_loss, action_targets

PLACEMENT = CubePlacement((0.5, 0.0, 0.4), 0.6)
EMBEDDING = 16


def tiny_config(**overrides) -> PredictorConfig:
    """A CPU-cheap shape of the same network: 64 px views, 8 px patches, width 64."""
    fields = dict(embedding_dim=EMBEDDING, image_size=64, patch=8, width=64, layers_within=1, layers_across=1, heads=2, dropout=0.0)
    return PredictorConfig(**{**fields, **overrides})


def random_views(batch: int, size: int, seed: int) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    views = torch.rand(batch, len(VIEWS), len(CHANNELS), size, size, generator=g)
    views[:, :, CHANNELS.index("occupancy")] = (views[:, :, CHANNELS.index("occupancy")] > 0.3).float()
    return views


def keyposes(positions: list[list[float]], seed: int) -> torch.Tensor:
    """(B, 8) keyposes at world positions with random orientations, gripper alternating."""
    from scipy.spatial.transform import Rotation

    quats = Rotation.random(len(positions), random_state=seed).as_quat()
    gripper = [[float(i % 2)] for i in range(len(positions))]
    return torch.tensor(np.concatenate([positions, quats, gripper], axis=1), dtype=torch.float32)


def test_default_config_shapes_and_decoded_keypose():
    torch.manual_seed(0)
    config = PredictorConfig(embedding_dim=EMBEDDING)
    model = ActionPredictor(config).eval()
    assert (config.image_size, config.patch, config.width, config.layers_within + config.layers_across, config.heads) == (128, 16, 128, 4, 4)
    assert config.in_channels == len(CHANNELS) and config.proprio_dim == PROPRIO_DIM == 5
    out = model(random_views(2, 128, 0), torch.randn(2, EMBEDDING), proprio_features(torch.tensor([0, 1]), torch.tensor([0, 3])))
    assert isinstance(out, PredictorOutput)
    assert out.heatmaps.shape == (2, len(VIEWS), 128, 128)
    assert out.rotation.shape == (2, 3, 72) and out.gripper.shape == (2, 2)
    decoded = decode_action(out, PLACEMENT)
    assert decoded.position.shape == (2, 3) and decoded.quat_xyzw.shape == (2, 4) and decoded.gripper_closed.dtype == torch.bool
    assert PLACEMENT.contains(decoded.position).all()
    torch.testing.assert_close(decoded.quat_xyzw.norm(dim=1), torch.ones(2))


def test_config_checks_and_gpu_size():
    with pytest.raises(ValueError, match="patch"):
        PredictorConfig(embedding_dim=4, image_size=100, patch=16)
    with pytest.raises(ValueError, match="heads"):
        PredictorConfig(embedding_dim=4, width=100, heads=3)
    rvt = PredictorConfig.rvt_size(embedding_dim=EMBEDDING)
    assert (rvt.width, rvt.layers_within + rvt.layers_across, rvt.heads, rvt.image_size) == (512, 8, 8, 224)
    assert PredictorConfig.from_json(rvt.to_json()) == rvt
    with pytest.raises(ValueError, match="views of shape"):
        ActionPredictor(tiny_config())(random_views(1, 32, 0), torch.zeros(1, EMBEDDING), torch.zeros(1, PROPRIO_DIM))


def test_proprio_features_are_gripper_then_phase_one_hot():
    feats = proprio_features(torch.tensor([True, False]), torch.tensor([2, 0]))
    torch.testing.assert_close(feats, torch.tensor([[1.0, 0, 0, 1, 0], [0.0, 1, 0, 0, 0]]))


def test_targets_decode_back_to_the_keypose():
    """Outputs equal to the targets decode to the keypose: position within one cell, rotation
    within the bins' bound up to the hand's half-turn symmetry (the targets' class of a grasp),
    gripper exact (targets and decoding share one geometry)."""
    kp = keyposes([[0.7, -0.2, 0.3], [0.2, 0.4, 0.9], [1.05, 0.55, -0.15]], seed=1)
    targets = action_targets(kp, PLACEMENT, 128)
    rotation = torch.nn.functional.one_hot(targets.rotation_bins, 72).float() * 10
    gripper = torch.nn.functional.one_hot(targets.gripper, 2).float() * 10
    decoded = decode_action(PredictorOutput(targets.heatmaps.clamp_min(1e-30).log(), rotation, gripper), PLACEMENT)
    assert (decoded.position - kp[:, :3]).abs().max() <= 2 * PLACEMENT.half_extent / 128
    assert grasp_geodesic_deg(decoded.quat_xyzw.numpy(), kp[:, 3:7].numpy()).max() <= 4.4
    assert decoded.gripper_closed.tolist() == [False, True, False]


def test_targets_refuse_positions_outside_the_cube():
    with pytest.raises(ValueError, match="outside the cube"):
        action_targets(keyposes([[0.5, 0.0, 0.4], [0.5, 0.0, 1.5]], seed=0), PLACEMENT, 64)


def test_gradient_reaches_every_parameter():
    torch.manual_seed(0)
    model = ActionPredictor(tiny_config())
    kp = keyposes([[0.6, 0.1, 0.3], [0.3, -0.2, 0.6]], seed=2)
    out = model(random_views(2, 64, 1), torch.randn(2, EMBEDDING), proprio_features(torch.tensor([0, 1]), torch.tensor([1, 2])))
    loss, parts = action_loss(out, action_targets(kp, PLACEMENT, 64))
    assert set(parts) == {"translation", "rotation", "gripper"}
    torch.testing.assert_close(loss.detach(), sum(parts.values()))
    loss.backward()
    dead = [name for name, p in model.named_parameters() if p.grad is None or not bool(p.grad.abs().gt(0).any())]
    assert not dead


def _train(model: ActionPredictor, views, eps, proprio, targets, steps: int, lr: float = 3e-3) -> list[dict[str, float]]:
    optimiser = torch.optim.AdamW(model.parameters(), lr=lr)
    history = []
    for _ in range(steps):
        loss, parts = action_loss(model(views, eps, proprio), targets)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        history.append({k: float(v) for k, v in parts.items()})
    return history


def test_loss_decreases_when_overfitting_a_tiny_batch():
    torch.manual_seed(0)
    model = ActionPredictor(tiny_config())
    kp = keyposes([[0.6, 0.1, 0.3], [0.3, -0.2, 0.6], [0.9, 0.3, 0.2], [0.1, -0.4, 0.8]], seed=3)
    targets = action_targets(kp, PLACEMENT, 64)
    proprio = proprio_features(torch.tensor([0, 1, 0, 1]), torch.tensor([0, 1, 2, 3]))
    history = _train(model, random_views(4, 64, 2), torch.randn(4, EMBEDDING), proprio, targets, steps=80)
    first, last = history[0], history[-1]
    floor = float(-(targets.heatmaps * targets.heatmaps.clamp_min(1e-30).log()).sum(dim=(-2, -1)).mean())  # target entropy
    assert last["translation"] - floor < 0.5 * (first["translation"] - floor), (first, last, floor)
    assert last["rotation"] < 0.2 * first["rotation"], (first, last)
    assert last["gripper"] < 0.1, (first, last)


def test_eps_alone_moves_the_heatmap_argmax_after_a_little_training():
    """Two samples with the same views and proprioception, different eps and different targets:
    120 steps must make eps move the predicted position to each sample's target."""
    torch.manual_seed(0)
    model = ActionPredictor(tiny_config())
    views = random_views(1, 64, 3).expand(2, -1, -1, -1, -1)
    proprio = proprio_features(torch.tensor([0, 0]), torch.tensor([1, 1]))
    eps = torch.randn(2, EMBEDDING)
    kp = keyposes([[0.3, -0.3, 0.2], [0.8, 0.35, 0.7]], seed=4)
    _train(model, views, eps, proprio, action_targets(kp, PLACEMENT, 64), steps=120)
    model.eval()
    with torch.no_grad():
        out = model(views, eps, proprio)
    argmax = out.heatmaps.flatten(2).argmax(dim=-1)  # (2, V)
    assert (argmax[0] != argmax[1]).all()
    decoded = decode_action(out, PLACEMENT)
    cell = 2 * PLACEMENT.half_extent / 64
    assert (decoded.position - kp[:, :3]).abs().max() <= 2 * cell
