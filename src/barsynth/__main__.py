"""``python -m barsynth``: the command-line tool."""

from .cli import main

main()
