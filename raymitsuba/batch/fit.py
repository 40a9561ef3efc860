"""Fitting many scenes, each to its own target image, on Dask workers: :func:`fit_many`.

The same machinery as :func:`raymitsuba.batch.render_many`: the client parses each scene,
checks its parameters (``--params``) and reads its target first (a scene error, an
unknown parameter or an unreadable target is reported and recorded, never sent to a
worker); each fit is one :class:`FitTask`, a pure function of the scene's text, textures,
target, parameters and options to the fitted scene's text (:func:`fit`, the same
:func:`raymitsuba.fit.fit` and write-back as ``raymitsuba fit``); only the client writes
the fitted scenes, atomically, and the manifest.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np

from raymitsuba.batch import manifest as manifests
from raymitsuba.batch.core import ItemError, Result, run_items
from raymitsuba.batch.render import Item, make_folder, parse, sha256_of
from raymitsuba.batch.tasks import textures_of, with_local_textures
from raymitsuba.model import Scene


@dataclass(frozen=True)
class FitTask:
    """One fit for a worker: the scene (parsed, and its bytes, which the fitted text keeps
    but for the fitted numbers), its textures' bytes, the target (linear float32 (H, W,
    3)), the parameter keys, Adam's ``iters`` and ``lr``, render options by name, and
    ``scan``: ``"auto"`` or ``"none"`` (:func:`raymitsuba.fit.fit`)."""

    model: Scene
    data: bytes
    target: np.ndarray
    keys: List[str]
    iters: int
    lr: float
    options: dict = field(default_factory=dict)
    textures: Dict[str, bytes] = field(default_factory=dict)
    scan: str = "auto"


def fit(task: FitTask) -> bytes:
    """The fitted scene's text (bytes) of ``task``; a fit that fails (diverges) is an
    :class:`~raymitsuba.batch.core.ItemError`."""
    from raymitsuba import api, backend
    from raymitsuba import fit as fitting

    backend.mitsuba(mitsuba_integrators=False)
    height, width = task.target.shape[:2]
    loaded = api.load(with_local_textures(task.model, task.textures), width=width,
                      height=height, **task.options)
    try:
        result = fitting.fit(loaded, task.target, task.keys, iters=task.iters, lr=task.lr,
                               scan=task.scan)
    except fitting.FitError as e:
        raise ItemError(str(e)) from None
    return fitting.rewrite_scene(task.data, task.model, result.fitted)


def fit_many(scenes: Sequence[str], targets: Sequence[str], outputs: Sequence[str],
             keys: Optional[Sequence[str]] = None, iters: int = 100, lr: float = 0.02,
             client=None, jobs: Optional[int] = None, threads: Optional[int] = None,
             scheduler: Optional[str] = None, skip_existing: bool = False,
             fail_fast: bool = False, manifest: Optional[str] = "", dialect: str = "auto",
             report: Optional[Callable] = None, progress: Optional[Callable] = None,
             scan: str = "auto", **options) -> List[Item]:
    """Fit each scene (a path) to its target image (a path) and write the fitted scene to
    its output: one :class:`~raymitsuba.batch.render.Item` per scene, in order. ``keys``:
    the parameters (default: as ``raymitsuba fit`` chooses); ``options``: ``spp``,
    ``max_depth``, ``aa``, ``memory_budget``, ``srgb`` (the target's decoding too);
    ``scan``: ``"auto"`` (default) or ``"none"``, as :func:`raymitsuba.fit.fit` takes it; the
    rest as :func:`raymitsuba.batch.render_many` takes them."""
    from raymitsuba import fit as fitting
    from raymitsuba import images

    items = [Item(str(s), str(o)) for s, o in zip(scenes, outputs)]
    book = manifests.Manifest(manifests.default_path(list(outputs)) if manifest == ""
                              else manifest)
    tasks, owners = [], []
    for i, (item, target) in enumerate(zip(items, targets)):
        model = parse(item, dialect, report)
        if model is None:
            continue
        if skip_existing and os.path.isfile(item.output):
            item.status, item.sha256 = "skipped", sha256_of(item.output)
            continue
        try:
            selected = fitting.select_keys(model, None if keys is None else list(keys))
            if not selected:
                raise fitting.FitError("nothing to fit: no material used by an object and "
                                       "no light; name parameters with --params")
            image = images.read(str(target), srgb=bool(options.get("srgb")))
            if not np.all(np.isfinite(image)):
                raise images.ImageError(f"{target}: the image holds non-finite values")
            with open(item.scene, "rb") as f:
                data = f.read()
        except (fitting.FitError, images.ImageError, OSError) as e:
            item.status, item.error = "error", f"{item.scene}: {e}"
            continue
        tasks.append(FitTask(model, data, image, selected, iters, lr, dict(options),
                             textures_of(model), scan))
        owners.append(i)
    for item in items:
        if item.status != "pending":
            book.add(item)

    def on_result(result: Result):
        item = items[owners[result.item[0]]]
        item.count(result)  # (one task per fit)
        if result.ok:
            write(item, result.value)
        else:
            item.status, item.error = result.status, result.error
        book.add(item)
        if progress is not None:
            progress(sum(i.status != "pending" for i in items), len(items))

    try:
        if tasks:
            run_items(_fit_indexed, list(enumerate(tasks)), client=client, jobs=jobs,
                      threads=threads, scheduler=scheduler, fail_fast=fail_fast,
                      on_result=on_result)
    finally:
        book.write()
    return items


def _fit_indexed(indexed):
    """:func:`fit` of an (index, task) pair (the index tells the client whose it is)."""
    return fit(indexed[1])


def write(item: Item, data: bytes) -> None:
    """Write a fitted scene to ``item``'s output, atomically."""
    from raymitsuba.atomic import atomic_path

    try:
        make_folder(item.output)
        with atomic_path(item.output, ".ray") as tmp, open(tmp, "wb") as f:
            f.write(data)
    except OSError as e:
        item.status, item.error = "failed", f"{item.output}: cannot write: {e.strerror or e}"
        return
    item.status, item.sha256 = "done", hashlib.sha256(data).hexdigest()
