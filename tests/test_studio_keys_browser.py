"""Notes in the studio's page: the computer keyboard and Web MIDI, in Debian's Chromium under
Playwright against `barsynth studio` running as a real process (the fixtures of
test_studio_browser.py). What the page plays is heard through its tap (an AnalyserNode between
the worklet and the volume: ``studio.liveSamples()``): two held keys give both notes' pitches; a
MIDI note on from a (fake, injected) MIDI input gives its pitch."""

from __future__ import annotations

import numpy as np
from test_studio_browser import NEW_BLOCKS_S, PICTURE_S, RATE, browser, studio, until, watch  # noqa: F401

RATIOS = "?model=banded&tuning=ratios&frequency_hz=440"
FAKE_MIDI = """
(() => {
  const input = { id: "fake-1", name: "Fake keys", type: "input", state: "connected", onmidimessage: null };
  const access = { inputs: new Map([["fake-1", input]]), outputs: new Map(), onstatechange: null, sysexEnabled: false };
  window.__midiAsked = 0;
  navigator.requestMIDIAccess = () => { window.__midiAsked += 1; return Promise.resolve(access); };
  window.__midi = (bytes) => input.onmidimessage && input.onmidimessage({ data: new Uint8Array(bytes) });
})();
"""
REFUSED_MIDI = "navigator.requestMIDIAccess = () => Promise.reject(new DOMException('denied', 'SecurityError'));"
NO_MIDI = "delete Navigator.prototype.requestMIDIAccess; delete navigator.requestMIDIAccess;"


def open_page(browser, url: str, errors: list[str], script: str | None = None):  # noqa: F811
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    if script:
        context.add_init_script(script)
    page = context.new_page()
    watch(page, errors)
    page.goto(url)
    until(page, "() => window.studio && studio.ready && studio.lastPicture !== null", PICTURE_S, "the page")
    return context, page


def heard(page) -> np.ndarray:
    """The newest 32768 samples the page played (0.68 s at 48 kHz)."""
    return np.asarray(page.evaluate("() => studio.liveSamples()"), float)


def level_at(x: np.ndarray, hz: float) -> float:
    """The spectrum's peak within 2 % of ``hz``, in dB below its strongest peak."""
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size))) + 1e-30
    f = np.fft.rfftfreq(x.size, 1 / RATE)
    return float(20 * np.log10(np.max(spectrum[np.abs(f / hz - 1) < 0.02]) / np.max(spectrum)))


def note_hz(pitch: int) -> float:
    return 440.0 * 2 ** ((pitch - 69) / 12)


def sounding(page, pitches: list[int], absent: list[int] = (), what: str = "") -> dict[int, float]:
    """Wait (a loaded machine may be slow to play) until every pitch in ``pitches`` is within 12 dB
    of the strongest peak of what the page plays, the newest 0.68 s from 0.75 s on (after the
    notes' onsets, whose clicks are broadband); returns the levels of ``pitches`` and ``absent``
    (dB re the strongest peak)."""
    deadline_blocks = page.evaluate("() => studio.blocksReceived")
    until(page, f"() => studio.blocksReceived >= {deadline_blocks + 140}", NEW_BLOCKS_S, f"audio for {what}")
    levels: dict[int, float] = {}
    for _ in range(40):
        x = heard(page)
        levels = {p: level_at(x, note_hz(p)) for p in [*pitches, *absent]}
        if x.size and all(levels[p] > -12 for p in pitches):
            break
        page.wait_for_timeout(100)
    assert all(levels[p] > -12 for p in pitches), (what, levels)
    return levels


def test_keys_play_notes_two_held_keys_sound_both_pitches(browser, studio):  # noqa: F811
    errors: list[str] = []
    context, page = open_page(browser, studio.url + RATIOS, errors)
    assert page.evaluate("() => studio.keys.enabled") is False
    page.locator("body").click(position={"x": 5, "y": 880})
    page.keyboard.press("z")  # keys off: z is no note (the page's own shortcuts keep their letters)
    assert page.evaluate("() => studio.keys.notesSent") == 0 and page.evaluate("() => studio.state") == "idle"
    page.keyboard.press("k")
    assert page.evaluate("() => studio.keys.enabled") is True
    page.keyboard.down("z")  # C4: opens the stream with the note
    page.keyboard.down("z")  # auto-repeat: no second note
    page.keyboard.down("c")  # E4, held with it
    until(page, "() => studio.state === 'playing' && studio.keys.held.join() === '60,64'", NEW_BLOCKS_S, "two held keys")
    levels = sounding(page, [60, 64], [57, 70], "C4 and E4")
    assert levels[57] < min(levels[60], levels[64]) - 40 and levels[70] < min(levels[60], levels[64]) - 40
    print("two held keys, dB re the strongest peak:", {k: round(v, 1) for k, v in levels.items()})
    assert page.evaluate("() => studio.keys.notesSent") == 2
    shown = page.evaluate("() => [...document.querySelectorAll('#keyboard .key.down')].map(k => k.dataset.step)")
    assert shown == ["0", "4"]  # the on-screen keyboard shows them
    page.keyboard.up("z")
    page.keyboard.up("c")
    until(page, "() => studio.keys.held.length === 0", 5, "the keys let go")
    page.keyboard.press("]")  # both rows an octave up
    page.keyboard.down("q")  # the upper row's C (C5), an octave up: C6 (84)
    until(page, "() => studio.keys.held.join() === '84'", 5, "C6")
    sounding(page, [84], [], "C6")
    page.keyboard.up("q")
    page.keyboard.press("[")
    # In a text box the keys type: no note.
    sent = page.evaluate("() => studio.keys.notesSent")
    page.locator("#description").click()
    page.keyboard.type("zq")
    assert page.evaluate("() => studio.keys.notesSent") == sent
    assert page.locator("#description").input_value().endswith("zq")
    # The mouse on the on-screen keyboard plays too.
    key = page.locator("#keyboard .key[data-step='7']")  # G4
    key.dispatch_event("pointerdown", {"pointerId": 1, "bubbles": True})
    until(page, "() => studio.keys.held.join() === '67'", 5, "G4 by mouse")
    sounding(page, [67], [], "G4 by mouse")
    key.dispatch_event("pointerup", {"pointerId": 1, "bubbles": True})
    until(page, "() => studio.keys.held.length === 0", 5, "the mouse let go")
    page.keyboard.press("Escape")
    assert page.evaluate("() => studio.errors") == [] and errors == []
    context.close()


def test_a_midi_note_on_plays_its_note_and_velocity_zero_lets_go(browser, studio):  # noqa: F811
    errors: list[str] = []
    context, page = open_page(browser, studio.url + RATIOS, errors, FAKE_MIDI)
    page.click("#midi-connect")
    until(page, "() => studio.keys.midi.state === 'ready'", 5, "the fake MIDI input")
    assert page.evaluate("() => studio.keys.midi.inputs") == ["Fake keys"]
    page.click("#play")  # the live sound (a strike at 440 Hz) ...
    until(page, "() => studio.state === 'playing' && studio.blocksReceived > 20", NEW_BLOCKS_S, "the stream")
    page.evaluate("() => window.__midi([0x90, 76, 110])")  # ... and E5 from the MIDI device
    until(page, "() => studio.keys.held.join() === '76'", 5, "the MIDI note held")
    levels = sounding(page, [76], [74, 78], "E5 from MIDI")
    assert levels[74] < levels[76] - 40 and levels[78] < levels[76] - 40
    print("a MIDI note, dB re the strongest peak:", {k: round(v, 1) for k, v in levels.items()})
    page.evaluate("() => window.__midi([0xB0, 64, 127])")  # the sustain pedal goes to the stream
    page.evaluate("() => window.__midi([0x90, 76, 0])")  # a note on of velocity 0 is a note off
    until(page, "() => studio.keys.held.length === 0", 5, "the MIDI note let go")
    assert page.evaluate("() => studio.keys.midi.messages") == 3
    page.keyboard.press("Escape")
    assert page.evaluate("() => studio.errors") == [] and errors == []
    context.close()


def test_without_web_midi_or_when_it_is_refused_the_page_says_so_quietly(browser, studio):  # noqa: F811
    for script, state, words in ((NO_MIDI, "absent", "no Web MIDI"), (REFUSED_MIDI, "refused", "not allowed")):
        errors: list[str] = []
        context, page = open_page(browser, studio.url, errors, script)
        if state == "refused":
            page.click("#midi-connect")
        else:
            assert page.locator("#midi-connect").is_disabled()
        until(page, f"() => studio.keys.midi.state === '{state}'", 5, state)
        assert words in page.locator("#midi-status").text_content()
        assert page.evaluate("() => studio.errors") == [] and errors == []
        assert page.locator("#message").is_hidden()
        context.close()
