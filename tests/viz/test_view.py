"""`actaim2 view`: the committed bags in the Rerun web viewer in headless Chromium, offline, and
the recordings of a small dataset and an evaluation run.

The browser reaches nothing but loopback (``browser.py``); the test asserts that every request
the page made went to the viewer's own server, that the console holds no error, and that the
3-D panel drew the fused cloud (pixels unlike the panel's background). ``ACTAIM2_VIEW_SCREENSHOT``
names a file for the screenshot (docs/figures/view_bags.png is made so).
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from actaim2.viz.recording import Sample, write_recording
from actaim2.viz.sources import (
    bag_samples,
    dataset_samples,
    evaluation_samples,
    kind_of,
)
from actaim2.viz.web_viewer import ViewerServer, viewer_assets
from browser import open_page

ROOT = Path(__file__).resolve().parents[2]
BAGS = ROOT / "bags"
READY = "window._handle !== undefined && !document.getElementById('status')"
CLOUD_PANEL = (0.02, 0.57, 0.10, 0.50)  # x0, x1, y0, y1 as fractions of the page: inside the 3-D panel
BACKGROUND_DIFFERENCE = 48  # max |channel difference| to the panel's commonest colour still counted as background
DRAWN_FRACTION = 0.03  # of the panel's pixels: the grid alone stays below 0.005


def drawn_fraction(png: bytes) -> float:
    """The share of the 3-D panel's pixels unlike its background (its commonest colour)."""
    import io

    from PIL import Image

    image = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(np.int16)
    h, w = image.shape[:2]
    x0, x1, y0, y1 = CLOUD_PANEL
    panel = image[int(y0 * h):int(y1 * h), int(x0 * w):int(x1 * w)].reshape(-1, 3)
    colours, counts = np.unique(panel, axis=0, return_counts=True)
    background = colours[counts.argmax()]
    return float((np.abs(panel - background).max(axis=1) > BACKGROUND_DIFFERENCE).mean())


def show(samples: list[Sample], tmp_path: Path, assets: dict[str, bytes]):
    recording = tmp_path / "view.rrd"
    write_recording(samples, recording, "test")
    with ViewerServer(recording, "test", assets=assets) as server:
        return server.url, open_page(server.url, settle=6.0, ready_js=READY, timeout=100.0)


@pytest.mark.timeout(240)
def test_the_committed_bags_in_an_offline_browser(browser, tmp_path):
    from actaim2.perception.config import load_perception_config

    assert kind_of(BAGS) == "bags"
    problems: list[str] = []
    samples = list(bag_samples(BAGS, 10, load_perception_config("azure_kinect"), None, problems.append))
    assert not problems
    assert [s.summary["mode label"] for s in samples] == ["pull", "push"]
    for sample in samples:
        assert len(sample.keyposes) == 4 and sample.summary["success"] is True
        assert len(sample.cloud[0]) > 10_000
        assert set(sample.pictures) == set(sample.views) == {"O_init", "O_final"}
        assert [v.shape[2] for v in sample.views["O_init"]] == [3] * 5

    assets = viewer_assets()
    url, page = show(samples, tmp_path, assets)
    if os.environ.get("ACTAIM2_VIEW_SCREENSHOT"):
        Path(os.environ["ACTAIM2_VIEW_SCREENSHOT"]).write_bytes(page.screenshot)
    outside = [r for r in page.requests if not r.startswith(url)]
    assert not outside, f"the page asked for more than its server: {outside}"
    errors = [text for level, text in page.console if level == "error"]
    assert not errors, errors
    asked = {r.removeprefix(url).split("?")[0] for r in page.requests}
    assert asked >= {"", "re_viewer.js", "re_viewer_bg.wasm", "recording.rrd"}
    drawn = drawn_fraction(page.screenshot)
    assert drawn > DRAWN_FRACTION, f"the 3-D panel shows little but its background ({drawn:.4f} of its pixels)"

    # the same page with no cloud to draw stays below the threshold: the check sees the cloud, not the grid
    _, empty = show([Sample("no cloud", {"success": False})], tmp_path, assets)
    assert drawn_fraction(empty.screenshot) < DRAWN_FRACTION


def test_a_small_dataset_and_an_evaluation_run(tmp_path, make_trajectory):
    from PIL import Image

    from actaim2.data.storage import DatasetWriter, encode_trajectory
    from actaim2.perception.config import capture_part, load_perception_config

    dataset = tmp_path / "dataset"
    with DatasetWriter(dataset, {"perception": capture_part(load_perception_config("ring5"))}) as writer:
        for n, moved in enumerate((0.0, 0.5)):
            writer.append(encode_trajectory(make_trajectory(f"t-random-{n:05d}", moved=moved)))
    assert kind_of(dataset) == "dataset"
    samples = list(dataset_samples(dataset, 10))
    assert [s.summary["success"] for s in samples] == [False, True]
    for sample in samples:
        assert len(sample.keyposes) == 4 and len(sample.cloud[0]) > 1000
        assert len(sample.pictures["O_init"]) == 5 and len(sample.views["O_final"]) == 5
        assert all(v.any() for v in sample.views["O_init"])

    run = tmp_path / "run"
    (run / "figures").mkdir(parents=True)
    results = [{"key": f"actaim2|drawer_000|{k}", "method": "actaim2", "object": "drawer_000", "cluster": k % 2,
                "success": k == 1, "confidence": [0.1, 0.2, 0.3, 0.4]} for k in range(3)]
    (run / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in results) + '{"key": "cut sh')
    Image.new("RGB", (64, 32), (200, 30, 30)).save(run / "figures" / "heatmaps_drawer_000.png")
    assert kind_of(run) == "evaluation"
    evaluated = list(evaluation_samples(run, 10))
    assert [s.summary["success"] for s in evaluated] == [False, True, False]
    assert evaluated[0].figures["heatmaps"].shape == (32, 64, 3) and evaluated[2].figures is evaluated[0].figures
    write_recording(evaluated, tmp_path / "run.rrd", "run")
    assert (tmp_path / "run.rrd").stat().st_size > 0
    record = ROOT / "results" / "d2ca9126_seen"  # a committed record of a run: its results.jsonl.gz
    assert kind_of(record) == "evaluation" and len(list(evaluation_samples(record, 5))) == 5

    # the command itself: serves the dataset's recording and page on loopback until interrupted
    proc = subprocess.Popen([sys.executable, "-m", "actaim2.cli", "view", str(dataset), "--no-browser", "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = ""
        while "(Ctrl-C stops)" not in line:
            line = proc.stdout.readline()
            if not line:
                pytest.fail(f"actaim2 view ended early: {proc.stderr.read()[-2000:]}")
        assert "2 sample(s)" in line, line
        url = line.split(" at ")[1].split()[0]
        assert url.startswith("http://127.0.0.1:")
        page = urllib.request.urlopen(url, timeout=30).read().decode()
        assert "re_viewer.js" in page and "googleapis" not in page
        assert len(urllib.request.urlopen(url + "recording.rrd", timeout=30).read()) > 10_000
    finally:
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 0, stderr[-2000:]
