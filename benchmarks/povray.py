"""Export a parsed .RAY scene to POV-Ray's scene language, for the benchmarks only, and
install POV-Ray where it is missing (:func:`ensure_povray`).

The export keeps the geometry, lights and the cost-relevant parts of the
materials (Phong highlight, mirror reflection, refraction with an index of
refraction, checkerboard), so that POV-Ray traces the same ray tree; the
images are close but not identical (POV-Ray's shading model differs in detail),
which does not matter for timing. Point lights have no distance falloff in
POV-Ray by default, as in the format. Both dialects export the same way (the
camera's vertical angle comes from ``Camera.vertical_fov``; MIT 6.837 mesh blocks
become one POV-Ray ``mesh`` per mesh of the model).
"""

from __future__ import annotations

import os
import shutil
import subprocess

import numpy as np

from raymitsuba.model import LightKind, ObjectKind, Scene


def ensure_povray():
    """Install POV-Ray 3.7 (Debian's ``povray``) with apt-get if it is missing and that is
    possible (root, apt-get); otherwise the benchmarks skip its rows."""
    if shutil.which("povray") or not shutil.which("apt-get") or os.geteuid() != 0:
        return
    print("installing povray with apt-get ...", flush=True)
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    subprocess.run(["apt-get", "update", "-qq"], capture_output=True, env=env)
    subprocess.run(["apt-get", "install", "-y", "-qq", "povray"], capture_output=True, env=env)


def vec(v):
    return f"<{v[0]:.9g}, {v[1]:.9g}, {v[2]:.9g}>"


def matrix(m):
    """POV-Ray's `matrix` keyword: 12 numbers, row-vector convention (p' = p M)."""
    a = np.array(m)
    rows = [a[:3, 0], a[:3, 1], a[:3, 2], a[:3, 3]]
    return "matrix <" + ", ".join(f"{x:.9g}" for r in rows for x in r) + ">"


def texture(material, checker):
    c = vec(material.color)
    pigment = f"pigment {{ checker color rgb {c} color rgb 0 scale {checker} }}" if checker \
        else f"pigment {{ color rgb {c} filter {material.refractivity:.6g} }}"
    return (f"texture {{ {pigment} finish {{ ambient {material.ambient_mix:.6g} "
            f"diffuse {material.diffuse_mix:.6g} phong {material.specular_mix:.6g} "
            f"phong_size {max(material.phong_coeff, 1):.6g} reflection {material.reflectivity:.6g} }} }}"
            f" interior {{ ior {material.ior:.6g} }}")


PRIMITIVES = {
    ObjectKind.SPHERE: "sphere { <0, 0, 0>, 1",
    ObjectKind.PLANE: "plane { <0, 1, 0>, 0",
    ObjectKind.CYLINDER: "cylinder { <0, -0.5, 0>, <0, 0.5, 0>, 1",
    ObjectKind.CONE: "cone { <0, -0.5, 0>, 1, <0, 0.5, 0>, 0",
}


def export(scene: Scene, width: int, height: int, max_depth: int = 5) -> str:
    """POV-Ray text of ``scene``; ``max_depth`` bounces after the camera ray (POV-Ray's
    max_trace_level counts the camera ray too); POV-Ray's own adc_bailout (1/255) stays."""
    cam = scene.camera
    aspect = width / height
    fov = cam.vertical_fov(width, height)
    lines = ["#version 3.7;",
             f"global_settings {{ max_trace_level {max_depth + 1} assumed_gamma 1.0 "
             "ambient_light rgb 0 }",
             f"background {{ color rgb {vec(scene.background)} }}",
             # POV-Ray is left-handed: mirror x to keep the image the same way round.
             f"camera {{ perspective location {vec(cam.eye)} look_at {vec(cam.lookat)} "
             f"sky {vec(cam.up)} right <-{aspect:.9g}, 0, 0> "
             f"angle {2 * np.degrees(np.arctan(np.tan(np.radians(fov) / 2) * aspect)):.9g} }}"]
    ambient = np.zeros(3)
    for light in scene.lights:
        if light.kind is LightKind.AMBIENT:
            ambient += light.color
        elif light.kind is LightKind.POINT:
            lines.append(f"light_source {{ {vec(light.position)} color rgb {vec(light.color)} }}")
        elif light.kind is LightKind.DIRECTIONAL:
            far = -1e6 * np.asarray(light.direction) / np.linalg.norm(light.direction)
            lines.append(f"light_source {{ {vec(far)} color rgb {vec(light.color)} parallel point_at <0,0,0> }}")
        else:
            lines.append(f"light_source {{ {vec(light.position)} color rgb {vec(light.color)} spotlight "
                         f"point_at {vec(np.add(light.position, light.direction))} radius 89 falloff 90 "
                         f"tightness {min(light.shape, 100):.6g} }}")
    lines[1] = lines[1].replace("ambient_light rgb 0", f"ambient_light rgb {vec(ambient)}")
    for obj in scene.objects:
        material = scene.materials[obj.material]
        if obj.kind is ObjectKind.TRIANGLE:
            p = np.array(obj.vertices)
            head = "triangle { " + ", ".join(vec(v) for v in p)
        else:
            head = PRIMITIVES[obj.kind]
        lines.append(f"{head} {texture(material, obj.checker)} {matrix(obj.to_world)} }}")
    for mesh in scene.meshes:
        v = mesh.vertices
        faces = " ".join(f"triangle {{ {vec(v[i])}, {vec(v[j])}, {vec(v[k])} }}"
                         for i, j, k in mesh.faces)
        lines.append(f"mesh {{ {faces} {texture(scene.materials[mesh.material], None)} }}")
    return "\n".join(lines) + "\n"
