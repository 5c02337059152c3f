"""One recipe per object category of the paper, plus the real-robot three-drawer shelf.

Each recipe draws an object's size, layout, handle shapes and placement, joint limits,
damping and colours from a random generator, so an (category, instance) pair always yields
the same object. Sizes are realistic but scaled, as the paper does, so that every handle is
within a Panda's (and a Jaco2's) reach when the object stands ``front_distance`` metres in
front of the robot base. The recipe records that distance in the object's parameters; the
loader reads it from ``meta.json``.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .model import ObjectModel
from .parts import GAP, Builder, Grasp, Palette, add_drawer, add_handle, add_hinged_panel, box, cylinder, shell

deg = np.pi / 180


def _pick(rng: np.random.Generator, options: list):
    return options[int(rng.integers(len(options)))]


def storage_furniture(rng: np.random.Generator, object_id: str) -> ObjectModel:
    """A cabinet: rows of drawers (one or two per row) and/or doors (single or double)."""
    pal = Palette.sample(rng)
    w, d, t = rng.uniform(0.45, 0.75), rng.uniform(0.34, 0.46), rng.uniform(0.016, 0.022)
    plinth, h = rng.uniform(0.06, 0.14), rng.uniform(0.45, 0.78)
    layout = _pick(rng, ["drawers", "drawers", "doors", "drawers_over_doors", "door_and_drawers"])
    b = Builder(object_id, "storage_furniture", {"front_distance": 0.62, "layout": layout})
    x0, x1 = -d / 2, d / 2
    b.base.shapes.append(box((x0 + 0.03, -w / 2 + 0.02, 0.0), (x1, w / 2 - 0.02, plinth), pal.accent))
    shell(b.base, (x0, x1), (-w / 2, w / 2), (plinth, plinth + h), t, pal.body)
    handle = _pick(rng, ["bar", "bar", "knob", "edge"])
    top, bottom = plinth + h - t, plinth + t
    if layout == "drawers":
        rows = int(rng.integers(1, 4))
        heights = np.full(rows, (top - bottom - (rows - 1) * t) / rows)
        kinds = ["drawer"] * rows
    elif layout == "doors":
        heights, kinds = np.array([top - bottom]), ["doors"]
    elif layout == "drawers_over_doors":
        hd = rng.uniform(0.12, 0.18)
        heights, kinds = np.array([hd, top - bottom - hd - t]), ["drawer", "doors"]
    else:  # one door on one side, a column of drawers on the other
        heights, kinds = None, ["door_and_drawers"]
    if kinds == ["door_and_drawers"]:
        split = rng.uniform(-0.1, 0.1) * w
        b.base.shapes.append(box((x0, split - t / 2, bottom), (x1 - t, split + t / 2, top), pal.body))
        door_side = _pick(rng, ["left", "right"])
        ylo, yhi = (split + t / 2, w / 2 - t) if door_side == "left" else (-w / 2 + t, split - t / 2)
        zh = rng.uniform(0.55, 0.8) * (top - bottom) + bottom
        add_hinged_panel(b, "door_0", "base", (ylo - t / 2 + GAP, yhi + t / 2 - GAP, bottom - t / 2 + GAP, top + t / 2 - GAP),
                         x0, rng.uniform(0.016, 0.022), door_side,
                         rng.uniform(75, 95) * deg, _pick(rng, ["bar", "knob"]), zh, rng, pal)
        dylo, dyhi = (-w / 2 + t, split - t / 2) if door_side == "left" else (split + t / 2, w / 2 - t)
        n = int(rng.integers(2, 4))
        hh = (top - bottom - (n - 1) * t) / n
        for i in range(n):
            z0 = bottom + i * (hh + t)
            if i:
                b.base.shapes.append(box((x0, dylo, z0 - t), (x1 - t, dyhi, z0), pal.body))
            add_drawer(b, f"drawer_{i}", "base", x0, (dylo, dyhi, z0, z0 + hh), t / 2, d - 0.05, handle, rng, pal)
        return b.build()
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
            panel_handle = _pick(rng, ["bar", "knob"])
            if double:
                mid = 0.0
                add_hinged_panel(b, f"door_{n_door}", "base", (mid + GAP, w / 2 - t / 2, z0 - t / 2 + GAP, z + t / 2 - GAP),
                                 x0, 0.018, "left", rng.uniform(75, 95) * deg, panel_handle, zh, rng, pal, inset=0.04)
                add_hinged_panel(b, f"door_{n_door + 1}", "base", (-w / 2 + t / 2, mid - GAP, z0 - t / 2 + GAP, z + t / 2 - GAP),
                                 x0, 0.018, "right", rng.uniform(75, 95) * deg, panel_handle, zh, rng, pal, inset=0.04)
                n_door += 2
            else:
                add_hinged_panel(b, f"door_{n_door}", "base", (-w / 2 + t / 2, w / 2 - t / 2, z0 - t / 2 + GAP, z + t / 2 - GAP),
                                 x0, 0.018, _pick(rng, ["left", "right"]), rng.uniform(75, 95) * deg, panel_handle, zh, rng, pal)
                n_door += 1
        z = z0 - t
    return b.build()


def table(rng: np.random.Generator, object_id: str) -> ObjectModel:
    """A table on four legs with one or two drawers under its top."""
    pal = Palette.sample(rng)
    w, d = rng.uniform(0.6, 0.95), rng.uniform(0.42, 0.55)
    ht, tt, leg = rng.uniform(0.48, 0.62), rng.uniform(0.025, 0.04), rng.uniform(0.035, 0.055)
    hd, t = rng.uniform(0.1, 0.15), 0.016
    b = Builder(object_id, "table", {"front_distance": 0.6})
    b.base.shapes.append(box((-d / 2, -w / 2, ht - tt), (d / 2, w / 2, ht), pal.body))
    for sx in (-1, 1):
        for sy in (-1, 1):
            cx, cy = sx * (d / 2 - 0.02 - leg / 2), sy * (w / 2 - 0.02 - leg / 2)
            b.base.shapes.append(box((cx - leg / 2, cy - leg / 2, 0.0), (cx + leg / 2, cy + leg / 2, ht - tt), pal.accent))
    x0, x1 = -d / 2 + 0.02, d / 2 - 0.02
    yl, yr = -w / 2 + 0.02 + leg, w / 2 - 0.02 - leg
    z0, z1 = ht - tt - hd, ht - tt
    b.base.shapes.append(box((x0, yl, z0 - t), (x1, yr, z0), pal.body))  # housing bottom
    b.base.shapes.append(box((x1 - t, yl, z0), (x1, yr, z1), pal.body))  # housing back
    n = 2 if (w > 0.72 and rng.random() < 0.6) else 1
    handle = _pick(rng, ["bar", "bar", "knob"])
    edges = np.linspace(yl, yr, n + 1)
    for i in range(n):
        ylo, yhi = edges[i] + (t / 2 if i else 0.0), edges[i + 1] - (t / 2 if i < n - 1 else 0.0)
        if i:
            b.base.shapes.append(box((x0, edges[i] - t / 2, z0), (x1 - t, edges[i] + t / 2, z1), pal.body))
        add_drawer(b, f"drawer_{i}", "base", x0, (ylo, yhi, z0, z1), t / 2, x1 - x0 - 0.03, handle, rng, pal)
    return b.build()


def door(rng: np.random.Generator, object_id: str) -> ObjectModel:
    """A door in its frame (scaled so that the handle is at arm height), opening towards the robot."""
    pal = Palette.sample(rng)
    W, H, post, fd = rng.uniform(0.34, 0.46), rng.uniform(0.75, 0.95), rng.uniform(0.04, 0.06), rng.uniform(0.06, 0.09)
    b = Builder(object_id, "door", {"front_distance": 0.7})
    b.base.shapes += [
        box((-fd / 2, -W / 2 - post, 0.0), (fd / 2, -W / 2, H + post), pal.body),
        box((-fd / 2, W / 2, 0.0), (fd / 2, W / 2 + post, H + post), pal.body),
        box((-fd / 2, -W / 2, H), (fd / 2, W / 2, H + post), pal.body),
        box((-fd / 2 - 0.01, -W / 2 - post - 0.05, 0.0), (fd / 2 + 0.01, W / 2 + post + 0.05, 0.012), pal.accent),
    ]
    kind = _pick(rng, ["lever", "lever", "bar", "knob"])
    zh = rng.uniform(0.42, 0.55)
    add_hinged_panel(b, "door", "base", (-W / 2 + GAP, W / 2 - GAP, 0.015, H - GAP), -fd / 2 + 0.035,
                     0.035, _pick(rng, ["left", "right"]), rng.uniform(70, 90) * deg, kind, zh, rng, pal,
                     damping=(0.5, 2.0), handle_length=rng.uniform(0.1, 0.13) if kind == "lever" else None)
    return b.build()


def refrigerator(rng: np.random.Generator, object_id: str) -> ObjectModel:
    """A fridge body with one door, a freezer door over (or under) the fridge door, or two side-by-side doors."""
    pal = Palette.sample(rng)
    layout = _pick(rng, ["single", "freezer_top", "freezer_bottom", "side_by_side"])
    w = rng.uniform(0.48, 0.58) if layout == "side_by_side" else rng.uniform(0.38, 0.46)
    d, h, plinth = rng.uniform(0.4, 0.52), rng.uniform(0.85, 1.02), rng.uniform(0.04, 0.08)
    b = Builder(object_id, "refrigerator", {"front_distance": 0.68, "layout": layout})
    b.base.shapes += [box((-d / 2 + 0.04, -w / 2 + 0.03, 0.0), (d / 2, w / 2 - 0.03, plinth), pal.accent),
                      box((-d / 2, -w / 2, plinth), (d / 2, w / 2, h), pal.body)]
    td, x0 = rng.uniform(0.035, 0.05), -d / 2
    hinge = _pick(rng, ["left", "right"])
    ang = lambda: rng.uniform(75, 95) * deg  # noqa: E731
    bar = lambda: rng.uniform(0.14, 0.26)  # noqa: E731
    if layout == "single":
        add_hinged_panel(b, "door", "base", (-w / 2, w / 2, plinth + GAP, h), x0, td, hinge, ang(), "bar",
                         rng.uniform(0.55, 0.72), rng, pal, handle_length=bar())
    elif layout in ("freezer_top", "freezer_bottom"):
        zs = plinth + (h - plinth) * (rng.uniform(0.6, 0.7) if layout == "freezer_top" else rng.uniform(0.35, 0.45))
        upper, lower = (zs + GAP, h), (plinth + GAP, zs - GAP)
        add_hinged_panel(b, "door_upper", "base", (-w / 2, w / 2, *upper), x0, td, hinge, ang(), "bar",
                         min(upper[0] + 0.13, 0.85), rng, pal, handle_length=rng.uniform(0.1, 0.16))
        add_hinged_panel(b, "door_lower", "base", (-w / 2, w / 2, *lower), x0, td, hinge, ang(), "bar",
                         max(lower[1] - 0.12, 0.3), rng, pal, handle_length=rng.uniform(0.1, 0.16))
    else:
        zh = rng.uniform(0.55, 0.7)
        add_hinged_panel(b, "door_left", "base", (GAP, w / 2, plinth + GAP, h), x0, td, "left", ang(), "bar", zh, rng, pal,
                         handle_length=bar(), inset=0.045)
        add_hinged_panel(b, "door_right", "base", (-w / 2, -GAP, plinth + GAP, h), x0, td, "right", ang(), "bar", zh, rng, pal,
                         handle_length=bar(), inset=0.045)
    return b.build()


def faucet(rng: np.random.Generator, object_id: str) -> ObjectModel:
    """A faucet on a counter: a single lever, two handles, or a lever and a swivelling spout."""
    pal = Palette.sample(rng)
    metal = (0.78, 0.78, 0.8, 1.0) if rng.random() < 0.7 else pal.handle
    cw, cd, ch = rng.uniform(0.38, 0.55), rng.uniform(0.3, 0.38), rng.uniform(0.22, 0.32)
    layout = _pick(rng, ["single_lever", "two_handles", "lever_and_spout"])
    b = Builder(object_id, "faucet", {"front_distance": 0.36, "layout": layout})
    b.base.shapes += [box((-cd / 2, -cw / 2, 0.0), (cd / 2, cw / 2, ch), pal.body),
                      box((-cd / 2 + 0.05, -cw / 2 + 0.06, ch - 0.004), (cd / 2 - 0.12, cw / 2 - 0.06, ch + 0.002), pal.accent)]
    xf = cd / 2 - 0.07
    body_r, body_h = rng.uniform(0.022, 0.032), rng.uniform(0.12, 0.2)
    b.base.shapes.append(cylinder((xf, 0.0, ch + body_h / 2), body_r, body_h, "z", metal))
    top = ch + body_h
    spout_z = top - rng.uniform(0.05, 0.07)
    spout_len = rng.uniform(0.13, 0.18)
    spout_r = rng.uniform(0.009, 0.013)

    def lever(name: str, pivot: tuple[float, float, float], arm: float, axis: float, lower: float, upper: float) -> None:
        link = b.add_part(name, "revolute", "base", pivot, (0.0, 0.0, axis), lower, upper, rng.uniform(0.02, 0.08), "lever")
        post = rng.uniform(0.025, 0.035)
        link.shapes.append(cylinder((0.0, 0.0, post / 2), 0.016, post, "z", metal))
        th, tw = rng.uniform(0.012, 0.016), rng.uniform(0.012, 0.016)
        link.shapes.append(box((-arm, -tw / 2, post - th), (0.0, tw / 2, post), metal))
        grasp = ((-arm + 0.018, 0.0, post - th / 2), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))
        b.add_handle(link, "lever", Grasp(*grasp))

    if layout == "two_handles":
        b.base.shapes.append(cylinder((xf - spout_len / 2, 0.0, spout_z), spout_r, spout_len, "x", metal))
        sep = rng.uniform(0.09, 0.13)
        arm, up = rng.uniform(0.06, 0.08), rng.uniform(80, 110) * deg
        # each handle swings outwards, away from the spout
        lever("handle_left", (xf, sep, ch), arm, -1.0, 0.0, up)
        lever("handle_right", (xf, -sep, ch), arm, 1.0, 0.0, up)
    else:
        a = rng.uniform(40, 65) * deg
        arm = rng.uniform(0.07, 0.1) if layout == "single_lever" else rng.uniform(0.055, 0.065)
        lever("lever", (xf, 0.0, top), arm, 1.0, -a, a)
        if layout == "single_lever":
            b.base.shapes.append(cylinder((xf - spout_len / 2, 0.0, spout_z), spout_r, spout_len, "x", metal))
        else:
            s = rng.uniform(35, 50) * deg
            link = b.add_part("spout", "revolute", "base", (xf, 0.0, spout_z), (0.0, 0.0, 1.0), -s, s, rng.uniform(0.02, 0.08), "spout")
            link.shapes.append(cylinder((0.0, 0.0, 0.0), body_r + 0.004, 0.03, "z", metal))
            link.shapes.append(cylinder((-spout_len / 2 - 0.01, 0.0, 0.0), spout_r, spout_len, "x", metal))
            b.add_handle(link, "spout", Grasp((-spout_len + 0.01, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0)))
    return b.build()


def switch(rng: np.random.Generator, object_id: str) -> ObjectModel:
    """A switch box on a post with one to three toggles (revolute) or sliders (prismatic)."""
    pal = Palette.sample(rng)
    kind = _pick(rng, ["toggle", "toggle", "slider"])
    n = int(rng.integers(1, 4 if kind == "toggle" else 3))
    pitch = rng.uniform(0.05, 0.065)
    w = n * pitch + 0.05
    dp, hz = rng.uniform(0.07, 0.1), rng.uniform(0.52, 0.62)
    b = Builder(object_id, "switch", {"front_distance": 0.5, "kind": kind})
    b.base.shapes += [box((-0.14, -0.14, 0.0), (0.14, 0.14, 0.02), pal.accent),
                      box((-0.025, -0.025, 0.02), (0.025, 0.025, hz - 0.12), pal.accent),
                      box((-dp / 2, -w / 2, hz - 0.12), (dp / 2, w / 2, hz + 0.03), pal.body)]
    plate = (0.93, 0.93, 0.9, 1.0) if rng.random() < 0.6 else pal.panel
    xp = -dp / 2 - 0.008
    b.base.shapes.append(box((xp, -w / 2 + 0.01, hz - 0.11), (-dp / 2, w / 2 - 0.01, hz + 0.02), plate))
    ys = (np.arange(n) - (n - 1) / 2) * pitch
    for i, y in enumerate(ys):
        name = f"{kind}_{i}"
        if kind == "toggle":
            a = rng.uniform(20, 30) * deg
            zc = hz - 0.045
            b.base.shapes.append(box((xp - 0.006, y - 0.014, zc - 0.02), (xp, y + 0.014, zc + 0.02), pal.handle))
            link = b.add_part(name, "revolute", "base", (xp - 0.006, y, zc), (0.0, 1.0, 0.0), -a, a, rng.uniform(0.005, 0.02), "toggle")
            L, s = rng.uniform(0.03, 0.038), rng.uniform(0.009, 0.012)
            link.shapes.append(box((-L, -s / 2, -s / 2), (0.004, s / 2, s / 2), (0.9, 0.9, 0.88, 1.0)))
            b.add_handle(link, "toggle", Grasp((-L + 0.01, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)))
        else:
            travel = rng.uniform(0.045, 0.065)
            z0 = hz - 0.095
            b.base.shapes.append(box((xp - 0.003, y - 0.006, z0 - 0.01), (xp, y + 0.006, z0 + travel + 0.01), pal.handle))
            link = b.add_part(name, "prismatic", "base", (xp - 0.003, y, z0), (0.0, 0.0, 1.0), 0.0, travel, rng.uniform(1.0, 3.0), "slider")
            link.shapes.append(box((-0.026, -0.009, -0.007), (0.0, 0.009, 0.007), (0.9, 0.9, 0.88, 1.0)))
            b.add_handle(link, "slider", Grasp((-0.016, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)))
    return b.build()


def window(rng: np.random.Generator, object_id: str) -> ObjectModel:
    """A window on a low wall: a sash sliding sideways or upwards, or one or two casements."""
    pal = Palette.sample(rng)
    glass = (0.6, 0.75, 0.85, 1.0)
    layout = _pick(rng, ["horizontal", "vertical", "casement", "casement_pair"])
    W = rng.uniform(0.34, 0.42) if layout == "casement" else rng.uniform(0.45, 0.62)
    H, hw, fr, fd = rng.uniform(0.36, 0.5), rng.uniform(0.22, 0.32), 0.04, 0.08
    b = Builder(object_id, "window", {"front_distance": 0.55, "layout": layout})
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
        b.base.shapes.append(box((0.0, -W / 2, z0), (0.006, W / 2, z1), glass))
        if layout == "horizontal":
            side = _pick(rng, [-1.0, 1.0])
            hy, hz = W / 4 + 0.01, H / 2 - GAP
            xyz, axis, travel = (-0.004, side * (W / 4 - 0.01 + GAP), zc), (0.0, -side, 0.0), W / 2 - 0.06
            anchor, along = (-sash_t, side * (hy - rail / 2), rng.uniform(-0.25, 0.15) * hz), (0, 0, 1)
        else:
            hy, hz = W / 2 - GAP, H / 4 + 0.01
            xyz, axis, travel = (-0.004, 0.0, zc - (H / 4 - 0.01 + GAP)), (0.0, 0.0, 1.0), H / 2 - 0.06
            anchor, along = (-sash_t, 0.0, -(hz - rail / 2)), (0, 1, 0)  # on the bottom rail, as a lift handle
        link = b.add_part("sash_0", "prismatic", "base", xyz, axis, 0.0, travel, rng.uniform(2.0, 6.0), "sash")
        link.shapes += [box((-sash_t, -hy, -hz), (0.0, hy, -hz + rail), pal.panel),
                        box((-sash_t, -hy, hz - rail), (0.0, hy, hz), pal.panel),
                        box((-sash_t, -hy, -hz + rail), (0.0, -hy + rail, hz - rail), pal.panel),
                        box((-sash_t, hy - rail, -hz + rail), (0.0, hy, hz - rail), pal.panel),
                        box((-sash_t / 2 - 0.003, -hy + rail, -hz + rail), (-sash_t / 2 + 0.003, hy - rail, hz - rail), glass)]
        kind = _pick(rng, ["bar", "knob"]) if layout == "horizontal" else "bar"
        g = add_handle(link, kind, anchor, (-1, 0, 0), along, rng, pal.handle, length=rng.uniform(0.08, 0.13))
        b.add_handle(link, kind, g)
    else:
        kind = _pick(rng, ["bar", "knob"])
        zh = zc + rng.uniform(-0.1, 0.1) * H
        if layout == "casement":
            panels = [("sash_0", (-W / 2 + GAP, W / 2 - GAP), _pick(rng, ["left", "right"]))]
        else:
            panels = [("sash_0", (GAP, W / 2 - GAP), "left"), ("sash_1", (-W / 2 + GAP, -GAP), "right")]
        for name, (ylo, yhi), hinge in panels:
            add_hinged_panel(b, name, "base", (ylo, yhi, z0 + GAP, z1 - GAP), -0.005, sash_t, hinge,
                             rng.uniform(70, 90) * deg, kind, zh, rng, pal, semantic="sash", inset=0.04)
    return b.build()


def storage_box(rng: np.random.Generator, object_id: str) -> ObjectModel:
    """A box on a stand with a lid hinged at the back, lifted by a tab or a knob on its front."""
    pal = Palette.sample(rng)
    w, d, hb, stand, t = rng.uniform(0.26, 0.42), rng.uniform(0.18, 0.25), rng.uniform(0.1, 0.16), rng.uniform(0.1, 0.18), 0.012
    b = Builder(object_id, "box", {"front_distance": 0.38})
    b.base.shapes.append(box((-d / 2 + 0.02, -w / 2 + 0.02, 0.0), (d / 2 - 0.02, w / 2 - 0.02, stand), pal.accent))
    shell(b.base, (-d / 2, d / 2), (-w / 2, w / 2), (stand, stand + hb), t, pal.body)
    b.base.shapes.append(box((-d / 2, -w / 2 + t, stand), (-d / 2 + t, w / 2 - t, stand + hb), pal.body))  # front wall
    tl = rng.uniform(0.012, 0.018)
    lid = b.add_part("lid", "revolute", "base", (d / 2, 0.0, stand + hb), (0.0, 1.0, 0.0), 0.0, rng.uniform(85, 105) * deg,
                     rng.uniform(0.05, 0.3), "lid")
    lid.shapes.append(box((-d - 0.004, -w / 2 - 0.004, 0.0), (0.0, w / 2 + 0.004, tl), pal.panel))
    kind = _pick(rng, ["edge", "knob"])
    if kind == "edge":
        g = add_handle(lid, "edge", (-d - 0.004, 0.0, tl / 2), (-1, 0, 0), (0, 1, 0), rng, pal.handle, length=rng.uniform(0.07, 0.12))
    else:
        skirt = 0.035
        lid.shapes.append(box((-d - 0.004 - 0.008, -w / 2 - 0.004, tl - skirt), (-d - 0.004, w / 2 + 0.004, tl), pal.panel))
        g = add_handle(lid, "knob", (-d - 0.012, 0.0, tl - skirt / 2), (-1, 0, 0), (0, 1, 0), rng, pal.handle)
    b.add_handle(lid, kind, g)
    return b.build()


def safe(rng: np.random.Generator, object_id: str) -> ObjectModel:
    """A safe on a stand: a heavy body and a thick door opened by its knob."""
    pal = Palette.sample(rng)
    s, d, stand = rng.uniform(0.3, 0.42), rng.uniform(0.3, 0.38), rng.uniform(0.12, 0.22)
    h = s * rng.uniform(0.9, 1.2)
    b = Builder(object_id, "safe", {"front_distance": 0.6})
    b.base.shapes += [box((-d / 2 + 0.02, -s / 2 + 0.02, 0.0), (d / 2 - 0.02, s / 2 - 0.02, stand), pal.accent),
                      box((-d / 2, -s / 2, stand), (d / 2, s / 2, stand + h), pal.body)]
    td = rng.uniform(0.04, 0.055)
    zh = stand + h * rng.uniform(0.45, 0.6)
    add_hinged_panel(b, "door", "base", (-s / 2 + 0.02, s / 2 - 0.02, stand + 0.02, stand + h - 0.02), -d / 2, td,
                     _pick(rng, ["left", "right"]), rng.uniform(75, 95) * deg, "knob", zh, rng, pal,
                     damping=(1.0, 3.0), inset=rng.uniform(0.05, 0.07))
    return b.build()


def three_drawer_shelf(rng: np.random.Generator, object_id: str) -> ObjectModel:
    """The paper's real-robot object: a small shelf with three stacked drawers grasped by their edge."""
    pal = Palette.sample(rng)
    w, d, h, stand, t = rng.uniform(0.36, 0.44), rng.uniform(0.28, 0.34), rng.uniform(0.36, 0.44), rng.uniform(0.15, 0.22), 0.015
    b = Builder(object_id, "three_drawer_shelf", {"front_distance": 0.58})
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


RECIPES: dict[str, Callable[[np.random.Generator, str], ObjectModel]] = {
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
