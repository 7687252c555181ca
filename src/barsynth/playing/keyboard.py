"""The computer keyboard as a two-octave keyboard for `barsynth play` when there is no MIDI input.

The layout of trackers and most soft synths: the bottom letter row plays C4 to B4 with the sharps
on the row above (``z s x d c v g b h n j m``), the top letter row C5 to C6 with the sharps on
the digit row (``q 2 w 3 e r 5 t 6 y 7 u i``). A terminal reports no key releases, so each key
plays a note on at a fixed velocity and its note off ``hold_s`` later. Escape (alone, not the
start of an arrow key's sequence) or Ctrl-D quits at once; Ctrl-C too (the terminal keeps
sending it as a signal). ``q`` is a note here, so it does not quit.

On a terminal, :class:`KeyboardInput` puts it in cbreak mode (keys arrive one by one, not
echoed; output and Ctrl-C work as usual) and restores its settings on every way out,
exceptions and Ctrl-C included; a status line on stderr shows the last note. When standard
input is not a terminal (a pipe, a file) it reads the same characters from it, and the end of
the input ends the playing once the last note has been released and rung on briefly.
"""

from __future__ import annotations

import os
import select
import sys
from typing import Any, TextIO

KEY_NOTES: dict[str, int] = {
    **dict(zip("zsxdcvgbhnjm", range(60, 72))),  # C4..B4
    **dict(zip("q2w3er5t6y7ui", range(72, 85))),  # C5..C6
}
"""Key -> MIDI note (60 = C4)."""
QUIT_KEYS = ("\x1b", "\x04")
"""Escape and Ctrl-D."""
NOTE_NAMES = ("C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B")
HELP = "keys z s x d c v g b h n j m = C4..B4, q 2 w 3 e r 5 t 6 y 7 u i = C5..C6; Escape quits"


def note_name(note: int) -> str:
    """``60`` -> ``'C4'``."""
    return f"{NOTE_NAMES[note % 12]}{note // 12 - 1}"


class KeyboardInput:
    """Keys from ``stream`` (standard input) as notes at ``velocity`` (1-127), each held ``hold_s`` seconds.

    Use it as a context manager (the terminal mode is set on entry and restored on exit), bind
    it to the renderer (:meth:`bind`), then call :meth:`poll` in the player's loop.
    """

    def __init__(self, stream: TextIO | None = None, *, velocity: int = 100, hold_s: float = 0.5,
                 status: TextIO | None = None):
        self.stream = stream if stream is not None else sys.stdin
        self.fd = self.stream.fileno()
        self.velocity = velocity
        self.hold_s = hold_s
        self.is_terminal = os.isatty(self.fd)
        self.status = status if status is not None else sys.stderr
        self.notes = 0
        self.last_sample = 0
        """The ring sample of the latest note off scheduled."""
        self._saved: Any = None
        self._renderer: Any = None
        self._hold_samples = 0

    def __enter__(self) -> KeyboardInput:
        if self.is_terminal:
            import termios
            import tty

            self._saved = termios.tcgetattr(self.fd)
            tty.setcbreak(self.fd, termios.TCSANOW)
        return self

    def __exit__(self, *exc: object) -> None:
        self.restore()

    def restore(self) -> None:
        """Put the terminal back as it was (idempotent)."""
        if self._saved is not None:
            import termios

            termios.tcsetattr(self.fd, termios.TCSADRAIN, self._saved)
            self._saved = None
            self.status.write("\r\033[K")
            self.status.flush()

    def bind(self, renderer: Any, sample_rate: float) -> None:
        """Send the notes to ``renderer`` (a :class:`~.live.Renderer`)."""
        self._renderer = renderer
        self._hold_samples = max(1, round(self.hold_s * sample_rate))

    def poll(self, timeout_s: float) -> str | None:
        """Wait up to ``timeout_s`` for keys and play them. Returns ``"quit"`` (a quit key),
        ``"end"`` (the input ended) or None (go on)."""
        ready, _, _ = select.select([self.fd], [], [], timeout_s)
        if not ready:
            return None
        data = os.read(self.fd, 64)
        if not data:
            return "end"
        return self.keys(data.decode("latin-1"))

    def keys(self, text: str) -> str | None:
        """Play the keys in ``text``; ``"quit"`` at a quit key."""
        for key in _without_sequences(text):
            if key in QUIT_KEYS:
                return "quit"
            note = KEY_NOTES.get(key.lower())
            if note is None or self._renderer is None:
                continue
            self._renderer.schedule("note_on", note, self.velocity)
            self.last_sample = self._renderer.schedule("note_off", note, delay_samples=self._hold_samples)
            self.notes += 1
            if self.is_terminal:
                self.status.write(f"\r\033[K{key} {note_name(note)} (note {note}, velocity {self.velocity}), "
                                  f"{self.notes} notes  [{HELP}]")
                self.status.flush()
        return None


def _without_sequences(text: str) -> str:
    """``text`` without the escape sequences of arrow and function keys (ESC [ or ESC O, then
    parameters, up to a final byte @ to ~) or of Alt with a key (ESC and the key), wherever in
    the read they come; an Escape that ends the read stays (the quit key)."""
    kept, i = [], 0
    while i < len(text):
        if text[i] == "\x1b" and i + 1 < len(text):
            j = i + 2
            if text[i + 1] in "[O":
                while j < len(text) and not "@" <= text[j] <= "~":
                    j += 1
                j += 1
            i = j
            continue
        kept.append(text[i])
        i += 1
    return "".join(kept)
