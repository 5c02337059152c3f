"""What the evaluation needs to know about a checkpoint before loading it: its views and its identity."""
from __future__ import annotations

import json
from pathlib import Path

from actaim2.artifact import checkpoint
from actaim2.perception.config import PerceptionConfig


def describe(stem: str | Path) -> dict:
    """{path, weights_sha256, dataset_digest, perception digest, clusters, selector kind, predictor inputs and view}
    from the JSON (no weights read)."""
    from actaim2.models.predictor import ALL_VIEWS, INPUT_GROUPS

    json_path = checkpoint.paths(stem)[1]
    if not json_path.exists():
        raise FileNotFoundError(f"checkpoint {stem}: {json_path} does not exist")
    meta = json.loads(json_path.read_text())
    selector = meta.get("selector_config") or {}
    predictor = meta.get("predictor_config") or {}
    return {"path": str(checkpoint.paths(stem)[1].with_suffix("")), "weights_sha256": meta.get("weights_sha256"),
            "dataset_digest": meta.get("dataset_digest"), "perception_digest": (meta.get("perception") or {}).get("digest"),
            "selector": selector.get("kind"), "clusters": int(selector.get("clusters", 0)) if selector.get("kind") != "cvae" else 0,
            "predictor_inputs": list(predictor.get("inputs", INPUT_GROUPS)), "predictor_view": predictor.get("view", ALL_VIEWS)}


def perception_of(stem: str | Path) -> PerceptionConfig:
    """The perception configuration a checkpoint was trained under: evaluation serves it exactly those views."""
    meta = json.loads(checkpoint.paths(stem)[1].read_text())
    try:
        return PerceptionConfig.from_dict(meta["perception"]["fields"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"checkpoint {stem} records no usable perception configuration: {exc}") from exc
