"""The interface between the Whitted integrator and the plugins it reads, decided here once.

The integrator never dispatches a virtual call per hit: at the start of a render it
reads every surface and light of the scene through the members that the classes below
declare, builds its tables (``surfaces.py``) and shades from them. :func:`check_surface`
and :func:`check_emitter` run then, once per plugin, and name a plugin that does not
provide its part; the names they check are the classes' own (:func:`members`).

* :class:`Surface`: the BSDF of every shape of the scene (``rayphong``, ``raytextured``),
  with its :class:`SurfaceMaterial`, or a :class:`SurfaceSet` of them, one per primitive;
* :class:`Light` (``raylight``) and :class:`Background` (``raybackground``): every emitter
  of the scene is one or the other;
* :class:`UnboundedPlane`: a mesh that stands for an unbounded plane (``rayplane``);
* :class:`MeshTopology`: a mesh that declares its faces' neighbours (``raytriangles``).
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Mapping
from typing import Protocol, runtime_checkable

from raymitsuba.model import Material

# The shading parameters of a surface, by name: ``color``, then the floats ka, kd, ks, n, kr,
# kt, eta; the scene model's list of a .RAY material's fields (meanings: ``phong.py``).
SURFACE_PARAMETERS = Material.FIELDS


@runtime_checkable
class Surface(Protocol):
    """A surface: what the integrator reads from the BSDF of a shape."""

    material: SurfaceMaterial  # owns the shading parameters (shared by the surfaces that share it)
    checker_size: float  # > 0: the base color times the checkerboard of this square side; 0: none
    image_textures: tuple  # of mi.Texture: each eval(si) multiplies the base color, in order


@runtime_checkable
class SurfaceSet(Protocol):
    """The BSDF of a shape whose primitives each have a surface (``raysurfaceset``: the
    sphere set). Its surfaces must stay opaque (kt = 0; ``surfaces.py`` checks)."""

    surfaces: tuple  # of Surface: the distinct surfaces of the primitives
    surface_of: object  # numpy uint32, one per primitive: the index of its surface
    # surfaces[table_from:] are the rows of a material table, read in bulk (a set may hold
    # 10^5 of them): each its own material (``row.material is row``), found in no other
    # set or shape, with no checkerboard and no image texture
    table_from: int
    # numpy float32 (rows, 2 + len(SURFACE_PARAMETERS)): row k the host values of
    # surfaces[table_from + k]: ``color``'s three, then the other parameters in order
    table: object


class SurfaceMaterial(Protocol):
    """The owner of a surface's shading parameters: one attribute per name of
    :data:`SURFACE_PARAMETERS` (``color`` a mi.Color3f, the others mi.Float, each of width 1),
    and these.

    Surfaces that share a material share these very objects, so they share their values and
    their gradients. The base color C is ``color`` times the surface's image textures, in
    order, times its checkerboard (``checkerboard.checker``)."""

    # The parameters' values by name, as Python floats (``color``: (r, g, b)), current after
    # every ``SceneParameters.update``: a render reads them without a Dr.Jit read per value.
    host_values: Mapping[str, float | tuple[float, float, float]]


@runtime_checkable
class Light(Protocol):
    """A light: ambient (its ``color`` is added to the ambient term) or not (``illuminate``)."""

    is_ambient: bool
    color: object  # mi.Color3f: the ambient term's intensity; else the largest illuminate gives (bailout.py)

    def illuminate(self, p):
        """(wi, dist, intensity) at the points ``p``, for a light that is not ambient (see
        ``light.py``)."""


@runtime_checkable
class Background(Protocol):
    """The background: the color of every ray that hits nothing."""

    background_color: object  # mi.Color3f


@runtime_checkable
class UnboundedPlane(Protocol):
    """A flat mesh that stands for an unbounded plane (``rayplane``: rings that reach past
    the horizon). Its outline is where the plane vanishes (the horizon), not the edge of
    whichever face a ray hit: the edge derivatives take the plane's own inside function
    there (``boundary/visibility.py``)."""

    unbounded_plane: bool  # True


@runtime_checkable
class MeshTopology(Protocol):
    """A mesh that declares which of its faces meet along an edge, where its positions do
    not tell (a tessellation, whose faces are grown apart: ``raymitsuba/geometry``). The
    edge derivatives follow a segment across a mesh's faces to its outline by them
    (``boundary/visibility.py``); a mesh without them has them found from its positions
    (``hits.HitTable.neighbours``)."""

    neighbours: object  # mi.UInt32, 3 per face (hits.NO_NEIGHBOUR: none), or None: not declared


@functools.cache  # (read once per protocol: a scene checks thousands of surfaces)
def members(protocol):
    """The names ``protocol`` declares, in order: its attributes, then its methods."""
    methods = [name for name, value in vars(protocol).items()
               if inspect.isfunction(value) and not name.startswith("_")]
    return tuple(inspect.get_annotations(protocol)) + tuple(methods)


# What a surface's material provides: the parameters, then SurfaceMaterial's own members.
MATERIAL_MEMBERS = SURFACE_PARAMETERS + members(SurfaceMaterial)


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
    """``bsdf``, unchanged, if it provides :class:`Surface` (and its material
    :class:`SurfaceMaterial`); else an InterfaceError (naming ``shape``, if given)."""
    lacking = missing(bsdf, members(Surface))
    if not lacking:
        lacking = [f"material.{name}" for name in missing(bsdf.material, MATERIAL_MEMBERS)]
    if lacking:
        where = f" (the BSDF of shape {describe(shape)})" if shape is not None else ""
        raise InterfaceError(
            f"raywhitted: the BSDF {describe(bsdf)}{where} is not a raymitsuba surface: it does "
            f"not provide {', '.join(lacking)} (see plugins/whitted/protocol.py; use rayphong or "
            f"raytextured)")
    return bsdf


def check_emitter(emitter):
    """'light' or 'background' for an emitter that provides :class:`Light` or
    :class:`Background`; else an InterfaceError."""
    if isinstance(emitter, Light):
        return "light"
    if isinstance(emitter, Background):
        return "background"
    raise InterfaceError(
        f"raywhitted: the emitter {describe(emitter)} is neither a raymitsuba light "
        f"({', '.join(members(Light))}) nor a background ({', '.join(members(Background))}) "
        f"(see plugins/whitted/protocol.py; use raylight or raybackground)")
