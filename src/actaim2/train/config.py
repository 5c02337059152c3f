"""Training configuration: dataclasses filled from one YAML file (train/configs/*.yaml).

Unknown keys are errors (a typo must not silently fall back to a default). Sizes that depend on
the data (the task-embedding size z_dim, the view resolution) are not configured: training
reads them from the dataset and writes the resolved configuration into every checkpoint.
A YAML may start from another one (``base: cpu_default``) and list only what it changes:
mappings are merged key by key, anything else replaced (the ablation configs do this, so they
keep the selector of the run they extend).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from actaim2.config_fields import check_fields
from actaim2.models.selector_base import SelectorConfig

CONFIG_DIR = Path(__file__).parent / "configs"
PHASES = ("selector", "predictor", "joint")
PREDICTOR_EPS = ("true", "served", "neighbour", "nearest_centre")
SELECTOR_CONDITIONS = ("own", "object")
PREDICTOR_BALANCES = ("none", "cluster")


@dataclass(frozen=True)
class ElboWeights:
    """Weights of the selector loss terms (paper: all 1; authors' code: 2 / 3 / 3 / 3)."""

    reconstruction: float = 1.0
    x_prior: float = 1.0
    y_prior: float = 1.0
    c_prior: float = 1.0
    # Not an ELBO term: reconstruction along the sampling path (c relaxed by Gumbel-softmax ->
    # x ~ p(x | y, c, O) -> eps), so that eps sampled from a cluster decodes like the data.
    generative: float = 1.0
    # Not an ELBO term either: log K - H(batch mean of q(c)), so that the posterior uses the K clusters
    # (train/elbo.py cluster_imbalance; 0: off, the paper).
    cluster_balance: float = 0.0
    # With it, the mean entropy of each trajectory's q(c): together they maximise the batch's mutual information
    # of cluster and data (IMSAT, Hu et al. 2017), so clusters are both used and told apart (0: off, the paper).
    cluster_confidence: float = 0.0
    # Not an ELBO term: winner-takes-all over the K clusters' noise-free draws - each trajectory pulls the cluster whose
    # draw lies nearest its eps, so one object's K draws spread over its eps (train/elbo.py cluster_coverage; 0: off).
    cluster_coverage: float = 0.0
    # Not an ELBO term: -log q(c* | x, y, O) of a trajectory whose cluster c* is known (a demonstration's mode label,
    # fine-tuning), so its posterior picks that cluster (train/elbo.py known_cluster_loss); no effect without one.
    # Its nats weigh against the reconstruction's squared error, summed over the hundreds of eps values.
    known_cluster: float = 100.0


@dataclass(frozen=True)
class PhaseConfig:
    """One training phase: AdamW, linear warm-up then cosine decay to ``final_lr_fraction`` of ``lr``."""

    epochs: float = 10.0
    batch_size: int = 8
    lr: float = 3e-4
    weight_decay: float = 0.01
    warmup_fraction: float = 0.05
    final_lr_fraction: float = 0.01
    grad_clip: float = 1.0


@dataclass(frozen=True)
class TrainConfig:
    seed: int = 0
    phases: tuple[str, ...] = PHASES  # which phases run, in this order
    selector: SelectorConfig = field(default_factory=SelectorConfig)  # z_dim is overwritten from the data
    predictor: dict = field(default_factory=dict)  # PredictorConfig fields except embedding_dim / image_size
    selector_phase: PhaseConfig = field(default_factory=PhaseConfig)
    predictor_phase: PhaseConfig = field(default_factory=PhaseConfig)
    joint_phase: PhaseConfig = field(default_factory=PhaseConfig)
    elbo: ElboWeights = field(default_factory=ElboWeights)
    joint_elbo_weight: float = 1.0  # L_total = L_action + w L_ELBO (paper: 1; authors' code: 0.6)
    augment: bool = True  # RVT scene augmentation of the predictor's batches
    eps_noise: float = 0.0  # std of Gaussian noise on the predictor's eps while training (standardised units)
    rotation_sigma_deg: float = 0.0  # std of the Gaussian rotation targets over each angle's bins (0: one-hot, RVT)
    # Weight of the mode contrast (train/mode_contrast.py): the demonstrated point must be likelier
    # under the trajectory's own eps than under the eps of the same object's other outcome (0: off, the paper).
    mode_contrast: float = 0.0
    # Learning-rate multiplier of the predictor's FiLM / mode-query layers (models/predictor.py
    # CONDITIONING_LAYERS), which a predictor continued from an "add" one starts at zero (1: one rate for all).
    conditioning_lr_scale: float = 1.0
    # Samplers whose trajectories the predictor learns keyposes from (empty: all, as the paper). The
    # selector always learns from every success: its clusters describe all the modes collection found.
    predictor_samplers: tuple[str, ...] = ()
    # The eps the predictor phase feeds (train/served_eps.py): "true" (the trajectory's own, plus
    # eps_noise; the paper) or "served" (a draw of the selector's clusters whose nearest true eps is
    # the trajectory's, ``served_draws`` per cluster and trajectory; true eps + noise where none is) or
    # "neighbour" (the true eps of the trajectory or of one of its ``neighbour_count`` nearest in eps among
    # its object's others: another placement, mostly the same outcome) or "nearest_centre" (of the K clusters'
    # noise-free eps on the trajectory's own O_init, the one nearest its true eps: what noise scale 0 serves).
    predictor_eps: str = "true"
    served_draws: int = 8
    served_noise_scale: float = 1.0  # the spread of those draws (ModeSelector.sample; 0: each cluster's noise-free eps)
    neighbour_count: int = 2
    # How the predictor phase draws its keyframes: "none" (uniformly, as collected; the paper) or "cluster"
    # (within each object, every cluster its trajectories are quantised to carries an equal share:
    # train/balance.py; the evaluation asks for each cluster equally often).
    predictor_balance: str = "none"
    # The O_init the selector phase conditions each trajectory on: "own" (the paper) or "object" (that of a random
    # trajectory of the same object, itself included). Why "object": every trajectory's placement jitter shows in its
    # O_init, so with its own the conditional prior can learn one eps per O_init and needs no cluster for another
    # outcome; with any of the object's, p(eps | O) has to hold all the outcomes the object showed.
    selector_condition: str = "own"
    # With --init-from: take the parent's predictor weights (True) or train a freshly initialised
    # predictor beside the parent's selector and z statistics (False), so that a conditioning is
    # learned from the first step instead of being added at zero to a converged predictor.
    predictor_from_parent: bool = True
    validation_fraction: float = 0.1  # trajectories of the training split held out for curves
    checkpoint_minutes: float = 10.0  # wall time between resumable checkpoints
    log_every: int = 20  # steps between TensorBoard scalars / progress-bar updates
    device: str = "auto"  # "auto" (CUDA when present) | "cpu" | "cuda"
    bf16: bool = False  # autocast to bfloat16 on CUDA

    def __post_init__(self) -> None:
        bad = [p for p in self.phases if p not in PHASES]
        if bad:
            raise ValueError(f"unknown phases {bad}; choose from {PHASES}")
        if self.rotation_sigma_deg < 0.0:
            raise ValueError(f"rotation_sigma_deg must be >= 0 (0: one-hot targets), got {self.rotation_sigma_deg}")
        if self.predictor_eps not in PREDICTOR_EPS:
            raise ValueError(f"predictor_eps must be one of {PREDICTOR_EPS}, got {self.predictor_eps!r}")
        if self.predictor_balance not in PREDICTOR_BALANCES:
            raise ValueError(f"predictor_balance must be one of {PREDICTOR_BALANCES}, got {self.predictor_balance!r}")
        if self.selector_condition not in SELECTOR_CONDITIONS:
            raise ValueError(f"selector_condition must be one of {SELECTOR_CONDITIONS}, got {self.selector_condition!r}")
        if self.served_draws < 1:
            raise ValueError(f"served_draws must be >= 1, got {self.served_draws}")
        if not self.served_noise_scale >= 0.0:
            raise ValueError(f"served_noise_scale must be >= 0, got {self.served_noise_scale}")
        if self.neighbour_count < 1:
            raise ValueError(f"neighbour_count must be >= 1, got {self.neighbour_count}")
        if self.mode_contrast < 0.0:
            raise ValueError(f"mode_contrast must be >= 0 (0: off), got {self.mode_contrast}")
        if self.conditioning_lr_scale <= 0.0:
            raise ValueError(f"conditioning_lr_scale must be > 0 (1: the phase's rate), got {self.conditioning_lr_scale}")

    def phase(self, name: str) -> PhaseConfig:
        return getattr(self, f"{name}_phase")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "TrainConfig":
        check_fields(cls, d, "train")
        out: dict = {}
        for key, value in d.items():
            if key == "selector":
                out[key] = SelectorConfig.from_dict(value)
            elif key.endswith("_phase"):
                check_fields(PhaseConfig, value, key)
                out[key] = PhaseConfig(**value)
            elif key == "elbo":
                check_fields(ElboWeights, value, key)
                out[key] = ElboWeights(**value)
            elif key in ("phases", "predictor_samplers"):
                out[key] = tuple(value)
            else:
                out[key] = value
        return cls(**out)


def load_config(path: str | Path) -> TrainConfig:
    """A YAML file, or the name of a bundled one ("cpu_default", "gpu_rvt", "ablation_depth", ...)."""
    return TrainConfig.from_dict(_read(path, ()))


def _read(path: str | Path, seen: tuple[Path, ...]) -> dict:
    """The YAML's mapping with its ``base`` chain merged in (base first, this file's keys over it)."""
    p = Path(path)
    if not p.exists() and (CONFIG_DIR / f"{path}.yaml").exists():
        p = CONFIG_DIR / f"{path}.yaml"
    if p.resolve() in seen:
        raise ValueError(f"training configuration {p} names itself as a base (through {[str(s) for s in seen]})")
    with open(p) as f:
        d = yaml.safe_load(f) or {}
    if not isinstance(d, dict):
        raise ValueError(f"training configuration {p} must hold a mapping, got {type(d).__name__}")
    base = d.pop("base", None)
    return d if base is None else _merge(_read(base, seen + (p.resolve(),)), d)


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for key, value in over.items():
        out[key] = _merge(base[key], value) if isinstance(value, dict) and isinstance(base.get(key), dict) else value
    return out
