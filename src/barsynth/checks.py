"""Validation of arguments, with barsynth's one-line error messages.

Every check returns the value in a normal form or raises
:class:`~barsynth.errors.ParameterError` with a message such as

    parameter length_m = -1 is out of range; allowed: > 0 m
    parameter q = 'high' is not a number; allowed: > 0 dimensionless
    parameter count = 2.5 is not a whole number; allowed: 1 to 100000 dimensionless (a whole number)

naming the parameter, the value given, the allowed range and the unit (an empty
unit reads "dimensionless").

Ranges: ``minimum`` and ``maximum`` are inclusive unless ``minimum_exclusive`` or
``maximum_exclusive`` is set; ``None`` means no bound. NaN and ±inf are always refused
("is not a finite number"). ``bool`` is never accepted as a number.

Files: :func:`check_input_file` and :func:`check_output_file` refuse a FIFO, a
device or a socket at once (reading one would hang or never end; writing one would
replace it), :func:`check_extension` an output name without the extension its format needs,
and :func:`show_text` shortens what a message quotes of a user's text (a name, a path) to at
most 80 characters.

This module imports only :mod:`barsynth.errors`, :mod:`math`, :mod:`os`, :mod:`stat`,
:mod:`sys` and (for type hints) :mod:`collections.abc`, so any part of barsynth may use it
without slowing its import. NumPy loads only in :func:`check_array`; a NumPy scalar is
recognised without importing NumPy (none can exist before NumPy is loaded).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import math
import os
import stat
import sys
from typing import TYPE_CHECKING

from .errors import ParameterError

if TYPE_CHECKING:
    import numpy as np

__all__ = ["check_array", "check_choice", "check_extension", "check_input_file", "check_number",
           "check_output_file", "check_whole", "file_kind", "number_within", "show_text", "show_value"]

_MAX_SHOWN = 80  # longest repr of a value quoted in a message


def _numpy_types(*names: str) -> tuple[type, ...]:
    """NumPy's scalar types ``names`` (e.g. "integer") if NumPy is loaded, else none."""
    np = sys.modules.get("numpy")
    return tuple(getattr(np, name) for name in names) if np is not None else ()


def _is_bool(value: object) -> bool:
    return isinstance(value, (bool, *_numpy_types("bool_")))


def _is_int(value: object) -> bool:
    """An int or NumPy integer (and a bool, which is an int: exclude it separately)."""
    return isinstance(value, (int, *_numpy_types("integer")))


def _is_real(value: object) -> bool:
    """An int, float, NumPy integer or NumPy floating (and a bool: exclude it separately)."""
    return isinstance(value, (int, float, *_numpy_types("integer", "floating")))


def _show(value: object) -> str:
    """``repr(value)`` if it is short and on one line, else a short description."""
    text = repr(value)
    if len(text) <= _MAX_SHOWN and "\n" not in text:
        return text
    dtype = getattr(value, "dtype", None)
    return f"<{type(value).__name__}{'' if dtype is None else f' of {dtype}'}>"


def show_value(value: object) -> str:
    """``repr(value)`` if it is short and on one line; a longer string as the start and end of its
    repr around "..." (at most 80 characters); anything else long as a short description."""
    if isinstance(value, str):
        return show_text(repr(value))
    return _show(value)


def show_text(text: object) -> str:
    """``text`` (a name, a path) on one line and at most ``_MAX_SHOWN`` characters: a longer one
    keeps its start and end (a path's file name) around "..."."""
    flat = " ".join(str(text).split()) if "\n" in str(text) or "\r" in str(text) else str(text)
    if len(flat) <= _MAX_SHOWN:
        return flat
    half = (_MAX_SHOWN - 3) // 2
    return f"{flat[:half]}...{flat[-half:]}"


def file_kind(mode: int) -> str:
    """What a file of ``os.stat`` mode ``mode`` is, for a message: 'a FIFO (named pipe)', 'a device', ..."""
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISDIR(mode):
        return "a folder"
    return "not a regular file"


def check_input_file(path: object, what: str) -> None:
    """Refuse, at once, a ``path`` to read that is missing or not a regular file (a FIFO would
    hang the reader, a device never end). ``what`` names it: ``"preset file"``, ``"config"``."""
    name = os.fspath(path)  # type: ignore[arg-type]
    try:
        mode = os.stat(name).st_mode
    except FileNotFoundError:
        raise ParameterError(f"{what} {show_text(name)}: no such file") from None
    except OSError as exc:
        raise ParameterError(f"{what} {show_text(name)}: {exc.strerror or 'cannot be read'}") from None
    if not stat.S_ISREG(mode):
        raise ParameterError(f"{what} {show_text(name)} is {file_kind(mode)}; allowed: a regular file")


def check_output_file(path: object, what: str) -> None:
    """Refuse, at once, a ``path`` to write that exists and is not a regular file (a FIFO or a
    device would be replaced by a file, or block). A new name, or a link to a file, is fine."""
    name = os.fspath(path)  # type: ignore[arg-type]
    try:
        mode = os.stat(name).st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        raise ParameterError(f"{what} {show_text(name)}: {exc.strerror or 'cannot be checked'}") from None
    if not stat.S_ISREG(mode):
        raise ParameterError(f"{what} {show_text(name)} is {file_kind(mode)}; allowed: a regular file or a new name")


def check_extension(path: object, what: str, extensions: Sequence[str]) -> str:
    """The extension of ``path``, lower-cased, if it is one of ``extensions`` (``(".wav", ".flac")``),
    else ParameterError (``what`` names it: ``"parameter output ="``). A name whose only dot starts it
    (``.wav``) has no extension: it is a hidden file's whole name.

    >>> check_extension("Take 1.WAV", "parameter output =", (".wav",))
    '.wav'
    """
    name = os.path.basename(os.fspath(path))  # type: ignore[arg-type]
    extension = os.path.splitext(name)[1].lower()
    if extension in extensions:
        return extension
    allowed = f"allowed: a name ending in {', '.join(extensions[:-1])}{' or ' if len(extensions) > 1 else ''}" \
              f"{extensions[-1]}"
    if extension:
        raise ParameterError(f"{what} {show_text(path)} has an unsupported extension; {allowed}")
    hidden = f" ({show_text(name)} alone is a hidden file's name)" if name.startswith(".") else ""
    raise ParameterError(f"{what} {show_text(path)} has no extension{hidden}; {allowed}")


def _bound(value: float) -> str:
    return str(value) if _is_int(value) else f"{value:g}"


def _allowed(
    unit: str,
    minimum: float | None,
    maximum: float | None,
    minimum_exclusive: bool,
    maximum_exclusive: bool,
    whole: bool = False,
) -> str:
    unit = unit or "dimensionless"
    low = None if minimum is None else f"{'>' if minimum_exclusive else '>='} {_bound(minimum)}"
    high = None if maximum is None else f"{'<' if maximum_exclusive else '<='} {_bound(maximum)}"
    if low is None and high is None:
        text = f"finite {unit} values"
    elif low is None or high is None:
        text = f"{low or high} {unit}"
    elif minimum_exclusive or maximum_exclusive:
        text = f"{low} and {high} {unit}"
    else:
        text = f"{_bound(minimum)} to {_bound(maximum)} {unit}"
    return f"allowed: {text}" + (" (a whole number)" if whole else "")


def _within(
    values,
    minimum: float | None,
    maximum: float | None,
    minimum_exclusive: bool,
    maximum_exclusive: bool,
):
    """Elementwise: finite and inside the range (a bool for a float, else a NumPy bool or bool array)."""
    if isinstance(values, float):
        ok = math.isfinite(values)
    else:
        import numpy as np

        ok = np.isfinite(values)
    if minimum is not None:
        ok = ok & (values > minimum if minimum_exclusive else values >= minimum)
    if maximum is not None:
        ok = ok & (values < maximum if maximum_exclusive else values <= maximum)
    return ok


def check_number(
    name: str,
    value: object,
    unit: str,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    minimum_exclusive: bool = False,
    maximum_exclusive: bool = False,
    parse_text: bool = False,
) -> float:
    """``value`` as a finite float inside the range, or ParameterError.

    Accepts ``int``, ``float`` and NumPy integer and floating scalars (not
    ``bool``); with ``parse_text`` also a ``str`` holding a number (as typed on a
    command line).

    >>> check_number("length_m", 0.3, "m", minimum=0.0, minimum_exclusive=True)
    0.3
    """
    allowed = _allowed(unit, minimum, maximum, minimum_exclusive, maximum_exclusive)
    number: float | None = None
    if _is_real(value) and not _is_bool(value):
        try:
            number = float(value)
        except OverflowError:  # an int beyond float range: out of any range
            number = math.inf
    elif parse_text and isinstance(value, str):
        try:
            number = float(value)
        except ValueError:
            pass
    if number is None:
        raise ParameterError(f"parameter {name} = {_show(value)} is not a number; {allowed}")
    if not math.isfinite(number):
        raise ParameterError(f"parameter {name} = {_show(value)} is not a finite number; {allowed}")
    if not _within(number, minimum, maximum, minimum_exclusive, maximum_exclusive):
        raise ParameterError(f"parameter {name} = {_show(value)} is out of range; {allowed}")
    return number


def check_whole(
    name: str,
    value: object,
    unit: str,
    minimum: int,
    maximum: int | None = None,
    *,
    integral_floats: bool = False,
) -> int:
    """``value`` as an ``int`` in ``[minimum, maximum]`` (no upper bound if None).

    Accepts ``int`` and NumPy integers (not ``bool``); with ``integral_floats`` also
    floats with a whole value such as ``3.0``.

    >>> check_whole("count", 3.0, "", 1, 10, integral_floats=True)
    3
    """
    if type(value) is int and value >= minimum and (maximum is None or value <= maximum):
        return value  # the common case, before any message is built (a block size: every process call)
    allowed = _allowed(unit, minimum, maximum, False, False, whole=True)
    number: int | None = None
    if _is_int(value) and not isinstance(value, bool):
        number = int(value)
    elif (integral_floats and isinstance(value, (float, *_numpy_types("floating"))) and float(value).is_integer()
          and abs(float(value)) <= 2.0 ** 53):  # beyond, a float is not the whole number that was typed
        number = int(value)
    if number is None:
        raise ParameterError(f"parameter {name} = {_show(value)} is not a whole number; {allowed}")
    if number < minimum or (maximum is not None and number > maximum):
        raise ParameterError(f"parameter {name} = {_show(value)} is out of range; {allowed}")
    return number


def check_array(
    name: str,
    value: object,
    unit: str,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    minimum_exclusive: bool = False,
    maximum_exclusive: bool = False,
) -> np.ndarray:
    """``value`` (a scalar or array_like of real numbers) as a float64 array.

    Every element must be finite and inside the range; the message quotes the
    first element that is not (in C order) and, for arrays, its index. Integer
    and floating input is accepted; bool, complex, strings and objects are not.
    A float64 ndarray is returned as it is, not copied.

    >>> check_array("x", [0.0, 0.5], "", minimum=0.0, maximum=1.0)
    array([0. , 0.5])
    """
    import numpy as np

    allowed = _allowed(unit, minimum, maximum, minimum_exclusive, maximum_exclusive)
    try:
        raw = np.asarray(value)
    except Exception:  # noqa: BLE001 - anything numpy cannot take is a bad argument
        raw = None
    if raw is None or raw.dtype.kind not in "iuf":
        raise ParameterError(f"parameter {name} = {_show(value)} is not a number; {allowed}")
    arr = raw.astype(np.float64, copy=False)
    ok = _within(arr, minimum, maximum, minimum_exclusive, maximum_exclusive)
    if not ok.all():
        first = int(np.flatnonzero(~ok)[0])
        where = ""
        if arr.ndim:
            index = tuple(int(i) for i in np.unravel_index(first, arr.shape))
            where = f"; the first bad element is at index {index[0] if arr.ndim == 1 else index}"
        bad = float(arr.flat[first])
        what = "is out of range" if math.isfinite(bad) else "is not a finite number"
        raise ParameterError(f"parameter {name} = {bad!r} {what}; {allowed}{where}")
    return arr


def check_choice(
    name: str,
    value: object,
    choices: Sequence[str],
    *,
    normalize: Callable[[str], str] | None = None,
) -> str:
    """The entry of ``choices`` that the string ``value`` names, or ParameterError.

    ``value`` is stripped and lower-cased, then passed through ``normalize`` (to
    accept other spellings) before it is looked up.

    >>> check_choice("window", " Hann ", ("hann", "boxcar"))
    'hann'
    """
    if isinstance(value, str):
        key = value.strip().lower()
        if normalize is not None:
            key = normalize(key)
        if key in choices:
            return key
    raise ParameterError(
        f"parameter {name} = {_show(value)} is not a known choice; "
        f"allowed: one of {', '.join(choices)}"
    )


def number_within(value: object, low: float, high: float, *, whole: bool = False) -> bool:
    """Whether ``value`` (as JSON decodes it) is a real number in ``[low, high]``: not a bool,
    not NaN or infinite, and with ``whole`` a whole number. An integer of any size is compared
    as an integer (``math.isfinite`` would overflow on one beyond float range).

    >>> number_within(10 ** 400, 16, 4096, whole=True), number_within(3.0, 1, 5, whole=True)
    (False, True)
    """
    if _is_bool(value) or not _is_real(value):
        return False
    if _is_int(value):
        return low <= value <= high
    number = float(value)
    return math.isfinite(number) and (not whole or number.is_integer()) and low <= number <= high
