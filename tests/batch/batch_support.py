"""What the batch tests share (``from batch_support import ...``): tiny scenes of the
gallery, their size, and the single render they are compared with."""

from __future__ import annotations

import os

from support import REPO

#: tiny scenes of the gallery: both dialects, a texture, glass
SCENES = [os.path.join(REPO, "scenes", name) for name in
          ("whitted.ray", "textured_objects.ray", "mit6837_balls.ray", "primitives.ray")]
SIZE = dict(width=32, height=24)


def single_render(scene, output, **options):
    """``raymitsuba render SCENE -o OUTPUT`` (one scene: today's command), in this process."""
    from raymitsuba.cli import main

    args = ["render", str(scene), "-o", str(output)]
    for name, value in options.items():
        flag = "--" + name.replace("_", "-")
        args += [flag] if value is True else [flag, str(value)]
    try:
        main.main(args, standalone_mode=False)
    except SystemExit as e:
        assert e.code in (0, None), e
    with open(output, "rb") as f:
        return f.read()
