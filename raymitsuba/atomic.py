"""Writing a file atomically: into a temporary file next to it, renamed over it when complete.

A failure (an exception, Ctrl-C) leaves no file behind and never truncates an existing one.
Used for every file raymitsuba writes: images, fitted scenes, fit plots.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from typing import Iterator


@contextlib.contextmanager
def atomic_path(path: str, suffix: str = "") -> Iterator[str]:
    """A temporary path in ``path``'s directory to write to (ending in ``suffix``, for writers
    that go by the extension). When the block ends normally the file gets the usual mode
    (0666 less the umask) and replaces ``path``; when it raises, the file is removed."""
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".raymitsuba-", suffix=suffix, dir=directory)
    os.close(fd)
    try:
        yield tmp
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
