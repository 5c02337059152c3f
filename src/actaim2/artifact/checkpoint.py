"""Checkpoints: safetensors weights + a JSON description beside them, loaded without unpickling.

A checkpoint ``<stem>`` is two files:
  <stem>.safetensors   tensors only (model weights under "selector." / "predictor.", and for a
                       resumable training checkpoint the optimiser moments under "optim.<phase>."
                       and the RNG states under "rng.")
  <stem>.json          format, the models' configurations, the perception configuration (and its
                       digest), the dataset digest, package versions, lineage, training state,
                       and the SHA-256 of the weights file.
Loading checks, in this order, and raises a :class:`CheckpointError` subclass with a message
naming the problem (never a bare crash, never unpickling):
  * CorruptCheckpointError   missing file, unreadable JSON, wrong format, weights file whose
                             hash differs from the JSON's, or a safetensors parse error;
  * PerceptionMismatchError  the JSON's perception configuration differs from the one the caller
                             serves with (the differing fields are listed);
  * WeightsMismatchError     tensors missing / unexpected / of another shape than the model the
                             JSON's configuration builds.
Both files are written to temporary names and renamed, JSON last, so an interrupted save leaves
the previous checkpoint intact. A policy trained on task embeddings has a third file,
``<stem>.encoder.pt``: the encoder E that made them (:func:`encoder_path`), copied by training.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import platform
import shutil
import time
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import torch

FORMAT = "actaim2-checkpoint"
FORMAT_VERSION = 1
ENCODER_SUFFIX = ".encoder.pt"
PACKAGES = ("torch", "numpy", "safetensors", "actaim2")


class CheckpointError(Exception):
    """A checkpoint that cannot be used; the message says why."""


class CorruptCheckpointError(CheckpointError):
    pass


class PerceptionMismatchError(CheckpointError):
    pass


class WeightsMismatchError(CheckpointError):
    pass


def _jsonable(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    return value


def perception_record(config: Any) -> dict:
    """The perception configuration as stored in a checkpoint: its fields and its digest.

    ``config`` is an :class:`actaim2.perception.config.PerceptionConfig` (its own ``to_dict`` and
    ``digest`` are used, so checkpoints, datasets and views carry one digest), or a plain dict of
    fields (hashed here) for callers without one.
    """
    if hasattr(config, "to_dict") and hasattr(config, "digest"):
        return {"fields": _jsonable(config.to_dict()), "digest": config.digest()}
    fields = _jsonable(config)
    if not isinstance(fields, dict):
        raise TypeError(f"a perception configuration must be a PerceptionConfig or a dict, got {type(config).__name__}")
    return {"fields": fields, "digest": hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:16]}


def _flatten(d: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(d, dict):
        out: dict[str, Any] = {}
        for k, v in d.items():
            out.update(_flatten(v, f"{prefix}{k}."))
        return out
    return {prefix[:-1]: d}


def perception_differences(stored: dict, expected: dict) -> list[str]:
    """'field: stored != expected' for every differing leaf field of two perception records."""
    a, b = _flatten(stored["fields"]), _flatten(expected["fields"])
    return [f"{k}: {a.get(k, '<absent>')!r} != {b.get(k, '<absent>')!r}" for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]


def package_versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "absent"
    return out


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def paths(stem: str | Path) -> tuple[Path, Path]:
    stem = Path(stem)
    if stem.suffix in (".json", ".safetensors"):
        stem = stem.with_suffix("")
    return stem.with_suffix(".safetensors"), stem.with_suffix(".json")


def encoder_path(stem: str | Path) -> Path:
    """``<stem>.encoder.pt``: the encoder E whose task embeddings the checkpoint's selector learned.

    E travels with the checkpoint because fine-tuning (``actaim2 bag2dataset``) and the Goal-RVT
    evaluation must embed new observations with that same E; without the file a checkpoint can
    only be served, not carried on.
    """
    weights, _ = paths(stem)
    return weights.with_name(weights.stem + ENCODER_SUFFIX)


def ship_encoder(stem: str | Path, encoder: str | Path) -> Path:
    """Copy the encoder file beside the checkpoint (atomically); its path."""
    target = encoder_path(stem)
    tmp = target.with_name(target.name + ".tmp")
    shutil.copyfile(encoder, tmp)
    os.replace(tmp, target)
    return target


def save(stem: str | Path, tensors: dict[str, torch.Tensor], meta: dict) -> Path:
    """Write ``<stem>.safetensors`` and ``<stem>.json``; returns the JSON path."""
    from safetensors.torch import save_file

    weights_path, json_path = paths(stem)
    weights_path.parent.mkdir(parents=True, exist_ok=True)
    tmp_weights = weights_path.with_name(weights_path.name + ".tmp")
    save_file({k: v.detach().contiguous().cpu() for k, v in tensors.items()}, str(tmp_weights))
    body = dict(_jsonable(meta), format=FORMAT, format_version=FORMAT_VERSION, weights_file=weights_path.name,
                weights_sha256=_sha256(tmp_weights), saved_unix=time.time())
    body.setdefault("packages", package_versions())
    tmp_json = json_path.with_name(json_path.name + ".tmp")
    tmp_json.write_text(json.dumps(body, indent=2, sort_keys=True))
    os.replace(tmp_weights, weights_path)
    os.replace(tmp_json, json_path)
    return json_path


def read(stem: str | Path, perception: dict | None = None) -> tuple[dict[str, torch.Tensor], dict]:
    """(tensors, meta) of a checkpoint, verified; ``perception`` (a :func:`perception_record`) must match if given."""
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    weights_path, json_path = paths(stem)
    for p in (json_path, weights_path):
        if not p.exists():
            raise CorruptCheckpointError(f"checkpoint file {p} does not exist")
    try:
        meta = json.loads(json_path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise CorruptCheckpointError(f"{json_path} is not valid JSON: {exc}") from exc
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise CorruptCheckpointError(f"{json_path} is not an {FORMAT} description")
    if meta.get("format_version") != FORMAT_VERSION:
        raise CorruptCheckpointError(f"{json_path} has format version {meta.get('format_version')}, this code reads {FORMAT_VERSION}")
    digest = _sha256(weights_path)
    if digest != meta.get("weights_sha256"):
        raise CorruptCheckpointError(f"{weights_path} does not match its description (sha256 {digest[:16]}..., "
                                     f"expected {str(meta.get('weights_sha256'))[:16]}...): the file is corrupted or was replaced")
    if perception is not None:
        stored = meta.get("perception")
        if not isinstance(stored, dict) or "fields" not in stored:
            raise PerceptionMismatchError(f"{json_path} records no perception configuration")
        diff = perception_differences(stored, perception) if stored.get("digest") != perception["digest"] else []
        if stored.get("digest") != perception["digest"]:
            raise PerceptionMismatchError(f"{json_path} was trained with another perception configuration "
                                          f"(digest {stored.get('digest')}, serving {perception['digest']}): "
                                          + ("; ".join(diff) or "fields equal up to rounding, digests differ"))
    try:
        tensors = load_file(str(weights_path))
    except (SafetensorError, OSError, ValueError) as exc:
        raise CorruptCheckpointError(f"{weights_path} cannot be read as safetensors: {exc}") from exc
    return tensors, meta


def state_with_prefix(tensors: dict[str, torch.Tensor], prefix: str) -> dict[str, torch.Tensor]:
    return {k[len(prefix):]: v for k, v in tensors.items() if k.startswith(prefix)}


def load_state(module: torch.nn.Module, state: dict[str, torch.Tensor], what: str) -> None:
    """``module.load_state_dict(state)`` with a WeightsMismatchError naming the first offending tensors."""
    own = module.state_dict()
    missing = sorted(set(own) - set(state))
    unexpected = sorted(set(state) - set(own))
    shapes = [f"{k} {tuple(state[k].shape)} != {tuple(own[k].shape)}" for k in sorted(set(own) & set(state))
              if state[k].shape != own[k].shape]
    if missing or unexpected or shapes:
        raise WeightsMismatchError(f"{what} weights do not match its configuration: missing {missing[:4]}, "
                                   f"unexpected {unexpected[:4]}, shapes {shapes[:4]}")
    module.load_state_dict(state)


@dataclasses.dataclass
class Policy:
    """What a policy checkpoint holds: the selector and/or the predictor, and the description."""

    selector: Any  # actaim2.models.selector_base.ModeSelector | None
    predictor: Any  # actaim2.models.predictor.ActionPredictor | None
    meta: dict


def policy_tensors(selector: torch.nn.Module | None, predictor: torch.nn.Module | None) -> dict[str, torch.Tensor]:
    out: dict[str, torch.Tensor] = {}
    for prefix, module in (("selector.", selector), ("predictor.", predictor)):
        if module is not None:
            out.update({prefix + k: v for k, v in module.state_dict().items()})
    return out


def load_policy(stem: str | Path, perception: dict | None = None, device: str | torch.device = "cpu") -> Policy:
    """Build the models the JSON describes and load their weights (eval mode).

    ``perception``: the serving side's :func:`perception_record`; a checkpoint trained with
    another configuration is refused (PerceptionMismatchError).
    """
    from actaim2.models.predictor import ActionPredictor, PredictorConfig
    from actaim2.models.registry import build_selector
    from actaim2.models.selector_base import SelectorConfig

    tensors, meta = read(stem, perception)
    selector = predictor = None
    try:
        if meta.get("selector_config") is not None:
            selector = build_selector(SelectorConfig.from_dict(meta["selector_config"]))
        if meta.get("predictor_config") is not None:
            predictor = ActionPredictor(PredictorConfig.from_json(meta["predictor_config"]))
    except (TypeError, ValueError) as exc:
        raise WeightsMismatchError(f"{paths(stem)[1]} describes a model this code cannot build: {exc}") from exc
    if selector is None and predictor is None:
        raise CorruptCheckpointError(f"{paths(stem)[1]} describes neither a selector nor a predictor")
    for prefix, module in (("selector.", selector), ("predictor.", predictor)):
        if module is not None:
            load_state(module, state_with_prefix(tensors, prefix), prefix[:-1])
            module.to(device).eval()
    return Policy(selector, predictor, meta)
