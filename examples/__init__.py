"""The paper's bodies as examples, outside the library (``jaxfem``, ``refine`` and ``tracking``
never import this package): the hand, the skin, the block, the cup holder and the Sec. 3.1 sheet,
their data generators and the scripts that reproduce the paper's figures (see examples/README.md).
Importable from the repository root; not installed by ``pip install .``."""
