"""``rayphong``: the .RAY material, as a Mitsuba BSDF and as the functions of its model.

The local model of the format, for a hit with facing normal N (the shading
normal flipped toward V), V the direction back along the incoming ray and L the
unit direction toward a light of intensity I::

    ambient  = ka * C                                (times the sum of ambient lights)
    local(L) = kd * C * (N.L) + ks * (R.V)^n         where N.L > 0, else 0
    R        = 2 (N.L) N - L,  (R.V)^n taken as 0 where R.V <= 0

The highlight is not tinted by the base color C. :func:`phong_local` is the one
implementation of this formula; the Whitted integrator calls it with the
parameters of the surface it hit (gathered from every material at once, see
``whitted.py``), and this BSDF's ``eval`` calls it in the local frame. ``eval``
is the Phong term for one light, not a radiometric BSDF, and ``sample`` is never
used: the integrator traces the mirror and refraction directions itself.

Parameters (all differentiable; exposed by ``mi.traverse`` under these names):

* ``color`` (Color3f, default (1, 1, 1)): base color C
* ``ambient_mix`` (float, 1): ka; ``diffuse_mix`` (float, 1): kd; ``specular_mix`` (float, 0): ks
* ``phong_coeff`` (float, 1): the Phong exponent n >= 0
* ``reflectivity`` (float, 0): kr; ``refractivity`` (float, 0): kt
* ``ior`` (float, 1): index of refraction eta inside the object (1 outside)

Also reachable as ``eval_attribute_3("ambient_reflectance")`` (ka C) and
``eval_attribute_1("reflectivity" | "refractivity" | "ior")``.
"""

import drjit as dr
import mitsuba as mi

from raymitsuba.model import Material

# The parameters and their defaults are the format's, decided once in the scene model.
FLOAT_PARAMS = Material.FIELDS[1:]  # every field but the color
DEFAULTS = {name: getattr(Material(), name) for name in FLOAT_PARAMS}


def phong_lobe(n_dot_l, n_dot_v, l_dot_v, exponent):
    """(R.V)^n with R = 2 (N.L) N - L, so R.V = 2 (N.L)(N.V) - L.V; 0 where R.V <= 0."""
    r_dot_v = 2.0 * n_dot_l * n_dot_v - l_dot_v
    return dr.select(r_dot_v > 0, dr.power(dr.maximum(r_dot_v, 1e-30), exponent), 0.0)


def phong_local(n, v, l, color, diffuse_mix, specular_mix, phong_coeff):
    """kd C (N.L) + ks (R.V)^n for unit vectors N (facing V), V and L; 0 where N.L <= 0."""
    n_dot_l = dr.dot(n, l)
    value = diffuse_mix * color * n_dot_l \
        + specular_mix * phong_lobe(n_dot_l, dr.dot(n, v), dr.dot(l, v), phong_coeff)
    return dr.select(n_dot_l > 0, value, 0.0)


class Phong(mi.BSDF):
    def __init__(self, props):
        super().__init__(props)
        self.color = mi.Color3f(props.get("color", mi.ScalarColor3f(1.0)))
        for name in FLOAT_PARAMS:
            setattr(self, name, mi.Float(props.get(name, DEFAULTS[name])))
        self.parameters_changed([])
        self.m_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.GlossyReflection \
            | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
        self.m_components = [self.m_flags]

    @property
    def material(self):
        return self

    textures = ()

    def eval(self, ctx, si, wo, active=True):
        return self.eval_local(si, wo, self.color, active)

    def eval_local(self, si, wo, color, active=True):
        """The Phong term in the local shading frame, for the base color ``color``."""
        # Two-sided: in the local frame the facing normal is (0, 0, sign(wi.z)).
        n = mi.Vector3f(0.0, 0.0, dr.select(mi.Frame3f.cos_theta(si.wi) < 0, -1.0, 1.0))
        value = phong_local(n, si.wi, wo, color, self.diffuse_mix, self.specular_mix,
                            self.phong_coeff)
        return dr.select(active, value, 0.0)

    def eval_attribute_3(self, name, si, active=True):
        if name == "ambient_reflectance":
            return self.ambient_mix * self.color
        if name == "color":
            return mi.Color3f(self.color)
        return mi.Color3f(0.0)

    def eval_attribute_1(self, name, si, active=True):
        if name in ("reflectivity", "refractivity", "ior"):
            return mi.Float(getattr(self, name))
        return mi.Float(0.0)

    def has_attribute(self, name, active=True):
        return name in ("ambient_reflectance", "color", "reflectivity", "refractivity", "ior")

    def sample(self, ctx, si, sample1, sample2, active=True):
        return mi.BSDFSample3f(), mi.Color3f(0.0)  # never sampled: see the module docstring

    def pdf(self, ctx, si, wo, active=True):
        return mi.Float(0.0)

    def traverse(self, callback):
        callback.put("color", self.color, mi.ParamFlags.Differentiable)
        for name in FLOAT_PARAMS:
            callback.put(name, getattr(self, name), mi.ParamFlags.Differentiable)

    def parameters_changed(self, keys):
        # Opaque: a new value must not become a new constant in the kernels (a recompile
        # at every step of a fit).
        dr.make_opaque(self.color, *(getattr(self, name) for name in FLOAT_PARAMS))

    def to_string(self):
        return f"Phong[color={self.color}, kd={self.diffuse_mix}, ks={self.specular_mix}]"
