"""A spot's cone (cos a = 0, where a spot of coefficient 0 ends; the package docstring,
"Pairs"): which lights have one, cos a, and g of a shadow pair across it
(:func:`cone_crossing`, which ``shadows.py`` reads where the unlit sample has no blocker).
The keys count a point outside the cone as unlit (``samples.py``'s ``hit_keys``)."""

import drjit as dr

from .terms import at_l_and_r, on_lanes, signs_differ


def has_cone(light):
    """Whether ``light`` is a spot, whose cone (cos a = 0) is an edge (light.py's kinds)."""
    return getattr(light, "kind", None) == "spotlight"


def spot_cosine(light, wi):
    """cos a of a spotlight at the points whose direction toward it is ``wi``: > 0 inside
    its cone (light.py)."""
    return dr.dot(dr.normalize(light.direction), -wi)


def cone_crossing(source, wi, facing, made, count, lanes):
    """g of the shadow pairs of light ``source`` whose unlit sample has no blocker, at the
    points whose direction toward it is ``wi`` (stacked rays of ``lanes`` lanes, ``count``
    pairs): for a spot, its cos a where its sign differs between L and R (its cone's edge
    rather than the terminator), else ``facing`` (N.L: the terminator's); and the pairs
    across the cone (a Bool per pair, or None: not a spot). ``made``: the choices an
    earlier call made (``Shadows.shadow_crossing``'s), or None."""
    if has_cone(source):  # a spot's cone edge (cos a = 0) rather than the terminator
        cone = spot_cosine(source, wi)
        if made is None:
            crosses = signs_differ(*at_l_and_r(dr.detach(cone), count))
        else:
            crosses = made[0]
        facing = dr.select(on_lanes(crosses, lanes), cone, facing)
    else:
        crosses = None
    return facing, crosses
