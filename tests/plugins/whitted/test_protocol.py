"""The interface between the Whitted integrator and its plugins (plugins/whitted/protocol.py): each
plugin provides its part, and a render that meets a plugin that does not stops at once with
an error naming it."""

import numpy as np
import pytest

from support import load_ray


def test_the_ray_plugins_provide_their_parts(mitsuba):
    from raymitsuba.plugins.whitted import protocol

    mi = mitsuba
    phong = mi.load_dict({"type": "rayphong"})
    textured = mi.load_dict({"type": "raytextured", "material": phong})
    for surface in (phong, textured):
        assert isinstance(surface, protocol.Surface)
        assert protocol.check_surface(surface) is surface
        for name in protocol.SURFACE_PARAMETERS:
            assert hasattr(surface.material, name), name
    for kind in ("ambient", "point", "directional", "spotlight"):
        assert protocol.check_emitter(mi.load_dict({"type": "raylight", "kind": kind})) == "light"
    background = mi.load_dict({"type": "raybackground", "color": mi.ScalarColor3f(0.1, 0.2, 0.3)})
    assert protocol.check_emitter(background) == "background"
    np.testing.assert_allclose(np.array(background.background_color).ravel(), [0.1, 0.2, 0.3],
                               rtol=1e-6)


def test_a_foreign_bsdf_is_named(mitsuba):
    from raymitsuba.plugins.whitted import protocol

    diffuse = mitsuba.load_dict({"type": "diffuse", "id": "paint"})
    with pytest.raises(protocol.InterfaceError, match="paint.*not a raymitsuba surface.*material"):
        protocol.check_surface(diffuse)


def test_a_foreign_emitter_is_named(mitsuba):
    from raymitsuba.plugins.whitted import protocol

    sky = mitsuba.load_dict({"type": "constant", "id": "sky"})
    with pytest.raises(protocol.InterfaceError, match="sky.*neither a raymitsuba light"):
        protocol.check_emitter(sky)


def test_a_material_without_a_parameter_is_named(mitsuba):
    from raymitsuba.plugins.whitted import protocol

    class Partial:
        material = type("Half", (), {"color": None})()
        checker_size = 0.0
        image_textures = ()

    with pytest.raises(protocol.InterfaceError, match="material.ambient_mix"):
        protocol.check_surface(Partial())


def test_a_render_checks_the_scene_first(mitsuba):
    # A .RAY scene whose sphere gets Mitsuba's diffuse BSDF instead of its material.
    import raymitsuba
    from raymitsuba.plugins.whitted import protocol

    mi = mitsuba
    loaded = load_ray("light 1 1 1 point 0 0 5\nsphere\n", 8, 8)
    scene_dict = dict(loaded.scene_dict)
    (key,) = [k for k, v in scene_dict.items() if isinstance(v, dict) and "bsdf" in v]
    scene_dict[key] = dict(scene_dict[key], bsdf={"type": "diffuse", "id": "paint"})
    scene = mi.load_dict(scene_dict)
    with pytest.raises(protocol.InterfaceError, match=f"paint.*{key}"):
        scene.integrator().render(scene, scene.sensors()[0])
    assert raymitsuba.render(loaded).shape == (8, 8, 3)  # the original still renders
