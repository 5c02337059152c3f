"""One recipe per object category of the paper, plus the real-robot three-drawer shelf.

Each category has at least four structures (``LAYOUTS``: which parts, how they are jointed,
which handle kinds), and instance ``i`` of a category is built with structure ``i mod n``, so
the seen (0-7) and unseen (8-15) instances, and the 8 held-out ones, each cover every
structure. Within a structure a recipe draws sizes, handle kinds and shapes, joint limits,
friction and colours from a random generator: a (category, instance) pair always yields
the same object (:mod:`.catalog` also redraws an instance that would be a near-duplicate of
an earlier one). Sizes follow the real category where the robot's reach allows and are
scaled down where it does not (doors, windows): docs/simulation.md lists the real and generated
ranges and the placement rule; the recipe records its ``front_distance`` in ``meta.json``.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .model import ObjectModel
from .parts import (
    GAP,
    Builder,
    Grasp,
    Palette,
    add_drawer,
    add_handle,
    add_hinged_panel,
    box,
    cylinder,
    shell,
)

deg = np.pi / 180


def _pick(rng: np.random.Generator, options: list):
    return options[int(rng.integers(len(options)))]


def storage_furniture(rng: np.random.Generator, object_id: str, layout: str) -> ObjectModel:
    """A cabinet: rows of drawers (one or two per row), doors (single or double), drawers over
    doors, or a door beside a column of drawers."""
    pal = Palette.sample(rng)
    b = Builder(object_id, "storage_furniture", {"front_distance": 0.62, "layout": layout})
    w, d = b.dim("width", rng, 0.45, 0.75), b.dim("depth", rng, 0.34, 0.46)
    t = rng.uniform(0.016, 0.022)
    plinth, h = b.dim("plinth", rng, 0.06, 0.14), b.dim("height", rng, 0.45, 0.78)
    x0, x1 = -d / 2, d / 2
    b.base.shapes.append(box((x0 + 0.03, -w / 2 + 0.02, 0.0), (x1, w / 2 - 0.02, plinth), pal.accent))
    shell(b.base, (x0, x1), (-w / 2, w / 2), (plinth, plinth + h), t, pal.body)
    handle = _pick(rng, ["bar", "u_handle", "knob", "edge"])
    top, bottom = plinth + h - t, plinth + t
    if layout == "door_and_drawers":
        split = b.dim("split", rng, -0.1, 0.1) * w
        b.base.shapes.append(box((x0, split - t / 2, bottom), (x1 - t, split + t / 2, top), pal.body))
        door_side = _pick(rng, ["left", "right"])
        ylo, yhi = (split + t / 2, w / 2 - t) if door_side == "left" else (-w / 2 + t, split - t / 2)
        zh = rng.uniform(0.55, 0.8) * (top - bottom) + bottom
        add_hinged_panel(b, "door_0", "base", (ylo - t / 2 + GAP, yhi + t / 2 - GAP, bottom - t / 2 + GAP, top + t / 2 - GAP),
                         x0, rng.uniform(0.016, 0.022), door_side,
                         rng.uniform(75, 95) * deg, _pick(rng, ["bar", "u_handle", "knob", "flush"]), zh, rng, pal)
        dylo, dyhi = (-w / 2 + t, split - t / 2) if door_side == "left" else (split + t / 2, w / 2 - t)
        n = int(rng.integers(2, 4))
        hh = (top - bottom - (n - 1) * t) / n
        for i in range(n):
            z0 = bottom + i * (hh + t)
            if i:
                b.base.shapes.append(box((x0, dylo, z0 - t), (x1 - t, dyhi, z0), pal.body))
            add_drawer(b, f"drawer_{i}", "base", x0, (dylo, dyhi, z0, z0 + hh), t / 2, d - 0.05, handle, rng, pal)
        return b.build()
    if layout == "drawers":
        rows = int(rng.integers(1, 4))
        heights = np.full(rows, (top - bottom - (rows - 1) * t) / rows)
        kinds = ["drawer"] * rows
    elif layout == "doors":
        heights, kinds = np.array([top - bottom]), ["doors"]
    else:  # drawers_over_doors
        hd = b.dim("drawer_height", rng, 0.12, 0.18)
        heights, kinds = np.array([hd, top - bottom - hd - t]), ["drawer", "doors"]
    z = top
    n_drawer = n_door = 0
    for hrow, kind in zip(heights, kinds):
        z0 = z - hrow
        if z < top:
            b.base.shapes.append(box((x0, -w / 2 + t, z), (x1 - t, w / 2 - t, z + t), pal.body))
        if kind == "drawer":
            cols = 2 if (w > 0.6 and rng.random() < 0.4) else 1
            edges = np.linspace(-w / 2 + t, w / 2 - t, cols + 1)
            for c in range(cols):
                ylo, yhi = edges[c] + (t / 2 if c else 0), edges[c + 1] - (t / 2 if c < cols - 1 else 0)
                if c:
                    b.base.shapes.append(box((x0, edges[c] - t / 2, z0), (x1 - t, edges[c] + t / 2, z), pal.body))
                add_drawer(b, f"drawer_{n_drawer}", "base", x0, (ylo, yhi, z0, z), t / 2, d - 0.05, handle, rng, pal)
                n_drawer += 1
        else:
            double = w > 0.5  # one wide door would swing into the robot
            zh = z0 + rng.uniform(0.6, 0.85) * hrow
            if double:  # the free edges meet in the middle: no room there for a hand pinching an edge
                panel_handle = _pick(rng, ["bar", "u_handle", "knob"])
                add_hinged_panel(b, f"door_{n_door}", "base", (GAP, w / 2 - t / 2, z0 - t / 2 + GAP, z + t / 2 - GAP),
                                 x0, 0.018, "left", rng.uniform(75, 95) * deg, panel_handle, zh, rng, pal, inset=0.04)
                add_hinged_panel(b, f"door_{n_door + 1}", "base", (-w / 2 + t / 2, -GAP, z0 - t / 2 + GAP, z + t / 2 - GAP),
                                 x0, 0.018, "right", rng.uniform(75, 95) * deg, panel_handle, zh, rng, pal, inset=0.04)
                n_door += 2
            else:
                add_hinged_panel(b, f"door_{n_door}", "base", (-w / 2 + t / 2, w / 2 - t / 2, z0 - t / 2 + GAP, z + t / 2 - GAP),
                                 x0, 0.018, _pick(rng, ["left", "right"]), rng.uniform(75, 95) * deg,
                                 _pick(rng, ["bar", "u_handle", "knob", "flush"]), zh, rng, pal)
                n_door += 1
        z = z0 - t
    return b.build()


def table(rng: np.random.Generator, object_id: str, layout: str) -> ObjectModel:
    """A table on legs with one drawer or two side by side under its top, a desk with a pedestal
    of drawers on one side, or a table with a cabinet door on one side and a drawer beside it."""
    pal = Palette.sample(rng)
    b = Builder(object_id, "table", {"front_distance": 0.6, "layout": layout})
    w = b.dim("width", rng, 0.75 if layout != "single_drawer" else 0.6, 0.95)
    d = b.dim("depth", rng, 0.42, 0.55)
    ht, tt, leg = b.dim("height", rng, 0.48, 0.62), rng.uniform(0.025, 0.04), rng.uniform(0.035, 0.055)
    hd, t = b.dim("drawer_height", rng, 0.1, 0.15), 0.016
    b.base.shapes.append(box((-d / 2, -w / 2, ht - tt), (d / 2, w / 2, ht), pal.body))
    x0, x1 = -d / 2 + 0.02, d / 2 - 0.02
    handle = _pick(rng, ["bar", "u_handle", "knob"])
    side = _pick(rng, [-1.0, 1.0])  # where a pedestal or cabinet stands (+y: the robot's left)
    legs = [(sx, sy) for sx in (-1, 1) for sy in (-1, 1)]
    if layout in ("pedestal", "cabinet"):
        legs = [(sx, -side) for sx in (-1, 1)]
    for sx, sy in legs:
        cx, cy = sx * (d / 2 - 0.02 - leg / 2), sy * (w / 2 - 0.02 - leg / 2)
        b.base.shapes.append(box((cx - leg / 2, cy - leg / 2, 0.0), (cx + leg / 2, cy + leg / 2, ht - tt), pal.accent))
    z0, z1 = ht - tt - hd, ht - tt

    def drawer_housing(ylo: float, yhi: float, n: int, first: int) -> None:
        """``n`` drawers side by side under the top between ylo and yhi."""
        b.base.shapes.append(box((x0, ylo, z0 - t), (x1, yhi, z0), pal.body))  # housing bottom
        b.base.shapes.append(box((x1 - t, ylo, z0), (x1, yhi, z1), pal.body))  # housing back
        edges = np.linspace(ylo, yhi, n + 1)
        for i in range(n):
            lo, hi = edges[i] + (t / 2 if i else 0.0), edges[i + 1] - (t / 2 if i < n - 1 else 0.0)
            if i:
                b.base.shapes.append(box((x0, edges[i] - t / 2, z0), (x1 - t, edges[i] + t / 2, z1), pal.body))
            add_drawer(b, f"drawer_{first + i}", "base", x0, (lo, hi, z0, z1), t / 2, x1 - x0 - 0.03, handle, rng, pal)

    inner = (-w / 2 + 0.02 + leg, w / 2 - 0.02 - leg)
    if layout in ("single_drawer", "twin_drawers"):
        drawer_housing(*inner, 1 if layout == "single_drawer" else 2, 0)
        return b.build()
    # a carcass from the floor to the top on one side: a pedestal of drawers, or a cabinet with a door
    pw = b.dim("pedestal_width", rng, 0.3, 0.38)
    py0, py1 = (w / 2 - pw, w / 2) if side > 0 else (-w / 2, -w / 2 + pw)
    plinth = rng.uniform(0.05, 0.08)
    b.base.shapes.append(box((x0 + 0.02, py0 + 0.01, 0.0), (x1, py1 - 0.01, plinth), pal.accent))
    shell(b.base, (x0, x1), (py0, py1), (plinth, ht - tt), t, pal.body)
    bottom, top = plinth + t, ht - tt - t
    if layout == "pedestal":
        n = int(rng.integers(2, 4))
        hh = (top - bottom - (n - 1) * t) / n
        for i in range(n):
            zz = bottom + i * (hh + t)
            if i:
                b.base.shapes.append(box((x0, py0 + t, zz - t), (x1 - t, py1 - t, zz), pal.body))
            add_drawer(b, f"drawer_{i}", "base", x0, (py0 + t, py1 - t, zz, zz + hh), t / 2, x1 - x0 - 0.05, handle, rng, pal)
    else:  # cabinet: a door on the carcass, a drawer under the top beside it
        hinge = "left" if side > 0 else "right"  # hinged on the outer side: it opens away from the drawer
        add_hinged_panel(b, "door", "base", (py0 + t / 2 + GAP, py1 - t / 2 - GAP, bottom - t / 2 + GAP, top + t / 2 - GAP),
                         x0, 0.018, hinge, rng.uniform(75, 95) * deg, _pick(rng, ["bar", "u_handle", "knob"]),
                         bottom + rng.uniform(0.6, 0.8) * (top - bottom), rng, pal)
        drawer_housing(*((inner[0], py0) if side > 0 else (py1, inner[1])), 1, 0)
    return b.build()


def door(rng: np.random.Generator, object_id: str, layout: str) -> ObjectModel:
    """A door in its frame, scaled so that the handle is at arm height: a single leaf with a
    lever, a single leaf with a pull (bar, U-handle or recessed lip), a pair of leaves, or a leaf
    sliding sideways in front of the opening."""
    pal = Palette.sample(rng)
    b = Builder(object_id, "door", {"front_distance": 0.7, "layout": layout})
    W = b.dim("width", rng, 0.5, 0.6) if layout == "double" else b.dim("width", rng, 0.34, 0.46)
    H, post, fd = b.dim("height", rng, 0.75, 0.95), rng.uniform(0.04, 0.06), rng.uniform(0.06, 0.09)
    b.base.shapes += [
        box((-fd / 2, -W / 2 - post, 0.0), (fd / 2, -W / 2, H + post), pal.body),
        box((-fd / 2, W / 2, 0.0), (fd / 2, W / 2 + post, H + post), pal.body),
        box((-fd / 2, -W / 2, H), (fd / 2, W / 2, H + post), pal.body),
        box((-fd / 2 - 0.01, -W / 2 - post - 0.05, 0.0), (fd / 2 + 0.01, W / 2 + post + 0.05, 0.012), pal.accent),
    ]
    zh = b.dim("handle_height", rng, 0.42, 0.55)
    leaf = (-W / 2 + GAP, W / 2 - GAP, 0.015, H - GAP)
    if layout == "lever":
        add_hinged_panel(b, "door", "base", leaf, -fd / 2 + 0.035, 0.035, _pick(rng, ["left", "right"]),
                         rng.uniform(70, 90) * deg, "lever", zh, rng, pal, handle_length=rng.uniform(0.1, 0.13))
    elif layout == "pull":
        add_hinged_panel(b, "door", "base", leaf, -fd / 2 + 0.035, 0.035, _pick(rng, ["left", "right"]),
                         rng.uniform(70, 90) * deg, _pick(rng, ["bar", "u_handle", "recessed"]), zh, rng, pal)
    elif layout == "double":
        kind = _pick(rng, ["bar", "knob", "u_handle"])
        for name, panel, hinge in (("door_left", (GAP, W / 2 - GAP), "left"), ("door_right", (-W / 2 + GAP, -GAP), "right")):
            add_hinged_panel(b, name, "base", (*panel, 0.015, H - GAP), -fd / 2 + 0.035, 0.03, hinge,
                             rng.uniform(70, 90) * deg, kind, zh, rng, pal, inset=0.04)
    else:  # sliding: the leaf hangs in front of the frame and slides sideways along it
        direction = _pick(rng, [-1.0, 1.0])
        td = 0.03
        link = b.add_part("door", "prismatic", "base", (-fd / 2 - 0.004, 0.0, 0.015 + (H - 0.015) / 2),
                          (0.0, direction, 0.0), 0.0, W * rng.uniform(0.6, 0.75), "sliding_door", rng)
        hh = (H - 0.015) / 2 - GAP
        link.shapes.append(box((-td, -W / 2 - post / 2, -hh), (0.0, W / 2 + post / 2, hh), pal.panel))
        b.base.shapes.append(box((-fd / 2 - 0.04, -W / 2 - post, H + post), (fd / 2, W / 2 + post, H + post + 0.03), pal.body))
        kind = _pick(rng, ["bar", "u_handle"])
        # on the trailing side: pulled away from it the leaf opens, pushed back it closes
        anchor = (-td, -direction * (W / 2 - 0.05), zh - (0.015 + (H - 0.015) / 2))
        b.add_handle(link, kind, add_handle(link, kind, anchor, (-1, 0, 0), (0, 0, 1), rng, pal.handle))
    return b.build()


def refrigerator(rng: np.random.Generator, object_id: str, layout: str) -> ObjectModel:
    """A fridge body with one door, a freezer door over the fridge door, a fridge door over a
    freezer drawer, or two side-by-side doors."""
    pal = Palette.sample(rng)
    b = Builder(object_id, "refrigerator", {"front_distance": 0.68, "layout": layout})
    w = b.dim("width", rng, 0.48, 0.58) if layout == "side_by_side" else b.dim("width", rng, 0.38, 0.46)
    d, h, plinth = b.dim("depth", rng, 0.4, 0.52), b.dim("height", rng, 0.85, 1.02), rng.uniform(0.04, 0.08)
    b.base.shapes.append(box((-d / 2 + 0.04, -w / 2 + 0.03, 0.0), (d / 2, w / 2 - 0.03, plinth), pal.accent))
    td, x0 = rng.uniform(0.035, 0.05), -d / 2
    hinge = _pick(rng, ["left", "right"])
    door_kind = _pick(rng, ["bar", "u_handle", "recessed"])
    ang = lambda: rng.uniform(75, 95) * deg  # noqa: E731
    bar = lambda: rng.uniform(0.14, 0.26)  # noqa: E731
    if layout == "freezer_drawer":  # an open-front box for the drawer below a solid fridge block
        zs = plinth + b.dim("split", rng, 0.28, 0.36) * (h - plinth)
        t = 0.02
        shell(b.base, (-d / 2, d / 2), (-w / 2, w / 2), (plinth, zs), t, pal.body)
        b.base.shapes.append(box((-d / 2, -w / 2, zs), (d / 2, w / 2, h), pal.body))
        add_hinged_panel(b, "door", "base", (-w / 2, w / 2, zs + GAP, h), x0, td, hinge, ang(), door_kind,
                         min(zs + 0.2, 0.8), rng, pal, handle_length=rng.uniform(0.12, 0.18))
        add_drawer(b, "freezer_drawer", "base", x0, (-w / 2 + t, w / 2 - t, plinth + t, zs - t), t / 2,
                   d - 0.06, _pick(rng, ["bar", "u_handle"]), rng, pal, max_travel=0.3)
        return b.build()
    b.base.shapes.append(box((-d / 2, -w / 2, plinth), (d / 2, w / 2, h), pal.body))
    if layout == "single":
        add_hinged_panel(b, "door", "base", (-w / 2, w / 2, plinth + GAP, h), x0, td, hinge, ang(), door_kind,
                         b.dim("handle_height", rng, 0.55, 0.72), rng, pal, handle_length=bar())
    elif layout == "freezer_top":
        zs = plinth + (h - plinth) * b.dim("split", rng, 0.6, 0.7)
        upper, lower = (zs + GAP, h), (plinth + GAP, zs - GAP)
        add_hinged_panel(b, "door_upper", "base", (-w / 2, w / 2, *upper), x0, td, hinge, ang(), door_kind,
                         min(upper[0] + 0.13, 0.85), rng, pal, handle_length=rng.uniform(0.1, 0.16))
        add_hinged_panel(b, "door_lower", "base", (-w / 2, w / 2, *lower), x0, td, hinge, ang(), door_kind,
                         max(lower[1] - 0.12, 0.3), rng, pal, handle_length=rng.uniform(0.1, 0.16))
    else:  # side_by_side
        zh = b.dim("handle_height", rng, 0.55, 0.7)
        kind = _pick(rng, ["bar", "u_handle"])  # the free edges meet in the middle: no pocket there
        add_hinged_panel(b, "door_left", "base", (GAP, w / 2, plinth + GAP, h), x0, td, "left", ang(), kind, zh, rng, pal,
                         handle_length=bar(), inset=0.045)
        add_hinged_panel(b, "door_right", "base", (-w / 2, -GAP, plinth + GAP, h), x0, td, "right", ang(), kind, zh, rng, pal,
                         handle_length=bar(), inset=0.045)
    return b.build()


def faucet(rng: np.random.Generator, object_id: str, layout: str) -> ObjectModel:
    """A faucet on a counter: a single lever on top, two handles, a lever and a swivelling
    spout, or a lever on the body's side lifted upwards."""
    pal = Palette.sample(rng)
    metal = (0.78, 0.78, 0.8, 1.0) if rng.random() < 0.7 else pal.handle
    b = Builder(object_id, "faucet", {"front_distance": 0.36, "layout": layout})
    cw, cd, ch = b.dim("counter_width", rng, 0.38, 0.55), b.dim("counter_depth", rng, 0.3, 0.38), b.dim("counter_height", rng, 0.22, 0.32)
    b.base.shapes += [box((-cd / 2, -cw / 2, 0.0), (cd / 2, cw / 2, ch), pal.body),
                      box((-cd / 2 + 0.05, -cw / 2 + 0.06, ch - 0.004), (cd / 2 - 0.12, cw / 2 - 0.06, ch + 0.002), pal.accent)]
    xf = cd / 2 - 0.07
    body_r, body_h = rng.uniform(0.022, 0.032), b.dim("body_height", rng, 0.12, 0.2)
    b.base.shapes.append(cylinder((xf, 0.0, ch + body_h / 2), body_r, body_h, "z", metal))
    top = ch + body_h
    spout_z = top - rng.uniform(0.05, 0.07)
    spout_len = b.dim("spout_length", rng, 0.13, 0.18)
    spout_r = rng.uniform(0.009, 0.013)

    def lever(name: str, pivot: tuple[float, float, float], arm: float, axis: float, lower: float, upper: float) -> None:
        link = b.add_part(name, "revolute", "base", pivot, (0.0, 0.0, axis), lower, upper, "lever", rng)
        post = rng.uniform(0.025, 0.035)
        link.shapes.append(cylinder((0.0, 0.0, post / 2), 0.016, post, "z", metal))
        th, tw = rng.uniform(0.012, 0.016), rng.uniform(0.012, 0.016)
        link.shapes.append(box((-arm, -tw / 2, post - th), (0.0, tw / 2, post), metal))
        grasp = ((-arm + 0.018, 0.0, post - th / 2), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))
        b.add_handle(link, "lever", Grasp(*grasp))

    if layout == "two_handles":
        b.base.shapes.append(cylinder((xf - spout_len / 2, 0.0, spout_z), spout_r, spout_len, "x", metal))
        sep = b.dim("separation", rng, 0.09, 0.13)
        arm, up = rng.uniform(0.06, 0.08), rng.uniform(80, 110) * deg
        # each handle swings outwards, away from the spout
        lever("handle_left", (xf, sep, ch), arm, -1.0, 0.0, up)
        lever("handle_right", (xf, -sep, ch), arm, 1.0, 0.0, up)
    elif layout == "side_lever":  # lifted about a horizontal axis: the cartridge's friction holds it against its weight
        b.base.shapes.append(cylinder((xf - spout_len / 2, 0.0, spout_z), spout_r, spout_len, "x", metal))
        side = _pick(rng, [-1.0, 1.0])
        arm = b.dim("arm", rng, 0.06, 0.08)
        link = b.add_part("lever", "revolute", "base", (xf, side * (body_r + 0.011), top - 0.025), (side, 0.0, 0.0),
                          0.0, rng.uniform(40, 55) * deg, "lever", rng)
        link.shapes.append(cylinder((0.0, 0.0, 0.0), 0.012, 0.022, "y", metal))
        th, tw = rng.uniform(0.012, 0.016), rng.uniform(0.012, 0.016)
        link.shapes.append(box((-tw / 2, 0.0 if side > 0 else -arm, -th / 2), (tw / 2, arm if side > 0 else 0.0, th / 2), metal))
        b.add_handle(link, "lever", Grasp((0.0, side * (arm - 0.018), 0.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0)))
    else:
        a = rng.uniform(40, 65) * deg
        arm = b.dim("arm", rng, 0.07, 0.1) if layout == "single_lever" else b.dim("arm", rng, 0.055, 0.065)
        lever("lever", (xf, 0.0, top), arm, 1.0, -a, a)
        if layout == "single_lever":
            b.base.shapes.append(cylinder((xf - spout_len / 2, 0.0, spout_z), spout_r, spout_len, "x", metal))
        else:
            s = rng.uniform(35, 50) * deg
            link = b.add_part("spout", "revolute", "base", (xf, 0.0, spout_z), (0.0, 0.0, 1.0), -s, s, "spout", rng)
            link.shapes.append(cylinder((0.0, 0.0, 0.0), body_r + 0.004, 0.03, "z", metal))
            link.shapes.append(cylinder((-spout_len / 2 - 0.01, 0.0, 0.0), spout_r, spout_len, "x", metal))
            b.add_handle(link, "spout", Grasp((-spout_len + 0.01, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0)))
    return b.build()


def switch(rng: np.random.Generator, object_id: str, layout: str) -> ObjectModel:
    """A switch box on a post with one to three toggles (bistable), one or two sliders (dimmer
    slides), one or two rotary dials, or one or two breaker-style levers (bistable)."""
    pal = Palette.sample(rng)
    n = int(rng.integers(1, 4 if layout == "toggle" else 3))
    b = Builder(object_id, "switch", {"front_distance": 0.5, "layout": layout})
    pitch = b.dim("pitch", rng, 0.05, 0.065) + (0.02 if layout in ("rotary", "breaker") else 0.0)
    w = n * pitch + 0.05
    dp, hz = b.dim("box_depth", rng, 0.07, 0.1), b.dim("height", rng, 0.52, 0.62)
    b.base.shapes += [box((-0.14, -0.14, 0.0), (0.14, 0.14, 0.02), pal.accent),
                      box((-0.025, -0.025, 0.02), (0.025, 0.025, hz - 0.12), pal.accent),
                      box((-dp / 2, -w / 2, hz - 0.12), (dp / 2, w / 2, hz + 0.03), pal.body)]
    plate = (0.93, 0.93, 0.9, 1.0) if rng.random() < 0.6 else pal.panel
    white = (0.9, 0.9, 0.88, 1.0)
    xp = -dp / 2 - 0.008
    b.base.shapes.append(box((xp, -w / 2 + 0.01, hz - 0.11), (-dp / 2, w / 2 - 0.01, hz + 0.02), plate))
    ys = (np.arange(n) - (n - 1) / 2) * pitch
    for i, y in enumerate(ys):
        name = f"{layout}_{i}"
        zc = hz - 0.045
        if layout in ("toggle", "breaker"):
            big = layout == "breaker"
            a = rng.uniform(20, 30) * deg
            bw = 0.022 if big else 0.014
            b.base.shapes.append(box((xp - 0.006, y - bw, zc - 0.02), (xp, y + bw, zc + 0.02), pal.handle))
            link = b.add_part(name, "revolute", "base", (xp - 0.006, y, zc), (0.0, 1.0, 0.0), -a, a,
                              "lever" if big else "toggle", rng)
            L = rng.uniform(0.05, 0.06) if big else rng.uniform(0.03, 0.038)
            s = rng.uniform(0.014, 0.018) if big else rng.uniform(0.009, 0.012)
            width = 0.03 if big else s
            link.shapes.append(box((-L, -width / 2, -s / 2), (0.004, width / 2, s / 2), white))
            b.add_handle(link, layout if not big else "lever", Grasp((-L + 0.01, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)))
        elif layout == "rotary":
            a = rng.uniform(90, 120) * deg
            link = b.add_part(name, "revolute", "base", (xp, y, zc), (-1.0, 0.0, 0.0), -a, a, "knob", rng)
            b.add_handle(link, "knob", add_handle(link, "knob", (0.0, 0.0, 0.0), (-1, 0, 0), (0, 0, 1), rng, white))
        else:
            travel = rng.uniform(0.045, 0.065)
            z0 = hz - 0.095
            b.base.shapes.append(box((xp - 0.003, y - 0.006, z0 - 0.01), (xp, y + 0.006, z0 + travel + 0.01), pal.handle))
            link = b.add_part(name, "prismatic", "base", (xp - 0.003, y, z0), (0.0, 0.0, 1.0), 0.0, travel, "slider", rng)
            link.shapes.append(box((-0.026, -0.009, -0.007), (0.0, 0.009, 0.007), white))
            b.add_handle(link, "slider", Grasp((-0.016, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)))
    return b.build()


def window(rng: np.random.Generator, object_id: str, layout: str) -> ObjectModel:
    """A window on a low wall: a sash sliding sideways or upwards (on balances), or one or two
    casements on friction stays."""
    pal = Palette.sample(rng)
    glass = (0.6, 0.75, 0.85, 1.0)
    b = Builder(object_id, "window", {"front_distance": 0.55, "layout": layout})
    W = b.dim("width", rng, 0.34, 0.42) if layout == "casement" else b.dim("width", rng, 0.45, 0.62)
    H, hw, fr, fd = b.dim("height", rng, 0.36, 0.5), b.dim("sill", rng, 0.22, 0.32), 0.04, 0.08
    b.base.shapes += [
        box((-0.07, -W / 2 - fr, 0.0), (0.07, W / 2 + fr, hw), pal.accent),
        box((-fd / 2, -W / 2 - fr, hw), (fd / 2, W / 2 + fr, hw + fr), pal.body),
        box((-fd / 2, -W / 2 - fr, hw + fr + H), (fd / 2, W / 2 + fr, hw + 2 * fr + H), pal.body),
        box((-fd / 2, -W / 2 - fr, hw + fr), (fd / 2, -W / 2, hw + fr + H), pal.body),
        box((-fd / 2, W / 2, hw + fr), (fd / 2, W / 2 + fr, hw + fr + H), pal.body),
    ]
    z0, z1 = hw + fr, hw + fr + H
    zc = (z0 + z1) / 2
    sash_t, rail = 0.02, 0.03
    if layout in ("horizontal", "vertical"):
        # the sash covers half the opening and slides over the fixed pane behind the other half
        b.base.shapes.append(box((0.0, -W / 2, z0), (0.006, W / 2, z1), glass, "glass"))
        if layout == "horizontal":
            side = _pick(rng, [-1.0, 1.0])
            hy, hz = W / 4 + 0.01, H / 2 - GAP
            xyz, axis, travel = (-0.004, side * (W / 4 - 0.01 + GAP), zc), (0.0, -side, 0.0), W / 2 - 0.06
            anchor, along = (-sash_t, side * (hy - rail / 2), rng.uniform(-0.25, 0.15) * hz), (0, 0, 1)
        else:
            hy, hz = W / 2 - GAP, H / 4 + 0.01
            xyz, axis, travel = (-0.004, 0.0, zc - (H / 4 - 0.01 + GAP)), (0.0, 0.0, 1.0), H / 2 - 0.06
            anchor, along = (-sash_t, 0.0, -(hz - rail / 2)), (0, 1, 0)  # on the bottom rail, as a lift handle
        link = b.add_part("sash_0", "prismatic", "base", xyz, axis, 0.0, travel, "sash", rng)
        link.shapes += [box((-sash_t, -hy, -hz), (0.0, hy, -hz + rail), pal.panel),
                        box((-sash_t, -hy, hz - rail), (0.0, hy, hz), pal.panel),
                        box((-sash_t, -hy, -hz + rail), (0.0, -hy + rail, hz - rail), pal.panel),
                        box((-sash_t, hy - rail, -hz + rail), (0.0, hy, hz - rail), pal.panel),
                        box((-sash_t / 2 - 0.003, -hy + rail, -hz + rail), (-sash_t / 2 + 0.003, hy - rail, hz - rail),
                            glass, "glass")]
        kind = _pick(rng, ["bar", "knob", "u_handle"]) if layout == "horizontal" else _pick(rng, ["bar", "u_handle"])
        g = add_handle(link, kind, anchor, (-1, 0, 0), along, rng, pal.handle, length=rng.uniform(0.08, 0.13))
        b.add_handle(link, kind, g)
    else:
        kind = _pick(rng, ["bar", "knob", "u_handle"])
        zh = zc + rng.uniform(-0.1, 0.1) * H
        if layout == "casement":
            panels = [("sash_0", (-W / 2 + GAP, W / 2 - GAP), _pick(rng, ["left", "right"]))]
        else:
            panels = [("sash_0", (GAP, W / 2 - GAP), "left"), ("sash_1", (-W / 2 + GAP, -GAP), "right")]
        for name, (ylo, yhi), hinge in panels:
            add_hinged_panel(b, name, "base", (ylo, yhi, z0 + GAP, z1 - GAP), -0.005, sash_t, hinge,
                             rng.uniform(70, 90) * deg, kind, zh, rng, pal, semantic="casement", inset=0.04)
    return b.build()


def storage_box(rng: np.random.Generator, object_id: str, layout: str) -> ObjectModel:
    """A low box: a lid hinged at the back (free hinges: it falls shut below its balance point
    and open past it), two such lids side by side over two compartments, a lid hinged on a
    side, or a lid sliding forward in grooves."""
    pal = Palette.sample(rng)
    b = Builder(object_id, "box", {"front_distance": 0.32, "layout": layout})
    w = b.dim("width", rng, 0.34, 0.44) if layout == "twin_lids" else b.dim("width", rng, 0.26, 0.42)
    d, hb = b.dim("depth", rng, 0.18, 0.25), b.dim("height", rng, 0.1, 0.16)
    # low and close to the robot: a lid swinging up about its back edge stays where the hand can follow it
    stand, t = b.dim("stand", rng, 0.0, 0.04), 0.012
    if stand > 0.005:  # a plinth
        b.base.shapes.append(box((-d / 2 + 0.02, -w / 2 + 0.02, 0.0), (d / 2 - 0.02, w / 2 - 0.02, stand), pal.accent))
    shell(b.base, (-d / 2, d / 2), (-w / 2, w / 2), (stand, stand + hb), t, pal.body)
    b.base.shapes.append(box((-d / 2, -w / 2 + t, stand), (-d / 2 + t, w / 2 - t, stand + hb), pal.body))  # front wall
    tl = rng.uniform(0.012, 0.018)
    top = stand + hb
    if layout in ("hinged_lid", "twin_lids"):
        kind = _pick(rng, ["edge", "knob", "flush"])
        overhang = 0.025 if kind == "flush" else 0.004
        spans = [(-w / 2, w / 2)] if layout == "hinged_lid" else [(0.0, w / 2), (-w / 2, 0.0)]
        if layout == "twin_lids":  # a divider between the compartments
            b.base.shapes.append(box((-d / 2 + t, -t / 2, stand + t), (d / 2 - t, t / 2, top), pal.body))
        for k, (y0, y1) in enumerate(spans):
            name = "lid" if layout == "hinged_lid" else f"lid_{k}"
            y0, y1 = y0 - (0.004 if y0 < -w / 2 + 1e-9 else -GAP), y1 + (0.004 if y1 > w / 2 - 1e-9 else -GAP)
            yc = (y0 + y1) / 2
            # stops just past the vertical: the lid rests open leaning back on them, its handle within reach
            lid = b.add_part(name, "revolute", "base", (d / 2, 0.0, top), (0.0, 1.0, 0.0), 0.0, rng.uniform(100, 110) * deg, "lid", rng)
            lid.shapes.append(box((-d - overhang, y0, 0.0), (0.0, y1, tl), pal.panel))
            if kind == "edge":
                g = add_handle(lid, "edge", (-d - 0.004, yc, tl / 2), (-1, 0, 0), (0, 1, 0), rng, pal.handle,
                               length=min(rng.uniform(0.07, 0.12), 0.6 * (y1 - y0)))
            elif kind == "knob":
                skirt = 0.035
                lid.shapes.append(box((-d - 0.004 - 0.008, y0, tl - skirt), (-d - 0.004, y1, tl), pal.panel))
                g = add_handle(lid, "knob", (-d - 0.012, yc, tl - skirt / 2), (-1, 0, 0), (0, 1, 0), rng, pal.handle)
            else:  # the fingers pinch the lid's overhanging front edge
                g = Grasp((-d - overhang + 0.012, yc, tl / 2), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.012, 0.02)
            b.add_handle(lid, kind, g)
    elif layout == "side_lid":  # hinged along one side edge: it lifts sideways
        sy = _pick(rng, [-1.0, 1.0])
        lid = b.add_part("lid", "revolute", "base", (0.0, sy * w / 2, top), (-sy, 0.0, 0.0), 0.0, rng.uniform(100, 110) * deg,
                         "lid", rng)
        lid.shapes.append(box((-d / 2 - 0.004, -w if sy > 0 else 0.0, 0.0), (d / 2 + 0.004, 0.0 if sy > 0 else w, tl), pal.panel))
        kind = _pick(rng, ["u_handle", "knob", "bar"])
        anchor = (-0.02, -sy * (w - 0.05), tl)  # on top, near the free edge
        g = add_handle(lid, kind, anchor, (0, 0, 1), (1, 0, 0), rng, pal.handle, length=rng.uniform(0.08, 0.12))
        b.add_handle(lid, kind, g)
    else:  # sliding_lid: a board in grooves, slid towards the robot
        lid = b.add_part("lid", "prismatic", "base", (0.0, 0.0, top), (-1.0, 0.0, 0.0), 0.0, rng.uniform(0.55, 0.7) * d,
                         "translation_lid", rng)
        lid.shapes.append(box((-d / 2 - 0.01, -w / 2 + t / 2, 0.0), (d / 2 - t, w / 2 - t / 2, tl), pal.panel))
        kind = _pick(rng, ["knob", "u_handle", "bar"])
        g = add_handle(lid, kind, (-d / 2 + 0.035, 0.0, tl), (0, 0, 1), (0, 1, 0), rng, pal.handle, length=rng.uniform(0.08, 0.12))
        b.add_handle(lid, kind, g)
    return b.build()


def safe(rng: np.random.Generator, object_id: str, layout: str) -> ObjectModel:
    """A safe on a stand: a thick door with a knob, a thick door with a lever, bar or recessed
    lip, a pair of doors, or a lid on gas struts (a deposit box)."""
    pal = Palette.sample(rng)
    b = Builder(object_id, "safe", {"front_distance": 0.6, "layout": layout})
    s = b.dim("width", rng, 0.42, 0.5) if layout == "double_door" else b.dim("width", rng, 0.3, 0.42)
    # a deposit box is shallow and stands low: its lid swings up over its back edge, its handle must stay in reach
    d = b.dim("depth", rng, 0.24, 0.3) if layout == "top_lid" else b.dim("depth", rng, 0.3, 0.38)
    stand = b.dim("stand", rng, 0.02, 0.08) if layout == "top_lid" else b.dim("stand", rng, 0.12, 0.22)
    h = s * b.dim("aspect", rng, 0.9, 1.2) if layout != "top_lid" else b.dim("lid_height", rng, 0.25, 0.32)
    b.base.shapes.append(box((-d / 2 + 0.02, -s / 2 + 0.02, 0.0), (d / 2 - 0.02, s / 2 - 0.02, stand), pal.accent))
    td = rng.uniform(0.04, 0.055)
    zh = stand + h * rng.uniform(0.45, 0.6)
    ang = lambda: rng.uniform(75, 95) * deg  # noqa: E731
    if layout == "top_lid":
        t = 0.03
        b.base.shapes.append(box((-d / 2, -s / 2, stand), (d / 2, s / 2, stand + h), pal.body))
        lid = b.add_part("lid", "revolute", "base", (d / 2, 0.0, stand + h), (0.0, 1.0, 0.0), 0.0, rng.uniform(80, 95) * deg,
                         "lid", rng)
        lid.shapes.append(box((-d - 0.004, -s / 2 - 0.004, 0.0), (0.0, s / 2 + 0.004, t), pal.panel))
        kind = _pick(rng, ["u_handle", "bar"])  # on the lid's front face: lifted by a horizontal pull
        g = add_handle(lid, kind, (-d - 0.004, 0.0, t / 2), (-1, 0, 0), (0, 1, 0), rng, pal.handle, length=rng.uniform(0.1, 0.14))
        b.add_handle(lid, kind, g)
        b.params["front_distance"] = 0.4  # the lid swings up and back: closer, so the raised handle stays in reach
        return b.build()
    b.base.shapes.append(box((-d / 2, -s / 2, stand), (d / 2, s / 2, stand + h), pal.body))
    if layout == "double_door":
        kind = _pick(rng, ["knob", "bar"])
        for name, (ylo, yhi), hinge in (("door_left", (GAP, s / 2 - 0.02), "left"), ("door_right", (-s / 2 + 0.02, -GAP), "right")):
            add_hinged_panel(b, name, "base", (ylo, yhi, stand + 0.02, stand + h - 0.02), -d / 2, td, hinge, ang(), kind, zh,
                             rng, pal, inset=0.04)
    else:
        kind = "knob" if layout == "knob_door" else _pick(rng, ["lever", "bar", "recessed"])
        add_hinged_panel(b, "door", "base", (-s / 2 + 0.02, s / 2 - 0.02, stand + 0.02, stand + h - 0.02), -d / 2, td,
                         _pick(rng, ["left", "right"]), ang(), kind, zh, rng, pal, inset=rng.uniform(0.05, 0.07),
                         handle_length=rng.uniform(0.09, 0.12) if kind == "lever" else None)
    return b.build()


def three_drawer_shelf(rng: np.random.Generator, object_id: str, layout: str) -> ObjectModel:
    """The paper's real-robot object: a small shelf with three stacked drawers grasped by their edge."""
    pal = Palette.sample(rng)
    b = Builder(object_id, "three_drawer_shelf", {"front_distance": 0.58, "layout": layout})
    w, d, h = b.dim("width", rng, 0.36, 0.44), b.dim("depth", rng, 0.28, 0.34), b.dim("height", rng, 0.36, 0.44)
    stand, t = b.dim("stand", rng, 0.15, 0.22), 0.015
    b.base.shapes.append(box((-d / 2, -w / 2, 0.0), (d / 2, w / 2, stand), pal.accent))
    shell(b.base, (-d / 2, d / 2), (-w / 2, w / 2), (stand, stand + h), t, pal.body)
    hh = (h - 2 * t - 2 * t) / 3
    for i in range(3):
        z0 = stand + t + i * (hh + t)
        if i:
            b.base.shapes.append(box((-d / 2, -w / 2 + t, z0 - t), (d / 2 - t, w / 2 - t, z0), pal.body))
        add_drawer(b, f"drawer_{i}", "base", -d / 2, (-w / 2 + t, w / 2 - t, z0, z0 + hh), t / 2, d - 0.04, "edge", rng, pal,
                   max_travel=0.2)
    return b.build()


Recipe = Callable[[np.random.Generator, str, str], ObjectModel]
RECIPES: dict[str, Recipe] = {
    "faucet": faucet,
    "table": table,
    "storage_furniture": storage_furniture,
    "door": door,
    "refrigerator": refrigerator,
    "switch": switch,
    "window": window,
    "box": storage_box,
    "safe": safe,
    "three_drawer_shelf": three_drawer_shelf,
}
# The structures of each category: instance i is built with LAYOUTS[category][i % len(...)].
LAYOUTS: dict[str, tuple[str, ...]] = {
    "faucet": ("single_lever", "two_handles", "lever_and_spout", "side_lever"),
    "table": ("single_drawer", "twin_drawers", "pedestal", "cabinet"),
    "storage_furniture": ("drawers", "doors", "drawers_over_doors", "door_and_drawers"),
    "door": ("lever", "pull", "double", "sliding"),
    "refrigerator": ("single", "freezer_top", "freezer_drawer", "side_by_side"),
    "switch": ("toggle", "slider", "rotary", "breaker"),
    "window": ("horizontal", "vertical", "casement", "casement_pair"),
    "box": ("hinged_lid", "twin_lids", "side_lid", "sliding_lid"),
    "safe": ("knob_door", "handle_door", "double_door", "top_lid"),
    "three_drawer_shelf": ("three_drawers",),
}
