"""The translator's scene dict: which Mitsuba object stands for each .RAY construct, under
which id. The ids are the public parameter names (mat{i}, light{j}, background)."""

import numpy as np
import pytest

from conftest import intersect_sphere, normalize


@pytest.fixture(scope="module")
def translate(mitsuba):
    from raymitsuba.parser import parse_text
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
    assert d["mat0"]["ambient_mix"] == 1.0 and d["mat0"]["specular_mix"] == 0.0  # the default
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
        from raymitsuba.tessellation import triangle_count

        faces = np.array(shape["faces"]).reshape(-1, 3)
        assert len(faces) >= triangle_count("sphere", 48) and "normals" in shape
        return
    # The analytic sphere's to_world: the unit sphere onto the transformed one, with its
    # pole (local +z, where Mitsuba's sphere puts it) on object +y (the format's pole).
    from raymitsuba.parser import parse_text

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
