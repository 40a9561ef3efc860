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

**Writing back** (:func:`rewrite_scene`): the .RAY text with only the fitted
numbers replaced, every other byte unchanged (comments, spacing, line ends), in
either dialect. Each key is parsed by :class:`raymitsuba.commands.ParamKey`; the
command it lives on is found from the model's positions (``Material.line`` /
``.column``, ``Light.line`` / ``.column``, ``Scene.background_at``), the operand
from the table of commands (:mod:`raymitsuba.commands`: which token feeds which
field, and whether the file holds the value or its reciprocal -- MIT 6.837's
``index`` is 1 / eta), and the token from the dialect's own lexical rules
(:func:`raymitsuba.lexer.tokens_from`; a MIT 6.837 command's operands may run onto
the next lines). A number whose value did not change keeps its original spelling, a
changed one is written as ``f"{x:.6g}"``.
"""

from __future__ import annotations

import fnmatch
import math
import re
import time
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from raymitsuba import commands as C
from raymitsuba.atomic import atomic_path
from raymitsuba.commands import ParamKey
from raymitsuba.lexer import LINE_END, tokens_from
from raymitsuba.model import Material, Scene

Value = Union[float, Tuple[float, ...]]

MATERIAL_FIELDS = Material.FIELDS

#: Lower bound of each field after every step (None: unbounded).
LOWER_BOUNDS: Dict[str, Optional[float]] = {
    "color": 0.0, "ambient_mix": 0.0, "diffuse_mix": 0.0, "specular_mix": 0.0,
    "phong_coeff": 0.0, "reflectivity": 1e-4, "refractivity": 1e-4, "ior": 1e-3,
    "position": None, "direction": None, "shape_coefficient": 0.0,
}

_LINE_END_KEPT = re.compile(f"({LINE_END.pattern})")  # re.split keeps the line ends


class FitError(ValueError):
    """A request the fit cannot carry out (unknown key, wrong target size, ...)."""


# -- which parameters ---------------------------------------------------------------------------
def writable_keys(model: Scene) -> List[str]:
    """Every parameter key whose value has a place in the .RAY file: the fields of each
    ``material`` / ``surface`` line (mat1, mat2, ...), of each ``light`` line by kind, and
    the background's color if it has a line."""
    keys = [f"mat{m.index}.{name}" for m in model.materials if m.line is not None
            for name in MATERIAL_FIELDS]
    for light in model.lights:
        keys += [f"light{light.index}.{name}" for name in C.light_fields(light.kind)]
    if model.background_at is not None:
        keys.append("background.color")
    return keys


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


def select_keys(model: Scene, requested: Optional[Sequence[str]]) -> List[str]:
    """Resolve ``requested`` (exact keys or shell patterns such as ``mat1.*``) against
    :func:`writable_keys`; None means :func:`default_keys`. Raises FitError naming the
    valid keys when an item matches nothing."""
    valid = writable_keys(model)
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
    return _key(key).field


def _key(key: str) -> ParamKey:
    try:
        return ParamKey.parse(key)
    except ValueError as e:
        raise FitError(str(e)) from None


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


def model_values(model: Scene, keys: Sequence[str]) -> Dict[str, Value]:
    """The values of ``keys`` as written in ``model`` (e.g. a ground-truth scene)."""
    out: Dict[str, Value] = {}
    for key in keys:
        parsed = _key(key)
        name = parsed.field
        if parsed.owner == "background":
            value = model.background
        elif parsed.owner == "mat":
            material = _material(model, parsed)
            value = getattr(material, name)
        else:
            light = _light(model, parsed)
            value = getattr(light, "shape" if name == "shape_coefficient" else name)
            if value is None:
                raise FitError(f"`{key}`: light {parsed.index} is a {light.kind.value} light "
                               f"and has no {name}")
        out[key] = tuple(float(v) for v in value) if isinstance(value, tuple) else float(value)
    return out


# -- the fit --------------------------------------------------------------------------------------
@dataclass
class Step:
    """One iteration: the loss of the parameters *before* its update, and those parameters."""

    iteration: int
    loss: float
    values: Dict[str, Value]


@dataclass
class FitResult:
    keys: List[str]
    start: Dict[str, Value]  # the values before the first step
    fitted: Dict[str, Value]  # the values after the last step (clamped)
    history: List[Step] = field(default_factory=list)
    final_loss: float = math.nan  # the loss of ``fitted``
    start_image: Optional[np.ndarray] = None
    fitted_image: Optional[np.ndarray] = None
    iterations: int = 0
    seconds: float = 0.0

    @property
    def losses(self) -> List[float]:
        """The loss before each step, then the final loss."""
        return [s.loss for s in self.history] + [self.final_loss]


def fit(loaded, target, keys: Optional[Sequence[str]] = None, iters: int = 100,
        lr: float = 0.02, spp: Optional[int] = None,
        callback: Optional[Callable[[Step], Optional[bool]]] = None,
        final_lr: float = 0.1) -> FitResult:
    """Fit the parameters ``keys`` of ``loaded`` (see :func:`raymitsuba.load`) to the linear
    (H, W, 3) image ``target`` by Adam on the mean squared error; ``iters`` steps of
    learning rate ``lr`` (relative, see the module docstring), decaying geometrically to
    ``final_lr * lr`` at the last step. ``callback(step)`` runs after
    each iteration; returning True stops the fit early. The scene's parameters hold the
    fitted values afterwards. ``keys`` None: :func:`default_keys`; any differentiable key
    of ``loaded.params`` is accepted (e.g. ``background.color``, clamped >= 0)."""
    import drjit as dr

    from raymitsuba.api import render
    from raymitsuba.backend import mitsuba

    mi = mitsuba()
    params = loaded.params
    keys = list(default_keys(loaded.model) if keys is None else keys)
    if not keys:
        raise FitError("no parameters to fit")
    for key in keys:
        if key not in params:
            raise FitError(f"unknown parameter `{key}`; valid keys: {', '.join(params.keys())}")
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
    target_tensor = mi.TensorXf(target)

    started = time.perf_counter()
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
    fitted = mi.traverse(loaded.scene)
    fitted.keep(keys)

    result = FitResult(keys=keys, start=start, fitted=dict(start))
    for iteration in range(iters):
        image = render(loaded, spp=spp, params=fitted)
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
def _format(x: float) -> str:
    text = f"{x:.6g}"
    return "0" if text == "-0" else text


def _material(model: Scene, key: ParamKey) -> Material:
    if key.index is None or key.index >= len(model.materials):
        raise FitError(f"`{key}`: the scene has no material {key.index}")
    if key.field not in MATERIAL_FIELDS:
        raise FitError(f"`{key}`: a material has no {key.field}")
    return model.materials[key.index]


def _light(model: Scene, key: ParamKey):
    if key.index is None or not 1 <= key.index <= len(model.lights):
        raise FitError(f"`{key}`: the scene has no light {key.index}")
    return model.lights[key.index - 1]


@dataclass(frozen=True)
class Place:
    """Where the operands of a key are: the command's line and column, and the token
    position of each component's operand with the operand (which may be a reciprocal)."""

    line: int
    column: int
    operands: Tuple[Tuple[int, C.Operand], ...]


def place_of(model: Scene, key: str) -> Place:
    """Where ``key``'s operands are written in the .RAY text the model was parsed from."""
    parsed = _key(key)
    if parsed.owner == "background":
        if model.background_at is None or parsed.field != "color":
            raise FitError(f"`{key}`: the scene has no `background` line to write it to")
        command = C.COMP575_COMMANDS["background"]
        line, column = model.background_at
    elif parsed.owner == "mat":
        material = _material(model, parsed)
        if material.line is None:
            raise FitError(f"`{key}`: the default material has no `material` or `surface` line")
        command = C.command_table(model.dialect)[C.MATERIAL_COMMAND[model.dialect]]
        line, column = material.line, material.column or 1
    else:
        light = _light(model, parsed)
        positions = C.light_positions(light.kind, parsed.field)
        if not positions:
            raise FitError(f"`{key}`: a {light.kind.value} light has no {parsed.field}")
        operands = C.LIGHT_COLOR if parsed.field == "color" else C.LIGHT_OPERANDS[light.kind]
        chosen = [o for o in operands if o.field == parsed.field]
        return Place(light.line, light.column or 1, tuple(zip(positions, chosen)))
    return Place(line, column, tuple(zip(command.positions(parsed.field),
                                         command.operand_for(parsed.field))))


def rewrite_scene(data: Union[bytes, str], model: Scene, values: Dict[str, Value]) -> Union[bytes, str]:
    """The .RAY source ``data`` with the operands of ``values``' keys replaced by the values.

    Every other byte is kept. ``model`` must be the parse of ``data`` (its line numbers
    locate the operands). A number whose value is unchanged (as float32, the precision of
    the renderer) keeps its original spelling."""
    is_bytes = isinstance(data, (bytes, bytearray))
    text = bytes(data).decode("utf-8", "surrogateescape") if is_bytes else data
    parts = _LINE_END_KEPT.split(text)  # line, end, line, end, ..., line
    lines = parts[0::2]
    edits: Dict[int, Dict[Tuple[int, int], str]] = {}  # line -> (start, end) -> new text
    for key, value in values.items():
        place = place_of(model, key)
        components = value if isinstance(value, tuple) else (value,)
        if len(components) != len(place.operands):
            raise FitError(f"`{key}`: expected {len(place.operands)} value(s), "
                           f"got {len(components)}")
        if not 1 <= place.line <= len(lines):
            raise FitError(f"line {place.line} is not in the scene text")
        tokens = list(tokens_from(lines, place.line, place.column, model.dialect))
        for (position, operand), component in zip(place.operands, components):
            if not math.isfinite(component):
                raise FitError(f"`{key}`: cannot write the non-finite value {component}")
            if position >= len(tokens):
                raise FitError(f"line {place.line} does not have operand {position}: "
                               f"{lines[place.line - 1]!r}")
            line, begin, end = tokens[position]
            original = lines[line - 1][begin:end]
            new = original if _same_float32(original, operand, component) \
                else _format(operand.written(component))
            edits.setdefault(line, {})[(begin, end)] = new
    for line, changes in edits.items():
        source = lines[line - 1]
        out, last = [], 0
        for (begin, end), new in sorted(changes.items()):
            out += [source[last:begin], new]
            last = end
        out.append(source[last:])
        parts[2 * (line - 1)] = "".join(out)
    result = "".join(parts)
    return result.encode("utf-8", "surrogateescape") if is_bytes else result


def _same_float32(token: str, operand: C.Operand, value: float) -> bool:
    """Whether the number ``token`` already means ``value`` (as float32, the renderer's
    precision) for ``operand``."""
    try:
        return np.float32(operand.value(float(token))) == np.float32(value)
    except (ValueError, ZeroDivisionError):
        return False


def write_scene(path: str, data: Union[bytes, str]) -> None:
    """Write ``data`` to ``path`` atomically (a temporary file renamed over it)."""
    if isinstance(data, str):
        data = data.encode("utf-8", "surrogateescape")
    with atomic_path(path, ".ray") as tmp, open(tmp, "wb") as f:
        f.write(data)
