"""Regenerate the gallery's texture images (run from anywhere; needs Pillow).

* ``uvgrid.png`` -- 64x64: a 4x4 grid of colored tiles (hue changes along u, brightness
  along v) with dark grid lines and a white "R" in the first tile, so that the orientation
  and the repeat of the texture coordinates can be read off a render.
* ``uvgrid.fsf`` -- the same bytes under the ``.fsf`` name the original format mentions
  (raymitsuba reads a .fsf file by its contents: this one is a PNG).
* ``redyellow.png`` -- 64x64: the red/yellow 2x2 checker of Whitted's 1980 floor (a plane
  repeats its texture once per unit, so each square is half a unit).
"""

import colorsys
import os
import shutil

from PIL import Image, ImageDraw, ImageFont

HERE = os.path.dirname(os.path.abspath(__file__))


def uvgrid(size=64, tiles=4):
    img = Image.new("RGB", (size, size))
    px = img.load()
    cell = size // tiles
    for y in range(size):
        for x in range(size):
            i, j = x // cell, y // cell
            hue = (i + 0.5 * (j % 2)) / tiles
            value = 1.0 - 0.12 * j
            r, g, b = colorsys.hsv_to_rgb(hue % 1.0, 0.65, value)
            px[x, y] = (round(255 * r), round(255 * g), round(255 * b))
    draw = ImageDraw.Draw(img)
    for k in range(0, size + 1, cell):
        draw.line([(k, 0), (k, size)], fill=(30, 30, 40), width=2)
        draw.line([(0, k), (size, k)], fill=(30, 30, 40), width=2)
    font = ImageFont.load_default(size=13)
    draw.text((4, 0), "R", fill=(255, 255, 255), font=font)
    return img


def redyellow(size=64):
    img = Image.new("RGB", (size, size), (230, 200, 20))
    draw = ImageDraw.Draw(img)
    h = size // 2
    draw.rectangle([0, 0, h - 1, h - 1], fill=(210, 30, 20))
    draw.rectangle([h, h, size - 1, size - 1], fill=(210, 30, 20))
    return img


if __name__ == "__main__":
    uvgrid().save(os.path.join(HERE, "uvgrid.png"), optimize=True)
    shutil.copyfile(os.path.join(HERE, "uvgrid.png"), os.path.join(HERE, "uvgrid.fsf"))
    redyellow().save(os.path.join(HERE, "redyellow.png"), optimize=True)
