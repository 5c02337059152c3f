"""Build a mode selector from its configuration (checkpoints store only the configuration)."""
from __future__ import annotations

from actaim2.models.baselines.cvae import CVAESelector
from actaim2.models.baselines.vqvae import VQVAESelector
from actaim2.models.selector import CGMVAE
from actaim2.models.selector_base import ModeSelector, SelectorConfig

SELECTORS: dict[str, type[ModeSelector]] = {"cgmvae": CGMVAE, "cvae": CVAESelector, "vqvae": VQVAESelector}


def build_selector(config: SelectorConfig) -> ModeSelector:
    return SELECTORS[config.kind](config)
