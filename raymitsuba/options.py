"""The render options, stated once: each option's name, default, valid range and meaning.

Every option a render takes is a field of :class:`RenderOptions`, and everything else is
made from this record:

* the command line's options (:mod:`raymitsuba.cli.options`): each field's flag, type,
  range, default and help text;
* the keywords of :func:`raymitsuba.load` (a keyword left out, or None, takes the
  default here);
* the ``raywhitted`` integrator's properties: the translator writes the fields whose
  reader is ``"integrator"`` (:meth:`RenderOptions.integrator_properties`) and the
  integrator reads them back with their defaults and ranges
  (:meth:`RenderOptions.from_properties`).

A value out of its range raises :class:`OptionError` (a ValueError) naming the option,
whichever way it came in. The fields' help texts are the one explanation of each option;
the README and the docstrings point here.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Dict, Iterator, Optional

from raymitsuba.model import DEFAULT_IMAGE_SIZE, MAX_IMAGE_SIZE

GIB = 1 << 30
VIEWPORT = f"the MIT 6.837 viewport's, else {DEFAULT_IMAGE_SIZE}"

#: Who reads an option: the image (the translator's sensor and film), the translator's
#: scene (textures), or the integrator (a property of ``raywhitted``).
IMAGE, SCENE, INTEGRATOR = "image", "scene", "integrator"


class OptionError(ValueError):
    """A render option out of its range (or of the wrong type)."""


@dataclass(frozen=True)
class Spec:
    """What the record says of one option besides its default (see :func:`option`).

    ``low`` / ``high``: the valid range (None: unbounded), ``low`` excluded when
    ``low_open``; ``reader``: IMAGE, SCENE or INTEGRATOR; ``unset``: what the option
    does when it is None (its default); ``cli``: whether the command line offers it
    (some are for tests and tools only); ``metavar``: the command line's name for its
    value; ``size``: a number of bytes, written ``2G`` or ``512M`` on the command line;
    ``flag_value``: the value of the option given without one (the command line's flag
    alone, or True from Python; None: a value is required)."""

    help: str
    reader: str
    kind: type
    unset: Optional[str] = None
    low: Optional[float] = None
    high: Optional[float] = None
    low_open: bool = False
    cli: bool = True
    metavar: Optional[str] = None
    size: bool = False
    flag_value: Any = None


    def check(self, name: str, value: Any) -> Any:
        """``value`` as the option's type, or an OptionError naming the option."""
        if value is None:
            return None
        if value is True and self.flag_value is not None:
            return self.flag_value
        if self.kind is bool:
            return bool(value)
        try:
            typed = self.kind(value)
        except (TypeError, ValueError):
            raise OptionError(f"{name} must be {'an integer' if self.kind is int else 'a number'}"
                              f", got {value!r}") from None
        if self.kind is int and typed != value:
            raise OptionError(f"{name} must be an integer, got {value!r}")
        below = self.low is not None and (typed <= self.low if self.low_open else typed < self.low)
        above = self.high is not None and typed > self.high
        if below or above or typed != typed:  # (nan is in no range)
            raise OptionError(f"{name} must be {self.range_text()}, got {value!r}")
        return typed

    def range_text(self) -> str:
        low = "" if self.low is None else f"{'>' if self.low_open else '>='} {self.low:g}"
        high = "" if self.high is None else f"<= {self.high:g}"
        return " and ".join(part for part in (low, high) if part) or "a number"


def option(default: Any, help: str, reader: str, kind: type, **spec: Any):
    """A field of :class:`RenderOptions`: its default and its :class:`Spec`."""
    return dataclasses.field(default=default,
                             metadata={"spec": Spec(help, reader, kind, **spec)})


@dataclass(frozen=True)
class RenderOptions:
    """The options of a render (see the module docstring); every field validated."""

    width: Optional[int] = option(
        None, "Image width.", IMAGE, int, unset=VIEWPORT, low=1, high=MAX_IMAGE_SIZE)
    height: Optional[int] = option(
        None, "Image height.", IMAGE, int, unset=VIEWPORT, low=1, high=MAX_IMAGE_SIZE)
    spp: int = option(
        1, "Samples per pixel (1: the pixel centre; more: stratified, box filter).",
        IMAGE, int, low=1, high=4096)
    max_depth: int = option(5, "Bounces after the camera ray.", INTEGRATOR, int, low=0, high=64)
    aa: Optional[float] = option(
        None, "Adaptive anti-aliasing, the way to make an image to look at: pixels whose "
              "centre and four corners differ by more than THRESHOLD (linear), and pixels "
              "between two such pixels, are traced again with a 2x2 to 12x12 grid by the "
              "contrast; pixels whose samples all followed one path (the same surfaces, "
              "lights and shadows) keep their first sample.",
        INTEGRATOR, float, unset="off", low=0, low_open=True, metavar="[THRESHOLD]",
        flag_value=0.02)
    memory_budget: int = option(
        2 * GIB, "Memory a chunk of camera rays may take (e.g. 512M, 4G).",
        INTEGRATOR, int, low=0, low_open=True, metavar="SIZE", size=True)
    bailout: Optional[float] = option(
        None, "Do not trace rays whose path weight (product of kr / kt from the camera) is at "
              "most this (0: the exact ray tree). Unset: a ray is not traced when all its "
              "subtree could add to its pixel is at most 1/1020 (a quarter of an 8-bit step), "
              "by a bound from the scene's lights and materials (plugins/whitted/bailout.py).",
        INTEGRATOR, float, unset="bounded", low=0, high=1)
    time_limit: float = option(
        3600.0, "Refuse renders estimated to take longer (0: no limit).",
        INTEGRATOR, float, low=0, metavar="SECONDS")
    srgb: bool = option(
        False, "Encode 8-bit output with the sRGB curve and decode 8-bit textures from it.",
        SCENE, bool)
    max_shadow_crossings: int = option(
        16, "A shadow ray that crosses more transparent surfaces than this is taken as "
            "blocked.", INTEGRATOR, int, low=1, cli=False)
    chunk_pixels: int = option(
        0, "At most this many pixels a chunk (0: as many as the memory budget holds).",
        INTEGRATOR, int, low=0, cli=False)
    ray_offset_scale: float = option(
        1.0, "Secondary and shadow rays start off the surface by this many times Mitsuba's ray "
             "epsilon (1: Mitsuba's own spawn_ray; raymitsuba compare renders 100 to find the "
             "pixels whose value hangs on it).",
        INTEGRATOR, float, low=0, low_open=True, cli=False)

    sphere_set: int = option(
        256, "Draw the opaque spheres (analytic ones, and untextured ones under non-uniform "
             "scales as exact ellipsoids) as one shape when a scene has at least this many "
             "(0: never): 10^4 spheres load in milliseconds, but those spheres cannot move "
             "or turn transparent in a fit (raymitsuba/geometry/sphere_set.py).",
        SCENE, int, low=0, metavar="N")

    def __post_init__(self):
        for name, spec in specs():
            object.__setattr__(self, name, spec.check(name, getattr(self, name)))

    @classmethod
    def given(cls, **values: Any) -> "RenderOptions":
        """The options with ``values`` set; a value of None takes the field's default."""
        return cls(**{name: value for name, value in values.items() if value is not None})

    def integrator_properties(self) -> Dict[str, Any]:
        """The ``raywhitted`` properties: the integrator's fields that differ from their
        defaults (the integrator reads the others' defaults from this record)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(RenderOptions)
                if f.metadata["spec"].reader == INTEGRATOR and getattr(self, f.name) != f.default}

    @classmethod
    def from_properties(cls, props) -> "RenderOptions":
        """The integrator's options read from Mitsuba ``props`` (others at their defaults)."""
        return cls.given(**{name: props.get(name) for name, spec in specs()
                            if spec.reader == INTEGRATOR and name in props})


def specs() -> Iterator:
    """(name, Spec) of every option, in the record's order."""
    for f in dataclasses.fields(RenderOptions):
        yield f.name, f.metadata["spec"]


def describe(reader: str) -> str:
    """The options read by ``reader`` as a reST list: name, type, default, help."""
    lines = []
    for name, spec in specs():
        if spec.reader == reader:
            value = default(name)
            shown = (spec.unset if value is None else
                     f"{value / GIB:g} GiB" if spec.size else repr(value))
            alone = "" if spec.flag_value is None else f"; True: {spec.flag_value!r}"
            lines.append(f"* ``{name}`` ({spec.kind.__name__}, default {shown}{alone}): "
                         f"{spec.help}")
    return "\n" + "\n".join(lines) + "\n"


def spec(name: str) -> Spec:
    """What the record says of option ``name``."""
    return RenderOptions.__dataclass_fields__[name].metadata["spec"]


def default(name: str) -> Any:
    """The default of option ``name``."""
    return RenderOptions.__dataclass_fields__[name].default
