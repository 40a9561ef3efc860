"""raymitsuba's Mitsuba plugins, one per file; :func:`register` makes them known to Mitsuba.

=================  =========  ===============================================
plugin name        kind       file
=================  =========  ===============================================
``raywhitted``     integrator ``whitted.py``: the recursive ray tracer
``rayphong``       BSDF       ``phong.py``: the .RAY material
``raytextured``    BSDF       ``textured.py``: a material times textures
``raychecker``     texture    ``checkerboard.py``: the plane checkerboard
``raylight``       emitter    ``light.py``: ambient/point/directional/spot
``raybackground``  emitter    ``background.py``: the background color
``rayplane``       shape      ``plane.py``: the infinite plane
``raytriangles``   shape      ``triangles.py``: a world-space mesh from arrays
=================  =========  ===============================================

Modules whose names start with ``_`` are pieces shared by plugins, not plugins:
``_mesh.py`` (an object-space tessellation to a mesh), and the Whitted integrator's
``_camera.py`` (camera rays, box filter), ``_protocol.py`` (what it reads from
the plugins), ``_surfaces.py`` (the surface table), ``_hits.py`` (the geometry
table: surface interactions by lookup), ``_lift.py`` (the terminator lift) and
``_tree.py`` (the ray tree).

Import this package only after a Mitsuba variant is set (see raymitsuba.backend).
"""

_registered = None


def register():
    """Register every plugin with the current Mitsuba variant (once per variant)."""
    global _registered
    import mitsuba as mi

    if _registered == mi.variant():
        return
    from . import background, checkerboard, light, phong, plane, textured, triangles, whitted

    mi.register_integrator("raywhitted", lambda props: whitted.Whitted(props))
    mi.register_bsdf("rayphong", lambda props: phong.Phong(props))
    mi.register_bsdf("raytextured", lambda props: textured.Textured(props))
    mi.register_texture("raychecker", lambda props: checkerboard.Checkerboard(props))
    mi.register_emitter("raylight", lambda props: light.Light(props))
    mi.register_emitter("raybackground", lambda props: background.Background(props))
    mi.register_shape("rayplane", lambda props: plane.Plane(props))
    mi.register_shape("raytriangles", lambda props: triangles.Triangles(props))
    _registered = mi.variant()
