"""What every mode selector P(eps | O_init) shares: configuration, condition encoder, z scaling, sampling result.

The CGMVAE (``selector.py``) and the baselines (``baselines/cvae.py``, ``baselines/vqvae.py``)
differ only in their latent; all of them

  * encode the robot-hidden initial views into per-view tokens (``obs_encoder.ObsEncoder``),
  * start their encoder of eps the same way: eps and the flattened tokens embedded to one width
    and summed (``ModeSelector.joint_embedding``),
  * reconstruct the dataset's task embedding z with the same transformer decoder
    (``eps_decoder.EpsDecoder``),
  * work in *standardised* z space: eps = (z - mean) / std with the training set's statistics
    (kept as buffers, so a checkpoint carries them). The action predictor is fed eps in that
    space, both the true one (Goal-RVT, pretraining) and the sampled one. With ``eps_dim`` > 0,
    eps is instead the whitened projection of that standardised z on its first ``eps_dim``
    principal components (of the training set, a buffer too): z has 1920 values, unique to its
    trajectory, and neither model learned to use them on a few hundred trajectories (the
    predictor erred as much fed the true z as fed the selector's near-mean reconstruction),
    while 16 components keep what tells an object's outcomes apart (nearest neighbour within an
    object: the same outcome for 89 % of train_seen successes, 91 % with all 1920 values),
  * answer ``sample(views, cluster, generator) -> SampleResult``.
"""
from __future__ import annotations

import abc
import dataclasses
from dataclasses import dataclass, field

import torch
from torch import nn

from actaim2.config_fields import check_fields
from actaim2.models.eps_decoder import EpsDecoder
from actaim2.models.obs_encoder import ObsEncoder, ObsEncoderConfig

SELECTOR_KINDS = ("cgmvae", "cvae", "vqvae")


@dataclass(frozen=True)
class SelectorConfig:
    kind: str = "cgmvae"  # "cgmvae" (the paper) | "cvae" (ActAIM) | "vqvae" (VQVAE-RVT)
    z_dim: int = 1920  # task embedding size: 5 cameras x 384 with the default autoencoder E
    z_tokens: int = 5  # decoder query tokens, one per camera block of z
    clusters: int = 8  # K (cgmvae mixture components, vqvae codebook size)
    latent_dim: int = 64  # x (cgmvae), the Gaussian latent (cvae), code size (vqvae)
    y_dim: int = 64  # cgmvae's y ~ N(0, I)
    width: int = 256  # residual MLP width
    blocks: int = 2  # residual blocks per MLP
    decoder_layers: int = 4  # the paper's 4 self-attention layers
    decoder_heads: int = 4
    commitment: float = 0.25  # vqvae commitment weight (van den Oord et al.)
    eps_dim: int = 0  # > 0: eps = whitened principal components of standardised z (module docstring); 0: eps = standardised z
    obs: ObsEncoderConfig = field(default_factory=ObsEncoderConfig)

    def __post_init__(self) -> None:
        if self.kind not in SELECTOR_KINDS:
            raise ValueError(f"selector kind must be one of {SELECTOR_KINDS}, got {self.kind!r}")
        if not 0 <= self.eps_dim <= self.z_dim:
            raise ValueError(f"eps_dim must lie in 0..z_dim ({self.z_dim}), got {self.eps_dim}")
        if self.eps_size % self.z_tokens:
            raise ValueError(f"eps has {self.eps_size} values (z_dim {self.z_dim}, eps_dim {self.eps_dim}), "
                             f"not a multiple of z_tokens {self.z_tokens}")

    @property
    def eps_size(self) -> int:
        """Values in eps: what the decoder reconstructs and the action predictor reads."""
        return self.eps_dim or self.z_dim

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "SelectorConfig":
        check_fields(cls, d, "selector")
        d = dict(d)
        obs = d.pop("obs", {})
        check_fields(ObsEncoderConfig, obs, "selector.obs")
        obs = dict(obs)
        if "widths" in obs:
            obs["widths"] = tuple(obs["widths"])
        return cls(**d, obs=ObsEncoderConfig(**obs))


@dataclass
class SampleResult:
    eps: torch.Tensor  # (B, eps_size) standardised task embedding, the action predictor's input
    cluster: torch.Tensor  # (B,) long; -1 for a selector without discrete modes (cvae)
    cluster_probabilities: torch.Tensor  # (B, K) the distribution the cluster was drawn from; (B, 0) for cvae


class ModeSelector(nn.Module, abc.ABC):
    """Base class: condition encoder, decoder, z standardisation. Subclasses add the latent."""

    def __init__(self, config: SelectorConfig):
        super().__init__()
        self.config = config
        self.obs_encoder = ObsEncoder(config.obs)
        self.decoder = EpsDecoder(config.latent_dim, config.obs.token_dim, config.eps_size, config.z_tokens,
                                  config.decoder_layers, config.decoder_heads)
        self.register_buffer("z_mean", torch.zeros(config.z_dim))
        self.register_buffer("z_std", torch.ones(config.z_dim))
        self.register_buffer("eps_basis", torch.zeros(config.z_dim, config.eps_dim) if config.eps_dim else None)
        # Every selector's encoder q(. | eps, O) starts alike: eps and O embedded to one width (joint_embedding).
        self.embed_eps = nn.Linear(config.eps_size, config.width)
        self.embed_condition = nn.Linear(self.condition_dim, config.width)

    @property
    def condition_dim(self) -> int:
        """Size of the flattened per-view tokens fed to the MLP heads."""
        return self.config.obs.views * self.config.obs.token_dim

    @torch.no_grad()
    def fit_statistics(self, views: torch.Tensor, z: torch.Tensor) -> None:
        """Input standardisation of the views and of z, from the training set (before training).

        Each dimension of z is divided by its spread, floored at the median spread over the
        dimensions. Without the floor, dimensions that are (nearly) constant on the training set
        (dead encoder features: 239 of 1920 had a spread under 1e-4 on data/v2) were blown up by
        10^3-10^6 wherever an unseen object moved them, and swamped both the selector's
        reconstruction loss and the predictor's input. Below the median a dimension is scaled
        down instead: it carries little of the variation that distinguishes outcomes.
        """
        if z.shape[-1] != self.config.z_dim:
            raise ValueError(f"z has {z.shape[-1]} dimensions, the selector expects {self.config.z_dim}")
        self.obs_encoder.fit_input_statistics(views)
        self.z_mean.copy_(z.float().mean(dim=0))
        if len(z) > 1:
            spread = z.float().std(dim=0)
            self.z_std.copy_(spread.clamp_min(float(spread.median().clamp_min(1e-6))))
        else:
            self.z_std.fill_(1.0)
        if self.eps_basis is not None:
            d = self.config.eps_dim
            if len(z) <= d:
                raise ValueError(f"eps_dim {d} principal components need more than {d} training trajectories, got {len(z)}")
            _, s, vh = torch.linalg.svd(self._scaled(z), full_matrices=False)  # centred: z_mean is the training mean
            self.eps_basis.copy_(vh[:d].T * (len(z) - 1) ** 0.5 / s[:d].clamp_min(1e-6))  # unit variance per component

    def _scaled(self, z: torch.Tensor) -> torch.Tensor:
        """z centred and scaled per dimension by the training statistics."""
        return (z.float() - self.z_mean) / self.z_std

    def standardise(self, z: torch.Tensor) -> torch.Tensor:
        """Raw task embedding z -> eps space."""
        eps = self._scaled(z)
        return eps if self.eps_basis is None else eps @ self.eps_basis

    def condition(self, views: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Per-view tokens (B, V, d) and their flattening (B, V * d)."""
        tokens = self.obs_encoder(views)
        return tokens, tokens.flatten(1)

    def joint_embedding(self, flat: torch.Tensor, eps_true: torch.Tensor) -> torch.Tensor:
        """[eps, O] embedded to one width (B, width), the first layer of the encoder q(. | eps, O)."""
        return nn.functional.gelu(self.embed_eps(eps_true) + self.embed_condition(flat))

    def _cluster_argument(self, cluster: int | None, batch: int, device: torch.device) -> torch.Tensor | None:
        if cluster is None:
            return None
        if not 0 <= int(cluster) < self.config.clusters:
            raise ValueError(f"cluster must be in 0..{self.config.clusters - 1}, got {cluster}")
        return torch.full((batch,), int(cluster), dtype=torch.long, device=device)

    @abc.abstractmethod
    def draw_noise(self, batch: int, generator: torch.Generator | None = None,
                   device: torch.device | str = "cpu") -> dict[str, torch.Tensor]:
        """The training forward's random draws, explicit so a batch can be split reproducibly (DDP test)."""
        ...

    @abc.abstractmethod
    def sample(self, views: torch.Tensor, cluster: int | None = None,
               generator: torch.Generator | None = None, noise_scale: float = 1.0) -> SampleResult:
        """Draw eps for each row of ``views``. ``noise_scale`` multiplies the spread of the latent draws
        (the sampling temperature of Kingma & Dhariwal 2018): 1 samples the learned distribution, 0 takes
        each cluster's most likely latent, so one cluster gives one eps per O_init."""
        ...

    @abc.abstractmethod
    def reconstruct(self, views: torch.Tensor, eps_true: torch.Tensor) -> torch.Tensor:
        """Deterministic reconstruction of a known eps through the posterior means (validation)."""
        ...

    @abc.abstractmethod
    def assign_clusters(self, views: torch.Tensor, eps_true: torch.Tensor) -> torch.Tensor:
        """(B,) the cluster a known eps belongs to (-1 without discrete modes)."""
        ...
