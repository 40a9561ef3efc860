"""raymitsuba: a differentiable renderer for the classic .RAY scene format, on Mitsuba 3."""

from raymitsuba.model import (Camera, Diagnostic, Light, LightKind, Material, ObjectKind,
                              RayError, Scene, SceneObject, Severity, Texture, TriangleMesh)

__version__ = "0.1.0"
__all__ = ["Camera", "Diagnostic", "Light", "LightKind", "Material", "ObjectKind", "RayError",
           "Scene", "SceneObject", "Severity", "Texture", "TriangleMesh",
           "parse", "parse_file", "parse_text", "load", "render", "translate", "Loaded"]


def __getattr__(name):
    # Lazy: `import raymitsuba` and `raymitsuba check` do not load Mitsuba.
    if name in ("parse", "parse_file", "parse_text"):
        from raymitsuba.format import parser
        return getattr(parser, name)
    if name in ("load", "render", "translate", "Loaded"):
        from raymitsuba import api
        return getattr(api, name)
    raise AttributeError(name)
