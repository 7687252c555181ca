"""Randomize, Mutate, A/B snapshots and undo/redo in the studio's page (issue 18), in Debian's
Chromium under Playwright against `barsynth studio` running as a real process (the fixtures of
test_studio_browser.py). What is checked is values: the page's settings (``studio.values``, which
go to the server as they are), what its controls show (slider positions, number boxes, choices),
the links, and for A/B the pitch the page plays (``studio.liveSamples()``)."""

from __future__ import annotations

import json
import math
import time
import urllib.request

import numpy as np
from test_studio_browser import PICTURE_S, browser, studio, until, watch  # noqa: F401
from test_studio_keys_browser import heard, level_at

SHOWN = """() => Object.fromEntries([...document.querySelectorAll('#controls input, #controls select')]
  .map((e) => [e.id, e.type === 'checkbox' ? e.checked : e.value]))"""


def open_page(browser, url: str, errors: list[str]):  # noqa: F811
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    page = context.new_page()
    watch(page, errors)
    page.goto(url)
    until(page, "() => window.studio && studio.ready", PICTURE_S, "the page")
    return context, page


def values(page) -> dict:
    return page.evaluate("() => studio.values")


def shown(page) -> dict:
    return page.evaluate(SHOWN)


def rows_of(studio, model: str) -> dict[str, dict]:  # noqa: F811
    models = json.load(urllib.request.urlopen(studio.url + "api/models", timeout=10))["models"]
    return {row["name"]: row for row in next(m for m in models if m["name"] == model)["parameters"]}


def unit(row: dict, v: float) -> float:
    """Where ``v`` lies along its row's range, on its scale (0 to 1)."""
    if row["scale"] == "log":
        return math.log(v / row["min"]) / math.log(row["max"] / row["min"])
    return (v - row["min"]) / (row["max"] - row["min"])


def slider_rows(rows: dict) -> list[dict]:
    """The number rows with a slider, less a material's (E and density jump with a material drawn)."""
    material = {n for row in rows.values() if row.get("sets") for n in row["sets"]["names"]}
    return [r for r in rows.values() if r["kind"] in ("float", "int") and not r["data"] and r["name"] not in material]


def share(page) -> str:
    page.click("#share")
    return page.locator("#share-url").input_value()


def test_randomize_and_mutate_are_seeded_and_their_links_give_the_same_settings(browser, studio):  # noqa: F811
    errors: list[str] = []
    rows = rows_of(studio, "twang")
    context, page = open_page(browser, studio.url + "?model=twang&preset=steel-30cm&q=250", errors)
    start = values(page)
    assert start["q"] == 250

    # Randomize: most sliders move, to values within their ranges; each slider shows its value.
    page.click("#randomize")
    until(page, "() => studio.draws === 1", 30, "the random draw")
    drawn, seed = values(page), page.evaluate("() => studio.lastDraw.seed")
    assert 0 <= seed < 2**32
    numbers = slider_rows(rows)
    assert sum(drawn[r["name"]] != start[r["name"]] for r in numbers) >= 0.8 * len(numbers)
    looks = shown(page)
    for row in numbers:
        assert row["min"] <= drawn[row["name"]] <= row["max"]
        position = round(1000 * unit(row, drawn[row["name"]]))
        assert abs(int(looks[f"param-{row['name']}"]) - position) <= 1, row["name"]
    assert page.locator("#draw-note").inner_text().startswith(f"random, seed {seed}")

    # The link names the draw: the settings it started from and the seed, not the drawn values.
    link = share(page)
    assert f"random={seed}" in link and "preset=steel-30cm" in link and "q=250" in link and "length_m" not in link
    other_context, other = open_page(browser, link, errors)
    until(other, "() => studio.draws === 1", 30, "the link's draw")
    assert values(other) == drawn  # every value to the last digit
    assert shown(other) == looks  # the same slider positions, boxes and choices
    assert other.evaluate("() => studio.history") == {"undo": 0, "redo": 0}  # the page starts there

    # Mutate by 0.05: every slider moves by at most 5 % of its range; the link holds the drawn
    # values it started from, the seed and the spread, and gives the same settings again.
    page.fill("#spread", "0.05")
    page.click("#mutate")
    until(page, "() => studio.draws === 2", 30, "the mutation")
    mutated, seed2 = values(page), page.evaluate("() => studio.lastDraw.seed")
    steps = [abs(unit(r, mutated[r["name"]]) - unit(r, drawn[r["name"]])) for r in numbers]
    assert max(steps) <= 0.05 + 1e-9 and sum(s > 0 for s in steps) >= 0.8 * len(numbers), steps
    link = share(page)
    assert f"mutate={seed2}" in link and "spread=0.05" in link and "random=" not in link
    assert "length_m=" in link  # the draw's starting point: the random values
    other.goto(link)
    until(other, "() => window.studio && studio.ready && studio.draws === 1", PICTURE_S, "the mutate link")
    assert values(other) == mutated and other.locator("#spread").input_value() == "0.05"

    # A value changed by hand after a draw: the link holds the values, no seed.
    page.fill("#num-length_m", "0.5")
    page.press("#num-length_m", "Enter")
    until(page, "() => studio.values.length_m === 0.5", 10, "the typed length")
    link = share(page)
    assert "mutate=" not in link and "spread=" not in link and "length_m=0.5" in link
    other.goto(link)
    until(other, "() => window.studio && studio.ready", PICTURE_S, "the values link")
    assert values(other) == values(page) and other.evaluate("() => studio.draws") == 0

    # A bad seed or spread in a link: the server's one line; the settings before the draw.
    for query, words in [("random=abc", "seed = 'abc'"), ("mutate=5&spread=2", "spread = 2 is out of range")]:
        other.goto(studio.url + "?model=twang&q=300&" + query)
        until(other, "() => window.studio && studio.ready", PICTURE_S, "a bad link")
        assert any(words in e for e in other.evaluate("() => studio.errors")), query
        assert other.evaluate("() => studio.draws") == 0 and values(other)["q"] == 300
    assert errors == []
    other_context.close()
    context.close()


def settings(page) -> tuple:
    return values(page), page.locator("#preset").input_value(), shown(page)


def test_ab_snapshots_and_undo_redo_round_trip_exactly(browser, studio):  # noqa: F811
    errors: list[str] = []
    context, page = open_page(browser, studio.url + "?model=twang", errors)
    for button in ("#undo", "#redo", "#recall-a", "#recall-b", "#swap-ab"):
        assert page.locator(button).is_disabled(), button
    states = [settings(page)]

    page.click("#randomize")
    until(page, "() => studio.draws === 1", 30, "the draw")
    states.append(settings(page))
    assert page.locator("#undo").is_enabled() and page.locator("#redo").is_disabled()

    # A slider dragged over several positions is one step.
    box = page.locator("#param-length_m").bounding_box()
    y = box["y"] + box["height"] / 2
    page.mouse.move(box["x"] + 0.2 * box["width"], y)
    page.mouse.down()
    seen = set()
    for f in (0.3, 0.45, 0.6, 0.75):
        page.mouse.move(box["x"] + f * box["width"], y, steps=3)
        seen.add(values(page)["length_m"])
    page.mouse.up()
    assert len(seen) == 4  # the value followed the drag
    assert page.evaluate("() => studio.history") == {"undo": 2, "redo": 0}
    states.append(settings(page))

    page.select_option("#preset", "wooden-30cm")
    until(page, "() => studio.values.length_m === 0.3 && studio.history.undo === 3", 10, "the preset")
    states.append(settings(page))

    # A/B: store, change, store, recall each; the lit button is the snapshot shown.
    page.click("#store-a")
    page.click("#mutate")
    until(page, "() => studio.draws === 2", 30, "the mutation")
    page.click("#store-b")
    a, b = states[-1], settings(page)
    states.append(b)
    assert page.evaluate("() => studio.ab") == {"a": True, "b": True, "showing": "b"}
    page.click("#recall-a")
    assert settings(page) == a and page.evaluate("() => studio.ab.showing") == "a"
    assert "on" in page.locator("#recall-a").get_attribute("class")
    page.click("#recall-b")
    assert settings(page) == b
    page.click("#swap-ab")
    assert settings(page) == a
    page.locator("body").click(position={"x": 5, "y": 880})
    page.keyboard.press("x")
    assert settings(page) == b
    states += [a, b, a, b]  # each recall a step

    # Undo (Ctrl+Z) back to the start, each step exactly; then nothing more to undo.
    assert page.evaluate("() => studio.history") == {"undo": len(states) - 1, "redo": 0}
    for back in reversed(states[:-1]):
        page.keyboard.press("Control+z")
        assert settings(page) == back
    assert page.locator("#undo").is_disabled() and page.locator("#redo").is_enabled()
    page.keyboard.press("Control+z")
    assert settings(page) == states[0]
    # Redo (Ctrl+Shift+Z) forward to the end.
    for ahead in states[1:]:
        page.keyboard.press("Control+Shift+z")
        assert settings(page) == ahead
    assert page.locator("#redo").is_disabled()
    page.click("#undo")
    assert settings(page) == states[-2]
    page.click("#redo")
    assert settings(page) == states[-1]

    # In a box, Ctrl+Z is the box's own: the settings stay.
    page.click("#num-q")
    page.keyboard.press("Control+z")
    assert settings(page) == states[-1] and page.evaluate("() => studio.history.redo") == 0
    # A new change after an undo leaves nothing to redo.
    page.click("#undo")
    page.select_option("#param-gain_mapping", "log")
    assert page.evaluate("() => studio.history.redo") == 0 and page.locator("#redo").is_disabled()
    assert errors == [] and page.evaluate("() => studio.errors") == []
    context.close()


def test_recalling_a_snapshot_changes_the_sound(browser, studio):  # noqa: F811
    """A at 440 Hz, B at 523.25 Hz (banded, tuned by ratios 1, 4, 10): recalling each while it
    plays, the page plays that pitch and not the other."""
    errors: list[str] = []
    context, page = open_page(browser, studio.url + "?model=banded&tuning=ratios&frequency_hz=440", errors)
    page.click("#store-a")
    page.fill("#num-frequency_hz", "523.2511")
    page.press("#num-frequency_hz", "Enter")
    until(page, "() => studio.values.frequency_hz === 523.2511", 10, "the typed frequency")
    page.click("#store-b")
    page.click("#play")
    until(page, "() => studio.state === 'playing' && studio.samplesPlayed > 48000", 30, "the live sound")
    for key, hz, other in [("a", 440.0, 523.2511), ("b", 523.2511, 440.0), ("a", 440.0, 523.2511)]:
        page.click(f"#recall-{key}")
        assert page.evaluate("() => studio.values.frequency_hz") == hz
        deadline = time.monotonic() + 20
        while True:  # the new voice is heard within the stream's lead; a loaded machine may be slow
            x = heard(page)
            levels = (level_at(x, hz), level_at(x, other)) if x.size and np.any(x) else (-99.0, 0.0)
            if levels[0] > -6 and levels[1] < -30:
                break
            assert time.monotonic() < deadline, (key, levels)
            page.wait_for_timeout(100)
    page.click("#stop")
    assert errors == [] and page.evaluate("() => studio.errors") == []
    context.close()
