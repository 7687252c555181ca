"""Physics of vibrating bars: pure functions, numbers in, numbers out (spec 1).

Euler–Bernoulli bars as in Fletcher & Rossing, *The Physics of Musical
Instruments*, 2nd ed. (Springer 1998), ch. 2; the eigenvalue table of Selfridge
et al., AES Convention Paper 10553 (2022), Table 1, is reproduced by
:func:`lambdas`.
"""

from .boundary import BOUNDARY_CONDITIONS, lambda_ratios, lambdas
from .damping import (
    alpha_from_q,
    alpha_from_t60,
    damped_frequency,
    q_from_t60,
    t60_from_alpha,
    t60_from_q,
)
from .materials import Material, material, materials
from .modes import bar_frequencies, bending_wave_constant, mode_shape
from .timoshenko import shear_coefficient, timoshenko_frequencies
from .timoshenko_grid import TwoFieldGrid, timoshenko_grid, timoshenko_grid_modes
from .tuned_bar import TunedBar, tune_bar

__all__ = [
    "BOUNDARY_CONDITIONS",
    "Material",
    "TunedBar",
    "TwoFieldGrid",
    "alpha_from_q",
    "alpha_from_t60",
    "bar_frequencies",
    "bending_wave_constant",
    "damped_frequency",
    "lambda_ratios",
    "lambdas",
    "material",
    "materials",
    "mode_shape",
    "q_from_t60",
    "shear_coefficient",
    "t60_from_alpha",
    "t60_from_q",
    "timoshenko_frequencies",
    "timoshenko_grid",
    "timoshenko_grid_modes",
    "tune_bar",
]
