"""The options several ``raymitsuba`` commands share, stated once here.

The render options (``--width`` ... ``--srgb``) are made from the record of
:mod:`raymitsuba.options`: each one's flag (its name with dashes), type, range, default
and help text come from there; a command passes the values on to :func:`raymitsuba.load`
as keywords of the same names (None where the record's default is "unset").
"""

from __future__ import annotations

from typing import Callable, Optional

import click

from raymitsuba import options
from raymitsuba.format import DIALECT_CHOICES

#: ``--dialect``, for every command that reads a scene.
dialect_option = click.option(
    "--dialect", type=click.Choice(list(DIALECT_CHOICES)), default="auto",
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


def format_size(size: int) -> str:
    """Bytes as :func:`parse_size` reads them back: 2147483648 -> '2G'."""
    for unit in ("T", "G", "M", "K"):
        if size % SIZE_UNITS[unit] == 0:
            return f"{size // SIZE_UNITS[unit]}{unit}"
    return str(size)


class Size(click.ParamType):
    """A number of bytes written ``2G``, ``512M``, ``3.5GB`` or ``1000000``."""

    name = "size"

    def convert(self, value, param, ctx):
        return value if isinstance(value, int) else parse_size(value)


def _click_type(spec: options.Spec):
    if spec.size:
        return Size()
    low_open = dict(min_open=True) if spec.low_open else {}
    if spec.kind is int:
        return click.IntRange(spec.low, spec.high, **low_open)
    return click.FloatRange(spec.low, spec.high, **low_open)


class OptionalValue(click.Option):
    """An option whose value may be left out (``--aa`` alone: the record's flag value). A
    next argument that is not a number is not taken as its value but left to the command
    (``--aa scene.ray`` is ``--aa`` and the scene)."""

    def add_to_parser(self, parser, ctx):
        super().add_to_parser(parser, ctx)
        alone = repr(self.flag_value)
        for opt in self.opts:  # (the parser's option objects are click's, not public API)
            parsed = parser._long_opt.get(opt) or parser._short_opt.get(opt)
            process = parsed.process

            def given(value, state, process=process):
                if isinstance(value, str) and not _is_number(value):
                    state.rargs.insert(0, value)
                    value = alone
                process(value, state)

            parsed.process = given


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def render_option(name: str, help: Optional[str] = None) -> Callable:
    """The click option of the render option ``name`` (see the module docstring); ``help``
    replaces the record's text where a command gives the option more to do."""
    spec, value = options.spec(name), options.default(name)
    flag = "--" + name.replace("_", "-")
    text = help or spec.help
    if spec.kind is bool:
        return click.option(flag, name, is_flag=True, default=value, help=text)
    if spec.flag_value is not None:  # the flag alone: its flag value
        return click.option(flag, name, cls=OptionalValue, type=_click_type(spec),
                            default=None, is_flag=False, flag_value=spec.flag_value,
                            metavar=spec.metavar, show_default=spec.unset,
                            help=f"{text} [{flag} alone: {spec.flag_value}]")
    if value is None:  # shown as what it means
        return click.option(flag, name, type=_click_type(spec), default=None,
                            metavar=spec.metavar, show_default=spec.unset, help=text)
    return click.option(flag, name, type=_click_type(spec), metavar=spec.metavar,
                        default=format_size(value) if spec.size else value, show_default=True,
                        help=text)


def render_options(*names: str, **helps: str) -> Callable:
    """A decorator adding the render options ``names`` to a command, in that order
    (``helps``: command-specific help texts by option name)."""
    def decorate(command):
        for name in reversed(names):
            command = render_option(name, helps.get(name))(command)
        return command
    return decorate


#: The options of a batch (several scenes, or one image in tiles) on Dask workers, by name
#: (as the command's keywords): where it runs and what it does about existing outputs and
#: failures (raymitsuba.batch).
BATCH = {
    "jobs": click.option("-j", "--jobs", type=click.IntRange(1), default=None, metavar="N",
                         help="Local worker processes. [default: the machine's cores; 1: "
                              "in this process, no cluster]"),
    "threads": click.option("--threads", type=click.IntRange(1), default=None, metavar="T",
                            help="Dr.Jit threads per worker. [default: the cores shared out "
                                 "among the local workers]"),
    "scheduler": click.option("--scheduler", default=None, metavar="ADDRESS",
                              help="A Dask scheduler's address (e.g. tcp://10.0.0.1:8786) to "
                                   "run on instead of local workers. [default: "
                                   "$DASK_SCHEDULER_ADDRESS]"),
    "skip_existing": click.option("--skip-existing", is_flag=True,
                                  help="Keep outputs that exist (they are complete: files are "
                                       "written atomically): resume an interrupted batch."),
    "fail_fast": click.option("--fail-fast", is_flag=True,
                              help="Stop at the first item that fails. [default: go on]"),
    "manifest": click.option("--manifest", default=None, type=click.Path(dir_okay=False),
                             help="The batch's JSON-lines manifest. [default: "
                                  "raymitsuba-manifest.jsonl beside the outputs]"),
}
#: the batch options' names, as the command's keywords
BATCH_OPTIONS = tuple(BATCH)


def batch_options(*names: str) -> Callable:
    """A decorator adding the batch options ``names`` to a command, in that order (none
    named: all of :data:`BATCH`)."""
    def decorate(command):
        for name in reversed(names or BATCH_OPTIONS):
            command = BATCH[name](command)
        return command
    return decorate
