"""Numerical building blocks that know nothing of tubes: scalar root lanes with implicit
derivatives, Bessel combinations. Imports the base layer only."""
