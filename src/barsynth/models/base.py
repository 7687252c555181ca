"""What every synthesis model offers, and the registry that finds them by name.

A model is a :class:`Model` with a parameter table, presets, ``describe`` (the modes it
will synthesise), ``voice`` (a :class:`Voice`: prepare / reset / trigger / release /
set_parameters / process) and ``render`` (offline, the same samples as the voice). The
CLI and the web layer only ever talk to this contract. After STK's ``Instrmnt`` (one
declared contract) and JUCE's ``dsp`` life cycle (allocate in ``prepare``, write into the
caller's block in ``process``).
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from ..errors import ModelError, ParameterError
from ..checks import check_whole, show_value
from ..parameters import ParameterTable
from .rendering import MAX_BLOCK_SAMPLES, check_block_size, check_dtype, check_sample_rate, check_seed

if TYPE_CHECKING:  # (a model without exciters, the twang, does not import them)
    from ..exciters import Exciter
    from .notemap import NoteMap


@dataclass(frozen=True)
class Mode:
    """One synthesised partial: its group, frequency (Hz), relative gain and T60 (s)."""

    group: str
    frequency_hz: float
    gain: float
    t60_s: float

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


class Voice:
    """One sounding instance of a model: the contract every model's voice keeps.

    The life cycle is JUCE's: :meth:`prepare` (sample rate and largest block; allocates),
    :meth:`reset` (silence), :meth:`trigger` / :meth:`release` (excite, let go),
    :meth:`set_parameters` (a validated change while sounding) and :meth:`process` (the next
    samples, into a buffer the caller may own). Blocks of any sizes give exactly the samples
    of one long block.

    A model's voice implements only its own part:

    - ``_prepare()``: design for ``self.sample_rate`` and ``self.parameters`` and allocate
      (raise to refuse: the base then keeps the previous rate);
    - ``_reset()``: silence;
    - ``trigger()`` (and ``release()`` where ``can_release``);
    - ``_update(old)``: follow a parameter change (``self.parameters`` is already the new
      record; raise to refuse it: the base then restores ``old``);
    - ``_render(out)``: write ``out.size`` samples into the float64 array ``out``.

    What a voice can do is declared on its class, not guessed:
    """

    model: ClassVar[Model]
    """The :class:`Model` this voice belongs to (set by the model's first instance)."""
    restarts_on_trigger: ClassVar[bool] = False
    """A trigger restarts the note (phasors back to 0, filters emptied) instead of adding to
    what rings: :class:`~barsynth.models.crossfade.CrossfadingVoice` fades the old note out."""
    can_release: ClassVar[bool] = False
    """:meth:`release` does something (a bow stroke stops); otherwise it does nothing."""
    uses_seed: ClassVar[bool] = False
    """The seed drives noise in the sound; otherwise it is accepted and has no effect."""
    DEFAULT_MAX_BLOCK: ClassVar[int] = 4096

    def __init__(self, parameters: Any = None, *, sample_rate: float = 48000.0, seed: int | None = 0,
                 max_block: int | None = None):
        self._params = resolve_parameters(self.model, parameters)
        self.seed = check_seed(seed)
        self.prepare(sample_rate, max_block)

    @property
    def parameters(self) -> Any:
        """The current (target) parameters, as the model's frozen record."""
        return self._params

    def prepare(self, sample_rate: float, max_block: int | None = None) -> None:
        """Set the sample rate (Hz) and the largest block :meth:`process` will be asked for with a
        buffer of the caller's (samples; longer ones are rendered in pieces), design, allocate
        and reset. A refused rate changes nothing."""
        rate = check_sample_rate(sample_rate)
        block = self.DEFAULT_MAX_BLOCK if max_block is None else check_whole(
            "max_block", max_block, "samples", 1, MAX_BLOCK_SAMPLES)
        previous = self.__dict__.get("sample_rate"), self.__dict__.get("max_block")
        self.sample_rate, self.max_block = rate, block  # (what _prepare allocates for)
        try:
            self._prepare()
        except Exception:
            if previous[0] is not None:
                self.sample_rate, self.max_block = previous
            raise
        self._scratch = np.empty(block)
        self.reset()

    def reset(self) -> None:
        """Silence: nothing rings, nothing is pending."""
        self._reset()

    def set_parameters(self, **values: Any) -> None:
        """Change parameters (validated, on top of the current ones: see
        :meth:`~barsynth.parameters.ParameterTable.changed`). What a model can glide it glides
        without a click (every model glides its output level); a change it cannot glide (a new
        grid, new loops) is cross-faded by :class:`~barsynth.models.crossfade.CrossfadingVoice`,
        as the studio plays.
        A refused change changes nothing."""
        new = self.model.table.changed(self._params, values)
        old, self._params = self._params, new
        try:
            self._update(old)
        except Exception:
            self._params = old
            raise

    def trigger(self) -> None:
        """Excite the voice now (strike, pluck, bow stroke, twang)."""
        raise NotImplementedError

    def release(self) -> None:
        """Let go (a bow stroke slows to rest); a voice that cannot release ignores it."""

    def note_on(self, pitch: Any = None, velocity: Any = 100, *, frequency_hz: Any = None) -> None:
        """Play a note: MIDI note ``pitch`` (69 = A4 = 440 Hz; fractions allowed) or
        ``frequency_hz``, at ``velocity`` (0-127, or a fraction 0-1). The model's note map
        (:mod:`barsynth.playing.notes`) sets the parameters the pitch moves and the velocity
        drives, then the voice is triggered; a note the model cannot reach is refused in one
        line and changes nothing."""
        from ..playing.notes import note_hz, note_settings, velocity_fraction

        hz, fraction = note_hz(pitch, frequency_hz=frequency_hz), velocity_fraction(velocity)
        changes = note_settings(self.model, self._params, hz, fraction, sample_rate=self.sample_rate)
        self.set_parameters(**changes)
        self.trigger()

    def note_off(self, velocity: Any = 0) -> None:
        """Let the note go (:meth:`release`: a bow lifts; a struck or plucked voice rings on)."""
        from ..playing.notes import velocity_fraction

        velocity_fraction(velocity)
        self.release()

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) now whatever a change while sounding may need
        later, so a live player never waits for a compile mid-stream; the samples are the same
        either way. Most voices compile everything at their first block: nothing to do."""

    @property
    def driven_until(self) -> int:
        """The index of the first sample (counted from the voice's reset) from which nothing drives
        it any more: a bowed voice sustains until its bow is lifted. 0 for a voice that is only
        struck, plucked or twanged (it only rings out)."""
        return 0

    def process(self, num_samples: int, *, out: np.ndarray | None = None, dtype: Any = np.float32) -> np.ndarray:
        """The next ``num_samples`` samples (mono).

        Without ``out``: a new array, float32 unless ``dtype`` says float64. With ``out`` (a
        1-D float32 or float64 array of exactly ``num_samples``, which the caller owns): the
        samples are written there and ``out`` is returned; nothing is allocated.
        """
        kind = plain_block_dtype(out, num_samples)
        # The common call (a player's block, every few ms): a buffer plain_block_dtype has found
        # valid in full, so check_out and check_block_size would pass it: no more checks.
        if kind is FLOAT64:
            self._render(out)
            return out
        if kind is FLOAT32:
            self._render_float32(out)
            return out
        return self._process_checked(num_samples, out, dtype)

    def _process_checked(self, num_samples: Any, out: Any, dtype: Any) -> np.ndarray:
        """:meth:`process` for any other call: everything checked (a bad one refused in one line)."""
        n = check_block_size(num_samples)
        if out is None:
            kind = check_dtype(dtype)
            samples = np.empty(n)
            if n:
                self._render(samples)
            return samples.astype(kind, copy=False)
        check_out(out, n)
        if not n:
            return out
        if out.dtype == np.float64:
            self._render(out)
        else:
            self._render_float32(out)
        return out

    def _render_float32(self, out: np.ndarray) -> None:
        """Into a float32 ``out``: computed in float64 (the work space, a block at a time), then cast."""
        n = out.size
        if n <= self.max_block:  # one piece (a player's block): the loop below, without its bookkeeping
            piece = self._scratch[:n]
            self._render(piece)
            out[:] = piece
            return
        for start in range(0, n, self.max_block):
            stop = min(n, start + self.max_block)
            piece = self._scratch[:stop - start]
            self._render(piece)
            out[start:stop] = piece

    # -- what a model implements -----------------------------------------------------------------
    def _prepare(self) -> None:
        raise NotImplementedError

    def _reset(self) -> None:
        raise NotImplementedError

    def _update(self, old: Any) -> None:
        raise NotImplementedError

    def _render(self, out: np.ndarray) -> None:
        raise NotImplementedError


FLOAT64, FLOAT32 = np.dtype(np.float64), np.dtype(np.float32)


def plain_block_dtype(out: Any, num_samples: Any) -> np.dtype | None:
    """``out``'s dtype (:data:`FLOAT64` or :data:`FLOAT32`) if it is for certain a valid buffer
    of ``num_samples`` (at least 1) for :meth:`Voice.process`, else None (valid or not: the
    caller then checks it in full).

    Valid for certain: a plain ndarray of NumPy's own native float64 or float32 dtype objects
    (compared by identity), of shape ``(num_samples,)``, C-contiguous, aligned and writeable
    (``flags.carray``), and ``num_samples`` a plain int in range: all that :func:`check_out` and
    :func:`~.rendering.check_block_size` test, in about a third of their time (0.3 us against
    0.6 us here; a call's whole fixed cost is about 1 us). Nothing is remembered from an earlier
    call: a buffer made read-only or reshaped in place since is tested afresh."""
    if type(out) is not np.ndarray or type(num_samples) is not int:
        return None
    kind = out.dtype
    if ((kind is FLOAT64 or kind is FLOAT32) and out.shape == (num_samples,)
            and 0 < num_samples <= MAX_BLOCK_SAMPLES and out.flags.carray):
        return kind
    return None


def check_out(out: Any, num_samples: int) -> np.ndarray:
    """A caller's output buffer: a writeable, contiguous 1-D float32 or float64 array of
    ``num_samples``."""
    if not (isinstance(out, np.ndarray) and out.ndim == 1 and out.dtype in (np.float32, np.float64)
            and out.flags.c_contiguous and out.flags.writeable and out.size == num_samples):
        shown = (f"{out.dtype} array of shape {out.shape}" if isinstance(out, np.ndarray)
                 else type(out).__name__)
        raise ParameterError(f"parameter out = {shown} is not allowed; allowed: a writeable, contiguous 1-D "
                             f"float32 or float64 array of num_samples = {num_samples} samples")
    return out


class Model:
    """A synthesis model: its parameter table, its presets, its voices and offline renders.

    A model names itself (``name``, ``summary``), its table (``table``), its voice class
    (``voice_class``) and implements :meth:`describe`. What it offers is declared on its
    class: ``exciters`` (the exciters a trigger can use, :mod:`barsynth.exciters`, in the order
    of its ``excitation`` choices; none for a model that is its own excitation) and
    ``reports_reference_errors`` (it implements :meth:`errors_cents`: each mode's error against
    a reference solution).
    """

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    table: ClassVar[ParameterTable]
    voice_class: ClassVar[type[Voice]]
    exciters: ClassVar[tuple[type[Exciter], ...]] = ()
    """The exciters its voices take, each by its ``excitation`` name (checked against the table)."""
    reports_reference_errors: ClassVar[bool] = False
    note_maps: ClassVar[tuple[NoteMap, ...]] = ()
    """What a note's pitch moves, its velocity drives and MIDI controls move (declared next to
    the table, :mod:`barsynth.models.notemap`); the first whose ``when`` holds is used."""
    constraints: ClassVar[tuple[Any, ...]] = ()
    """Joint constraints on settings each in range (:class:`~barsynth.models.constraints.Constraint`,
    declared next to the table): cheap rules, each with its one-line refusal, that random draws
    are filtered by before a voice is designed; the model's own checks stay authoritative (where
    they check the same rule, they raise the constraint's refusal: one copy)."""

    def __init__(self) -> None:
        self._check_exciters()
        if "model" not in vars(self.voice_class):  # the first instance (the registry's MODEL) is the voices' model
            self.voice_class.model = self

    def _check_exciters(self) -> None:
        """The table's ``excitation`` choices are the names of ``exciters``, each one of barsynth's."""
        names = tuple(e.name for e in self.exciters)
        choices = self.table["excitation"].choices if "excitation" in self.table else ()
        if choices != names:
            raise TypeError(f"model {self.name}: its exciters {names} must be its table's excitation choices {choices}")
        if self.exciters:
            from ..exciters import EXCITERS

            strangers = [e.__name__ for e in self.exciters if EXCITERS.get(e.name) is not e]
            if strangers:
                raise TypeError(f"model {self.name}: exciters {strangers} are not in barsynth.exciters.EXCITERS")

    @property
    def params(self) -> ParameterTable:
        """The parameter table (name, unit, range, default, scale, doc of every control)."""
        return self.table

    @property
    def presets(self) -> tuple[str, ...]:
        """Names of the presets shipped for this model."""
        from ..presets import preset_names

        return preset_names(self.name)

    def preset(self, name: str) -> Any:
        """The parameters of the shipped preset ``name``, resolved (the model's record)."""
        from ..presets import preset_parameters

        return self.resolve(preset_parameters(self.name, name))

    def resolve(self, parameters: Any = None) -> Any:
        """``parameters`` (None, a mapping of overrides or the record) as the model's record."""
        return resolve_parameters(self, parameters)

    def voice(self, parameters: Any = None, *, sample_rate: float = 48000.0, seed: int | None = 0,
              max_block: int | None = None) -> Voice:
        """A new voice, prepared for ``sample_rate`` (Hz); see :class:`Voice`."""
        return self.voice_class(parameters, sample_rate=sample_rate, seed=seed, max_block=max_block)

    def render(self, parameters: Any = None, *, duration_s: Any = 2.0, sample_rate: float = 48000.0,
               seed: int | None = 0, normalize: bool = True, dtype: Any = np.float32) -> np.ndarray:
        """One note offline: a voice triggered once and rendered for ``duration_s`` seconds at
        ``sample_rate`` Hz, peak-normalised to -1 dBFS unless ``normalize`` is false (then
        exactly the voice's samples), float32 or float64 (``dtype``)."""
        from .rendering import render_voice

        check_dtype(dtype)
        voice = self.voice(parameters, sample_rate=sample_rate, seed=seed)
        self.check_renderable(voice)
        return render_voice(voice, duration_s, normalize=normalize, dtype=dtype)

    def check_renderable(self, voice: Voice) -> None:
        """Refuse (ParameterError) a voice whose note would be no sound at all; by default all are fine."""

    def describe(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[Mode]:
        """The modes the model will synthesise: group, frequency (Hz), gain, T60 (s)."""
        raise NotImplementedError

    def errors_cents(self, parameters: Any = None, *, sample_rate: float = 48000.0) -> list[float]:
        """Each described mode's error (cents) against a reference (where ``reports_reference_errors``)."""
        raise NotImplementedError(f"model {self.name} reports no reference errors")


# name -> "module:attribute"; imported on first use so `import barsynth` stays fast.
_MODEL_PATHS: dict[str, str] = {
    "twang": "barsynth.models.twang:MODEL",
    "farnell": "barsynth.models.farnell:MODEL",
    "banded": "barsynth.models.banded:MODEL",
    "allpass": "barsynth.models.allpass:MODEL",
    "fd": "barsynth.models.fd:MODEL",
    "ruler": "barsynth.models.ruler:MODEL",
    "kalimba": "barsynth.models.kalimba:MODEL",
}


def model_names() -> tuple[str, ...]:
    """Names of every model barsynth offers."""
    return tuple(_MODEL_PATHS)


def get_model(name: str) -> Model:
    """The model called ``name`` (raises :class:`ModelError` for an unknown name)."""
    try:
        path = _MODEL_PATHS[name]
    except KeyError:
        raise ModelError(
            f"unknown model {show_value(name)}; available: {', '.join(model_names())}"
        ) from None
    module_name, attr = path.split(":")
    return getattr(importlib.import_module(module_name), attr)


def resolve_parameters(model: Model, parameters: Any) -> Any:
    """Accept None, a mapping of overrides, or the model's own dataclass."""
    if parameters is None:
        return model.table.resolve()
    if isinstance(parameters, Mapping):
        return model.table.resolve(parameters)
    if isinstance(parameters, model.table.dataclass):
        return parameters
    raise ParameterError(
        f"parameter parameters = {show_value(parameters)} is not allowed; allowed: None, a mapping "
        f"of parameter names to values, or {model.table.dataclass.__name__}"
    )
