"""barsynth studio as someone uses it: Debian's Chromium, driven by Playwright, against
`barsynth studio` running as a real process.

The page really plays: an AudioContext at 48 kHz (Chromium's fake output when the machine
has no sound card), the AudioWorklet fed by the WebSocket stream from the page's worker, and
the page's own figures (window.studio) to check that samples arrive and are played, that every
slider change reaches the output, that the buffer stays within the server's lead, that quick
Stops and Plays end with the sound streaming, and that a slider dragged over a model whose
changes are slow to design keeps its stream. How fast a change is heard and how often the
buffer runs dry depend on how busy the machine is: the tests print those figures but assert
nothing a loaded machine cannot keep; ``benchmarks/studio_browser.py`` measures them. Chromium comes from
Debian; Playwright never downloads a browser (see tests/browser.py). Screenshots of each stage
are kept in test-artifacts/screenshots/ (or $BARSYNTH_SCREENSHOTS).
"""

from __future__ import annotations

import io
import json
import math
import statistics
import sys
import time
import tomllib
import urllib.request
from pathlib import Path

import numpy as np
import pytest
import soundfile
from browser import ServerProcess, chromium, screenshot_folder
from playwright.sync_api import Page, expect

from barsynth.models import model_names

STUDIO_COMMAND = [sys.executable, "-m", "barsynth", "studio", "--port", "0"]
RATE = 48000
VIEWPORT = {"width": 1400, "height": 900}
NEW_BLOCKS_S = 15.0  # how long the page may wait for new audio before a stall is a failure (a loaded machine)
PICTURE_S = 60.0  # how long a picture may take: rendered in a worker at nice 10, which CPU hogs starve


class Studio(ServerProcess):
    """`python -m barsynth studio --port 0` in a process of its own."""

    what = "studio"

    def command(self) -> list[str]:
        return STUDIO_COMMAND

    def post(self, path: str, body: dict) -> dict:
        request = urllib.request.Request(self.url + path.lstrip("/"), data=json.dumps(body).encode(),
                                         headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(request, timeout=30) as response:
            return json.load(response)


@pytest.fixture(scope="module")
def browser():
    with chromium() as browser:
        yield browser


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    server = Studio(tmp_path_factory.mktemp("studio") / "studio.log")
    server.start()
    yield server
    assert server.stop() == 0  # SIGTERM stops the studio cleanly


@pytest.fixture(scope="module")
def shots():
    folder = screenshot_folder()

    def shot(page: Page, name: str) -> Path:
        path = folder / f"studio-{name}.png"
        page.screenshot(path=path, full_page=True)
        assert path.stat().st_size > 20000  # a real picture of a page, not an empty one
        return path
    return shot


def until(page: Page, script: str, timeout_s: float = 10.0, what: str = "") -> None:
    """Poll a page expression (wait_for_function would evaluate a string, which the page's CSP forbids)."""
    deadline = time.monotonic() + timeout_s
    while not page.evaluate(script):
        assert time.monotonic() < deadline, f"timed out waiting for {what or script}: " + page.evaluate(
            "() => JSON.stringify({state: studio.state, blocks: studio.blocksReceived, played: studio.samplesPlayed, "
            "errors: studio.errors, picture: studio.lastPicture && studio.lastPicture.model})")
        page.wait_for_timeout(25)


def figures(page: Page) -> dict:
    return page.evaluate("() => ({state: studio.state, blocks: studio.blocksReceived, played: studio.samplesPlayed, "
                         "maxBuffered: studio.maxBufferedFrames, underruns: studio.underruns, "
                         "latencies: studio.latencies.slice(), changeLatencies: studio.changeLatencies.slice(), "
                         "errors: studio.errors.slice(), sets: studio.sets, streams: studio.streams, "
                         "closes: studio.closes, reports: studio.playedReports, heard: studio.heardSetId, "
                         "now: performance.now()})")


def dropouts_during(page: Page, work) -> int:
    """How many times the page's buffer ran dry while ``work`` ran (and the 100 ms after)."""
    before = page.evaluate("() => studio.underruns")
    work()
    page.wait_for_timeout(100)
    return page.evaluate("() => studio.underruns") - before


def picture(page: Page) -> dict:
    return page.evaluate("() => studio.lastPicture")


def watch(page: Page, errors: list[str]) -> None:
    """Collect the page's uncaught errors and anything its Content-Security-Policy refused."""
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.on("console", lambda msg: errors.append(msg.text) if "Content Security Policy" in msg.text else None)


def open_studio(browser, url: str, errors: list[str]):
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    page = context.new_page()
    watch(page, errors)
    page.goto(url)
    until(page, "() => window.studio && studio.ready && studio.lastPicture !== null", PICTURE_S, "the first pictures")
    return context, page


def pictures_of(page: Page, model: str, name: str | None = None, value: float | None = None,
                timeout_s: float = PICTURE_S) -> dict:
    """Wait until the pictures show ``model`` (with parameter ``name`` at ``value``) and return them."""
    check = f"p.model === {json.dumps(model)}"
    if name is not None:
        check += f" && p.values && Math.abs(p.values[{json.dumps(name)}] - {value}) < 1e-9"
    until(page, f"() => {{ const p = studio.lastPicture; return p !== null && {check}; }}", timeout_s,
          f"pictures of {model} {name or ''}")
    return picture(page)


def table_rows(page: Page) -> list[list[str]]:
    return page.locator("#mode-table tbody tr").evaluate_all(
        "rows => rows.map(r => [...r.cells].map(c => c.textContent.trim()))")


def grows(page: Page, key: str, timeout_s: float = 5.0, by: int = 1) -> int:
    """Wait until window.studio[key] has grown by ``by``; returns the new value."""
    start = page.evaluate(f"() => studio.{key}")
    until(page, f"() => studio.{key} >= {start + by}", timeout_s, f"studio.{key} to grow from {start}")
    return page.evaluate(f"() => studio.{key}")


def louder_over(modes: list[dict], duration_s: float) -> dict:
    """The mode that rings loudest over a file of ``duration_s``: its gain times its decay's
    integral (a long-ringing low mode beats a short loud one in the spectrum)."""
    def weight(mode: dict) -> float:
        decay = math.log(1000.0) / mode["t60_s"]
        return abs(mode["gain"]) * (1.0 - math.exp(-decay * duration_s)) / decay
    return max(modes, key=weight)


def test_a_twang_played_live_changed_saved_and_shared(browser, studio, shots):
    errors: list[str] = []
    context, page = open_studio(browser, studio.url, errors)
    context.grant_permissions(["clipboard-read", "clipboard-write"], origin=studio.url.rstrip("/"))
    expect(page).to_have_title("barsynth studio")
    models = page.locator("#model option").all_inner_texts()
    assert models == list(model_names())
    page.select_option("#model", "twang")
    first = pictures_of(page, "twang", "length_m", 0.3)

    # The controls come from the table: one per parameter, log sliders where the scale is log.
    table = json.load(urllib.request.urlopen(studio.url + "api/models", timeout=10))["models"][0]["parameters"]
    for row in table:
        control = page.locator(f"#param-{row['name']}")
        expect(control).to_have_count(1)
        assert row["doc"] in control.get_attribute("title")
    assert page.locator("#param-thickness_m").get_attribute("class") == "log"
    expect(page.locator("#param-gain_mapping")).to_have_value("linear")
    expect(page.locator("#num-length_m")).to_have_value("0.3")
    expect(page.locator("#param-length_m")).to_have_value(str(round(1000 * (0.3 - 0.05) / 0.95)))

    # The twang's 18 modes in its three groups, in the plot's data and the table.
    assert first["modes"] == 18
    assert first["groups"] == {"full-cantilever": 6, "short-cantilever": 6, "free-bar": 6}
    assert first["spectrogramHash"] and 0.8 < first["waveformPeak"] <= 1.0
    rows = table_rows(page)
    assert len(rows) == 18 and {r[1] for r in rows} == {"full-cantilever", "short-cantilever", "free-bar"}
    expect(page.locator("#mode-table caption")).to_contain_text("18 modes of twang in 3 groups")
    shots(page, "01-twang-loaded")

    # Play: the stream starts and strikes; blocks arrive and are played.
    page.click("#play")
    until(page, "() => studio.state === 'playing' && studio.blocksReceived > 20 && studio.samplesPlayed > 9600",
          10, "the live sound")
    page.wait_for_timeout(300)
    in_shots = dropouts_during(page, lambda: shots(page, "02-twang-playing"))  # a full-page screenshot

    # Move the length slider, as a hand would: steps a while apart, then a quick run of key presses.
    slider = page.locator("#param-length_m")
    for position in (300, 260, 230, 200, 180, 165):
        blocks = figures(page)["blocks"]
        slider.fill(str(position))
        page.wait_for_timeout(220)
        until(page, f"() => studio.blocksReceived > {blocks}", NEW_BLOCKS_S, "new audio")  # it keeps coming
    slider.focus()
    for _ in range(7):
        page.keyboard.press("ArrowLeft")  # 165 -> 158
        page.wait_for_timeout(12)
    expect(page.locator("#num-length_m")).to_have_value("0.2001")
    grows(page, "blocksReceived", NEW_BLOCKS_S, 20)
    changed = pictures_of(page, "twang", "length_m", 0.2001)
    assert changed["spectrogramHash"] != first["spectrogramHash"]
    assert table_rows(page)[0][2] != rows[0][2]  # the lowest mode moved up with a shorter ruler
    assert changed["table"][0]["frequency_hz"] > 1.9 * first["table"][0]["frequency_hz"]
    until(page, "() => studio.lastSet !== null && studio.heardSetId >= studio.lastSet.id", NEW_BLOCKS_S,
          "the last change to be heard")
    live = figures(page)
    assert live["state"] == "playing" and live["errors"] == []
    # 13 moves, merged while a change is on its way (more merging on a busier machine); the last is heard
    assert 2 <= live["sets"] <= 13 and len(live["latencies"]) >= 1, live
    median = statistics.median(live["latencies"])
    assert 0 < live["maxBuffered"] < 0.1 * RATE, live  # the server's lead bounds the buffer, loaded or not
    print(f"live twang: {live['sets']} changes sent, heard after {median:.0f} ms (median; "
          f"{min(live['latencies']):.0f} to {max(live['latencies']):.0f} ms; from the slider: median "
          f"{statistics.median(live['changeLatencies']):.0f} ms), at most {live['maxBuffered']} samples "
          f"buffered, {live['blocks']} blocks")
    in_shots += dropouts_during(page, lambda: shots(page, "03-twang-changed"))

    # Re-trigger while it rings (the t key and the button); it keeps sounding; then stop.
    page.locator("body").click(position={"x": 5, "y": 880})  # away from any text box
    page.keyboard.press("t")
    grows(page, "blocksReceived", NEW_BLOCKS_S, 20)
    page.click("#trigger")
    grows(page, "samplesPlayed", NEW_BLOCKS_S, RATE // 10)
    session = figures(page)
    page.click("#stop")
    until(page, "() => studio.state === 'idle'", NEW_BLOCKS_S)
    page.wait_for_timeout(1000)  # what was already on its way (a loaded machine delays it)
    stopped = figures(page)["blocks"]
    page.wait_for_timeout(500)
    assert figures(page)["blocks"] == stopped  # nothing comes after a stop
    expect(page.locator("#live")).to_have_text("stopped")
    # Dropouts (the buffer running dry) are a measure of the machine's load: reported, not asserted.
    print(f"live twang: {session['underruns']} dropouts in {session['played'] / RATE:.1f} s played, "
          f"{in_shots} of them during the screenshots")

    # Download the WAV of these settings.
    page.fill("#duration", "2")
    with page.expect_download() as info:
        page.click("#download")
    download = info.value
    assert download.suggested_filename == "twang.wav"
    samples, rate = soundfile.read(io.BytesIO(Path(download.path()).read_bytes()))
    assert rate == RATE and samples.shape == (2 * RATE,)
    assert 20 * np.log10(np.max(np.abs(samples))) == pytest.approx(-1.0, abs=0.2)
    spectrum = np.abs(np.fft.rfft(samples * np.hanning(samples.size)))
    strongest = np.fft.rfftfreq(samples.size, 1 / rate)[np.argmax(spectrum)]
    loudest = louder_over(changed["table"], 2.0)
    assert strongest == pytest.approx(loudest["frequency_hz"], abs=max(1.0, 0.03 * loudest["frequency_hz"]))
    described = studio.post("/api/describe", {"model": "twang", "parameters": {"length_m": 0.2001}})["modes"]
    assert [m["frequency_hz"] for m in described] == pytest.approx([m["frequency_hz"] for m in changed["table"]])

    # A length the server refuses: its message, and no file.
    page.fill("#duration", "30")
    page.click("#download")
    expect(page.locator("#message")).to_contain_text("duration_s = 30 is out of range; allowed: 0.01 to 20 s")
    page.fill("#duration", "2")

    # Copy link: the address holds the model and the changed value; a new page restores it.
    page.select_option("#param-gain_mapping", "log")
    page.click("#share")
    link = page.locator("#share-url").input_value()
    assert link.startswith(studio.url) and "model=twang" in link
    assert "length_m=0.2001" in link and "gain_mapping=log" in link and "thickness_m" not in link
    assert page.url == link
    assert page.evaluate("() => navigator.clipboard.readText()") == link  # copied
    other = context.new_page()
    watch(other, errors)
    other.goto(link)
    until(other, "() => window.studio && studio.ready", PICTURE_S)
    expect(other.locator("#model")).to_have_value("twang")
    expect(other.locator("#num-length_m")).to_have_value("0.2001")
    expect(other.locator("#param-length_m")).to_have_value("158")
    expect(other.locator("#param-gain_mapping")).to_have_value("log")
    restored = pictures_of(other, "twang", "length_m", 0.2001)
    assert restored["values"]["gain_mapping"] == "log"
    shots(other, "04-twang-from-link")
    other.close()

    # A link with a preset keeps it; only what differs from the preset is in the address.
    page.select_option("#preset", "steel-30cm")
    pictures_of(page, "twang", "length_m", 0.3)
    page.locator("#num-q").fill("250")
    page.locator("#num-q").press("Enter")
    expect(page.locator("#param-q")).to_have_value(str(round(1000 * math.log(250 / 50) / math.log(800 / 50))))
    page.click("#share")
    link = page.locator("#share-url").input_value()
    assert "preset=steel-30cm" in link and "q=250" in link and "youngs_modulus_pa" not in link
    other = context.new_page()
    watch(other, errors)
    other.goto(link)
    until(other, "() => window.studio && studio.ready", PICTURE_S)
    expect(other.locator("#preset")).to_have_value("steel-30cm")
    expect(other.locator("#num-q")).to_have_value("250")
    expect(other.locator("#num-youngs_modulus_pa")).to_have_value("2e11")  # the preset's, not the default
    other.close()

    # Save preset: a TOML file whose [parameters] hold the values.
    page.fill("#description", "stiff steel ruler")
    with page.expect_download() as info:
        page.click("#save-preset")
    assert info.value.suggested_filename == "twang.toml"
    preset = tomllib.loads(Path(info.value.path()).read_text())
    assert preset["preset"]["description"] == "stiff steel ruler"
    assert preset["parameters"]["q"] == 250.0 and preset["parameters"]["youngs_modulus_pa"] > 1e11

    # A bad typed value: the server's one line, naming the parameter; the control goes back.
    box = page.locator("#num-length_m")
    box.fill("5")
    box.press("Enter")
    message = page.locator("#message")
    expect(message).to_be_visible()
    expect(message).to_have_attribute("role", "alert")
    expect(message).to_contain_text("length_m = 5")
    expect(message).to_contain_text("0.05 to 1 m")
    expect(box).to_have_value("0.3")
    assert page.evaluate("() => studio.values.length_m") == 0.3
    assert any("length_m" in e for e in page.evaluate("() => studio.errors"))
    shots(page, "05-bad-value")
    box.fill("0.25")
    box.press("Enter")
    expect(message).to_be_hidden()
    assert errors == []
    context.close()


def steady(page: Page, seconds: float = 0.6, what: str = "") -> dict:
    """Check that the stream plays on: blocks keep arriving and are played, each sample counted
    once (never more than real time), over at least ``seconds``; returns the figures at the end.
    (How close to real time it keeps up depends on the machine's load, so only a stall of
    ``NEW_BLOCKS_S`` fails.)"""
    until(page, "() => studio.state === 'playing'", NEW_BLOCKS_S, what)
    start = figures(page)
    until(page, f"() => studio.blocksReceived >= {start['blocks'] + 20}", NEW_BLOCKS_S, f"blocks after {what}")
    start = figures(page)
    page.wait_for_timeout(seconds * 1000)
    until(page, f"() => studio.blocksReceived >= {start['blocks'] + 20} && studio.samplesPlayed >= "
                f"{start['played'] + 20 * 256}", NEW_BLOCKS_S, f"blocks played after {what}")
    end = figures(page)
    elapsed_s = (end["now"] - start["now"]) / 1000
    played = end["played"] - start["played"]
    assert end["state"] == "playing" and end["errors"] == [] and end["closes"] == 0, (what, end)
    # Played samples are counted from the worklet's reports every 1024 frames: allow two of them.
    assert played <= elapsed_s * RATE + 2048, f"{what}: {played} samples played in {elapsed_s:.2f} s"
    return end


QUICK_STOP_PLAY = """async ([gap, sequence]) => {
  // Presses in one go, `gap` ms apart (0: in the same task), as a hand on the keys cannot be but
  // a page's code and events queued behind a busy main thread can.
  const pause = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
  for (const [k, id] of sequence.entries()) {
    if (k && gap) await pause(gap);
    document.getElementById(id).click();
  }
}"""


def test_quick_stop_and_play_end_with_the_sound_streaming_and_a_sleeping_stream_keeps_reporting(browser, studio):
    errors: list[str] = []
    context, page = open_studio(browser, studio.url, errors)
    page.click("#play")
    steady(page, what="play")
    streams = page.evaluate("() => studio.streams")
    for gap in (0, 50, 0, 50):
        page.evaluate(QUICK_STOP_PLAY, [gap, ["stop", "play"]])
        steady(page, 0.5, f"stop, play {gap} ms apart")
    for gap in (0, 50):
        page.evaluate(QUICK_STOP_PLAY, [gap, ["play", "stop", "play", "stop", "play"]])
        steady(page, 0.5, f"play, stop, play, stop, play {gap} ms apart")
    page.locator("body").click(position={"x": 5, "y": 880})
    page.keyboard.press("s")
    page.keyboard.press("t")
    end = steady(page, 0.5, "the s and t keys")
    # One socket per Play that opened one: presses in one task leave one (a Play waits a
    # moment for the audio, and a later press supersedes it); 50 ms apart, each Play opens one.
    assert end["streams"] == streams + 4 + 1 + 2 + 1
    assert errors == [], end
    print(f"quick stop and play: {end['streams']} sockets, {end['underruns']} dropouts")

    # The main thread is not on the audio's way: held for 0.4 s (far longer than the server's
    # 32 ms lead), blocks still arrive in the worker and are played. (Whether none runs dry
    # depends on the machine's load: benchmarks/studio_browser.py measures it.)
    before = figures(page)
    page.evaluate("() => { const t = performance.now(); while (performance.now() - t < 400) {} }")
    after = steady(page, 0.2, "a busy main thread")
    assert after["played"] > before["played"] and after["blocks"] > before["blocks"]
    print(f"busy main thread: {after['underruns'] - before['underruns']} dropouts")

    # A sleeping stream (silent for a second, not struck for three) sends nothing, so the
    # worklet has nothing to report; the worker reports anyway, so the server never closes it.
    for name, value in (("length_m", "0.1"), ("q", "50")):  # a quick decay
        page.locator(f"#num-{name}").fill(value)
        page.locator(f"#num-{name}").press("Enter")
    page.locator("body").click(position={"x": 5, "y": 880})  # away from the text boxes
    page.keyboard.press("t")
    deadline = time.monotonic() + 9
    slept = None
    while time.monotonic() < deadline:
        before = figures(page)
        page.wait_for_timeout(1200)
        after = figures(page)
        if after["blocks"] == before["blocks"]:
            slept = (before, after)
            break
    assert slept, "the stream did not go to sleep"
    before, after = slept
    reports = after["reports"] - before["reports"]
    assert reports >= 1, f"{reports} played reports in 1.2 s of a sleeping stream"
    print(f"sleeping stream: {reports} played reports in 1.2 s")
    assert after["state"] == "playing" and after["errors"] == []
    page.keyboard.press("t")  # it wakes
    grows(page, "blocksReceived", NEW_BLOCKS_S, 20)
    page.keyboard.press("Escape")
    assert errors == []
    context.close()


def test_an_allpass_slider_dragged_while_it_plays_keeps_the_stream_and_is_heard(browser, studio):
    """A change of the all-pass bar needs a new design (about 0.1 to 0.3 s a value): the page
    sends one set at a time, so a dragged slider never floods the server."""
    errors: list[str] = []
    context, page = open_studio(browser, studio.url, errors)
    page.select_option("#model", "allpass")
    pictures_of(page, "allpass", "length_m", 0.3)
    page.click("#play")
    until(page, "() => studio.blocksReceived > 20 && studio.samplesPlayed > 9600", 10, "allpass's live sound")
    slider = page.locator("#param-length_m")
    box = slider.bounding_box()
    y = box["y"] + box["height"] / 2
    x0 = box["x"] + box["width"] * float(slider.input_value()) / 1000  # about where its knob is
    page.mouse.move(x0, y)
    page.mouse.down()
    start = figures(page)
    began = time.monotonic()
    moves = 0
    while time.monotonic() - began < 2.0:  # back and forth over about 0.2 to 0.45 m, a pixel a step
        moves += 1
        page.mouse.move(x0 + 14 * math.sin(moves / 12), y)
        page.wait_for_timeout(10)
    page.mouse.move(x0 - 9, y)
    page.mouse.up()
    dragged = figures(page)
    final = page.evaluate("() => studio.values.length_m")
    until(page, f"() => studio.lastSet !== null && studio.lastSet.parameters.length_m === {final} && "
                "studio.heardSetId >= studio.lastSet.id", 5, "the last change to be heard")
    end = figures(page)
    last = page.evaluate("() => studio.lastSet")
    assert last["parameters"] == {"length_m": final}
    assert end["state"] == "playing" and end["closes"] == 0 and end["errors"] == [], end
    sets = end["sets"] - start["sets"]
    assert 1 <= sets <= moves, sets  # merged: no more sets than moves
    # (How many were heard while it moved depends on the machine's load: printed below.)
    grows(page, "blocksReceived", NEW_BLOCKS_S, 20)
    latencies = end["latencies"][-sets:]
    print(f"allpass drag: {moves} moves in 2 s, {sets} sets sent, heard after {statistics.median(latencies):.0f} ms "
          f"(median; {min(latencies):.0f} to {max(latencies):.0f} ms; the last {latencies[-1]:.0f} ms), "
          f"{dragged['underruns'] - start['underruns']} dropouts while dragging, {end['underruns']} in all")
    page.keyboard.press("Escape")
    assert errors == []
    context.close()


@pytest.mark.parametrize("model", [name for name in model_names() if name != "twang"])
def test_every_other_model_has_its_sliders_and_pictures(browser, studio, shots, model):
    errors: list[str] = []
    context, page = open_studio(browser, studio.url, errors)
    page.select_option("#model", model)
    shown = pictures_of(page, model)
    entry = next(m for m in json.load(urllib.request.urlopen(studio.url + "api/models", timeout=10))["models"]
                 if m["name"] == model)
    controlled = [row for row in entry["parameters"] if not row["data"]]  # a data row has no control
    assert page.locator("#controls [id^=param-]").count() == len(controlled)
    for row in entry["parameters"]:
        expect(page.locator(f"#param-{row['name']}")).to_have_count(0 if row["data"] else 1)
    data = {row["name"] for row in entry["parameters"] if row["data"]}
    assert data == ({"attack_samples", "attack_rate_hz"} if model == "banded" else set())
    assert data <= set(page.evaluate("() => Object.keys(studio.values)"))  # kept and sent all the same
    described = studio.post("/api/describe", {"model": model, "parameters": {}})["modes"]
    assert shown["modes"] == len(described) > 0
    assert shown["spectrogramHash"] and 0.8 < shown["waveformPeak"] <= 1.0
    assert page.locator("#mode-table tbody tr").count() == len(described)
    if any("error_cents" in m for m in described):
        expect(page.locator("#mode-table thead")).to_contain_text("error (cents)")

    if model == "banded":  # a brief live run: struck, re-struck by key, bowed and released, a new preset
        page.click("#play")
        until(page, "() => studio.blocksReceived > 20 && studio.samplesPlayed > 9600", 10, "banded's live sound")
        page.keyboard.press(" ")
        grows(page, "blocksReceived", NEW_BLOCKS_S, 20)
        page.select_option("#param-excitation", "bow")
        page.locator("body").click(position={"x": 5, "y": 880})
        page.keyboard.press("t")  # a bow stroke...
        grows(page, "samplesPlayed", NEW_BLOCKS_S, RATE // 5)
        page.keyboard.press("r")  # ...released
        grows(page, "blocksReceived", NEW_BLOCKS_S, 20)
        page.select_option("#preset", "marimba")
        pictures_of(page, model)
        grows(page, "blocksReceived", NEW_BLOCKS_S, 20)
        assert page.evaluate("() => studio.state") == "playing"
        page.keyboard.press("Escape")
        until(page, "() => studio.state === 'idle'", NEW_BLOCKS_S)
        assert page.evaluate("() => studio.errors") == []
    if model == "ruler":  # the physical twang streams: twanged, twanged again, its overhang moved while it rings
        page.click("#play")
        until(page, "() => studio.blocksReceived > 20 && studio.samplesPlayed > 9600", 10, "the ruler's live sound")
        page.keyboard.press(" ")
        grows(page, "blocksReceived", NEW_BLOCKS_S, 20)
        page.locator("#param-overhang_m").fill("120")  # slider positions 0-1000: about 13 cm
        grows(page, "samplesPlayed", NEW_BLOCKS_S, RATE // 5)
        assert page.evaluate("() => studio.state") == "playing"
        page.keyboard.press("Escape")
        until(page, "() => studio.state === 'idle'", NEW_BLOCKS_S)
        assert page.evaluate("() => studio.errors") == []
    if model == "fd":  # a choice changes the pictures
        before = shown["spectrogramHash"]
        page.select_option("#param-bc", "clamped-free")
        until(page, "() => studio.lastPicture.values && studio.lastPicture.values.bc === 'clamped-free'", PICTURE_S)
        assert picture(page)["spectrogramHash"] != before
    shots(page, f"06-{model}")
    assert errors == []
    context.close()


WORKLET_RUN = """async () => {
  // The page's worklet in an OfflineAudioContext, fed blocks at chosen render quanta over a
  // MessageChannel, as the stream's worker feeds it; its reports to the worker come back on it.
  const rate = 48000, Q = 128;
  const ctx = new OfflineAudioContext(1, Q * 36, rate);
  await ctx.audioWorklet.addModule("/static/worklet.js");
  const node = new AudioWorkletNode(ctx, "barsynth-stream",
    { numberOfInputs: 0, numberOfOutputs: 1, outputChannelCount: [1] });
  node.connect(ctx.destination);
  const posted = [], reports = [];
  node.port.onmessage = (event) => posted.push(event.data);
  const channel = new MessageChannel();
  node.port.postMessage({ type: "link", port: channel.port1 }, [channel.port1]);
  const link = channel.port2;
  link.onmessage = (event) => reports.push(event.data);
  const block = (id, gen = 1, value = 0.5) => {
    const buffer = new ArrayBuffer(8 + 256 * 4);
    new Float32Array(buffer, 8).fill(value);
    link.postMessage({ type: "block", gen, buffer, offset: 8, setId: id }, [buffer]);
  };
  const pause = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
  const at = (quantum, work) => ctx.suspend(quantum * Q / rate).then(async () => {
    work();
    await pause(150);  // the messages reach the worklet before rendering goes on (a loaded machine: slowly)
    ctx.resume();
  });
  node.port.postMessage({ type: "reset", gen: 1 });
  block(0); block(0); block(1);  // 6 quanta, then the buffer runs dry
  await pause(150);
  at(10, () => { block(2); block(2); });  // back after 4 quanta of silence
  at(12, () => { block(3); block(3); block(3); });
  at(15, () => node.port.postMessage({ type: "stop", gen: 1 }));
  at(17, () => {  // during the stop's fade: a block of the stopped socket, then the next socket's
    block(4);     // start (its reset comes late) with two blocks: less than half its lead
    link.postMessage({ type: "started", gen: 2, lead: 1536 });
    block(0, 2, 0.25); block(0, 2, 0.25);
  });
  at(20, () => block(0, 2, 0.25));  // half the lead: it plays
  at(26, () => {
    node.port.postMessage({ type: "reset", gen: 2 });  // late: changes nothing
    block(5, 1);  // the old socket's: dropped
    block(1, 2, 0.25); block(1, 2, 0.25); block(1, 2, 0.25); block(1, 2, 0.25);
  });
  at(29, () => node.port.postMessage({ type: "stop", gen: 2 }));
  const out = await ctx.startRendering();
  await pause(150);
  return { out: Array.from(out.getChannelData(0)), posted, reports };
}"""


def test_the_worklet_fades_out_when_it_runs_dry_fades_back_in_and_fades_out_at_a_stop(browser, studio):
    """The worklet on its own, in an OfflineAudioContext: no step anywhere in its output, and
    nothing of a stopped socket mixed into the next."""
    context = browser.new_context()
    page = context.new_page()
    page.goto(studio.url)
    run = page.evaluate(WORKLET_RUN)
    context.close()
    out = np.array(run["out"])
    q, ramp = 128, np.arange(128)
    stop = 480  # 10 ms at 48 kHz
    expected = np.zeros(36 * q)
    expected[:q] = 0.5 * ramp / q  # the start fades in over 128 frames
    expected[q:5 * q] = 0.5
    expected[5 * q:6 * q] = 0.5 * (1 - (ramp + 1) / q)  # the last quantum buffered fades to zero
    expected[10 * q:11 * q] = 0.5 * ramp / q  # samples are back: a fade-in
    expected[11 * q:15 * q] = 0.5
    expected[15 * q:15 * q + stop] = 0.5 * (stop - 1 - np.arange(stop)) / stop  # stop
    expected[20 * q:21 * q] = 0.25 * ramp / q  # the next socket, once half its lead is there
    expected[21 * q:25 * q] = 0.25
    expected[25 * q:26 * q] = 0.25 * (1 - (ramp + 1) / q)
    expected[26 * q:27 * q] = 0.25 * ramp / q
    expected[27 * q:29 * q] = 0.25
    expected[29 * q:29 * q + stop] = 0.25 * (stop - 1 - np.arange(stop)) / stop
    assert out == pytest.approx(expected, abs=1e-6)
    assert np.max(np.abs(np.diff(out))) <= 0.5 / 128 + 1e-6  # no click
    posted, reports = run["posted"], run["reports"]
    assert [(m["gen"], m["heard"]) for m in posted if "heard" in m] == [(1, 0), (1, 1), (1, 2), (1, 3), (2, 0), (2, 1)]
    assert [m["gen"] for m in posted if m.get("underrun")] == [1, 2]
    # Frames of each socket taken from the buffer, reported to the worker every 256 and on
    # running dry; the stop's fade is counted in the final figure.
    assert [(m["gen"], m["samples"]) for m in reports if m["type"] == "played"] == \
        [(1, 256), (1, 512), (1, 768), (1, 1024), (1, 1280), (2, 256), (2, 512), (2, 768), (2, 1024)]
    assert [m for m in reports if m["type"] == "stopped"] == [{"type": "stopped", "gen": g} for g in (1, 2)]
    assert [m for m in posted if "stopped" in m] == [{"stopped": True, "gen": 1, "played": 11 * q + stop},
                                                   {"stopped": True, "gen": 2, "played": 9 * q + stop}]
    stats = [(m["gen"], m["played"]) for m in posted if "stats" in m]
    assert stats == sorted(stats) and all(played <= 11 * q for gen, played in stats if gen == 1)


# --- controls that have no effect are greyed out (a row's "when") ----------------------------

def control_state(page: Page, name: str) -> dict:
    """How the control of parameter ``name`` looks: greyed out or not, its title, its inputs."""
    return page.evaluate("""(name) => {
      const wrap = document.querySelector(`#controls .param[data-name="${name}"]`);
      const inputs = [...wrap.querySelectorAll("input, select")];
      return { inactive: wrap.classList.contains("inactive"), title: wrap.title,
               titles: inputs.map((i) => i.title), disabled: inputs.map((i) => i.disabled),
               opacity: Number(getComputedStyle(wrap).opacity), listed: studio.inactive.includes(name) };
    }""", name)


def assert_greyed(page: Page, name: str, unless: str) -> None:
    until(page, f"() => studio.inactive.includes({json.dumps(name)})", 10, f"{name} greyed out")
    state = control_state(page, name)
    assert state["inactive"] and all(state["disabled"]) and state["opacity"] < 0.6
    assert state["title"].startswith(f"no effect unless {unless}")
    assert all(t == state["title"] for t in state["titles"])


def assert_active(page: Page, name: str) -> None:
    until(page, f"() => !studio.inactive.includes({json.dumps(name)})", 10, f"{name} active again")
    state = control_state(page, name)
    assert not state["inactive"] and not any(state["disabled"]) and state["opacity"] == 1
    assert "no effect" not in state["title"] and all("no effect" not in t for t in state["titles"])


def test_a_control_is_greyed_out_while_its_when_does_not_hold(browser, studio, shots):
    """banded's own table: the bow's rows act only under excitation = bow, frequency_hz only under
    tuning = ratios, the bar's size and material only under tuning = physics."""
    errors: list[str] = []
    context, page = open_studio(browser, studio.url + "?model=banded", errors)
    pictures_of(page, "banded")

    # The defaults: struck and tuned by physics, so neither the bow nor the frequency acts.
    inactive = page.evaluate("() => studio.inactive")
    assert {"frequency_hz", "bow_force_n", "mode_ratios", "pluck_displacement_mm"} <= set(inactive)
    assert not {"material", "length_m", "mallet_hardness", "q"} & set(inactive)
    assert_greyed(page, "bow_force_n", "excitation = bow")
    assert_greyed(page, "frequency_hz", "tuning = ratios")
    assert_active(page, "q")  # acts while some mode has no T60 of its own (none has, by default)
    shots(page, "08-greyed-out")

    # Choosing the controlling value brings the control back at once; choosing another greys it again.
    page.select_option("#param-excitation", "bow")
    assert_active(page, "bow_force_n")
    assert_greyed(page, "mallet_hardness", "excitation = strike")
    page.fill("#num-bow_force_n", "5")
    page.press("#num-bow_force_n", "Enter")
    until(page, "() => studio.values.bow_force_n === 5", 10, "bow_force_n typed")
    page.select_option("#param-excitation", "pluck")
    assert_greyed(page, "bow_force_n", "excitation = bow")
    assert page.evaluate("() => studio.values.bow_force_n") == 5  # greyed out, not forgotten
    page.select_option("#param-tuning", "ratios")
    assert_active(page, "frequency_hz")
    assert_greyed(page, "length_m", "tuning = physics")

    # A preset or the defaults again: the greying follows the values loaded.
    page.select_option("#preset", "")
    until(page, "() => studio.values.tuning === 'physics'", 10, "the defaults")
    assert page.evaluate("() => studio.inactive") == inactive

    # A link that bows: the link's values are in force from the start.
    page.goto(studio.url + "?model=banded&excitation=bow&tuning=ratios")
    until(page, "() => window.studio && studio.ready", PICTURE_S, "the page from a link")
    assert_active(page, "bow_force_n")
    assert_active(page, "frequency_hz")
    assert errors == [] and page.evaluate("() => studio.errors") == []
    context.close()


def test_a_control_that_acts_only_above_a_number_is_greyed_out_below_it(browser, studio):
    """The twang's vibrato depth acts only while the vibrato runs (vibrato_rate_hz > 0, a number, not
    a choice): greyed out at rate 0, back as soon as a rate is typed, greyed again at 0; banded's q
    greys out once every mode has its own T60."""
    errors: list[str] = []
    context, page = open_studio(browser, studio.url + "?model=twang", errors)
    pictures_of(page, "twang")
    assert_greyed(page, "vibrato_depth_hz", "vibrato_rate_hz > 0")
    page.fill("#num-vibrato_rate_hz", "5")
    page.press("#num-vibrato_rate_hz", "Enter")
    assert_active(page, "vibrato_depth_hz")
    page.fill("#num-vibrato_rate_hz", "0")
    page.press("#num-vibrato_rate_hz", "Enter")
    assert_greyed(page, "vibrato_depth_hz", "vibrato_rate_hz > 0")

    page.goto(studio.url + "?model=banded")
    until(page, "() => window.studio && studio.ready", PICTURE_S, "banded")
    assert_active(page, "q")
    page.fill("#num-mode_count", "2")
    page.press("#num-mode_count", "Enter")
    page.fill("#param-mode_t60s_s", "1, 0.5")
    page.press("#param-mode_t60s_s", "Enter")
    assert_greyed(page, "q", "tuning = physics or geometry and mode_t60s_s has fewer values than mode_count")
    page.fill("#num-mode_count", "3")
    page.press("#num-mode_count", "Enter")
    assert_active(page, "q")
    assert errors == [] and page.evaluate("() => studio.errors") == []
    context.close()


def test_a_material_sets_youngs_modulus_and_density(browser, studio):
    """The material is a <select> like the other choices; choosing one shows its E and rho, and the
    server takes the settings (no refusal); moving E by hand turns it back to custom."""
    from barsynth.physics import material, materials

    errors: list[str] = []
    context, page = open_studio(browser, studio.url + "?model=banded", errors)
    pictures_of(page, "banded")
    select = page.locator("#param-material")
    assert select.evaluate("(s) => s.tagName") == "SELECT"
    assert select.locator("option").count() == 1 + len(materials())
    expect(select).to_have_value("custom")
    box, row = select.bounding_box(), page.locator('#controls .param[data-name="material"]').bounding_box()
    side = page.locator("#side").bounding_box()
    assert row["height"] < 40 and box["x"] + box["width"] <= side["x"] + side["width"]
    tuning = page.locator("#param-tuning").bounding_box()
    assert abs(box["x"] - tuning["x"]) < 1 and abs(box["width"] - tuning["width"]) < 1

    steel = material("steel")
    page.select_option("#param-material", "steel")
    until(page, "() => studio.values.material === 'steel'", 10, "the material chosen")
    assert page.evaluate("() => [studio.values.youngs_modulus_pa, studio.values.density_kg_m3]") == [
        steel.youngs_modulus_pa, steel.density_kg_m3]
    assert float(page.input_value("#num-youngs_modulus_pa")) == pytest.approx(steel.youngs_modulus_pa)
    until(page, "() => studio.lastPicture.values && studio.lastPicture.values.material === 'steel'", PICTURE_S,
          "the steel bar's pictures")
    page.fill("#num-youngs_modulus_pa", "1e11")
    page.press("#num-youngs_modulus_pa", "Enter")
    until(page, "() => studio.values.material === 'custom'", 10, "the material back to custom")
    expect(select).to_have_value("custom")
    until(page, "() => studio.lastPicture.values.material === 'custom'", PICTURE_S, "the custom bar's pictures")
    assert errors == [] and page.evaluate("() => studio.errors") == []
    context.close()




FIT_S = 180.0  # how long a fit may take: a worker at nice 10 on a loaded machine
DROP_FILE = """(b64) => {
  const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
  const transfer = new DataTransfer();
  transfer.items.add(new File([bytes], "note.wav", { type: "audio/wav" }));
  return transfer;
}"""


def struck_note(rate: int = 44100) -> bytes:
    """A WAV of a struck note: 440 Hz and partials at 2.76 and 5.4 times it, after 45 ms of quiet."""
    t = np.arange(int(1.5 * rate)) / rate
    x = sum(a * np.exp(-t * math.log(1000.0) / t60) * np.sin(2 * np.pi * f * t)
            for f, a, t60 in [(440.0, 0.5, 1.2), (440.0 * 2.76, 0.25, 0.6), (440.0 * 5.4, 0.1, 0.3)])
    buffer = io.BytesIO()
    soundfile.write(buffer, np.concatenate([np.zeros(int(0.045 * rate)), 0.8 * x]), rate, format="WAV",
                    subtype="PCM_16")
    return buffer.getvalue()


def test_a_recording_dropped_on_the_page_is_fitted_loaded_and_played_against_its_fit(browser, studio, shots,
                                                                                     tmp_path):
    import base64

    errors: list[str] = []
    context, page = open_studio(browser, studio.url, errors)
    expect(page.locator("#fit-model option")).to_have_count(3)
    expect(page.locator("#fit-result")).to_be_hidden()

    # Dropped anywhere on the page (here on the pictures): the page shows it is taking the file,
    # then fits it.
    transfer = page.evaluate_handle(DROP_FILE, base64.b64encode(struck_note()).decode())
    page.dispatch_event("#pictures", "dragenter", {"dataTransfer": transfer})
    page.dispatch_event("#pictures", "dragover", {"dataTransfer": transfer})
    assert "dropping" in page.get_attribute("body", "class")
    page.dispatch_event("#pictures", "drop", {"dataTransfer": transfer})
    assert "dropping" not in (page.get_attribute("body", "class") or "")
    until(page, "() => studio.fit.state !== 'idle'", 10, "the fit to start")
    until(page, "() => studio.fit.state !== 'fitting'", FIT_S, "the fit")
    assert page.evaluate("() => studio.fit.state") == "done", page.evaluate("() => studio.errors")

    # The fitted settings are in the controls, as a preset's would be: banded, 440 Hz, its ratios.
    result = page.evaluate("() => studio.fit.result")
    assert result["model"] == "banded" and result["partials"] == 3 and result["distanceDb"] < result["baselineDb"]
    expect(page.locator("#model")).to_have_value("banded")
    expect(page.locator("#preset")).to_have_value("(fitted)")
    expect(page.locator("#preset option:checked")).to_have_text("(fitted: note.wav)")
    expect(page.locator("#num-frequency_hz")).to_have_value("440")
    assert page.input_value("#param-mode_ratios").startswith("1,2.7")
    expect(page.locator("#param-excitation")).to_have_value("sample")
    values = page.evaluate("() => studio.values")
    assert values["attack_rate_hz"] == 44100 and len(values["attack_samples"]) > 800  # kept, with no control
    pictures_of(page, "banded", "frequency_hz", values["frequency_hz"])

    # The A/B panel: the distance, the partials' table and both spectrograms, painted.
    expect(page.locator("#fit-result")).to_be_visible()
    expect(page.locator("#fit-distance")).to_contain_text("spectral distance")
    rows = page.locator("#fit-table tbody tr").evaluate_all(
        "rows => rows.map(r => [...r.cells].map(c => c.textContent.trim()))")
    assert [r[1] for r in rows] == ["440.00", "1214.40", "2376.00"]
    assert all(abs(float(r[5])) < 2.0 for r in rows)  # cents
    for canvas in ("#fit-spec-recording", "#fit-spec-resynthesis"):
        colours = page.locator(canvas).evaluate("""(c) => {
          const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
          const seen = new Set();
          for (let i = 0; i < d.length; i += 4 * 97) seen.add(d[i] << 16 | d[i + 1] << 8 | d[i + 2]);
          return seen.size; }""")
        assert colours > 20
    assert result["spectrogramHashes"][0] != result["spectrogramHashes"][1]

    # A and B play: samples reach the page's audio output (its analyser), the recording by button,
    # the resynthesis by key; each press starts its own sound.
    page.click("#play-recording")
    until(page, "() => studio.fit.heardPeak.recording > 0.1", NEW_BLOCKS_S, "the recording to sound")
    page.locator("body").click(position={"x": 5, "y": 880})
    page.keyboard.press("b")
    until(page, "() => studio.fit.heardPeak.resynthesis > 0.1", NEW_BLOCKS_S, "the resynthesis to sound")
    assert page.evaluate("() => studio.fit.plays") == {"recording": 1, "resynthesis": 1}
    assert page.evaluate("() => studio.fit.playing") in ("resynthesis", None)
    shots(page, "09-fit")

    # The live sound plays the fitted settings (the recorded attack too), at another pitch as well.
    page.click("#play")
    until(page, "() => studio.blocksReceived > 20 && studio.samplesPlayed > 9600", NEW_BLOCKS_S, "the fit played live")
    assert page.evaluate("() => studio.fit.playing") is None  # the A/B player stopped for it
    page.fill("#num-frequency_hz", "330")
    page.press("#num-frequency_hz", "Enter")
    until(page, "() => studio.heardSetId >= 1 || (studio.lastSet && studio.lastSet.parameters.frequency_hz === 330)",
          NEW_BLOCKS_S, "the new pitch sent")
    grows(page, "blocksReceived", NEW_BLOCKS_S, 20)
    pictures_of(page, "banded", "frequency_hz", 330)
    page.keyboard.press("Escape")
    until(page, "() => studio.state === 'idle'", NEW_BLOCKS_S)
    assert page.evaluate("() => studio.errors") == []

    # A file that is no sound, chosen with the file button: the server's one line, and the page goes on.
    bad = tmp_path / "bad.wav"
    bad.write_text("not a sound at all\n" * 20)
    page.set_input_files("#fit-file", str(bad))
    until(page, "() => studio.fit.state === 'failed'", FIT_S, "the refusal")
    expect(page.locator("#message")).to_contain_text("audio file bad.wav: cannot be read as WAV, FLAC or OGG")
    expect(page.locator("#fit-status")).to_contain_text("no fit")
    expect(page.locator("#num-frequency_hz")).to_have_value("330")  # the settings stay
    assert errors == []
    context.close()
