"""The geometry and camera keys as scene parameters (raymitsuba/parameters.py): moving the
geometry, refusing what cannot move, and the interior derivative against finite
differences where no edge moves (a sphere, a cylinder or a triangle filling the frame:
every sample sees the same surface, so only the shading changes).

Tolerances: the central difference with h = 1e-3 (angles: 0.05 degree) of a smooth image has a truncation error
O(h^2) ~ 1e-6 and float32 noise ~1e-7 / 2h per pixel, averaged over ~600 terms; the
Jacobians of the keys are exact (affine keys) or O(1e-4 degree^2) (angles). Measured
errors are 1e-4 .. 4e-3 (the fov's: the sensor's float32 trigonometry); asserted 1 %.
"""

from __future__ import annotations

import pathlib

import numpy as np
import pytest

from support_edges import finite_difference, forward, image, loaded, reverse, weights

FILLED = """\
eye 0.2 0.3 5
lookat 0 0.1 0
fov 12
light 1 1 1 point 2 3 6
light 0.2 0.2 0.2 ambient
material 0.8 0.4 0.3 0.3 0.7 0.3 10 0 0 1
translate 0.1 0 0
rotateY 20
scale 2 2 2
sphere
"""
# FILLED's sphere textured (a grid): its texture coordinates move and turn with the keys;
# rotateX, first on the stack, turns it about its own centre: only its texture moves
TEXTURED = FILLED.replace("translate 0.1", "texture " + str(
    pathlib.Path(__file__).parent.parent / "scenes" / "textures" / "uvgrid.png") +
    "\nrotateX 37\ntranslate 0.1")
MIT = """\
eye 0.2 0.3 10 fov 12
surface 0.8 0.4 0.3 0.3 0.7 0.3 10 0 0 1
light 1 1 1 point 2 3 9
sphere 0.1 0 0 2.2
"""
MESH = """\
eye 0.1 0.1 10 fov 20
surface 0.8 0.4 0.3 0.3 0.7 0.4 10 0 0 1
light 1 1 1 point 1 2 9
triangles
v -9 -8 0
v 9 -8 -1
v 0 9 0.5
f 0 1 2
end
"""
CYLINDER = """\
eye 0.2 0.3 5
lookat 0 0.1 0
fov 12
light 1 1 1 point 2 3 6
light 0.2 0.2 0.2 ambient
material 0.8 0.4 0.3 0.3 0.7 0.3 10 0 0 1
translate 0.1 0 0
rotateY 20
rotateX 80
scale 2 2 3
cylinder
"""
TRIANGLE = """\
eye 0.1 0.1 5
fov 20
light 1 1 1 point 1 2 4
light 0.2 0.2 0.2 ambient
material 0.8 0.4 0.3 0.3 0.7 0.4 10 0 0 1
triangle -6 -5 0  6 -5 -1  0 6 0.5
"""


@pytest.fixture(scope="module")
def mi():
    from raymitsuba.backend import mitsuba

    return mitsuba()


@pytest.mark.parametrize("text, key, direction, h", [
    (FILLED, "translate1.offset", (0.3, -0.5, 0.2), 1e-3),
    (FILLED, "scale1.factors", (0.4, 0.4, 0.4), 1e-3),
    (FILLED, "rotateY1.angle", (1.0,), 0.05),  # degrees: the centre moves 0.2 * h radians
    (FILLED, "camera.eye", (0.3, 0.4, 0.2), 1e-3),
    (FILLED, "camera.lookat", (0.3, -0.2, 0.1), 1e-3),
    (FILLED, "camera.fov", (1.0,), 1e-2),
    (MIT, "sphere1.center", (0.3, -0.5, 0.2), 1e-3),
    (MIT, "sphere1.radius", (1.0,), 1e-3),
    (TRIANGLE, "triangle1.v1", (0.3, 0.5, -0.4), 1e-3),
    (MESH, "v2.position", (0.3, 0.5, -0.4), 1e-3),
    # a tessellated cylinder filling the frame: its vertices and normals move with the keys
    # (larger steps: its derivative is small where its normals turn, float32 noise larger)
    (CYLINDER, "translate1.offset", (0.3, -0.5, 0.2), 1e-2),
    (CYLINDER, "scale1.factors", (0.4, 0.1, -0.2), 3e-2),
    (CYLINDER, "rotateX1.angle", (1.0,), 0.2),
])
def test_interior_derivatives_match_finite_differences(mi, text, key, direction, h):
    reference = finite_difference(mi, text, key, direction, h, spp=1, width=24, height=18)
    grad = forward(mi, text, key, direction, 1, width=24, height=18)
    w = weights(18, 24)
    assert np.sum(w * grad) == pytest.approx(np.sum(w * reference), rel=0.01)
    rev = reverse(mi, text, key, w, 1, width=24, height=18) @ np.asarray(direction)
    assert rev == pytest.approx(np.sum(w * grad), rel=1e-4)


@pytest.mark.parametrize("key, direction, h", [
    ("translate1.offset", (0.3, -0.5, 0.2), 1e-3),
    ("scale1.factors", (0.4, 0.4, 0.4), 1e-3),
    ("rotateY1.angle", (1.0,), 0.05),  # the centre moves and the texture turns
    ("rotateX1.angle", (1.0,), 0.05),  # only the texture turns
])
def test_a_textured_spheres_texels_follow_its_keys(mi, key, direction, h):
    """The texture coordinates at a pixel move with the sphere's centre, radius and frame.
    The reference: the median of central differences at h, h / 3 and h / 10 -- over the
    bilinear texture's kinks one step's difference varies by up to 1.5 % (measured: the
    translate's -30.9, -31.1, -30.8, -30.5), hence 2 %. Without the frame's derivative the
    translate's came out +40.7 (the wrong sign) and the rotateX's 0."""
    reference = np.median([np.sum(weights(18, 24) * finite_difference(
        mi, TEXTURED, key, direction, step, spp=1, width=24, height=18))
        for step in (h, h / 3, h / 10)])
    grad = forward(mi, TEXTURED, key, direction, 1, width=24, height=18)
    assert np.sum(weights(18, 24) * grad) == pytest.approx(reference, rel=0.02)


def test_a_key_moves_the_geometry(mi):
    # the same image as the scene written with the new value (float32 round-off aside: the
    # sphere's transform reaches Mitsuba by another path, its inverse rounded differently)
    moved = image(loaded(mi, FILLED, 1, "translate1.offset", (0.3, 0.0, 0.0)))
    written = image(loaded(mi, FILLED.replace("translate 0.1 0 0", "translate 0.3 0 0"), 1))
    assert np.abs(moved - written).max() < 1e-5
    assert np.abs(moved - image(loaded(mi, FILLED, 1))).max() > 0.01
    eye = image(loaded(mi, FILLED, 1, "camera.eye", (0.2, 0.5, 5.0)))
    assert np.abs(eye - image(loaded(mi, FILLED.replace("eye 0.2 0.3 5", "eye 0.2 0.5 5"),
                                     1))).max() < 1e-5


def test_keys_that_cannot_move_are_refused(mi):
    from raymitsuba.format.writeback import ParameterError

    scene = loaded(mi, "translate 0 -1 0\nplane\nchecker" "board 0.5\nplane\n", 1)
    assert "checkerboard1.size" not in scene.params  # (moves checker lines only)
    scene.params["translate1.offset"] = mi.Point3f(0, -2, 0)
    with pytest.raises(ParameterError, match="plane"):
        scene.params.update()
    sphere = loaded(mi, FILLED, 1)
    sphere.params["scale1.factors"] = mi.Point3f(2, 3, 2)  # would make it an ellipsoid
    with pytest.raises(ParameterError, match="shapes stand for|represented"):
        sphere.params.update()


def test_a_tessellated_object_moves_with_the_mesh_it_was_loaded_with(mi):
    """A cylinder's mesh keeps its segment counts when a key moves it (nearer the camera it
    would get more): its vertices move with the key, its normals turn with it."""
    import drjit as dr

    def mesh(scene):
        params = mi.traverse(scene.scene)
        return (np.array(params["quadrics_0.vertex_positions"]).reshape(-1, 3),
                np.array(params["quadrics_0.vertex_normals"]).reshape(-1, 3))

    scene = loaded(mi, CYLINDER, 1)
    positions, normals = mesh(scene)
    # (the translate is first on the stack: its offset is in the cylinder's own frame, moved
    # to the world by the rotations and the scale after it, the linear part of to_world)
    linear = np.array(scene.model.objects[0].to_world)[:3, :3]
    scene.params["translate1.offset"] = mi.Point3f(0.1, 0.0, 2.0)
    scene.params.update()
    moved, turned = mesh(scene)
    assert moved.shape == positions.shape  # the mesh it was loaded with, not a new one
    assert len(mesh(loaded(mi, CYLINDER.replace("translate 0.1 0 0", "translate 0.1 0 2"),
                           1))[0]) != len(positions)  # (written in the file, it would differ)
    np.testing.assert_allclose(moved, positions + linear @ [0.0, 0.0, 2.0], atol=1e-5)
    np.testing.assert_array_equal(turned, normals)
    scene.params["scale1.factors"] = mi.Point3f(2.0, 3.0, 3.0)
    scene.params.update()
    _, turned = mesh(scene)
    assert np.abs(turned - normals).max() > 0.1
    np.testing.assert_allclose(np.linalg.norm(turned, axis=1), 1.0, atol=1e-5)
    assert dr.width(scene.params["scale1.factors"]) == 1


def test_a_linear_keys_jacobian_is_kept_while_the_rotations_stay(mi, monkeypatch):
    """translate1.offset's Jacobian depends on rotateY1.angle's value, not on its own: an
    update that moves the offset translates the scene once (the move), one that turns the
    rotation too computes the Jacobian again (six more translations: two per component).
    Either way the derivative is that of the scene loaded with those values written in."""
    import drjit as dr
    import raymitsuba

    from raymitsuba import parameters

    translations = []
    real = parameters.shape_geometry

    def counted(*args, **kwargs):  # (the real translation, counted)
        translations.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(parameters, "shape_geometry", counted)
    scene = loaded(mi, FILLED, 1)
    params = scene.params
    direction = mi.Point3f(0.3, -0.5, 0.2)

    def move(offset, angle):
        translations.clear()
        params["translate1.offset"] = mi.Point3f(*offset)
        params["rotateY1.angle"] = mi.Float(angle)
        dr.enable_grad(params["translate1.offset"])
        params.update()
        dr.set_grad(params["translate1.offset"], direction)
        result = raymitsuba.render(scene)
        dr.forward_to(result)
        return len(translations), dr.grad(result).numpy().astype(np.float64)

    def written(offset, angle):  # the same values written in the file
        text = FILLED.replace("translate 0.1 0 0", "translate %r %r %r" % offset) \
            .replace("rotateY 20", "rotateY %r" % angle)
        return forward(mi, text, "translate1.offset", (0.3, -0.5, 0.2), 1)

    move((0.12, 0.0, 0.0), 21.0)  # (the first Jacobian; both keys checked once)
    count, kept = move((0.15, 0.01, 0.0), 21.0)
    assert count == 1
    assert np.allclose(kept, written((0.15, 0.01, 0.0), 21.0), rtol=1e-4, atol=1e-5)
    count, again = move((0.15, 0.01, 0.0), 25.0)
    assert count == 7
    assert np.allclose(again, written((0.15, 0.01, 0.0), 25.0), rtol=1e-4, atol=1e-5)
    assert not np.allclose(again, kept, rtol=1e-2)
