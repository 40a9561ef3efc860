"""Image files: atomic writes, the formats, exact float round trips, 8-bit clamping and the
optional sRGB curve."""

import os
import stat

import numpy as np
import pytest
from PIL import Image

from raymitsuba import images


def _values(h=5, w=7, seed=3):
    """float32 values of every kind: negative, zero, tiny, above one, large."""
    rng = np.random.default_rng(seed)
    v = rng.normal(scale=3.0, size=(h, w, 3)).astype(np.float32)
    v[0, 0] = [0.0, -0.0, 1e-30]
    v[0, 1] = [1e20, -1e-7, 0.5]
    return v


def _srgb(linear):
    """The sRGB transfer curve (IEC 61966-2-1), independently of the module."""
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)


@pytest.mark.parametrize("ext", [".exr", ".npy", ".EXR"])
def test_float_round_trip_is_exact(tmp_path, ext):
    values = _values()
    path = str(tmp_path / f"image{ext}")
    images.write(path, values)
    back = images.read(path)
    assert back.dtype == np.float32 and back.shape == (5, 7, 3)
    assert back.tobytes() == values.tobytes()  # bit for bit, signs of zeros included


def test_exr_is_a_linear_float_openexr_file(tmp_path):
    import OpenEXR

    path = str(tmp_path / "x.exr")
    images.write(path, np.full((2, 3, 3), 0.25, np.float32))
    with open(path, "rb") as f:
        assert f.read(4) == b"\x76\x2f\x31\x01"
    with OpenEXR.File(path) as f:
        channels = f.channels()
        pixels = channels["RGB"].pixels if "RGB" in channels else \
            np.stack([channels[c].pixels for c in "RGB"], -1)
    assert pixels.dtype == np.float32
    np.testing.assert_array_equal(pixels, 0.25)  # no transfer curve


def test_png_clamps_to_0_1_and_rounds(tmp_path):
    row = np.array([-0.5, 0.0, 0.25, 0.5, 0.75, 1.0, 2.0, 100.0, 1 / 255, 0.4 / 255],
                   np.float32)
    image = np.stack([row, row[::-1], np.full_like(row, 0.2)], -1)[None]  # (1, 10, 3)
    path = str(tmp_path / "x.png")
    images.write(path, image)
    with Image.open(path) as im:
        assert im.format == "PNG" and im.mode == "RGB"
        pixels = np.asarray(im)
    # clip, then round(v * 255): 63.75 -> 64, 127.5 -> 128, 191.25 -> 191; no curve
    want = [0, 0, 64, 128, 191, 255, 255, 255, 1, 0]
    np.testing.assert_array_equal(pixels[0, :, 0], want)
    np.testing.assert_array_equal(pixels[0, :, 1], want[::-1])
    np.testing.assert_array_equal(pixels[0, :, 2], 51)
    back = images.read(path)  # 8-bit values / 255, linear unless asked otherwise
    np.testing.assert_array_equal(back, pixels.astype(np.float32) / 255)


def test_srgb_option_applies_the_curve_on_write_and_read(tmp_path):
    row = np.array([0.0, 0.001, 0.0031308, 0.01, 0.2, 0.5, 0.8, 1.0, 1.5], np.float32)
    image = np.repeat(row[None, :, None], 3, axis=2)
    path = str(tmp_path / "x.png")
    images.write(path, image, srgb=True)
    with Image.open(path) as im:
        pixels = np.asarray(im)[0, :, 0]
    np.testing.assert_array_equal(pixels, np.round(_srgb(row.astype(np.float64)) * 255))
    assert pixels[5] == 188  # 0.5 linear is 73.5% in sRGB
    # Reading back with the curve inverts it: the decoded values encode to the same codes,
    # and are within half a code's step of the clipped originals (the decoding curve's
    # slope is at most 2.4 * 1.055 / 1.055: half a step of 1/255 is < 0.005 in linear).
    back = images.read(path, srgb=True)[0, :, 0]
    np.testing.assert_allclose(_srgb(back.astype(np.float64)) * 255, pixels, atol=1e-3)
    np.testing.assert_allclose(back, np.clip(row, 0, 1), atol=0.005)


@pytest.mark.parametrize("ext", [".jpg", ".jpeg"])
def test_jpeg_output(tmp_path, ext):
    path = str(tmp_path / f"x{ext}")
    images.write(path, np.full((16, 16, 3), 0.5, np.float32))
    with open(path, "rb") as f:
        assert f.read(3) == b"\xff\xd8\xff"
    back = images.read(path)
    np.testing.assert_allclose(back, 128 / 255, atol=2 / 255)  # lossy, but a flat field


def test_unknown_format_is_rejected_before_writing(tmp_path):
    with pytest.raises(images.ImageError, match="unknown output format"):
        images.write(str(tmp_path / "x.tiff"), np.zeros((2, 2, 3), np.float32))
    with pytest.raises(images.ImageError):
        images.check_writable("render")  # no extension
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("ext", [".exr", ".png", ".npy"])
def test_write_is_atomic(tmp_path, monkeypatch, ext):
    path = tmp_path / f"out{ext}"
    path.write_bytes(b"previous contents")

    # A writer that fails half way through leaves the old file alone and no temporary.
    def broken(target, *args, **kwargs):
        if hasattr(target, "write"):  # np.save is given an open file
            target.write(b"half an ima")
        else:
            with open(target, "wb") as f:
                f.write(b"half an ima")
        raise OSError("disk full")

    monkeypatch.setattr(images, "_write_exr", broken)
    monkeypatch.setattr(images, "_write_8bit", broken)
    monkeypatch.setattr(images.np, "save", broken)
    with pytest.raises(OSError, match="disk full"):
        images.write(str(path), np.zeros((2, 2, 3), np.float32))
    assert path.read_bytes() == b"previous contents"
    assert os.listdir(tmp_path) == [path.name]
    monkeypatch.undo()

    # A successful write replaces it whole, with the usual permissions.
    images.write(str(path), np.ones((2, 2, 3), np.float32))
    assert os.listdir(tmp_path) == [path.name]
    np.testing.assert_array_equal(images.read(str(path)), 1.0)
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o666 & ~umask


def test_read_rejects_what_is_not_an_rgb_image(tmp_path):
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png at all")
    with pytest.raises(images.ImageError, match="cannot read"):
        images.read(str(bad))
    with pytest.raises(images.ImageError):
        images.read(str(tmp_path / "missing.exr"))
    np.save(tmp_path / "flat.npy", np.zeros((4, 4), np.float32))
    with pytest.raises(images.ImageError, match="RGB"):
        images.read(str(tmp_path / "flat.npy"))
    # An 8-bit grayscale file is read as RGB.
    Image.fromarray(np.full((3, 2), 51, np.uint8), "L").save(tmp_path / "gray.png")
    np.testing.assert_array_equal(images.read(str(tmp_path / "gray.png")),
                                  np.full((3, 2, 3), 0.2, np.float32))


def test_a_render_writes_directly(tmp_path):
    import raymitsuba

    loaded = raymitsuba.load("light 1 1 1 ambient\nmaterial 0.5 0.25 2  1 1 0 1  0 0 1\n"
                             "sphere\n", width=9, height=9)
    image = raymitsuba.render(loaded)  # a Dr.Jit tensor
    images.write(str(tmp_path / "r.exr"), image)
    images.write(str(tmp_path / "r.png"), image)
    np.testing.assert_array_equal(images.read(str(tmp_path / "r.exr")), np.array(image))
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "r.png"))[4, 4],
                                  [128, 64, 255])  # 0.5, 0.25 and 2 clamped to 1
