"""Camera rays of the Whitted integrator: which rays leave the camera for each pixel.

Conventions, decided here once:

* Pixels are numbered row-major from the image's top-left corner; row 0 is the top.
* Rays are **pixel-major**: all ``spp`` samples of pixel 0, then those of pixel 1...
  (the image is the box-filtered average of each pixel's consecutive lanes).
* One sample per pixel goes through the pixel centre; ``spp = n^2`` samples use the
  centres of an n x n grid of strata; other counts are stratified in x with a
  golden-ratio sequence in y.
* Pixel *corners* (adaptive anti-aliasing's first pass, ``antialias.py``) are the
  (W + 1) x (H + 1) points at whole pixel coordinates, numbered row-major from the image's
  top-left corner: corner (x, y) is shared by the pixels (x - 1 .. x, y - 1 .. y). Each is
  moved by a fixed offset of at most ``CORNER_JITTER`` of a pixel in x and in y, a hash of
  its number (the same on every run): a regular lattice of samples half a pixel apart
  aliases a periodic pattern (a checkerboard towards the horizon) into flat moire, where
  every sample agrees and no pixel is refined.
"""

import drjit as dr
import mitsuba as mi
import numpy as np

from .arrays import jit_array

GOLDEN = 0.6180339887498949
CORNER_JITTER = 0.2  # pixels: how far a corner's sample may be from the corner, in x and y


def stratum_offset(s, spp):
    """Position in [0, 1)^2 of sample s of ``spp`` within its pixel (see the module docstring)."""
    if spp == 1:
        return mi.Point2f(0.5, 0.5)
    n = int(round(spp ** 0.5))
    if n * n == spp:
        row = s // n
        return grid_offset(s - row * n, row, n)
    x = (mi.Float(s) + 0.5) / spp
    y = dr.fma(mi.Float(s), GOLDEN, 0.5)
    return mi.Point2f(x, y - dr.floor(y))


def grid_offset(column, row, n):
    """Position in [0, 1)^2 of the stratum (column, row) (UInt32) of an n x n grid: its
    centre (``n`` an int, or Float by lane)."""
    return mi.Point2f((mi.Float(column) + 0.5) / n, (mi.Float(row) + 0.5) / n)


def camera_rays(sensor, width, height, spp, first=0, count=None, pixels=None, footprint=False):
    """Camera rays, pixel-major (all samples of a pixel, then the next pixel's); row 0 is the top.

    Of the pixels ``first`` .. ``first + count - 1`` (default: the whole image), or of the
    pixels listed in ``pixels`` (a UInt32 array, in its order). A pixel's rays are the same
    whichever batch it is part of: the image does not depend on how it is split.
    ``footprint``: ray differentials (``mi.RayDifferential3f``) spanning each sample's share
    of its pixel (1 / sqrt(spp) of a pixel in x and in y: see :func:`sample`)."""
    if pixels is None:
        count = width * height - first if count is None else count
    else:
        count = dr.width(pixels)
    index = dr.arange(mi.UInt32, count * spp)
    local = index // spp
    offset = stratum_offset(index - local * spp, spp)
    if pixels is not None:
        pixel = dr.gather(mi.UInt32, pixels, local)
    elif first:  # data, not a constant of the kernel: it changes from chunk to chunk
        pixel = local + dr.opaque(mi.UInt32, first)
    else:
        pixel = local
    return sample(sensor, film_position(pixel, offset, width, height),
                  spp ** -0.5 if footprint else None)


def film_position(pixel, offset, width, height):
    """The film position (``mi.Point2f``, [0, 1]^2) of the point ``offset`` ([0, 1)^2 of a
    pixel, x right and y down) of pixel number ``pixel`` (UInt32) of a width x height image."""
    row = pixel // width
    return mi.Point2f((mi.Float(pixel - row * width) + offset.x) / width,
                      (mi.Float(row) + offset.y) / height)


def graded_rays(sensor, width, height, pixels, sides, footprint=False):
    """Camera rays of pixels each with its own grid, pixel-major: pixel ``pixels[i]`` (numpy
    uint32) with the n x n grid of strata of n = ``sides[i]`` (numpy uint32), its rays those
    of :func:`camera_rays` with spp = n^2 (``footprint``: 1 / n of a pixel)."""
    spp = sides.astype(np.int64) ** 2
    starts = np.cumsum(spp) - spp  # each pixel's first lane
    lane_side = np.repeat(sides, spp)
    sample_number = np.arange(int(spp.sum()), dtype=np.int64) - np.repeat(starts, spp)
    # (on the host: Dr.Jit 1.5 on LLVM stops the process with SIGFPE at a UInt32 array
    # divided by another, e.g. UInt32([5, 7]) // UInt32([2, 3]))
    row, column = np.divmod(sample_number, lane_side)
    offset = grid_offset(jit_array(mi.UInt32, column), jit_array(mi.UInt32, row),
                         jit_array(mi.Float, lane_side))
    pixel = jit_array(mi.UInt32, np.repeat(pixels, spp))
    # (float64 to float32 as spp ** -0.5 is by camera_rays)
    scale = jit_array(mi.Float, (lane_side.astype(np.float64) ** 2) ** -0.5) \
        if footprint else None
    return sample(sensor, film_position(pixel, offset, width, height), scale)


def corner_rays(sensor, width, height, first, count, footprint=False):
    """One camera ray through each of the pixel corners ``first`` .. ``first + count - 1``
    (numbered as in the module docstring) of a ``width`` x ``height`` image (``footprint``:
    with ray differentials a pixel wide)."""
    corner = dr.arange(mi.UInt32, count) + dr.opaque(mi.UInt32, first)
    row = corner // (width + 1)
    jitter = corner_jitter(corner)
    film_pos = mi.Point2f((mi.Float(corner - row * (width + 1)) + jitter.x) / width,
                          (mi.Float(row) + jitter.y) / height)
    return sample(sensor, film_pos, 1.0 if footprint else None)


def sample(sensor, film_pos, footprint=None):
    """The camera ray through ``film_pos``; with ``footprint`` (pixels), a
    ``mi.RayDifferential3f`` whose offset rays are that far in x and in y (the sample's
    footprint: anti-aliasing's filtered checkerboard reads it)."""
    if footprint is None:
        ray, _ = sensor.sample_ray(time=0.0, sample1=0.5, sample2=film_pos,
                                   sample3=mi.Point2f(0.5))
        return mi.Ray3f(ray)
    ray, _ = sensor.sample_ray_differential(time=0.0, sample1=0.5, sample2=film_pos,
                                            sample3=mi.Point2f(0.5))
    ray.scale_differential(footprint)
    return ray


def corner_jitter(corner):
    """The offset (pixels, each coordinate within +-CORNER_JITTER) of the sample of pixel
    corner number ``corner`` (UInt32): two 16-bit halves of an integer hash of it."""
    h = corner * 0x9E3779B1
    h ^= h >> 15
    h *= 0x85EBCA77
    h ^= h >> 13
    h *= 0xC2B2AE3D
    h ^= h >> 16
    unit = mi.Point2f(mi.Float(h & 0xFFFF), mi.Float(h >> 16)) * (1.0 / 65536.0)
    return (unit * 2.0 - 1.0) * CORNER_JITTER


def pixel_sums(color, count, spp):
    """Per pixel, the sum of its ``spp`` consecutive lanes of ``color`` (``count`` pixels)."""
    pixel = dr.arange(mi.UInt32, count) * spp
    total = dr.gather(mi.Color3f, color, pixel)
    for s in range(1, spp):
        total += dr.gather(mi.Color3f, color, pixel + s)
    return total


def pixel_means(color, count, spp):
    """Per pixel, the box-filtered average of its ``spp`` consecutive lanes (Color3f)."""
    total = pixel_sums(color, count, spp)
    if spp > 1:
        total *= 1.0 / spp
    return total


def box_filter(color, width, height, spp):
    """The (H, W, 3) image: each pixel the average of its ``spp`` consecutive lanes."""
    image = pixel_means(color, width * height, spp)
    return mi.TensorXf(dr.ravel(image), shape=(height, width, 3))
