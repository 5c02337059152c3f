"""How a policy artifact is served: the defaults of /sample_mode and /predict_keypose that
policy_node, the evaluation and validation share, checked once where they are made."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ServingConfig:
    # Fallback keyposes /predict_keypose gives with each keypose: its point with the next likeliest
    # rotations, which the planner tries in turn when it refuses the keypose (0 = none).
    keypose_alternatives: int = 4
    # Weight w of the mode guidance of the predicted point (models/mode_guidance.py); 0 = the plain
    # predictor, one forward pass.
    mode_guidance: float = 0.0
    # Spread of the selector's latent draws /sample_mode uses (ModeSelector.sample's noise_scale):
    # 0 serves each cluster's noise-free eps, 1 samples the trained distribution.
    noise_scale: float = 0.0

    def __post_init__(self) -> None:
        if self.keypose_alternatives < 0:
            raise ValueError(f"keypose_alternatives {self.keypose_alternatives} is negative")
        if not self.mode_guidance >= 0.0:
            raise ValueError(f"mode_guidance {self.mode_guidance} is not a weight >= 0")
        check_noise_scale(self.noise_scale)


def check_noise_scale(value: float, name: str = "noise_scale") -> float:
    """``value`` if it is a noise scale (>= 0; NaN is not); a ValueError naming ``name`` (a parameter or flag) otherwise."""
    if not value >= 0.0:
        raise ValueError(f"{name} {value} is not a scale >= 0")
    return value


DEFAULT_SERVING = ServingConfig()
