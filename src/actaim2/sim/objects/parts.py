"""Building blocks of generated articulated objects: boards, handles, drawers, hinged panels.

Boards are boxes; handles are real shapes made of separate convex pieces, so every collision
hull is exact and the space a hand needs stays empty: a round bar on two standoffs, a
U-shaped tube (straight legs, bends of convex tube segments, grip), a lever on one post, a
mushroom knob (stem + revolved cap), a lip sticking out of the panel, a recessed lip (a
pocket routed into a thick panel next to its free edge: one finger goes into the pocket, the
other past the edge) and a flush edge without any handle (the fingers pinch the panel's free
edge). Sizes suit a parallel gripper with ~8 cm opening and ~2 cm finger pads: bars stand
3.5-4.8 cm off their panel so fingertips wrap them without touching it.

Every part gets its joint friction, damping and behaviour drawn from the category's row of
:mod:`.physics_table` and its material (hence its mass) from the same module.

Frames: the object frame has z up and its front towards -x. A part's link frame is placed
by its joint; movable parts open towards the joint's upper limit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .model import Handle, Joint, Link, ObjectModel
from .physics_table import HANDLE_MATERIAL, part_material, sample_dynamics
from .shapes import RGBA, Shape, Vec3

GAP = 0.002  # clearance between neighbouring panels (m)
# A robot at its home pose keeps its hand within ~0.42 m of its base (Panda's tcp is at 0.31 m):
# a hinged panel, half-open towards the robot, must stay beyond that, so objects with hinged
# panels stand farther away (see Builder.build).
HOME_CLEARANCE = 0.44
HANDLE_KINDS = ("bar", "u_handle", "lever", "knob", "edge", "recessed", "flush")


def box(lo: Vec3, hi: Vec3, rgba: RGBA, material: str = "") -> Shape:
    """An axis-aligned box from its two corners."""
    lo_, hi_ = np.asarray(lo, float), np.asarray(hi, float)
    return Shape("box", tuple(np.abs(hi_ - lo_)), tuple((lo_ + hi_) / 2), (0.0, 0.0, 0.0), rgba, material)


def cylinder(center: Vec3, radius: float, length: float, axis: str, rgba: RGBA, material: str = "") -> Shape:
    """A cylinder whose axis is the object-frame ``axis`` ('x', 'y' or 'z')."""
    rpy = {"x": (0.0, np.pi / 2, 0.0), "y": (np.pi / 2, 0.0, 0.0), "z": (0.0, 0.0, 0.0)}[axis]
    return Shape("cylinder", (radius, length, 0.0), tuple(map(float, center)), rpy, rgba, material)


def revolved(base: np.ndarray, axis: np.ndarray, profile: list[tuple[float, float]], rgba: RGBA,
             material: str = "", segments: int = 16) -> Shape:
    """A convex mesh piece: the hull of circles of radius r at height h along ``axis`` from ``base``
    for each (h, r) of ``profile`` (a knob cap, one segment of a bent tube)."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    a = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.cos(a)[:, None] * e1 + np.sin(a)[:, None] * e2
    points = np.concatenate([np.asarray(base) + h * axis + r * ring for h, r in profile])
    return Shape("mesh", (0.0, 0.0, 0.0), rgba=rgba, material=material, points=tuple(map(tuple, points)))


def tube(p0: np.ndarray, p1: np.ndarray, radius: float, rgba: RGBA, material: str = "") -> Shape:
    """A straight tube piece between two points (any direction) as a convex mesh."""
    d = np.asarray(p1, float) - np.asarray(p0, float)
    return revolved(np.asarray(p0, float), d, [(0.0, radius), (float(np.linalg.norm(d)), radius)], rgba, material)


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
    """Accumulates links, joints and handles of one object; ``base`` is created up front.

    ``dim`` draws a size and records it, normalised to its range, in ``params["dims"]``:
    with the layout and the parts' kinds it tells two instances apart (catalog's near-duplicate
    rule)."""

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

    def dim(self, name: str, rng: np.random.Generator, lo: float, hi: float) -> float:
        """A size drawn uniformly from [lo, hi], recorded normalised for the near-duplicate rule."""
        value = float(rng.uniform(lo, hi))
        self.params.setdefault("dims", {})[name] = (value - lo) / (hi - lo)
        return value

    def add_part(self, name: str, joint_type: str, parent: str, xyz: Vec3, axis: Vec3, lower: float, upper: float,
                 semantic: str, rng: np.random.Generator) -> Link:
        """A movable part: its joint's friction and damping drawn from the category's table row, its
        material (and so its mass) the table's for this part kind."""
        dynamics = sample_dynamics(self.category, semantic, rng)
        link = Link(name, material=part_material(self.category, semantic).name)
        self.links.append(link)
        self.joints.append(Joint(f"{name}_joint", joint_type, parent, name, tuple(map(float, xyz)), tuple(map(float, axis)),
                                 float(lower), float(upper), float(dynamics.damping), float(dynamics.friction), semantic))
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
    Kinds: ``bar`` (round bar on two standoffs), ``u_handle`` (bent tube), ``lever`` (bar on one
    post, door-lever style), ``knob`` (stem + mushroom cap), ``edge`` (a flat lip sticking out
    of the panel). Recessed lips and flush edges are cut into the panel itself
    (:func:`add_hinged_panel`).
    """
    a, n, u = (np.asarray(v, float) for v in (anchor, normal, along))
    approach = -n
    closing = np.cross(approach, u)
    metal = HANDLE_MATERIAL
    if kind in ("bar", "lever"):
        standoff = rng.uniform(0.035, 0.048)  # clear gap behind the bar
        radius = rng.uniform(0.006, 0.009)
        bar_len = length if length is not None else rng.uniform(0.09, 0.16)
        centre = a + n * (standoff + radius)
        if kind == "lever":
            centre = centre + u * (bar_len / 2 - 0.012)
            posts = [a]
        else:
            posts = [a + u * (bar_len / 2 - 0.015), a - u * (bar_len / 2 - 0.015)]
        for p in posts:
            link.shapes.append(cylinder(p + n * (standoff + radius) / 2, 0.0065, standoff + radius, axis_name(n), rgba, metal))
        link.shapes.append(cylinder(centre, radius, bar_len, axis_name(u), rgba, metal))
        return Grasp(tuple(centre), tuple(approach), tuple(closing), standoff + radius, bar_len)
    if kind == "u_handle":
        standoff = rng.uniform(0.036, 0.046)
        radius = rng.uniform(0.005, 0.007)
        bend = rng.uniform(0.012, 0.018)  # bend radius of the tube's centre line
        grip_len = length if length is not None else rng.uniform(0.1, 0.16)
        h = standoff + radius  # tube centre line above the panel
        for sign in (-1.0, 1.0):
            foot = a + sign * u * grip_len / 2
            link.shapes.append(tube(foot, foot + n * (h - bend), radius, rgba, metal))
            centre_of_bend = foot + n * (h - bend) - sign * u * bend
            angles = np.linspace(0.0, np.pi / 2, 4)
            arc = [centre_of_bend + bend * (np.cos(t) * sign * u + np.sin(t) * n) for t in angles]
            link.shapes += [tube(p0, p1, radius, rgba, metal) for p0, p1 in zip(arc[:-1], arc[1:])]
        centre = a + n * h
        link.shapes.append(cylinder(centre, radius, grip_len - 2 * bend, axis_name(u), rgba, metal))
        return Grasp(tuple(centre), tuple(approach), tuple(closing), h, grip_len + 2 * radius)  # span: out to the legs
    if kind == "knob":
        stem = rng.uniform(0.022, 0.032)
        cap_r, cap_len = rng.uniform(0.014, 0.02), rng.uniform(0.018, 0.024)
        link.shapes.append(cylinder(a + n * stem / 2, 0.0075, stem, axis_name(n), rgba, metal))
        profile = [(0.0, 0.75 * cap_r), (0.3 * cap_len, cap_r), (0.75 * cap_len, cap_r), (cap_len, 0.7 * cap_r)]
        link.shapes.append(revolved(a + n * stem, n, profile, rgba, metal))
        centre = a + n * (stem + cap_len / 2)
        return Grasp(tuple(centre), tuple(approach), tuple(closing), stem + cap_len / 2, 2 * cap_r)
    if kind == "edge":
        depth, thick = rng.uniform(0.032, 0.04), 0.01
        width = length if length is not None else rng.uniform(0.1, 0.18)
        half = np.abs(u) * width / 2 + np.abs(closing) * thick / 2
        link.shapes.append(box(a - half, a + n * depth + half, rgba))
        return Grasp(tuple(a + n * (depth - 0.014)), tuple(approach), tuple(closing), depth - 0.014, width)
    raise ValueError(f"unknown handle kind {kind!r}; kinds are {HANDLE_KINDS}")


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
    link = b.add_part(name, "prismatic", parent, (front_x, yc, zc), (-1.0, 0.0, 0.0), 0.0, travel, "drawer", rng)
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
                           length=min(rng.uniform(0.1, 0.16), 1.6 * hy))
    b.add_handle(link, handle_kind, grasp)
    return link


POCKET_WIDTH = 0.05  # recessed lip: the pocket a finger goes into (m across, ~2.5-3 cm deep)
LIP_WIDTH = 0.018  # recessed lip: the strip between the pocket and the free edge, pinched by the fingers
FLUSH_BITE = 0.012  # flush edge: how far the pads reach over the panel's free edge


def add_hinged_panel(b: Builder, name: str, parent: str, panel: tuple[float, float, float, float], front_x: float,
                     thickness: float, hinge: str, max_angle: float, handle_kind: str, handle_z: float,
                     rng: np.random.Generator, pal: Palette, semantic: str = "door",
                     handle_length: float | None = None, inset: float | None = None) -> Link:
    """A panel covering ``panel`` = (y0, y1, z0, z1), back face at ``front_x``, hinged on a vertical
    edge (``hinge`` 'left' = +y side as seen by the robot, or 'right') and opening towards -x.

    ``handle_z`` is the handle height in the object frame. ``recessed`` cuts a pocket next to
    the free edge (panels >= 3.5 cm thick); ``flush`` has no handle: the grasp pinches the free
    edge across the panel's thickness, the hand coming along the panel towards the hinge.
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
    link = b.add_part(name, "revolute", parent, xyz, axis, 0.0, max_angle, semantic, rng)
    b.reach = max(b.reach, W * np.sin(max_angle / 2))
    h = (z1 - z0) / 2
    zh = handle_z - zc
    t = thickness
    if handle_kind == "recessed":
        if t < 0.035:
            raise ValueError(f"a recessed lip needs a panel >= 35 mm thick, got {t * 1000:.0f} mm")
        pocket_h, pocket_d = rng.uniform(0.12, 0.16), min(0.03, t - 0.008)
        lip_in, pocket_in = free + side * LIP_WIDTH, free + side * (LIP_WIDTH + POCKET_WIDTH)
        # the hinge line is the link's y = 0 on either side
        main, lip, pocket = (sorted((p0, p1)) for p0, p1 in ((pocket_in, 0.0), (free, lip_in), (lip_in, pocket_in)))
        zp0, zp1 = zh - pocket_h / 2, zh + pocket_h / 2
        link.shapes += [
            box((-t, main[0], -h), (0.0, main[1], h), pal.panel),
            box((-t, lip[0], -h), (0.0, lip[1], h), pal.panel),
            box((-t, pocket[0], -h), (0.0, pocket[1], zp0), pal.panel),
            box((-t, pocket[0], zp1), (0.0, pocket[1], h), pal.panel),
            box((-t + pocket_d, pocket[0], zp0), (0.0, pocket[1], zp1), pal.panel),
        ]
        grasp = Grasp((-t + 0.012, free + side * LIP_WIDTH / 2, zh), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), 0.012, pocket_h)
    else:
        link.shapes.append(box((-t, span[0], -h), (0.0, span[1], h), pal.panel))
        if handle_kind == "flush":
            grasp = Grasp((-t / 2, free + side * FLUSH_BITE, zh), (0.0, side, 0.0), (1.0, 0.0, 0.0), FLUSH_BITE, 0.02)
        else:
            inset = inset if inset is not None else rng.uniform(0.045, 0.07)
            anchor = (-t, free + side * inset, zh)
            along = (0, side, 0) if handle_kind == "lever" else (0, 0, 1)  # a lever points from the free edge to the hinge
            grasp = add_handle(link, handle_kind, anchor, (-1, 0, 0), along, rng, pal.handle, length=handle_length)
    b.add_handle(link, handle_kind, grasp)
    return link
