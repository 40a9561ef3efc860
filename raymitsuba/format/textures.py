"""Texture files: which image format a file holds, from its first bytes.

The parser checks every texture when it reads the ``texture`` line, so that a missing
or unreadable image is a located scene error rather than a failure at render time.
"""

from __future__ import annotations

import os
import stat
from typing import Dict, Optional, Union

from raymitsuba.model import Texture

#: What a texture file may contain, as named in messages.
TEXTURE_FORMATS = ("EXR", "HDR (Radiance RGBE)", "PFM", "PNG", "JPEG",
                   "PPM/PGM/PBM (netpbm P1-P6)", "BMP", "TGA (by its .tga extension)")
_TEXTURE_MAGIC = (  # (prefix, format); first match wins
    (b"\x76\x2f\x31\x01", "exr"),
    (b"\x89PNG\r\n\x1a\n", "png"),
    (b"\xff\xd8\xff", "jpeg"),
    (b"#?RADIANCE", "hdr"),
    (b"#?RGBE", "hdr"),
    (b"BM", "bmp"),
)
_TGA_HEADER_SIZE = 18
_TGA_IMAGE_TYPES = frozenset({1, 2, 3, 9, 10, 11})


def os_reason(exc: BaseException) -> str:
    """The short reason of an OS error, for messages."""
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return str(exc) or type(exc).__name__


def detect_format(path: str) -> Optional[str]:
    """The image format of the file at ``path``, from its first bytes; None if unknown.

    Raises OSError when the file cannot be opened or read, or is not a regular file.
    """
    st = os.stat(path)
    if stat.S_ISDIR(st.st_mode):
        raise IsADirectoryError(21, "Is a directory")
    if not stat.S_ISREG(st.st_mode):
        raise OSError(0, "not a regular file")
    with open(path, "rb") as f:
        head = f.read(32)
    for magic, fmt in _TEXTURE_MAGIC:
        if head.startswith(magic):
            return fmt
    if len(head) >= 3 and head[0:1] == b"P" and head[2:3] in b" \t\r\n":
        if head[1:2] in b"Ff":
            return "pfm"
        if head[1:2] in b"123456":
            return "ppm"
    if (path.lower().endswith(".tga") and len(head) >= _TGA_HEADER_SIZE
            and head[1] in (0, 1) and head[2] in _TGA_IMAGE_TYPES):
        return "tga"
    return None


class TextureFiles:
    """Resolves and checks the texture files of one scene, each path once.

    :meth:`load` gives a :class:`Texture` or an error message.
    """

    def __init__(self, base_dir: Optional[str]):
        self.base_dir = base_dir
        self.cache: Dict[str, Union[Texture, str]] = {}

    def load(self, name: str) -> Union[Texture, str]:
        try:
            base = self.base_dir if self.base_dir is not None else os.getcwd()
            path = os.path.abspath(os.path.join(base, name))
        except (OSError, ValueError) as exc:
            return f"cannot resolve the texture path `{name}`: {os_reason(exc)}"
        cached = self.cache.get(path)
        if cached is None:
            cached = self.cache[path] = _probe(name, path)
        return cached


def _probe(name: str, path: str) -> Union[Texture, str]:
    try:
        fmt = detect_format(path)
    except FileNotFoundError:
        return f"texture file `{name}` not found (looked for {path})"
    except (OSError, ValueError) as exc:
        return f"cannot read texture file `{name}` ({path}): {os_reason(exc)}"
    if fmt is None:
        return (f"texture file `{name}` is not an image in an accepted format; accepted: "
                f"{', '.join(TEXTURE_FORMATS)}")
    return Texture(path=path, format=fmt)
