"""Validation of /sample_mode and /predict_keypose requests: every refusal says what was wrong.

A :class:`RequestError` carries the reason that ``policy_node`` puts into ``message`` with
``success=false``; the node keeps serving. Stamps are integer nanoseconds (ROS time), so the
checks need no ROS types.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from actaim2 import keypose

NO_VIEWS = "no views yet"
STALE = "stale observation"


class RequestError(ValueError):
    """A request the policy cannot answer; ``str(error)`` is the reason given to the client."""


def is_transient(message: str) -> bool:
    """Whether a refusal goes away by itself once newer views arrive (a client retries those)."""
    return message.startswith((NO_VIEWS, STALE))


def check_embedding(values: Sequence[float], dim: int) -> np.ndarray:
    """The embedding as float32 (dim,), or a RequestError for a wrong length or non-finite values."""
    eps = np.asarray(values, dtype=np.float32)
    if eps.shape != (dim,):
        raise RequestError(f"embedding has {eps.size} values, the checkpoint's predictor expects {dim} "
                           "(pass the embedding /sample_mode returned)")
    bad = int(np.count_nonzero(~np.isfinite(eps)))
    if bad:
        raise RequestError(f"embedding contains NaN or infinite values ({bad} of {dim})")
    return eps


def check_phase(phase: int) -> int:
    """The requested phase as an int, or a RequestError (the keypose's own phase check)."""
    try:
        return keypose.check_phase(phase)
    except ValueError as exc:
        raise RequestError(str(exc)) from None


def check_cluster(cluster: int, clusters: int) -> int | None:
    """None for -1 (sample from the prior), the cluster for 0..clusters-1, else a RequestError."""
    if int(cluster) == -1:
        return None
    if clusters == 0:
        raise RequestError(f"unknown cluster {cluster}: this mode selector has no discrete clusters; pass -1")
    if not 0 <= int(cluster) < clusters:
        raise RequestError(f"unknown cluster {cluster}: the mode selector has {clusters} clusters (0..{clusters - 1}), "
                           "or -1 to sample one")
    return int(cluster)


def resolve_mode_label(label: str, cluster: int, label_cluster: dict[str, int]) -> int:
    """The cluster a request asks for: ``cluster`` without a mode label, else the label's cluster under the
    checkpoint's map (``label_cluster``); a RequestError for an unknown label or one that disagrees with a
    requested cluster (>= 0)."""
    if not label:
        return int(cluster)
    if label not in label_cluster:
        known = f"it maps {', '.join(sorted(label_cluster))}" if label_cluster else \
            "it maps no mode labels (a checkpoint fine-tuned on labelled demonstrations does)"
        raise RequestError(f"unknown mode label {label!r}: {known}")
    mapped = label_cluster[label]
    if int(cluster) >= 0 and int(cluster) != mapped:
        raise RequestError(f"mode label {label!r} is cluster {mapped}, the request asks for cluster {cluster}: "
                           "pass -1 or that cluster")
    return mapped


def check_fresh(views_stamp_ns: int, not_before_ns: int) -> None:
    """Views stamped before ``not_before`` show the scene before the last motion: refused."""
    if views_stamp_ns < not_before_ns:
        raise RequestError(f"{STALE}: the latest views are stamped {views_stamp_ns / 1e9:.3f} s, "
                           f"before not_before {not_before_ns / 1e9:.3f} s")
