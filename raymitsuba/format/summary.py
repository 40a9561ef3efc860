"""What ``raymitsuba check`` prints about a valid scene, and the bounds it needs.

:func:`object_bounds` gives the exact world-space axis-aligned bounding box of
every finite object under its (affine) ``to_world`` matrix ``M`` = [A | t]:

* sphere (an ellipsoid in the world): centre t, half-extent along axis i the
  norm of row i of A -- the largest of a_i . u over unit vectors u;
* cylinder: the segment t +- A e_y / 2 swept by the world image of the unit
  disk in the xz plane, whose half-extent along axis i is
  sqrt(A_i0^2 + A_i2^2); so the half-extent is |A_i1| / 2 + sqrt(A_i0^2 + A_i2^2);
* cone: the convex hull of that disk around the base centre t - A e_y / 2 and
  the apex t + A e_y / 2;
* triangle: its three transformed corners;
* a MIT 6.837 mesh: the vertices its faces use (already in world space).

Planes are infinite and have no box (``None``); :func:`scene_bounds` leaves them out.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import List, Optional, Tuple

from raymitsuba.format.commands import DIALECT_NAMES
from raymitsuba.format.lexer import MIT6837
from raymitsuba.model import (LightKind, ObjectKind, RayError, Scene, SceneObject, TriangleMesh,
                              Vec3)
from raymitsuba.format.parser import parse_file

Box = Tuple[Vec3, Vec3]  # (lower corner, upper corner)


def object_bounds(obj: SceneObject) -> Optional[Box]:
    """The world-space axis-aligned bounding box of ``obj``; None for a plane."""
    m = obj.to_world
    if obj.kind is ObjectKind.PLANE:
        return None
    if obj.kind is ObjectKind.TRIANGLE:
        assert obj.vertices is not None
        corners = [tuple(r[0] * x + r[1] * y + r[2] * z + r[3] for r in m[:3])
                   for x, y, z in obj.vertices]
        lo = tuple(min(c[i] for c in corners) for i in range(3))
        hi = tuple(max(c[i] for c in corners) for i in range(3))
        return lo, hi  # type: ignore[return-value]
    lo, hi = [], []
    for a0, a1, a2, t in m[:3]:
        if obj.kind is ObjectKind.SPHERE:
            half = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
            lo.append(t - half)
            hi.append(t + half)
            continue
        disk = math.sqrt(a0 * a0 + a2 * a2)  # half-extent of the transformed unit xz disk
        if obj.kind is ObjectKind.CYLINDER:
            half = abs(a1) / 2 + disk
            lo.append(t - half)
            hi.append(t + half)
        else:  # cone: base disk centred at t - a1/2, apex at t + a1/2
            base, apex = t - a1 / 2, t + a1 / 2
            lo.append(min(base - disk, apex))
            hi.append(max(base + disk, apex))
    return tuple(lo), tuple(hi)  # type: ignore[return-value]


def mesh_bounds(mesh: TriangleMesh) -> Box:
    """The box of the vertices the mesh's faces use."""
    used = {i for face in mesh.faces for i in face}
    points = [mesh.vertices[i] for i in used]
    lo = tuple(min(p[k] for p in points) for k in range(3))
    hi = tuple(max(p[k] for p in points) for k in range(3))
    return lo, hi  # type: ignore[return-value]


def scene_bounds(scene: Scene) -> Optional[Box]:
    """The union of the boxes of the scene's finite objects; None if it has none."""
    boxes = [b for b in map(object_bounds, scene.objects) if b is not None]
    boxes += [mesh_bounds(m) for m in scene.meshes]
    if not boxes:
        return None
    lo = tuple(min(b[0][i] for b in boxes) for i in range(3))
    hi = tuple(max(b[1][i] for b in boxes) for i in range(3))
    return lo, hi  # type: ignore[return-value]


def _number(v: float) -> str:
    text = f"{v:.6g}"
    return "0" if text == "-0" else text


def _vector(v) -> str:
    return "(" + ", ".join(_number(c) for c in v) + ")"


def _counts(kinds, order) -> str:
    counter = Counter(kinds)
    total = sum(counter.values())
    parts = [f"{counter[k]} {k.value}" for k in order if counter[k]]
    return f"{total}" + (f" ({', '.join(parts)})" if parts else "")


def summary_lines(scene: Scene) -> List[str]:
    """The indented summary of a valid scene, one line per item, without the file name."""
    cam = scene.camera
    box = scene_bounds(scene)
    if box is None:
        bounds = "none (no finite objects)"
    else:
        bounds = f"{_vector(box[0])} to {_vector(box[1])}"
    if any(o.kind is ObjectKind.PLANE for o in scene.objects):
        bounds += "  (planes are infinite and left out)"
    declared = len(scene.materials) - 1
    fov = _number(cam.fov) + (" (horizontal)" if cam.fov_axis == "x" else "")
    lines = [
        f"dialect    {DIALECT_NAMES[scene.dialect]}",
        f"camera     eye {_vector(cam.eye)}  lookat {_vector(cam.lookat)}  "
        f"up {_vector(cam.up)}  fov {fov}",
        f"background {_vector(scene.background)}",
        f"objects    {_counts((o.kind for o in scene.objects), list(ObjectKind))}",
        f"lights     {_counts((li.kind for li in scene.lights), list(LightKind))}",
        f"materials  {declared} declared (plus the default)",
        f"bounds     {bounds}",
        f"warnings   {len(scene.warnings)}",
    ]
    if scene.dialect == MIT6837:
        size = (f"{scene.viewport[0]} x {scene.viewport[1]} (viewport)" if scene.viewport
                else "512 x 512 (default; no viewport)")
        blocks = len({m.block_line for m in scene.meshes})
        meshes = (f"{len(scene.meshes)} ({scene.triangle_count} triangles, "
                  f"{blocks} block{'s' if blocks != 1 else ''})")
        lines[4:4] = [f"meshes     {meshes}"]
        lines[2:2] = [f"image      {size}"]
    return lines


def summarize(scene: Scene) -> str:
    """``FILE: ok`` followed by the indented :func:`summary_lines`."""
    return "\n".join([f"{scene.file}: ok"] + ["  " + line for line in summary_lines(scene)])


def check_scenes(paths, echo, dialect: str = "auto", list_params: bool = False) -> bool:
    """Parse every file of ``paths``; print summaries and diagnostics; True if all are valid.

    ``dialect`` is passed to the parser; ``list_params``: print each scene's parameter keys
    (``KEY LINE:COL VALUE...``, :func:`raymitsuba.format.writeback.key_listing`) instead of
    its summary. ``echo(text, err=False)`` prints a line (``click.echo``): summaries to stdout,
    diagnostics to stderr. Nothing but :class:`RayError` is expected from the parser.
    """
    all_valid = True
    for path in paths:
        try:
            scene = parse_file(path, dialect)
        except RayError as exc:
            for diagnostic in exc.diagnostics:
                echo(diagnostic.format(), err=True)
            n = len(exc.errors)
            echo(f"{exc.diagnostics[0].file}: invalid, {n} error{'s' if n != 1 else ''}", err=True)
            all_valid = False
            continue
        for diagnostic in scene.warnings:
            echo(diagnostic.format(), err=True)
        if list_params:
            from raymitsuba.format.writeback import key_listing

            with open(path, "rb") as f:
                data = f.read()
            for line in key_listing(scene, data):
                echo(line)
        else:
            echo(summarize(scene))
    return all_valid
