"""The Data Collection row: collection's GMM-adaptive sampler fitted from a dataset's exploration
stage, then fresh samples of it executed in the simulator like every other row.

The dataset is written through the real storage code; its trajectories are synthetic (pictures
are blanks, actions approach the cabinet front along +x, task embeddings form two clusters for
the successful ones), which is all the GMM fit reads.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from actaim2.data.actions import ActionSequence
from actaim2.data.labelling import EMBEDDINGS_FILE
from actaim2.data.storage import DatasetWriter, encode_trajectory, trajectory_id
from actaim2.data.trajectory import OBSERVATION_NAMES, CameraImage, ObjectState, Trajectory
from actaim2.eval.data_collection import data_collection_samplers
from actaim2.eval.evalset import EvalObject
from actaim2.eval.sources import pseudo_group
from actaim2.eval.tasks import SampleCounts, plan_tasks
from actaim2.eval.worker import EvalWorker, WorkerSetup
from actaim2.perception.config import load_perception_config
from actaim2.robots import load_robot_spec
from actaim2.sim.objects.catalog import object_id

APPROACH_PLUS_X = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # tcp z along world +x
OBJECTS = (("storage_furniture", 0, "train_seen"), ("box", 0, "heldout_category"))


def write_dataset(root: Path, per_object: int = 16) -> None:
    rng = np.random.default_rng(0)
    blank = CameraImage(np.zeros((4, 4, 3), np.uint8), np.ones((4, 4), np.float32), np.eye(3), np.eye(4))
    approach = load_robot_spec("panda").hand.approach_distance
    ids, z = [], []
    with DatasetWriter(root, {"seed": 0, "robot": "panda"}) as writer:
        for category, instance, split in OBJECTS:
            oid = object_id(category, instance)
            for k in range(per_object):
                sampler, index = ("random", "grasp")[k % 2], k // 2
                moved = k % 4 != 3
                y, height = rng.uniform(-0.1, 0.1), rng.uniform(0.3, 0.45)
                action = ActionSequence(np.array([0.40, y, height]), np.array([0.27, y, height]), APPROACH_PLUS_X, approach)
                trajectory = Trajectory(trajectory_id(oid, sampler, index), oid, category, instance, split, sampler, k,
                                        action.keyposes(), {n: {"cam": blank} for n in OBSERVATION_NAMES},
                                        {n: {} for n in OBSERVATION_NAMES},
                                        ObjectState(["joint"], np.zeros(1), np.ones(1), np.full(1, 0.5), np.full(1, 0.9 if moved else 0.5)))
                encoded = encode_trajectory(trajectory)
                encoded.entry.update(index=index, action=[float(v) for v in action.vector()])
                writer.append(encoded)
                ids.append(trajectory.id)
                z.append(rng.normal(0.0, 0.1, 8) + (np.where(np.arange(8) < 4, 3.0, -3.0) * (1 if k % 2 else -1) if moved else 0.0))
    np.savez(root / EMBEDDINGS_FILE, ids=np.array(ids), z=np.stack(z).astype(np.float32), encoder_digest=np.array("synthetic"))


@pytest.mark.timeout(600)
def test_data_collection_row_fits_and_executes(tmp_path) -> None:
    write_dataset(tmp_path / "ds")
    objects = [EvalObject("train_seen", "storage_furniture", 0),
               EvalObject("heldout_category", "box", 0),
               EvalObject("heldout_category", "box", 1)]  # box 1: not collected
    samplers = data_collection_samplers(tmp_path / "ds", objects)
    assert set(samplers) == {"storage_furniture_000", "box_000"}
    assert all(s.n_clusters >= 1 for s in samplers.values())
    perception = load_perception_config("ring5")
    setup = WorkerSetup("panda", "ring5", "raycast", perception.center, perception.half_extent, gmm=samplers)
    worker = EvalWorker(setup)
    obj = EvalObject("train_seen", "storage_furniture", 0)
    tasks = plan_tasks({"data_collection": 0}, [obj], SampleCounts(per_cluster=1, baseline_per_group=1, per_object=0))
    assert [t.slot for t in tasks] == list(range(8))  # one sample per pseudo-cluster
    rows = [worker.run(t) for t in tasks[:2]]
    for task, row in zip(tasks, rows):
        assert "error" not in row, row
        assert (row["group"], row["repetition"]) == pseudo_group(obj.key, task.slot)
        assert not row["note"].startswith("no sample: no sampler")
        if not row["note"].startswith("no sample"):  # its own mode: the GMM cluster the slot drew from
            k = samplers["storage_furniture_000"].n_clusters
            assert (row["gmm_cluster"], row["gmm_clusters"]) == (task.slot % k, k)
    # an object the dataset does not hold has no sampler: the sample fails with the reason (the CLI plans none)
    missing = worker.run(plan_tasks({"data_collection": 0}, [EvalObject("heldout_category", "safe", 0)],
                                    SampleCounts(1, 1, 0))[0])
    assert missing["note"] == "no sample: no sampler for safe_000" and missing["success"] is False
