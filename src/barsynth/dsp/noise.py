"""White noise for the per-sample kernels: xorshift64* (Vigna, "An experimental
exploration of Marsaglia's xorshift generators, scrambled", ACM TOMS 42, 2016),
uniform in [-1, 1) like Pd's ``noise~``, seeded through NumPy's ``SeedSequence``."""

from __future__ import annotations

import numpy as np
from numba import njit

_MULTIPLIER = np.uint64(2685821657736338717)
_TO_UNIT = 2.0 / 9007199254740992.0  # 2 / 2^53


def noise_state(seed: int | None) -> np.ndarray:
    """The generator's state (one nonzero uint64) for ``seed`` (None: fresh entropy)."""
    return np.random.SeedSequence(seed).generate_state(1, dtype=np.uint64) | np.uint64(1)


@njit(cache=True, inline="always")
def uniform_noise(state):
    """One step: returns ``(new_state, value in [-1, 1))``."""
    state ^= state >> np.uint64(12)
    state ^= state << np.uint64(25)
    state ^= state >> np.uint64(27)
    return state, float((state * _MULTIPLIER) >> np.uint64(11)) * _TO_UNIT - 1.0
