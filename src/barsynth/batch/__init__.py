"""Batch rendering (spec 11): a TOML spec -> a deterministic list of items -> audio files and a manifest.

:mod:`.spec` reads the spec, :mod:`.items` resolves each item's parameters and seed,
:mod:`.run` renders them (local processes) and writes the files and the manifest.
"""
