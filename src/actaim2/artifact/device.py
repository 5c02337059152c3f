"""The torch device a policy artifact is trained or served on."""
from __future__ import annotations

import torch


def choose_device(preference: str, local_rank: int = 0) -> torch.device:
    """"auto": CUDA when present, else CPU; "cpu" / "cuda" as asked (cuda without a GPU is an error)."""
    if preference == "cpu" or (preference == "auto" and not torch.cuda.is_available()):
        return torch.device("cpu")
    if not torch.cuda.is_available():
        raise RuntimeError("device 'cuda' requested but torch sees no CUDA device")
    return torch.device("cuda", local_rank)
