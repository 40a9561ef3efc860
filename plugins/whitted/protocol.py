"""The interface between the Whitted integrator and the plugins it reads, decided here once.

The integrator never dispatches a virtual call per hit: at the start of a render it
reads every surface and light of the scene through the members below, builds its
tables (``surfaces.py``) and shades from them. :func:`check_surface` and
:func:`check_emitter` run then, once per plugin, and name a plugin that does not
provide its part.

**A surface** (the BSDF of every shape of the scene; ``rayphong``, ``raytextured``):

* ``material``: the object that owns the surface's shading parameters, one
  attribute per name of :data:`SURFACE_PARAMETERS`: ``color`` (mi.Color3f) and the
  floats ka, kd, ks, n, kr, kt, eta (mi.Float), each of width 1 (see ``phong.py``
  for their meaning). Surfaces that share a material share these very objects, so
  they share their values and their gradients.
  The material also keeps ``host_values``: the same values as a tuple of Python floats
  (r, g, b, ka, kd, ks, n, kr, kt, eta), current after every ``SceneParameters.update``.
* ``checker_size`` (float): > 0: the base color is multiplied by the .RAY
  checkerboard of squares of this side (``checkerboard.checker``); 0: no checkerboard.
* ``image_textures`` (tuple of mi.Texture): each ``texture.eval(si)`` multiplies
  the base color, in order, before the checkerboard.

**A light** (``raylight``): ``is_ambient`` (bool); ``color`` (mi.Color3f), the
ambient term's intensity; ``illuminate(p) -> (wi, dist, intensity)`` for a
non-ambient light (see ``light.py``).

**A background** (``raybackground``): ``background_color`` (mi.Color3f), the color
of every ray that hits nothing.

Every emitter of the scene must be a light or a background.
"""

from typing import Protocol, runtime_checkable

from ..phong import FLOAT_PARAMS

SURFACE_PARAMETERS = ("color",) + tuple(FLOAT_PARAMS)


@runtime_checkable
class Surface(Protocol):
    material: object
    checker_size: float
    image_textures: tuple


@runtime_checkable
class Light(Protocol):
    is_ambient: bool
    color: object

    def illuminate(self, p): ...


@runtime_checkable
class Background(Protocol):
    background_color: object


class InterfaceError(TypeError):
    """A plugin of the scene does not provide what the Whitted integrator reads."""


def describe(plugin):
    """How an error names a plugin: its class and its id in the scene (if any)."""
    name = type(plugin).__name__
    try:
        ident = plugin.id()
    except Exception:  # not an mi.Object
        ident = ""
    return f"{name} {ident!r}" if ident else name


def missing(plugin, names):
    return [name for name in names if not hasattr(plugin, name)]


def check_surface(bsdf, shape=None):
    """``bsdf``, unchanged, if it provides the surface interface; else an InterfaceError."""
    lacking = missing(bsdf, ("material", "checker_size", "image_textures"))
    if not lacking:
        lacking = [f"material.{name}"
                   for name in missing(bsdf.material, SURFACE_PARAMETERS + ("host_values",))]
    if lacking:
        where = f" (the BSDF of shape {describe(shape)})" if shape is not None else ""
        raise InterfaceError(
            f"raywhitted: the BSDF {describe(bsdf)}{where} is not a raymitsuba surface: it does "
            f"not provide {', '.join(lacking)} (see plugins/whitted/protocol.py; use rayphong or "
            f"raytextured)")
    return bsdf


def check_emitter(emitter):
    """'light' or 'background' for an emitter that provides that interface; else an
    InterfaceError."""
    if isinstance(emitter, Light):
        return "light"
    if isinstance(emitter, Background):
        return "background"
    raise InterfaceError(
        f"raywhitted: the emitter {describe(emitter)} is neither a raymitsuba light (is_ambient, "
        f"color, illuminate) nor a background (background_color) (see plugins/whitted/protocol.py; use "
        f"raylight or raybackground)")
