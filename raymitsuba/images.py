"""Image files: writing renders (atomically) and reading targets.

Values are linear throughout the renderer. By output extension:

* ``.exr``: float32 linear RGB (OpenEXR, lossless RLE compression);
* ``.png``, ``.jpg``/``.jpeg``: 8-bit, values clamped to [0, 1]; no transfer
  curve unless ``srgb=True``, which applies the sRGB curve (Pillow writes them);
* ``.npy``: float32 array of shape (H, W, 3).

:func:`read` reads those and whatever Pillow reads (PPM ``P3`` and ``P6``, as student
tracers write them) as linear float32 (H, W, 3).

A file is written to a temporary file in the same directory and renamed over
the target only when complete: a failure leaves no file and never truncates an
existing one.
"""

from __future__ import annotations

import os

import numpy as np

from raymitsuba.atomic import atomic_path

WRITERS = (".exr", ".png", ".jpg", ".jpeg", ".npy")


class ImageError(ValueError):
    pass


def srgb_encode(linear):
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)


def srgb_decode(encoded):
    return np.where(encoded <= 0.04045, encoded / 12.92, np.power((encoded + 0.055) / 1.055, 2.4))


def check_writable(path: str) -> None:
    """Raise ImageError unless ``path`` has a known extension (before any rendering)."""
    if os.path.splitext(path)[1].lower() not in WRITERS:
        raise ImageError(f"{path}: unknown output format; use one of {', '.join(WRITERS)}")


def is_8bit(path: str) -> bool:
    """Whether ``path``'s format stores 8-bit values (what :func:`encode_8bit` makes)."""
    return os.path.splitext(path)[1].lower() in (".png", ".jpg", ".jpeg")


def write(path: str, image, srgb: bool = False) -> None:
    """Write an (H, W, 3) linear image to ``path`` atomically (format by extension).

    For an 8-bit format the image may also be uint8, already encoded by :func:`encode_8bit`
    (a large render is encoded chunk by chunk, without a float copy of the whole image)."""
    check_writable(path)
    ext = os.path.splitext(path)[1].lower()
    image = np.asarray(image)
    if not (image.dtype == np.uint8 and is_8bit(path)):
        image = np.asarray(image, dtype=np.float32)
    with atomic_path(path, ext) as tmp:
        if ext == ".exr":
            _write_exr(tmp, image)
        elif ext == ".npy":
            with open(tmp, "wb") as f:
                np.save(f, image)
        else:
            _write_8bit(tmp, image, srgb, "JPEG" if ext in (".jpg", ".jpeg") else "PNG")


def encoded(image, ext: str, srgb: bool = False) -> bytes:
    """The bytes :func:`write` would write for ``image`` to a file ending in ``ext``
    (``".png"``...): written by :func:`write` itself into a temporary directory and read
    back, so that a file made from them is the same, byte for byte. (A batch's workers
    encode; only the client writes the files.)"""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="raymitsuba-") as folder:
        path = os.path.join(folder, "image" + ext)
        write(path, image, srgb=srgb)
        with open(path, "rb") as f:
            return f.read()


def write_bytes(path: str, data: bytes) -> None:
    """Write ``data`` (e.g. from :func:`encoded`) to ``path`` atomically."""
    with atomic_path(path, os.path.splitext(path)[1]) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)


# RLE: lossless and readable by every OpenEXR version, like ZIP, but several times less
# CPU time to write for somewhat larger files (at most the uncompressed size).
EXR_COMPRESSION = "RLE_COMPRESSION"


def _write_exr(path, image):
    import OpenEXR

    header = {"compression": getattr(OpenEXR, EXR_COMPRESSION), "type": OpenEXR.scanlineimage}
    channels = {"RGB": np.ascontiguousarray(image)}
    with OpenEXR.File(header, channels) as f:
        f.write(path)


# zlib level of PNG output: 1 writes a 1024 x 768 render ~40% faster than Pillow's default 6,
# for files ~25% larger (a few tens of kB)
PNG_COMPRESS_LEVEL = 1


def encode_8bit(image, srgb=False):
    """Linear float values to the 8-bit values an 8-bit file stores (clamped to [0, 1])."""
    if srgb:
        values = srgb_encode(image).astype(np.float32, copy=False)
    else:
        values = np.clip(image, 0.0, 1.0)  # a new array: the steps below work in place
    np.multiply(values, 255.0, out=values)
    np.rint(values, out=values)  # what np.round does, without the temporaries
    return values.astype(np.uint8)


def _write_8bit(path, image, srgb, fmt):
    from PIL import Image

    pixels = image if image.dtype == np.uint8 else encode_8bit(image, srgb)
    options = {"quality": 95} if fmt == "JPEG" else {"compress_level": PNG_COMPRESS_LEVEL}
    Image.fromarray(pixels, "RGB").save(path, format=fmt, **options)


def read(path: str, srgb: bool = False) -> np.ndarray:
    """An image file as a linear float32 (H, W, 3) array (8-bit decoded by ``srgb``)."""
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext == ".npy":
            image = np.load(path)
        elif ext == ".exr":
            import OpenEXR

            with OpenEXR.File(path) as f:
                channels = f.channels()
                image = channels["RGB"].pixels if "RGB" in channels else \
                    np.stack([channels[c].pixels for c in "RGB"], -1)
        else:
            from PIL import Image

            with Image.open(path) as im:
                image = np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0
            if srgb:
                image = srgb_decode(image)
    except Exception as e:  # any reader's failure is the file's problem
        raise ImageError(f"{path}: cannot read image: {e}") from None
    image = np.asarray(image, dtype=np.float32)
    if image.ndim != 3 or image.shape[2] != 3:
        raise ImageError(f"{path}: expected an RGB image, got shape {image.shape}")
    return image
