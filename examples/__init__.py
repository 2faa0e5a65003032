"""The paper's bodies as examples: their geometry generators, bundles and the scripts that reproduce
the paper's figures. Nothing in ``jaxfem`` or ``refine`` imports this package."""
