"""The options several ``raymitsuba`` commands share, stated once here."""

from __future__ import annotations

import click

#: ``--dialect``, for every command that reads a scene.
dialect_option = click.option(
    "--dialect", type=click.Choice(["auto", "comp575", "mit6837"]), default="auto",
    show_default=True,
    help="The .RAY dialect: auto (decided from the file's commands), comp575 or mit6837 "
         "(the parent MIT 6.837 format).")


SIZE_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


def parse_size(text: str) -> int:
    """'2G', '512M', '3.5GB', '1000000' -> bytes."""
    t = text.strip().upper().removesuffix("B").removesuffix("I")
    unit = t[-1:] if t[-1:] in SIZE_UNITS and t[-1:] else ""
    try:
        value = float(t[:-1] if unit else t)
    except ValueError:
        raise click.BadParameter(f"{text!r}: expected a size such as 2G or 512M") from None
    if value <= 0:
        raise click.BadParameter(f"{text!r}: must be positive")
    return int(value * SIZE_UNITS[unit])
