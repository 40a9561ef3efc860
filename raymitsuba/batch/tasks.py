"""What a worker computes: a scene and its options to an encoded image, or to a band of rows.

A :class:`RenderTask` carries everything a render needs, so that any worker can run it
on any machine, sharing no files with the client: the parsed scene (the client parsed
it; a worker never sees a scene error), the bytes of its textures, the render options,
and what to return. :func:`render` is a pure function of it:

* ``ext`` given (``".png"``, ``".exr"``, ``".npy"``...): the bytes of the image file, as
  ``raymitsuba render`` would write it (:func:`raymitsuba.images.encoded`);
* ``rows`` = (top, bottom) instead: those rows of the image, float32 (bottom - top, W,
  3), the same bits as those rows of the whole render (``raywhitted``'s ``render_array``).

Textures are written once per worker machine, named by their content's sha256, into the
temporary directory, and the scene's texture paths point there.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import tempfile
from dataclasses import dataclass, field
from typing import Dict, Optional, Tuple

from raymitsuba.batch.core import ItemError
from raymitsuba.model import Scene

TEXTURE_DIR = "raymitsuba-textures"  # in the worker's temporary directory


@dataclass(frozen=True)
class RenderTask:
    """One render for a worker (see the module docstring)."""

    model: Scene  # the parsed scene
    options: dict  # render options by name, as raymitsuba.load takes them (None: default)
    textures: Dict[str, bytes] = field(default_factory=dict)  # texture path -> its bytes
    ext: Optional[str] = None  # the output's extension: return the file's bytes
    rows: Optional[Tuple[int, int]] = None  # (top, bottom): return these rows, float32


def textures_of(model: Scene) -> Dict[str, bytes]:
    """{path: bytes} of every texture file the scene's objects use (read on the client)."""
    found = {}
    for obj in model.objects:
        if obj.texture is not None and obj.texture.path not in found:
            with open(obj.texture.path, "rb") as f:
                found[obj.texture.path] = f.read()
    return found


def with_local_textures(model: Scene, textures: Dict[str, bytes]) -> Scene:
    """``model`` with each texture path replaced by a file of this machine holding its
    bytes (written once, named by their sha256; same extension)."""
    if not textures:
        return model
    folder = os.path.join(tempfile.gettempdir(), TEXTURE_DIR)
    os.makedirs(folder, exist_ok=True)
    local = {}
    for path, data in textures.items():
        name = hashlib.sha256(data).hexdigest() + os.path.splitext(path)[1]
        target = os.path.join(folder, name)
        if not os.path.exists(target):
            from raymitsuba.atomic import atomic_path

            with atomic_path(target) as tmp, open(tmp, "wb") as f:
                f.write(data)
        local[path] = target
    objects = tuple(obj if obj.texture is None or obj.texture.path not in local else
                    dataclasses.replace(obj, texture=dataclasses.replace(
                        obj.texture, path=local[obj.texture.path]))
                    for obj in model.objects)
    return dataclasses.replace(model, objects=objects)


def render(task: RenderTask):
    """The task's image bytes, or its band of rows (see the module docstring). A request no
    memory budget can hold is an :class:`~raymitsuba.batch.core.ItemError`."""
    from raymitsuba import api, backend, images

    backend.mitsuba(mitsuba_integrators=False)
    from raymitsuba.plugins.whitted.guards import BudgetError

    try:
        loaded = api.load(with_local_textures(task.model, task.textures), **task.options)
        image = loaded.integrator.render_array(loaded.scene, rows=task.rows)
    except BudgetError as e:
        raise ItemError(str(e)) from None
    if task.rows is not None:
        return image
    return images.encoded(image, task.ext, srgb=bool(task.options.get("srgb")))
