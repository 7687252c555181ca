"""The desk under a slapped ruler: material presets, plate modes and a modal bank (spec 9.2, 9.5).

The ruler engine hands the desk the contact force it exerts on it (N, one value per output
sample, positive pressing the top down); :func:`process_desk` turns that force into the
pressure the desk top radiates (Pa at 1 m above the desk).

Plate. The top is a simply supported rectangular plate ``a x b`` (``length_m`` x ``width_m``),
thickness ``h``, with (Leissa, *Vibration of Plates*, NASA SP-160, 1969, ch. 4)

    f_mn = (pi/2) sqrt(D / (rho h)) ((m/a)^2 + (n/b)^2),   D = E h^3 / (12 (1 - nu^2)),

shape ``W_mn(x, y) = sin(m pi x/a) sin(n pi y/b)`` (unit peak) and modal mass
``M = rho h a b / 4``; equivalently the mass-normalised shape is
``phi_mn = W_mn / sqrt(M) = 2 sin(m pi x/a) sin(n pi y/b) / sqrt(rho h a b)``. A real table
top sits on legs or rails, a glass top on pads: simple support is the spec's start, not a
measurement.

Wood is orthotropic. A wooden top (grain along its length) is given as the isotropic plate of
Huber's approximation ``D_12 + 2 D_66 = sqrt(D_11 D_22)``: ``E = sqrt(E_L E_T)`` and
``nu^2 = nu_LT nu_TL`` (``nu_TL = nu_LT E_T / E_L``) give ``D = sqrt(D_11 D_22)`` exactly.
On the real dimensions this keeps the formula above but puts the lowest mode 15 % (pine) to
25 % (oak) above the Huber plate's (its along-grain modes too low, its cross-grain ones too high).

Losses. Each mode's ``Q = 1 / loss_factor``, the same at every frequency (no growth with f),
so ``t60_s = 2 Q ln(1000) / omega``. The loss factors are those of a mounted top (joints,
legs, pads), well above the materials' own (Cremer, Heckl & Petersson, *Structure-Borne
Sound*, 3rd ed., 2005: wood 0.008-0.01, steel 1e-4-6e-4, glass 6e-4-2e-3).

Radiation. A mode's volume displacement is ``V = q int W dA = q a b c_m c_n`` with
``c_m = 2/(m pi)`` for odd ``m``; an even index has no net volume, and is given the
same factor times :data:`EDGE_RADIATION_FACTOR` (0.3, assumed): below the coincidence
frequency such modes radiate from their edges and corners, weaker than the odd-odd ones
(C. E. Wallace, JASA 51, 1972, 946-952), and this one number stands for that. The
pressure at ``r = 1 m`` is the monopole estimate ``p = rho_air V'' / (4 pi r)``, times the
open top's short-circuit factor ``s = k d / sqrt(1 + (k d)^2)`` (``k = omega / c_air``,
``d = (a + b) / 4``; this form and ``d`` assumed): a top open below radiates from both faces,
and where it is small against the wavelength the two cancel to a dipole, whose pressure is
the monopole's times about ``k d`` (P. M. Morse and K. U. Ingard, *Theoretical Acoustics*,
1968, ch. 7); without it a 1 mm steel top's 8 Hz mode would ring as strong infrasound.
On the upper side of the top (where the ruler and the listener are) a top pushed down gives a
rarefaction, so for a force ``F`` at ``(x0, y0)``

    q'' + (omega/Q) q' + omega^2 q = W(x0, y0) F / M,    p = -s rho_air a b c_m c_n q'' / (4 pi r),

i.e. with ``x = -s rho_air a b c_m c_n q / (4 pi r)`` each mode is
``x'' + (omega/Q) x' + omega^2 x = gain F``, ``gain = -s rho_air a b c_m c_n W(x0, y0) / (4 pi r M)``
(Pa/N), and its pressure is ``x''``;
``|gain|`` is the mode's pressure per newton well above its resonance, ``|gain| Q`` at it.

Discretisation. Each mode's state ``(x, x')`` advances by the exact zero-order-hold solution
over one sample (the force held constant over the sample): ``s <- e^{AT} s + Gamma F``. The
output is the mode's mean acceleration over that sample, ``(x'[n+1] - x'[n]) / T``: exact
for a held force, and free of the question which side of a force step a point sample takes. Modes at or above
``0.45 sample_rate`` are dropped (muted, never folded).

Contact. ``contact_stiffness_n_m2`` (N/m per metre of ruler lying on the desk) and
``contact_damping_n_s_m2`` are penalty values of the ruler engine's one-sided contact. The
physical line-contact stiffness of a ruler on wood (across the grain, E about 1 GPa) is of
order 1e9 N/m^2, on steel or glass (E* of tens of GPa) of order 1e10-1e11: stiffer than an
FD ruler at 48 kHz resolves cheaply. The presets keep the order (wood < oak < steel < glass) at
1e9, 1.5e9, 4e9, 6e9 N/m^2 (assumed): a ruler lying on a penalty foundation ``k`` is held over
about ``(4 E I / k)^(1/4)`` (5 mm for a 3 mm acrylic ruler on wood), so a softer one lowers the
short cantilever's pitch (2e8 N/m^2: 5 % lower; 1e9: 3 %), and a stiffer one costs Newton
iterations on the desk's chatter (2e10: twice as many).
The damping is set from a restitution coefficient (assumed: pine 0.5, oak 0.6, steel 0.8,
glass 0.85) of a linear spring-dashpot contact carrying :data:`REFERENCE_RULER_KG_M` (a
30 mm x 1 mm steel rule, 0.2355 kg/m): see :func:`contact_damping_for` and
:func:`contact_restitution` (a lighter ruler on the same desk rebounds less).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from ...checks import check_number, check_whole
from ...errors import ParameterError
from ...physics.materials import material

__all__ = ["AIR_DENSITY_KG_M3", "DESKS", "DESK_NAMES", "EDGE_RADIATION_FACTOR", "LISTENING_DISTANCE_M",
           "MAX_MODE_FRACTION", "REFERENCE_RULER_KG_M", "SPEED_OF_SOUND_M_S", "Desk", "DeskBank", "DeskModes",
           "contact_damping_for", "contact_restitution", "contact_restitution_from", "desk_bank", "desk_mode_list",
           "desk_modes", "process_desk", "reset_desk"]

AIR_DENSITY_KG_M3 = 1.204
"""Air at 20 degC and 101.325 kPa (kg/m^3; ISO 2533 standard-atmosphere value at 20 degC)."""

SPEED_OF_SOUND_M_S = 343.2
"""Speed of sound in air at 20 degC (m/s)."""

LISTENING_DISTANCE_M = 1.0
"""Distance above the desk at which :func:`process_desk` gives the pressure (m)."""

EDGE_RADIATION_FACTOR = 0.3
"""Volume factor of an even mode index relative to an odd one (dimensionless; assumed)."""

MAX_MODE_FRACTION = 0.45
"""Modes at or above this fraction of the sample rate are dropped by :func:`desk_bank`."""

REFERENCE_RULER_KG_M = 7850.0 * 0.030 * 0.001
"""Mass per metre of the ruler the contact damping is set for: a 30 mm x 1 mm steel rule (kg/m)."""

_MAX_COUNT = 1000  # most modes desk_modes gives (a bank of more costs more than it adds)


@dataclass(frozen=True)
class Desk:
    """A desk top: its plate, its losses and its contact with a ruler.

    Attributes
    ----------
    name, description : str
        Key in :data:`DESKS`, and what the numbers describe.
    youngs_modulus_pa : float
        Young's modulus ``E`` of the (equivalent isotropic) plate, Pa.
    density_kg_m3 : float
        Density ``rho``, kg/m^3.
    poisson_ratio : float
        ``nu``, dimensionless, 0 to 0.5 (exclusive).
    thickness_m, length_m, width_m : float
        The top's thickness ``h`` and sides ``a`` (along the front edge) and ``b`` (front to back), m.
    loss_factor : float
        ``eta`` of every mode, dimensionless, 0 to 1: ``Q = 1 / eta`` at every frequency.
    contact_stiffness_n_m2 : float
        Penalty stiffness of the ruler-desk contact per metre of ruler on the desk, N/m per m.
    contact_damping_n_s_m2 : float
        Contact damping per metre of ruler, acting only while pressed, N s/m per m.
    source : str
        Where the numbers come from ("assumed" where so).
    """

    name: str
    description: str
    youngs_modulus_pa: float
    density_kg_m3: float
    poisson_ratio: float
    thickness_m: float
    length_m: float
    width_m: float
    loss_factor: float
    contact_stiffness_n_m2: float
    contact_damping_n_s_m2: float
    source: str

    def __post_init__(self) -> None:
        for field, unit in (("youngs_modulus_pa", "Pa"), ("density_kg_m3", "kg/m^3"), ("thickness_m", "m"),
                            ("length_m", "m"), ("width_m", "m"), ("contact_stiffness_n_m2", "N/m^2")):
            check_number(field, getattr(self, field), unit, minimum=0.0, minimum_exclusive=True)
        check_number("poisson_ratio", self.poisson_ratio, "", minimum=0.0, maximum=0.5, maximum_exclusive=True)
        check_number("loss_factor", self.loss_factor, "", minimum=0.0, maximum=1.0, minimum_exclusive=True)
        check_number("contact_damping_n_s_m2", self.contact_damping_n_s_m2, "N s/m^2", minimum=0.0)

    @property
    def q(self) -> float:
        """Every mode's quality factor ``1 / loss_factor`` (dimensionless)."""
        return 1.0 / self.loss_factor

    @property
    def bending_stiffness_n_m(self) -> float:
        """The plate's ``D = E h^3 / (12 (1 - nu^2))``, N m."""
        return self.youngs_modulus_pa * self.thickness_m ** 3 / (12.0 * (1.0 - self.poisson_ratio ** 2))

    @property
    def mass_per_area_kg_m2(self) -> float:
        """``rho h``, kg/m^2."""
        return self.density_kg_m3 * self.thickness_m


def contact_damping_for(stiffness_n_m2: float, restitution: float,
                        mass_per_length_kg_m: float = REFERENCE_RULER_KG_M) -> float:
    """Damping (N s/m^2) giving a linear spring-dashpot contact the coefficient of restitution ``e``.

    For a mass ``mu`` (per metre) on a spring ``k`` and dashpot ``c`` (per metre), released in
    contact, the rebound speed over the impact speed is ``e = exp(-zeta pi / sqrt(1 - zeta^2))``
    with ``zeta = c / (2 sqrt(k mu))``; so ``zeta = -ln e / sqrt(pi^2 + ln^2 e)``.

    >>> round(contact_restitution_from(1e9, contact_damping_for(1e9, 0.5), REFERENCE_RULER_KG_M), 12)
    0.5
    """
    k = check_number("stiffness_n_m2", stiffness_n_m2, "N/m^2", minimum=0.0, minimum_exclusive=True)
    e = check_number("restitution", restitution, "", minimum=0.0, maximum=1.0, minimum_exclusive=True)
    mu = check_number("mass_per_length_kg_m", mass_per_length_kg_m, "kg/m", minimum=0.0, minimum_exclusive=True)
    log_e = math.log(e)
    zeta = -log_e / math.sqrt(math.pi ** 2 + log_e ** 2)
    return 2.0 * zeta * math.sqrt(k * mu)


def contact_restitution_from(stiffness_n_m2: float, damping_n_s_m2: float, mass_per_length_kg_m: float) -> float:
    """Coefficient of restitution of a linear spring-dashpot contact (dimensionless, 0 if overdamped)."""
    zeta = damping_n_s_m2 / (2.0 * math.sqrt(stiffness_n_m2 * mass_per_length_kg_m))
    if zeta >= 1.0:
        return 0.0
    return math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta * zeta))


def contact_restitution(desk: Desk, mass_per_length_kg_m: float = REFERENCE_RULER_KG_M) -> float:
    """The coefficient of restitution of a ruler of ``mass_per_length_kg_m`` (kg/m) slapping ``desk``.

    >>> contact_restitution(DESKS["wood"]) < contact_restitution(DESKS["steel"])
    True
    """
    mu = check_number("mass_per_length_kg_m", mass_per_length_kg_m, "kg/m", minimum=0.0, minimum_exclusive=True)
    return contact_restitution_from(desk.contact_stiffness_n_m2, desk.contact_damping_n_s_m2, mu)


def _wood_plate(e_bending_pa: float, et_over_el: float, nu_lt: float) -> tuple[float, float]:
    """Huber's equivalent isotropic ``(E, nu)`` of a wood plate: ``E_L = 1.1 x`` the bending MOE (WH2010)."""
    e_l = 1.1 * e_bending_pa
    e_t = et_over_el * e_l
    return math.sqrt(e_l * e_t), math.sqrt(nu_lt * nu_lt * et_over_el)


def _make_desks() -> dict[str, Desk]:
    wh = ("USDA FPL Wood Handbook (FPL-GTR-190, 2010) ch. 5 at 12 % MC: Table 5-3a MOE (static bending) "
          "and specific gravity G (rho = G x 1120 kg/m^3, as in barsynth's materials.toml), Table 5-1 E_T/E_L, "
          "Table 5-2 nu_LT; read from engdatabase.com's transcription of those tables (pine-ponderosa, "
          "oak-red-laurel for the red-oak group's ratios) and WH Table 5-3a via issuu.com/nhla")
    plate_note = "Huber-equivalent isotropic plate: E = sqrt(E_L E_T), nu = sqrt(nu_LT nu_TL), E_L = 1.1 MOE"
    pine_e, pine_nu = _wood_plate(8.9e9, 0.083, 0.400)
    oak_e, oak_nu = _wood_plate(12.5e9, 0.082, 0.448)
    steel, glass = material("steel"), material("glass")
    contact = "contact stiffness: assumed penalty value (see module doc); damping for restitution {e} (assumed) " \
              "with a 0.2355 kg/m steel rule"
    desks = [
        Desk("wood", "A pine table top, 25 mm thick, 1.2 m x 0.7 m, grain along its length, on legs.",
             pine_e, 0.40 * 1120.0, pine_nu, 0.025, 1.2, 0.7, 0.02,
             1e9, contact_damping_for(1e9, 0.5),
             f"Ponderosa pine, {wh}: MOE 8.9 GPa, G 0.40, E_T/E_L 0.083, nu_LT 0.400; {plate_note}. "
             "Size and thickness: assumed (a typical table). Loss factor 0.02: assumed for a mounted top "
             "(CHP wood material eta 0.008-0.01 plus joints and legs). " + contact.format(e=0.5)),
        Desk("oak", "An oak table top, 30 mm thick, 1.6 m x 0.8 m, grain along its length, on legs.",
             oak_e, 0.63 * 1120.0, oak_nu, 0.030, 1.6, 0.8, 0.015,
             1.5e9, contact_damping_for(1.5e9, 0.6),
             f"Northern red oak, {wh}: MOE 12.5 GPa, G 0.63, E_T/E_L 0.082 and nu_LT 0.448 (red-oak group); "
             f"{plate_note}. "
             "Size and thickness: assumed. Loss factor 0.015: assumed (CHP wood eta 0.008-0.01 plus mounting). "
             + contact.format(e=0.6)),
        Desk("steel", "A steel desk: a 1 mm sheet-steel top, 1.2 m x 0.6 m, on a frame (simply supported).",
             steel.youngs_modulus_pa, steel.density_kg_m3, steel.poisson_ratio, 0.001, 1.2, 0.6, 0.01,
             4e9, contact_damping_for(4e9, 0.8),
             f"E, rho, nu: barsynth materials.toml [steel] ({steel.source.split('. Q:')[0]}). Size: assumed "
             "(an office desk). Loss factor 0.01: assumed for a sheet on a frame (CHP steel material eta "
             "1e-4-6e-4; the frame's joints, drawers and what lies on a desk add most). " + contact.format(e=0.8)),
        Desk("glass", "A 10 mm soda-lime glass table top, 1.2 m x 0.7 m, on pads (taken as simply supported).",
             glass.youngs_modulus_pa, glass.density_kg_m3, glass.poisson_ratio, 0.010, 1.2, 0.7, 0.003,
             6e9, contact_damping_for(6e9, 0.85),
             f"E, rho, nu: barsynth materials.toml [glass] ({glass.source.split('. Q:')[0]}). Size: assumed. "
             "Loss factor 0.003: assumed (CHP glass eta 6e-4-2e-3, plus rubber pads). " + contact.format(e=0.85)),
    ]
    return {desk.name: desk for desk in desks}


DESKS: dict[str, Desk] = _make_desks()
"""The desk presets, by name."""

DESK_NAMES: tuple[str, ...] = tuple(DESKS)
"""``("wood", "oak", "steel", "glass")``."""


class DeskModes(NamedTuple):
    """A desk's modes, lowest first.

    Attributes
    ----------
    frequency_hz : numpy.ndarray
        Mode frequencies, Hz.
    t60_s : numpy.ndarray
        Time to decay by 60 dB, s.
    gain : numpy.ndarray
        Pa at 1 m (above the desk) per N of contact force (pressing down), as each mode's
        acceleration response: mode ``x'' + (omega/Q) x' + omega^2 x = gain F``, pressure ``x''``.
    """

    frequency_hz: np.ndarray
    t60_s: np.ndarray
    gain: np.ndarray


def _volume_factor(index: np.ndarray) -> np.ndarray:
    """``int_0^1 sin(k pi u) du = 2/(k pi)`` for odd ``k``; an even ``k`` gets that times the edge factor."""
    base = 2.0 / (index * math.pi)
    return np.where(index % 2 == 1, base, EDGE_RADIATION_FACTOR * base)


def desk_modes(desk: Desk, *, max_hz: float, max_count: int = 40,
               contact_xy: tuple[float, float] = (0.5, 0.15)) -> DeskModes:
    """The desk top's lowest simply supported plate modes below ``max_hz``, driven at ``contact_xy``.

    Parameters
    ----------
    desk : Desk
        The desk.
    max_hz : float
        Only modes below this frequency (Hz, > 0).
    max_count : int
        At most this many modes (the lowest), 1 to 1000.
    contact_xy : (float, float)
        Where the ruler presses, as fractions (0 to 1) of ``length_m`` and ``width_m``; the
        default is the middle of the front edge, 15 % of the depth in.

    Returns
    -------
    DeskModes
        Frequencies (sorted; ties by ``m``, then ``n``), T60s and gains (Pa/N); possibly empty.

    Examples
    --------
    >>> round(float(desk_modes(DESKS["wood"], max_hz=1000.0).frequency_hz[0]), 1)
    78.3
    """
    if not isinstance(desk, Desk):
        raise ParameterError(f"parameter desk = {desk!r:.80} is not a Desk; allowed: a Desk, e.g. DESKS['wood']")
    max_hz = check_number("max_hz", max_hz, "Hz", minimum=0.0, minimum_exclusive=True)
    max_count = check_whole("max_count", max_count, "", 1, _MAX_COUNT)
    if not (isinstance(contact_xy, (tuple, list)) and len(contact_xy) == 2):
        raise ParameterError(f"parameter contact_xy = {contact_xy!r:.80} is not a pair; "
                             "allowed: (x, y), each 0 to 1 dimensionless")
    x0 = check_number("contact_xy[0]", contact_xy[0], "", minimum=0.0, maximum=1.0)
    y0 = check_number("contact_xy[1]", contact_xy[1], "", minimum=0.0, maximum=1.0)
    a, b = desk.length_m, desk.width_m
    base_hz = 0.5 * math.pi * math.sqrt(desk.bending_stiffness_n_m / desk.mass_per_area_kg_m2)
    # f_m1 >= base (m/a)^2: no m beyond a sqrt(max_hz / base); and none beyond max_count (the modes
    # (1..max_count, n) all lie below (max_count + 1, n)); likewise for n.
    m_top = min(max_count, int(a * math.sqrt(max_hz / base_hz)) + 1)
    n_top = min(max_count, int(b * math.sqrt(max_hz / base_hz)) + 1)
    m, n = np.meshgrid(np.arange(1, m_top + 1), np.arange(1, n_top + 1), indexing="ij")
    m, n = m.ravel(), n.ravel()
    f = base_hz * ((m / a) ** 2 + (n / b) ** 2)
    keep = f < max_hz
    m, n, f = m[keep], n[keep], f[keep]
    order = np.lexsort((n, m, f))[:max_count]
    m, n, f = m[order], n[order], f[order]
    omega = 2.0 * math.pi * f
    t60 = 2.0 * desk.q * math.log(1000.0) / omega
    shape_at_contact = np.sin(m * math.pi * x0) * np.sin(n * math.pi * y0)
    volume_m2 = a * b * _volume_factor(m) * _volume_factor(n)
    modal_mass_kg = desk.mass_per_area_kg_m2 * a * b / 4.0
    kd = omega / SPEED_OF_SOUND_M_S * (a + b) / 4.0
    short_circuit = kd / np.sqrt(1.0 + kd * kd)
    gain = -(short_circuit * AIR_DENSITY_KG_M3 * volume_m2 * shape_at_contact
             / (4.0 * math.pi * LISTENING_DISTANCE_M * modal_mass_kg))
    return DeskModes(f.astype(np.float64), t60.astype(np.float64), gain.astype(np.float64))


def desk_mode_list(desk: Desk, max_hz: float, max_count: int = 40) -> list[tuple[float, float, float]]:
    """``(frequency_hz, gain Pa/N, t60_s)`` of each mode of :func:`desk_modes` (default contact), for reading."""
    modes = desk_modes(desk, max_hz=max_hz, max_count=max_count)
    return [(float(f), float(g), float(t)) for f, g, t in zip(modes.frequency_hz, modes.gain, modes.t60_s)]


class DeskBank(NamedTuple):
    """A bank of two-pole resonators, one per mode: coefficients and the state they carry.

    Attributes
    ----------
    coefficients : numpy.ndarray
        ``(modes, 6)``: per mode ``[Phi11 - 1, Phi12, Gamma1, Phi21, Phi22 - 1, Gamma2]`` of the
        exact zero-order-hold step ``(x, v) <- Phi (x, v) + Gamma F`` (``Gamma`` holds the gain).
    state : numpy.ndarray
        ``(modes, 2)``: each mode's ``x`` and ``v = x'``; zeros are silence.
    sample_rate : float
        Hz; the output is ``(v[n+1] - v[n]) * sample_rate``.
    """

    coefficients: np.ndarray
    state: np.ndarray
    sample_rate: float


def _zoh_step(omega: float, q: float, gain: float, dt: float) -> tuple[float, ...]:
    """``[Phi11 - 1, Phi12, Gamma1, Phi21, Phi22 - 1, Gamma2]`` of ``x'' + (omega/Q) x' + omega^2 x = gain F``."""
    sigma = 0.5 * omega / q
    omega_d = omega * math.sqrt(1.0 - 0.25 / (q * q))
    theta = omega_d * dt
    decay = math.exp(-sigma * dt)
    decay_m1 = math.expm1(-sigma * dt)
    cos_m1 = -2.0 * math.sin(0.5 * theta) ** 2
    sin_t = math.sin(theta)
    ratio = sigma / omega_d
    # Phi11 - 1 = e^{-s T}(cos + r sin) - 1 = (e^{-s T} - 1) cos + (cos - 1) + e^{-s T} r sin, written to keep
    # its digits when omega T is small.
    p11m1 = decay_m1 * (1.0 + cos_m1) + cos_m1 + decay * ratio * sin_t
    p22m1 = decay_m1 * (1.0 + cos_m1) + cos_m1 - decay * ratio * sin_t
    p12 = decay * sin_t / omega_d
    p21 = -omega * omega * p12
    return p11m1, p12, -gain * p11m1 / (omega * omega), p21, p22m1, gain * p12


def desk_bank(modes: DeskModes, sample_rate: float) -> DeskBank:
    """The resonator bank of ``modes`` at ``sample_rate`` (Hz), silent; modes at or above 0.45 fs dropped.

    >>> bank = desk_bank(desk_modes(DESKS["steel"], max_hz=20000.0), 48000.0)
    >>> bank.coefficients.shape, bank.state.shape
    ((40, 6), (40, 2))
    """
    sample_rate = check_number("sample_rate", sample_rate, "Hz", minimum=0.0, minimum_exclusive=True)
    f, t60, gain = (np.asarray(v, dtype=np.float64).ravel() for v in modes)
    if not (f.size == t60.size == gain.size):
        raise ParameterError(f"parameter modes has {f.size} frequencies, {t60.size} T60s and {gain.size} gains; "
                             "allowed: the same number of each")
    if not (np.all(np.isfinite(f)) and np.all(f > 0.0)):
        raise ParameterError("parameter modes.frequency_hz holds a value that is not > 0; allowed: > 0 Hz")
    if not np.all(np.isfinite(gain)):
        raise ParameterError("parameter modes.gain holds a non-finite value; allowed: finite Pa/N")
    omega = 2.0 * math.pi * f
    q = np.divide(omega * t60, 2.0 * math.log(1000.0))
    if not (np.all(np.isfinite(q)) and np.all(q > 0.5)):
        raise ParameterError("parameter modes.t60_s holds a value of Q = omega t60 / (2 ln 1000) <= 0.5; allowed: "
                             "an underdamped mode, t60_s > ln(1000) / omega s")
    keep = f < MAX_MODE_FRACTION * sample_rate
    dt = 1.0 / sample_rate
    rows = [_zoh_step(float(w), float(qq), float(g), dt) for w, qq, g in zip(omega[keep], q[keep], gain[keep])]
    coefficients = np.array(rows, dtype=np.float64).reshape(len(rows), 6)
    return DeskBank(coefficients, np.zeros((len(rows), 2)), sample_rate)


@njit(cache=True, nogil=True)
def process_desk(force_n, out, bank):  # pragma: no cover - compiled
    """``out[i]`` = the desk's pressure (Pa at 1 m) for ``force_n[i]`` (N, pressing down), i < len(out).

    The bank's state carries over, so any split into blocks gives the same samples. Allocates
    nothing. ``force_n`` and ``out`` are float64 arrays of one length.
    """
    if force_n.size != out.size:
        raise ValueError("process_desk: force_n and out must have the same length")
    c = bank.coefficients
    s = bank.state
    fs = bank.sample_rate
    for i in range(out.size):
        out[i] = 0.0
    for k in range(c.shape[0]):
        p11m1, p12, g1, p21, p22m1, g2 = c[k, 0], c[k, 1], c[k, 2], c[k, 3], c[k, 4], c[k, 5]
        x, v = s[k, 0], s[k, 1]
        for i in range(out.size):
            force = force_n[i]
            dx = p11m1 * x + p12 * v + g1 * force
            dv = p21 * x + p22m1 * v + g2 * force
            x += dx
            v += dv
            out[i] += dv * fs
        s[k, 0], s[k, 1] = x, v


def reset_desk(bank: DeskBank) -> None:
    """Silence the bank (zero every mode's state)."""
    bank.state[:] = 0.0
