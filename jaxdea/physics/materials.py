"""Elastic energy functions W(I_1) in units of the shear modulus μ (docs/theory/axisymmetric.md §0).

Each function takes the first invariant I_1 and the Gent constant G (ignored by models that do not
use it) and returns W/μ. The electro-elastic energy adds I_5/2 (ideal dielectric, Eq. 9 of the
paper); see :mod:`jaxdea.physics.moduli`. A new model is one function here and one entry in ``ENERGIES``.
"""

import jax.numpy as jnp


def gent(i1, gent_constant):
    """Gent energy W = −(G/2) ln[1 − (I_1 − 3)/G]; G = inf gives neo-Hookean (docs/theory/axisymmetric.md
    §0)."""
    limited = jnp.isinf(gent_constant)
    g = jnp.where(limited, 1.0, gent_constant)  # double-where: finite gradients at G = inf
    x = jnp.where(limited, 0.0, (i1 - 3.0) / g)
    return jnp.where(limited, 0.5 * (i1 - 3.0), -0.5 * g * jnp.log1p(-x))


def neo_hookean(i1, gent_constant=None):
    """Neo-Hookean energy W = (I_1 − 3)/2."""
    del gent_constant
    return 0.5 * (i1 - 3.0)


ENERGIES = {"gent": gent, "neo_hookean": neo_hookean}
