"""Small helpers that every stage may use and that belong to none (no Mitsuba, no .RAY)."""

from __future__ import annotations

import contextlib
import gc


@contextlib.contextmanager
def no_cyclic_gc():
    """Pause the cyclic garbage collector while a parse (or a load: api.load, the
    integrator's scene tables) builds its (acyclic) objects.

    A large scene allocates millions of tuples; each allocation burst would
    otherwise trigger collections that re-scan everything built so far.

    On the way out, what was built joins the oldest generation directly (``gc.freeze()``
    then ``gc.unfreeze()``: two list splices), so the first young collection after the
    pause does not traverse it all (a tenth of a second for 10^5 spheres' model) only to
    promote it; a full collection still examines it. Skipped when the program froze objects
    itself (``gc.get_freeze_count()``): unfreezing would undo that.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            if gc.get_freeze_count() == 0:
                gc.freeze()
                gc.unfreeze()
            gc.enable()


def error_message(exc: BaseException) -> str:
    """One line for an unexpected exception: the last line of the innermost cause's message.

    Mitsuba and Dr.Jit wrap errors raised inside a render (``drjit.custom(...): error while
    performing a custom differentiable operation (see above)``); the cause says what failed.
    """
    while exc.__cause__ is not None:
        exc = exc.__cause__
    text = str(exc).strip()
    return text.splitlines()[-1] if text else type(exc).__name__
