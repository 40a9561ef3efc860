"""``raymitsuba convert``: a MIT 6.837 .ray file to its COMP 575 equivalent."""

from __future__ import annotations

import click

from raymitsuba.cli import common
from raymitsuba.atomic import atomic_path
from raymitsuba.cli.common import EXIT_FAILURE, EXIT_SCENE_ERROR, report
from raymitsuba.cli.options import dialect_option


@click.command()
@click.argument("scene", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="The COMP 575 .ray file to write.")
@dialect_option
def convert(scene, output, dialect):
    """Write the COMP 575 equivalent of the MIT 6.837 file SCENE to OUTPUT.

    The output is commented and renders the same image at the same size; COMP 575 has no
    viewport, so the size is written as a comment (render with --width/--height). Scene
    errors exit with status 2 and write nothing; so does a SCENE already in COMP 575.
    """
    from raymitsuba.format.convert import to_comp575
    from raymitsuba.format.lexer import MIT6837

    model = common.parse_or_exit(scene, dialect)
    report(model.warnings)
    if model.dialect != MIT6837:
        common.fail("raymitsuba convert", f"{scene} is already in the COMP 575 dialect; "
                                              f"nothing to convert", EXIT_SCENE_ERROR)
    text = to_comp575(model)
    try:
        with atomic_path(output, ".ray") as tmp, open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError as e:
        common.fail("raymitsuba convert", f"cannot write {output}: {e.strerror or e}",
                        EXIT_FAILURE)
    width, height = model.image_size()
    click.echo(f"wrote {output} (COMP 575; render it at {width} x {height})")
