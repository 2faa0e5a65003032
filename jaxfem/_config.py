"""Configuration shared by the whole library, applied once when :mod:`jaxfem` is imported: float64
everywhere, and compiled programs kept on disk between processes (:mod:`jaxfem.cache`)."""

import jax

# Finite-element tangents and implicit derivatives lose digits quickly in float32; the library
# works in float64 and says so explicitly (klujax would turn it on as a side effect otherwise).
jax.config.update("jax_enable_x64", True)

from .cache import configure_default  # noqa: E402

configure_default()
