"""barsynth studio: every model in the browser (issue 6; under construction).

:mod:`barsynth.studio.server` holds the HTTP API the page is built on: the models,
their parameter tables and presets, bounded renders to WAV, mode tables, and
preset files. The page, live streaming and ``barsynth studio`` come next.
"""
