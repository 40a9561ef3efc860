"""``rayphong``: the .RAY material as a Mitsuba BSDF.

It computes the local Phong term of the format for one light, as seen by the
Whitted integrator (:mod:`whitted`)::

    eval(wo) = kd * C * (N.L) + ks * (R.V)^n     where N.L > 0, else 0
    R        = 2 (N.L) N - L,  (R.V)^n taken as 0 where R.V <= 0

with ``wo = L`` the unit direction toward the light and ``si.wi = V`` the
direction back along the incoming ray, both in the local shading frame. The
material is **two-sided**: N is the shading normal flipped to face the incoming
ray (toward ``si.wi``). The highlight is not tinted by the base color C. The
integrator multiplies ``eval`` by the light's intensity and its shadow-ray
transmittance; it is not a cosine-weighted radiometric BSDF, and it is never
sampled (the integrator traces mirror and refraction directions itself).

The other terms of the model are reached through ``eval_attribute_*``:

* ``eval_attribute_3("ambient_reflectance")``: ka * C (times the ambient light)
* ``eval_attribute_1("reflectivity")``: kr, ``("refractivity")``: kt, ``("ior")``: eta

Parameters (all differentiable; exposed by ``mi.traverse`` under these names):

* ``color`` (Color3f, default (1, 1, 1)): base color C
* ``ambient_mix`` (float, 1), ``diffuse_mix`` (float, 1), ``specular_mix`` (float, 0)
* ``phong_coeff`` (float, 1): the Phong exponent n >= 0
* ``reflectivity`` (float, 0), ``refractivity`` (float, 0)
* ``ior`` (float, 1): index of refraction eta inside the object (1 outside)

An object with a texture or a checkerboard is given a ``raytextured`` BSDF that
wraps this one and multiplies C by the texel; both call :meth:`Phong.local`.
"""

import drjit as dr
import mitsuba as mi

_FLOAT_PARAMS = ("ambient_mix", "diffuse_mix", "specular_mix", "phong_coeff",
                 "reflectivity", "refractivity", "ior")
_DEFAULTS = {"ambient_mix": 1.0, "diffuse_mix": 1.0, "specular_mix": 0.0, "phong_coeff": 1.0,
             "reflectivity": 0.0, "refractivity": 0.0, "ior": 1.0}


def facing_cosines(si, wo):
    """(N.V, N.L) with N the shading normal flipped toward V = si.wi (local frame)."""
    side = dr.select(mi.Frame3f.cos_theta(si.wi) < 0, -1.0, 1.0)
    return side * mi.Frame3f.cos_theta(si.wi), side * mi.Frame3f.cos_theta(wo)


def phong_lobe(si, wo, n):
    """(R.V)^n with R the mirror image of L = wo about the facing normal; 0 where R.V <= 0."""
    n_dot_v, n_dot_l = facing_cosines(si, wo)
    # In the local frame N = (0, 0, +-1): R.V = 2 (N.L)(N.V) - L.V
    r_dot_v = 2.0 * n_dot_l * n_dot_v - dr.dot(wo, si.wi)
    safe = dr.maximum(r_dot_v, 1e-30)
    return dr.select(r_dot_v > 0, dr.power(safe, n), 0.0)


class Phong(mi.BSDF):
    def __init__(self, props):
        super().__init__(props)
        self.color = mi.Color3f(props.get("color", mi.ScalarColor3f(1.0)))
        for name in _FLOAT_PARAMS:
            setattr(self, name, mi.Float(props.get(name, _DEFAULTS[name])))
        self.m_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.GlossyReflection \
            | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
        self.m_components = [self.m_flags]

    # -- the model -------------------------------------------------------------------------
    def local(self, si, wo, color, active=True):
        """kd C (N.L) + ks (R.V)^n for the unit light direction wo, 0 where N.L <= 0."""
        _, n_dot_l = facing_cosines(si, wo)
        value = self.diffuse_mix * color * n_dot_l \
            + self.specular_mix * phong_lobe(si, wo, self.phong_coeff)
        return dr.select(active & (n_dot_l > 0), value, 0.0)

    def ambient(self, color):
        return self.ambient_mix * color

    def scalar_attribute(self, name):
        if name in ("reflectivity", "refractivity", "ior"):
            return getattr(self, name)
        raise KeyError(name)

    # -- mi.BSDF interface -------------------------------------------------------------------
    def eval(self, ctx, si, wo, active=True):
        return self.local(si, wo, self.color, active)

    def eval_attribute_3(self, name, si, active=True):
        if name == "ambient_reflectance":
            return self.ambient(self.color)
        if name == "color":
            return self.color
        return mi.Color3f(0.0)

    def eval_attribute_1(self, name, si, active=True):
        return self.scalar_attribute(name)

    def has_attribute(self, name, active=True):
        return name in ("ambient_reflectance", "color", "reflectivity", "refractivity", "ior")

    def sample(self, ctx, si, sample1, sample2, active=True):
        return mi.BSDFSample3f(), mi.Color3f(0.0)  # never sampled: see the module docstring

    def pdf(self, ctx, si, wo, active=True):
        return mi.Float(0.0)

    def traverse(self, callback):
        callback.put("color", self.color, mi.ParamFlags.Differentiable)
        for name in _FLOAT_PARAMS:
            callback.put(name, getattr(self, name), mi.ParamFlags.Differentiable)

    def parameters_changed(self, keys):
        pass

    def to_string(self):
        return f"Phong[color={self.color}, ks={self.specular_mix}, n={self.phong_coeff}]"
