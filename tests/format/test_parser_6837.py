"""Tests of the MIT 6.837 dialect (raymitsuba/format/mit6837.py, dialect detection in
raymitsuba/format/parser.py) against docs/format.md's "The parent dialect", rule by rule.

Scenes are written inline; diagnostics are compared as (line, column, message).
"""

from __future__ import annotations

import math

import pytest

from raymitsuba.model import Camera, LightKind, Material, ObjectKind, RayError, Scene
from raymitsuba.format.parser import detect_dialect, parse, parse_file, parse_text

LIT = "light 1 1 1 ambient\n"
SURFACE = "surface 1 0 0 0.1 0.9 0 1 0 0 1\n"  # a MIT 6.837 marker that changes nothing


def ok(text, **kwargs) -> Scene:
    return parse_text(text, **kwargs)


def ok6837(text) -> Scene:
    scene = parse_text(text, dialect="mit6837")
    assert scene.dialect == "mit6837"
    return scene


def errors(text, dialect="mit6837"):
    with pytest.raises(RayError) as info:
        parse_text(text, dialect=dialect)
    return [(d.line, d.column, d.message) for d in info.value.errors]


def error(text, dialect="mit6837"):
    found = errors(text, dialect)
    assert len(found) == 1, found
    return found[0]


def warnings(text):
    return [(d.line, d.column, d.message) for d in ok6837(text).warnings]


def block(*lines):
    return "triangles\n" + "".join(line + "\n" for line in lines) + "end\n" + LIT


SQUARE = ("v 0 0 0", "v 1 0 0", "v 1 1 0", "v 0 1 0")


# ---- telling the dialects apart --------------------------------------------------------


class TestDetection:
    @pytest.mark.parametrize("line", [
        "surface 1 1 1 1 1 0 1 0 0 1", "triangles\nend", "viewport 10 10", "sphere 0 0 0 1",
        "SURFACE 1 1 1 1 1 0 1 0 0 1", "  Sphere\t0 0 0 1", "sphere\n0 0 0 1",
        "sphere # a comment\n# another\n 0 0 0 1"])
    def test_mit_6837_markers(self, line):
        assert ok(line + "\n" + LIT).dialect == "mit6837"

    @pytest.mark.parametrize("word", ["v", "f", "end"])
    def test_block_words_are_markers(self, word):
        # outside a block they are errors, but errors of the MIT 6.837 dialect
        message = errors(f"{word} 0 0 0\n", dialect="auto")[0][2]
        assert "outside a mesh block" in message or "without an open" in message

    @pytest.mark.parametrize("line", [
        "material 1 1 1 1 1 0 1 0 0 1", "plane", "cylinder", "cone", "triangle 0 0 0 1 0 0 0 1 0",
        "translate 1 2 3", "scale 1 1 1", "rotateX 1", "rotatey 1", "ROTATEZ 1", "pop", "reset",
        "checkerboard 1", "sphere", "sphere # a ball", "light 1 1 1 spotlight 0 0 0 0 -1 0 1"])
    def test_comp_575_markers(self, line):
        text = line + "\n" + LIT + ("translate 0 0 0\n" if line == "pop" else "")
        text = ("translate 0 0 0\n" + text) if line == "pop" else text
        assert ok(text).dialect == "comp575"

    def test_texture_is_a_comp_575_marker(self):
        lines = ["texture none"]
        assert detect_dialect(lines) == "comp575"

    def test_no_marker_is_comp_575(self):
        scene = ok("eye 0 0 3\nbackground 1 1 1\n" + LIT)
        assert scene.dialect == "comp575" and scene.camera.fov == 45

    def test_a_cylinder_with_operands_is_no_marker(self):
        assert detect_dialect(["cylinder 0 0 0 1 2"]) == "comp575"
        assert detect_dialect(["surface 1 1 1 1 1 0 1 0 0 1", "cylinder 1 2 3"]) == "mit6837"

    @pytest.mark.parametrize("text", [
        "", "sphere", "Surface 1", "x\n  TRIANGLES\n", "fov 1\nF 1 2 3", "v\tx", "vx\nv",
        "sphere \nsphere  #\nsphere 1", "end#\nEND", "a\n\tViewport 1", "sph\u00e9re\nSURFACE 1",
        "\u212aend\nsurface", "plane\nsphere /1\nsphere\t2", "v/", "x\nf", "x\nf\n"])
    def test_the_lower_case_marker_search_finds_what_the_regex_finds(self, text):
        from raymitsuba.format.parser import _MIT_MARKERS, _MIT_MARKERS_BELOW, first_mit_marker
        expected = _MIT_MARKERS.match(text) or _MIT_MARKERS_BELOW.search(text)
        found = first_mit_marker(text)
        assert (found and (found.start(1), found.group(1))) == \
            (expected and (expected.start(1), expected.group(1)))

    def test_mixed_markers_name_one_line_of_each(self):
        text = "# x\nsurface 1 1 1 1 1 0 1 0 0 1\nsphere 0 0 0 1\n  material 1 1 1 1 1 0 1 0 0 1\n"
        (line, column, message) = error(text, dialect="auto")
        assert (line, column) == (4, 3)
        assert message.startswith("line 2 uses `surface` (MIT 6.837) but line 4 uses `material` "
                                  "(COMP 575)")

    def test_mixed_error_is_at_the_later_marker(self):
        line, column, message = error("plane\nviewport 2 2\n", dialect="auto")
        assert (line, column) == (2, 1)
        assert "line 2 uses `viewport` (MIT 6.837) but line 1 uses `plane` (COMP 575)" in message

    def test_forcing_a_dialect(self):
        assert ok("eye 0 0 3\n", dialect="mit6837").dialect == "mit6837"
        assert ok("eye 0 0 3\n", dialect="mit6837").camera.fov == 30
        assert detect_dialect(["sphere 1"]) == "mit6837"
        assert error("sphere 1\n" + LIT, dialect="comp575") == (
            1, 8, "`sphere` takes no operands, found 1")

    def test_an_unknown_dialect_is_a_value_error(self):
        with pytest.raises(ValueError, match="dialect must be one of auto, comp575, mit6837"):
            parse_text("", dialect="6837")

    def test_parse_and_parse_file_take_the_dialect(self, tmp_path):
        path = tmp_path / "s.ray"
        path.write_text("eye 0 0 3\n")
        assert parse_file(path, dialect="mit6837").dialect == "mit6837"
        assert parse(str(path), dialect="mit6837").dialect == "mit6837"
        assert parse("eye 0 0 3\n", dialect="mit6837").dialect == "mit6837"


# ---- lexical rules -----------------------------------------------------------------------


class TestLexical:
    def test_operands_run_across_line_breaks(self):
        scene = ok6837("surface 1 0 0\n 0.1 0.9 0\n 1 0 0\n 0.5\nsphere\n1 2\n3 4\n" + LIT)
        assert scene.materials[1].ior == 2.0
        assert scene.objects[0].to_world[0] == (4.0, 0.0, 0.0, 1.0)

    @pytest.mark.parametrize("comment", ["# note", "/ note", "// note", "#", "/"])
    def test_hash_and_slash_comments(self, comment):
        scene = ok6837(f"{comment}\nsphere 1 2 3 4 {comment} 5 6\neye 0 0 9{comment}\n" + LIT)
        assert len(scene.objects) == 1 and scene.camera.eye == (0, 0, 9)

    def test_a_comment_inside_a_token_cuts_it(self):
        assert ok6837("fov 45/2\n").camera.fov == 45

    def test_keywords_are_case_insensitive(self):
        scene = ok6837("EYE 0 0 9\nSurface 1 1 1 1 1 0 1 0 0 1\nSPHERE 0 0 0 1\nTriangles\n"
                       "V 0 0 0\nv 1 0 0\nv 0 1 0\nF 0 1 2\nEND\nLIGHT 1 1 1 POINT 0 0 5\n")
        assert len(scene.objects) == 1 and len(scene.meshes) == 1

    @pytest.mark.parametrize("literal, value", [("1e1", 10.0), (".5", 0.5), ("+2.", 2.0)])
    def test_numbers(self, literal, value):
        assert ok6837(f"background {literal} 0 0\n").background[0] == value

    @pytest.mark.parametrize("literal", ["nan", "inf", "-Infinity", "1e400"])
    def test_nan_and_inf_are_rejected(self, literal):
        line, column, message = error(f"eye 0 {literal} 3\n")
        assert (line, column) == (1, 7) and message.startswith("expected a number for `y` of `eye`")

    def test_nan_on_the_next_line_is_a_bad_operand(self):
        assert error("eye 0 0\nnan\n")[2] == (
            "expected a number for `z` of `eye`, found `nan` (nan and infinity are not allowed)")

    def test_unknown_word_suggests_a_command(self):
        assert error("surfce 1 1 1 1 1 0 1 0 0 1\n") == (
            1, 1, "unknown command `surfce`; did you mean `surface`?")
        assert error("lokat 0 0 0\n")[2].endswith("did you mean `lookat`?")

    def test_an_unknown_word_alone_on_a_line_is_a_command_not_an_operand(self):
        assert errors("eye 0 0 9\nbogus\nfov 40\n") == [
            (2, 1, "unknown command `bogus`; the MIT 6.837 commands are eye, lookat, up, fov, "
                   "viewport, background, surface, sphere, triangles, v, f, end, light")]

    @pytest.mark.parametrize("word", ["cube", "torus", "obj", "quads", "q", "rotation", "bumpmap",
                                      "texture", "backgroundcubemap", "CUBE"])
    def test_commands_of_later_programs(self, word):
        line, column, message = error(f"{SURFACE}{word} 1 2 3\n")
        assert (line, column) == (2, 1)
        assert message == (f"`{word}` is not part of the MIT 6.837 format (a later program "
                           f"built on its code added it)")

    def test_a_cylinder_with_operands(self):
        assert error("cylinder 0 0 0 1 2\n")[2].startswith(
            "`cylinder` with operands is not part of the MIT 6.837 format")

    def test_comp_575_commands_are_named_as_such(self):
        assert error("material 1 1 1 1 1 0 1 0 0 1\n") == (
            1, 1, "`material` is a COMP 575 command, not part of the MIT 6.837 format; "
                  "did you mean `surface`?")
        assert error("translate 1 2 3\n")[2] == (
            "`translate` is a COMP 575 command, not part of the MIT 6.837 format")

    def test_operand_counts(self):
        assert error("eye 0 0\nlookat 0 0 -1\n") == (1, 8, "`eye` takes 3 operands (x y z), found 2")
        assert error("eye 0 0 9 7\n") == (1, 11, "`eye` takes 3 operands (x y z), found 4")
        assert error("eye 0 0 9\n7\n") == (2, 1, "`eye` takes 3 operands (x y z), found 4")
        assert error("sphere 0 0 1\n" + LIT) == (
            1, 13, "`sphere` takes 4 operands (cx cy cz r), found 3")

    def test_a_number_where_a_command_belongs(self):
        assert error("7 eye 0 0 9\n") == (1, 1, "expected a command, found the number `7`")

    def test_every_error_is_reported_in_one_pass(self):
        assert [e[:2] for e in errors("eye 0 x 9\nsphere 0 0 0 -1\nbogus 1\n")] == [
            (1, 7), (2, 14), (3, 1)]

    def test_errors_point_at_their_token_on_a_later_line(self):
        assert error("surface 1 1 1\n  1 1 0\n  1 0 0 -2\n") == (
            3, 9, "the ratio of indices of refraction `index` must be > 0, found -2")


# ---- camera ------------------------------------------------------------------------------


class TestCamera:
    def test_defaults(self):
        camera = ok6837("").camera
        assert camera == Camera(eye=(0, 0, 10), lookat=(0, 0, 0), up=(0, 1, 0), fov=30,
                                line=None, fov_axis="x")

    def test_the_fov_is_horizontal(self):
        camera = ok6837("fov 60\n").camera
        assert camera.fov == 60 and camera.fov_axis == "x"
        expected = math.degrees(2 * math.atan(math.tan(math.radians(30)) * 300 / 400))
        assert camera.vertical_fov(400, 300) == pytest.approx(expected, abs=1e-12)
        assert camera.vertical_fov(100, 100) == pytest.approx(60, abs=1e-12)

    def test_comp_575_fov_stays_vertical(self):
        assert ok("fov 60\n").camera.vertical_fov(400, 300) == 60

    @pytest.mark.parametrize("fov", ["0", "180", "-5"])
    def test_fov_range(self, fov):
        assert error(f"fov {fov}\n")[:2] == (1, 5)

    def test_camera_errors_as_in_comp_575(self):
        assert "same point" in error("eye 1 1 1\nlookat 1 1 1\n")[2]
        assert "parallel" in error("up 0 0 1\n")[2]

    def test_viewport(self):
        scene = ok6837("viewport 640 480\n")
        assert scene.viewport == (640, 480) and scene.image_size() == (640, 480)
        assert scene.image_size(100, None) == (100, 480)
        assert ok6837("").viewport is None and ok6837("").image_size() == (512, 512)

    @pytest.mark.parametrize("operands, column", [("0 10", 10), ("10 -1", 13), ("2.5 10", 10),
                                                  ("10 20000", 13)])
    def test_viewport_sizes_are_positive_whole_numbers(self, operands, column):
        line, col, message = error(f"viewport {operands}\n")
        assert (line, col) == (1, column) and "whole number of pixels" in message

    def test_viewport_accepts_a_whole_float(self):
        assert ok6837("viewport 64.0 3e1\n").viewport == (64, 30)

    def test_a_second_viewport_warns(self):
        assert warnings("viewport 1 1\nviewport 2 2\n")[0][:2] == (2, 1)


# ---- lights ------------------------------------------------------------------------------


class TestLights:
    def test_kinds(self):
        scene = ok6837("light 0.1 0.1 0.1 ambient\nlight 1 1 1 point 1 2 3\n"
                       "light 1 1 1 directional 0 -1 0\n")
        assert [li.kind for li in scene.lights] == [LightKind.AMBIENT, LightKind.POINT,
                                                    LightKind.DIRECTIONAL]
        assert scene.lights[1].position == (1, 2, 3) and scene.lights[2].direction == (0, -1, 0)

    def test_operands_across_lines(self):
        assert ok6837("light 1 1 1\n  point\n  1 2 3\n").lights[0].position == (1, 2, 3)

    def test_no_spotlight(self):
        assert error("light 1 1 1 spotlight 0 0 0 0 -1 0 1\n") == (
            1, 13, "`spotlight` lights are not part of the MIT 6.837 format; expected ambient, "
                   "point or directional")

    def test_unknown_kind(self):
        assert error("light 1 1 1 pont 0 0 0\n")[2] == "unknown light kind `pont`; did you mean `point`?"


# ---- surfaces ----------------------------------------------------------------------------


class TestSurfaces:
    def test_index_is_outside_over_inside(self):
        material = ok6837("surface 0.5 0.6 0.7 0.1 0.2 0.3 40 0.4 0.5 0.8\n").materials[1]
        assert material == Material(color=(0.5, 0.6, 0.7), ambient_mix=0.1, diffuse_mix=0.2,
                                    specular_mix=0.3, phong_coeff=40, reflectivity=0.4,
                                    refractivity=0.5, ior=1 / 0.8, index=1, line=1, column=1)

    @pytest.mark.parametrize("index", ["0", "-0.5"])
    def test_index_must_be_positive(self, index):
        line, column, message = error(f"surface 1 1 1 1 1 0 1 0 0 {index}\n")
        assert (line, column) == (1, 27) and "`index` must be > 0" in message

    def test_an_index_whose_reciprocal_overflows(self):
        assert error("surface 1 1 1 1 1 0 1 0 0 1e-320\n")[:2] == (1, 27)

    def test_negative_phong_exponent(self):
        assert "`ns` must be >= 0" in error("surface 1 1 1 1 1 0 -1 0 0 1\n")[2]

    def test_negative_coefficients_warn(self):
        assert warnings("surface 1 -1 1 1 1 0 1 0 0 1\n") == [
            (1, 11, "negative `g` (-1) in `surface`")]

    def test_default_material_and_numbering(self):
        scene = ok6837("sphere 0 0 0 1\n" + SURFACE + "sphere 0 0 0 1\n" + SURFACE
                       + "sphere 0 0 0 1\n" + LIT)
        assert scene.materials[0] == Material()
        assert [o.material for o in scene.objects] == [0, 1, 2]
        assert [m.line for m in scene.materials] == [None, 2, 4]

    def test_surface_operand_count(self):
        assert error("surface 1 1 1\nsphere 0 0 0 1\n" + LIT)[2] == (
            "`surface` takes 10 operands (r g b ka kd ks ns kr kt index), found 3")


# ---- spheres -----------------------------------------------------------------------------


class TestSpheres:
    def test_a_sphere_is_a_similarity_transform(self):
        (obj,) = ok6837("sphere 1 -2 3.5 0.25\n" + LIT).objects
        assert obj.kind is ObjectKind.SPHERE
        assert obj.to_world == ((0.25, 0, 0, 1), (0, 0.25, 0, -2), (0, 0, 0.25, 3.5), (0, 0, 0, 1))

    @pytest.mark.parametrize("radius", ["0", "-1"])
    def test_radius_must_be_positive(self, radius):
        assert error(f"sphere 0 0 0 {radius}\n" + LIT) == (
            1, 14, f"a sphere's radius `r` must be > 0, found {radius}")

    @pytest.mark.parametrize("radius", ["1e-120", "1e120"])
    def test_a_radius_out_of_floating_point_range(self, radius):
        assert "overflow or become singular" in error(f"sphere 0 0 0 {radius}\n" + LIT)[2]

    def test_no_light_warning(self):
        assert warnings("\n  sphere 0 0 0 1\n") == [
            (2, 3, "the scene has objects but no light: it renders black except for the background")]


# ---- mesh blocks -------------------------------------------------------------------------


class TestMeshBlocks:
    def test_a_block_is_one_mesh(self):
        scene = ok6837(block(*SQUARE, "f 0 1 2", "f 0 2 3"))
        (mesh,) = scene.meshes
        assert mesh.vertices == ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0))
        assert mesh.faces == ((0, 1, 2), (0, 2, 3))
        assert (mesh.material, mesh.line, mesh.block_line) == (0, 6, 1)
        assert scene.objects == () and scene.triangle_count == 2

    def test_faces_are_fans_from_their_first_index(self):
        (mesh,) = ok6837(block(*SQUARE, "v 0 2 0", "f 4 0 1 2 3")).meshes
        assert mesh.faces == ((4, 0, 1), (4, 1, 2), (4, 2, 3))

    def test_indices_are_per_block(self):
        scene = ok6837(block("v 0 0 0", "v 1 0 0", "v 0 1 0", "f 0 1 2")
                       + block("v 5 0 0", "v 6 0 0", "v 5 1 0", "f 2 1 0"))
        assert [m.faces for m in scene.meshes] == [((0, 1, 2),), ((2, 1, 0),)]
        assert scene.meshes[1].vertices[0] == (5, 0, 0)

    def test_a_surface_inside_a_block_applies_to_the_faces_after_it(self):
        scene = ok6837(SURFACE + block(*SQUARE, "f 0 1 2", SURFACE.strip(), "f 0 2 3")
                       + "sphere 0 0 0 1\n")
        assert [(m.material, m.faces) for m in scene.meshes] == [(1, ((0, 1, 2),)),
                                                                 (2, ((0, 2, 3),))]
        assert scene.objects[0].material == 2  # the current surface after `end`: the last set
        assert scene.meshes[0].vertices is scene.meshes[1].vertices

    def test_an_empty_block_has_no_mesh(self):
        assert ok6837("triangles\nend\n").meshes == ()

    def test_operands_across_lines_in_a_block(self):
        (mesh,) = ok6837("triangles v 0 0 0 v 1 0\n0 v 0 1 0\nf 0\n1\n2 end\n" + LIT).meshes
        assert mesh.faces == ((0, 1, 2),)

    @pytest.mark.parametrize("face, column, message", [
        ("f 0 1 4", 7, "vertex index 4 is not defined in this block (defined so far: 0 to 3)"),
        ("f 0 -1 2", 5, "vertex indices start at 0, found `-1`"),
        ("f 0 1.5 2", 5, "a vertex index is a whole number, found `1.5`"),
        ("f 0 1 nan", 7, "expected a vertex index for `f`, found `nan` (nan and infinity are not allowed)"),
        ("f 0 1", 6, "a face `f` takes 3 or more vertex indices, found 2"),
    ])
    def test_face_errors_at_their_token(self, face, column, message):
        assert error(block(*SQUARE, face)) == (6, column, message)

    def test_a_whole_float_index_is_accepted(self):
        assert ok6837(block(*SQUARE, "f 0 1.0 2e0")).meshes[0].faces == ((0, 1, 2),)

    def test_an_index_must_be_defined_before_the_face(self):
        assert errors(block("v 0 0 0", "f 0 1 2", "v 1 0 0", "v 0 1 0"))[0][2] == (
            "vertex index 1 is not defined in this block (defined so far: 0 to 0)")
        assert errors(block("f 0 0 0"))[0][2].endswith("(defined so far: none yet)")

    def test_degenerate_fan_triangles_are_skipped_with_one_warning(self):
        # fans: (0 0 1) one degenerate; (1 2 1) one; (3 3 3 3) two; 4 in all
        scene = ok6837(block(*SQUARE, "f 0 1 2", "f 0 0 1", "f 1 2 1", "f 3 3 3 3", "f 0 2 3"))
        assert scene.meshes[0].faces == ((0, 1, 2), (0, 2, 3))
        assert [(w.line, w.column, w.message) for w in scene.warnings] == [
            (7, 1, "4 degenerate fan triangles were skipped (a repeated vertex index); "
                   "this is the first")]

    def test_a_face_closed_on_its_first_vertex_keeps_its_triangle(self):
        # `f a b c a` fans into (a b c) and the degenerate (a c a): the first is kept
        scene = ok6837(block(*SQUARE, "f 0 1 2 0", "f 0 2 3 0"))
        assert scene.meshes[0].faces == ((0, 1, 2), (0, 2, 3))
        assert [(w.line, w.column, w.message) for w in scene.warnings] == [
            (6, 1, "2 degenerate fan triangles were skipped (a repeated vertex index); "
                   "this is the first")]

    def test_only_the_degenerate_triangles_of_a_longer_fan_are_skipped(self):
        # fan of 0 1 1 2 3: (0 1 1) degenerate, (0 1 2) and (0 2 3) kept
        scene = ok6837(block(*SQUARE, "f 0 1 1 2 3"))
        assert scene.meshes[0].faces == ((0, 1, 2), (0, 2, 3))
        assert scene.warnings[0].message.startswith("1 degenerate fan triangle was skipped")

    def test_a_face_of_only_degenerate_triangles_adds_nothing(self):
        scene = ok6837(block(*SQUARE, "f 0 1 0", "f 0 1 2"))
        assert scene.meshes[0].faces == ((0, 1, 2),)
        assert scene.meshes[0].line == 7  # the mesh starts at its first kept face

    def test_v_and_f_outside_a_block(self):
        assert error("v 0 0 0\n") == (1, 1, "`v` outside a mesh block (open one with `triangles`)")
        assert error("f 0 1 2\n") == (1, 1, "`f` outside a mesh block (open one with `triangles`)")

    def test_end_without_triangles(self):
        assert error("end\n") == (1, 1, "`end` without an open `triangles` block")

    def test_nested_triangles(self):
        assert error("triangles\nv 0 0 0\n  triangles\nend\n") == (
            3, 3, "nested `triangles`: the block opened on line 1 is not closed "
                  "(close it with `end` first)")

    def test_a_block_open_at_the_end_is_reported_at_its_triangles(self):
        assert error(LIT + "  triangles\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n") == (
            2, 3, "this `triangles` block is never closed with `end`")

    def test_other_commands_inside_a_block(self):
        line, column, message = error("triangles\nsphere 0 0 0 1\nend\n" + LIT)
        assert (line, column) == (2, 1)
        assert message.startswith("`sphere` inside the `triangles` block of line 1")

    def test_a_bad_vertex_keeps_the_numbering(self):
        found = errors(block("v 0 x 0", "v 1 0 0", "v 0 1 0", "f 0 1 2"))
        assert found == [(2, 5, "expected a number for `y` of `v`, found `x`")]

    def test_a_large_block_parses(self):
        n = 2000
        lines = [f"v {i} {i % 7} {i % 3}" for i in range(n)]
        lines += [f"f {i} {i + 1} {i + 2}" for i in range(n - 2)] * 2
        scene = ok6837(block(*lines))
        assert scene.triangle_count == 2 * (n - 2) and len(scene.meshes) == 1


class TestDetectionEdges:
    def test_a_sphere_with_a_slash_comment_then_operands_below(self):
        assert detect_dialect(["sphere / a ball", "0 0 0 1"]) == "mit6837"
        assert detect_dialect(["sphere / a ball", "plane"]) == "comp575"

    def test_markers_must_start_a_line(self):
        assert detect_dialect(["eye 0 0 9 # surface"]) == "comp575"
        assert detect_dialect(["# surface 1 1 1", "/ triangles"]) == "comp575"
