"""Visual success labels of a stored dataset: measure part motions, calibrate, label, check.

Files written next to the dataset's index:
  motions.jsonl     the moved parts of every trajectory (part_motion.py), measured once per
                    motion configuration and appended as they come (an interrupted labelling resumes)
  encoder.pt        the default encoder E, trained on this dataset's training split (if not given)
  embeddings.npz    ids, task embeddings z = E(O_init) - E(O_final) (float32) and the encoder's digest
  labels.jsonl      {id, score, success} per trajectory (read by DatasetReader as entry["label"])
  labelling.json    the label's model and its accuracy per split and per category, with the
                    measured alternatives

The label (success.py): P(success) from the moved parts' motion, and each part's reach read
off its object's trajectories, by a logistic model calibrated on the calibration split
(default: the training split) against the ground truth; success iff P exceeds the threshold
calibrated there too. The ground truth is read for that calibration and for the report, nowhere else. The
report headlines the splits that were not used for calibration. The task embeddings z are what
the GMM-adaptive sampler clusters and what the models learn from; their size ||z|| is also the
paper's success score, reported as an alternative.
"""
from __future__ import annotations

import hashlib
import json
import multiprocessing as mp
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from actaim2.data.encoder import AUTOENCODER_SPEC, ImageEncoder
from actaim2.data.encoder_training import train_autoencoder
from actaim2.data.part_motion import MotionConfig, PartMotion, part_motions
from actaim2.data.splits import CALIBRATION_SPLITS
from actaim2.data.storage import DatasetReader, write_labels
from actaim2.data.success import (
    DEFAULT_MODEL,
    ReachConfig,
    SuccessModel,
    calibrate_threshold,
    change,
    label_metrics,
    motion_features,
    part_reaches,
)

ENCODER_FILE = "encoder.pt"
EMBEDDINGS_FILE = "embeddings.npz"
MOTIONS_FILE = "motions.jsonl"
REPORT_FILE = "labelling.json"
MIN_CALIBRATION = 5  # moved parts of each outcome the calibration split needs; fewer: the default model


def encoder_digest(path: Path) -> str:
    """16 hex digits of an encoder file: E's identity (its spec, so its input size, and its weights)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


def embeddings_encoder_digest(root: str | Path) -> str | None:
    """The digest of the encoder E that made a dataset's task embeddings (``embeddings.npz``), or None
    when it has none yet: what checkpoints record and fine-tuning compares."""
    path = Path(root) / EMBEDDINGS_FILE
    if not path.exists():
        return None
    with np.load(path) as f:
        return str(f["encoder_digest"]) if "encoder_digest" in f else None


def dataset_encoder(root: str | Path) -> Path | None:
    """The encoder file that made a dataset's task embeddings, or None when none is found.

    Candidates, the first whose digest is the embeddings' wins: the file labelling used
    (``labelling.json``: a user's VGG-19 file or the trained default), the file ``bag2dataset``
    converted with (``dataset.json``), ``<root>/encoder.pt``.
    """
    root = Path(root)
    digest = embeddings_encoder_digest(root)
    if digest is None:
        return None
    candidates = []
    if (root / REPORT_FILE).exists():
        candidates.append(Path(json.loads((root / REPORT_FILE).read_text())["encoder"]))
    if (root / "dataset.json").exists():
        used = json.loads((root / "dataset.json").read_text()).get("encoder")
        if isinstance(used, dict) and used.get("path"):
            candidates.append(Path(used["path"]))
    candidates.append(root / ENCODER_FILE)
    return next((p for p in candidates if p.is_file() and encoder_digest(p) == digest), None)


def fit_default_encoder(reader: DatasetReader, max_trajectories: int = 150, steps: int = 800, seed: int = 0,
                        show_progress: bool = True) -> tuple[ImageEncoder, list[float]]:
    """Train the autoencoder E on O_init and O_final of (up to) ``max_trajectories`` training trajectories."""
    train = sorted((e for e in reader.entries if e["split"] in CALIBRATION_SPLITS),
                   key=lambda e: e["id"])  # independent of append order
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


# -- part motions ---------------------------------------------------------------------------

def motion_digest(config: MotionConfig) -> str:
    return hashlib.sha256(json.dumps(asdict(config), sort_keys=True).encode()).hexdigest()[:16]


_READER: DatasetReader | None = None


def _init_motion_worker(root: str) -> None:
    global _READER
    _READER = DatasetReader(root)


def _measure(args: tuple[str, MotionConfig]) -> tuple[str, list[dict]]:
    tid, config = args
    _, obs = _READER.observations(_READER.by_id[tid], ["init", "final"])
    return tid, [p.to_json() for p in part_motions(obs["init"], obs["final"], config)]


def measure_motions(root: str | Path, config: MotionConfig = MotionConfig(), workers: int = 0,
                    show_progress: bool = True) -> dict[str, list[PartMotion]]:
    """The moved parts of every stored trajectory (motions.jsonl rows of this configuration are reused).

    Rows are appended as they are measured, so an interrupted run keeps what it measured.
    ``workers`` > 0 measures in that many processes (0: in this one).
    """
    root = Path(root)
    digest = motion_digest(config)
    path = root / MOTIONS_FILE
    done: dict[str, list[PartMotion]] = {}
    if path.exists():
        raw = path.read_bytes()
        path.write_bytes(raw[: raw.rfind(b"\n") + 1])  # a line torn by a kill is measured again
        for line in path.read_text().splitlines():
            row = json.loads(line)
            if row["digest"] == digest:
                done[row["id"]] = [PartMotion.from_json(p) for p in row["parts"]]
    reader = DatasetReader(root)
    todo = [e["id"] for e in reader.entries if e["id"] not in done]
    if not todo:
        return done
    bar = tqdm(total=len(todo), desc="part motions", unit="traj", disable=not show_progress)
    with open(path, "a") as f:
        if workers > 0:
            os.environ.setdefault("OMP_NUM_THREADS", "1")
            with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"), initializer=_init_motion_worker,
                                     initargs=(str(root),)) as pool:
                results = pool.map(_measure, [(t, config) for t in todo], chunksize=4)
                for tid, parts in results:
                    f.write(json.dumps({"id": tid, "digest": digest, "parts": parts}) + "\n")
                    f.flush()
                    done[tid] = [PartMotion.from_json(p) for p in parts]
                    bar.update(1)
        else:
            _init_motion_worker(str(root))
            for tid in todo:
                _, parts = _measure((tid, config))
                f.write(json.dumps({"id": tid, "digest": digest, "parts": parts}) + "\n")
                f.flush()
                done[tid] = [PartMotion.from_json(p) for p in parts]
                bar.update(1)
    bar.close()
    return done


# -- the label ------------------------------------------------------------------------------

def object_reaches(entries: list[dict], motions: dict[str, list[PartMotion]], config: ReachConfig = ReachConfig()
                   ) -> list[list[float]]:
    """Each entry's moved parts' reaches (:func:`part_reaches`), read off the given entries of its object."""
    by_object: dict[str, list[int]] = {}
    for k, e in enumerate(entries):
        by_object.setdefault(e["object_id"], []).append(k)
    out: list[list[float]] = [[] for _ in entries]
    for rows in by_object.values():
        for k, reaches in zip(rows, part_reaches([motions[entries[k]["id"]] for k in rows], config)):
            out[k] = reaches
    return out


def _reaches_or_unknown(parts_per_trajectory: list[list[PartMotion]], reaches: list[list[float]] | None) -> list[list[float]]:
    """``reaches`` as given, or every reach unknown (0) when None: a lone trajectory has none."""
    return reaches if reaches is not None else [[0.0] * len(parts) for parts in parts_per_trajectory]


def success_scores(parts_per_trajectory: list[list[PartMotion]], model: SuccessModel,
                   reaches: list[list[float]] | None = None) -> np.ndarray:
    """P(success) of each trajectory: the most likely of its moved parts (0 when nothing moved).

    ``reaches`` as :func:`object_reaches` gives them; None: every reach unknown (a lone trajectory).
    """
    reaches = _reaches_or_unknown(parts_per_trajectory, reaches)
    return np.array([max((model.probability(motion_features(p, r)) for p, r in zip(parts, rs)), default=0.0)
                     for parts, rs in zip(parts_per_trajectory, reaches)])


def calibrate(parts_per_trajectory: list[list[PartMotion]], gt: np.ndarray,
              reaches: list[list[float]] | None = None) -> SuccessModel | None:
    """Fit the success model on trajectories whose outcome says which part it is about.

    A trajectory with one moved part lends it its outcome; in a failed one every moved part
    failed; in a successful one with several moved parts the ground truth does not say which
    part moved far enough, so it is left out. The threshold on P(success) is then the most
    accurate one over all the given trajectories. None when fewer than ``MIN_CALIBRATION``
    parts of either outcome are left (a handful of trajectories calibrates nothing).
    """
    reaches = _reaches_or_unknown(parts_per_trajectory, reaches)
    rows, outcomes = [], []
    for parts, rs, success in zip(parts_per_trajectory, reaches, gt):
        if len(parts) == 1 or (parts and not success):
            rows += [motion_features(p, r) for p, r in zip(parts, rs)]
            outcomes += [bool(success)] * len(parts)
    y = np.array(outcomes, dtype=bool)
    if min(y.sum(), (~y).sum()) < MIN_CALIBRATION:
        return None
    model = SuccessModel.fit(np.array(rows), y)
    return replace(model, threshold=calibrate_threshold(success_scores(parts_per_trajectory, model, reaches), gt))


def visual_labels(entries: list[dict], motions: dict[str, list[PartMotion]],
                  calibration_splits: tuple[str, ...] = CALIBRATION_SPLITS,
                  reaches: list[list[float]] | None = None) -> tuple[np.ndarray, SuccessModel, bool]:
    """(P(success) per entry, the model, whether it was calibrated on ``calibration_splits``).

    ``reaches``: :func:`object_reaches` of the entries (None: read off them here with the default
    :class:`ReachConfig`). Without enough moved trajectories of both outcomes in the calibration
    split the model is :data:`DEFAULT_MODEL`, the calibration measured on the collection in
    docs/data.md.
    """
    parts = [motions[e["id"]] for e in entries]
    reaches = reaches if reaches is not None else object_reaches(entries, motions)
    calib = [k for k, e in enumerate(entries) if e["split"] in calibration_splits]
    if not calib:
        raise ValueError(f"no trajectories in calibration split(s) {list(calibration_splits)} to "
                         f"calibrate the success label on")
    model = calibrate([parts[k] for k in calib], np.array([entries[k]["gt_success"] for k in calib], dtype=bool),
                      [reaches[k] for k in calib])
    return success_scores(parts, model or DEFAULT_MODEL, reaches), model or DEFAULT_MODEL, model is not None


def _report(labels: np.ndarray, gt: np.ndarray, splits: np.ndarray, calib: np.ndarray) -> dict:
    return {
        "per_split": {s: label_metrics(labels[splits == s], gt[splits == s]) for s in sorted(set(splits))},
        "other_splits": label_metrics(labels[~calib], gt[~calib]) if (~calib).any() else None,
    }


def label_dataset(root: str | Path, encoder_path: str | Path,
                  calibration_splits: tuple[str, ...] = CALIBRATION_SPLITS, workers: int = 0,
                  motion_config: MotionConfig = MotionConfig(), reach_config: ReachConfig = ReachConfig(),
                  show_progress: bool = True) -> dict:
    """Measure motions, embed, calibrate on ``calibration_splits``, write labels; returns the
    report."""
    reader = DatasetReader(root)
    if not reader.entries:
        raise ValueError(f"{root} holds no trajectories to label")
    motions = measure_motions(root, motion_config, workers, show_progress)
    encoder = ImageEncoder.load(encoder_path)
    z = embed_dataset(reader, encoder, encoder_digest(encoder_path), show_progress)
    entries = reader.entries
    reaches = object_reaches(entries, motions, reach_config)
    scores, model, calibrated = visual_labels(entries, motions, calibration_splits, reaches)
    labels = scores > model.threshold
    gt = np.array([e["gt_success"] for e in entries], dtype=bool)
    splits = np.array([e["split"] for e in entries])
    calib = np.isin(splits, calibration_splits)
    write_labels(root, [{"id": e["id"], "score": round(float(s), 6), "success": bool(lab)} for e, s, lab in zip(entries, scores, labels)])

    parts = [motions[e["id"]] for e in entries]
    embedding_change = change(np.stack([z[e["id"]] for e in entries]))
    displacement = np.array([max((p.displacement for p in ps), default=0.0) for ps in parts])
    alternatives = {}
    for name, description, values in (  # thresholds need both outcomes in the calibration split
        ("embedding_change", "the paper's: ||E(O_init) - E(O_final)|| / sqrt(dim) > threshold (E: " + encoder.spec.kind + ")",
         embedding_change),
        ("largest_displacement", "depth change: the farthest any vanished point of a moved part was carried > threshold",
         displacement),
    ):
        if gt[calib].all() or not gt[calib].any():
            continue
        threshold = calibrate_threshold(values[calib], gt[calib])
        alternatives[name] = {"description": description, "threshold": threshold, **_report(values > threshold, gt, splits, calib)}
    absolute = calibrate([p for p, c in zip(parts, calib) if c], gt[calib])  # the same model without the reach terms
    if absolute is not None:
        alternatives["without_reach"] = {"description": "the same model with every reach unknown (absolute terms only)",
                                         "threshold": absolute.threshold,
                                         **_report(success_scores(parts, absolute) > absolute.threshold, gt, splits, calib)}
    alternatives["anything_moved"] = {"description": "some part moved (no calibration)",
                                      **_report(np.array([bool(ps) for ps in parts]), gt, splits, calib)}
    categories = np.array([e["category"] for e in entries])
    known = [r > 0 for rs in reaches for r in rs]
    report = {
        "method": "part motion (part_motion.py) + reach per part from its object's trajectories + logistic model (success.py), "
                  "P(success) > calibrated threshold",
        "model": {**model.to_json(), "calibrated_here": calibrated},
        "motion_config": asdict(motion_config),
        "reach_config": asdict(reach_config),
        "parts_with_known_reach": float(np.mean(known)) if known else 0.0,
        "calibration_split": ",".join(s for s in calibration_splits if s in set(splits)),
        **_report(labels, gt, splits, calib),
        "per_category": {c: {"split": str(splits[categories == c][0]), **label_metrics(labels[categories == c], gt[categories == c])}
                         for c in sorted(set(categories))},
        "alternatives": alternatives,
        "encoder": str(encoder_path),
        "encoder_kind": encoder.spec.kind,
        "encoder_digest": encoder_digest(encoder_path),
    }
    (Path(root) / REPORT_FILE).write_text(json.dumps(report, indent=2))
    return report
