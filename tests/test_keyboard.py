"""The computer keyboard of `barsynth play` (barsynth.playing.keyboard): two octaves from C4, each key
a note on at the velocity and its note off after the hold; Escape and Ctrl-D quit, arrow keys and
other characters do nothing. (Played through JACK, from a pipe and a terminal: tests/test_play_jack.py.)"""

from __future__ import annotations

import io
import os

from barsynth.playing.keyboard import KEY_NOTES, KeyboardInput, note_name


class FakeRenderer:
    """Records what is scheduled; the consumer stands at sample 1000, the latency is 100 samples."""

    def __init__(self):
        self.calls = []

    def schedule(self, method, *args, delay_samples=0):
        self.calls.append((method, args, delay_samples))
        return 1000 + 100 + delay_samples


def _keyboard(**kwargs) -> tuple[KeyboardInput, FakeRenderer]:
    read_end, write_end = os.pipe()
    os.close(write_end)
    keyboard = KeyboardInput(os.fdopen(read_end), status=io.StringIO(), **kwargs)
    renderer = FakeRenderer()
    keyboard.bind(renderer, 48000)
    return keyboard, renderer


def test_two_octaves_from_c4_chromatic():
    assert [KEY_NOTES[k] for k in "zsxdcvgbhnjm"] == list(range(60, 72))
    assert [KEY_NOTES[k] for k in "q2w3er5t6y7ui"] == list(range(72, 85))
    assert (note_name(60), note_name(61), note_name(84), note_name(69)) == ("C4", "C#4", "C6", "A4")


def test_a_key_plays_a_note_on_and_its_note_off_after_the_hold():
    keyboard, renderer = _keyboard(velocity=87, hold_s=0.25)
    assert keyboard.keys("zI") is None  # (capitals too: caps lock)
    assert renderer.calls == [("note_on", (60, 87), 0), ("note_off", (60,), 12000),
                              ("note_on", (84, 87), 0), ("note_off", (84,), 12000)]
    assert keyboard.notes == 2 and keyboard.last_sample == 1000 + 100 + 12000


def test_escape_and_ctrl_d_quit_arrow_keys_and_other_characters_do_nothing():
    keyboard, renderer = _keyboard()
    assert keyboard.keys("\x1b[A") is None and keyboard.keys("\x1bOB") is None  # up, down
    assert keyboard.keys("p.,/ \n") is None and renderer.calls == []
    assert keyboard.keys("\x1b") == "quit"
    assert keyboard.keys("x\x04c") == "quit" and [c[1] for c in renderer.calls] == [(62, 100), (62,)]


def test_an_arrow_key_inside_a_read_is_skipped_and_an_escape_ending_it_quits():
    keyboard, renderer = _keyboard()
    assert keyboard.keys("z\x1b[Ax\x1b[1;5Cc") is None  # a note, up, a note, Ctrl-right, a note
    assert [c[1] for c in renderer.calls if c[0] == "note_on"] == [(60, 100), (62, 100), (64, 100)]
    assert keyboard.keys("v\x1b") == "quit"


def test_the_end_of_a_pipe_ends_the_input():
    keyboard, _ = _keyboard()
    with keyboard:
        assert not keyboard.is_terminal
        assert keyboard.poll(1.0) == "end"
