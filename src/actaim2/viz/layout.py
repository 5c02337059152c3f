"""The committed Foxglove layout of the live view, ``docs/foxglove/actaim2_layout.json``.

Built with the Foxglove SDK's layout classes from the channel names of
:mod:`actaim2.viz.foxglove_live`, so the panels and the channels cannot drift apart; a test
compares the committed file with :func:`layout_json`. Rewrite it with
``python -m actaim2.viz.layout docs/foxglove/actaim2_layout.json``.

Panels: a 3-D scene (the fused cloud in ``world``, the TF tree, the keyposes), the five views
and the five heatmaps in tabs, the mode probabilities as a plot and raw message, the episode
events.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import foxglove.layouts as fl

from actaim2.perception.ortho_views import VIEWS

COMMITTED = Path("docs/foxglove/actaim2_layout.json")


def _image(topic: str) -> fl.ImagePanel:
    return fl.ImagePanel(title=topic, config=fl.ImageConfig(
        image_mode=fl.ImageModeConfig(image_topic=topic)))


def _tabs(prefix: str) -> fl.TabContainer:
    return fl.TabContainer(tabs=[fl.TabItem(title=f"{prefix} {v}",
                                            content=_image(f"/{prefix}/{v}")) for v in VIEWS])


def build_layout() -> fl.Layout:
    scene = fl.ThreeDeePanel(title="world", config=fl.ThreeDeeConfig(
        follow_tf="world",
        topics={
            "/fused_points": fl.BaseRendererPointCloudTopicSettings(
                visible=True, point_size=3.0, color_mode="rgba-fields"),
            "/keyposes": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
        },
    ))
    mode = fl.SplitContainer(direction="column", items=[
        fl.SplitItem(content=fl.PlotPanel(title="mode probabilities", config=fl.PlotConfig(
            paths=[fl.PlotSeries(value="/mode.probabilities[:]", time_range="latest",
                                 array_expansion="byIndex")],
            x_axis_val="index", show_legend=False))),
        fl.SplitItem(content=fl.RawMessagesPanel(
            title="chosen cluster", config=fl.RawMessagesConfig(topic_path="/mode"))),
        fl.SplitItem(content=fl.RawMessagesPanel(
            title="episode", config=fl.RawMessagesConfig(topic_path="/episode"))),
    ])
    pictures = fl.SplitContainer(direction="column", items=[
        fl.SplitItem(content=_tabs("views")), fl.SplitItem(content=_tabs("heatmaps"))])
    return fl.Layout(content=fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=2, content=scene),
        fl.SplitItem(proportion=1, content=pictures),
        fl.SplitItem(proportion=1, content=mode),
    ]))


def layout_json() -> str:
    """The layout, indented, with a final newline (as committed)."""
    return json.dumps(json.loads(build_layout().to_json()), indent=2) + "\n"


def main(argv: list[str]) -> int:
    target = Path(argv[0]) if argv else COMMITTED
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(layout_json())
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
