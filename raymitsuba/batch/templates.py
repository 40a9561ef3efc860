"""Output names from a template: one output per scene of a batch.

A template is a path with placeholders in Python's format syntax, filled for each scene:

* ``{stem}``: the scene's file name without its extension (``scenes/whitted.ray`` ->
  ``whitted``);
* ``{name}``: its file name (``whitted.ray``);
* ``{parent}``: the name of the folder it is in (``scenes``; a submission per folder);
* ``{index}``: its position among the scenes given, from 0; a format spec works
  (``frames/{index:04d}.png`` -> ``frames/0000.png``...).

:func:`expand` refuses (:class:`TemplateError`, before anything runs) a template with
another placeholder, several scenes and a template without placeholders, and two scenes
that would write the same file. A template may name inputs too (``raymitsuba compare
'submissions/{stem}.png' scenes/*.ray``: the image each scene is compared with).
"""

from __future__ import annotations

import os
import string
from typing import List, Sequence

FIELDS = ("stem", "name", "parent", "index")


class TemplateError(ValueError):
    pass


def placeholders(template: str) -> List[str]:
    """The names of the placeholders of ``template`` (TemplateError if malformed)."""
    try:
        return [name for _, name, _, _ in string.Formatter().parse(template)
                if name is not None]
    except ValueError as e:
        raise TemplateError(f"{template!r}: {e}") from None


def fill(template: str, scene: str, index: int) -> str:
    """``template`` filled for the scene at path ``scene``, ``index``-th of the batch."""
    path = os.path.abspath(scene)
    name = os.path.basename(path)
    values = dict(stem=os.path.splitext(name)[0], name=name,
                  parent=os.path.basename(os.path.dirname(path)), index=index)
    try:
        return template.format(**values)
    except (ValueError, TypeError) as e:  # a format spec that does not fit its value
        raise TemplateError(f"{template!r}: {e}") from None


def expand(template: str, scenes: Sequence[str], distinct: bool = True) -> List[str]:
    """One path per scene (see the module docstring); ``distinct``: refuse two scenes with
    the same path (outputs; inputs may be shared)."""
    names = placeholders(template)
    unknown = sorted({n for n in names if n not in FIELDS})
    if unknown:
        raise TemplateError(f"{template!r}: unknown placeholder {{{unknown[0]}}}; use "
                            + ", ".join("{" + f + "}" for f in FIELDS))
    if len(scenes) > 1 and not names:
        raise TemplateError(f"{template!r}: {len(scenes)} scenes need a template naming each "
                            "output, e.g. 'out/{stem}.png'")
    outputs = [fill(template, scene, i) for i, scene in enumerate(scenes)]
    if not distinct:
        return outputs
    seen = {}
    for scene, output in zip(scenes, outputs):
        key = os.path.realpath(output)
        if key in seen:
            raise TemplateError(f"{seen[key]} and {scene} would both be written to {output}; "
                                "add a placeholder that tells them apart ({parent}, {index})")
        seen[key] = scene
    return outputs
