"""Checking your own ray tracer with pytest: ``assert_image_matches`` and a reference cache.

Installed as a pytest plugin (entry point ``pytest11``), so a test file needs no set-up::

    from raymitsuba.testing import assert_image_matches

    def test_whitted(tmp_path):
        my_tracer.render("scenes/whitted.ray", tmp_path / "out.ppm", 96, 72)
        assert_image_matches(tmp_path / "out.ppm", "scenes/whitted.ray")

``assert_image_matches(image, reference, tolerance=2/255, min_match=99.9, srgb=False,
spp=None, max_depth=None, dialect="auto", stable=True)``: ``image`` a path or an
(H, W, 3) linear array; ``reference`` a path to an image, an array, or a .RAY scene
(path or parsed Scene), rendered at the image's size with the render options given
(None: the defaults of :class:`raymitsuba.options.RenderOptions`), its unstable pixels
left out (see :mod:`raymitsuba.compare`). It fails with the figures and the path of a
side-by-side picture (image | reference | heat map) written into pytest's temporary
directory.

A scene's reference (its image and unstable pixels: 4 renders) is rendered once per
session and kept on disk in pytest's cache directory (``.pytest_cache/d/raymitsuba``),
keyed by the scene's bytes (and its textures'), the size, tolerance and render options,
and the versions of raymitsuba (the digest of its source), Mitsuba, Dr.Jit and the
variant: a later session reuses it until one of them changes. The session fixture
``raymitsuba_references`` is that cache (:class:`ReferenceCache`; its ``reference(model,
width, height, tolerance, stable, **options)`` gives a ``stable.Reference``).

The plugin imports nothing but the standard library and pytest until a test calls it:
Mitsuba is loaded only when a scene is first rendered.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from typing import Optional

import pytest

CACHE_FOLDER = "raymitsuba"
#: The pytest sessions running, innermost last (pytester runs sessions inside a session),
#: and the reference cache of each.
_sessions = []


class ReferenceCache:
    """Scene references kept in memory for the session and on disk in ``folder`` (None:
    in memory only); ``hits`` and ``renders`` count what it served and rendered."""

    def __init__(self, folder: Optional[str]):
        self.folder = folder
        self.memory = {}
        self.hits = 0
        self.renders = 0

    def key(self, model, width, height, tolerance, stable, options) -> str:
        digest = hashlib.sha256()
        for part in (_scene_bytes(model), *_versions(),
                     json.dumps([width, height, tolerance, stable, model.dialect,
                                 sorted((k, v) for k, v in options.items() if v is not None)])):
            digest.update(part if isinstance(part, bytes) else str(part).encode())
            digest.update(b"\0")
        return digest.hexdigest()[:32]

    def reference(self, model, width, height, tolerance, stable=True, **options):
        import numpy as np

        from raymitsuba.compare import stable as stability

        key = self.key(model, width, height, tolerance, stable, options)
        if key in self.memory:
            self.hits += 1
            return self.memory[key]
        path = os.path.join(self.folder, key + ".npz") if self.folder else None
        if path and os.path.exists(path):
            with np.load(path) as data:
                found = stability.Reference(data["image"], data["unstable"] if stable else None,
                                            0)
            self.hits += 1
        else:
            found = stability.reference(model, width, height, tolerance, stable, **options)
            self.renders += found.renders
            if path:
                from raymitsuba.atomic import atomic_path

                os.makedirs(self.folder, exist_ok=True)
                with atomic_path(path, ".npz") as tmp:
                    np.savez(tmp, image=found.image, unstable=(
                        found.unstable if found.unstable is not None else np.zeros(0, bool)))
        self.memory[key] = found
        return found


def _scene_bytes(model) -> bytes:
    """What the scene is made of: its file's bytes (or the model's text), its textures'."""
    parts = []
    if model.file and os.path.isfile(model.file):
        with open(model.file, "rb") as f:
            parts.append(f.read())
    else:
        parts.append(repr(model).encode())
    for texture in sorted({o.texture.path for o in model.objects if o.texture}):
        with open(texture, "rb") as f:
            parts.append(f.read())
    return b"\0".join(parts)


_VERSIONS = []


def _versions():
    """raymitsuba's source digest, Mitsuba's and Dr.Jit's versions and the variant."""
    if not _VERSIONS:
        from raymitsuba.backend import mitsuba

        mi = mitsuba()
        import drjit

        digest = hashlib.sha256()
        here = os.path.dirname(os.path.abspath(__file__))
        import raymitsuba.plugins as plugins

        for top in (here, os.path.dirname(os.path.abspath(plugins.__file__))):
            for folder, dirs, files in sorted(os.walk(top)):
                dirs.sort()
                for name in sorted(files):
                    if name.endswith(".py"):
                        with open(os.path.join(folder, name), "rb") as f:
                            digest.update(name.encode() + b"\0" + f.read())
        _VERSIONS.extend([digest.hexdigest(), mi.__version__, drjit.__version__, mi.variant()])
    return _VERSIONS


def _config():
    return _sessions[-1][0] if _sessions else None


def _cache() -> ReferenceCache:
    if not _sessions:  # called outside pytest: in memory only
        _sessions.append((None, ReferenceCache(None)))
    config, cache = _sessions[-1]
    if cache is None:
        folder = None
        if config is not None and getattr(config, "cache", None) is not None:
            folder = str(config.cache.mkdir(CACHE_FOLDER))
        cache = ReferenceCache(folder)
        _sessions[-1] = (config, cache)
    return cache


def _diff_folder() -> str:
    config = _config()
    factory = getattr(config, "_tmp_path_factory", None) if config is not None else None
    if factory is not None:
        return str(factory.mktemp("raymitsuba-diff"))
    return tempfile.mkdtemp(prefix="raymitsuba-diff-")


def assert_image_matches(image, reference, tolerance: Optional[float] = None,
                         min_match: Optional[float] = None, srgb: bool = False,
                         spp: Optional[int] = None, max_depth: Optional[int] = None,
                         dialect: str = "auto", stable: bool = True):
    """Fail unless ``image`` matches ``reference`` (see the module docstring); return the
    :class:`raymitsuba.compare.Result` when it does."""
    from raymitsuba import compare
    from raymitsuba.compare import ERROR, MISSING, PASS

    settings = compare.Settings(
        tolerance=compare.TOLERANCE if tolerance is None else tolerance,
        min_match=compare.MIN_MATCH if min_match is None else min_match, srgb=srgb,
        dialect=dialect, stable=stable, options=dict(spp=spp, max_depth=max_depth))
    if compare.is_scene(reference):
        result = compare.compare_scene(image, reference, settings, _cache().reference)
    else:
        result = compare.compare_images(image, reference, settings)
    if result.status in (ERROR, MISSING):
        pytest.fail(f"cannot compare: {result.message}", pytrace=False)
    if result.status != PASS:
        from raymitsuba import images

        path = os.path.join(_diff_folder(), result.name + "-diff.png")
        images.write(path, result.diff_picture(srgb))
        figures = "\n  ".join(result.score.lines())
        pytest.fail(f"{result.image_name} does not match {result.reference_name}: "
                    f"{result.score.match:.3f} % within {settings.tolerance * 255:g}/255 "
                    f"< {settings.min_match:g} %\n  {figures}\n  diff picture: {path}",
                    pytrace=False)
    return result


# -- the plugin's hooks and fixture ------------------------------------------------------------
def pytest_configure(config):
    _sessions.append((config, None))


def pytest_unconfigure(config):
    _sessions[:] = [(c, cache) for c, cache in _sessions if c is not config]


@pytest.fixture(scope="session")
def raymitsuba_references() -> ReferenceCache:
    """The session's :class:`ReferenceCache` (on disk in pytest's cache directory)."""
    return _cache()
