"""``raymitsuba fit``: fit material and light parameters of a .RAY scene to a target image.

See :mod:`raymitsuba.fit` for the loss (mean squared error), the optimizer (Adam, step
sizes relative to each parameter's scale), the valid ranges and the default parameters.
"""

from __future__ import annotations

import os

import click

from raymitsuba import images
from raymitsuba.cli import common
from raymitsuba.atomic import atomic_path
from raymitsuba.cli.common import EXIT_FAILURE, EXIT_SCENE_ERROR, report
from raymitsuba.cli.options import BATCH_OPTIONS, batch_options, dialect_option, render_options

PLOT_FORMATS = (".png", ".pdf", ".svg")


def fail(message: str, code: int = EXIT_SCENE_ERROR):
    """Exit with ``raymitsuba fit: error: MESSAGE`` (by default for bad input: status 2)."""
    common.fail("raymitsuba fit", message, code)


def parse_scene(path: str, dialect: str = "auto"):
    """The parsed scene and its bytes (exit 2 with FILE:LINE:COL diagnostics on errors)."""
    model = common.parse_or_exit(path, dialect)
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        fail(f"{path}: cannot read the scene file: {e.strerror or e}")
    return model, data


def show(value) -> str:
    if isinstance(value, tuple):
        return "(" + ", ".join(f"{v:.4g}" for v in value) + ")"
    return f"{value:.4g}"


@click.command()
@click.argument("scenes", nargs=-1, required=True, type=click.Path(dir_okay=False),
                metavar="SCENE...")
@click.option("--target", required=True, type=click.Path(dir_okay=False),
              help="The image to match (.exr, .npy, .png, .jpg); its size sets the render size. "
                   "With several scenes, a template ('targets/{stem}.png'; as --output).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="The fitted scene: SCENE with only the fitted numbers changed. With "
                   "several scenes a template naming each: {stem}, {name}, {parent}, {index} "
                   "(e.g. 'fitted/{stem}.ray').")
@click.option("--params", "keys", default=None, metavar="KEY,KEY...",
              help="Parameters to fit, e.g. mat1.color,mat1.diffuse_mix,light1.color "
                   "(shell patterns such as 'mat1.*' work). Default: every material "
                   "parameter of the materials used by objects (kr and kt only where they "
                   "start above 0, ior only where kt does) and every light's color.")
@click.option("--iters", default=100, show_default=True, type=click.IntRange(0, 1_000_000),
              help="Adam steps.")
@click.option("--lr", default=0.02, show_default=True, type=click.FloatRange(0, min_open=True),
              help="Learning rate, relative to each parameter's scale max(1, |start|).")
@click.option("--levels", default=1, show_default=True, type=click.IntRange(1, 8),
              help="Coarse to fine (one scene): the steps are shared among this many levels, "
                   "the first comparing images averaged over 2^(levels-1) pixel blocks (so that "
                   "an object far from its place in the target still gets a gradient), the "
                   "last at full resolution.")
@click.option("--scan", "scans", multiple=True, metavar="auto|none|KEY=LOW:HIGH:N",
              help="Scans before the steps, for losses with many basins (such as eta behind "
                   "glass in front of a checkerboard). 'auto' (the default): each fitted ior "
                   "and fov alone over start/1.5 .. start*1.5 (33 renders each, no "
                   "derivatives), starting from the best. 'none': no scan. KEY=LOW:HIGH:N "
                   "(one scene; repeatable: every combination; no automatic scan then): N "
                   "evenly spaced values of the scalar key KEY from LOW to HIGH, e.g. "
                   "mat2.ior=1.0:2.0:12.")
@render_options("spp", "max_depth", "aa", "memory_budget", "sphere_set")
@click.option("--truth", default=None, type=click.Path(dir_okay=False),
              help="The true scene (same structure): also print each parameter's error.")
@click.option("--plot", default=None, type=click.Path(dir_okay=False),
              help="Write the loss curve and target / start / fitted images (.png, .pdf, .svg).")
@render_options("srgb", srgb="Decode an 8-bit target (and textures) from sRGB; show the plot's "
                                 "images in sRGB.")
@click.option("-q", "--quiet", is_flag=True, help="Print only the final summary.")
@batch_options()
@dialect_option
def fit(scenes, target, output, keys, iters, lr, levels, scans, truth, plot, quiet, dialect,
        **options):
    """Fit parameters of the .RAY file SCENE so that its render matches TARGET.

    Minimises the mean squared error over pixels and channels (linear values) with
    Adam, keeping every parameter in its valid range, and writes the fitted scene to
    OUTPUT (atomically). Scene errors are reported as FILE:LINE:COLUMN and exit with
    status 2, like unknown --params keys and unreadable targets. Several SCENEs: one fit
    each on Dask workers (as ``raymitsuba render SCENE...``), with a manifest.
    """
    batch = {name: options.pop(name) for name in BATCH_OPTIONS}
    scans = scan_mode(scans)
    if len(scenes) == 1 and not any(batch.values()) and "{" not in target + output:
        return fit_one(scenes[0], target, output, keys, iters, lr, truth, plot, quiet,
                       dialect, options, levels, scans)
    if truth is not None or plot is not None:
        raise click.BadParameter("--truth and --plot are for one scene",
                                 param_hint="--truth/--plot")
    if levels != 1 or not isinstance(scans, str):
        raise click.BadParameter("--levels and --scan KEY=LOW:HIGH:N are for one scene",
                                 param_hint="--levels/--scan")
    from raymitsuba.batch.templates import TemplateError, expand, fill

    try:
        outputs = expand(output, scenes)
        targets = [fill(target, scene, i) for i, scene in enumerate(scenes)]
    except TemplateError as e:
        raise click.BadParameter(str(e))
    run_batch(scenes, targets, outputs, keys, iters, lr, dialect, batch, options, scans)


def scan_mode(scans):
    """``--scan``'s values as :func:`raymitsuba.fit.fit` takes them: "auto" (none given, or
    'auto'), "none", or the KEY=LOW:HIGH:N texts (not mixed with 'auto' or 'none')."""
    words = [text.strip().lower() for text in scans]
    if not scans or words == ["auto"]:
        return "auto"
    if words == ["none"]:
        return "none"
    if "auto" in words or "none" in words:
        raise click.BadParameter("give 'auto', 'none' or KEY=LOW:HIGH:N grids, not a mix",
                                 param_hint="--scan")
    return tuple(scans)


def run_batch(scenes, targets, outputs, keys, iters, lr, dialect, batch, options,
              scan="auto"):
    """One fit per scene on Dask workers (raymitsuba.batch.fit.fit_many): a line for each
    that failed, a one-line summary; exit status 0, 1 (a fit failed) or 2 (a scene, its
    parameters or its target had an error)."""
    from raymitsuba.batch.fit import fit_many
    from raymitsuba.batch.manifest import default_path

    manifest = batch.pop("manifest") or default_path(outputs)
    try:
        items = fit_many(scenes, targets, outputs,
                         keys=None if keys is None else keys.split(","), iters=iters, lr=lr,
                         dialect=dialect, report=report, manifest=manifest, scan=scan, **batch,
                         **options)
    except KeyboardInterrupt:
        fail("interrupted; the fitted scenes finished are kept (resume with --skip-existing)",
             130)
    except Exception as e:  # the cluster: no scheduler at the address, a worker refused...
        fail(common.error_message(e), EXIT_FAILURE)
    common.summarise("raymitsuba fit", items, manifest)


def fit_one(scene, target, output, keys, iters, lr, truth, plot, quiet, dialect, options,
            levels=1, scans="auto"):
    """Today's single fit, in this process."""
    from raymitsuba import fit as fitting

    scan = scans
    scans = () if isinstance(scans, str) else scans
    try:
        scans = [fitting.Scan.parse(text) for text in scans]
        for item in scans:
            item.values()  # (its range checked before the scene is read)
    except fitting.FitError as e:
        raise click.BadParameter(str(e), param_hint="--scan")
    if scans:
        scan = scans

    if plot is not None and os.path.splitext(plot)[1].lower() not in PLOT_FORMATS:
        raise click.BadParameter(f"{plot}: use one of {', '.join(PLOT_FORMATS)}",
                                 param_hint="--plot")
    srgb = bool(options["srgb"])
    model, data = parse_scene(scene, dialect)
    report(model.warnings)
    try:
        selected = fitting.select_keys(model, None if keys is None else keys.split(","), data)
    except fitting.FitError as e:
        fail(str(e))
    if not selected:
        fail("nothing to fit: the scene has no `material` (or `surface`) line used by an object and no light; "
             "name parameters with --params")
    for item in scans:
        if item.key not in selected:
            fail(f"--scan: `{item.key}` is not among the fitted parameters "
                 f"({', '.join(selected)})")
    truth_values = None
    if truth is not None:
        truth_model, truth_data = parse_scene(truth, dialect)
        try:
            truth_values = fitting.model_values(truth_model, selected, truth_data)
        except fitting.FitError as e:
            fail(f"{truth}: {e}")
    try:
        target_image = images.read(target, srgb=srgb)
    except images.ImageError as e:
        fail(str(e))
    import numpy as np

    if not np.all(np.isfinite(target_image)):
        fail(f"{target}: the image holds non-finite values (nan or inf)")
    if not os.path.isdir(os.path.dirname(os.path.abspath(output))):
        fail(f"{output}: the directory does not exist")

    from raymitsuba import api, backend
    from raymitsuba._llvm import LLVMError

    height, width = target_image.shape[:2]

    def progress(step):
        if quiet:
            return
        line = f"iter {step.iteration:4d}/{iters}  loss {step.loss:.6e}  " + "  ".join(
            f"{key}={show(value)}" for key, value in step.values.items())
        if truth_values is not None:
            errors = fitting.parameter_error(step.values, truth_values)
            line += f"  |error| max {max(errors.values()):.3g}"
        click.echo(line)

    try:
        backend.mitsuba(mitsuba_integrators=False)  # raywhitted only: skip Mitsuba's integrators
        loaded = api.load(model, width=width, height=height, **options)
        try:  # a key that cannot move is bad input (status 2), said before any render
            fitting.check_keys(loaded, selected)
        except fitting.FitError as e:
            fail(str(e))
        result = fitting.fit(loaded, target_image, selected, iters=iters, lr=lr, callback=progress,
                             levels=levels, scan=scan)
        fitted_text = fitting.rewrite_scene(data, model, result.fitted)
        if plot is not None:
            write_plot(plot, target_image, result, srgb)
        fitting.write_scene(output, fitted_text)
    except fitting.FitError as e:
        fail(str(e), EXIT_FAILURE)
    except LLVMError as e:
        fail(str(e), EXIT_FAILURE)
    except KeyboardInterrupt:
        fail("interrupted; no output written", 130)
    except OSError as e:
        fail(f"cannot write the output: {e}", EXIT_FAILURE)
    except Exception as e:  # Mitsuba's own errors (e.g. a texture it cannot decode)
        fail(f"{scene}: {common.error_message(e)}", EXIT_FAILURE)

    if result.scanned and scan == "auto":
        for item in result.scans:
            tried = [(values, loss) for values, loss in result.scanned if item.key in values]
            best, loss = min(tried, key=lambda pair: pair[1])
            click.echo(f"scanned {item.key} (auto; --scan none to skip): its start and "
                       f"{item.count} values in [{item.low:.4g}, {item.high:.4g}]: best "
                       f"{show(best[item.key])}  loss {loss:.6e}")
        click.echo(f"  the automatic scan: {len(result.scanned)} renders, "
                   f"{result.scan_seconds:.1f} s")
    elif result.scanned:
        best, loss = min(result.scanned, key=lambda item: item[1])
        click.echo(f"scanned {len(result.scanned)} combination(s): best " + "  ".join(
            f"{key}={show(value)}" for key, value in best.items()) + f"  loss {loss:.6e}")
    click.echo(f"fitted {len(selected)} parameter(s) in {result.iterations} iterations, "
               f"{result.seconds:.1f} s: loss {result.losses[0]:.6e} -> {result.final_loss:.6e}")
    for key in selected:
        line = f"  {key}: {show(result.start[key])} -> {show(result.fitted[key])}"
        if truth_values is not None:
            error = fitting.parameter_error({key: result.fitted[key]}, truth_values)[key]
            line += f"  (true {show(truth_values[key])}, |error| {error:.3g})"
        click.echo(line)
    click.echo(f"wrote {output}" + (f" and {plot}" if plot else ""))


def write_plot(path: str, target, result, srgb: bool) -> None:
    """Loss curve (log scale) and the target / start / fitted images side by side, atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    def display(image):
        image = np.asarray(image, dtype=np.float64)
        return images.srgb_encode(image) if srgb else np.clip(image, 0.0, 1.0)

    fig, axes = plt.subplots(1, 4, figsize=(16, 4), gridspec_kw={"width_ratios": [1.4, 1, 1, 1]})
    losses = result.losses
    axes[0].semilogy(range(len(losses)), np.maximum(losses, 1e-30))
    axes[0].set_xlabel("iteration")
    axes[0].set_ylabel("MSE loss")
    axes[0].set_title("loss")
    axes[0].grid(True, which="both", alpha=0.3)
    for ax, image, title in zip(axes[1:], (target, result.start_image, result.fitted_image),
                                ("target", "start", "fitted")):
        ax.imshow(display(image), interpolation="nearest")
        ax.set_title(title)
        ax.set_axis_off()
    fig.tight_layout()
    ext = os.path.splitext(path)[1].lower()
    try:
        with atomic_path(path, ext) as tmp:
            fig.savefig(tmp, dpi=100, format=ext[1:])
    finally:
        plt.close(fig)
