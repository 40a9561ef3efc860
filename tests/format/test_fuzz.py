"""Property tests of the parser: whatever the input, the outcome is a Scene or a RayError.

Both dialects. For MIT 6.837: token soup of its vocabulary with operands broken across
lines and mesh blocks with indices in and out of range, valid 6.837 scenes cut and
mutated anywhere, and random text read with the dialect forced. For COMP 575, three
generators: token soup drawn from the format's vocabulary plus junk,
mutations of valid scenes, and raw bytes / raw text. For every example the
parser must either return a :class:`Scene` whose numbers are all finite, or
raise a :class:`RayError` with at least one error, every diagnostic located
at line >= 1 and column >= 1 within its quoted line. Nothing else may escape.

Runs are deterministic (``derandomize=True``) and short (a few hundred examples
per property) so that CI sees the same examples every time.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from raymitsuba.format.convert import to_comp575
from raymitsuba.model import RayError, Scene, Severity
from raymitsuba.format.parser import COMMANDS, parse_file, parse_text

FUZZ = settings(max_examples=250, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

VALID_SCENES = [
    "",
    "sphere\nlight 1 1 1 ambient\n",
    """\
eye 0 1.6 6.5
lookat 0 0.9 0
up 0 1 0
fov 42
background 0.45 0.7 1.0
light 0.18 0.18 0.18 ambient
light 0.75 0.75 0.72 point 4 8 6   # key
light 1 1 1 directional 0 -1 -1
light 1 1 1 spotlight 0 5 0 0 -1 0 4
material 1 0.75 0.1 0.3 0.8 0.1 20 0.15 0 1
checkerboard 1
plane
checkerboard -1
material 0.9 0.9 0.95 0.05 0.1 0.6 80 0.85 0 1
translate -0.9 1.1 -1.6
rotateY 30
scale 1 2 1
sphere
cylinder
pop
cone
reset
texture t.png
triangle 0 0 0 1 0 0 0 1 0
texture none
""",
    'texture "t.png"  # quoted\r\nROTATEZ 90\r\nCone\r\nLIGHT 1 1 1 Point 0 0 0\r\n',
    """\
# MIT 6.837 / with comments
viewport 32 24
eye 0 1 9  lookat 0 0 0  up 0 1 0  fov 40
background 0.1 0.1 0.2
light 0.2 0.2 0.2 ambient
light 1 1 1 point 3 4
  5
light 1 1 1 directional 0 -1 -1
surface 1 0 0 0.1 0.9 0.3 20
        0.2 0.5 0.666
sphere 0 0 0 1
triangles
  v -2 -1 -2  v 2 -1 -2
  v 2 -1 2
  v -2 -1 2
  f 0 1 2 3
  surface 0 1 0 0.2 0.8 0 1 0 0 1
  f 2 1 0
  f 3 3 1
end
sphere 1 1 1 0.5 # last
""",
]

WORDS = [c for name in COMMANDS for c in (name, name.upper(), name.lower())] + [
    "ambient", "point", "directional", "spotlight", "POINT", "none", "NONE"]
NUMBERS = ["0", "1", "-1", "0.5", "+1", "1.", ".5", "1e-3", "1E3", "-0", "90", "180", "45",
           "1e308", "-1e308", "1e-320", "1e400", "nan", "inf", "-inf", "1_0", "1e", ".", "-",
           "12345678901234567890"]
JUNK = ["#", "#x", '"', '"t.png"', '"a b', "t.png", "x.fsf", "abc", "\u00e9", "\u00a0", "\t",
        "\ufeff", "\x00", "\x0c", "\u2028", "\ud800", "\\", "/", "..", "/tmp", "\r", "\n"]

GOOD_NUMBERS = ["0", "1", "-1", "0.5", "+1", "1.", ".5", "1e-3", "1E3", "-0", "90", "2", "-3"]
tokens = st.sampled_from(WORDS) | st.sampled_from(NUMBERS) | st.sampled_from(JUNK) | \
    st.text(max_size=4)
printable = st.text(st.characters(blacklist_categories=("Cc", "Cs")), max_size=6)
operands = st.integers(0, 19).flatmap(
    lambda i: tokens if i == 0 else st.sampled_from(GOOD_NUMBERS))  # mostly good numbers
separators = st.sampled_from([" ", "\t", "  ", " \t "])
line_ends = st.sampled_from(["\n", "\r\n", "\r"])
LIGHT_TAILS = {"ambient": 0, "point": 3, "directional": 3, "spotlight": 7}


@st.composite
def soup_lines(draw):
    """One line: usually a real command with about the right number of operands."""
    choice = draw(st.integers(0, 19))
    if choice == 0:
        return draw(separators).join(draw(st.lists(tokens, max_size=12)))
    if choice == 1:
        return "# " + draw(printable)
    name = draw(st.sampled_from(COMMANDS))
    name = draw(st.sampled_from([name, name.upper(), name.lower()]))
    head = [name]
    key = name.lower()
    if key == "light":
        kind = draw(st.sampled_from(list(LIGHT_TAILS) + ["pont", "AMBIENT"]))
        count = LIGHT_TAILS.get(kind.lower(), 3)
        head = [name] + draw(st.lists(operands, min_size=3, max_size=3)) + [kind]
    elif key == "texture":
        count = 0
        head = [name, draw(st.sampled_from(["t.png", '"t.png"', "x.fsf", "none", "NONE",
                                             "missing.png", '"a b', "t.png # c"]))]
    else:
        count = {"eye": 3, "lookat": 3, "up": 3, "fov": 1, "background": 3, "triangle": 9,
                 "translate": 3, "scale": 3, "rotatex": 1, "rotatey": 1, "rotatez": 1,
                 "material": 10, "checkerboard": 1}.get(key, 0)
    if draw(st.integers(0, 4)) == 0:
        count = max(0, count + draw(st.integers(-2, 2)))
    words = head + draw(st.lists(operands, min_size=count, max_size=count))
    if draw(st.integers(0, 5)) == 0:
        words.append("#" + draw(printable))
    return draw(separators).join(words)


soups = st.tuples(st.lists(soup_lines(), max_size=30), line_ends).map(lambda t: t[1].join(t[0]))


@st.composite
def mutated_scenes(draw):
    """A valid scene with a few random edits: deletions, insertions, swaps, truncation."""
    text = draw(st.sampled_from(VALID_SCENES[1:]))
    for _ in range(draw(st.integers(1, 6))):
        if not text:
            break
        i = draw(st.integers(0, len(text) - 1))
        edit = draw(st.sampled_from(["delete", "insert", "replace", "truncate", "duplicate",
                                     "swap-lines"]))
        if edit == "delete":
            text = text[:i] + text[i + 1:]
        elif edit == "insert":
            text = text[:i] + draw(tokens) + text[i:]
        elif edit == "replace":
            text = text[:i] + draw(st.sampled_from(NUMBERS + JUNK)) + text[i + 1:]
        elif edit == "truncate":
            text = text[:i]
        elif edit == "duplicate":
            j = draw(st.integers(i, len(text)))
            text = text[:j] + text[i:j] + text[j:]
        else:
            parts = text.split("\n")
            a, b = draw(st.integers(0, len(parts) - 1)), draw(st.integers(0, len(parts) - 1))
            parts[a], parts[b] = parts[b], parts[a]
            text = "\n".join(parts)
    return text


def check_outcome(data, base_dir=None, dialect="auto") -> None:
    """The property: a Scene with finite numbers, or a RayError with located diagnostics."""
    try:
        scene = parse_text(data, file="fuzz.ray", base_dir=base_dir, dialect=dialect)
    except RayError as exc:
        assert exc.errors, "a RayError carries at least one error"
        for d in exc.diagnostics:
            check_diagnostic(d)
        assert str(exc)
        return
    assert isinstance(scene, Scene)
    for d in scene.warnings:
        assert d.severity is Severity.WARNING
        check_diagnostic(d)
    cam = scene.camera
    assert 0 < cam.fov < 180 and cam.eye != cam.lookat
    numbers = [*cam.eye, *cam.lookat, *cam.up, *scene.background]
    for obj in scene.objects:
        numbers += [v for row in obj.to_world for v in row]
        numbers += [v for p in (obj.vertices or ()) for v in p]
        assert 0 <= obj.material < len(scene.materials)
        assert obj.checker is None or (obj.kind.value == "plane" and obj.checker > 0)
    for m in scene.materials:
        numbers += [*m.color, m.ambient_mix, m.diffuse_mix, m.specular_mix, m.phong_coeff,
                    m.reflectivity, m.refractivity, m.ior]
        assert m.phong_coeff >= 0 and m.ior > 0
    for li in scene.lights:
        numbers += [*li.color, *(li.position or ()), *(li.direction or ())]
    for mesh in scene.meshes:
        assert mesh.faces and 0 <= mesh.material < len(scene.materials)
        assert all(0 <= i < len(mesh.vertices) and len(set(f)) == 3 for f in mesh.faces for i in f)
        numbers += [v for p in mesh.vertices for v in p]
    if scene.viewport is not None:
        assert all(isinstance(n, int) and n >= 1 for n in scene.viewport)
    assert dialect == "auto" or scene.dialect == dialect
    if scene.dialect == "mit6837":  # its conversion is a valid COMP 575 scene of the same size
        converted = parse_text(to_comp575(scene), dialect="comp575")
        assert converted.camera.fov == cam.vertical_fov(*scene.image_size())
        assert len(converted.materials) == len(scene.materials)
        assert len(converted.objects) == len(scene.objects) + scene.triangle_count
    assert all(isinstance(v, float) and math.isfinite(v) for v in numbers)


def check_diagnostic(d) -> None:
    assert d.file == "fuzz.ray"
    assert isinstance(d.line, int) and d.line >= 1
    assert isinstance(d.column, int) and d.column >= 1
    assert d.message
    if d.source_line:
        assert d.column <= len(d.source_line) + 1
        assert "\n" not in d.source_line and "\r" not in d.source_line
    assert d.format()


# -- MIT 6.837 ----------------------------------------------------------------------------------
WORDS_6837 = ["eye", "lookat", "up", "fov", "viewport", "background", "surface", "sphere",
              "triangles", "v", "f", "end", "light", "SURFACE", "Triangles", "cube", "material",
              "ambient", "point", "directional", "spotlight", "#", "/", "//x", "#y"]
COUNTS_6837 = {"eye": 3, "lookat": 3, "up": 3, "fov": 1, "viewport": 2, "background": 3,
               "surface": 10, "sphere": 4, "v": 3, "triangles": 0, "end": 0}
INDICES = ["0", "1", "2", "3", "4", "7", "-1", "1.5", "2.0", "1e0", "x", "99999999999"]
breaks = st.sampled_from([" ", " ", " ", "\n", "\r\n", "\t", " / c\n", " #c\r"])


@st.composite
def lines_6837(draw):
    """One command of the MIT 6.837 dialect, its tokens joined by spaces or line breaks."""
    choice = draw(st.integers(0, 9))
    if choice == 0:
        words = draw(st.lists(st.sampled_from(WORDS_6837) | tokens, max_size=8))
    elif choice <= 3:
        words = ["f"] + draw(st.lists(st.sampled_from(INDICES), min_size=2, max_size=6))
    elif choice == 4:
        kind = draw(st.sampled_from(list(LIGHT_TAILS)))
        count = LIGHT_TAILS[kind] + draw(st.integers(-1, 1))
        words = ["light"] + draw(st.lists(operands, min_size=3, max_size=3)) + [kind] + \
            draw(st.lists(operands, min_size=max(count, 0), max_size=max(count, 0)))
    else:
        name = draw(st.sampled_from(list(COUNTS_6837)))
        count = COUNTS_6837[name]
        if draw(st.integers(0, 4)) == 0:
            count = max(0, count + draw(st.integers(-2, 2)))
        words = [name] + draw(st.lists(operands, min_size=count, max_size=count))
    out = words[0] if words else ""
    for word in words[1:]:
        out += draw(breaks) + word
    return out


@st.composite
def mesh_scenes(draw):
    """A few MIT 6.837 commands around a mesh block, cut anywhere."""
    head = draw(st.lists(lines_6837(), max_size=6))
    body = [f"v {draw(st.sampled_from(GOOD_NUMBERS))} {draw(st.sampled_from(GOOD_NUMBERS))} "
            f"{draw(st.sampled_from(GOOD_NUMBERS))}" for _ in range(draw(st.integers(0, 5)))]
    body += draw(st.lists(lines_6837(), max_size=8))
    text = "\n".join(head + ["triangles"] + body + ["end"] + draw(st.lists(lines_6837(), max_size=3)))
    return text[:draw(st.integers(0, len(text)))] if draw(st.booleans()) else text


@FUZZ
@given(mesh_scenes())
def test_mit_6837_mesh_blocks(text):
    check_outcome(text)
    check_outcome(text, dialect="mit6837")


@FUZZ
@given(st.lists(lines_6837(), max_size=25).map("\n".join))
def test_mit_6837_soup(text):
    check_outcome(text, dialect="mit6837")


@FUZZ
@given(st.text(max_size=200) | soups)
def test_random_text_as_mit_6837(text):
    check_outcome(text, dialect="mit6837")


@pytest.fixture(scope="module")
def base_dir(tmp_path_factory):
    """A directory with one real texture (t.png) and one file that is no image (x.fsf)."""
    from PIL import Image

    path = tmp_path_factory.mktemp("fuzz-textures")
    Image.new("RGB", (2, 2), (200, 100, 50)).save(path / "t.png")
    (path / "x.fsf").write_bytes(b"not an image")
    return str(path)


@FUZZ
@given(soups)
def test_token_soup(base_dir, text):
    check_outcome(text, base_dir)


@FUZZ
@given(mutated_scenes())
def test_mutated_valid_scenes(base_dir, text):
    check_outcome(text, base_dir)


@FUZZ
@given(st.binary(max_size=400))
def test_random_bytes(base_dir, data):
    check_outcome(data, base_dir)


@FUZZ
@given(st.text(max_size=300))
def test_random_text(base_dir, text):
    check_outcome(text, base_dir)


@pytest.mark.parametrize("text", VALID_SCENES)
def test_the_seed_scenes_are_valid(base_dir, text):
    assert isinstance(parse_text(text, base_dir=base_dir), Scene)


@settings(max_examples=40, deadline=None, derandomize=True, database=None)
@given(data=st.binary(max_size=200) | soups.map(lambda s: s.encode("utf-8", "surrogatepass")))
def test_files_too(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("fuzz-file") / "scene.ray"
    path.write_bytes(data)
    try:
        parse_file(path)
    except RayError as exc:
        assert all(d.line >= 1 and d.column >= 1 for d in exc.diagnostics)
