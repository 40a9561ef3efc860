"""The parsers' bulk path against their exact path: the same scene, the same diagnostics.

Each dialect's parser reads runs of simple lines (a command word and its numbers) in bulk
and sends every other line, and every line whose command could report something, down the
exact line-by-line path (``fast_path = False`` takes only that one). Here both read the same
texts -- the fuzz generators' and hand-made edge cases: a bad number inside a run of good
lines, hex, inf, nan and underscore floats, CRLF, tabs, Unicode digits and spaces -- with
chunks of a few lines, so that every boundary case is met, and must agree exactly: equal
scenes (values compared bit for bit), or the same diagnostics (message, line, column).
"""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given

from raymitsuba.format import bulk
from raymitsuba.format.comp575 import Comp575Parser
from raymitsuba.format.mit6837 import Mit6837Parser
from raymitsuba.format.parser import parse_text
from raymitsuba.model import RayError

from hypothesis import strategies as st

from test_fuzz import FUZZ, lines_6837, mesh_scenes, mutated_scenes, soups


def outcome(text, dialect="auto"):
    """(the scene's fields with every float as its bits) or the diagnostics, formatted."""
    try:
        scene = parse_text(text, file="f.ray", dialect=dialect)
    except RayError as exc:
        return "error", [d.format() for d in exc.diagnostics]
    return "scene", bits(scene), [d.format() for d in scene.warnings]


def bits(value):
    """``value`` with every float replaced by its bit pattern (so -0.0 differs from 0.0)."""
    if isinstance(value, float):
        return struct.pack("<d", value)
    if isinstance(value, (tuple, list)):
        return tuple(bits(v) for v in value)
    if hasattr(value, "__dataclass_fields__"):
        return (type(value).__name__,) + tuple(
            bits(getattr(value, f)) for f in value.__dataclass_fields__)
    return value


def both(text, dialect="auto"):
    """(the bulk path's outcome, the exact path's outcome)."""
    fast = outcome(text, dialect)
    Comp575Parser.fast_path = Mit6837Parser.fast_path = False
    try:
        exact = outcome(text, dialect)
    finally:
        Comp575Parser.fast_path = Mit6837Parser.fast_path = True
    return fast, exact


@pytest.fixture(autouse=True)
def small_chunks(monkeypatch):
    """Chunks of 3 lines: every test meets chunk boundaries and remembered lines."""
    monkeypatch.setattr(bulk, "CHUNK", 3)


def agree(text, dialect="auto"):
    fast, exact = both(text, dialect)
    assert fast == exact
    return fast


# -- COMP 575 -------------------------------------------------------------------------------
GOOD = ("material 0.8 0.2 0.1 0.1 0.7 0.3 20 0.1 0 1\ntranslate 1 2 3\nscale 0.5 0.5 0.5\n"
        "rotateY 30\nsphere\ncone\ncylinder\ntriangle 0 0 0 1 0 0 0 1 0\npop\npop\npop\n"
        "light 1 1 1 point 0 5 5\n")


def run_of(bad_line, before=7, after=7):
    """``bad_line`` inside a run of good simple lines: (the text, its line number)."""
    good = ["scale 2 2 2", "translate 1 2 3", "sphere", "pop", "pop",
            "material 1 1 1 0.1 0.7 0.3 20 0 0 1", "rotateX 45"]
    lines = [good[i % len(good)] for i in range(before)] + [bad_line] + \
        [good[i % len(good)] for i in range(after)]
    return "\n".join(lines) + "\nlight 1 1 1 ambient\n", before + 1


def test_good_scene_is_read_alike():
    kind, *_ = agree(GOOD * 5)
    assert kind == "scene"


@pytest.mark.parametrize("bad, column, message", [
    ("translate 1 2 x", 15, "expected a number for `z` of `translate`, found `x`"),
    ("translate 1 0x10 3", 13, "expected a number for `y` of `translate`, found `0x10`"),
    ("scale 1 inf 1", 9, "expected a number for `y` of `scale`, found `inf` "
                         "(nan and infinity are not allowed)"),
    ("scale nan 1 1", 7, "expected a number for `x` of `scale`, found `nan`"),
    ("rotateZ 1e999", 9, "expected a number for `theta` of `rotateZ`, found `1e999` "
                         "(too large for a double)"),
    ("material 1 1 1 0.1 0.7 0.3 20 0 0 1 7", 37, "`material` takes 10 operands"),
    ("translate 1 2", 14, "`translate` takes 3 operands (x y z), found 2"),
    ("sphere 1", 8, "`sphere` takes no operands, found 1"),
    ("\ttranslate\t1 \t2  y", 18, "expected a number for `z` of `translate`, found `y`"),
    ("translate 1 2 \u0663", 15, "(numbers are written in ASCII digits)"),
    ("scale 1 0 1", 9, "`scale` factor `y` is zero"),
    ("scale 1 -0 1", 9, "`scale` factor `y` is zero"),
    ("material 1 1 1 0.1 0.7 0.3 -2 0 0 1", 28, "the Phong coefficient `n` must be >= 0"),
    ("material 1 1 1 0.1 0.7 0.3 2 0 0 -0", 34, "the index of refraction `eta` must be > 0"),
    ("translate 1e308 0 0\ntranslate 1e308 0 0", 1, "`translate` makes the transform overflow"),
])
def test_bad_line_in_a_run_of_good_ones(bad, column, message):
    text, ln = run_of(bad)
    kind, diagnostics = agree(text, "comp575")
    assert kind == "error"
    first = diagnostics[0]
    if "\n" in bad:  # the second line of the pair is the bad one
        ln, column = ln + 1, column
    head = first.splitlines()[0]
    assert head.startswith(f"f.ray:{ln}:{column}: error: ") and message in head, first


@pytest.mark.parametrize("text", [
    "translate 1_0 2 3\nsphere\n",  # float() reads underscores: 10
    "scale 1__0 1 1\nsphere\n",
    "translate 0x1p3 0 0\n",
    "translate -inf 0 0\n", "translate +nan 0 0\n", "translate Infinity 0 0\n",
    "translate 1e308 1e308 1e308\nsphere\n",  # finite numbers whose sum overflows
    "scale 1e200 1e200 1e200\nscale 1e200 1 1\nsphere\n",
    "scale 1e-200 1e-200 1e-200\nscale 1e-200 1 1\nsphere\n",  # underflow: singular
    "material -1 1 1 0.1 0.7 0.3 20 0 0 1\nsphere\n",  # a warning
    "material 1 1 1 0.1 0.7 0.3 20 0 0 1e-320\nsphere\n",
    "translate -0 -0.0 0\nsphere\n",  # signed zeros kept
    "scale -1 -1 -1\ntranslate -0 -0 -0\nsphere\nreset\nscale -1 -1 -1\ntranslate 0 0 0\n"
    "sphere\n",
    "translate 1 2 3\r\nscale 2 2 2\r\nsphere\r\npop\r\npop\r\n",
    "translate\t1\t2\t3\nSPHERE\nsphere # c\nsphere #\n#sphere\nTranslate 1 2 3#\n",
    "translate 1 2 3 # the comment\nscale 1 2 3#4\nscale 1 2 #3\n",
    "translate 1\u00a02 3 4\nsphere\u2003\nsphere\n",  # Unicode spaces stay in a token
    "\u00a0\n\u2028\nsphere\n",  # a line of a Unicode space only is a token, not blank
    "translate \uff11 2 3\n",
    "pop\nsphere\npop\n",  # pop on an empty stack
    "sphere\nsphere\nplane\ncheckerboard 2\nplane\nsphere\n",
    "triangle 0 0 0 1 1 1 2 2 2\ntriangle 0 0 0 1 0 0 0 1 0\n",  # collinear: a warning
    "scale 1e150 1e150 1e150\ntriangle 1e300 0 0 0 1 0 0 0 1\nsphere\n",
    # a scale on a pushed composite: its magnitude is found when a triangle asks for it
    "translate 1 2 3\nscale 1e150 1e150 1e150\ntriangle 1e300 0 0 0 1 0 0 0 1\nsphere\n",
    "translate 1 2 3\nscale 1e200 1e200 1e200\nscale 1e200 1 1\nscale 2 0 1\nsphere\n",
    "translate 1 2 3\nscale 1e-200 1e-200 1e-200\nscale 1e-200 1 1\nsphere\n",
    "rotateX 90\nrotatey 90\nROTATEZ 90\nrotateX -0\nsphere\n",
    "eye 0 0 5\neye 0 0 6\nlookat 0 0 0\nfov 45\nfov 200\nbackground -1 0 0\n",
    "texture none\nsphere\nreset 1\npop 2\nmaterial 1 1 1\nlight 1 1 1 point 1 2\n",
    "\n\n   \n\t\nsphere\n\n\n",
    "sph\u00e9re\nmaterial 1 1 1 0.1 0.7 0.3 20 0 0 1\n",
])
def test_edge_cases_agree(text):
    agree(text * 3, "comp575")
    agree(text, "comp575")
    agree(text)


def test_values_are_the_exact_paths_bits():
    text = ("scale 3 0.30000000000000004 7e-3\ntranslate 0.1 1e-310 -0\nsphere\n"
            "reset\nscale -1 1 1\ntranslate -0 -0 -0\nsphere\nlight 1 1 1 ambient\n")
    kind, *_ = agree(text)
    assert kind == "scene"
    first, second = (o.to_world for o in parse_text(text).objects)
    assert first[0][3] == 0.1 and first[1][3] == 1e-310 and first[1][1] == 0.30000000000000004
    assert math.copysign(1.0, second[0][3]) == -1.0  # -1 * 0 + -0: -0


number_literals = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.floats(allow_nan=False, allow_infinity=False).map(lambda x: f"{x:.15g}"),
    st.from_regex(r"[+-]?[0-9]{1,30}(\.[0-9]{0,30})?([eE][+-]?[0-9]{1,3})?", fullmatch=True),
    st.text("0123456789.eE+-_xinfatyINFATY", min_size=1, max_size=8))


@given(st.lists(st.lists(number_literals, min_size=0, max_size=9), min_size=1, max_size=6))
def test_bulk_numbers_are_the_bits_float_reads(operands):
    """The bulk number reader (fastnumbers) reads every literal it accepts to the bits of
    ``float``; a line with one it refuses, or with a non-finite one, is sent on (None)."""
    words = [["cmd"] + ops for ops in operands]
    try:
        expected = [tuple(map(float, ops)) for ops in operands]
    except ValueError:
        expected = None
    if expected is not None and not all(math.isfinite(x) for v in expected for x in v):
        expected = None
    got = bulk.operands(words)
    if got is None:  # refused: an underscore, or a sum that overflows; never a wrong value
        return
    assert expected is not None
    assert [bits(v) for v in got] == [bits(v) for v in expected]


def test_line_numbers_and_materials_across_chunks():
    text = "".join(f"material {k % 10 / 10} 1 1 0.1 0.7 0.3 20 0 0 1\n"
                   f"translate {k} 0 0\nsphere\npop\n" for k in range(40))
    kind, scene, _ = agree(text + "light 1 1 1 ambient\n")
    parsed = parse_text(text + "light 1 1 1 ambient\n")
    assert [o.line for o in parsed.objects] == [4 * k + 3 for k in range(40)]
    assert [o.material for o in parsed.objects] == list(range(1, 41))
    assert [m.line for m in parsed.materials[1:]] == [4 * k + 1 for k in range(40)]


def test_column_of_an_indented_material():
    scene = parse_text("  \tmaterial 1 1 1 0.1 0.7 0.3 20 0 0 1\nsphere\nlight 1 1 1 ambient\n")
    assert scene.materials[1].column == 4
    agree("  \tmaterial 1 1 1 0.1 0.7 0.3 20 0 0 1\nsphere\nlight 1 1 1 ambient\n")


@FUZZ
@given(soups)
def test_soup_agrees(text):
    agree(text, "comp575")


@FUZZ
@given(mutated_scenes())
def test_mutated_scenes_agree(text):
    agree(text)


def test_simple_lines_take_the_bulk_path(monkeypatch):
    """Only the lines that are not simple reach the exact path."""
    seen = []
    exact = Comp575Parser._run_line
    monkeypatch.setattr(Comp575Parser, "_run_line",
                        lambda self, ln, line: (seen.append(ln), exact(self, ln, line)))
    scene = parse_text(GOOD * 4 + "sphere # a comment\n")
    assert len(scene.objects) == 16 + 1
    assert seen == [12, 24, 36, 48, 49]  # the lights and the comment


# -- MIT 6.837 ------------------------------------------------------------------------------
MESH = ("surface 0.8 0.2 0.1 0.1 0.7 0.3 20 0 0 1\nsphere 0 0 0 1\ntriangles\nv 0 0 0\nv 1 0 0\n"
        "v 0 1 0\nv 1 1 0\nf 0 1 2\nf 1 3 2\nsurface 0.2 0.8 0.1 0.1 0.7 0.3 20 0 0 1\n"
        "f 0 1 3 2\nend\nsphere 2 0 0 0.5\nlight 1 1 1 point 0 5 5\n")


@pytest.mark.parametrize("text", [
    MESH,
    "sphere 1 2\n3 4\nsphere 0 0 0 1\n",  # operands across lines
    "v 1 2 3\n4\ntriangles\nv 1 2 3\n4\nv 1 2 3\nend\n",
    "triangles\nv 0 0 0\nv 1 0 0\n\n\nv 0 1 0\n  \nf 0 1 2\nend\n",  # blank lines between
    "triangles\nv 0 0 0 # a comment\nv 1 0 0 / another\nv 0 1 0\n# f 0 1 2\nf 0 1 2\nend\n",
    "v 1 2 3\nf 0 1 2\nend\n",  # outside a block
    "triangles\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 3\nf -1 0 1\nf 0 1.5 2\nf 0 1e0 2\n"
    "f 0 1_0 2\nf 0 1\nf 0 1 1\nf 0 1 2 0\nf 0 1 2 1 2\nend\n",  # indices, degenerate fans
    "triangles\nv 0 0 0\nv 1 0 0\nv 0 1 0\nsphere 0 0 0 1\ntriangles\nf 0 1 2\nend\n",
    "sphere 0 0 0 0\nsphere 0 0 0 -1\nsphere 0 0 0 1e200\nsphere 0 0 0 1e-200\n"
    "sphere 1e308 1e308 1e308 1\nsphere 0 0 0 1\n",  # radius checks, sums that overflow
    "sphere 0 0 0 nan\nsphere 0 0 0 inf\nsphere 0 0 0 0x1\nsphere 0 0 0 1 2\n",
    "surface -1 0.2 0.1 0.1 0.7 0.3 20 0 0 1\nsurface 1 1 1 0.1 0.7 0.3 20 0 0 0\n"
    "surface 1 1 1 0.1 0.7 0.3 20 0 0 1e-320\nsurface 1 1 1 0.1 0.7 0.3 -1 0 0 1\n"
    "  \tsurface 1 1 1 0.1 0.7 0.3 20 0 0 0.666\nsphere 0 0 0 1\n",
    "triangles\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",  # never closed
    "SPHERE 0 0 0 1\nV 1 2 3\nTriangles\nV 0 0 0\nV 1 0 0\nV 0 1 0\nF 0 1 2\nEnd\n",
    "viewport 64 48\neye 0 0 5\nsphere\t0\t0\t0\t1\r\nsphere 1 1 1 1\r\nlight 1 1 1 ambient\n",
    "sph\u00e8re 0 0 0 1\nsphere 0 0 0 1\nv 1\u00a02 3\n",
    "sphere 0 0 0 1\n\u00a0\nsphere 0 0 0 1\n\u00a04\nsphere 0 0 0 1\n\u2028\n",
    "sphere 0 0 0 1\nmaterial 1 1 1 0.1 0.7 0.3 20 0 0 1\nsphere 0 0 0 1\nsurface 1 1 1\n",
    "sphere 0 0 0 1\nsphere 0 0 0 1\nfoo\nsphere 0 0 0 1\n12\nsphere 0 0 0 1\n",
])
def test_mit_6837_edge_cases_agree(text):
    agree(text * 2, "mit6837")
    agree(text, "mit6837")
    agree(text)


@FUZZ
@given(mesh_scenes())
def test_mit_6837_mesh_scenes_agree(text):
    agree(text, "mit6837")


@FUZZ
@given(st.lists(lines_6837(), max_size=12))
def test_mit_6837_command_soups_agree(commands):
    agree("\n".join(commands), "mit6837")


def test_simple_mit_6837_lines_take_the_bulk_path(monkeypatch):
    """Only the lines that are not simple reach the token stream's path: the camera, the
    lights, a block's `triangles` and `end`, a comment, and each first object (noted there)."""
    seen = []
    exact = Mit6837Parser._run_exact
    monkeypatch.setattr(Mit6837Parser, "_run_exact",
                        lambda self, start, stop: (seen.extend(range(start + 1, stop + 1)),
                                                   exact(self, start, stop)))
    scene = parse_text(MESH * 3 + "sphere 5 5 5 1 # a comment\n")
    assert len(scene.objects) == 7 and len(scene.meshes) == 6
    first = [2, 3, 12, 14]  # the first sphere, `triangles`, `end`, the light
    later = [14 * k + ln for k in (1, 2) for ln in (3, 12, 14)]
    assert seen == first + later + [43, 44]  # the comment, the empty line after the last end
