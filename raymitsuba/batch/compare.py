"""Comparing many images with their references on Dask workers: :func:`compare_many`
(``raymitsuba compare 'submissions/{stem}.png' scenes/*.ray``).

The same machinery as :func:`raymitsuba.batch.render_many`. The client reads every
submission and parses every scene first: a scene with an error is reported (``report``,
its ``FILE:LINE:COLUMN`` diagnostics) and a submission that is not there is recorded as
missing, neither ever sent to a worker; the other comparisons go on. Each comparison is
one :class:`CompareTask`, and :func:`compare` a pure function of it -- the submission's
pixels, the reference (a parsed scene and its textures' bytes, or an image's pixels) and
the :class:`~raymitsuba.compare.Settings` -- to a :class:`raymitsuba.compare.Result`: the
same :func:`~raymitsuba.compare.compare_scene` (or ``compare_images``) a single
comparison calls, so the figures are the same, bit for bit, wherever it runs.

Nothing is written here: the results come back to the client, which writes the report,
the CSV and the ``--diff`` pictures (raymitsuba/cli/compare.py). There is no manifest: a
comparison leaves no output to resume from, and the report is the batch's record.

A batch with at most one scene to render runs in this process (no cluster is worth
starting for it) unless a client or a scheduler is given.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from raymitsuba.batch.core import Result, run_items
from raymitsuba.batch.runtime import SCHEDULER_ENV
from raymitsuba.batch.render import Item, parse
from raymitsuba.batch.tasks import textures_of, with_local_textures
from raymitsuba.compare import (ERROR, FAILED, MISSING, Result as Comparison, Settings,
                                compare_images, compare_scene, is_scene)
from raymitsuba.model import Scene


@dataclass(frozen=True)
class CompareTask:
    """One comparison for a worker: the submission (linear float32 (H, W, 3)), the
    reference (a parsed scene, or an image's pixels), the settings, the names the result
    carries (image, reference) and the scene's textures' bytes."""

    image: np.ndarray
    reference: Union[Scene, np.ndarray]
    settings: Settings
    names: Tuple[str, str]
    textures: Dict[str, bytes] = field(default_factory=dict)


def compare(task: CompareTask) -> Comparison:
    """The :class:`~raymitsuba.compare.Result` of ``task`` (see the module docstring)."""
    if isinstance(task.reference, Scene):
        reference = with_local_textures(task.reference, task.textures)
        result = compare_scene(task.image, reference, task.settings)
    else:
        result = compare_images(task.image, task.reference, task.settings)
    result.image_name, result.reference_name = task.names
    return result


def _read(path: str, settings: Settings) -> np.ndarray:
    from raymitsuba import images

    return images.read(path, srgb=settings.srgb)


def prepare(image: str, reference: str, settings: Settings,
            report: Optional[Callable]) -> Union[CompareTask, Comparison]:
    """The task comparing ``image`` with ``reference`` (paths), or the comparison's result
    when it ends here: its scene has an error (reported), its image is missing or cannot
    be read."""
    names = (image, reference)
    if is_scene(reference):
        parsed = Item(reference, image)
        model = parse(parsed, settings.dialect, report)
        if model is None:
            return Comparison(reference, image, ERROR, message=parsed.error)
    if not os.path.exists(image):
        return Comparison(reference, image, MISSING, message=f"{image}: no such image")
    try:
        pixels = _read(image, settings)
        if not is_scene(reference):
            return CompareTask(pixels, _read(reference, settings), settings, names)
        return CompareTask(pixels, model, settings, names, textures_of(model))
    except (ValueError, OSError) as e:  # ImageError: the inputs' fault
        return Comparison(reference, image, ERROR, message=str(e))


def compare_many(images: Sequence[str], references: Sequence[str],
                 settings: Settings = Settings(), client=None, jobs: Optional[int] = None,
                 threads: Optional[int] = None, scheduler: Optional[str] = None,
                 report: Optional[Callable] = None,
                 on_result: Optional[Callable[[int, Comparison], None]] = None
                 ) -> List[Comparison]:
    """Compare each image (a path) with its reference (a path: a .RAY scene or an image):
    one :class:`raymitsuba.compare.Result` per pair, in order.

    ``client``, ``jobs``, ``threads``, ``scheduler``: where, as
    :func:`raymitsuba.batch.core.run_items` takes them (a batch of at most one scene to
    render: in this process, unless ``client`` or ``scheduler`` say where).
    ``report(diagnostics)``: called with each scene's warnings and errors as it is parsed,
    before any comparison runs. ``on_result(i, result)``: called in this process as the
    ``i``-th comparison ends (those that end before any work first, then in the order
    they end)."""
    results: List[Optional[Comparison]] = [None] * len(images)
    tasks, owners = [], []
    for i, (image, reference) in enumerate(zip(images, references)):
        prepared = prepare(str(image), str(reference), settings, report)
        if isinstance(prepared, CompareTask):
            tasks.append(prepared)
            owners.append(i)
        else:
            results[i] = prepared
    if on_result is not None:
        for i, result in enumerate(results):
            if result is not None:
                on_result(i, result)

    def ended(result: Result):
        index, task = result.item
        if result.ok:
            comparison = result.value
        else:  # the work failed (ERROR: the item refused itself; compare_scene does not)
            comparison = Comparison(task.names[1], task.names[0],
                                    ERROR if result.status == "error" else FAILED,
                                    message=result.error or result.status)
        results[owners[index]] = comparison
        if on_result is not None:
            on_result(owners[index], comparison)

    renders = sum(isinstance(task.reference, Scene) for task in tasks)
    if client is None and renders <= 1 and not (scheduler or os.environ.get(SCHEDULER_ENV)):
        jobs = 1
    if tasks:
        run_items(_compare_indexed, list(enumerate(tasks)), client=client, jobs=jobs,
                  threads=threads, scheduler=scheduler, on_result=ended)
    return results


def _compare_indexed(indexed):
    """:func:`compare` of an (index, task) pair (the index tells the client whose it is)."""
    return compare(indexed[1])
