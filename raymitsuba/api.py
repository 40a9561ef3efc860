"""The Python API: load a .RAY scene into Mitsuba, render it, get at its parameters.

    loaded = raymitsuba.load("scenes/whitted.ray", width=256, height=256)
    image = raymitsuba.render(loaded)             # dr TensorXf, (H, W, 3), linear
    loaded.params["mat1.color"]                   # Color3f, differentiable
    loaded.params["light2.position"]

The parameter keys are stated by :class:`raymitsuba.format.commands.ParamKey`, the render
options by :class:`raymitsuba.options.RenderOptions`. Both dialects load the same way
(``dialect="auto"`` decides from the text; force it with ``"comp575"`` or ``"mit6837"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from raymitsuba.model import Scene
from raymitsuba.translate import Options, translate


@dataclass
class Loaded:
    model: Scene  # the parsed scene
    options: Options
    scene_dict: dict  # what mi.load_dict received
    scene: Any  # mi.Scene
    data: Any = None  # the .RAY text (bytes) the model was parsed from, if known
    _params: Any = field(default=None, repr=False)
    _geometry: Any = field(default=None, repr=False)

    @property
    def params(self):
        """``mi.traverse(scene)`` (mi.SceneParameters) with the geometry and camera keys
        (:class:`raymitsuba.parameters.GeometryKeys`, when the scene's text is known), made
        at the first use and kept: a plain render does not need it, and it visits every
        object of the scene."""
        if self._params is None:
            self._params = self.traverse()
        return self._params

    def traverse(self):
        """A new ``mi.traverse(scene)`` with the keys that are not Mitsuba objects' own:
        the geometry and camera keys and the ``mat{i}`` keys of the sphere set's material
        table (``plugins/surfaceset.py``), registered by their nodes."""
        from raymitsuba.backend import mitsuba

        params = mitsuba().traverse(self.scene)
        if self.geometry is not None:
            self.geometry.register(params)
        for bsdf in (shape.bsdf() for shape in self.scene.shapes()):
            if hasattr(bsdf, "register"):  # a surface set's table
                bsdf.register(params)
        return params

    @property
    def geometry(self):
        """The node of the geometry and camera keys (None: the scene's text is unknown)."""
        if self._geometry is None and self.data is not None:
            from raymitsuba.parameters import GeometryKeys

            self._geometry = GeometryKeys(self, self.data)
        return self._geometry

    @property
    def integrator(self):
        return self.scene.integrator()


def parse_any(source, dialect: str = "auto") -> Scene:
    from raymitsuba.format import parser

    if isinstance(source, Scene):
        return source
    return parser.parse(source, dialect)


def source_data(source, model: Scene):
    """The .RAY text (bytes) of ``model``, parsed from ``source`` (a path, text or the Scene
    itself: then its file, if it can be read), or None."""
    import os

    if isinstance(source, (bytes, bytearray, memoryview)):
        return bytes(source)
    path = source if isinstance(source, (str, os.PathLike)) and not isinstance(source, Scene) \
        else model.file
    if isinstance(path, str) and "\n" in path:  # .RAY text
        return path.encode("utf-8", "surrogateescape")
    try:
        if os.path.isfile(path):
            with open(path, "rb") as f:
                return f.read()
    except (OSError, TypeError, ValueError):
        pass
    return source.encode("utf-8", "surrogateescape") if isinstance(source, str) else None


def load(source, width=None, height=None, spp=None, max_depth=None, srgb=None, dialect="auto",
         aa=None, memory_budget=None, bailout=None, time_limit=None,
         ray_offset_scale=None, sphere_set=None) -> Loaded:
    """Parse (a path, .RAY text or a Scene, in ``dialect``) and load it into Mitsuba.

    The other keywords are render options: :class:`raymitsuba.options.RenderOptions` states
    each one's default (taken where a keyword is None), range and meaning; a value out of
    its range raises :class:`~raymitsuba.options.OptionError`. A size left out is the MIT
    6.837 ``viewport``'s, else 512.
    """
    from raymitsuba.backend import mitsuba
    from raymitsuba.util import no_cyclic_gc

    model = parse_any(source, dialect)
    mi = mitsuba()
    width, height = model.image_size(width, height)
    options = Options.given(width=width, height=height, spp=spp, max_depth=max_depth, srgb=srgb,
                            aa=aa, memory_budget=memory_budget, bailout=bailout,
                            time_limit=time_limit, ray_offset_scale=ray_offset_scale,
                            sphere_set=sphere_set)
    with no_cyclic_gc():  # objects by the 10^4: collections would re-scan them
        scene_dict = translate(model, options)
        # Serially: a mesh plugin's constructor waits on Dr.Jit (params.update() evaluates),
        # and a thread waiting in Mitsuba's parallel loader runs the next pending constructor
        # inside that wait, so 1,000 meshes nested 1,000 constructors deep (RecursionError).
        # (Parallel is also slower with the Python plugins.)
        # Unoptimized: the scene's shapes are the dict's, in its order. Mitsuba's optimization
        # merges the meshes of one material into a plain mesh (planes stopped being planes)
        # through a hash table keyed by the material's address, so the shapes came out in an
        # order that changed from one load to the next. A ray that ties between two shapes
        # (two walls' seam) hits the one Embree meets first, which follows that order: the
        # same scene gave another image in some loads. (The other optimization, merging
        # equal objects, would drop all but one of equal materials' keys; the translator
        # merges its meshes itself.)
        scene = mi.load_dict(scene_dict, parallel=False, optimize=False)
    return Loaded(model, options, scene_dict, scene, source_data(source, model))


def render(loaded: Loaded, spp: int | None = None, params=None):
    """The image as a Dr.Jit TensorXf (H, W, 3), linear. Differentiable w.r.t. ``params``
    (default: all of ``loaded.params``, if it has been used) through ``mi.render``.

    Traced in chunks within the loaded ``memory_budget`` and assembled where the tensor
    lives, without waiting for the chunks' kernels (with ``aa``, on the host: the
    refinement reads it; 16384 x 16384 works: a 3.2 GB tensor);
    ``loaded.integrator.render_array(loaded.scene)`` gives the numpy array, assembled on the
    host. A request no budget can hold raises
    ``BudgetError`` (raymitsuba.plugins.whitted.guards) before anything is traced."""
    from raymitsuba.backend import mitsuba

    mi = mitsuba()
    import drjit as dr  # after mitsuba(): the variant and libLLVM are chosen there

    if params is None and loaded._params is not None:
        params = loaded.params
        # mi.render walks every parameter it is given (8 per material) at each call; with
        # none that has gradients enabled there is nothing to attach: a primal render.
        # (Not made here when never used: only through it can a gradient have been enabled.)
        if not any(dr.grad_enabled(params[key]) for key in params.keys()):
            params = None
    return mi.render(loaded.scene, params=params, spp=int(spp or loaded.options.spp))
