"""barsynth studio: every model in the browser (``barsynth studio``; see ``docs/studio.md``).

- :mod:`barsynth.studio.server`: the FastAPI app (the page, the HTTP API) and ``serve``;
- :mod:`barsynth.studio.live`: one page's WebSocket stream (its reader, commands and blocks);
- :mod:`barsynth.studio.stream`: a live stream without the network: pacing, gain, limiter, stop, sleep;
- :mod:`barsynth.studio.work`: renders, pictures and mode tables in worker processes, bounded;
- :mod:`barsynth.studio.pictures`: waveform, spectrogram and modes as numbers the page paints;
- :mod:`barsynth.studio.presets_file`: settings as a preset file;
- ``web/``: the page (HTML, CSS, the page's script, the stream worker and the AudioWorklet).
"""
