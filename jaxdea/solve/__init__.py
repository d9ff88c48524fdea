"""Roots of the characteristic function: frequencies, growth rates, critical voltages,
curves, branch tracing, root counting, accuracy estimates, mode shapes, stability.
Imports physics, numerics and the base layer."""
