"""Numerical configuration shared by the whole library: float64 everywhere."""

import jax

# Finite-element tangents and implicit derivatives lose digits quickly in float32; the library
# works in float64 and says so explicitly (klujax would turn it on as a side effect otherwise).
jax.config.update("jax_enable_x64", True)
