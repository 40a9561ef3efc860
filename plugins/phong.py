"""``rayphong``: the .RAY material, as a Mitsuba BSDF and as the functions of its model.

The local model of the format, for a hit with facing normal N (the shading
normal flipped toward V), V the direction back along the incoming ray and L the
unit direction toward a light of intensity I::

    ambient  = ka * C                                (times the sum of ambient lights)
    local(L) = kd * C * (N.L) + ks * (R.V)^n         where N.L > 0, else 0
    R        = 2 (N.L) N - L,  (R.V)^n taken as 0 where R.V <= 0

The highlight is not tinted by the base color C. :func:`phong_local` is the one
implementation of this formula; the Whitted integrator calls it with the
parameters of the surface it hit, gathered from the surface table
(``whitted/surfaces.py``), which it builds from this plugin's members through the surface
interface (``whitted/protocol.py``). So the BSDF itself holds parameters only: it has no
``eval``, ``sample`` or ``pdf`` (it is not a radiometric BSDF, and Mitsuba's own
integrators cannot render it).

Parameters (all differentiable; exposed by ``mi.traverse`` under these names):

* ``color`` (Color3f, default (1, 1, 1)): base color C
* ``ambient_mix`` (float, 1): ka; ``diffuse_mix`` (float, 1): kd; ``specular_mix`` (float, 0): ks
* ``phong_coeff`` (float, 1): the Phong exponent n >= 0
* ``reflectivity`` (float, 0): kr; ``refractivity`` (float, 0): kt
* ``ior`` (float, 1): index of refraction eta inside the object (1 outside)
* ``index`` (int, not a parameter): the material's number in file order, the i of its
  key ``mat{i}``. It keeps equal materials distinct where a loader merges objects whose
  properties are all equal (``mi.load_dict``'s ``optimize``, which ``raymitsuba.load``
  turns off), which would drop the keys of all but one.
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
        self.index = int(props.get("index", 0))
        color = props.get("color", mi.ScalarColor3f(1.0))
        values = [float(props.get(name, DEFAULTS[name])) for name in FLOAT_PARAMS]
        self.color = mi.Color3f(color)
        for name, value in zip(FLOAT_PARAMS, values):
            setattr(self, name, mi.Float(value))
        self.host_values = {"color": (color[0], color[1], color[2]),
                            **dict(zip(FLOAT_PARAMS, values))}
        self.parameters_changed([])
        self.m_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.GlossyReflection \
            | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
        self.m_components = [self.m_flags]

    # The surface interface (plugins/whitted/protocol.py): a plain material is its own material,
    # with no checkerboard and no image texture. Its ``host_values`` are kept by
    # ``parameters_changed``, which Mitsuba calls on every ``SceneParameters.update`` that
    # changes one.
    @property
    def material(self):
        return self

    checker_size = 0.0
    image_textures = ()

    def traverse(self, callback):
        callback.put("color", self.color, mi.ParamFlags.Differentiable)
        for name in FLOAT_PARAMS:
            callback.put(name, getattr(self, name), mi.ParamFlags.Differentiable)

    def parameters_changed(self, keys):
        # Opaque: a new value must not become a new constant in the kernels (a recompile
        # at every step of a fit).
        dr.make_opaque(self.color, *(getattr(self, name) for name in FLOAT_PARAMS))
        if keys:
            self.host_values = self.read_values()

    def read_values(self):
        """The parameters' values by name as Python floats (``color``: (r, g, b)), read from
        the parameters."""
        color = self.color
        return {"color": (color.x[0], color.y[0], color.z[0]),
                **{name: getattr(self, name)[0] for name in FLOAT_PARAMS}}

    def to_string(self):
        return f"Phong[color={self.color}, kd={self.diffuse_mix}, ks={self.specular_mix}]"
