"""What ``actaim2 view`` shows, as a Rerun recording: one step of the ``sample`` timeline per
trajectory, episode or evaluated sample.

Per sample (whatever the record has of it): the cameras' O_init and O_final pictures, the five
orthographic views of both, the fused cloud of O_init in 3-D with the four keyposes drawn over
it as grippers (fingers as far apart as the gripper state, the approach axis, a label), a
summary (outcome, cluster, object, ...) and the pictures the record keeps beside it (an
evaluation run's heatmap and embedding figures). Anything a sample lacks is cleared, so
scrubbing never shows the previous sample's picture as this one's.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from actaim2.keypose import Keypose
from actaim2.perception.ortho_views import VIEWS

TIMELINE = "sample"
OBSERVATIONS = ("O_init", "O_final")
KEYPOSE_COLOURS = ((255, 170, 0), (80, 200, 255), (120, 230, 80), (255, 80, 200))  # INIT, REACH, GRASP, MANIPULATE
POINT_RADIUS = 0.004  # m: one voxel of the fused cloud is 5 mm
MAX_POINTS = 200_000  # per cloud: more adds nothing on screen and weighs down the browser


@dataclass
class Sample:
    name: str
    summary: dict[str, object]  # shown as a list; "success" and "cluster" are also plotted
    keyposes: list[Keypose] = field(default_factory=list)
    cloud: tuple[np.ndarray, np.ndarray | None] | None = None  # fused O_init: xyz (N, 3), rgb (N, 3) uint8
    pictures: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)  # O_init/O_final -> camera -> RGB
    views: dict[str, list[np.ndarray]] = field(default_factory=dict)  # O_init/O_final -> one RGB picture per view
    figures: dict[str, np.ndarray] = field(default_factory=dict)  # name -> RGB picture kept with the record (shared)


def summary_markdown(sample: Sample) -> str:
    rows = "\n".join(f"* **{key}**: {value}" for key, value in sample.summary.items())
    return f"### {sample.name}\n\n{rows}\n"


def gripper_parts(keypose: Keypose) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Boxes (centres (3, 3), half sizes (3, 3), quaternion xyzw) of two fingers and the palm, and
    the approach arrow (origin, vector along the tcp's z) of the gripper at ``keypose``."""
    from actaim2.viz.foxglove_live import FINGER_GAP_CLOSED, FINGER_GAP_OPEN, quaternion_matrix

    gap = FINGER_GAP_CLOSED if keypose.gripper_closed else FINGER_GAP_OPEN
    rotation = quaternion_matrix(keypose.quat_xyzw)
    offsets = np.array([[0.0, -gap / 2, -0.025], [0.0, gap / 2, -0.025], [0.0, 0.0, -0.055]])
    half = np.array([[0.0075, 0.005, 0.025], [0.0075, 0.005, 0.025], [0.01, gap / 2 + 0.01, 0.005]])
    centres = np.asarray(keypose.position, float) + offsets @ rotation.T
    origin = np.asarray(keypose.position, float) + rotation @ np.array([0.0, 0.0, -0.16])
    return centres, half, np.asarray(keypose.quat_xyzw, float), origin, rotation @ np.array([0.0, 0.0, 0.08])


def _keypose_entities(keyposes: list[Keypose]) -> dict[str, object]:
    import rerun as rr

    from actaim2.viz.foxglove_live import keypose_label

    entities: dict[str, object] = {}
    for n, keypose in enumerate(keyposes):
        centres, half, quat, origin, approach = gripper_parts(keypose)
        colour = KEYPOSE_COLOURS[keypose.phase % len(KEYPOSE_COLOURS)]
        entities[f"world/keyposes/{n}/gripper"] = rr.Boxes3D(
            centers=centres, half_sizes=half, quaternions=[rr.Quaternion(xyzw=quat)] * 3, colors=colour, fill_mode="solid")
        entities[f"world/keyposes/{n}/approach"] = rr.Arrows3D(
            origins=[origin], vectors=[approach], colors=colour, radii=0.003, labels=[keypose_label(keypose, str(n))],
            show_labels=True)
    if keyposes:
        entities["world/keyposes/path"] = rr.LineStrips3D([np.array([k.position for k in keyposes])], colors=(200, 200, 200),
                                                          radii=0.0015)
    return entities


def _entities(sample: Sample, rng: np.random.Generator) -> dict[str, object]:
    """Entity path -> what to log there for ``sample`` (its figures apart)."""
    import rerun as rr

    entities: dict[str, object] = {
        "summary": rr.TextDocument(summary_markdown(sample), media_type=rr.MediaType.MARKDOWN)}
    for key in ("success", "cluster"):
        value = sample.summary.get(key)
        if isinstance(value, bool | int | float | np.integer | np.floating):
            entities[f"outcome/{key}"] = rr.Scalars(float(value))
    if sample.cloud is not None:
        xyz, rgb = sample.cloud
        if len(xyz) > MAX_POINTS:
            keep = rng.choice(len(xyz), MAX_POINTS, replace=False)
            xyz, rgb = xyz[keep], None if rgb is None else rgb[keep]
        entities["world/cloud"] = rr.Points3D(xyz, colors=rgb, radii=POINT_RADIUS)
    entities.update(_keypose_entities(sample.keyposes))
    for observation in OBSERVATIONS:
        for camera, picture in sample.pictures.get(observation, {}).items():
            entities[f"pictures/{observation}/{camera}"] = rr.Image(picture)
        for view, picture in zip(VIEWS, sample.views.get(observation, []), strict=False):
            entities[f"views/{observation}/{view}"] = rr.Image(picture)
    return entities


def blueprint(figure_names: list[str]):
    """The 3-D scene beside the summary and plots; pictures, views and figures in tabs below."""
    import rerun.blueprint as rrb

    pictures = [rrb.Spatial2DView(origin=f"pictures/{o}", name=f"{o} cameras") for o in OBSERVATIONS]
    views = [rrb.Spatial2DView(origin=f"views/{o}/{v}", name=f"{o} {v}") for o in OBSERVATIONS for v in VIEWS]
    figures = [rrb.Spatial2DView(origin=f"figures/{name}", name=name) for name in figure_names]
    tabs = [rrb.Grid(*pictures, name="O_init / O_final"), rrb.Grid(*views, grid_columns=len(VIEWS), name="views")]
    if figures:
        tabs.append(rrb.Grid(*figures, name="figures"))
    top = rrb.Horizontal(
        rrb.Spatial3DView(origin="world", name="fused cloud and keyposes"),
        rrb.Vertical(rrb.TextDocumentView(origin="summary", name="sample"),
                     rrb.TimeSeriesView(origin="outcome", name="outcome and cluster")),
        column_shares=[3, 2])
    return rrb.Blueprint(rrb.Vertical(top, rrb.Tabs(*tabs), row_shares=[3, 2]),
                         rrb.TimePanel(state="collapsed", timeline=TIMELINE, play_state="paused"),
                         rrb.SelectionPanel(state="collapsed"), rrb.BlueprintPanel(state="collapsed"))


def write_recording(samples: list[Sample], path: Path, name: str) -> None:
    """Write ``samples`` as an .rrd file with the layout of :func:`blueprint`: each sample's
    entities at its step, and a clear at that step for what the previous sample had and it lacks."""
    import rerun as rr

    if not samples:
        raise ValueError(f"{name}: nothing to show (no trajectory, episode or sample)")
    figure_names = sorted({name for s in samples for name in s.figures})
    rec = rr.RecordingStream(f"actaim2 view {name}")
    rec.save(path, default_blueprint=blueprint(figure_names))
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    rng = np.random.default_rng(0)
    shown: set[str] = set()
    for index, sample in enumerate(samples):
        rec.set_time(TIMELINE, sequence=index)
        entities = _entities(sample, rng)
        figures = {f"figures/{key}" for key in sample.figures}
        # samples of one object share their figures: logged again only when they change
        if index == 0 or sample.figures is not samples[index - 1].figures:
            entities.update({f"figures/{key}": rr.Image(picture) for key, picture in sample.figures.items()})
        for entity in sorted(shown - set(entities) - figures):
            rec.log(entity, rr.Clear(recursive=False))
        for entity, archetype in entities.items():
            rec.log(entity, archetype)
        shown = set(entities) | figures
    rec.flush()
    rec.disconnect()
