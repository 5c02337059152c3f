"""The training procedure of the paper: pretrain the selector, pretrain the predictor, train jointly.

Phases (``TrainConfig.phases``, in order):
  selector   the mode selector alone on (O_init, z): its loss (train/elbo.py).
  predictor  the action predictor alone on keyframes (O_i, a_i) fed the trajectory's *true*
             standardised z as eps. The result is the Goal-RVT baseline. With
             ``predictor_eps: served`` it is fed the selector's draws instead, with
             ``neighbour`` a same-object neighbour's true eps, with ``nearest_centre`` the
             noise-free cluster eps of its own O_init nearest its true eps (train/served_eps.py).
  joint      both: L_action(predictor(O_i, sg[eps_hat])) + w L_ELBO, eps_hat the selector's
             reconstruction of the trajectory's z; the stop-gradient keeps the action loss
             out of the selector (paper, "Training Procedure").
Baseline selectors (cvae, vqvae) run "selector" then "joint" from a Goal-RVT predictor
(``init_from``), so they reuse its pretraining as the issue asks.

Optimiser: AdamW, linear warm-up then cosine decay per phase, gradient clipping. Every
``checkpoint_minutes`` and at the end of each phase a resumable checkpoint ``<out>/train_state``
is written (weights, optimiser moments, RNG state, phase and step); :meth:`Trainer.resume`
continues from it exactly (tests/train/test_checkpoint.py). The final models go to
``<out>/policy`` (weights only), the predictor after its pretraining to ``<out>/goal_rvt``.
Rank 0 shows progress bars, writes TensorBoard scalars (``<out>/tensorboard``) and
``<out>/history.jsonl`` (per-epoch training and validation losses, for curves).
"""
from __future__ import annotations

import json
import math
import time
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from actaim2.artifact import checkpoint
from actaim2.data.storage import object_of, sampler_of
from actaim2.models.augment import augment
from actaim2.models.gumbel import gumbel_temperature
from actaim2.models.predictor import (
    CONDITIONING_LAYERS,
    ActionPredictor,
    PredictorConfig,
    proprio_features,
)
from actaim2.models.registry import build_selector
from actaim2.models.selector_base import ModeSelector
from actaim2.models.view_geometry import CubePlacement
from actaim2.perception.ortho_views import CHANNELS
from actaim2.progress import progress
from actaim2.train.action_loss import action_loss, action_targets, heatmap_log_likelihood
from actaim2.train.balance import cluster_balanced_weights
from actaim2.train.config import TrainConfig
from actaim2.train.data import TrainingData
from actaim2.train.distributed import DistContext, rank_slice, wrap
from actaim2.train.elbo import selector_loss
from actaim2.train.mode_contrast import contrast_partners, draw_partners, mode_contrast_loss
from actaim2.train.served_eps import (
    nearest_centre_pools,
    neighbour_eps_pools,
    pick_from_pools,
    served_eps_pools,
)

STATE = "train_state"
POLICY = "policy"
GOAL_RVT = "goal_rvt"  # the predictor right after its pretraining on true z (plus the z statistics it reads)


def learning_rate(step: int, total: int, base: float, warmup_fraction: float, final_fraction: float) -> float:
    """Linear warm-up over ``warmup_fraction`` of the steps, then cosine decay to ``final_fraction * base``."""
    warmup = max(1, int(round(warmup_fraction * total)))
    if step < warmup:
        return base * (step + 1) / warmup
    progress = min(1.0, (step - warmup) / max(1, total - warmup))
    return base * (final_fraction + (1.0 - final_fraction) * 0.5 * (1.0 + math.cos(math.pi * progress)))


@dataclass
class PhaseResult:
    steps: int
    seconds: float
    last_metrics: dict = field(default_factory=dict)


class Trainer:
    """Owns the models, the data and the bookkeeping of one training run (one process of it under DDP)."""

    def __init__(self, config: TrainConfig, train: TrainingData, val: TrainingData | None, placement: CubePlacement,
                 perception: dict, dataset_digest: str, out: str | Path, ctx: DistContext,
                 init_from: str | Path | None = None, show_progress: bool = True):
        self.config, self.train, self.val, self.placement = config, train, val, placement
        self.perception, self.dataset_digest, self.ctx = perception, dataset_digest, ctx
        self.out, self.show = Path(out), show_progress and ctx.is_main
        self.out.mkdir(parents=True, exist_ok=True)
        self.device = ctx.device
        resolution = int(train.init_views.shape[-1])
        z_dim = int(train.z.shape[1])
        n_views, channels = int(train.init_views.shape[1]), int(train.init_views.shape[2])
        selector = config.selector.to_dict()
        selector.update(z_dim=z_dim, obs={**selector["obs"], "views": n_views, "in_channels": channels})
        self.selector_config = type(config.selector).from_dict(selector)
        channel_names = perception["fields"].get("channels", CHANNELS)  # a record without them: the renderer's full set
        self.predictor_config = PredictorConfig.from_json({**config.predictor, "embedding_dim": self.selector_config.eps_size,
                                                           "image_size": resolution,
                                                           "views": n_views, "in_channels": channels,
                                                           "channel_names": channel_names})
        torch.manual_seed(config.seed)
        self.selector: ModeSelector = build_selector(self.selector_config).to(self.device)
        self.predictor = ActionPredictor(self.predictor_config).to(self.device)
        self.lineage: dict = {"init_from": None, "phases_done": []}
        self.encoder_file: Path | None = None  # E of the task embeddings, shipped beside every model saved (callers set it)
        self.phase_index, self.step, self.optimizer_state = 0, 0, None
        self.temperature = gumbel_temperature(0.0)  # the CGMVAE's Gumbel-softmax temperature, annealed per epoch
        self.partners = self._contrast_partners() if config.mode_contrast > 0.0 else None
        self.eps_pools: list[np.ndarray] | None = None  # per trajectory, in a "served" or "neighbour" predictor phase
        self.same_object = self._same_object() if config.selector_condition == "object" else None
        if init_from is not None:
            self._init_from(init_from)
        else:
            rows = np.arange(min(len(train), 512))
            views, z = train.selector_batch(rows, self.device)
            self.selector.fit_statistics(views, z)
        self.writer = self._tensorboard() if ctx.is_main else None

    # ----------------------------------------------------------------- setup
    def _init_from(self, stem: str | Path) -> None:
        """Start from another run's policy (e.g. the Goal-RVT predictor and its z statistics).

        A predictor that reads other inputs than the one there (an input ablation: other
        ``inputs`` or ``view``), or one the config asks fresh (``predictor_from_parent: false``), is
        not taken from it: it is trained afresh, beside the selector.
        A FiLM or query predictor continued from an ``add`` one takes all its weights; the layers the
        parent lacks start where they change nothing (``PredictorConfig.conditioning``).
        """
        policy = checkpoint.load_policy(stem, self.perception, self.device)
        same_inputs = policy.predictor is not None and (policy.predictor.config.inputs, policy.predictor.config.view) \
            == (self.predictor_config.inputs, self.predictor_config.view)
        load_predictor = same_inputs and self.config.predictor_from_parent
        if load_predictor:
            state = policy.predictor.state_dict()
            if policy.predictor.config.conditioning == "add":
                # FiLM or query layers added to an "add" predictor start as initialised here, which
                # keeps the parent's outputs; every other key must come from the parent
                state = {**{k: v for k, v in self.predictor.state_dict().items() if k.startswith(CONDITIONING_LAYERS)},
                         **state}
            checkpoint.load_state(self.predictor, state, "predictor")
        if policy.selector is not None and type(policy.selector) is type(self.selector):
            checkpoint.load_state(self.selector, policy.selector.state_dict(), "selector")
        elif policy.selector is not None:  # another selector kind: keep its input statistics only
            self.selector.z_mean.copy_(policy.selector.z_mean)
            self.selector.z_std.copy_(policy.selector.z_std)
            if self.selector.eps_basis is not None:
                self.selector.eps_basis.copy_(policy.selector.eps_basis)
            self.selector.obs_encoder.channel_mean.copy_(policy.selector.obs_encoder.channel_mean)
            self.selector.obs_encoder.channel_std.copy_(policy.selector.obs_encoder.channel_std)
        parent = policy.meta.get("lineage", {})
        self.lineage["init_from"] = {"path": str(stem), "weights_sha256": policy.meta.get("weights_sha256"),
                                     "phases_done": parent.get("phases_done"), "predictor_loaded": load_predictor,
                                     "init_from": parent.get("init_from")}  # the chain back to the first run

    def _same_object(self) -> list[np.ndarray]:
        """Per training trajectory, the rows of its object's trajectories (itself included): the O_init a
        selector-phase batch may condition it on (``TrainConfig.selector_condition``)."""
        objects = np.array([object_of(i) for i in self.train.ids])
        return [np.flatnonzero(objects == o) for o in objects]

    def _contrast_partners(self) -> list[np.ndarray]:
        """Per training trajectory, the same object's trajectories of another outcome (train/mode_contrast.py)."""
        if self.train.outcomes is None:
            raise ValueError("mode_contrast needs each trajectory's outcome: a simulated collection opened with "
                             "train.data.open_cache (demonstrations from bags measured no DoF)")
        partners = contrast_partners([object_of(i) for i in self.train.ids], self.train.outcomes)
        if not any(len(p) for p in partners):
            raise ValueError("mode_contrast: no object's training trajectories reached two outcomes")
        return partners

    def _tensorboard(self):
        try:
            from torch.utils.tensorboard import SummaryWriter
        except ImportError:  # tensorboard is optional outside the project venv (e.g. a bare GPU machine)
            return None
        return SummaryWriter(str(self.out / "tensorboard"))

    # ----------------------------------------------------------- checkpoints
    def _meta(self, phase: str | None = None) -> dict:
        return {
            "selector_config": self.selector_config.to_dict(),
            "predictor_config": self.predictor_config.to_json(),
            "perception": self.perception,
            "dataset_digest": self.dataset_digest,
            "train_config": self.config.to_dict(),
            "lineage": self.lineage,
            "training": {"phase_index": self.phase_index, "phase": phase, "step": self.step},
        }

    def save_state(self, optimizer: torch.optim.Optimizer | None, phase: str | None) -> None:
        """Resumable checkpoint: weights, optimiser moments (as tensors), RNG state, position."""
        if not self.ctx.is_main:
            return
        tensors = checkpoint.policy_tensors(self.selector, self.predictor)
        meta = self._meta(phase)
        if optimizer is not None:
            state = optimizer.state_dict()
            for pid, entries in state["state"].items():
                for key, value in entries.items():
                    tensors[f"optim.{pid}.{key}"] = torch.as_tensor(value)
            meta["optimizer_groups"] = state["param_groups"]
        tensors["rng.torch"] = torch.get_rng_state()
        checkpoint.save(self.out / STATE, tensors, meta)

    def save_model(self, name: str) -> Path:
        """Weights-only checkpoint ``<out>/<name>`` (JSON path), with :attr:`encoder_file` beside it."""
        json_path = checkpoint.save(self.out / name, checkpoint.policy_tensors(self.selector, self.predictor), self._meta())
        if self.encoder_file is not None:
            checkpoint.ship_encoder(self.out / name, self.encoder_file)
        return json_path

    def save_policy(self) -> Path:
        return self.save_model(POLICY)

    def resume(self) -> bool:
        """Load ``<out>/train_state`` if present; returns whether training resumes from it."""
        if not checkpoint.paths(self.out / STATE)[1].exists():
            return False
        tensors, meta = checkpoint.read(self.out / STATE, self.perception)
        if meta["dataset_digest"] != self.dataset_digest:
            raise checkpoint.CheckpointError(f"{self.out / STATE} was trained on dataset {meta['dataset_digest']}, "
                                             f"not on this one ({self.dataset_digest})")
        checkpoint.load_state(self.selector, checkpoint.state_with_prefix(tensors, "selector."), "selector")
        checkpoint.load_state(self.predictor, checkpoint.state_with_prefix(tensors, "predictor."), "predictor")
        self.lineage = meta["lineage"]
        self.phase_index, self.step = meta["training"]["phase_index"], meta["training"]["step"]
        optim = checkpoint.state_with_prefix(tensors, "optim.")
        if optim:
            state: dict = {}
            for key, value in optim.items():
                pid, name = key.split(".", 1)
                state.setdefault(int(pid), {})[name] = value
            self.optimizer_state = {"state": state, "param_groups": meta["optimizer_groups"]}
        torch.set_rng_state(tensors["rng.torch"])
        return True

    # -------------------------------------------------------------- training
    def run(self) -> dict[str, PhaseResult]:
        results = {}
        for index, phase in enumerate(self.config.phases):
            if index < self.phase_index:
                continue
            results[phase] = self._run_phase(phase)
            self.phase_index, self.step, self.optimizer_state = index + 1, 0, None
            self.lineage["phases_done"].append(phase)
            self.save_state(None, None)
            if phase == "predictor" and self.ctx.is_main:
                self.save_model(GOAL_RVT)
        if self.ctx.is_main:
            self.save_policy()
        if self.writer is not None:
            self.writer.close()
        return results

    def _items(self, phase: str, data: TrainingData) -> np.ndarray:
        """Trajectory rows (selector phase) or (trajectory, phase) keyframe pairs (others).

        Keyframes come only from the trajectories of ``config.predictor_samplers`` when it names any.
        """
        if phase == "selector":
            return np.arange(len(data))[:, None]
        frames = data.keyframes()
        if not self.config.predictor_samplers:
            return frames
        kept = np.array([sampler_of(i) in self.config.predictor_samplers for i in data.ids], dtype=bool)
        return frames[kept[frames[:, 0]]]

    def _modules(self, phase: str) -> list[torch.nn.Module]:
        return {"selector": [self.selector], "predictor": [self.predictor], "joint": [self.selector, self.predictor]}[phase]

    def _param_groups(self, params: list[torch.nn.Parameter]) -> list[dict]:
        """The optimiser's groups of a phase's ``params``: the predictor's conditioning layers (FiLM, the mode
        query) apart when ``config.conditioning_lr_scale`` is not 1.

        Why: continued from an "add" predictor those layers start at zero, where the continuation's small
        learning rate left them: after 10 epochs the mode query's projection was still ~10x below a freshly
        initialised layer's weights (docs/training.md, "The mode query at ten times the learning rate").
        """
        scale = self.config.conditioning_lr_scale
        own = {id(p) for n, p in self.predictor.named_parameters() if n.startswith(CONDITIONING_LAYERS)}
        conditioning = [p for p in params if id(p) in own]
        if scale == 1.0 or not conditioning:
            return [{"params": params, "lr_scale": 1.0}]
        return [{"params": [p for p in params if id(p) not in own], "lr_scale": 1.0},
                {"params": conditioning, "lr_scale": scale}]

    @torch.no_grad()
    def _eps_pools(self, trajectories: np.ndarray) -> list[np.ndarray] | None:
        """The per-trajectory eps pools a "served", "neighbour" or "nearest_centre" predictor phase feeds from
        (train/served_eps.py), for the predictor's ``trajectories``; None for "true" eps. The selector is fixed
        from here on."""
        if self.config.predictor_eps == "true":
            return None
        objects = [object_of(i) for i in self.train.ids]
        if self.config.predictor_eps == "neighbour":
            true = self.selector.standardise(torch.from_numpy(self.train.z).to(self.device)).cpu().numpy()
            return neighbour_eps_pools(true, objects, trajectories, self.config.neighbour_count)
        self.selector.eval()
        if self.config.predictor_eps == "nearest_centre":
            pools, chosen = nearest_centre_pools(self.selector, self.train, trajectories, self.device)
            if self.ctx.is_main:
                print(f"nearest-centre eps: trajectories per cluster "
                      f"{np.bincount(chosen, minlength=self.selector.config.clusters).tolist()}")
            return pools
        pools = served_eps_pools(self.selector, self.train, objects, trajectories, self.config.served_draws, self.device,
                                 self.config.seed, self.config.served_noise_scale)
        if self.ctx.is_main:
            held = [len(p) for p in pools if len(p)]
            print(f"served eps: {len(held)} of {len(trajectories)} trajectories hold draws "
                  f"(median {int(np.median(held)) if held else 0} each); the others keep their true eps")
        return pools

    @torch.no_grad()
    def _draw_probabilities(self, phase: str, items: np.ndarray) -> np.ndarray | None:
        """Each of ``items``' chance of a place in a batch: None (uniform) unless the predictor phase is
        cluster-balanced (train/balance.py), where each trajectory's cluster is its nearest-centre cluster."""
        if phase != "predictor" or self.config.predictor_balance == "none":
            return None
        trajectories = np.unique(items[:, 0])
        self.selector.eval()
        _, chosen = nearest_centre_pools(self.selector, self.train, trajectories, self.device)
        weights = np.zeros(len(self.train))
        weights[trajectories] = cluster_balanced_weights(np.array([object_of(self.train.ids[i]) for i in trajectories]),
                                                         chosen)
        if self.ctx.is_main:
            print(f"cluster-balanced keyframes: trajectory weights {weights[trajectories].min():.2f} to "
                  f"{weights[trajectories].max():.2f} (1 = as collected)")
        probabilities = weights[items[:, 0]]
        return probabilities / probabilities.sum()

    def _run_phase(self, phase: str) -> PhaseResult:
        cfg = self.config.phase(phase)
        items = self._items(phase, self.train)
        if len(items) == 0:
            raise ValueError(f"no training items for phase {phase}")
        steps_per_epoch = max(1, math.ceil(len(items) / cfg.batch_size))
        total = max(1, int(round(cfg.epochs * steps_per_epoch)))
        params = [p for m in self._modules(phase) for p in m.parameters() if p.requires_grad]
        optimizer = torch.optim.AdamW(self._param_groups(params), lr=cfg.lr, weight_decay=cfg.weight_decay)
        if self.optimizer_state is not None:
            optimizer.load_state_dict(self.optimizer_state)
        wrapped = {m: wrap(m, self.ctx) for m in self._modules(phase)}
        if phase == "predictor":
            self.eps_pools = self._eps_pools(np.unique(items[:, 0]))
        probabilities = self._draw_probabilities(phase, items)
        last_save, t0, metrics = time.monotonic(), time.monotonic(), {}
        bar = progress(total=total, initial=self.step, desc=f"{phase}", unit="step",
                       disable=not self.show)
        for m in self._modules(phase):
            m.train()
        while self.step < total:
            rng = np.random.default_rng([self.config.seed, self.config.phases.index(phase), self.step])
            size = min(cfg.batch_size, len(items))
            batch_items = items[rng.choice(len(items), size=size, replace=False, p=probabilities)]
            for group in optimizer.param_groups:
                group["lr"] = group.get("lr_scale", 1.0) * learning_rate(self.step, total, cfg.lr, cfg.warmup_fraction,
                                                                         cfg.final_lr_fraction)
            self.temperature = gumbel_temperature(self.step / steps_per_epoch)
            loss, metrics = self.loss(phase, self.train, rank_slice(batch_items, self.ctx), wrapped, rng)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            metrics["grad_norm"] = float(torch.nn.utils.clip_grad_norm_(params, cfg.grad_clip))
            optimizer.step()
            self.step += 1
            bar.update(1)
            if self.step % self.config.log_every == 0 or self.step == total:
                bar.set_postfix(loss=f"{metrics['loss']:.3f}")
                self._log(f"{phase}/train", metrics, self.step)
            if self.step % steps_per_epoch == 0 or self.step == total:
                self._epoch_end(phase, metrics)
            if time.monotonic() - last_save > 60.0 * self.config.checkpoint_minutes:
                self.save_state(optimizer, phase)
                last_save = time.monotonic()
        bar.close()
        self.eps_pools = None
        return PhaseResult(total, time.monotonic() - t0, metrics)

    def _autocast(self):
        if self.config.bf16 and self.device.type == "cuda":
            return torch.autocast("cuda", dtype=torch.bfloat16)
        return nullcontext()

    def loss(self, phase: str, data: TrainingData, items: np.ndarray, wrapped: dict | None = None,
             rng: np.random.Generator | None = None) -> tuple[torch.Tensor, dict[str, float]]:
        """Total loss of one (per-rank) batch for ``phase``: L_action + w L_ELBO (either alone in pretraining)."""
        action, elbo, metrics = self.losses(phase, data, items, wrapped, rng)
        if action is None:
            loss = elbo
        elif elbo is None:
            loss = action
        else:
            loss = action + self.config.joint_elbo_weight * elbo
        metrics["loss"] = loss.item()
        return loss, metrics

    def losses(self, phase: str, data: TrainingData, items: np.ndarray, wrapped: dict | None = None,
               rng: np.random.Generator | None = None) -> tuple[torch.Tensor | None, torch.Tensor | None, dict[str, float]]:
        """(L_action or None, L_ELBO or None, metrics) of one batch of ``items``.

        ``wrapped`` maps modules to their DDP wrappers; ``rng`` draws the scene augmentation
        (none without it, as in validation). Only a training batch (with ``rng``) gives the
        predictor the demonstrated point (``rotation_pooling="point"``) and the Gaussian rotation
        targets (``rotation_sigma_deg``): validation losses read the predicted point and score
        the one-hot CE(R), as served and comparable across runs. In the joint phase the predictor reads the
        selector's reconstruction of z *detached* (sg[eps]), so L_action has no path into the
        selector (tests/train/test_stop_gradient.py).
        """
        wrapped = wrapped or {}
        selector, predictor = wrapped.get(self.selector, self.selector), wrapped.get(self.predictor, self.predictor)
        weights = self.config.elbo
        with self._autocast():
            if phase == "selector":
                rows = items[:, 0]
                condition = rows
                if self.same_object is not None and rng is not None:  # a training batch of self.train
                    condition = np.array([rng.choice(self.same_object[r]) for r in rows])
                views, _ = data.selector_batch(condition, self.device)  # the O_init each trajectory is conditioned on
                z = torch.from_numpy(data.z[rows]).to(self.device)
                elbo, _, metrics = selector_loss(selector, views, self.selector.standardise(z), weights, temperature=self.temperature,
                                                 clusters=data.known_clusters(rows, self.device))
                return None, elbo, metrics
            batch = data.keyframe_batch(items, self.device)
            eps_true = self.selector.standardise(batch["z"])
            metrics: dict[str, float] = {}
            elbo = None
            eps_in = eps_true
            if phase == "joint":
                elbo, eps_hat, sel_metrics = selector_loss(selector, batch["init_views"], eps_true, weights, temperature=self.temperature,
                                                           clusters=data.known_clusters(items[:, 0], self.device))
                eps_in = eps_hat.detach()
                metrics.update({f"selector_{k}": v for k, v in sel_metrics.items()})
            views, keypose = self.augment(batch["views"], batch["keypose"], rng)
            point = self.placement.to_cube(keypose[:, :3]) if rng is not None else None  # teacher forcing: training only
            proprio = proprio_features(batch["gripper"], batch["phase"])
            out = predictor(views, self.training_eps(eps_in, items[:, 0], rng), proprio, point)
            targets = action_targets(keypose, self.placement, views.shape[-1], view=self.predictor_config.view_index)
            action, parts = action_loss(out, targets,
                                        rotation_sigma_deg=self.config.rotation_sigma_deg if rng is not None else 0.0)
            metrics.update({"action": action.item(), **{k: float(v) for k, v in parts.items()}})
            if self.partners is not None and phase == "predictor" and rng is not None:  # a training batch of self.train
                positions, drawn = draw_partners(self.partners, items[:, 0], rng)
                if len(positions):
                    k = torch.from_numpy(positions).to(self.device)
                    eps_other = self.selector.standardise(torch.from_numpy(self.train.z[drawn]).to(self.device))
                    other = predictor(views[k], self.training_eps(eps_other, drawn, rng), proprio[k], point[k])
                    contrast = mode_contrast_loss(heatmap_log_likelihood(out.heatmaps[k], targets.heatmaps[k]),
                                                  heatmap_log_likelihood(other.heatmaps, targets.heatmaps[k]))
                    action = action + self.config.mode_contrast * contrast
                    metrics["mode_contrast"] = contrast.item()
            return action, elbo, metrics

    def perturb_eps(self, eps: torch.Tensor, rng: np.random.Generator | None) -> torch.Tensor:
        """eps plus Gaussian noise of ``config.eps_noise`` (standardised units) while training.

        Why: z is a 1920-value embedding unique to its trajectory, so a predictor fed it exactly
        can key its outputs on it and memorise each trajectory's rotation (the first committed
        run: training CE(R) 5.1 while validation CE(R) rose from 12.2 to 20.6, above the 12.8 of
        a uniform guess). Noise leaves the mode (the direction of the visual change) readable and
        the trajectory's identity not; at serving eps is a draw of the selector anyway.
        """
        if rng is None or self.config.eps_noise <= 0.0:
            return eps
        noise = torch.from_numpy(rng.standard_normal(tuple(eps.shape)).astype(np.float32)).to(eps.device, eps.dtype)
        return eps + self.config.eps_noise * noise

    def training_eps(self, eps: torch.Tensor, rows: np.ndarray, rng: np.random.Generator | None) -> torch.Tensor:
        """The eps a training batch of trajectories ``rows`` feeds the predictor: ``eps`` plus noise,
        and, in a "served" or "neighbour" predictor phase, an eps of the pool of every trajectory whose
        pool holds one (train/served_eps.py). Validation (no ``rng``) feeds ``eps`` as given."""
        eps = self.perturb_eps(eps, rng)
        if self.eps_pools is None or rng is None:
            return eps
        positions, drawn = pick_from_pools(self.eps_pools, rows, rng)
        if len(positions):
            eps = eps.clone()
            eps[torch.from_numpy(positions).to(eps.device)] = torch.from_numpy(drawn).to(eps.device, eps.dtype)
        return eps

    def augment(self, views: torch.Tensor, keypose: torch.Tensor,
                rng: np.random.Generator | None) -> tuple[torch.Tensor, torch.Tensor]:
        """RVT's scene augmentation of rendered views and keyposes (models/augment.py), per sample."""
        if not self.config.augment or rng is None:
            return views, keypose
        pairs = [augment(v, k, self.placement, rng) for v, k in zip(views.cpu().numpy(), keypose.cpu().numpy())]
        return (torch.from_numpy(np.stack([v for v, _ in pairs]).astype(np.float32)).to(views.device),
                torch.from_numpy(np.stack([k for _, k in pairs]).astype(np.float32)).to(keypose.device))

    @torch.no_grad()
    def validate(self, phase: str, limit: int = 256) -> dict[str, float] | None:
        """Mean losses over (up to ``limit``) held-out items: eval mode, no augmentation, fixed noise.

        The selector's draws use a forked RNG, so validating leaves the training RNG untouched
        (a resumed run stays on the same random sequence). ``reconstruction_mse`` is the mean
        squared error per dimension of eps through the posterior means.
        """
        if self.val is None or len(self.val) == 0:
            return None
        items = self._items(phase, self.val)
        if len(items) == 0:
            return None
        items = items[np.random.default_rng(self.config.seed).permutation(len(items))[:limit]]
        modules = self._modules(phase)
        for m in modules:
            m.eval()
        sums: dict[str, float] = {}
        with torch.random.fork_rng(devices=[self.device] if self.device.type == "cuda" else []):
            torch.manual_seed(self.config.seed)
            for chunk in np.array_split(items, max(1, math.ceil(len(items) / self.config.phase(phase).batch_size))):
                _, metrics = self.loss(phase, self.val, chunk)
                if phase != "predictor":
                    views, z = self.val.selector_batch(chunk[:, 0], self.device)
                    eps = self.selector.standardise(z)
                    rec = self.selector.reconstruct(views, eps)
                    metrics["reconstruction_mse"] = float(((rec - eps) ** 2).mean())
                for k, v in metrics.items():
                    sums[k] = sums.get(k, 0.0) + v * len(chunk)
        for m in modules:
            m.train()
        return {k: v / len(items) for k, v in sums.items()}

    def _epoch_end(self, phase: str, train_metrics: dict) -> None:
        if not self.ctx.is_main:
            return
        val = self.validate(phase)
        record = {"phase": phase, "step": self.step, "train": train_metrics, "val": val}
        with open(self.out / "history.jsonl", "a") as f:
            f.write(json.dumps(record) + "\n")
        if val is not None:
            self._log(f"{phase}/val", val, self.step)

    def _log(self, tag: str, metrics: dict, step: int) -> None:
        if self.writer is None:
            return
        for k, v in metrics.items():
            self.writer.add_scalar(f"{tag}/{k}", v, step)
