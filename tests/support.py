"""Helpers shared by several test files (``from support import ...``).

* :func:`render_ray` renders .RAY text at a small size and returns a numpy (H, W, 3) array;
  :func:`kernels_launched`, the kernels a render launched (Dr.Jit's kernel history).
* :func:`camera_rays` is an independent implementation of the format's pixel-ray
  geometry (pixel centre (x + 0.5, y + 0.5), row 0 at the top, image right =
  normalize(view x up), vertical fov), so that a test can compute the exact expected
  value of a pixel in numpy (float64) without asking the renderer.
* A few float64 intersection routines (sphere, ellipsoid, plane) and the contract's
  local shading formula, for the same purpose.
* :data:`REPO`: the repository's root (test files live at several depths of tests/).
* :data:`FIT_SCENE`, :data:`FIT_SPHERE`, :data:`FIT_MIT_SCENE`: the scenes of the fit and
  write-back tests.
"""

from __future__ import annotations

import math
import os

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# -- rendering ----------------------------------------------------------------------------------
def load_ray(text, width=32, height=32, spp=1, max_depth=5, srgb=False, dialect="auto",
             **options):
    import raymitsuba

    return raymitsuba.load(text, width=width, height=height, spp=spp, max_depth=max_depth,
                           srgb=srgb, dialect=dialect, **options)


def render_ray(text, width=32, height=32, spp=1, max_depth=5, srgb=False,
               dialect="auto", **options) -> np.ndarray:
    """Render .RAY ``text``; a float32 numpy array of shape (height, width, 3), linear;
    ``options``: the other options of ``raymitsuba.load``."""
    import raymitsuba

    loaded = load_ray(text, width, height, spp, max_depth, srgb, dialect, **options)
    return np.array(raymitsuba.render(loaded))


def kernels_launched(loaded):
    """The kernels that rendering ``loaded`` (a raymitsuba.load result) launched: Dr.Jit's
    kernel history records (``hash``, ``operation_count``, ``cache_hit``: found in the
    in-memory or on-disk cache, i.e. not compiled for this render, ...)."""
    import drjit as dr
    import raymitsuba

    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()  # clears it
        dr.eval(raymitsuba.render(loaded))
        return [k for k in dr.kernel_history() if "operation_count" in k]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)


# -- the camera ---------------------------------------------------------------------------------
def normalize(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def camera_basis(eye=(0, 0, 5), lookat=(0, 0, 0), up=(0, 1, 0)):
    """(forward, right, top): unit vectors; right = normalize(view x up), top = right x view."""
    forward = normalize(np.subtract(lookat, eye))
    right = normalize(np.cross(forward, up))
    top = np.cross(right, forward)
    return forward, right, top


def camera_ray(x, y, width, height, eye=(0, 0, 5), lookat=(0, 0, 0), up=(0, 1, 0), fov=45.0):
    """(origin, unit direction) of the camera ray through the point (x, y) of the film in
    pixel units, x to the right, y down from the top edge; the centre of pixel (col, row) is
    (col + 0.5, row + 0.5). Broadcasts over arrays x, y (directions get a last axis of 3)."""
    forward, right, top = camera_basis(eye, lookat, up)
    tan_half = math.tan(math.radians(fov) / 2.0)
    sx = (2.0 * np.asarray(x, np.float64) / width - 1.0) * tan_half * width / height
    sy = (1.0 - 2.0 * np.asarray(y, np.float64) / height) * tan_half
    d = forward + sx[..., None] * right + sy[..., None] * top
    return np.asarray(eye, np.float64), normalize(d)


def camera_rays(width, height, eye=(0, 0, 5), lookat=(0, 0, 0), up=(0, 1, 0), fov=45.0,
                dx=0.0, dy=0.0):
    """Rays through every pixel centre (shifted by (dx, dy) pixels): origin and (H, W, 3) directions."""
    rows, cols = np.meshgrid(np.arange(height), np.arange(width), indexing="ij")
    return camera_ray(cols + 0.5 + dx, rows + 0.5 + dy, width, height, eye, lookat, up, fov)


def world_to_pixel(p, width, height, eye=(0, 0, 5), lookat=(0, 0, 0), up=(0, 1, 0), fov=45.0):
    """Film position (x, y) in pixels (as camera_ray takes it) of the world point p."""
    forward, right, top = camera_basis(eye, lookat, up)
    q = np.asarray(p, np.float64) - np.asarray(eye, np.float64)
    depth = q @ forward
    tan_half = math.tan(math.radians(fov) / 2.0)
    sx = (q @ right) / depth / (tan_half * width / height)
    sy = (q @ top) / depth / tan_half
    return (sx + 1.0) * width / 2.0, (1.0 - sy) * height / 2.0


# -- transforms (the contract's conventions, in float64) ----------------------------------------
def translation(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def scaling(x, y, z):
    return np.diag([float(x), float(y), float(z), 1.0])


def rotation(axis, degrees):
    """Counter-clockwise by ``degrees`` looking from the positive ``axis`` ("x", "y" or "z")
    toward the origin (right-handed)."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m = np.eye(4)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def stack(*transforms):
    """The object-to-world matrix of a transform stack, oldest first: Tn ... T2 T1."""
    m = np.eye(4)
    for t in transforms:
        m = t @ m
    return m


def to_object(to_world, o, d):
    """Rays (o, d) in the object space of ``to_world`` (directions not renormalised, so t is
    the same parameter in both spaces)."""
    inv = np.linalg.inv(to_world)
    return inv[:3, :3] @ np.asarray(o, np.float64) + inv[:3, 3], d @ inv[:3, :3].T


def normal_to_world(to_world, n_obj):
    """Object-space normals to unit world normals by the inverse transpose."""
    return normalize(n_obj @ np.linalg.inv(to_world[:3, :3]))


# -- geometry in float64 ------------------------------------------------------------------------
def intersect_sphere(o, d, center=(0, 0, 0), radius=1.0):
    """Nearest positive t of unit-direction rays (o, d) with a sphere; nan where missed."""
    oc = np.asarray(o, np.float64) - np.asarray(center, np.float64)
    b = np.sum(oc * d, axis=-1)
    c = np.sum(oc * oc, axis=-1) - radius * radius
    disc = b * b - c
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    t0, t1 = -b - root, -b + root
    return np.where(t0 > 1e-9, t0, np.where(t1 > 1e-9, t1, np.nan))


def intersect_ellipsoid(o, d, to_world):
    """(t, world unit normal) of rays with the unit sphere mapped by the 4x4 ``to_world``."""
    m = np.asarray(to_world, np.float64)
    inv = np.linalg.inv(m)
    o_obj = inv[:3, :3] @ np.asarray(o, np.float64) + inv[:3, 3]
    d_obj = d @ inv[:3, :3].T
    a = np.sum(d_obj * d_obj, axis=-1)
    b = np.sum(o_obj * d_obj, axis=-1)
    c = np.sum(o_obj * o_obj, axis=-1) - 1.0
    disc = b * b - a * c
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    t0, t1 = (-b - root) / a, (-b + root) / a
    t = np.where(t0 > 1e-9, t0, np.where(t1 > 1e-9, t1, np.nan))
    p_obj = o_obj + t[..., None] * d_obj
    n = normalize(p_obj @ inv[:3, :3])  # inverse transpose: (M^-T n) for row vectors
    return t, n


def intersect_plane(o, d, point, normal):
    """t of rays with the plane through ``point`` with ``normal``; nan where parallel/behind."""
    denom = d @ np.asarray(normal, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.subtract(point, o) @ np.asarray(normal, np.float64)) / denom
    return np.where(t > 1e-9, t, np.nan)


def intersect_triangle(o, d, a, b, c):
    """(t, u, v) of rays with triangle abc (Moller-Trumbore; point = a + u (b - a) + v (c - a));
    t is nan where the ray misses the triangle's plane region or the hit is behind."""
    a, b, c = (np.asarray(x, np.float64) for x in (a, b, c))
    e1, e2 = b - a, c - a
    pvec = np.cross(d, e2)
    det = pvec @ e1
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        tvec = np.asarray(o, np.float64) - a
        u = np.sum(tvec * pvec, axis=-1) * inv
        qvec = np.cross(tvec, e1)
        v = np.sum(d * qvec, axis=-1) * inv
        t = (qvec @ e2) * inv
    inside = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9)
    return np.where(inside, t, np.nan), u, v


def phong(n, v, l, color, kd, ks, exponent, intensity=(1, 1, 1)):
    """The contract's per-light term I (kd C (N.L) + ks (R.V)^n), 0 where N.L <= 0.
    ``n`` must already face ``v``; broadcasts over leading axes."""
    n_dot_l = np.sum(n * l, axis=-1, keepdims=True)
    r = 2.0 * n_dot_l * n - l
    r_dot_v = np.sum(r * v, axis=-1, keepdims=True)
    spec = np.where(r_dot_v > 0, np.power(np.maximum(r_dot_v, 0.0), exponent), 0.0)
    value = kd * np.asarray(color, np.float64) * n_dot_l + ks * spec
    return np.asarray(intensity, np.float64) * np.where(n_dot_l > 0, value, 0.0)


def lit_runs(mask):
    """For each row of a boolean (H, W) mask: (first, last) True column, or None."""
    out = []
    for row in mask:
        cols = np.flatnonzero(row)
        out.append((cols[0], cols[-1]) if len(cols) else None)
    return out


# -- scenes shared by the fit and write-back tests ---------------------------------------------
# Comments, tabs, odd spacing, several materials and every kind of light: everything but
# the fitted numbers must survive a rewrite byte for byte.
FIT_SCENE = (
    "# a test scene\r\n"
    "eye 0.1 0.05 5\r\n"
    "fov 35   # degrees\r\n"
    "light 0.9 0.85 0.8 point 1.5 1 6\r\n"
    "light\t0.3 0.3 0.3   ambient # fill\r\n"
    "light 1 1 1 directional -0.3 -0.2 -1\r\n"
    "light 1 1 1 spotlight 0 3 3 0 -1 -1 4 # spot\r\n"
    "material 0.8 0.45 0.3 0.4 \t 0.40 0.5 12 0 0 1 # the sphere\r\n"
    "sphere\r\n"
    "material 1 1 1 1 1 0 1 0 0 1\n"
    "\n"
    "material 1 1 1 1 1 0 1 0 0.5 1e0\r"
    "translate 3 0 0\r"
    "sphere\n"
)

# A tiny scene for fits: one sphere, ambient + point light.
FIT_SPHERE = """\
eye 0.1 0.05 5
fov 35
light 0.9 0.85 0.8 point 1.5 1 6
light 0.3 0.3 0.3 ambient
material 0.8 0.45 0.3 0.4 0.7 0.5 12 0 0 1
sphere
"""

# Both dialects: a MIT 6.837 scene with a glass sphere (index written across lines) and a mesh.
FIT_MIT_SCENE = ("# MIT 6.837 / index is n_outside / n_inside\r\n"
       "background 0.1 0.2 0.3\r\n"
       "light 1 1 1 point 0 4 6\r\n"
       "surface 0.9 0.9 1 0.1 0.2 0.6 40\r\n"
       "   0.1 0.8 0.5   / glass, written across lines\r\n"
       "sphere 0 0 0 1\r\n"
       "triangles\r\nv 0 0 -2\r\nv 1 0 -2\r\nv 0 1 -2\r\n"
       "surface 1 0 0 0.2 0.8 0 1 0 0 1\r\nf 0 1 2\r\nend\r\n")


# -- a real browser -----------------------------------------------------------------------------
CHROMIUM = "/usr/bin/chromium"  # Debian's; ./dev test installs it
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                  "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--hide-scrollbars")
# Marks each picture's natural size on it once the page has loaded, for --dump-dom to show.
MARK_IMAGES = """<script>
window.addEventListener('load', () => {
  for (const img of document.images)
    img.setAttribute('data-loaded', img.complete ? img.naturalWidth + 'x' + img.naturalHeight : 'no');
  document.body.setAttribute('data-marked', document.images.length);
});
</script>"""


def chromium(args, folder, timeout=60):
    """Run headless chromium with ``args`` (profile in ``folder``); its stdout. The whole
    process group is killed if it outlives ``timeout`` seconds."""
    import signal
    import subprocess

    command = [CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={folder}/profile", *args]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                               text=True, start_new_session=True)
    try:
        out, _ = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        raise
    finally:
        try:  # anything it left behind in its group
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return out


def open_in_browser(html_path, folder, size=(1200, 1600)):
    """(the page's DOM with every <img> marked ``data-loaded="WxH"`` or ``"no"``, the path
    of a screenshot of the page) of ``html_path`` opened in headless chromium."""
    marked = os.path.join(folder, "marked.html")
    with open(html_path, encoding="utf-8") as f:
        text = f.read()
    with open(marked, "w", encoding="utf-8") as f:
        f.write(text.replace("</body>", MARK_IMAGES + "</body>"))
    budget = "--virtual-time-budget=5000"
    dom = chromium([budget, "--dump-dom", "file://" + marked], folder)
    shot = os.path.join(folder, "screenshot.png")
    chromium([budget, f"--window-size={size[0]},{size[1]}", f"--screenshot={shot}",
              "file://" + html_path], folder)
    return dom, shot
