"""raymitsuba's Mitsuba plugins, one per file; :func:`register` makes them known to Mitsuba.

=================  =========  ===============================================
plugin name        kind       file
=================  =========  ===============================================
``raywhitted``     integrator ``whitted/``: the recursive ray tracer (a package)
``rayphong``       BSDF       ``phong.py``: the .RAY material
``raytextured``    BSDF       ``textured.py``: a material times textures
``raysurfaceset``  BSDF       ``surfaceset.py``: a surface per primitive (sphere set)
``raychecker``     texture    ``checkerboard.py``: the plane checkerboard
``raylight``       emitter    ``light.py``: ambient/point/directional/spot
``raybackground``  emitter    ``background.py``: the background color
``rayplane``       shape      ``plane.py``: the infinite plane
``raytriangles``   shape      ``triangles.py``: a world-space mesh from arrays
=================  =========  ===============================================

``_mesh.py`` is not a plugin: the shape plugins' shared object-space tessellation to a
mesh. The integrator's own parts live in its package, ``whitted/`` (see its index).

Import this package only after a Mitsuba variant is set (see raymitsuba.backend).
"""

_registered = None


def register():
    """Register every plugin with the current Mitsuba variant (once per variant)."""
    global _registered
    import mitsuba as mi

    if _registered == mi.variant():
        return
    from . import (background, checkerboard, light, phong, plane, surfaceset, textured,
                   triangles, whitted)

    mi.register_integrator("raywhitted", lambda props: whitted.Whitted(props))
    mi.register_bsdf("rayphong", lambda props: phong.Phong(props))
    mi.register_bsdf("raytextured", lambda props: textured.Textured(props))
    mi.register_bsdf("raysurfaceset", lambda props: surfaceset.SurfaceSet(props))
    mi.register_texture("raychecker", lambda props: checkerboard.Checkerboard(props))
    mi.register_emitter("raylight", lambda props: light.Light(props))
    mi.register_emitter("raybackground", lambda props: background.Background(props))
    mi.register_shape("rayplane", lambda props: plane.Plane(props))
    mi.register_shape("raytriangles", lambda props: triangles.Triangles(props))
    _registered = mi.variant()
