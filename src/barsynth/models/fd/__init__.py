"""The finite-difference bar: the accurate reference, uniform or undercut (spec 3.3, 1.6).

Sources: S. Bilbao, Numerical Sound Synthesis (Wiley 2009), ch. 7 (the theta scheme, losses
``sigma0``/``sigma1``, the bowed bar by Newton's method); A. Chaigne and V. Doutaut,
"Numerical simulations of xylophones. I.", JASA 101 (1997) (the Hertzian mallet, non-uniform
bars); G. Essl and P. R. Cook (ICMC 1999, JASA 2000) for the bowed bar's behaviour the model
must show.

The bar ``rho A(x) y_tt = -(E I(x) y_xx)_xx - 2 sigma0 rho A y_t + 2 sigma1 rho A y_txx + f``
lives on ``points`` grid nodes (:mod:`barsynth.physics.grid`), with any boundary condition of
spec 1.2 and any thickness profile (uniform, parabolic or circular undercut, or sampled).
With ``theory = timoshenko`` (spec 8.2) the bar is thick: shear and rotary inertia, on the
staggered two-field grid of :mod:`barsynth.physics.timoshenko_grid` (deflections at the nodes,
rotations between them, interleaved: the same pentadiagonal step), with ``shear_modulus_pa``
and ``shear_coefficient`` (a ``material`` sets them).
Time steps are the implicit theta scheme, one pentadiagonal solve per step; at
``theta <= 0.5`` it is stable at any step, above 0.5 the step is checked against the grid's
highest frequency before anything runs, and a scheme that would blow up is refused with the
largest ``theta`` that would not.

Excitations (:mod:`barsynth.exciters`): ``strike`` (a mallet, a mass on a Hertzian spring
``F = k d^2.5``, coupled to the bar step by step), ``bow`` (the friction of
:mod:`barsynth.dsp.friction` at the bow point, solved with each step by Newton's method or,
with ``bow_solver = explicit``, taken from the step before), ``pluck`` (the bar held out
``pluck_displacement_mm`` at the strike point and let go; near a clamped or pinned end no
point is held out more than ``PLUCK_REACH`` times that). A strike, bow or pluck at a fixed
point does nothing. The output is the bar's velocity at the pick-up (m/s) x ``level_db``; a
free-free bar's rigid-body motion (it would fly off when struck) is kept out of forces and
output.

Modules: :mod:`.table` (the parameters, :class:`FdParams`), :mod:`.design` (grid, stability,
the step's matrices, the decimation filter, modes and errors), :mod:`.kernel` (the numba
step), :mod:`.voice` (:class:`FdVoice`) and :mod:`.model` (:class:`FdModel`, ``MODEL``).
"""

from .design import check_stability, decimation_filter, discrete_frequency, discrete_t60
from .model import MAX_DESCRIBED, MODEL, FdModel, mode_errors_cents
from .table import FD_TABLE, FdParams
from .voice import FdVoice

__all__ = ["FD_TABLE", "MAX_DESCRIBED", "MODEL", "FdModel", "FdParams", "FdVoice", "check_stability",
           "decimation_filter", "discrete_frequency", "discrete_t60", "mode_errors_cents"]
