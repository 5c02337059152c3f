"""Episode videos (``actaim2 evaluate --videos N``): one ActAIM2 episode per cluster on N objects, as animated GIFs.

A film camera (one more :class:`actaim2.sim.cameras.CameraSpec`, looking at robot and object
from the front left, robot visible) is rendered through the simulator's own render path (SAPIEN,
or ray casting without Vulkan) every ``FRAME_PERIOD`` simulated seconds while the keyposes
execute: the episode is :func:`actaim2.eval.episode.run_sample` itself, watched through
``SimEnv.step_observers``, so the video shows exactly what the evaluation executes. Each frame
carries the object, the cluster, the phase under way and the outcome of the episode.

Pillow writes the GIF (a project dependency through matplotlib): it plays in a browser and in
the README without a codec, which an MP4 would need.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from actaim2.eval.episode import run_sample
from actaim2.eval.tasks import EvalTask
from actaim2.keypose import PHASE_NAMES
from actaim2.sim.cameras import CameraSpec, look_at_optical
from actaim2.sim.env import SimEnv

FRAME_PERIOD = 0.1  # s, simulated, between frames
PLAYBACK = 0.1  # s per frame in the GIF: real time
END_HOLD = 1.5  # s the last frame stays on before the GIF loops
FILM_SIZE = (320, 240)  # rendered pixels (width, height)
LABEL_HEIGHT = 30  # px of caption band above each frame (two lines)
SKY = (235, 235, 235)  # pixels that see nothing
_FILM_FOVY = 55.0  # degrees
_FILM_EYE = np.array([-0.1, -1.1, 1.3])  # m, world: left of the robot, above: the object's front and the arm in view
_FILM_TARGET = np.array([0.55, 0.0, 0.4])  # between the robot and the object


def film_camera() -> CameraSpec:
    """The camera the videos are shot with (a world-fixed pinhole, no noise)."""
    width, height = FILM_SIZE
    f = 0.5 * height / np.tan(np.deg2rad(_FILM_FOVY) / 2.0)
    return CameraSpec("film", width, height, f, f, width / 2.0, height / 2.0, 0.05, 10.0,
                      look_at_optical(_FILM_EYE, _FILM_TARGET), "film_optical_frame", "", ())


class Film:
    """Renders the film camera every FRAME_PERIOD of simulated time once started (a step observer)."""

    def __init__(self, env: SimEnv):
        from actaim2.sim.render_path import make_renderer

        if env.render_path is None:
            raise ValueError("episode videos need a SimEnv with a render path (construct it with cameras=...)")
        self.renderer = make_renderer(env.render_path, env.scene, [film_camera()])
        self.frames: list[np.ndarray] = []
        self.phases: list[str] = []
        self.phase = "start"
        self._next = 0.0

    def __call__(self, env: SimEnv) -> None:
        if env.time + 1e-9 >= self._next:
            self.shoot(env)

    def shoot(self, env: SimEnv) -> None:
        frame = self.renderer.render()["film"]
        rgb = frame.rgb.copy()
        rgb[frame.segmentation == 0] = SKY
        self.frames.append(rgb)
        self.phases.append(self.phase)
        self._next = env.time + FRAME_PERIOD

    def restart(self) -> None:
        self.frames, self.phases, self.phase, self._next = [], [], "start", 0.0


class _Filmed:
    """A source whose sample is filmed: the film starts when the sample begins (after the reset)
    and learns each phase when its keypose is asked for, just before it executes."""

    def __init__(self, source, film: Film):
        self.source, self.film = source, film

    def begin(self, scene):
        plan = self.source.begin(scene)
        scene.env.step_observers.append(self.film)
        self.film.shoot(scene.env)
        inner = plan.next

        def next_keypose(phase: int, gripper_closed: bool):
            self.film.phase = PHASE_NAMES[phase]
            return inner(phase, gripper_closed)

        plan.next = next_keypose
        return plan


def outcome_text(record: dict) -> str:
    if record["success"]:
        dof, direction = record["mode"]
        return f"success: {dof} {'opened' if direction > 0 else 'closed'} {record['largest_change']:.0%}"
    return f"failure ({record['largest_change']:.0%} of the range)"


def film_sample(worker, film: Film, task: EvalTask) -> dict:
    """Execute ``task`` with ``worker`` (an :class:`actaim2.eval.worker.EvalWorker`) while filming; the run's record."""
    film.restart()
    try:
        record = run_sample(worker.env, worker.planner, worker.executor, worker.cloud_config,
                            _Filmed(worker.source(task.method), film), task, worker.setup.dof_fraction,
                            worker.setup.velocity_scaling)
    finally:
        if film in worker.env.step_observers:
            worker.env.step_observers.remove(film)
    film.phase = "end"
    film.shoot(worker.env)
    return record


def write_gif(film: Film, captions: tuple[str, str], path: Path) -> None:
    """The film's frames, each under a caption band (line 1, then line 2 with the frame's phase)."""
    from PIL import Image, ImageDraw, ImageFont

    font = ImageFont.load_default(size=11)
    width, height = FILM_SIZE
    images = []
    for rgb, phase in zip(film.frames, film.phases):
        image = Image.new("RGB", (width, height + LABEL_HEIGHT), (255, 255, 255))
        image.paste(Image.fromarray(rgb), (0, LABEL_HEIGHT))
        draw = ImageDraw.Draw(image)
        draw.text((4, 2), captions[0], fill=(0, 0, 0), font=font)
        draw.text((4, 16), f"{phase:<10s} {captions[1]}", fill=(0, 0, 0), font=font)
        images.append(image)
    durations = [int(PLAYBACK * 1000)] * (len(images) - 1) + [int(END_HOLD * 1000)]
    path.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(path, save_all=True, append_images=images[1:], duration=durations, loop=0)


@dataclass(frozen=True)
class Video:
    path: Path
    object: str
    cluster: int
    record: dict  # the filmed run's record (the same sample as the results', re-executed)


def write_videos(worker, tasks: list[EvalTask], records: dict[str, dict], out: Path, objects: int) -> list[Video]:
    """For the first ``objects`` objects with ActAIM2 results: each cluster's first sample, re-executed on film."""
    by_object: dict[str, dict[int, EvalTask]] = {}
    for t in tasks:
        if t.method == "actaim2" and t.key in records:
            by_object.setdefault(t.obj.key, {}).setdefault(t.cluster, t)
    film = Film(worker.env)
    videos = []
    for key, clusters in list(by_object.items())[:objects]:
        for cluster, task in sorted(clusters.items()):
            record = film_sample(worker, film, task)
            path = out / f"{key.replace(':', '_').replace('/', '_')}_cluster{cluster}.gif"
            write_gif(film, (f"{key}  cluster {cluster} of {task.clusters}  (seed {task.reset_seed})",
                             outcome_text(record)), path)
            videos.append(Video(path, key, cluster, record))
    return videos


def video_table(videos: list[Video], out: Path) -> str:
    """The videos section of tables.md: one row per filmed episode, the GIF linked and shown."""
    lines = ["", "## Videos", "",
             f"One ActAIM2 episode per cluster (its first sample, re-executed on film; {FRAME_PERIOD:g} s simulated "
             f"between frames, played at {FRAME_PERIOD / PLAYBACK:g}x):", "",
             "| object | cluster | outcome | phases executed | video |", "|---|---|---|---|---|"]
    for v in videos:
        link = v.path.relative_to(out).as_posix()
        lines.append(f"| {v.object} | {v.cluster} | {outcome_text(v.record)} | {v.record['phases_executed']} | "
                     f"[{v.path.name}]({link}) |")
    lines += [""] + [f"![{v.path.stem}]({v.path.relative_to(out).as_posix()})" for v in videos]
    return "\n".join(lines) + "\n"
