"""Comparing an image with a reference -- an image, or a .RAY scene rendered for it -- fairly.

What ``raymitsuba compare``, its HTML report and the pytest plugin
(:mod:`raymitsuba.testing`) share. Its parts:

=============  ===========================================================================
module         what it owns
=============  ===========================================================================
``score``      the figures of one image against one reference (:class:`Score`)
``stable``     a scene's reference image and its unstable pixels (4 renders)
``picture``    the 8-bit views, the heat map, the side-by-side ``--diff`` picture
``report``     the HTML page and the CSV file of a batch
=============  ===========================================================================

One comparison is :func:`compare_scene` (a scene) or :func:`compare_images` (an image):
a pure function of its inputs and :class:`Settings` to a :class:`Result` record, which a
batch engine runs in a worker process (everything in and out pickles; a batch of them:
:func:`raymitsuba.batch.compare.compare_many`). Bad inputs
(unreadable files, scene errors, sizes that differ) give a Result with status
``"error"`` and a one-line message, never an exception.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from raymitsuba.compare.score import TOLERANCE, CompareError, Score, difference, score

#: The default ``--min-match``: percent of the scored pixels within the tolerance.
MIN_MATCH = 99.9
PASS, FAIL, MISSING, ERROR = "pass", "fail", "missing", "error"
FAILED = "failed"  # in a batch: the comparison itself failed (e.g. it killed its workers)

__all__ = ["Settings", "Result", "compare_scene", "compare_images", "compare", "Score",
           "CompareError", "TOLERANCE", "MIN_MATCH", "is_scene"]


@dataclass(frozen=True)
class Settings:
    """How to compare. ``srgb``: 8-bit images hold sRGB-encoded values (decoded before
    comparing; also the render option of the same name); ``stable``: leave out the pixels
    whose reference is not stable (scenes only); ``options``: the render options of the
    reference (``spp``, ``max_depth``, ...; left out: the defaults of
    :class:`raymitsuba.options.RenderOptions`)."""

    tolerance: float = TOLERANCE
    min_match: float = MIN_MATCH
    srgb: bool = False
    dialect: str = "auto"
    stable: bool = True
    options: dict = field(default_factory=dict)


@dataclass
class Result:
    """One comparison. ``status``: pass, fail, missing (no image), error (bad input) or
    failed (in a batch: the work itself failed); ``message`` says why when not scored;
    ``image`` and ``reference``: linear (H, W, 3) arrays and ``unstable`` the left-out
    pixels (None where not computed); ``renders``: renders of the scene it took."""

    reference_name: str
    image_name: str
    status: str
    score: Optional[Score] = None
    message: str = ""
    image: Optional[np.ndarray] = None
    reference: Optional[np.ndarray] = None
    unstable: Optional[np.ndarray] = None
    renders: int = 0

    @property
    def name(self) -> str:
        return os.path.splitext(os.path.basename(self.reference_name))[0]

    def record(self) -> dict:
        """The result as JSON-ready values (no arrays)."""
        out = {"reference": self.reference_name, "image": self.image_name,
               "status": self.status, "message": self.message, "renders": self.renders}
        out.update(self.score.record() if self.score else {})
        return out

    def diff_picture(self, srgb: bool = False):
        """uint8 side-by-side picture: the image | the reference | the heat map."""
        from raymitsuba.compare.picture import side_by_side

        return side_by_side(self.image, self.reference, difference(self.image, self.reference),
                            self.unstable, srgb)


def is_scene(reference) -> bool:
    """Whether ``reference`` is a scene: a parsed Scene or a path ending in .ray."""
    from raymitsuba.model import Scene

    return isinstance(reference, Scene) or (
        isinstance(reference, (str, os.PathLike))
        and os.fspath(reference).lower().endswith(".ray"))


def _image(source, settings: Settings, name: str) -> np.ndarray:
    if isinstance(source, (str, os.PathLike)):
        from raymitsuba import images

        return images.read(os.fspath(source), srgb=settings.srgb)
    return np.asarray(source, np.float32)


def _name(source, default: str) -> str:
    return os.fspath(source) if isinstance(source, (str, os.PathLike)) else default


def compare_images(image, reference, settings: Settings = Settings()) -> Result:
    """``image`` against the image ``reference`` (each a path or an (H, W, 3) array);
    every pixel is scored (an image reference says nothing of stability)."""
    names = _name(image, "<image>"), _name(reference, "<reference>")
    try:
        a = _image(image, settings, names[0])
        b = _image(reference, settings, names[1])
        figures = score(a, b, settings.tolerance)
    except (ValueError, OSError) as e:  # ImageError, CompareError: the inputs' fault
        return Result(names[1], names[0], ERROR, message=str(e))
    return _finish(Result(names[1], names[0], PASS, figures, image=a, reference=b), settings)


def compare_scene(image, scene, settings: Settings = Settings(), references=None) -> Result:
    """``image`` (a path, an (H, W, 3) array or None: missing) against ``scene`` (a .RAY
    path or a parsed Scene) rendered at the image's size, its unstable pixels left out
    (``settings.stable``). ``references``: what makes the reference (the signature of
    ``stable.reference``; None: that function, a cache may stand in for it)."""
    from raymitsuba.compare import stable
    from raymitsuba.model import RayError

    names = _name(image, "<image>"), _name(scene, getattr(scene, "file", "<scene>"))
    if image is None or (isinstance(image, (str, os.PathLike)) and not os.path.exists(image)):
        return Result(names[1], names[0], MISSING, message=f"{names[0]}: no such image")
    try:
        a = _image(image, settings, names[0])
        if a.ndim != 3 or a.shape[2] != 3:
            raise CompareError(f"{names[0]}: expected an RGB image, got shape {a.shape}")
        from raymitsuba.api import parse_any

        model = parse_any(scene, settings.dialect)
    except (ValueError, OSError) as e:
        return Result(names[1], names[0], ERROR, message=str(e))
    except RayError as e:
        return Result(names[1], names[0], ERROR, message=e.errors[0].format().splitlines()[0])
    height, width = a.shape[:2]
    try:
        ref = (references or stable.reference)(model, width, height, settings.tolerance,
                                               settings.stable, srgb=settings.srgb,
                                               **settings.options)
    except Exception as e:  # a render refused (BudgetError) or failed: this scene's error
        from raymitsuba.util import error_message

        return Result(names[1], names[0], ERROR, message=f"{names[1]}: {error_message(e)}")
    scored = None if ref.unstable is None else ~ref.unstable
    figures = score(a, ref.image, settings.tolerance, scored)
    return _finish(Result(names[1], names[0], PASS, figures, image=a, reference=ref.image,
                          unstable=ref.unstable, renders=ref.renders), settings)


def compare(image, reference, settings: Settings = Settings()) -> Result:
    """:func:`compare_scene` or :func:`compare_images`, as ``reference`` is a scene or not."""
    if is_scene(reference):
        return compare_scene(image, reference, settings)
    return compare_images(image, reference, settings)


def _finish(result: Result, settings: Settings) -> Result:
    result.status = PASS if result.score.passed(settings.min_match) else FAIL
    return result
