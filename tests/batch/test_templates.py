"""Tests of raymitsuba/batch/templates.py: output names from a template, refused before
anything runs when they cannot name each scene's output apart."""

from __future__ import annotations

import os

import pytest

from raymitsuba.batch.templates import TemplateError, expand


def test_each_placeholder_names_the_scene_it_stands_for():
    scenes = ["course/alice/scene.ray", "course/bob/scene.ray"]
    assert expand("out/{parent}-{stem}.png", scenes) == ["out/alice-scene.png",
                                                         "out/bob-scene.png"]
    assert expand("{name}.exr", ["a/x.ray"]) == ["x.ray.exr"]


def test_the_index_counts_from_zero_with_its_format_spec():
    assert expand("frames/{index:04d}.png", ["a.ray", "b.ray"]) == ["frames/0000.png",
                                                                    "frames/0001.png"]


def test_several_scenes_without_a_placeholder_are_refused():
    with pytest.raises(TemplateError, match="2 scenes need a template"):
        expand("out.png", ["a.ray", "b.ray"])


def test_two_scenes_that_would_write_one_file_are_refused(tmp_path):
    a, b = tmp_path / "x" / "s.ray", tmp_path / "y" / "s.ray"
    with pytest.raises(TemplateError, match="would both be written to"):
        expand(os.path.join(tmp_path, "{stem}.png"), [str(a), str(b)])


def test_an_unknown_placeholder_is_refused():
    with pytest.raises(TemplateError, match=r"unknown placeholder \{frame\}"):
        expand("{frame}.png", ["a.ray"])


def test_a_template_of_inputs_may_name_one_file_for_several_scenes():
    # raymitsuba compare 'subs/{parent}.png' a/x.ray a/y.ray: both compared with subs/a.png
    assert expand("subs/{parent}.png", ["a/x.ray", "a/y.ray"], distinct=False) == [
        "subs/a.png", "subs/a.png"]
    with pytest.raises(TemplateError, match="unknown placeholder"):
        expand("subs/{student}.png", ["a/x.ray"], distinct=False)
