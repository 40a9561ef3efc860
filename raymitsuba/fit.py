"""Fitting material and light parameters of a .RAY scene to a target image.

    loaded = raymitsuba.load("scene.ray", width=W, height=H)      # the target's size
    result = fit(loaded, target, ["mat1.diffuse_mix", "light1.color"], iters=100, lr=0.02)
    result.fitted["mat1.diffuse_mix"]                               # a float (3-tuples for colors)
    text = rewrite_scene(open("scene.ray", "rb").read(), loaded.model, result.fitted)

**Loss.** The mean squared error over all pixels and the three channels,
``mean((render - target)^2)`` (L2), of linear values. The render uses the
loaded scene's sampling (``spp``; one sample per pixel goes through the pixel
centre, so a target rendered from the true scene is matched exactly at the
optimum).

**Optimizer.** ``mi.ad.Adam`` with a step size relative to each parameter's
scale: parameter ``k`` gets the learning rate ``lr * max(1, max|start value|)``,
so ``lr`` is a fraction of the parameter's size (colors, mixes, kr, kt and ior
move by about ``lr`` per step, a Phong exponent of 20 or a light 6 units away by
about ``20 lr`` / ``6 lr``). The rate decays geometrically over the run to
``final_lr`` (default 1/10) of that at the last step, which lets Adam settle
instead of circling the minimum.

**Valid ranges.** After every step each parameter is clamped into its range
(:data:`LOWER_BOUNDS`): colors and the ambient/diffuse/specular mixes >= 0,
phong_coeff >= 0, ior >= 1e-3 (the format needs eta > 0), the spot's shape
coefficient >= 0, and reflectivity and refractivity >= 1e-4. The last is
because a branch of the ray tree whose weight is exactly 0 is not traced, so
the derivative *at* kr = 0 (or kt = 0) cannot see what a reflection (or
refraction) would add: a fitted kr or kt that reached 0 could never come back.
Positions and directions are not bounded.

**Default parameters** (:func:`default_keys`): for every material used by an
object and written on a ``material`` line: color, ambient_mix, diffuse_mix,
specular_mix, phong_coeff; reflectivity and refractivity only where they start
above 0 (at 0 their derivative is blind, see above); ior only where refractivity
starts above 0 (otherwise it changes nothing); plus the color of every light.
Note that some parameters are only jointly determined by an image (a material's
color times its diffuse mix times the light's color): fitting all of them lowers
the loss but need not recover each one; pick ``keys`` accordingly.

**Scans before the steps** (``scan``). A gradient only sees the loss near the current
values, and some losses have many basins -- eta behind glass in front of a checkerboard
is one: each checker square seen through the ball makes its own, and from eta = 1.15
(true 1.5) the steps alone walk away from 1.5 (a barrier at about 1.25; they end at 1.13).
Blurring or block-averaging the images (``levels``) does not remove those basins (the
barrier stays where it is at every blur, measured up to a Gaussian of 8 pixels), so the
fit looks for the right basin by rendering, before any step:

* ``scan="auto"`` (the default; ``--scan auto``): **an automatic scan** of each scalar key
  among ``keys`` whose field is in :data:`AUTO_SCAN` -- ``ior`` (eta bends the refracted
  rays: *what* the glass shows moves) and ``fov`` (zooms everything the camera sees) --
  whatever its scene. Each such key is scanned alone, in the order of ``keys``, the others
  at their current values (an earlier scanned key at its best): its start value and then
  :data:`AUTO_SCAN_COUNT` (32) evenly spaced values from start / :data:`AUTO_SCAN_RATIO` to
  start x AUTO_SCAN_RATIO (1.5), cut to the key's valid range (eta >= 1e-3, 0 < fov <=
  179 degrees); the steps start from the value of least loss (the start where none is
  lower, the first of equal losses). The window covers a start 33 % below or 50 % above
  the truth; its spacing, 2.7 % of the start (0.031 in eta at 1.15), is finer than the true
  basin of the checkered wall (about 1.35-1.7 in eta; 26-34 degrees of a 30 degree fov).
  **Cost: 33 primal renders per scanned key** (no derivatives; at 64 x 48, spp 16, about
  1.3 s, as much as three gradient steps; at 256 x 192, 3.3 s), recorded in
  ``FitResult.scans``, ``.scanned`` and ``.scan_seconds``. Keys of other fields are not
  scanned: the shading coefficients' losses are smooth (kd's is a parabola), positions
  and directions are vectors (from 10 % off a light's position needs no scan: README.md);
  scan other scalar keys (an angle, a radius) by hand if their loss has many basins.
* ``scan=[Scan(key, low, high, n), ...]`` (``--scan KEY=LOW:HIGH:N``, repeatable; no
  automatic scan then): **a hand-chosen grid**. The scene is rendered at each value of the
  grids of the scanned scalar keys (their product: every combination), the other keys at
  their start, and the steps start from the combination of least loss. The grid's
  spacing must be finer than the true basin's width; the steps then place the key
  exactly. One primal render per combination; at most :data:`MAX_SCAN`.
* ``scan=()`` (``--scan none``): no scan.

What the three fits of issue 30 measure with the defaults (README.md, "Fitting: scans and
results", has the table and the commands: ``benchmarks/fit_auto.py``).

**Writing back**: :func:`rewrite_scene` (from :mod:`raymitsuba.format.writeback`, which
says how) puts the fitted numbers into the .RAY text, every other byte unchanged.
"""

from __future__ import annotations

import fnmatch
import math
import re
import time
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Union

import numpy as np

from raymitsuba.atomic import atomic_path
from raymitsuba.format.commands import ParamKey
from raymitsuba.format.writeback import (MATERIAL_FIELDS, ParameterError, Value, model_values,
                                         parse_key, rewrite_scene, writable_keys)
from raymitsuba.model import Scene

__all__ = ["AUTO_SCAN", "AUTO_SCAN_COUNT", "AUTO_SCAN_RATIO", "FitError", "FitResult",
           "MAX_SCAN", "Scan", "auto_scans", "check_keys", "Step", "LOWER_BOUNDS", "MATERIAL_FIELDS", "Value",
           "clamp_value", "coarse", "default_keys", "downsampled", "level_of", "field_of", "fit", "model_values", "parameter_error",
           "rewrite_scene", "select_keys", "set_values", "to_python", "writable_keys",
           "write_scene"]

#: Lower bound of each field after every step (None: unbounded).
LOWER_BOUNDS: Dict[str, Optional[float]] = {
    "color": 0.0, "ambient_mix": 0.0, "diffuse_mix": 0.0, "specular_mix": 0.0,
    "phong_coeff": 0.0, "reflectivity": 1e-4, "refractivity": 1e-4, "ior": 1e-3,
    "position": None, "direction": None, "shape_coefficient": 0.0,
    # geometry and camera keys (the others -- offsets, factors, angles, corners, centres, the
    # eye, lookat and up -- are free)
    "radius": 1e-6, "fov": 1e-3,
}

#: The most combinations a scan may render (each is one render of the scene).
MAX_SCAN = 10_000

#: The fields whose keys ``scan="auto"`` scans (module docstring), and each one's valid
#: range for the scan: (lowest, highest) value tried.
AUTO_SCAN: Dict[str, tuple] = {"ior": (1e-3, math.inf), "fov": (1e-3, 179.0)}

#: The automatic scan's window: start / ratio to start x ratio.
AUTO_SCAN_RATIO = 1.5

#: The automatic scan's evenly spaced values in that window (the start is rendered too).
AUTO_SCAN_COUNT = 32

#: What a request the fit cannot carry out raises (an unknown key, a wrong target size, a
#: key with no line to write back to...): one class with the write-back's errors.
FitError = ParameterError


# -- which parameters ---------------------------------------------------------------------------
def used_materials(model: Scene) -> List[int]:
    """The materials (indices) of the objects and meshes, sorted."""
    return sorted({obj.material for obj in model.objects} | {m.material for m in model.meshes})


def default_keys(model: Scene) -> List[str]:
    """The default set of fitted parameters (see the module docstring)."""
    keys = []
    for index in used_materials(model):
        material = model.materials[index]
        if material.line is None:
            continue  # the default material: no line to write it back to
        names = ["color", "ambient_mix", "diffuse_mix", "specular_mix", "phong_coeff"]
        if material.reflectivity > 0:
            names.append("reflectivity")
        if material.refractivity > 0:
            names += ["refractivity", "ior"]
        keys += [f"mat{index}.{name}" for name in names]
    keys += [f"light{light.index}.color" for light in model.lights]
    return keys


def select_keys(model: Scene, requested: Optional[Sequence[str]], data=None) -> List[str]:
    """Resolve ``requested`` (exact keys or shell patterns such as ``mat1.*``) against
    :func:`writable_keys` (with the file's text ``data``, the geometry and camera keys too);
    None means :func:`default_keys`. Raises FitError naming the valid keys when an item
    matches nothing."""
    valid = writable_keys(model, data)
    if requested is None:
        return default_keys(model)
    keys: List[str] = []
    for item in requested:
        item = item.strip()
        if not item:
            continue
        matches = [k for k in valid if fnmatch.fnmatchcase(k, item)]
        if not matches:
            raise FitError(f"unknown parameter `{item}`{_why_not(model, item)}; valid keys: "
                           + (", ".join(valid) if valid else "none (no material or light lines)"))
        keys += [k for k in matches if k not in keys]
    if not keys:
        raise FitError("no parameters to fit")
    return keys


def _why_not(model: Scene, item: str) -> str:
    """Why the key ``item`` cannot be written back, when it names a line that is missing."""
    try:
        key = ParamKey.parse(item)
    except ValueError:
        return ""
    if key.owner == "mat" and key.index == 0:
        return " (mat0, the default material, has no `material` or `surface` line to write back to)"
    if key.owner == "background" and model.background_at is None:
        return " (the scene has no `background` line to write back to)"
    return ""


def field_of(key: str) -> str:
    return parse_key(key).field


# -- values ---------------------------------------------------------------------------------------
def to_python(value) -> Value:
    """A scene parameter as a float (scalars) or a tuple of floats (colors, points)."""
    array = np.array(value.numpy(), dtype=np.float64).ravel()
    return float(array[0]) if array.size == 1 else tuple(float(v) for v in array)


def clamp_value(key: str, value: Value) -> Value:
    """``value`` clamped into the range of the key's field."""
    low = LOWER_BOUNDS.get(field_of(key))
    if low is None:
        return value
    if isinstance(value, tuple):
        return tuple(max(v, low) for v in value)
    return max(value, low)


def parameter_error(fitted: Dict[str, Value], truth: Dict[str, Value]) -> Dict[str, float]:
    """Per key: the largest absolute difference between fitted and true components."""
    out = {}
    for key, value in fitted.items():
        a = np.atleast_1d(np.asarray(value, np.float64))
        b = np.atleast_1d(np.asarray(truth[key], np.float64))
        out[key] = float(np.max(np.abs(a - b)))
    return out


# -- the fit --------------------------------------------------------------------------------------
@dataclass
class Step:
    """One iteration: the loss of the parameters *before* its update, and those parameters."""

    iteration: int
    loss: float
    values: Dict[str, Value]


@dataclass(frozen=True)
class Scan:
    """A grid of ``count`` evenly spaced values of the scalar key ``key``, from ``low`` to
    ``high`` inclusive, tried before the gradient steps (see the module docstring)."""

    key: str
    low: float
    high: float
    count: int

    @classmethod
    def parse(cls, text: str) -> "Scan":
        """``KEY=LOW:HIGH:COUNT``, as ``--scan`` takes it (FitError if malformed)."""
        key, _, grid = text.partition("=")
        parts = grid.split(":")
        try:
            if not key.strip() or len(parts) != 3:
                raise ValueError
            low, high, count = float(parts[0]), float(parts[1]), int(parts[2])
        except ValueError:
            raise FitError(f"--scan `{text}`: write KEY=LOW:HIGH:COUNT, e.g. "
                           f"mat2.ior=1.0:2.0:12") from None
        return cls(key.strip(), low, high, count)

    def values(self) -> List[float]:
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low < self.high
                and self.count >= 2):
            raise FitError(f"the scan of `{self.key}` needs LOW < HIGH, both finite, and at "
                           f"least 2 values")
        return [float(v) for v in np.linspace(self.low, self.high, self.count)]


@dataclass
class FitResult:
    keys: List[str]
    start: Dict[str, Value]  # the values before the first step (after the scan, if any)
    fitted: Dict[str, Value]  # the values after the last step (clamped)
    history: List[Step] = field(default_factory=list)
    final_loss: float = math.nan  # the loss of ``fitted``
    start_image: Optional[np.ndarray] = None
    fitted_image: Optional[np.ndarray] = None
    iterations: int = 0
    seconds: float = 0.0
    # the scan's combinations ({key: value}) and their losses, in order (empty: no scan;
    # an automatic scan: each key's start, then its grid, key after key)
    scanned: List[tuple] = field(default_factory=list)
    scans: List["Scan"] = field(default_factory=list)  # the scans that ran (auto or given)
    scan_seconds: float = 0.0  # their renders' time (included in ``seconds``)

    @property
    def losses(self) -> List[float]:
        """The loss before each step, then the final loss."""
        return [s.loss for s in self.history] + [self.final_loss]


def fit(loaded, target, keys: Optional[Sequence[str]] = None, iters: int = 100,
        lr: float = 0.02, spp: Optional[int] = None,
        callback: Optional[Callable[[Step], Optional[bool]]] = None,
        final_lr: float = 0.1, levels: int = 1,
        scan: Union[str, Sequence[Scan], None] = "auto") -> FitResult:
    """Fit the parameters ``keys`` of ``loaded`` (see :func:`raymitsuba.load`) to the linear
    (H, W, 3) image ``target`` by Adam on the mean squared error; ``iters`` steps of
    learning rate ``lr`` (relative, see the module docstring), decaying geometrically to
    ``final_lr * lr`` at the last step. ``callback(step)`` runs after
    each iteration; returning True stops the fit early. The scene's parameters hold the
    fitted values afterwards. ``keys`` None: :func:`default_keys`; any differentiable key
    of ``loaded.params`` is accepted (e.g. ``background.color``, clamped >= 0).

    ``levels`` > 1: coarse to fine (see :func:`level_of`): the first steps compare the
    render and the target averaged over blocks of 2^(levels - 1) pixels, then 2^(levels -
    2)..., the last share at full resolution.

    ``scan``: ``"auto"`` (default): the automatic scan of the keys whose field is in
    :data:`AUTO_SCAN` (eta, the fov); a sequence of :class:`Scan`: grids of scalar keys
    among ``keys`` tried first, the steps starting from their best combination; ``()``,
    None or ``"none"``: no scan (see the module docstring)."""
    import drjit as dr

    from raymitsuba.api import render
    from raymitsuba.backend import mitsuba

    mi = mitsuba()
    params = loaded.params
    keys = list(default_keys(loaded.model) if keys is None else keys)
    if not keys:
        raise FitError("no parameters to fit")
    check_keys(loaded, keys)
    target = np.asarray(target, dtype=np.float32)
    shape = (loaded.options.height, loaded.options.width, 3)
    if target.shape != shape:
        raise FitError(f"the target is {target.shape[1]}x{target.shape[0]} but the scene is "
                       f"loaded at {shape[1]}x{shape[0]}")
    if not np.all(np.isfinite(target)):
        raise FitError("the target image holds non-finite values")
    if iters < 0 or not (lr > 0):
        raise FitError("need iters >= 0 and lr > 0")
    spp = int(spp or loaded.options.spp)
    from raymitsuba.plugins.whitted.arrays import jit_tensor
    target_tensor = jit_tensor(target)  # (aligned: the loss's kernels the same in every fit)
    if isinstance(scan, str) and scan not in ("auto", "none"):
        raise FitError(f"scan={scan!r}: use 'auto', 'none' or a list of Scan")
    automatic = scan == "auto"
    scans = auto_scans(keys, params) if automatic else \
        [] if scan is None or scan == "none" else list(scan)
    grids = scan_grids(scans, keys, params, product=not automatic)

    started = time.perf_counter()
    scanned = []
    if automatic:  # each key alone, its start first
        for item in scans:
            start_value = clamp_value(item.key, to_python(params[item.key]))
            scanned += run_scan(loaded, {item.key: [start_value] + grids[item.key]}, target,
                                spp)
    elif grids:
        scanned = run_scan(loaded, grids, target, spp)
    scan_seconds = time.perf_counter() - started
    optimizer = mi.ad.Adam(lr=lr)
    start, scales = {}, {}
    for key in keys:
        start[key] = to_python(params[key])
        optimizer[key] = typed(mi, params[key], clamp_value(key, start[key]))
        scales[key] = max(1.0, float(np.max(np.abs(np.atleast_1d(start[key])))))
    params.update(optimizer)
    start = {key: to_python(optimizer[key]) for key in keys}  # clamped
    # The steps render and update through the fitted parameters only: Mitsuba's render and
    # update visit every parameter they are given, 8 per material of the scene.
    fitted = loaded.traverse()
    fitted.keep([re.escape(key) + "$" for key in keys])

    result = FitResult(keys=keys, start=start, fitted=dict(start), scanned=scanned,
                       scans=scans, scan_seconds=scan_seconds)
    for iteration in range(iters):
        image = render(loaded, spp=spp, params=fitted)
        factor = 2 ** level_of(iteration, iters, levels)
        if factor > 1:
            loss = dr.mean(dr.square(downsampled(mi, image, factor) - coarse(target, factor)),
                           axis=None)
        else:
            loss = dr.mean(dr.square(image - target_tensor), axis=None)
        dr.backward(loss)
        loss_value = float(loss.numpy().ravel()[0])
        if iteration == 0:
            result.start_image = image.numpy()
        values = {key: to_python(optimizer[key]) for key in keys}
        decay = final_lr ** (iteration / max(iters - 1, 1))
        optimizer.set_learning_rate({key: lr * decay * scales[key] for key in keys})
        optimizer.step()
        for key in keys:
            value = to_python(optimizer[key])
            if not np.all(np.isfinite(value)):
                raise FitError(f"the fit diverged: `{key}` became {value} at iteration "
                               f"{iteration + 1}; try a smaller learning rate")
            clamped = clamp_value(key, value)
            if clamped != value:
                optimizer[key] = typed(mi, params[key], clamped)
        fitted.update(optimizer)
        step = Step(iteration + 1, loss_value, values)
        result.history.append(step)
        result.iterations = iteration + 1
        if callback is not None and callback(step):
            break

    # Leave the fitted values in the scene, detached from the optimizer.
    for key in keys:
        params[key] = dr.detach(optimizer[key])
    params.update()
    result.fitted = {key: to_python(params[key]) for key in keys}
    with dr.suspend_grad():
        final = render(loaded, spp=spp).numpy()
    result.fitted_image = final
    if result.start_image is None:
        result.start_image = final
    result.final_loss = float(np.mean(np.square(final.astype(np.float64) - target)))
    result.seconds = time.perf_counter() - started
    return result


def check_keys(loaded, keys: Sequence[str]) -> None:
    """FitError, before anything is rendered, for a key of ``keys`` that ``loaded`` does
    not have or that cannot move (a plane's transform: the message says where and why)."""
    params = loaded.params
    for key in keys:
        if key not in params:
            raise FitError(f"unknown parameter `{key}`; valid keys: {', '.join(params.keys())}")
        if loaded.geometry is not None and key in loaded.geometry.values:
            loaded.geometry.check(key)


def auto_scans(keys: Sequence[str], params) -> List[Scan]:
    """The automatic scans of ``keys`` at the values ``params`` holds (module docstring):
    for each scalar key whose field is in :data:`AUTO_SCAN`, in order, AUTO_SCAN_COUNT
    values from start / AUTO_SCAN_RATIO to start x AUTO_SCAN_RATIO, cut to the field's
    range (none where the start is not positive or the window is empty)."""
    out = []
    for key in keys:
        window = AUTO_SCAN.get(field_of(key))
        if window is None:
            continue
        value = to_python(params[key])
        if not isinstance(value, float) or not (value > 0 and math.isfinite(value)):
            continue
        low = max(value / AUTO_SCAN_RATIO, window[0])
        high = min(value * AUTO_SCAN_RATIO, window[1])
        if low < high:
            out.append(Scan(key, low, high, AUTO_SCAN_COUNT))
    return out


def scan_grids(scan: Sequence[Scan], keys: List[str], params,
               product: bool = True) -> Dict[str, List[float]]:
    """{key: its values} of the scans, checked: scalar keys among ``keys``, each once, at
    most MAX_SCAN combinations in all (``product`` False: the keys are scanned one by one,
    so renders, not combinations) (FitError otherwise, before anything is rendered)."""
    grids: Dict[str, List[float]] = {}
    for item in scan:
        if item.key not in keys:
            raise FitError(f"the scanned key `{item.key}` is not among the fitted keys "
                           f"({', '.join(keys)})")
        if item.key in grids:
            raise FitError(f"`{item.key}` is scanned twice")
        if not isinstance(to_python(params[item.key]), float):
            raise FitError(f"`{item.key}` is not a number: only scalar keys can be scanned")
        grids[item.key] = [clamp_value(item.key, v) for v in item.values()]
    combinations = (math.prod if product else sum)(len(v) for v in grids.values())
    if combinations > MAX_SCAN:
        raise FitError(f"the scan has {combinations} combinations, more than {MAX_SCAN} "
                       f"(one render each)")
    return grids


def run_scan(loaded, grids: Dict[str, List[float]], target: np.ndarray, spp: int) -> List[tuple]:
    """Render ``loaded`` at every combination of ``grids`` and leave it at the one of least
    loss (the mean squared error against ``target``); returns [({key: value}, loss)] in
    order (the first of equal losses wins)."""
    import itertools

    import drjit as dr

    from raymitsuba.api import render

    keys = list(grids)
    out = []
    with dr.suspend_grad():
        for combination in itertools.product(*(grids[k] for k in keys)):
            values = dict(zip(keys, combination))
            set_values(loaded, values)
            image = render(loaded, spp=spp).numpy()
            out.append((values, float(np.mean(np.square(image.astype(np.float64) - target)))))
    set_values(loaded, min(out, key=lambda item: item[1])[0])
    return out


def level_of(iteration: int, iters: int, levels: int) -> int:
    """**Coarse to fine**: the pyramid level of step ``iteration`` (0-based) of ``iters``:
    the steps are shared equally among ``levels`` levels, coarsest first; level L compares
    images averaged over 2^L x 2^L blocks of pixels. An edge that the target and the start
    place in different pixels gives an L2 loss that does not see which way to move it
    (the two do not overlap); averaged over larger blocks they do, and the gradient points
    the right way; the full resolution then places it exactly."""
    if levels <= 1 or iters <= 0:
        return 0
    return levels - 1 - min(iteration * levels // iters, levels - 1)


def coarse(image, factor):
    """The (H, W, 3) numpy ``image`` averaged over factor x factor blocks (the last, partial
    rows and columns dropped)."""
    h, w = image.shape[0] // factor, image.shape[1] // factor
    return image[:h * factor, :w * factor].reshape(h, factor, w, factor, 3).mean(axis=(1, 3))


def downsampled(mi, image, factor):
    """:func:`coarse` of a Dr.Jit TensorXf (H, W, 3), differentiable: gathers and sums."""
    import drjit as dr

    height, width = image.shape[0], image.shape[1]
    h, w = height // factor, width // factor
    y, x, c = np.meshgrid(np.arange(h), np.arange(w), np.arange(3), indexing="ij")
    total = None
    for dy in range(factor):
        for dx in range(factor):
            index = ((y * factor + dy) * width + (x * factor + dx)) * 3 + c
            part = dr.gather(mi.Float, image.array, mi.UInt32(index.ravel().astype(np.uint32)))
            total = part if total is None else total + part
    return mi.TensorXf(total * (1.0 / (factor * factor)), shape=(h, w, 3))


def typed(mi, like, value: Value):
    """``value`` (float or tuple) as a Dr.Jit value of the same type as ``like``."""
    if isinstance(value, tuple):
        return type(like)(*value)
    return mi.Float(value)


def set_values(loaded, values: Dict[str, Value]) -> None:
    """Set parameters of ``loaded`` from Python values (floats; tuples for colors, points and
    directions), as :func:`to_python` gives them and ``FitResult.fitted`` holds them."""
    from raymitsuba.backend import mitsuba

    mi = mitsuba()
    for key, value in values.items():
        loaded.params[key] = typed(mi, loaded.params[key], value)
    loaded.params.update()


# -- writing back ---------------------------------------------------------------------------------
def write_scene(path: str, data: Union[bytes, str]) -> None:
    """Write ``data`` to ``path`` atomically (a temporary file renamed over it)."""
    if isinstance(data, str):
        data = data.encode("utf-8", "surrogateescape")
    with atomic_path(path, ".ray") as tmp, open(tmp, "wb") as f:
        f.write(data)
