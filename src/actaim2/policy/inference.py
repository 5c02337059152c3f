"""The learned policy behind /sample_mode and /predict_keypose: one checkpoint, checked, warmed up.

:meth:`PolicyModel.load` builds the mode selector and the action predictor a checkpoint
describes (safetensors + JSON, nothing unpickled) and refuses it, naming the differing fields,
when it was trained under another perception configuration than the one serving it
(``actaim2.perception.config``): views made one way are not what a model trained on the other
expects.

Each model is served the views it was trained on. A checkpoint records one perception
configuration; its optional ``robot_filter`` entry ({"selector": bool, "predictor": bool}) says
when one of the two models was trained with the other robot-filter setting, and
:meth:`PolicyModel.views_config` then gives that model's configuration (and digest), which
``fusion_node`` publishes on its second views topic.

Outputs:
  * :meth:`PolicyModel.sample_mode` - a cluster (given, or drawn from the learned prior), the
    interaction mode eps (standardised task embedding, what the predictor reads) and the
    cluster probabilities. The same seed and views give the same eps.
  * :meth:`PolicyModel.predict_keypose` - the keypose (pose of ``tcp`` in ``world``, quaternion
    x, y, z, w) and a confidence in 0..1: the mean over views of each heatmap's largest
    probability (a single-view predictor's: times its largest depth-cell probability) times the
    product over the three Euler axes of the largest bin probability.

The predictor is always fed all five views with every rendered channel; an input-ablation
checkpoint (``predictor_config`` ``inputs`` / ``view`` in its JSON) reads its subset itself.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from actaim2.artifact import checkpoint
from actaim2.artifact.device import choose_device
from actaim2.artifact.serving import DEFAULT_SERVING, check_noise_scale
from actaim2.keypose import Keypose
from actaim2.models.mode_guidance import guide, with_reference
from actaim2.models.predictor import decode_action, proprio_features
from actaim2.models.rotation_bins import bins_to_quat, ranked_bins
from actaim2.models.view_geometry import CubePlacement
from actaim2.perception.config import PerceptionConfig
from actaim2.policy.requests import RequestError, check_cluster, check_embedding, check_phase
from actaim2.policy.views import Views
from actaim2.profiling import timed

ROLES = ("selector", "predictor")
# Fallback rotations are this far apart (up to the hand's half turn): closer ones meet the same obstacles.
ALTERNATIVE_SEPARATION_DEG = 30.0


class PolicyLoadError(RuntimeError):
    """The checkpoint cannot serve: missing, corrupt, other weights, or another perception configuration."""


@dataclass(frozen=True)
class ModeSample:
    cluster: int  # -1 for a selector without discrete modes
    eps: np.ndarray  # (embedding_dim,) float32
    probabilities: np.ndarray  # (clusters,) float32, the distribution the cluster was drawn from


@dataclass(frozen=True)
class KeyposePrediction:
    keypose: Keypose
    confidence: float
    # The same point and gripper with the next likeliest rotations (``rotation_bins.ranked_bins``),
    # for a planner to fall back on when it refuses ``keypose`` (``KeyposeRunner.run_first``).
    alternatives: tuple[Keypose, ...] = ()


class PolicyModel:
    """A loaded checkpoint ready to answer requests (call :meth:`warm_up` before the first one)."""

    def __init__(self, policy: checkpoint.Policy, stem: Path, serving: PerceptionConfig, device: torch.device):
        self.selector, self.predictor, self.meta = policy.selector, policy.predictor, policy.meta
        self.stem, self.serving, self.device = stem, serving, device
        self.placement = CubePlacement.of(serving)
        filters = self.meta.get("robot_filter") or {}
        self._configs = {role: serving.replace(remove_robot_views=bool(filters.get(role, serving.remove_robot_views)))
                         for role in ROLES}

    @classmethod
    def load(cls, stem: str | Path, serving: PerceptionConfig, device: str = "auto") -> "PolicyModel":
        """Load and check; PolicyLoadError with the reason (never a bare crash)."""
        try:
            target = choose_device(device)
            policy = checkpoint.load_policy(stem, checkpoint.perception_record(serving), target)
        except (checkpoint.CheckpointError, RuntimeError, ValueError, OSError) as exc:
            raise PolicyLoadError(str(exc)) from exc
        model = cls(policy, checkpoint.paths(stem)[1].with_suffix(""), serving, target)
        if model.predictor is not None and model.selector is not None \
                and model.predictor.config.embedding_dim != model.selector.config.eps_size:
            raise PolicyLoadError(f"{stem}: the selector's eps has {model.selector.config.eps_size} values, "
                                  f"the predictor reads {model.predictor.config.embedding_dim}")
        return model

    # -- what it serves ---------------------------------------------------------------------
    @property
    def embedding_dim(self) -> int:
        return self.predictor.config.embedding_dim if self.predictor is not None else self.selector.config.eps_size

    @property
    def clusters(self) -> int:
        """Discrete modes of the selector (0 for the continuous CVAE baseline)."""
        return 0 if self.selector is None or self.selector.config.kind == "cvae" else self.selector.config.clusters

    @property
    def mode_labels(self) -> dict[str, int]:
        """Operator mode label -> cluster, as fine-tuning on labelled demonstrations mapped them (empty otherwise)."""
        finetune = (self.meta.get("lineage") or {}).get("finetune") or {}
        return {label: int(c) for label, c in ((finetune.get("mode_labels") or {}).get("label_cluster") or {}).items()}

    def views_config(self, role: str) -> PerceptionConfig:
        """The perception configuration whose views ``role`` ("selector" or "predictor") was trained on."""
        return self._configs[role]

    def describe(self) -> str:
        """One line for logs and the demo: which checkpoint, which weights, which views."""
        parts = [name for name, m in (("selector", self.selector), ("predictor", self.predictor)) if m is not None]
        return (f"checkpoint {self.stem} (weights sha256 {str(self.meta.get('weights_sha256'))[:16]}, "
                f"{' + '.join(parts)}, {self.clusters} clusters, eps {self.embedding_dim}) on {self.device}, "
                f"views {self._configs['selector'].digest()} ({self.serving.rig}, {self.serving.resolution} px)")

    def warm_up(self) -> float:
        """One pass of each model on blank views (allocations, kernel selection); seconds taken."""
        started = time.perf_counter()
        for role in ROLES:
            config = self._configs[role]
            blank = Views(0, np.zeros((5, len(config.channels), config.resolution, config.resolution), np.float32))
            if role == "selector" and self.selector is not None:
                sample = self.sample_mode(blank, -1, 0)
            elif role == "predictor" and self.predictor is not None:
                eps = sample.eps if self.selector is not None else np.zeros(self.embedding_dim, np.float32)
                self.predict_keypose(blank, eps, 0, False)
        return time.perf_counter() - started

    # -- the two services ---------------------------------------------------------------------
    def _batch(self, views: Views) -> torch.Tensor:
        return torch.from_numpy(np.ascontiguousarray(views.data))[None].to(self.device)

    @timed("model forward")
    @torch.inference_mode()
    def sample_mode(self, views: Views, cluster: int, seed: int, noise_scale: float = DEFAULT_SERVING.noise_scale) -> ModeSample:
        """``noise_scale``: the spread of the latent draw (``ModeSelector.sample``; 0 = the cluster's noise-free eps)."""
        check_noise_scale(noise_scale)
        if self.selector is None:
            raise RequestError(f"{self.stem} holds no mode selector (an action predictor alone): /sample_mode is unavailable")
        chosen = check_cluster(cluster, self.clusters)
        generator = torch.Generator(device=self.device).manual_seed(int(seed))
        result = self.selector.sample(self._batch(views), chosen, generator, noise_scale)
        return ModeSample(int(result.cluster[0]), result.eps[0].float().cpu().numpy(),
                          result.cluster_probabilities[0].float().cpu().numpy())

    @timed("model forward")
    @torch.inference_mode()
    def predict_keypose(self, views: Views, eps: np.ndarray | list[float], phase: int, gripper_closed: bool,
                        alternatives: int = 0, separation_deg: float = ALTERNATIVE_SEPARATION_DEG,
                        guidance: float = 0.0) -> KeyposePrediction:
        """The keypose, its confidence and up to ``alternatives`` fallbacks whose rotations lie
        ``separation_deg`` from it and from each other. ``guidance``: the mode guidance weight of the
        translation (:mod:`actaim2.models.mode_guidance`; 0 = the plain predictor)."""
        if self.predictor is None:
            raise RequestError(f"{self.stem} holds no action predictor: /predict_keypose is unavailable")
        eps = check_embedding(eps, self.embedding_dim)
        phase = check_phase(phase)
        proprio = proprio_features(torch.tensor([bool(gripper_closed)], device=self.device),
                                   torch.tensor([phase], device=self.device))
        eps_rows = torch.from_numpy(eps)[None].to(self.device)
        if guidance:  # a negative weight reaches guide(), which refuses it
            out = guide(self.predictor(self._batch(views).expand(2, -1, -1, -1, -1), with_reference(eps_rows),
                                       proprio.expand(2, -1)), guidance)
        else:
            out = self.predictor(self._batch(views), eps_rows, proprio)
        action = decode_action(out, self.placement, self.predictor.config.view_index,
                               self.predictor.config.decode_sigma_px)
        heat = torch.softmax(out.heatmaps[0].flatten(1).float(), dim=-1).amax(dim=-1).mean()
        if out.depth is not None:
            heat = heat * torch.softmax(out.depth[0].float(), dim=-1).amax()
        rotation = torch.softmax(out.rotation[0].float(), dim=-1).amax(dim=-1).prod()
        position, closed = action.position[0].double().cpu().numpy(), bool(action.gripper_closed[0])
        keypose = Keypose(phase, position, action.quat_xyzw[0].double().cpu().numpy(), closed)
        others = ()
        if alternatives > 0:
            triples = ranked_bins(out.rotation[0].float().cpu().numpy(), alternatives + 1, separation_deg)[1:]
            others = tuple(Keypose(phase, position, q.astype(np.float64), closed)
                           for q in bins_to_quat(triples, out.rotation.shape[-1]))
        return KeyposePrediction(keypose, float(heat * rotation), others)
