"""The translator's scene dict: which Mitsuba object stands for each .RAY construct, under
which id. The ids are the public parameter names (mat{i}, light{j}, background)."""

import numpy as np
import pytest

from support import intersect_sphere, normalize


@pytest.fixture(scope="module")
def translate(mitsuba):
    from raymitsuba.format.parser import parse_text
    from raymitsuba.translate import Options, translate as run

    def go(text, **options):
        return run(parse_text(text), Options(**{"width": 16, "height": 16, **options}))

    return go


def _shapes(d):
    return {k: v for k, v in d.items() if isinstance(v, dict) and "bsdf" in v}


def test_ids_of_materials_lights_background_integrator_and_sensor(translate):
    d = translate("eye 1 2 3\nfov 30\nbackground 0.1 0.2 0.3\n"
                  "light 1 1 1 ambient\n"
                  "material 1 0 0  0.1 0.2 0.3 4  0.5 0.6 1.7\n"
                  "light 0.5 0.5 0.5 point 1 2 3\n"
                  "material 0 1 0  1 1 0 1  0 0 1\n"
                  "light 1 0 0 directional 0 -1 0\n"
                  "light 0 0 1 spotlight 0 5 0  0 -2 0  7\n", width=20, height=10, spp=4,
                  max_depth=3)
    assert d["type"] == "scene"
    assert d["integrator"] == {"type": "raywhitted", "max_depth": 3}
    sensor = d["sensor"]
    assert sensor["type"] == "perspective" and sensor["fov"] == 30.0 and sensor["fov_axis"] == "y"
    assert (sensor["film"]["width"], sensor["film"]["height"]) == (20, 10)
    assert sensor["sampler"]["sample_count"] == 4
    assert d["background"]["type"] == "raybackground"
    assert list(d["background"]["color"]) == pytest.approx([0.1, 0.2, 0.3])

    # mat0 is the default material; `material` lines are numbered from 1 in file order.
    for key, color in (("mat0", [1, 1, 1]), ("mat1", [1, 0, 0]), ("mat2", [0, 1, 0])):
        assert d[key]["type"] == "rayphong" and d[key]["id"] == key
        assert list(d[key]["color"]) == pytest.approx(color)
    mat1 = d["mat1"]
    assert [mat1[f] for f in ("ambient_mix", "diffuse_mix", "specular_mix", "phong_coeff",
                              "reflectivity", "refractivity", "ior")] == \
        pytest.approx([0.1, 0.2, 0.3, 4, 0.5, 0.6, 1.7])
    # the default material: its color alone (the plugin has the defaults; see below)
    assert "ambient_mix" not in d["mat0"] and "specular_mix" not in d["mat0"]
    assert "mat3" not in d

    # light{j} counts `light` lines from 1, whatever their kind.
    assert [d[f"light{j}"]["kind"] for j in range(1, 5)] == \
        ["ambient", "point", "directional", "spotlight"]
    assert "light5" not in d
    assert list(d["light2"]["position"]) == pytest.approx([1, 2, 3])
    assert list(d["light3"]["direction"]) == pytest.approx([0, -1, 0])  # as written: travel
    spot = d["light4"]
    assert list(spot["position"]) == pytest.approx([0, 5, 0])
    assert list(spot["direction"]) == pytest.approx([0, -2, 0])
    assert spot["shape_coefficient"] == 7.0
    assert all(d[f"light{j}"]["type"] == "raylight" for j in range(1, 5))


def test_objects_share_their_material_by_reference(translate):
    d = translate("light 1 1 1 ambient\n"
                  "sphere\n"                                # before any material: mat0
                  "material 1 0 0  1 1 0 1  0 0 1\n"
                  "sphere\ncylinder\ncone\nplane\n"         # all mat1
                  "material 0 1 0  1 1 0 1  0 0 1\n"
                  "translate 0 3 0\nsphere\n")              # mat2
    shapes = _shapes(d)
    assert all(v["bsdf"]["type"] == "ref" for v in shapes.values())
    refs = {k: v["bsdf"]["id"] for k, v in shapes.items()}
    kinds = {k: v["type"] for k, v in shapes.items()}
    # Analytic spheres and planes one by one, named by line; the cylinder and the cone of
    # mat1 merged into one tessellated mesh.
    assert refs == {"sphere_2": "mat0", "sphere_4": "mat1", "quadrics_0": "mat1",
                    "plane_7": "mat1", "sphere_10": "mat2"}
    assert kinds == {"sphere_2": "sphere", "sphere_4": "sphere", "quadrics_0": "raytriangles",
                     "plane_7": "rayplane", "sphere_10": "sphere"}


def test_textured_surfaces_wrap_the_material(translate, tmp_path):
    from PIL import Image

    Image.new("RGB", (2, 2), (255, 0, 0)).save(tmp_path / "a.png")
    Image.new("RGB", (2, 2), (0, 255, 0)).save(tmp_path / "b.png")
    d = translate(f"light 1 1 1 ambient\nmaterial 1 1 1  1 1 0 1  0 0 1\n"
                  f"texture {tmp_path / 'a.png'}\n"
                  "sphere\ncylinder\n"                       # mat1 x a.png: one surface
                  f"texture {tmp_path / 'b.png'}\nsphere\n"  # mat1 x b.png: another
                  "texture none\ncone\n"                     # plain mat1
                  "checkerboard 0.5\nplane\n"                # mat1 x checker 0.5
                  "sphere\n")                                # checker: planes only -> mat1
    shapes = _shapes(d)
    refs = {k: v["bsdf"]["id"] for k, v in shapes.items()}
    # The cylinder (line 5) shares sphere 4's surface, the cone (line 9) is plain mat1:
    # two merged meshes.
    meshes = {refs[k] for k in shapes if k.startswith("quadrics_")}
    assert meshes == {refs["sphere_4"], "mat1"} and len(shapes) == 6
    assert refs["sphere_4"] != refs["sphere_7"]
    assert refs["sphere_12"] == "mat1"
    by_line = {4: refs["sphere_4"], 7: refs["sphere_7"], 11: refs["plane_11"]}
    surfaces = {k: v for k, v in d.items() if k.startswith("surface")}
    assert set(surfaces) == {by_line[4], by_line[7], by_line[11]}
    for key, surface in surfaces.items():
        assert surface["type"] == "raytextured" and surface["id"] == key
        assert surface["material"] == {"type": "ref", "id": "mat1"}
    a, b, checker = surfaces[by_line[4]], surfaces[by_line[7]], surfaces[by_line[11]]
    assert a["texture"]["type"] == "bitmap" and a["texture"]["filename"].endswith("a.png")
    assert b["texture"]["filename"].endswith("b.png")
    assert "checker" not in a and "texture" not in checker
    assert checker["checker"] == {"type": "raychecker", "size": 0.5}
    assert a["texture"]["raw"] is True  # linear values unless the sRGB option is on
    d = translate(f"light 1 1 1 ambient\ntexture {tmp_path / 'a.png'}\nsphere\n", srgb=True)
    assert d["surface0"]["texture"]["raw"] is False


@pytest.mark.parametrize("steps, kind", [
    ("", "sphere"),
    ("rotateX 30\nrotateY -70\nscale 2 2 2\ntranslate 1 2 3\n", "sphere"),
    ("scale 1 2 1\n", "raytriangles"),
    ("scale 2 1 1\nrotateZ 30\nscale 1 1 3\n", "raytriangles"),   # sheared
    ("rotateZ 30\nscale 1 1.0001 1\n", "raytriangles"),
    ("scale -1 1 1\n", "raytriangles"),                            # mirrored
])
def test_similarity_sphere_is_analytic_otherwise_a_smooth_mesh(translate, steps, kind):
    d = translate("light 1 1 1 ambient\n" + steps + "sphere\n")
    (shape,) = _shapes(d).values()
    assert shape["type"] == kind
    if kind == "raytriangles":
        from raymitsuba.geometry.tessellation import triangle_count

        faces = np.array(shape["faces"]).reshape(-1, 3)
        assert len(faces) >= triangle_count("sphere", 48) and "normals" in shape
        return
    # The analytic sphere's to_world: the unit sphere onto the transformed one, with its
    # pole (local +z, where Mitsuba's sphere puts it) on object +y (the format's pole).
    from raymitsuba.format.parser import parse_text

    model = np.array(parse_text("light 1 1 1 ambient\n" + steps + "sphere\n").objects[0].to_world)
    m = np.array(shape["to_world"].matrix, dtype=np.float64)
    np.testing.assert_allclose(m[:3, 3], model[:3, 3], atol=1e-5)
    np.testing.assert_allclose(m[:3, :3] @ [0, 0, 1], model[:3, :3] @ [0, 1, 0], atol=1e-5)
    radius = np.linalg.norm(model[:3, 0])
    points = normalize(np.random.default_rng(1).normal(size=(20, 3)))
    np.testing.assert_allclose(np.linalg.norm(points @ m[:3, :3].T, axis=1), radius, rtol=1e-5)


def test_triangles_merge_per_surface_in_world_space(translate):
    d = translate("light 1 1 1 ambient\n"
                  "translate 0 0 1\n"
                  "triangle 0 0 0  1 0 0  0 1 0\n"
                  "triangle 0 0 0  0 1 0  1 0 0\n"
                  "material 1 0 0  1 1 0 1  0 0 1\n"
                  "scale -1 1 1\n"                     # a mirroring transform
                  "triangle 0 0 0  1 0 0  0 1 0\n")
    meshes = {k: v for k, v in d.items() if k.startswith("triangles_")}
    assert len(meshes) == 2  # one mesh per surface (mat0, mat1)
    by_ref = {v["bsdf"]["id"]: v for v in meshes.values()}
    assert set(by_ref) == {"mat0", "mat1"}
    assert all(v["type"] == "raytriangles" for v in meshes.values())
    plain = np.array(by_ref["mat0"]["positions"]).reshape(-1, 3)
    np.testing.assert_allclose(plain, [[0, 0, 1], [1, 0, 1], [0, 1, 1],
                                       [0, 0, 1], [0, 1, 1], [1, 0, 1]])
    uv = np.array(by_ref["mat0"]["texcoords"]).reshape(-1, 2)
    np.testing.assert_allclose(uv, [[0, 0], [1, 0], [0, 1]] * 2)
    # Mirrored (translate, then scale -1 1 1): corners (0,0,1), (-1,0,1), (0,1,1). The
    # front side, carried by the inverse transpose, still faces +z, so the world winding
    # is reversed to keep it; each corner keeps its own texture coordinates.
    mirrored = np.array(by_ref["mat1"]["positions"]).reshape(-1, 3)
    uv = np.array(by_ref["mat1"]["texcoords"]).reshape(-1, 2)
    front = np.cross(mirrored[1] - mirrored[0], mirrored[2] - mirrored[0])
    assert front[2] > 0
    corners = {tuple(p): tuple(t) for p, t in zip(mirrored.tolist(), uv.tolist())}
    assert corners == {(0, 0, 1): (0, 0), (-1, 0, 1): (1, 0), (0, 1, 1): (0, 1)}


def test_translated_dict_loads_and_renders(mitsuba, translate):
    mi = mitsuba
    d = translate("light 1 1 1 ambient\nmaterial 0.5 0.25 1  1 1 0 1  0 0 1\nsphere\n",
                  width=9, height=9)
    scene = mi.load_dict(d)
    image = np.array(mi.render(scene))
    assert image.shape == (9, 9, 3)
    np.testing.assert_allclose(image[4, 4], [0.5, 0.25, 1.0], atol=1e-7)
    o = np.array([0.0, 0, 5])
    assert np.isnan(intersect_sphere(o, normalize([1.0, 1, -5]))) and image[0, 0].sum() == 0


# -- the MIT 6.837 dialect ------------------------------------------------------------------------
def test_mit_6837_meshes_are_raytriangles_per_surface_run(translate):
    d = translate("light 1 1 1 ambient\ntriangles\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                  "f 0 1 2 3\nsurface 1 0 0 1 1 0 1 0 0 1\nf 2 1 0\nend\n")
    assert [k for k in d if k.startswith(("mesh", "triangles_"))] == ["mesh0", "mesh1"]
    assert d["mesh0"]["type"] == "raytriangles" and d["mesh0"]["bsdf"]["id"] == "mat0"
    assert d["mesh1"]["bsdf"]["id"] == "mat1"
    np.testing.assert_array_equal(np.array(d["mesh0"]["positions"]).reshape(-1, 3),
                                  [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 0], [1, 1, 0], [0, 1, 0]])
    np.testing.assert_array_equal(np.array(d["mesh1"]["positions"]).reshape(-1, 3),
                                  [[1, 1, 0], [1, 0, 0], [0, 0, 0]])  # face order: the front side
    np.testing.assert_array_equal(np.array(d["mesh1"]["texcoords"]).reshape(-1, 2),
                                  [[0, 0], [1, 0], [0, 1]])


def test_mit_6837_spheres_are_analytic_even_several_on_a_line(translate):
    d = translate("light 1 1 1 ambient\nsphere 0 0 0 1 sphere 2 0 0 0.5 sphere 0 2 0 2\n")
    spheres = {k: v for k, v in _shapes(d).items() if v["type"] == "sphere"}
    assert len(spheres) == 3


def test_mit_6837_sensor_fov_is_vertical_for_the_image(translate):
    import math

    d = translate("fov 60\nsurface 1 1 1 1 1 0 1 0 0 1\n", width=16, height=8)
    expected = math.degrees(2 * math.atan(math.tan(math.radians(30)) * 8 / 16))
    assert d["sensor"]["fov"] == pytest.approx(expected, abs=1e-12)
    assert d["sensor"]["fov_axis"] == "y"


# -- geometry in bulk ----------------------------------------------------------------------------
TRANSFORMS = ["", "translate 1 2 3\n", "scale -1 1 1\n", "rotateX 30\nscale 2 -0.5 1\n",
              "rotateY 45\nscale -1 -2 -3\ntranslate 0 1 0\n"]  # two mirror, one does not


def _per_triangle(model):
    """The translator's triangles one by one, as it did before building them in bulk: world
    corners in winding order and their texture coordinates, one row per triangle."""
    rows = []
    for obj in model.objects:
        m = np.array(obj.to_world)
        corners = np.array(obj.vertices) @ m[:3, :3].T + m[:3, 3]
        order = [0, 2, 1] if np.linalg.det(m[:3, :3]) < 0 else [0, 1, 2]
        uv = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
        rows.append(np.concatenate([corners[order].ravel(), uv[order].ravel()]))
    return np.array(rows)


def test_triangles_in_bulk_match_one_by_one(translate):
    """A few hundred triangles under mirroring and non-mirroring transforms, interleaved:
    the bulk mesh has exactly the corners (float32), winding and texture coordinates of the
    triangle-by-triangle construction (as a set: the bulk groups them by transform)."""
    from raymitsuba.format.parser import parse_text

    rng = np.random.default_rng(3)
    lines = ["light 1 1 1 ambient\n"]
    for k in range(300):
        lines.append(TRANSFORMS[k % len(TRANSFORMS)])
        lines.append("triangle " + " ".join(f"{v:.4f}" for v in rng.uniform(-2, 2, 9)) + "\n")
        lines.append("reset\n")
    text = "".join(lines)
    (mesh,) = [v for k, v in translate(text).items() if k.startswith("triangles_")]
    got = np.concatenate([np.array(mesh["positions"]).reshape(-1, 9),
                          np.array(mesh["texcoords"]).reshape(-1, 6)], axis=1)
    want = _per_triangle(parse_text(text))
    want[:, :9] = want[:, :9].astype(np.float32)
    assert got.shape == want.shape == (300, 15)
    np.testing.assert_array_equal(got[np.lexsort(got.T)], want[np.lexsort(want.T)])


def test_placed_copies_match_one_by_one_and_face_outward():
    """Placing a template under k transforms at once gives each object's own placement, and
    every face's right-hand-rule normal agrees with its vertex normals (outward) in the
    world, mirrored or not; the vertices lie on the transformed primitive."""
    from raymitsuba.geometry import tessellation
    from support import rotation, scaling, stack, translation

    transforms = np.array([stack(scaling(1, 2, 0.5), rotation("x", 30), translation(1, 2, 3)),
                           stack(scaling(-1, 1, 1), rotation("y", 70)),
                           stack(scaling(0.3, -0.2, -1.5), translation(-4, 0, 1))])
    for kind in ("sphere", "cylinder", "cone"):
        template = tessellation.template(kind, 16)
        together = tessellation.placed(template, transforms)
        for k, m in enumerate(transforms):
            alone = tessellation.placed(template, m[None])
            v = slice(k * len(template.positions), (k + 1) * len(template.positions))
            np.testing.assert_array_equal(together.positions[v], alone.positions)
            np.testing.assert_array_equal(together.normals[v], alone.normals)
            f = slice(k * len(template.faces), (k + 1) * len(template.faces))
            np.testing.assert_array_equal(together.faces[f] - v.start, alone.faces)
        p = together.positions[together.faces]
        face_n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        assert np.all(np.einsum("ij,ij->i", face_n, together.normals[together.faces].sum(1)) > 0)
        merged = tessellation.merged([(template, transforms)])
        np.testing.assert_allclose(merged.positions, together.positions, rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(merged.faces, together.faces)
    sphere = tessellation.placed(tessellation.template("sphere", 16), transforms[:1])
    local = (sphere.positions - transforms[0, :3, 3]) @ np.linalg.inv(transforms[0, :3, :3]).T
    radius = np.linalg.norm(local, axis=1)  # on the unit sphere, up to chords and the overlap
    assert np.all(radius < 1.0 + 2e-4) and np.all(radius > np.cos(np.pi / 16) - 1e-3)


@pytest.mark.parametrize("kind", ["sphere", "cylinder", "cone"])
def test_triangle_counts_in_closed_form(kind):
    from raymitsuba.geometry import tessellation

    for m in (8, 12, 30, 48, 130, 768):
        assert len(tessellation.template(kind, m).faces) == tessellation.triangle_count(kind, m)


def _mesh_faces(d):
    return sum(np.array(v["faces"]).size // 3 for k, v in d.items() if k.startswith("quadrics_"))


QUADRICS = "".join(f"scale 1 2 1\ntranslate {x} 0 -10\n{kind}\nreset\n"
                   for x in range(-6, 7) for kind in ("sphere", "cylinder", "cone"))


def test_tessellation_budget_scales_segment_counts_down(translate):
    """Over the budget, every object's segment count is scaled down by one factor until the
    total fits; below it, the counts are those of the silhouette target."""
    free = _mesh_faces(translate(QUADRICS, width=64, height=64))
    budget = free // 3
    d = translate(QUADRICS, width=64, height=64, tessellation_budget=budget)
    assert budget * 0.8 < _mesh_faces(d) <= budget
    # The largest count scaled down still fits: halving the budget again halves about twice.
    smaller = _mesh_faces(translate(QUADRICS, width=64, height=64, tessellation_budget=budget // 4))
    assert smaller <= budget // 4


def test_tessellation_budget_gives_way_at_the_floor_then_refuses(translate):
    """At BUDGET_MIN_SEGMENTS the budget gives way up to the limit; past the limit the scene
    is refused with one line saying why, before any mesh is built."""
    from raymitsuba.geometry.tessellation import triangle_count
    from raymitsuba.translate import BUDGET_MIN_SEGMENTS, GeometryTooLarge

    floor = 13 * sum(int(triangle_count(k, BUDGET_MIN_SEGMENTS)) for k in ("sphere", "cylinder", "cone"))
    d = translate(QUADRICS, tessellation_budget=10, tessellation_limit=floor)
    assert _mesh_faces(d) == floor
    with pytest.raises(GeometryTooLarge) as info:
        translate(QUADRICS, tessellation_budget=10, tessellation_limit=floor - 1)
    message = str(info.value)
    assert "\n" not in message and f"need {floor} triangles" in message and "39 curved" in message


def test_a_material_passes_only_the_fields_off_their_default(translate, mitsuba):
    # The rayphong gets a field only where it differs from the default (down to the sign of
    # a zero); loaded, every material has all of its values.
    import raymitsuba

    text = ("light 1 1 1 point 0 0 5\nmaterial 1 1 1  1 0.5 0 1  -0 0 1\nsphere\n"
            "material 0.5 0.5 0.5  1 1 0 1  0 0 1.5\ntranslate 2 0 0\nsphere\n")
    d = translate(text)
    assert set(d["mat0"]) == {"type", "id", "index", "color"}
    assert set(d["mat1"]) == {"type", "id", "index", "color", "diffuse_mix", "reflectivity"}
    assert d["mat1"]["diffuse_mix"] == 0.5 and str(d["mat1"]["reflectivity"]) == "-0.0"
    assert set(d["mat2"]) == {"type", "id", "index", "color", "ior"}
    params = raymitsuba.load(text, width=4, height=4).params
    want = {"mat0": (1, 1, 0, 1, 0, 0, 1), "mat1": (1, 0.5, 0, 1, -0.0, 0, 1),
            "mat2": (1, 1, 0, 1, 0, 0, 1.5)}
    for key, values in want.items():
        for name, value in zip(("ambient_mix", "diffuse_mix", "specular_mix", "phong_coeff",
                                "reflectivity", "refractivity", "ior"), values):
            got = float(params[f"{key}.{name}"][0])
            assert got == value and np.copysign(1, got) == np.copysign(1, value), (key, name)


def _groups_by_keys(objs):
    """The grouping Groups makes, computed plainly: (kind, material, texture, checker) keys
    numbered in order of first use, and each object's number."""
    numbers = {}
    group = [numbers.setdefault((o.kind, o.material, o.texture, o.checker), len(numbers))
             for o in objs]
    return group, list(numbers)


@pytest.mark.parametrize("checkered", [False, True])
def test_objects_group_by_kind_and_surface_in_order_of_first_use(checkered):
    """Groups numbers (kind, material, texture, checker) in order of first use, whether no
    object is textured (its numpy path) or one is (its dict path): a scene mixing kinds and
    materials, a material used by two kinds and again after others."""
    from raymitsuba.format.parser import parse_text
    from raymitsuba.translate import Groups

    text = ("sphere\nmaterial 1 0 0 1 1 0 1 0 0 1\nsphere\ncone\n"
            "material 0 1 0 1 1 0 1 0 0 1\ncylinder\nsphere\n"
            "material 0 0 1 1 1 0 1 0 0 1\ntriangle 0 0 0 1 0 0 0 1 0\nsphere\n"
            + ("checkerboard 0.5\n" if checkered else "") + "plane\nsphere\n")
    objs = parse_text(text).objects
    assert (Groups._untextured(objs) is None) == checkered  # (the path taken)
    groups = Groups(objs)
    group, keys = _groups_by_keys(objs)
    assert groups.group.tolist() == group and groups.keys == keys
    # (the first sphere has the default material, 0; the last joins the third material's
    # first sphere: 8 groups)
    assert [(k[0].value, k[1]) for k in groups.keys] == [
        ("sphere", 0), ("sphere", 1), ("cone", 1), ("cylinder", 2), ("sphere", 2),
        ("triangle", 3), ("sphere", 3), ("plane", 3)]
    assert groups.group.tolist()[-1] == 6
    empty = Groups(())
    assert empty.group.tolist() == [] and empty.keys == []
