"""The geometry table (plugins/whitted/hits.py): surface interactions by lookup, against Mitsuba's
own ``scene.ray_intersect`` on the same rays -- the same bits on meshes, the same up to
float rounding of uv on analytic spheres -- and the same derivatives along the ray."""

import numpy as np
import pytest

from support import load_ray

SCENE = """\
eye 0.3 1.2 6
lookat 0 0.3 0
light 1 1 1 point 2 4 5
material 0.8 0.3 0.2 0.2 0.7 0.3 20 0 0 1
translate -1.4 0.5 0
sphere
pop
scale 0.6 0.9 0.6
translate 0 0.6 0
sphere
pop
pop
translate 1.4 0 0
cylinder
pop
checkerboard 1
translate 0 -0.5 0
plane
pop
checkerboard -1
triangle -3 0 -2  3 0 -2  0 3 -2
"""


@pytest.fixture(scope="module")
def hits(mitsuba):
    """(scene, rays through every pixel, Mitsuba's interactions, the table's interactions)."""
    from raymitsuba.plugins.whitted.camera import camera_rays
    from raymitsuba.plugins.whitted.hits import HitTable

    mi = mitsuba
    scene = load_ray(SCENE, 48, 36).scene
    table = HitTable().update(scene)
    assert table.supported
    ray = camera_rays(scene.sensors()[0], 48, 36, 1)
    want = scene.ray_intersect(ray, ray_flags=mi.RayFlags.AllNonDifferentiable, coherent=True)
    return scene, table, ray, want, table.intersect(scene, ray, True)


def fields(si):
    return {"t": si.t, "p": si.p, "n": si.n, "sh_n": si.sh_frame.n, "uv": si.uv}


def test_the_scene_has_every_kind_of_shape(hits):
    scene, *_ = hits
    shapes = scene.shapes()
    assert any(shape.class_name() == "Sphere" for shape in shapes)
    assert any(shape.is_mesh() and shape.has_vertex_normals() for shape in shapes)  # smooth
    assert any(shape.is_mesh() and not shape.has_vertex_normals() for shape in shapes)  # flat


def test_same_hits_as_mitsuba(mitsuba, hits):
    import drjit as dr

    _, _, _, want, got = hits
    valid = np.array(want.is_valid())
    assert np.array_equal(valid, np.array(got.is_valid())) and valid.sum() > 500
    assert np.array_equal(np.array(dr.reinterpret_array(mitsuba.UInt32, want.shape)),
                          np.array(dr.reinterpret_array(mitsuba.UInt32, got.shape)))
    assert np.array_equal(np.array(want.prim_index)[valid], np.array(got.prim_index)[valid])


def test_mesh_fields_are_mitsubas_bits_and_sphere_uv_close(mitsuba, hits):
    import drjit as dr

    scene, _, _, want, got = hits
    valid = np.array(want.is_valid())
    spheres = {dr.reinterpret_array(mitsuba.UInt32, mitsuba.ShapePtr(s))[0]
               for s in scene.shapes() if s.class_name() == "Sphere"}
    on_sphere = np.isin(np.array(dr.reinterpret_array(mitsuba.UInt32, want.shape)), list(spheres))
    assert on_sphere[valid].sum() > 50 and (~on_sphere[valid]).sum() > 300
    for name, value in fields(want).items():
        a = np.array(value).reshape(-1, valid.size)[:, valid]
        b = np.array(fields(got)[name]).reshape(-1, valid.size)[:, valid]
        # meshes: the same bits; spheres: the table solves the hit itself (float32 rounding)
        assert np.array_equal(a[:, ~on_sphere[valid]], b[:, ~on_sphere[valid]]), name
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-5, err_msg=name)


def test_sphere_hits_are_as_accurate_as_mitsubas(mitsuba, hits):
    """The table's sphere distance (hits.sphere_hit: the root from the ray's closest approach
    to the centre) against the float64 root of the same float32 ray and sphere: no further
    off than Mitsuba's own sphere, in the median and the worst case."""
    import drjit as dr

    scene, table, ray, want, got = hits
    shape_ids = np.array(dr.reinterpret_array(mitsuba.UInt32, want.shape))
    sphere = [s for s in scene.shapes() if s.class_name() == "Sphere"][0]
    on = np.array(want.is_valid()) & (shape_ids == dr.reinterpret_array(
        mitsuba.UInt32, mitsuba.ShapePtr(sphere))[0])
    row = table.rows_by_name[sphere.id()]
    c = np.array(table.center).reshape(3, -1)[:, row].astype(np.float64)
    r = float(np.array(table.radius)[row])
    o = np.array(ray.o).reshape(3, -1)[:, on].T.astype(np.float64)
    d = np.array(ray.d).reshape(3, -1)[:, on].T.astype(np.float64)
    oc = o - c
    a, b = (d * d).sum(1), (oc * d).sum(1)
    exact = (-b - np.sqrt(b * b - a * ((oc * oc).sum(1) - r * r))) / a
    ours = np.abs(np.array(got.t)[on] - exact)
    theirs = np.abs(np.array(want.t)[on] - exact)
    assert on.sum() > 50
    assert np.median(ours) <= np.median(theirs) and ours.max() <= theirs.max()


def test_derivatives_follow_the_ray_as_mitsubas(mitsuba, hits):
    # d(t, p, uv)/d(ray direction) in forward mode, both ways.
    import drjit as dr

    mi = mitsuba
    scene, table, ray, _, _ = hits
    theta = mi.Float(0.0)
    dr.enable_grad(theta)
    moved = mi.Ray3f(ray.o, dr.normalize(ray.d + mi.Vector3f(theta, 0.5 * theta, 0.0)))
    want = scene.ray_intersect(moved, ray_flags=mi.RayFlags.AllNonDifferentiable, coherent=False)
    got = table.intersect(scene, moved)
    outputs = [want.t, want.p, got.t, got.p]
    dr.set_grad(theta, 1.0)
    dr.forward_to(*outputs)
    grads = [np.array(dr.grad(o)) for o in outputs]
    valid = np.array(want.is_valid())
    for a, b in ((grads[0], grads[2]), (grads[1], grads[3])):
        a = a.reshape(-1, valid.size)[:, valid]
        b = b.reshape(-1, valid.size)[:, valid]
        assert np.abs(a).max() > 0.1
        np.testing.assert_allclose(b, a, rtol=1e-2, atol=1e-3)  # float32; grazing hits


def test_known_hits_are_the_tracers_on_their_faces_and_extend_them(mitsuba, hits):
    """HitTable.known_hits (the boundary terms' hits on the surface a pair sees): on the face
    the ray tracer found, the same interaction -- the same bits on spheres (both solve the
    root from the table), within float32 rounding on meshes (the plane's point instead of
    Embree's); on a face the ray does not reach, the point of its plane (the triangle's z =
    -2); on a sphere the ray's line misses, no hit."""
    import drjit as dr

    mi = mitsuba
    from raymitsuba.plugins.whitted.hits import NO_SHAPE

    scene, table, ray, want, got = hits
    ids = dr.reinterpret_array(mi.UInt32, want.shape)
    valid = np.array(want.is_valid())
    known = table.intersect(scene, ray, True, table.known_hits(
        ray, dr.select(want.is_valid(), ids, NO_SHAPE), want.prim_index, want.t))
    assert np.array_equal(np.array(known.is_valid()), valid)
    spheres = {dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]
               for s in scene.shapes() if s.class_name() == "Sphere"}
    on_sphere = np.isin(np.array(ids), list(spheres)) & valid
    for name, value in fields(got).items():
        a = np.array(value).reshape(-1, valid.size)
        b = np.array(fields(known)[name]).reshape(-1, valid.size)
        assert np.array_equal(a[:, on_sphere], b[:, on_sphere]), name
        scale = 1e-4 * max(1.0, float(np.abs(a[:, valid]).max()))  # (t: ~10 units)
        np.testing.assert_allclose(b[:, valid], a[:, valid], rtol=0, atol=scale, err_msg=name)

    lanes = dr.width(ray.d)
    triangle = [s for s in scene.shapes() if s.is_mesh() and s.face_count() == 1][0]
    tri_id = dr.reinterpret_array(mi.UInt32, mi.ShapePtr(triangle))[0]
    plane = table.known_hits(ray, dr.full(mi.UInt32, tri_id, lanes), dr.zeros(mi.UInt32, lanes),
                             dr.full(mi.Float, 1.0, lanes))
    point = np.array(ray(plane.t))
    assert np.array(plane.is_valid()).all()  # (every ray goes towards -z)
    np.testing.assert_allclose(point[2], -2.0, atol=1e-5)
    assert (np.abs(point[0]) > 3).any()  # (beyond the triangle's corners)

    sphere = [s for s in scene.shapes() if s.class_name() == "Sphere"][0]
    sphere_id = dr.reinterpret_array(mi.UInt32, mi.ShapePtr(sphere))[0]
    on = table.known_hits(ray, dr.full(mi.UInt32, sphere_id, lanes), dr.zeros(mi.UInt32, lanes),
                          dr.full(mi.Float, 1.0, lanes))
    row = table.rows_by_name[sphere.id()]
    c = np.array(table.center).reshape(3, -1)[:, row].astype(np.float64)
    r = float(np.array(table.radius)[row])
    o = np.array(ray.o).reshape(3, -1).T.astype(np.float64)
    d = np.array(ray.d).reshape(3, -1).T.astype(np.float64)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    miss = np.linalg.norm(np.cross(c - o, d), axis=1)  # the line's distance to the centre
    clear = np.abs(miss - r) > 1e-4
    assert np.array_equal(np.array(on.is_valid())[clear], (miss < r)[clear])
    assert (miss < r).sum() > 50 and (miss > r).sum() > 500
    # a sphere the line meets behind the ray (both roots t < 0): no hit, as for the tracer
    back = mi.Ray3f(ray.o, -ray.d)
    behind = table.known_hits(back, dr.full(mi.UInt32, sphere_id, lanes),
                              dr.zeros(mi.UInt32, lanes), dr.full(mi.Float, 1.0, lanes))
    assert not np.array(behind.is_valid()).any()
    traced = scene.ray_intersect_preliminary(back)
    found = np.array(dr.reinterpret_array(mi.UInt32, traced.shape)) == sphere_id
    assert not (found & np.array(traced.is_valid())).any()


def test_a_shape_outside_the_table_falls_back_to_mitsuba(mitsuba):
    # Mitsuba's analytic disk: not in the table; the render still shades it.
    from raymitsuba.plugins.whitted.hits import HitTable

    mi = mitsuba
    loaded = load_ray("light 1 1 1 point 0 0 5\nsphere\n", 8, 8)
    scene_dict = dict(loaded.scene_dict)
    scene_dict["extra"] = {"type": "disk", "bsdf": {"type": "ref", "id": "mat0"},
                           "to_world": mi.ScalarTransform4f().translate([0, 0, -3])}
    scene = mi.load_dict(scene_dict)
    assert not HitTable().update(scene).supported
    image = np.array(mi.render(scene))
    assert image.shape == (8, 8, 3) and image.max() > 0


def test_sphere_rows_are_read_as_mi_traverse_reads_them(mitsuba):
    # The table reads each sphere's transform directly (shape_property, sphere_rows), not
    # through mi.traverse and dr.slice of the whole matrices: the same values, bit for bit.
    import drjit as dr

    from raymitsuba.plugins.whitted.hits import HitTable, shape_property, sphere_rows

    mi = mitsuba
    text = "light 1 1 1 point 0 0 5\n" + "".join(
        f"rotateZ {17 * k}\nrotateX {29 * k}\nscale {0.2 + 0.1 * k} {0.2 + 0.1 * k} "
        f"{0.2 + 0.1 * k}\ntranslate {k - 2} {0.5 * k} {-k}\nsphere\npop\npop\npop\npop\n"
        for k in range(5))
    scene = load_ray(text, 8, 8).scene
    spheres = [s for s in scene.shapes() if s.class_name() == "Sphere"]
    assert len(spheres) == 5
    table = HitTable().update(scene)
    first = np.array(table.first)
    for shape in spheres:
        row = first[dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0]]
        to_world = mi.traverse(shape)["to_world"]
        assert shape_property(shape, "to_world") == to_world
        matrix = np.array(dr.slice(to_world.matrix, 0), np.float32)
        inverse = np.array(dr.slice(to_world.inverse_transpose, 0), np.float32).T
        center, axis, to_object = (np.array(v, np.float32) for v in sphere_rows(to_world))
        assert np.array_equal(center, matrix[:3, 3]) and np.array_equal(axis, matrix[:3, 0])
        assert np.array_equal(to_object, inverse[:3, :].T)
        assert sphere_rows(to_world, uv=False)[2] is None
        # and the table's row of this sphere holds them
        assert np.array_equal(np.array([np.array(c)[row] for c in table.center]), center)
        np.testing.assert_array_equal(np.array(table.radius)[row],
                                      np.float32(np.linalg.norm(axis.astype(np.float64))))
        assert np.array_equal(np.array(table.to_object).reshape(-1, 4, 3)[row], to_object)


def test_a_table_without_uv_has_the_same_hits_and_zero_sphere_uv(mitsuba, hits):
    # update(scene, uv=False) (no checkerboard, no image texture) skips the spheres'
    # world-to-object matrices: the same t, p, n; sphere uv 0; meshes' uv unchanged.
    import drjit as dr

    from raymitsuba.plugins.whitted.hits import HitTable

    scene, table, ray, _, with_uv = hits
    plain = HitTable().update(scene, uv=False)
    assert plain.to_object is None and not plain.uv
    got = plain.intersect(scene, ray, True)
    valid = np.array(with_uv.is_valid())
    a, b = fields(with_uv), fields(got)
    for name in ("t", "p", "n", "sh_n"):
        assert np.array_equal(np.array(a[name]), np.array(b[name])), name
    spheres = {dr.reinterpret_array(mitsuba.UInt32, mitsuba.ShapePtr(s))[0]
               for s in scene.shapes() if s.class_name() == "Sphere"}
    on_sphere = np.isin(np.array(dr.reinterpret_array(mitsuba.UInt32, got.shape)), list(spheres))
    uv, uv_with = np.array(b["uv"]), np.array(a["uv"])
    assert np.all(uv[:, valid & on_sphere] == 0)
    assert np.array_equal(uv[:, valid & ~on_sphere], uv_with[:, valid & ~on_sphere])
    # asked for uv later, the same table rebuilds with them; asked without, it keeps them
    assert plain.update(scene, uv=True).to_object is not None and plain.uv
    assert table.update(scene, uv=False).to_object is not None


def test_the_integrator_reads_sphere_uv_only_for_textures(mitsuba, tmp_path):
    # The geometry table skips the spheres' uv unless a surface has a checkerboard or an
    # image texture; a textured sphere still gets its texture's two halves.
    from PIL import Image

    import raymitsuba

    plain = raymitsuba.load("eye 0 0 5\nlight 1 1 1 point 0 0 5\nsphere\n", width=24, height=24)
    tracer = plain.integrator.tracer
    assert not tracer.scene_terms(plain.scene).geometry.uv
    texture = np.zeros((2, 2, 3), np.uint8)
    texture[:, 0] = (255, 0, 0)  # u < 1/2: red; u >= 1/2: green
    texture[:, 1] = (0, 255, 0)
    Image.fromarray(texture).save(tmp_path / "halves.png")
    path = tmp_path / "textured.ray"
    path.write_text("eye 0 0 5\nlight 1 1 1 point 0 0 5\ntexture halves.png\nrotateX 90\n"
                    "sphere\n")
    textured = raymitsuba.load(str(path), width=24, height=24)
    assert textured.integrator.tracer.scene_terms(textured.scene).geometry.uv
    image = textured.integrator.render_array(textured.scene)
    red = image[..., 0] > image[..., 1] + 0.05
    green = image[..., 1] > image[..., 0] + 0.05
    assert red.sum() > 20 and green.sum() > 20


def test_the_normal_at_a_tangent_point_follows_the_surface(mitsuba, hits):
    """``normal_at`` (ray differentials' curvature, differentials.py): at the hit itself the
    shading normal; at the point where a ray a hundredth of a pixel away meets the hit's
    tangent plane, that ray's own shading normal to first order (spheres, the ellipsoid, the
    smooth cylinder; a flat face's normal does not change)."""
    import drjit as dr

    from raymitsuba.plugins.whitted.camera import camera_rays
    from raymitsuba.plugins.whitted.differentials import tangent_point

    mi = mitsuba
    scene, table, ray, _, si = hits
    hit = si.is_valid()
    at_hit = table.normal_at(si, si.p, hit)
    valid = np.array(hit)
    assert np.abs(np.array(at_hit - si.sh_frame.n))[:, valid].max() < 1e-5
    # the pixels' rays moved by 0.01 pixel in x
    moved = camera_rays(scene.sensors()[0], 48 * 100, 36, 1)
    index = dr.arange(mi.UInt32, 48 * 36)
    moved = dr.gather(mi.Ray3f, moved, (index // 48) * 4800 + (index % 48) * 100 + 51)
    actual = table.intersect(scene, moved, False)
    p, met = tangent_point(si, moved.o, moved.d)
    predicted = np.array(table.normal_at(si, p, hit & met))
    same = valid & (np.array(dr.reinterpret_array(mi.UInt32, actual.shape))
                    == np.array(dr.reinterpret_array(mi.UInt32, si.shape))) \
        & (np.array(actual.prim_index) == np.array(si.prim_index))
    change = np.linalg.norm(np.array(actual.sh_frame.n) - np.array(si.sh_frame.n), axis=0)
    error = np.linalg.norm(np.array(actual.sh_frame.n) - predicted, axis=0)
    curved = same & (change > 1e-4)
    assert curved.sum() > 300
    # the error against the change: measured median 1.6e-4, 95th percentile below 0.01; the
    # largest, 0.18, at grazing hits near a silhouette, where the tangent plane leaves the
    # surface fastest (second order)
    ratio = error[curved] / change[curved]
    assert np.median(ratio) < 1e-3 and np.quantile(ratio, 0.95) < 0.02 and ratio.max() < 0.5


def test_a_flat_meshs_coplanar_faces_are_one_surface_and_a_smooth_meshs_are_not(mitsuba, hits):
    """``surface_key`` (path signatures, signature.py): the plane's faces (of its rings) share
    one key, the smooth cylinder's faces have their own."""
    import drjit as dr

    scene, table, _, _, si = hits
    key = np.array(table.surface_key(si, si.is_valid()))
    shape = np.array(dr.reinterpret_array(mitsuba.UInt32, si.shape))
    prim = np.array(si.prim_index)
    plane = [dr.reinterpret_array(mitsuba.UInt32, mitsuba.ShapePtr(s))[0]
             for s in scene.shapes() if s.is_mesh() and not s.has_vertex_normals()
             and s.face_count() > 2]
    cylinder = [dr.reinterpret_array(mitsuba.UInt32, mitsuba.ShapePtr(s))[0]
                for s in scene.shapes() if s.is_mesh() and s.has_vertex_normals()]
    on_plane = np.isin(shape, plane) & np.array(si.is_valid())
    assert len(set(prim[on_plane])) > 2 and len(set(key[on_plane])) == 1
    on_cylinder = np.isin(shape, cylinder) & np.array(si.is_valid())
    assert on_cylinder.sum() > 20 and (key[on_cylinder] == prim[on_cylinder]).all()


def test_a_mesh_without_declared_neighbours_has_them_from_its_positions(mitsuba):
    """The geometry table's neighbours: a tessellated cylinder's are the ones its template
    declares (``raytriangles``' ``neighbours``); two ``triangle`` lines that share an edge
    (one mesh of unshared vertices, no declaration) meet by their corners' positions."""
    from raymitsuba.plugins.whitted.hits import NO_NEIGHBOUR, HitTable

    text = ("eye 0 0 5\nlookat 0 0 0\nlight 1 1 1 point 0 0 5\n"
            "material 0.5 0.5 0.5 0.2 0.7 0 1 0 0 1\n"
            "triangle 0 0 0  1 0 0  1 1 0\ntriangle 0 0 0  1 1 0  0 1 0\n"
            "translate 3 0 0\ncylinder\n")
    scene = load_ray(text, 8, 6).scene
    table = HitTable().update(scene)
    across = table.neighbours().numpy().reshape(-1, 3)
    for face0, count, _, _, declared in table.mesh_ranges:
        mine = across[face0:face0 + count]
        if declared is None:  # the two triangles
            assert mine.tolist() == [[NO_NEIGHBOUR, NO_NEIGHBOUR, 1], [0, NO_NEIGHBOUR, NO_NEIGHBOUR]]
        else:
            assert (mine != NO_NEIGHBOUR).all() and (mine < count).all()
    assert sum(declared is not None for *_, declared in table.mesh_ranges) == 1
