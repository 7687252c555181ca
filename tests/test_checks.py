"""The shared argument checks of barsynth.checks and their one-line messages."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import barsynth.checks
from barsynth.checks import check_array, check_choice, check_number, check_whole
from barsynth.errors import ParameterError


def message(call) -> str:
    with pytest.raises(ParameterError) as info:
        call()
    text = str(info.value)
    assert isinstance(info.value, ValueError)
    assert "\n" not in text
    return text


# -- check_number -----------------------------------------------------------------------
def test_number_accepts_reals_and_returns_float():
    for value in (3, 3.0, np.int32(3), np.float32(3.0), np.float64(3.0)):
        out = check_number("q", value, "", minimum=1.0, maximum=5.0)
        assert out == 3.0 and type(out) is float


def test_number_message_names_parameter_value_range_and_unit():
    text = message(lambda: check_number("length_m", 2.5, "m", minimum=0.05, maximum=1.0))
    assert text == "parameter length_m = 2.5 is out of range; allowed: 0.05 to 1 m"


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_number_rejects_non_finite_even_without_bounds(bad):
    text = message(lambda: check_number("gain_db", bad, "dB"))
    assert text.startswith(f"parameter gain_db = {bad!r} is not a finite number; allowed:")
    assert text.endswith("dB values")


@pytest.mark.parametrize("bad", [True, False, np.bool_(True), "3", None, [1.0], 1 + 0j])
def test_number_rejects_bool_text_and_non_numbers(bad):
    text = message(lambda: check_number("q", bad, "", minimum=0.0))
    assert text == f"parameter q = {bad!r} is not a number; allowed: >= 0 dimensionless"


def test_number_parses_text_only_when_asked():
    assert check_number("sample_rate", " 44100 ", "Hz", parse_text=True) == 44100.0
    text = message(lambda: check_number("sample_rate", "fast", "Hz", minimum=1.0, parse_text=True))
    assert text == "parameter sample_rate = 'fast' is not a number; allowed: >= 1 Hz"
    text = message(lambda: check_number("sample_rate", "nan", "Hz", parse_text=True))
    assert text == "parameter sample_rate = 'nan' is not a finite number; allowed: finite Hz values"
    message(lambda: check_number("sample_rate", True, "Hz", parse_text=True))


@pytest.mark.parametrize("path,needle", [
    ("x.mp3", "parameter output = x.mp3 has an unsupported extension; allowed: a name ending in .wav or .flac"),
    (".wav", "parameter output = .wav has no extension (.wav alone is a hidden file's name); allowed:"),
    ("dir/.flac", "parameter output = dir/.flac has no extension (.flac alone is a hidden"),
    ("noext", "parameter output = noext has no extension; allowed: a name ending in .wav or .flac"),
])
def test_extension_refusals_say_what_the_name_lacks(path, needle):
    from barsynth.checks import check_extension

    assert check_extension("a/Take 1.FLAC", "parameter output =", (".wav", ".flac")) == ".flac"
    assert check_extension(".hidden.wav", "parameter output =", (".wav", ".flac")) == ".wav"
    assert message(lambda: check_extension(path, "parameter output =", (".wav", ".flac"))).startswith(needle)


def test_number_bounds_inclusive_by_default():
    assert check_number("x", 0.0, "m", minimum=0.0, maximum=1.0) == 0.0
    assert check_number("x", 1.0, "m", minimum=0.0, maximum=1.0) == 1.0
    unit_interval = {"minimum": 0.0, "maximum": 1.0}
    for bad in (-1e-9, 1.0 + 1e-9):
        assert "allowed: 0 to 1 m" in message(lambda: check_number("x", bad, "m", **unit_interval))


def test_number_exclusive_bounds():
    above = {"minimum": 0.0, "minimum_exclusive": True}
    assert check_number("t", 1e-300, "s", **above) == 1e-300
    assert message(lambda: check_number("t", 0, "s", **above)) == (
        "parameter t = 0 is out of range; allowed: > 0 s"
    )
    below = {"maximum": 24000.0, "maximum_exclusive": True}
    assert check_number("f", 23999.9, "Hz", **below) == 23999.9
    assert "allowed: < 24000 Hz" in message(lambda: check_number("f", 24000.0, "Hz", **below))
    both = {**above, **below}
    assert "allowed: > 0 and < 24000 Hz" in message(lambda: check_number("f", 0.0, "Hz", **both))
    assert "allowed: > 0 and <= 600 s" in message(
        lambda: check_number("d", 601, "s", minimum=0.0, maximum=600.0, minimum_exclusive=True)
    )
    assert "allowed: <= 0 dB" in message(lambda: check_number("g", 1, "dB", maximum=0.0))


# -- check_whole ------------------------------------------------------------------------
def test_whole_accepts_ints_and_returns_int():
    for value in (1, np.int64(1), np.uint8(1)):
        out = check_whole("count", value, "", 1, 10)
        assert out == 1 and type(out) is int
    assert check_whole("count", 10, "", 1, 10) == 10  # both bounds inclusive
    assert check_whole("num_samples", 10**12, "samples", 0) == 10**12  # no upper bound


def test_whole_message_names_parameter_value_range_and_unit():
    text = message(lambda: check_whole("count", 11, "", 1, 10))
    assert text == (
        "parameter count = 11 is out of range; allowed: 1 to 10 dimensionless (a whole number)"
    )
    text = message(lambda: check_whole("num_samples", -1, "samples", 0))
    assert text == (
        "parameter num_samples = -1 is out of range; allowed: >= 0 samples (a whole number)"
    )


@pytest.mark.parametrize("bad", [True, False, 2.5, 2.0, float("nan"), float("inf"), "2", None])
def test_whole_rejects_bool_floats_and_text(bad):
    text = message(lambda: check_whole("count", bad, "", 1, 10))
    assert text.startswith(f"parameter count = {bad!r} is not a whole number; allowed: 1 to 10")


def test_whole_takes_integral_floats_only_when_asked():
    assert check_whole("n", 3.0, "", 1, 10, integral_floats=True) == 3
    assert type(check_whole("n", np.float64(3.0), "", 1, 10, integral_floats=True)) is int
    for bad in (2.5, float("nan"), float("inf"), True):
        assert "is not a whole number" in message(
            lambda: check_whole("n", bad, "", 1, 10, integral_floats=True)
        )
    too_big = message(lambda: check_whole("n", 11.0, "", 1, 10, integral_floats=True))
    assert "is out of range" in too_big


# -- check_array ------------------------------------------------------------------------
def test_array_returns_float64_and_keeps_shape():
    out = check_array("x", [[0, 1], [2, 3]], "m")
    assert out.dtype == np.float64 and out.shape == (2, 2)
    scalar = check_array("x", 0.5, "m", minimum=0.0, maximum=1.0)
    assert scalar.ndim == 0 and float(scalar) == 0.5
    already = np.linspace(0.0, 1.0, 5)
    assert check_array("x", already, "m") is already  # not copied


def test_array_reports_the_first_bad_element_with_range_and_unit():
    above = {"minimum": 0.0, "minimum_exclusive": True}
    text = message(lambda: check_array("q", [1.0, 0.0, -2.0], "", **above))
    assert text == (
        "parameter q = 0.0 is out of range; allowed: > 0 dimensionless; "
        "the first bad element is at index 1"
    )
    grid = [[0.5, 0.2], [np.inf, 2.0]]
    text = message(lambda: check_array("x", grid, "m", minimum=0.0, maximum=1.0))
    assert text.startswith("parameter x = inf is not a finite number; allowed: 0 to 1 m;")
    assert text.endswith("index (1, 0)")
    text = message(lambda: check_array("t60_s", -3.0, "s", **above))
    assert text == "parameter t60_s = -3.0 is out of range; allowed: > 0 s"


def test_array_bounds_inclusive_and_exclusive():
    assert check_array("x", [0.0, 1.0], "", minimum=0.0, maximum=1.0).tolist() == [0.0, 1.0]
    below_one = {"maximum": 1.0, "maximum_exclusive": True}
    message(lambda: check_array("x", [0.0, 1.0], "", minimum=0.0, **below_one))
    message(lambda: check_array("x", [0.0, 0.5], "", minimum=0.0, minimum_exclusive=True))


@pytest.mark.parametrize("bad", [[1.0, np.nan], [np.inf], np.array([0.0, -np.inf])])
def test_array_rejects_non_finite_without_bounds(bad):
    text = message(lambda: check_array("samples", bad, ""))
    assert text.startswith("parameter samples = ")
    assert "is not a finite number; allowed: finite dimensionless values" in text


@pytest.mark.parametrize(
    "bad",
    [
        True, [True, False], "0.5", ["0.5"], [1.0, None],
        np.zeros(3, dtype=complex), [[1.0], [1.0, 2.0]],
    ],
)
def test_array_rejects_bool_text_complex_and_ragged(bad):
    text = message(lambda: check_array("x", bad, "m", minimum=0.0))
    assert text.startswith("parameter x = ")
    assert text.endswith("is not a number; allowed: >= 0 m")


def test_array_message_stays_short_for_big_arrays():
    text = message(lambda: check_array("samples", np.zeros(100_000, dtype=complex), ""))
    assert text == (
        "parameter samples = <ndarray of complex128> is not a number; "
        "allowed: finite dimensionless values"
    )


# -- check_choice -----------------------------------------------------------------------
def test_choice():
    choices = ("free-free", "clamped-free")
    assert check_choice("bc", " Free-Free ", choices) == "free-free"
    dashes = lambda s: s.replace("_", "-")  # noqa: E731
    assert check_choice("bc", "clamped_free", choices, normalize=dashes) == "clamped-free"
    for bad in ("glued", "clamped_free", 1, None):
        text = message(lambda: check_choice("bc", bad, choices))
        assert text == (
            f"parameter bc = {bad!r} is not a known choice; "
            "allowed: one of free-free, clamped-free"
        )


# -- the module stays light -------------------------------------------------------------
def test_checks_imports_only_the_standard_library_numpy_and_errors():
    tree = ast.parse(Path(barsynth.checks.__file__).read_text(encoding="utf-8"))
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            imported.add("." * node.level + (node.module or ""))
    assert imported <= {"__future__", "math", "os", "stat", "sys", "typing", "collections.abc", "numpy", ".errors"}


def test_importing_checks_does_not_load_numpy():
    """NumPy loads in check_array only (a NumPy scalar cannot exist before NumPy is loaded)."""
    import subprocess
    import sys

    code = "import sys, barsynth.checks as c; c.check_number('q', 2, ''); print('numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False"]


def test_a_float_beyond_2_to_53_is_not_taken_for_the_whole_number_typed():
    """1e30 as a float is 1000000000000000019884624838656, not 10**30: refused, not misread."""
    from barsynth.checks import check_whole

    assert check_whole("seed", 2.0 ** 53, "", 0, None, integral_floats=True) == 2 ** 53
    with pytest.raises(ParameterError, match="not a whole number"):
        check_whole("seed", 1e30, "", 0, None, integral_floats=True)
