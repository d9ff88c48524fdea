"""The tube: materials, moduli, base state, state matrices, the wall's discretisation and
propagation, the characteristic function. Imports numerics and the base layer."""
