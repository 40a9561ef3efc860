"""Tests of raymitsuba/format/lexer.py: the lexical rules both dialects share and where they differ."""

from __future__ import annotations

from raymitsuba.format.lexer import (LINE_END, Token, decode, line_tokens, stream_6837, strip_comment_6837,
                              token_spans, tokens_from)


def decoded(data):
    reports = []
    lines = decode(data, lambda *args: reports.append(args))
    return lines, reports


def test_line_ends_are_lf_crlf_and_cr():
    assert decoded("a\r\nb\rc\nd")[0] == ["a", "b", "c", "d"]
    assert LINE_END.split("a\x0bb\u2028c") == ["a\x0bb\u2028c"]


def test_a_byte_order_mark_is_dropped():
    assert decoded(b"\xef\xbb\xbfeye")[0] == ["eye"]
    assert decoded("\ufeffeye")[0] == ["eye"]


def test_bad_lines_are_reported_and_come_back_empty():
    lines, reports = decoded(b"eye 0 0 1\nfo\xffv 3\nup 0 1 0\x00\n")
    assert lines == ["eye 0 0 1", "", "", ""]
    assert [(r[0], r[1]) for r in reports] == [(2, 3), (3, 9)]
    assert reports[0][2].startswith("invalid UTF-8 (byte ff)")
    assert reports[1][2].startswith("a NUL byte (U+0000)")


def test_comp_575_comments_are_tokens_that_start_with_hash():
    assert line_tokens("sphere # a #b") == ["sphere"]
    assert line_tokens("a#b c") == ["a#b", "c"]
    assert line_tokens("x / y") == ["x", "/", "y"]


def test_mit_6837_comments_start_at_any_hash_or_slash():
    assert strip_comment_6837("sphere 0 0 0 1 / big") == "sphere 0 0 0 1 "
    assert strip_comment_6837("fov 45#x") == "fov 45"
    assert strip_comment_6837("fov 45/2") == "fov 45"


def test_token_spans_per_dialect():
    line = "eye 1 2 3 # x / y"
    assert token_spans(line) == [(0, 3), (4, 5), (6, 7), (8, 9)]
    assert token_spans("eye 1/2 3", "mit6837") == [(0, 3), (4, 5)]
    assert token_spans("eye 1/2 3") == [(0, 3), (4, 7), (8, 9)]


def test_the_6837_stream_carries_lines_and_columns():
    tokens = list(stream_6837(["# c", "  sphere 0", "\t1 2 / x", "", "3"]))
    assert tokens == [Token("sphere", 2, 2, 8), Token("0", 2, 9, 10), Token("1", 3, 1, 2),
                      Token("2", 3, 3, 4), Token("3", 5, 0, 1)]
    assert tokens[0].column == 3


def test_unicode_spaces_stay_inside_tokens():
    assert [t.text for t in stream_6837(["a\u00a0b c"])] == ["a\u00a0b", "c"]


def test_tokens_from_a_command():
    lines = ["eye 1 2 3 up 0 1 0", "surface 1 1", "  1 # c", "1"]
    assert list(tokens_from(lines, 1, 11)) == [(1, 10, 12), (1, 13, 14), (1, 15, 16), (1, 17, 18)]
    assert list(tokens_from(lines, 2, 1, "mit6837"))[3:] == [(3, 2, 3), (4, 0, 1)]
    assert [t[0] for t in tokens_from(lines, 2, 1)] == [2, 2, 2]  # COMP 575: one line
