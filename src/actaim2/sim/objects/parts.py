"""Building blocks of generated articulated objects: boards, handles, drawers, hinged panels.

Everything is made of boxes and cylinders so SAPIEN gets exact, cheap collision shapes.
Sizes are chosen for a parallel gripper with ~8 cm opening and ~2 cm finger pads: handle
bars stand 3.5-5 cm off their panel so the fingertips wrap them without touching the panel,
and every grasp closes the fingers along the part's direction of motion where it can
(form closure), so pulling and pushing both hold.

Frames: the object frame has z up and its front towards -x. A part's link frame is placed
by its joint; movable parts open towards the joint's upper limit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .model import RGBA, Handle, Joint, Link, ObjectModel, Shape, Vec3

GAP = 0.002  # clearance between neighbouring panels (m)
# A robot at its home pose keeps its hand within ~0.42 m of its base (Panda's tcp is at 0.31 m):
# a hinged panel, half-open towards the robot, must stay beyond that, so objects with hinged
# panels stand farther away (see Builder.build).
HOME_CLEARANCE = 0.44


def box(lo: Vec3, hi: Vec3, rgba: RGBA) -> Shape:
    """An axis-aligned box from its two corners."""
    lo_, hi_ = np.asarray(lo, float), np.asarray(hi, float)
    return Shape("box", tuple(np.abs(hi_ - lo_)), tuple((lo_ + hi_) / 2), (0.0, 0.0, 0.0), rgba)


def cylinder(center: Vec3, radius: float, length: float, axis: str, rgba: RGBA) -> Shape:
    """A cylinder whose axis is the object-frame ``axis`` ('x', 'y' or 'z')."""
    rpy = {"x": (0.0, np.pi / 2, 0.0), "y": (np.pi / 2, 0.0, 0.0), "z": (0.0, 0.0, 0.0)}[axis]
    return Shape("cylinder", (radius, length, 0.0), tuple(map(float, center)), rpy, rgba)


def axis_name(v: np.ndarray) -> str:
    return "xyz"[int(np.argmax(np.abs(v)))]


@dataclass
class Palette:
    """Colours of one object: body, movable panels, handles, accents."""

    body: RGBA
    panel: RGBA
    handle: RGBA
    accent: RGBA

    @staticmethod
    def sample(rng: np.random.Generator) -> "Palette":
        woods = [(0.55, 0.38, 0.22), (0.72, 0.55, 0.36), (0.4, 0.26, 0.15), (0.85, 0.72, 0.52)]
        plains = [(0.92, 0.92, 0.9), (0.6, 0.62, 0.66), (0.25, 0.27, 0.3), (0.55, 0.7, 0.8), (0.75, 0.82, 0.65), (0.85, 0.6, 0.55)]
        handles = [(0.75, 0.75, 0.78), (0.1, 0.1, 0.1), (0.8, 0.65, 0.3), (0.45, 0.45, 0.5)]
        pool = woods + plains
        body = pool[rng.integers(len(pool))]
        panel = body if rng.random() < 0.5 else pool[rng.integers(len(pool))]
        jitter = lambda c: tuple(float(np.clip(x + rng.normal(0, 0.03), 0, 1)) for x in c) + (1.0,)  # noqa: E731
        return Palette(jitter(body), jitter(panel), jitter(handles[rng.integers(len(handles))]), jitter(pool[rng.integers(len(pool))]))


@dataclass
class Builder:
    """Accumulates links, joints and handles of one object; ``base`` is created up front."""

    object_id: str
    category: str
    params: dict = field(default_factory=dict)
    links: list[Link] = field(default_factory=lambda: [Link("base")])
    joints: list[Joint] = field(default_factory=list)
    handles: list[Handle] = field(default_factory=list)
    reach: float = 0.0  # how far (m) a part reaches towards the robot, beyond the object's front, when half-open

    @property
    def base(self) -> Link:
        return self.links[0]

    def add_part(self, name: str, joint_type: str, parent: str, xyz: Vec3, axis: Vec3, lower: float, upper: float,
                 damping: float, semantic: str, friction: float = 0.0) -> Link:
        link = Link(name)
        self.links.append(link)
        self.joints.append(Joint(f"{name}_joint", joint_type, parent, name, tuple(map(float, xyz)),
                                 tuple(map(float, axis)), float(lower), float(upper), float(damping), float(friction), semantic))
        return link

    def add_handle(self, link: Link, kind: str, grasp: "Grasp") -> None:
        self.handles.append(Handle(link.name, f"{link.name}_joint", kind, tuple(map(float, grasp.position)),
                                   tuple(map(float, grasp.approach)), tuple(map(float, grasp.closing)),
                                   float(grasp.depth), float(grasp.span)))

    def build(self) -> ObjectModel:
        if self.reach > 0.0:
            self.params["front_distance"] = float(max(self.params.get("front_distance", 0.0), HOME_CLEARANCE + self.reach))
        return ObjectModel(self.object_id, self.category, self.links, self.joints, self.handles, self.params)


@dataclass(frozen=True)
class Grasp:
    """Where to grasp a handle, in its link frame (see :class:`actaim2.sim.objects.model.Handle`)."""

    position: Vec3
    approach: Vec3
    closing: Vec3
    depth: float = 0.0
    span: float = 0.0


def add_handle(link: Link, kind: str, anchor: Vec3, normal: Vec3, along: Vec3, rng: np.random.Generator,
               rgba: RGBA, length: float | None = None) -> Grasp:
    """Add a handle's shapes to ``link`` and return where to grasp it.

    ``anchor`` is a point on the panel surface, ``normal`` the panel's outward normal, ``along``
    the direction a bar runs (and the in-surface direction the fingers do *not* close along).
    Kinds: ``bar`` (bar on two standoffs), ``lever`` (bar on one standoff, door-lever style),
    ``knob`` (stem + cap), ``edge`` (a flat lip sticking out of the panel).
    """
    a, n, u = (np.asarray(v, float) for v in (anchor, normal, along))
    approach = -n
    closing = np.cross(approach, u)
    if kind in ("bar", "lever"):
        standoff = rng.uniform(0.035, 0.048)
        thick = rng.uniform(0.012, 0.018)
        bar_len = length if length is not None else rng.uniform(0.09, 0.16)
        centre = a + n * (standoff + thick / 2)
        if kind == "lever":
            centre = centre + u * (bar_len / 2 - 0.012)
            posts = [a]
        else:
            posts = [a + u * (bar_len / 2 - 0.015), a - u * (bar_len / 2 - 0.015)]
        for p in posts:
            link.shapes.append(cylinder(p + n * standoff / 2, 0.0065, standoff, axis_name(n), rgba))
        half = np.abs(u) * bar_len / 2 + np.abs(n) * thick / 2 + np.abs(closing) * thick / 2
        link.shapes.append(box(centre - half, centre + half, rgba))
        return Grasp(tuple(centre), tuple(approach), tuple(closing), standoff + thick / 2, bar_len)
    if kind == "knob":
        stem = rng.uniform(0.022, 0.032)
        cap_r, cap_len = rng.uniform(0.014, 0.02), 0.02
        link.shapes.append(cylinder(a + n * stem / 2, 0.0075, stem, axis_name(n), rgba))
        centre = a + n * (stem + cap_len / 2)
        link.shapes.append(cylinder(centre, cap_r, cap_len, axis_name(n), rgba))
        return Grasp(tuple(centre), tuple(approach), tuple(closing), stem + cap_len / 2, 2 * cap_r)
    if kind == "edge":
        depth, thick = rng.uniform(0.032, 0.04), 0.01
        width = length if length is not None else rng.uniform(0.1, 0.18)
        half = np.abs(u) * width / 2 + np.abs(closing) * thick / 2
        link.shapes.append(box(a - half, a + n * depth + half, rgba))
        return Grasp(tuple(a + n * (depth - 0.014)), tuple(approach), tuple(closing), depth - 0.014, width)
    raise ValueError(f"unknown handle kind {kind!r}")


def shell(link: Link, x: tuple[float, float], y: tuple[float, float], z: tuple[float, float], t: float, rgba: RGBA) -> None:
    """An open-front carcass (back, sides, top, bottom) spanning the given ranges."""
    (x0, x1), (y0, y1), (z0, z1) = x, y, z
    link.shapes += [
        box((x1 - t, y0, z0), (x1, y1, z1), rgba),
        box((x0, y0, z0), (x1 - t, y0 + t, z1), rgba),
        box((x0, y1 - t, z0), (x1 - t, y1, z1), rgba),
        box((x0, y0 + t, z1 - t), (x1 - t, y1 - t, z1), rgba),
        box((x0, y0 + t, z0), (x1 - t, y1 - t, z0 + t), rgba),
    ]


def add_drawer(b: Builder, name: str, parent: str, front_x: float, opening: tuple[float, float, float, float],
               overlap: float, depth: float, handle_kind: str, rng: np.random.Generator, pal: Palette,
               max_travel: float = 0.3) -> Link:
    """A drawer in the clear ``opening`` (y0, y1, z0, z1) of a carcass whose front is at ``front_x``.

    The front panel overlays the carcass by ``overlap`` on each side; the drawer slides along -x.
    """
    y0, y1, z0, z1 = opening
    yc, zc = (y0 + y1) / 2, (z0 + z1) / 2
    W, H = y1 - y0, z1 - z0
    travel = min(depth * rng.uniform(0.7, 0.85), max_travel)
    link = b.add_part(name, "prismatic", parent, (front_x, yc, zc), (-1.0, 0.0, 0.0), 0.0, travel,
                      rng.uniform(2.0, 8.0), "drawer")
    tf, tb, c = rng.uniform(0.016, 0.022), 0.012, 0.004
    hy, hz = W / 2 + overlap - GAP, H / 2 + overlap - GAP
    link.shapes.append(box((-tf, -hy, -hz), (0.0, hy, hz), pal.panel))
    iy, bottom, top = W / 2 - c, -H / 2 + c, H / 2 - c - 0.01
    link.shapes += [
        box((0.0, -iy, bottom), (depth, iy, bottom + tb), pal.body),
        box((0.0, -iy, bottom + tb), (depth, -iy + tb, top), pal.body),
        box((0.0, iy - tb, bottom + tb), (depth, iy, top), pal.body),
        box((depth - tb, -iy + tb, bottom + tb), (depth, iy - tb, top), pal.body),
    ]
    if handle_kind == "edge":
        grasp = add_handle(link, "edge", (-tf, 0.0, hz - 0.005), (-1, 0, 0), (0, 1, 0), rng, pal.handle, length=min(0.16, 1.4 * hy))
    else:
        zh = rng.uniform(-0.15, 0.25) * hz if H > 0.12 else 0.0
        grasp = add_handle(link, handle_kind, (-tf, 0.0, zh), (-1, 0, 0), (0, 1, 0), rng, pal.handle,
                           length=min(rng.uniform(0.09, 0.16), 1.6 * hy))
    b.add_handle(link, handle_kind, grasp)
    return link


def add_hinged_panel(b: Builder, name: str, parent: str, panel: tuple[float, float, float, float], front_x: float,
                     thickness: float, hinge: str, max_angle: float, handle_kind: str, handle_z: float,
                     rng: np.random.Generator, pal: Palette, semantic: str = "door", damping: tuple[float, float] = (0.3, 1.5),
                     handle_length: float | None = None, inset: float | None = None) -> Link:
    """A panel covering ``panel`` = (y0, y1, z0, z1), back face at ``front_x``, hinged on a vertical
    edge (``hinge`` 'left' = +y side as seen by the robot, or 'right') and opening towards -x.

    ``handle_z`` is the handle height in the object frame.
    """
    y0, y1, z0, z1 = panel
    zc = (z0 + z1) / 2
    W = y1 - y0
    if hinge == "left":  # hinge line at y1; panel extends to -y; turning about -z swings it to -x
        xyz, axis, span, free = (front_x, y1, zc), (0.0, 0.0, -1.0), (-W, 0.0), -W
        side = 1.0
    else:
        xyz, axis, span, free = (front_x, y0, zc), (0.0, 0.0, 1.0), (0.0, W), W
        side = -1.0
    link = b.add_part(name, "revolute", parent, xyz, axis, 0.0, max_angle, rng.uniform(*damping), semantic)
    b.reach = max(b.reach, W * np.sin(max_angle / 2))
    h = (z1 - z0) / 2
    link.shapes.append(box((-thickness, span[0], -h), (0.0, span[1], h), pal.panel))
    inset = inset if inset is not None else rng.uniform(0.045, 0.07)
    anchor = (-thickness, free + side * inset, handle_z - zc)
    if handle_kind == "lever":  # lever points from the free edge towards the hinge
        grasp = add_handle(link, "lever", anchor, (-1, 0, 0), (0, side, 0), rng, pal.handle, length=handle_length)
    else:
        grasp = add_handle(link, handle_kind, anchor, (-1, 0, 0), (0, 0, 1), rng, pal.handle, length=handle_length)
    b.add_handle(link, handle_kind, grasp)
    return link
