"""The layout's one rule, pinned: no module imports one further up the pipeline.

The pipeline is format -> model -> translate -> plugins, with the CLI on top. Every module
of the package belongs to one room below; a module may import only its own room and the
rooms its room is allowed. The imports are read from the source (ast), every one of them:
at the top of a file or inside a function (the lazy ones), absolute or relative.
README.md's "Layout" section states the same rule for people.
"""

from __future__ import annotations

import ast
import os
import sys

import pytest

from support import REPO

#: room -> the rooms it may import (besides itself), lowest first. ``shared`` is the seam
#: everyone reads: the model, the render options and small helpers, none of them Mitsuba.
ALLOWED = {
    "shared": set(),
    "format": {"shared"},
    "translate": {"shared"},
    "plugins": {"shared"},
    "backend": {"shared", "plugins"},
    "library": {"shared", "format", "translate", "plugins", "backend"},
    "cli": {"shared", "format", "translate", "plugins", "backend", "library"},
}
ROOMS = {
    "raymitsuba.model": "shared", "raymitsuba.options": "shared", "raymitsuba.util": "shared",
    "raymitsuba.atomic": "shared",
    "raymitsuba.translate": "translate",
    "raymitsuba._llvm": "backend", "raymitsuba.backend": "backend", "raymitsuba.images": "backend",
    "raymitsuba.api": "library", "raymitsuba.fit": "library", "raymitsuba.parameters": "library", "raymitsuba.testing": "library",
    "raymitsuba": "cli", "raymitsuba.__main__": "cli",  # the package's face: entry points
}
PREFIXES = {"raymitsuba.format": "format", "raymitsuba.geometry": "shared", "raymitsuba.cli": "cli",
            "raymitsuba.compare": "library",
            "raymitsuba.plugins": "plugins", "raymitsuba.batch": "library"}


def room(module: str) -> str:
    if module in ROOMS:
        return ROOMS[module]
    for prefix, name in PREFIXES.items():
        if module == prefix or module.startswith(prefix + "."):
            return name
    raise AssertionError(f"{module} is in no room: add it to tests/test_layers.py and the "
                         "README's Layout section")


def modules():
    """{module name: path} of every module of the package (plugins/ is raymitsuba.plugins)."""
    found = {}
    for top, package in (("raymitsuba", "raymitsuba"), ("plugins", "raymitsuba.plugins")):
        for folder, _, files in os.walk(os.path.join(REPO, top)):
            parts = os.path.relpath(folder, os.path.join(REPO, top)).split(os.sep)
            prefix = ".".join([package] + [p for p in parts if p != "."])
            for f in files:
                if f.endswith(".py"):
                    name = prefix if f == "__init__.py" else f"{prefix}.{f[:-3]}"
                    found[name] = os.path.join(folder, f)
    return found


MODULES = modules()


def imports(name: str, path: str):
    """(imported module, line) of every import of the project's modules in ``path``."""
    package = name if path.endswith("__init__.py") else name.rpartition(".")[0]
    with open(path, encoding="utf-8") as f:
        tree = ast.parse(f.read(), path)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            # `from package import module` names a module; `from module import name` does not
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base
                       for a in node.names]
        else:
            continue
        for target in targets:
            if target == "raymitsuba" or target.startswith("raymitsuba."):
                yield target, node.lineno


def test_every_module_is_in_a_room():
    for name in MODULES:
        room(name)


@pytest.mark.parametrize("name", sorted(MODULES))
def test_no_module_imports_one_further_up_the_pipeline(name):
    mine = room(name)
    wrong = [f"{os.path.relpath(MODULES[name], REPO)}:{line}: imports {target} ({room(target)})"
             for target, line in imports(name, MODULES[name])
             if room(target) != mine and room(target) not in ALLOWED[mine]]
    assert not wrong, f"{name} ({mine}) may import only {sorted(ALLOWED[mine] | {mine})}:\n" \
        + "\n".join(wrong)


def test_the_rooms_allowed_make_the_pipeline_order():
    # a room is allowed only rooms listed before it: no two rooms import each other
    order = list(ALLOWED)
    for name, allowed in ALLOWED.items():
        assert all(order.index(other) < order.index(name) for other in allowed), name


# The shared geometry conventions of the translator and the plugins: arrays, so numpy.
NUMPY_CONVENTIONS = ("raymitsuba.geometry.tessellation", "raymitsuba.geometry.sphere_set",
                     "raymitsuba.geometry.topology")


# What the front end may import beyond the standard library: fastnumbers, a number reader in C
# without numpy (the COMP 575 bulk path's, format/comp575.py).
FRONT_END_LIBRARIES = {"fastnumbers"}


@pytest.mark.parametrize("name", sorted(n for n in MODULES if room(n) in ("format", "shared")
                                        and n not in NUMPY_CONVENTIONS))
def test_the_language_and_the_model_need_only_the_standard_library(name):
    """The .RAY front end (and the model it builds) runs without numpy or Mitsuba: the
    standard library and FRONT_END_LIBRARIES."""
    with open(MODULES[name], encoding="utf-8") as f:
        tree = ast.parse(f.read())
    third_party = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            top = [a.name.split(".")[0] for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            top = [(node.module or "").split(".")[0]]
        else:
            continue
        third_party |= {t for t in top if t != "raymitsuba" and t not in sys.stdlib_module_names
                        and t not in FRONT_END_LIBRARIES}
    assert not third_party, f"{name} imports {sorted(third_party)}"


def test_the_integrators_protocol_depends_on_no_concrete_plugin():
    """What raywhitted reads from its plugins is declared in plugins/whitted/protocol.py,
    which the plugins satisfy; it imports none of them."""
    name = "raymitsuba.plugins.whitted.protocol"
    plugins = {target for target, _ in imports(name, MODULES[name])
               if room(target) == "plugins"}
    assert not plugins, f"{name} imports {sorted(plugins)}"


def _cycles(graph: dict) -> list:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_no_modules_import_each_other_in_a_circle():
    """Within a room too, every import (lazy ones included) points one way: a circle (as
    batch/cluster.py and batch/core.py once made) means neither can be read alone."""
    graph = {name: {t for t, _ in imports(name, path) if t in MODULES and t != name}
             for name, path in MODULES.items()}
    assert not _cycles(graph)


def test_the_package_top_holds_at_most_twelve_modules():
    """A module that joins the top of raymitsuba/ goes in a room's folder once there are
    twelve (README.md, "Layout")."""
    top = [f for f in os.listdir(os.path.join(REPO, "raymitsuba"))
           if f.endswith(".py") and f not in ("__init__.py", "__main__.py")]
    assert len(top) <= 12, sorted(top)


def test_every_package_is_installed():
    """pyproject.toml lists every package of the code (a wheel leaves out one it does not
    name, though an editable install finds it)."""
    import tomllib

    with open(os.path.join(REPO, "pyproject.toml"), "rb") as f:
        listed = set(tomllib.load(f)["tool"]["setuptools"]["packages"])
    packages = {name for name, path in MODULES.items() if path.endswith("__init__.py")}
    assert packages == listed, f"missing {sorted(packages - listed)}, extra {sorted(listed - packages)}"
