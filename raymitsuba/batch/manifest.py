"""The manifest of a batch: one JSON object per line, one line per scene, beside the outputs.

Keys: ``scene``, ``output`` (paths as given), ``status`` (``done``, ``skipped``: the
output existed and ``--skip-existing`` kept it, ``error``: the scene is wrong, reported
before any work, or refused by the guards; ``failed``; ``cancelled``: not run after a
failure with ``--fail-fast``), ``error`` (one line, or null), ``attempts`` (workers the
item was started on; with tiles, summed over them), ``seconds`` (on the workers),
``worker`` (address; with tiles, every worker that rendered one, space-separated) and
``sha256`` (of the output file, when there is one).

The file is rewritten (atomically) as items end, so an interrupted batch leaves a
manifest of what it finished.
"""

from __future__ import annotations

import json
import os
import time
from typing import List, Optional

from raymitsuba.atomic import atomic_path

NAME = "raymitsuba-manifest.jsonl"  # in the outputs' common folder
EVERY = 1.0  # seconds between rewrites while a batch runs


def default_path(outputs: List[str]) -> str:
    """The manifest's path: :data:`NAME` in the folder that holds every output."""
    folders = [os.path.dirname(os.path.abspath(o)) for o in outputs] or [os.getcwd()]
    return os.path.join(os.path.commonpath(folders), NAME)


class Manifest:
    """The items of a batch that have ended, in the order they ended, written to ``path``
    (None: nowhere); each item's ``record()`` is its line, read when the file is written."""

    def __init__(self, path: Optional[str]):
        self.path = path
        self.items: List = []  # objects with a record() -> dict
        self.written = 0.0  # time.monotonic() of the last write

    def add(self, item) -> None:
        self.items.append(item)
        if time.monotonic() - self.written > EVERY:
            self.write()

    def write(self) -> None:
        if self.path is None:
            return
        os.makedirs(os.path.dirname(os.path.abspath(self.path)), exist_ok=True)
        with atomic_path(self.path, ".jsonl") as tmp, open(tmp, "w") as f:
            for item in self.items:
                f.write(json.dumps(item.record()) + "\n")
        self.written = time.monotonic()


def read(path: str) -> List[dict]:
    """The records of a manifest file."""
    with open(path) as f:
        return [json.loads(line) for line in f if line.strip()]
