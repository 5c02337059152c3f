"""The command-line options of the protocol that evaluate and validate share."""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Sequence

from actaim2.data.real_objects import PARTNET_ROOT_ENV, SPLITS_FILE
from actaim2.protocol.lock import LEDGER_FILE, LOCK_FILE


def add_protocol_arguments(parser: argparse.ArgumentParser) -> None:
    """``--final``, ``--lock``, ``--ledger``: shared by evaluate and validate
    (actaim2.protocol.lock)."""
    parser.add_argument(
        "--final",
        action="store_true",
        help="run test-split objects, once, under the protocol lock (docs/evaluation.md, "
        "Protocol); the run is appended to the ledger",
    )
    parser.add_argument(
        "--lock", type=Path, default=LOCK_FILE, help=f"the protocol lock (default {LOCK_FILE})"
    )
    parser.add_argument(
        "--ledger",
        type=Path,
        default=LEDGER_FILE,
        help=f"the --final runs' ledger (default {LEDGER_FILE})",
    )


def splits_files(args: argparse.Namespace, folders: Sequence[Path] = ()) -> list[Path]:
    """The splits files that say which real folders are test objects: the partnet catalogue's
    (where it is known) and the one in or beside each of ``folders`` (object folders, or
    folders of them)."""
    root = args.partnet_root or os.environ.get(PARTNET_ROOT_ENV)
    files = [Path(root) / SPLITS_FILE] if root else []
    for folder in folders:
        files += [Path(folder) / SPLITS_FILE, Path(folder).parent / SPLITS_FILE]
    return list(dict.fromkeys(files))
