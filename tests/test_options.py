"""Tests of raymitsuba/options.py: one record of render options, from which the command line,
the API and the integrator take their defaults and ranges."""

from __future__ import annotations

import dataclasses

import pytest

from raymitsuba import options
from raymitsuba.options import OptionError, RenderOptions


def test_the_defaults_are_the_formats_usual_render():
    o = RenderOptions()
    assert (o.width, o.height, o.spp, o.max_depth, o.aa, o.bailout) == (None, None, 1, 5, None, None)
    assert (o.memory_budget, o.time_limit, o.srgb) == (2 << 30, 3600.0, False)


@pytest.mark.parametrize("name, value, message", [
    ("spp", 0, "spp must be >= 1 and <= 4096, got 0"),
    ("max_depth", 65, "max_depth must be >= 0 and <= 64, got 65"),
    ("max_depth", 2.5, "max_depth must be an integer, got 2.5"),
    ("aa", 0.0, "aa must be > 0, got 0.0"),
    ("bailout", float("nan"), "bailout must be >= 0 and <= 1, got nan"),
    ("width", 16385, "width must be >= 1 and <= 16384, got 16385"),
    ("memory_budget", "lots", "memory_budget must be an integer, got 'lots'"),
])
def test_a_value_out_of_its_range_names_the_option(name, value, message):
    with pytest.raises(OptionError) as e:
        RenderOptions(**{name: value})
    assert str(e.value) == message


def test_given_takes_none_as_the_default():
    assert RenderOptions.given(spp=None, max_depth=3) == RenderOptions(max_depth=3)


def test_integrator_properties_are_what_differs_from_the_defaults():
    assert RenderOptions().integrator_properties() == {}
    o = RenderOptions(aa=0.02, bailout=1e-3, max_depth=3, spp=4, srgb=True)
    assert o.integrator_properties() == {"max_depth": 3, "aa": 0.02, "bailout": 1e-3}


def test_the_integrator_reads_the_records_defaults_and_ranges(mitsuba):
    integrator = mitsuba.load_dict({"type": "raywhitted"})
    assert integrator.tracer.max_depth == options.default("max_depth")
    assert integrator.tracer.max_shadow_crossings == options.default("max_shadow_crossings")
    assert integrator.tracer.bailout == options.default("bailout")
    assert integrator.memory_budget == options.default("memory_budget")
    assert integrator.time_limit == options.default("time_limit")
    assert integrator.aa == 0.0 and integrator.chunk_pixels is None
    with pytest.raises(Exception, match="max_depth must be >= 0"):
        mitsuba.load_dict({"type": "raywhitted", "max_depth": -1})


def test_the_api_checks_the_same_ranges():
    import raymitsuba

    with pytest.raises(OptionError, match="spp must be >= 1"):
        raymitsuba.load("sphere\n", width=4, height=4, spp=0)


def test_every_command_line_render_option_is_made_from_the_record():
    from raymitsuba.cli.fit import fit
    from raymitsuba.cli.options import format_size
    from raymitsuba.cli.render import render

    params = {p.name: p for p in render.params}
    for name, spec in options.specs():
        if not spec.cli:
            assert name not in params
            continue
        param = params[name]
        assert param.opts == ["--" + name.replace("_", "-")]
        value = options.default(name)
        assert param.default == (format_size(value) if spec.size else value)
    fit_params = {p.name: p for p in fit.params}
    for name in ("spp", "max_depth", "aa", "memory_budget", "srgb"):
        assert fit_params[name].opts == params[name].opts
        assert fit_params[name].type.__class__ is params[name].type.__class__


def test_the_integrators_docstring_lists_its_options(mitsuba):
    from raymitsuba.plugins.whitted import integrator

    for name, spec in options.specs():
        listed = f"* ``{name}`` ({spec.kind.__name__}" in integrator.__doc__
        assert listed == (spec.reader == options.INTEGRATOR), name


def test_the_translators_options_extend_the_record():
    from raymitsuba.translate import Options

    render_fields = [f.name for f in dataclasses.fields(RenderOptions)]
    assert [f.name for f in dataclasses.fields(Options)][:len(render_fields)] == render_fields
    with pytest.raises(OptionError):
        Options(spp=-1)
