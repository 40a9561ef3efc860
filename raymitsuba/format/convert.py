"""MIT 6.837 to COMP 575: the COMP 575 text of a parsed MIT 6.837 scene.

:func:`to_comp575` writes a commented, readable COMP 575 file that renders the same
image as the MIT 6.837 scene at the scene's image size (its ``viewport``, else
512 x 512):

* the camera is written out in full (the dialects' defaults differ), with the fov
  converted to the vertical angle for that size (``Camera.vertical_fov``);
* COMP 575 has no ``viewport``: the size is written as a comment, and the file must
  be rendered at that size (``--width W --height H``) to give the same image;
* every ``surface`` becomes a ``material`` with eta = 1 / index, in file order, so
  ``mat{i}`` names the same material in both files;
* ``sphere cx cy cz r`` becomes ``scale r r r`` / ``translate cx cy cz`` / ``sphere``
  / ``pop`` / ``pop``, which builds exactly the same matrix;
* each face of a mesh block becomes a ``triangle`` with the same corners in the same
  order (fans already split, degenerate faces already dropped).

Numbers are written with Python's shortest round-trip spelling, so the COMP 575 file
parses to the same doubles.
"""

from __future__ import annotations

from typing import List

from raymitsuba.model import LightKind, Material, Scene, SceneObject, TriangleMesh


def number(x: float) -> str:
    """The shortest spelling that reads back as ``x`` (whole numbers without ``.0``)."""
    if x == int(x) and abs(x) < 1e15:
        return str(int(x))
    return repr(float(x))


def numbers(*values) -> str:
    return " ".join(number(v) for v in values)


def to_comp575(scene: Scene, source: str = "") -> str:
    """The COMP 575 text equivalent to the MIT 6.837 ``scene`` (``source``: its file name)."""
    width, height = scene.image_size()
    cam = scene.camera
    size = ("its `viewport`" if scene.viewport else "the default, as it has no `viewport`")
    out = [f"# {source or scene.file}, converted from the MIT 6.837 dialect to COMP 575 "
           f"by `raymitsuba convert`.",
           f"# Image size: {width} x {height} ({size}). COMP 575 has no viewport command:",
           f"# render this file with --width {width} --height {height} to get the same image.",
           "",
           f"# The 6.837 fov is horizontal ({number(cam.fov)} degrees); this one is vertical, "
           f"for {width} x {height}.",
           f"eye {numbers(*cam.eye)}",
           f"lookat {numbers(*cam.lookat)}",
           f"up {numbers(*cam.up)}",
           f"fov {number(cam.vertical_fov(width, height))}",
           f"background {numbers(*scene.background)}",
           ""]
    for light in scene.lights:
        out.append(_light(light))
    items = [((m.index, 0, 0), _material(m)) for m in scene.materials[1:]]
    items += [((o.material, 1, o.line), _sphere(o)) for o in scene.objects]
    items += [((m.material, 1, m.line), _mesh(m)) for m in scene.meshes]
    for _, lines in sorted(items, key=lambda item: item[0]):
        out.append("")
        out += lines
    return "\n".join(out) + "\n"


def _light(light) -> str:
    head = f"light {numbers(*light.color)} {light.kind.value}"
    if light.kind is LightKind.POINT:
        return f"{head} {numbers(*light.position)}"
    if light.kind is LightKind.DIRECTIONAL:
        return f"{head} {numbers(*light.direction)}"
    return head


def _material(m: Material) -> List[str]:
    values = (*m.color, m.ambient_mix, m.diffuse_mix, m.specular_mix, m.phong_coeff,
              m.reflectivity, m.refractivity, m.ior)
    return [f"# surface {m.index} (line {m.line}): eta = 1 / index = {number(m.ior)}",
            f"material {numbers(*values)}"]


def _sphere(obj: SceneObject) -> List[str]:
    (r, _, _, cx), (_, _, _, cy), (_, _, _, cz), _ = obj.to_world
    return [f"# sphere (line {obj.line}): centre ({numbers(cx, cy, cz)}), radius {number(r)}",
            f"scale {numbers(r, r, r)}", f"translate {numbers(cx, cy, cz)}", "sphere", "pop",
            "pop"]


def _mesh(mesh: TriangleMesh) -> List[str]:
    v = mesh.vertices
    lines = [f"# triangles block (line {mesh.block_line}), faces from line {mesh.line}: "
             f"{len(mesh.faces)} triangles"]
    lines += [f"triangle {numbers(*v[i], *v[j], *v[k])}" for i, j, k in mesh.faces]
    return lines
