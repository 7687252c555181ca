"""Every Examples section in the library's docstrings runs and prints what it shows."""

from __future__ import annotations

import doctest
import importlib

import numpy as np
import pytest

MODULES = [
    "barsynth.physics.boundary",
    "barsynth.physics.modes",
    "barsynth.physics.damping",
    "barsynth.physics.materials",
    "barsynth.models.twang",
    "barsynth.models.twang.voice",
    "barsynth.models.farnell",
    "barsynth.models.farnell.voice",
    "barsynth.models.banded",
    "barsynth.models.banded.voice",
    "barsynth.models.banded.design",
    "barsynth.models.allpass",
    "barsynth.models.allpass.design",
    "barsynth.models.allpass.voice",
    "barsynth.numerics",
    "barsynth.models.fd",
    "barsynth.models.fd.voice",
    "barsynth.models.crossfade",
    "barsynth.exciters.base",
    "barsynth.exciters.sample",
    "barsynth.dsp.resample",
    "barsynth.physics.tuned_bar",
    "barsynth.physics.grid",
    "barsynth.physics.profiles",
    "barsynth.physics.undercut",
    "barsynth.physics.theory",
    "barsynth.physics.timoshenko",
    "barsynth.physics.timoshenko_grid",
    "barsynth.dsp.bow_stroke",
    "barsynth.analysis.bowing",
    "barsynth.studio.presets_file",
    "barsynth.analysis.search",
    "barsynth.analysis.note",
    "barsynth.analysis.plots",
    "barsynth.parameters",
    "barsynth.extras",
    "barsynth.models.kalimba.model",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0


def test_the_examples_are_really_there():
    finder = doctest.DocTestFinder()
    found = sum(len(t.examples) for name in ("barsynth.models.twang", "barsynth.models.twang.voice")
                for t in finder.find(importlib.import_module(name)))
    assert found >= 5


def test_the_readmes_library_example_runs(capsys):
    """The README's Python block, as a user would paste it."""
    import re
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", readme, flags=re.S)
    assert blocks
    for block in blocks:
        exec(compile(block, "README.md", "exec"), {})
    assert len(capsys.readouterr().out.splitlines()) >= 3  # it prints the partials it found


def test_the_contracts_example_model_keeps_the_contract(capsys):
    """docs/contract.md's whole model in a page runs, and its voice keeps the contract."""
    import re
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[1] / "docs" / "contract.md").read_text(encoding="utf-8")
    block, _exciter = re.findall(r"```python\n(.*?)```", doc, flags=re.S)
    space: dict = {}
    exec(compile(block, "docs/contract.md", "exec"), space)
    assert capsys.readouterr().out == "440.0 24000\n"
    model = space["MODEL"]
    assert model.voice_class.model is model and model.params is model.table
    x = model.render({"t60_s": 0.2}, duration_s=0.4, normalize=False, dtype="float64")
    peak_at = lambda part: float(np.max(np.abs(part)))  # noqa: E731
    assert peak_at(x[int(0.2 * 48000):int(0.21 * 48000)]) == pytest.approx(1e-3, rel=0.03)  # T60


def test_the_contracts_example_exciter_is_one_class_that_keeps_the_interface(capsys):
    """docs/contract.md's new exciter runs: its in-advance force, its declared forms, its rows."""
    import re
    from pathlib import Path

    from barsynth.exciters import Exciter

    doc = (Path(__file__).resolve().parents[1] / "docs" / "contract.md").read_text(encoding="utf-8")
    _model, block = re.findall(r"```python\n(.*?)```", doc, flags=re.S)
    space: dict = {}
    exec(compile(block, "docs/contract.md", "exec"), space)
    assert capsys.readouterr().out == "49 4.0\n"
    flick = space["Flick"]
    assert issubclass(flick, Exciter) and flick.in_advance and not flick.coupled and not flick.direct
    assert [row.name for row in flick.parameters()] == ["flick_force_n"]
    assert flick.parameters()[0].when == ((("excitation", ("flick",)),),)
