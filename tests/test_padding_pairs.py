"""jaxfem.padding's padding matrix entries: the first pairs of the upper triangle, made without
the whole triangle, are np.triu_indices' first pairs (sizes drawn at random)."""

import numpy as np

from jaxfem.padding import _first_pairs


def test_first_pairs_are_triu_indices_first_pairs():
    rng = np.random.default_rng(int(np.random.SeedSequence().entropy % 2**32))
    cases = [(1, 0), (2, 1), (5, 10)] + [(int(m), int(rng.integers(0, m * (m - 1) // 2 + 1)))
                                         for m in rng.integers(2, 400, 30)]
    for m, k in cases:
        i, j = np.triu_indices(m, 1)
        a, b = _first_pairs(m, k)
        assert np.array_equal(a, i[:k]) and np.array_equal(b, j[:k]), (m, k)
