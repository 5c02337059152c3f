"""Golden outputs of the committed sim bags (bags/sim_azure_kinect_*): what fusion_node publishes for
each when the bag is played into it, and the tolerances a replay is held to.

    python tests/bags/golden.py write BAG...    # run by scripts/record_golden_bags.sh after recording

The outputs come from :func:`actaim2.perception.bag_views.bag_frames` (the node's steps in-process)
and are stored small: for every frame the header stamp, the unfiltered fused cloud's point count,
centroid and bounds, and per view and channel the mean of the robot-hidden /ortho_views; for
three frames (first, middle, last) the whole views as float16.

Tolerances (the same code on the same input; what may differ is the machine's float arithmetic
and, on a loaded machine, a joint state extrapolated instead of interpolated at a cloud's stamp,
which moves the self-filter's robot by a fraction of a millimetre):
  * fused cloud: point count within 0.5 %, centroid within 1 mm, bounds within one voxel (5 mm);
  * views, every frame: each view/channel mean within 0.002 (values are normalised to about [-1, 1]);
  * views, whole frames: mean absolute difference <= 0.002 and at most 0.5 % of the values off by > 0.02.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

GOLDEN = Path(__file__).resolve().parent / "golden"
ROBOT = "kinova_j2s6s200"  # the robot the bags were recorded with (scripts/record_golden_bags.sh)
PERCEPTION = "azure_kinect"
COUNT_TOLERANCE = 0.005  # relative
CENTROID_TOLERANCE = 0.001  # m
BOUNDS_TOLERANCE = 0.005  # m: one voxel
MEAN_TOLERANCE = 0.002
VALUE_TOLERANCE = 0.02
OFF_FRACTION = 0.005


def summarise(stamp_ns: int, xyz: np.ndarray, views: np.ndarray) -> dict[str, np.ndarray]:
    """The per-frame figures compared for every frame (reference and replay alike)."""
    return {"stamp": np.int64(stamp_ns), "count": np.int64(len(xyz)), "centroid": xyz.mean(axis=0),
            "low": xyz.min(axis=0), "high": xyz.max(axis=0), "view_means": views.mean(axis=(2, 3))}


def reference(bag: Path) -> dict[str, np.ndarray]:
    """The golden arrays of ``bag``, computed in-process."""
    from actaim2.perception.bag_views import bag_frames
    from actaim2.perception.config import load_perception_config
    from actaim2.robots import load_robot_spec

    frames = list(bag_frames(bag, load_perception_config(PERCEPTION), load_robot_spec(ROBOT)))
    if not frames:
        raise ValueError(f"{bag}: no frame fusion_node would publish")
    rows = [summarise(f.stamp_ns, f.fused.xyz, f.views) for f in frames]
    golden = {key: np.stack([r[key] for r in rows]) for key in rows[0]}
    whole = sorted({0, len(frames) // 2, len(frames) - 1})
    golden["whole_stamps"] = golden["stamp"][whole]
    golden["whole_views"] = np.stack([frames[i].views for i in whole]).astype(np.float16)
    return golden


def path_of(bag: Path) -> Path:
    return GOLDEN / f"{Path(bag).name}.npz"


def load(bag: Path) -> dict[str, np.ndarray]:
    with np.load(path_of(bag)) as data:
        return {key: data[key] for key in data.files}


def compare(golden: dict[str, np.ndarray], frames: dict[int, tuple[np.ndarray, np.ndarray]]) -> list[str]:
    """What a replay got wrong: ``frames`` maps a header stamp (ns) to (fused xyz, views)."""
    problems = []
    for i, stamp in enumerate(golden["stamp"]):
        t = f"frame at {stamp / 1e9:.3f} s"
        if int(stamp) not in frames:
            problems.append(f"{t}: not published")
            continue
        got = summarise(int(stamp), *frames[int(stamp)])
        if abs(int(got["count"]) - int(golden["count"][i])) > COUNT_TOLERANCE * golden["count"][i]:
            problems.append(f"{t}: {got['count']} fused points, golden {golden['count'][i]}")
        if np.abs(got["centroid"] - golden["centroid"][i]).max() > CENTROID_TOLERANCE:
            problems.append(f"{t}: fused centroid {got['centroid']}, golden {golden['centroid'][i]}")
        for key in ("low", "high"):
            if np.abs(got[key] - golden[key][i]).max() > BOUNDS_TOLERANCE:
                problems.append(f"{t}: fused bound {key} {got[key]}, golden {golden[key][i]}")
        worst = np.abs(got["view_means"] - golden["view_means"][i]).max()
        if worst > MEAN_TOLERANCE:
            problems.append(f"{t}: a view/channel mean is off by {worst:.4f}")
    for stamp, expected in zip(golden["whole_stamps"], golden["whole_views"].astype(np.float32)):
        if int(stamp) in frames:
            difference = np.abs(frames[int(stamp)][1] - expected)
            off = float((difference > VALUE_TOLERANCE).mean())
            if difference.mean() > MEAN_TOLERANCE or off > OFF_FRACTION:
                problems.append(f"views at {stamp / 1e9:.3f} s: mean |difference| {difference.mean():.4f}, "
                                f"{100 * off:.2f} % of the values off by > {VALUE_TOLERANCE}")
    return problems


def write(bags: list[Path]) -> None:
    GOLDEN.mkdir(exist_ok=True)
    for bag in bags:
        golden = reference(bag)
        np.savez_compressed(path_of(bag), **golden)
        print(f"{path_of(bag)}: {len(golden['stamp'])} frames, {path_of(bag).stat().st_size / 1e3:.0f} kB")


if __name__ == "__main__":
    if len(sys.argv) < 3 or sys.argv[1] != "write":
        raise SystemExit(__doc__)
    write([Path(b) for b in sys.argv[2:]])
