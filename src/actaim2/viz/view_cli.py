"""`actaim2 view PATH`: a dataset, an evaluation run or rosbag2 bags in the Rerun web viewer, offline.

The samples (``actaim2.viz.sources``) are written as a Rerun recording (``actaim2.viz.recording``)
and served with the viewer on http://127.0.0.1:PORT/ (``actaim2.viz.web_viewer``: nothing is
fetched from anywhere but this machine); the command opens the page in the default browser
unless told not to and serves until interrupted. ``--save FILE.rrd`` keeps the recording (the
desktop viewer ``rerun FILE.rrd`` opens it too).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("path", type=Path, help="a dataset folder, an evaluation run folder (--out of evaluate) or its "
                                               "record under results/, a bag (.mcap, .db3 or its folder) or a folder of bags")
    parser.add_argument("--limit", type=int, default=200, help="show at most this many trajectories, samples or episodes")
    parser.add_argument("--port", type=int, default=9090, help="port on 127.0.0.1 (0: any free one)")
    parser.add_argument("--no-browser", action="store_true", help="only serve; print the address")
    parser.add_argument("--save", type=Path, help="also keep the recording as this .rrd file")
    parser.add_argument("--perception", default="azure_kinect",
                        help="bags: the rig's perception configuration (a rig name or a YAML)")
    parser.add_argument("--remove-robot", metavar="ROBOT", help="bags: hide this robot (preset or YAML) from the views")


def load_samples(args: argparse.Namespace) -> list:
    from actaim2.viz import sources

    kind = sources.kind_of(args.path)
    if kind == "dataset":
        samples = sources.dataset_samples(args.path, args.limit)
    elif kind == "evaluation":
        samples = sources.evaluation_samples(args.path, args.limit)
    else:
        from actaim2.perception.config import load_perception_config

        samples = sources.bag_samples(args.path, args.limit, load_perception_config(args.perception), args.remove_robot,
                                      lambda text: print(f"actaim2 view: {text}", file=sys.stderr))
    return list(samples)


def main(args: argparse.Namespace) -> int:
    import webbrowser

    from actaim2.viz.recording import write_recording
    from actaim2.viz.web_viewer import ViewerServer

    if not args.path.exists():
        print(f"actaim2 view: {args.path} does not exist", file=sys.stderr)
        return 2
    try:
        samples = load_samples(args)
    except (ValueError, OSError) as exc:
        print(f"actaim2 view: {exc}", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory(prefix="actaim2-view-") as tmp:
        recording = args.save or Path(tmp) / "recording.rrd"
        try:
            write_recording(samples, recording, args.path.name)
        except ValueError as exc:
            print(f"actaim2 view: {exc}", file=sys.stderr)
            return 1
        try:
            server = ViewerServer(recording, args.path.name, args.port)
        except OSError as exc:
            print(f"actaim2 view: cannot serve on 127.0.0.1:{args.port} ({exc}): try --port 0", file=sys.stderr)
            return 1
        with server:
            print(f"actaim2 view: {len(samples)} sample(s) of {args.path} at {server.url} (Ctrl-C stops)", flush=True)
            if not args.no_browser:
                webbrowser.open(server.url)
            try:
                while True:
                    time.sleep(3600)
            except KeyboardInterrupt:
                pass
    return 0
