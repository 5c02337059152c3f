"""Visual success labels of a stored dataset: embed, calibrate, label, and check against ground truth.

Files written next to the dataset's index:
  encoder.pt        the default encoder E, trained on this dataset's training split (if not given)
  embeddings.npz    ids, task embeddings z (float32) and the digest of the encoder that made them
  labels.jsonl      {id, score, change, success} per trajectory (read by DatasetReader as entry["label"])
  labelling.json    threshold, score definition, and labelling accuracy per split

The threshold is calibrated on the calibration split (default: training split) and the accuracy
against the ground-truth criterion is reported on every split, headlined on the splits that
were not used for calibration.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from actaim2.data.encoder import AUTOENCODER_SPEC, ImageEncoder
from actaim2.data.encoder_training import train_autoencoder
from actaim2.data.splits import TRAIN
from actaim2.data.storage import DatasetReader, write_labels
from actaim2.data.success import OBJECT_PERCENTILE, calibrate_threshold, change, label_metrics, relative_score

ENCODER_FILE = "encoder.pt"
EMBEDDINGS_FILE = "embeddings.npz"
REPORT_FILE = "labelling.json"


def encoder_digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


def fit_default_encoder(reader: DatasetReader, max_trajectories: int = 150, steps: int = 800, seed: int = 0,
                        show_progress: bool = True) -> tuple[ImageEncoder, list[float]]:
    """Train the autoencoder E on O_init and O_final of (up to) ``max_trajectories`` training trajectories."""
    train = sorted((e for e in reader.entries if e["split"] == TRAIN), key=lambda e: e["id"])  # independent of append order
    if not train:
        raise ValueError(f"{reader.root} has no training-split trajectories to train the encoder on")
    rng = np.random.default_rng(seed)
    chosen = [train[i] for i in sorted(rng.choice(len(train), size=min(max_trajectories, len(train)), replace=False))]
    prep = ImageEncoder(AUTOENCODER_SPEC, torch.nn.Identity())  # only its preprocess() is used
    pieces = []
    for entry in tqdm(chosen, desc="encoder pictures", disable=not show_progress):
        _, obs = reader.observations(entry, ["init", "final"])
        pieces += [prep.preprocess([o[c] for c in sorted(o)]) for o in obs.values()]
    bar = tqdm(total=steps, desc="encoder training", disable=not show_progress)

    def progress(step: int, loss: float) -> None:
        bar.update(1)
        bar.set_postfix(loss=f"{loss:.4f}")

    encoder, losses = train_autoencoder(torch.cat(pieces), steps=steps, seed=seed, progress=progress)
    bar.close()
    return encoder, losses


def embed_dataset(reader: DatasetReader, encoder: ImageEncoder, digest: str, show_progress: bool = True) -> dict[str, np.ndarray]:
    """z for every trajectory, reusing embeddings.npz rows made by the same encoder."""
    path = reader.root / EMBEDDINGS_FILE
    cached: dict[str, np.ndarray] = {}
    if path.exists():
        with np.load(path) as f:
            if str(f["encoder_digest"]) == digest:
                cached = dict(zip(f["ids"].tolist(), f["z"]))
    out = {}
    for entry in tqdm(reader.entries, desc="task embeddings", disable=not show_progress):
        if entry["id"] in cached:
            out[entry["id"]] = cached[entry["id"]]
            continue
        _, obs = reader.observations(entry, ["init", "final"])
        init, final = encoder.encode([obs["init"], obs["final"]])
        out[entry["id"]] = (init - final).astype(np.float32)
    ids = list(out)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, ids=np.array(ids), z=np.stack([out[i] for i in ids]) if ids else np.zeros((0, 0), np.float32),
             encoder_digest=np.array(digest))
    tmp.replace(path)
    return out


def visual_labels(entries: list[dict], z: dict[str, np.ndarray], calibration_split: str = TRAIN) -> tuple[np.ndarray, np.ndarray, float]:
    """(relative scores, changes, threshold) of ``entries``, the threshold calibrated on their
    ``calibration_split`` members; the labels are ``scores > threshold``."""
    changes = change(np.stack([z[e["id"]] for e in entries]))
    scores = relative_score(changes, np.array([e["object_id"] for e in entries]))
    calib = np.array([e["split"] == calibration_split for e in entries])
    if not calib.any():
        raise ValueError(f"no trajectories in calibration split {calibration_split!r} to calibrate the success threshold on")
    gt = np.array([e["gt_success"] for e in entries], dtype=bool)
    return scores, changes, calibrate_threshold(scores[calib], gt[calib])


def label_dataset(root: str | Path, encoder_path: str | Path, calibration_split: str = TRAIN, show_progress: bool = True) -> dict:
    """Embed, calibrate the threshold on ``calibration_split``, write labels; returns the report."""
    reader = DatasetReader(root)
    if not reader.entries:
        raise ValueError(f"{root} holds no trajectories to label")
    encoder = ImageEncoder.load(encoder_path)
    z = embed_dataset(reader, encoder, encoder_digest(encoder_path), show_progress)
    scores, changes, threshold = visual_labels(reader.entries, z, calibration_split)
    gt = np.array([e["gt_success"] for e in reader.entries], dtype=bool)
    splits = np.array([e["split"] for e in reader.entries])
    calib = splits == calibration_split

    def metrics(values: np.ndarray, threshold: float) -> dict:
        return {
            "threshold": threshold,
            "per_split": {s: label_metrics(values[splits == s], gt[splits == s], threshold) for s in sorted(set(splits))},
            "other_splits": label_metrics(values[~calib], gt[~calib], threshold) if (~calib).any() else None,
        }

    write_labels(root, [{"id": e["id"], "score": float(s), "change": float(c), "success": bool(s > threshold)}
                        for e, s, c in zip(reader.entries, scores, changes)])
    report = {
        "encoder": str(encoder_path),
        "encoder_kind": encoder.spec.kind,
        "score": f"rms(z) / p{OBJECT_PERCENTILE:g} of rms(z) over the object's trajectories",
        "calibration_split": calibration_split,
        **metrics(scores, threshold),
        # For comparison, the paper's literal criterion: one threshold on the change itself.
        "absolute_change": metrics(changes, calibrate_threshold(changes[calib], gt[calib])),
    }
    (Path(root) / REPORT_FILE).write_text(json.dumps(report, indent=2))
    return report
