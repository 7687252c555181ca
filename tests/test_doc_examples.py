"""Every Examples section in the library's docstrings runs and prints what it shows."""

from __future__ import annotations

import doctest
import importlib

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
    "barsynth.physics.grid",
    "barsynth.physics.profiles",
    "barsynth.physics.undercut",
    "barsynth.dsp.bow_stroke",
    "barsynth.analysis.bowing",
    "barsynth.studio.presets_file",
    "barsynth.analysis.search",
    "barsynth.analysis.plots",
    "barsynth.parameters",
    "barsynth.extras",
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
