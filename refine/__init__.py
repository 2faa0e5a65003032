"""refine: measurement bundles, error measures and the searches that refine a finite-element model.

Deliberately empty of imports: submodules are imported where used (``from refine.bundle import
read_bundle``), so importing refine never pulls in jaxfem.
"""
