"""The public path of :mod:`jaxdea.physics.units` (its names, re-exported)."""

from jaxdea.physics.units import *  # noqa: F403
