"""Batch rendering (spec 11): a TOML spec -> a deterministic list of items -> audio files and a manifest.

:mod:`.spec` reads the spec, :mod:`.sampler` draws valid random settings, :mod:`.items` resolves
each item's parameters and seed, :mod:`.run` renders them and writes the files and the manifest.
"""
