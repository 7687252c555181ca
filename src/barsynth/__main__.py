"""``python -m barsynth``: the command-line tool."""

from .entry import run

run()
