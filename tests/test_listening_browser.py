"""The listening test as a participant takes it: Debian's Chromium, driven by Playwright,
against `barsynth listen serve` running as a real process on a real SQLite file.

Chromium comes from Debian; Playwright never downloads a browser here (see tests/browser.py).
Screenshots of each stage are kept in test-artifacts/screenshots/ (or $BARSYNTH_SCREENSHOTS).
"""

from __future__ import annotations

import json
import sqlite3
import sys
import time
from pathlib import Path

import pytest
from browser import ServerProcess, chromium, screenshot_folder
from playwright.sync_api import Page, expect

class Server(ServerProcess):
    """`python -m barsynth listen serve` in a process of its own."""

    what = "listening server"

    def __init__(self, config: Path, results: Path, log: Path):
        super().__init__(log)
        self.config, self.results = config, results

    def command(self) -> list[str]:
        return [sys.executable, "-m", "barsynth", "listen", "serve", str(self.config),
                "--results", str(self.results), "--port", str(self.port)]


@pytest.fixture(scope="module")
def browser():
    with chromium() as browser:
        yield browser


@pytest.fixture
def server(listening_config, tmp_path):
    server = Server(listening_config, tmp_path / "results.db", tmp_path / "server.log")
    yield server
    server.stop()


@pytest.fixture
def shots():
    folder = screenshot_folder()

    def shot(page: Page, name: str) -> None:
        path = folder / f"listening-{name}.png"
        page.screenshot(path=path, full_page=True)
        assert path.stat().st_size > 5000  # a real picture of a page, not an empty one
    return shot


def db_rows(results: Path, sql: str) -> list[tuple]:
    with sqlite3.connect(results) as con:
        return con.execute(sql).fetchall()


def plan_of(results: Path) -> tuple[str, dict]:
    ((participant, plan),) = db_rows(results, "SELECT participant, plan FROM sessions")
    return participant, json.loads(plan)


def play_every_sound(page: Page, section: str) -> None:
    """Click every Play button of the step on screen; the last sound is heard to its end."""
    buttons = page.locator(f"#{section} button.play")
    expect(page.locator(f"#{section}")).to_be_visible()
    assert buttons.count() >= 2
    for i in range(buttons.count()):
        buttons.nth(i).click()
        expect(page.locator(f"#{section} .plays").nth(i)).to_have_text("played once")
    # The browser really fetched, decoded and played the served WAV to its end.
    last = buttons.nth(buttons.count() - 1).get_attribute("data-handle")
    until(page, f"() => player.src.endsWith('/api/audio/{last}') && player.ended && player.duration > 0.3")


def until(page: Page, script: str, timeout_s: float = 30.0) -> None:
    """Poll a page expression (wait_for_function would evaluate a string, which the page's CSP forbids)."""
    deadline = time.monotonic() + timeout_s
    while not page.evaluate(script):
        assert time.monotonic() < deadline, f"timed out waiting for {script}: " + page.evaluate(
            "() => JSON.stringify({src: player.src, t: player.currentTime, d: player.duration, "
            "paused: player.paused, ended: player.ended, state: player.readyState, error: player.error && "
            "player.error.code, status: document.getElementById('status').textContent})")
        page.wait_for_timeout(50)


def set_sliders(page: Page, fractions: list[float]) -> list[float]:
    """Move each slider with the mouse, as a participant would; returns the values shown."""
    items = page.locator("#mushra-clips li.clip")
    assert items.count() >= len(fractions)  # the first len(fractions) sliders
    values = []
    for i, fraction in enumerate(fractions):
        slider = items.nth(i).locator("input.rating")
        box = slider.bounding_box()
        # A click at the very left end for 0: the value may not change, yet the rating is given.
        page.mouse.click(box["x"] + max(fraction * box["width"], 1), box["y"] + box["height"] / 2)
        value = float(slider.input_value())
        assert value == pytest.approx(9.99 * fraction, abs=0.4)
        expect(items.nth(i).locator("output")).to_have_text(f"{value:.2f}")
        values.append(value)
    return values


def answer_pair(page: Page, progress: str, picked: str, difficulty: int) -> None:
    expect(page.locator("#progress")).to_have_text(progress)
    submit = page.locator("#ab-submit")
    expect(submit).to_be_disabled()
    play_every_sound(page, "ab")
    if page.locator("input[name=picked]:checked").count() == 0:
        expect(page.locator("input[name=difficulty]").first).to_be_disabled()  # first: which is real?
    page.get_by_label(f"{picked} is real").check()
    page.locator(f"input[name=difficulty][value='{difficulty}']").check()
    expect(submit).to_be_enabled()
    submit.click()


def first_page_played(browser, url: str):
    """A new participant in a fresh browser, on page 1 with every sound played."""
    context = browser.new_context(viewport={"width": 1000, "height": 900})
    page = context.new_page()
    page.goto(url)
    page.click("#start")
    expect(page.locator("#progress")).to_have_text("Page 1 of 2 · step 1 of 4")
    play_every_sound(page, "mushra")
    return context, page


def stored_ratings(results: Path, participant: str) -> dict[tuple[int, str], tuple]:
    rows = db_rows(results, "SELECT page, clip, rating, shown_position, play_count, comment FROM mushra_ratings "
                            f"WHERE participant = '{participant}'")
    return {(page, clip): (rating, position, plays, comment) for page, clip, rating, position, plays, comment in rows}


def test_a_participant_completes_the_whole_test(browser, server, shots):
    url = server.start()
    context = browser.new_context(viewport={"width": 1000, "height": 900})
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(url)
    expect(page.locator("#welcome")).to_be_visible()
    expect(page.locator("h1")).to_have_text("Ruler realism")
    shots(page, "01-welcome")
    page.click("#start")

    # Page 1: three sounds. Submitting waits until every sound has been played.
    expect(page.locator("#progress")).to_have_text("Page 1 of 2 · step 1 of 4")
    submit = page.locator("#mushra-submit")
    expect(submit).to_be_disabled()
    play_every_sound(page, "mushra")
    page.locator("#mushra button.play").first.click()  # a replay
    expect(page.locator("#mushra .plays").first).to_have_text("played 2 times")
    page1 = set_sliders(page, [0.85, 0.4, 0.05])
    third = page.locator("#mushra-clips li.clip").nth(2).locator("input.rating")
    third.focus()
    for _ in range(3):
        third.press("ArrowRight")  # the keyboard moves a slider by 0.01
    page1[2] = round(page1[2] + 0.03, 2)
    assert float(third.input_value()) == pytest.approx(page1[2])
    page.get_by_label("Comment on Sound 1").fill("sounds like a real ruler")
    expect(submit).to_be_enabled()
    shots(page, "02-mushra-page")
    submit.click()

    expect(page.locator("#progress")).to_have_text("Page 2 of 2 · step 2 of 4")
    play_every_sound(page, "mushra")
    page2 = set_sliders(page, [0.3, 0.7])
    submit.click()

    expect(page.locator("#progress")).to_have_text("Pair 1 of 2 · step 3 of 4")
    expect(page.locator("input[name=difficulty]").first).to_be_disabled()
    page.get_by_label("A is real").check()  # before playing: difficulty opens, submit stays shut
    expect(page.locator("input[name=difficulty]").first).to_be_enabled()
    shots(page, "03-ab-pair")
    answer_pair(page, "Pair 1 of 2 · step 3 of 4", "A", 4)
    answer_pair(page, "Pair 2 of 2 · step 4 of 4", "B", 2)

    expect(page.locator("#done")).to_be_visible()
    shots(page, "04-done")
    participant, plan = plan_of(server.results)
    expect(page.locator("#participant")).to_have_text(participant)

    # The database holds exactly what was given, by clip, position and play count.
    ratings = stored_ratings(server.results, participant)
    assert len(ratings) == 5
    for step, values in zip(plan["steps"][:2], (page1, page2)):
        for position, (shown, value) in enumerate(zip(step["clips"], values)):
            rating, stored_position, plays, comment = ratings[(step["page"], shown["clip"])]
            assert rating == pytest.approx(value) and stored_position == position
            assert plays == (2 if (step["page"], position) == (0, 0) else 1)
            assert comment == ("sounds like a real ruler" if (step["page"], position) == (0, 0) else "")
    answers = db_rows(server.results, "SELECT pair, model, picked_real, difficulty FROM ab_answers")
    expected = []
    for step, (picked, difficulty) in zip(plan["steps"][2:], [("A", 4), ("B", 2)]):
        real = step["clips"][0 if picked == "A" else 1]["clip"] in ("real1", "real2")
        label = "proposed" if step["pair"] == 0 else "anchor"
        expected.append((label, int(real), difficulty))
    assert sorted((m, p, d) for _, m, p, d in answers) == sorted(expected)
    assert errors == []
    context.close()
    assert server.stop() == 0  # SIGTERM stops the server cleanly


def test_killing_the_server_mid_session_loses_nothing_and_the_session_resumes(browser, server, shots):
    url = server.start()
    context, page = first_page_played(browser, url)
    page1 = set_sliders(page, [0.9, 0.5, 0.1])
    page.click("#mushra-submit")
    expect(page.locator("#progress")).to_have_text("Page 2 of 2 · step 2 of 4")
    play_every_sound(page, "mushra")
    page2 = set_sliders(page, [0.25, 0.75])  # set, not yet submitted: kept as a draft in the browser

    server.kill()
    participant, plan = plan_of(server.results)
    ratings = stored_ratings(server.results, participant)
    assert {key: value[0] for key, value in ratings.items()} == pytest.approx(
        {(0, shown["clip"]): value for shown, value in zip(plan["steps"][0]["clips"], page1)})

    # Submitting while the server is down: a clear message, nothing lost, the page stays.
    page.click("#mushra-submit")
    expect(page.locator("#status")).to_contain_text("cannot be reached")
    expect(page.locator("#progress")).to_have_text("Page 2 of 2 · step 2 of 4")
    shots(page, "05-server-down")

    assert server.start() == url  # the same address again, the same results file
    page.reload()
    expect(page.locator("#progress")).to_have_text("Page 2 of 2 · step 2 of 4")
    expect(page.locator("#status")).to_be_hidden()
    sliders = page.locator("#mushra-clips input.rating")
    assert [float(sliders.nth(i).input_value()) for i in range(2)] == pytest.approx(page2)
    expect(page.locator("#mushra .plays").first).to_have_text("played once")  # plays were stored too
    shots(page, "06-resumed")
    page.click("#mushra-submit")
    answer_pair(page, "Pair 1 of 2 · step 3 of 4", "A", 5)
    answer_pair(page, "Pair 2 of 2 · step 4 of 4", "A", 3)
    expect(page.locator("#done")).to_be_visible()

    assert db_rows(server.results, "SELECT COUNT(*) FROM participants") == [(1,)]
    ratings = stored_ratings(server.results, participant)
    assert len(ratings) == 5
    for step, values in zip(plan["steps"][:2], (page1, page2)):
        for shown, value in zip(step["clips"], values):
            assert ratings[(step["page"], shown["clip"])][0] == pytest.approx(value)
    assert db_rows(server.results, "SELECT COUNT(*) FROM ab_answers") == [(2,)]
    context.close()


def test_a_new_participant_at_the_same_computer_starts_afresh(browser, server, shots):
    url = server.start()
    context, page = first_page_played(browser, url)
    set_sliders(page, [0.9, 0.5])
    expect(page.locator("#mushra-submit")).to_be_disabled()  # Sound 3's slider was never set
    expect(page.locator("#mushra-hint")).to_have_text("Set the slider of Sound 3.")
    set_sliders(page, [0.9, 0.5, 0.0])  # 0 chosen on purpose is a rating
    expect(page.locator("#mushra-submit")).to_be_enabled()
    page.get_by_label("Comment on Sound 2").fill("first person's note")
    first, _ = plan_of(server.results)

    # The first participant walks away; the next one starts as new (after a confirmation).
    page.reload()  # what they left is still there for them...
    expect(page.locator("#mushra-clips input.rating").first).not_to_have_value("0")
    page.once("dialog", lambda dialog: dialog.accept())
    page.get_by_role("button", name="Start as a new participant").click()
    expect(page.locator("#progress")).to_have_text("Page 1 of 2 · step 1 of 4")
    expect(page.locator("#mushra .plays").first).to_have_text("not played yet")
    sliders = page.locator("#mushra-clips input.rating")
    assert [sliders.nth(i).input_value() for i in range(3)] == ["0", "0", "0"]  # ...but not for the next one
    expect(page.get_by_label("Comment on Sound 2")).to_have_value("")
    expect(page.locator("#mushra-hint")).to_contain_text("Play Sound 1, Sound 2, Sound 3 before submitting.")
    participants = [row[0] for row in db_rows(server.results, "SELECT id FROM participants ORDER BY rowid")]
    assert len(participants) == 2 and participants[0] == first
    context.close()
