"""Rendering many scenes, or one image in bands of rows, on Dask workers: :func:`render_many`.

The client (this process) parses every scene first: a scene with an error is reported
(``report``, its ``FILE:LINE:COLUMN`` diagnostics) and recorded, never sent to a worker;
the others are rendered. Each scene becomes one :class:`~raymitsuba.batch.tasks.RenderTask`
returning the output file's bytes or, with ``tiles`` N, N tasks returning bands of rows
(``tasks.render``). Only the client writes files, each atomically:

* an output, as soon as its bytes (or its last band) arrive;
* with tiles, each finished band, as ``tile-K.npy`` in a folder beside the output named
  for the scene's content, options and N (``.OUTPUT.tiles-HASH``), so that an interrupted
  render resumes from the bands it has; the folder is removed once the output is written;
* the manifest (:mod:`raymitsuba.batch.manifest`).

A tiled image is assembled band by band, as 8-bit values for an 8-bit format (as the
single render encodes it chunk by chunk): the client holds what the single render does.

An output's folder is made if it is not there (a template such as ``out/{parent}/{stem}.png``
names folders).

The image is the same, bit for bit, as ``raymitsuba render`` of the scene makes.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from dataclasses import dataclass, field
from typing import Callable, List, Optional, Sequence

import numpy as np

from raymitsuba.batch import manifest as manifests
from raymitsuba.batch.core import Result, run_items
from raymitsuba.batch.tasks import RenderTask, render, textures_of


@dataclass
class Item:
    """One scene of a batch and how it ended (a line of the manifest)."""

    scene: str  # the scene's path, as given
    output: str  # its output's path
    status: str = "pending"  # done, skipped, error, failed, cancelled
    error: Optional[str] = None  # one line, when not done
    attempts: int = 0  # workers its tasks were started on
    seconds: float = 0.0  # on the workers
    workers: List[str] = field(default_factory=list)  # that rendered it
    sha256: Optional[str] = None  # of the output file

    @property
    def ok(self) -> bool:
        return self.status in ("done", "skipped")

    def count(self, result) -> None:
        """Add a task's :class:`~raymitsuba.batch.core.Result` (one of the item's tasks:
        a tiled image has one per band) to the item's attempts, seconds and workers."""
        self.attempts += result.attempts
        self.seconds += result.seconds
        if result.worker:
            self.workers.append(result.worker)

    def record(self) -> dict:
        return dict(scene=self.scene, output=self.output, status=self.status,
                    error=self.error, attempts=self.attempts, seconds=round(self.seconds, 3),
                    worker=" ".join(sorted(set(self.workers))) or None, sha256=self.sha256)


def sha256_of(path: str) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def parse(item: Item, dialect: str, report: Optional[Callable]):
    """``item``'s scene parsed, its warnings reported; on errors, reported too, ``item``
    marked as an error (its first error's line) and None."""
    from raymitsuba.format import parser
    from raymitsuba.model import RayError, Severity

    try:
        model = parser.parse_file(item.scene, dialect)
    except RayError as e:
        if report is not None:
            report(e.diagnostics)
        first = next((d for d in e.diagnostics if d.severity is Severity.ERROR),
                     e.diagnostics[0])
        item.status, item.error = "error", first.format().splitlines()[0]
        return None
    if report is not None:
        report(model.warnings)
    return model


def bands(height: int, tiles: int) -> List[tuple]:
    """The rows (top, bottom) of ``tiles`` bands of nearly equal height."""
    edges = [height * k // tiles for k in range(tiles + 1)]
    return list(zip(edges[:-1], edges[1:]))


def tile_folder(item: Item, source: bytes, options: dict, tiles: int) -> str:
    """Where the finished bands of ``item``'s render are kept (see the module docstring)."""
    key = hashlib.sha256(source + json.dumps([options, tiles], sort_keys=True).encode())
    head, tail = os.path.split(os.path.abspath(item.output))
    return os.path.join(head, f".{tail}.tiles-{key.hexdigest()[:16]}")


class _Tiled:
    """The bands of one tiled output: kept as they arrive, assembled when all are there."""

    def __init__(self, folder: str, rows: List[tuple], width: int, height: int):
        self.folder, self.rows = folder, rows
        self.width, self.height = width, height
        self.missing = set(range(len(rows)))

    def path(self, k: int) -> str:
        return os.path.join(self.folder, f"tile-{k:04d}.npy")

    def keep(self, k: int, band: np.ndarray) -> None:
        from raymitsuba.atomic import atomic_path

        os.makedirs(self.folder, exist_ok=True)
        with atomic_path(self.path(k), ".npy") as tmp, open(tmp, "wb") as f:
            np.save(f, band)
        self.missing.discard(k)

    def kept(self, k: int) -> bool:
        """Whether band ``k`` was finished by an earlier run (and is whole)."""
        top, bottom = self.rows[k]
        try:
            band = np.load(self.path(k), mmap_mode="r")
        except (OSError, ValueError):
            return False
        if band.shape != (bottom - top, self.width, 3) or band.dtype != np.float32:
            return False
        self.missing.discard(k)
        return True

    def image(self, encode=None) -> np.ndarray:
        """The image, assembled from the kept bands; ``encode``: optional function of a
        band's float values (elementwise, such as ``images.encode_8bit``) applied band by
        band, so that an 8-bit image needs no float copy of the whole image."""
        image = None
        for k, (top, bottom) in enumerate(self.rows):
            band = np.load(self.path(k))
            band = band if encode is None else encode(band)
            if image is None:
                image = np.empty((self.height, self.width, 3), band.dtype)
            image[top:bottom] = band
        return image


def render_many(scenes: Sequence, outputs: Sequence[str], client=None,
                jobs: Optional[int] = None, threads: Optional[int] = None,
                scheduler: Optional[str] = None, tiles: Optional[int] = None,
                skip_existing: bool = False, fail_fast: bool = False,
                manifest: Optional[str] = "", dialect: str = "auto",
                report: Optional[Callable] = None, progress: Optional[Callable] = None,
                **options) -> List[Item]:
    """Render each scene (a path) to its output (a path; format by extension): one
    :class:`Item` per scene, in order.

    ``client``, ``jobs``, ``threads``, ``scheduler``, ``fail_fast``: where and how, as
    :func:`raymitsuba.batch.core.run_items` takes them. ``tiles``: split each image into
    that many bands of rows, each a task. ``skip_existing``: an output that exists is kept
    (outputs are written atomically: it is complete). ``manifest``: its path ("": beside
    the outputs, :func:`manifest.default_path`; None: none). ``report(diagnostics)``: called
    with each scene's warnings and errors as it is parsed. ``progress(done, total)``:
    called as work ends, in scenes (pixels with tiles). ``options``: the render options,
    as :func:`raymitsuba.load` takes them."""
    from raymitsuba.options import RenderOptions

    RenderOptions.given(**options)  # a value out of its range: OptionError, before any work
    items = [Item(str(scene), str(output)) for scene, output in zip(scenes, outputs)]
    book = manifests.Manifest(manifests.default_path(list(outputs)) if manifest == ""
                              else manifest)
    tasks, owners, tiled = [], [], {}  # the tasks, their items' indices, tiled outputs
    for i, item in enumerate(items):
        model = parse(item, dialect, report)
        if model is None:
            continue
        if skip_existing and os.path.isfile(item.output):
            item.status, item.sha256 = "skipped", sha256_of(item.output)
            continue
        given = dict(options)
        width, height = model.image_size(given.pop("width", None), given.pop("height", None))
        given.update(width=width, height=height)
        textures = textures_of(model)
        if not tiles:
            tasks.append(RenderTask(model, given, textures, ext=os.path.splitext(item.output)[1]))
            owners.append((i, None))
            continue
        with open(item.scene, "rb") as f:
            source = f.read() + b"".join(hashlib.sha256(t).digest() for t in textures.values())
        rows = bands(height, min(tiles, height))
        tiled[i] = _Tiled(tile_folder(item, source, given, tiles), rows, width, height)
        for k in range(len(rows)):
            if not tiled[i].kept(k):
                tasks.append(RenderTask(model, given, textures, rows=rows[k]))
                owners.append((i, k))
    for i, tiles_of in tiled.items():  # every band kept by an earlier run
        if not tiles_of.missing:
            _finish(items[i], tiles_of, options)

    units = [(t.rows[1] - t.rows[0]) * t.options["width"] if t.rows else 1 for t in tasks]
    total, done = sum(units), [0]
    for i, item in enumerate(items):  # ended before any work: scene errors, skipped, kept
        if item.status != "pending":
            book.add(item)

    def on_result(result: Result):
        index = result.item[0]
        i, k = owners[index]
        item = items[i]
        item.count(result)
        if not result.ok:  # a tiled item ends at its first band not done
            if item.status == "pending":
                item.status, item.error = result.status, result.error
                book.add(item)
        elif k is None:
            _write(item, result.value)
            book.add(item)
        else:
            tiled[i].keep(k, result.value)
            if not tiled[i].missing and item.status == "pending":
                _finish(item, tiled[i], options)
                book.add(item)
        done[0] += units[index]
        if progress is not None:
            progress(done[0], total)

    try:
        if tasks:
            run_items(_render_indexed, list(enumerate(tasks)), client=client, jobs=jobs,
                      threads=threads, scheduler=scheduler, fail_fast=fail_fast,
                      on_result=on_result)
    finally:
        book.write()
    return items


def _render_indexed(indexed):
    """``tasks.render`` of an (index, task) pair (the index tells the client whose it is)."""
    return render(indexed[1])


def make_folder(path: str) -> None:
    """The folder of an output, made if a template named one that is not there yet."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)


def _write(item: Item, data: bytes) -> None:
    from raymitsuba import images

    try:
        make_folder(item.output)
        images.write_bytes(item.output, data)
    except OSError as e:
        item.status, item.error = "failed", f"{item.output}: cannot write: {e.strerror or e}"
        return
    item.status, item.sha256 = "done", hashlib.sha256(data).hexdigest()


def _finish(item: Item, tiles_of: _Tiled, options: dict) -> None:
    """Write ``item``'s output from its kept bands, then remove them."""
    from raymitsuba import images

    try:
        make_folder(item.output)
        srgb = bool(options.get("srgb"))
        encode = (lambda band: images.encode_8bit(band, srgb)) if images.is_8bit(item.output) \
            else None
        images.write(item.output, tiles_of.image(encode), srgb=srgb)
    except OSError as e:
        item.status, item.error = "failed", f"{item.output}: cannot write: {e.strerror or e}"
        return
    item.status, item.sha256 = "done", sha256_of(item.output)
    shutil.rmtree(tiles_of.folder, ignore_errors=True)
