"""One participant's way through a listening test: the plan, and the checks on every answer.

A plan is drawn when a participant starts (spec 4.1, 4.2): the clips of each MUSHRA
page in random order, then the A/B pairs in random order, each with the real
recording on a random side. Clips are known to the browser only by opaque handles,
so nothing on a page tells which clip is the recording or the anchor. The plan is
stored with the participant, so a session resumes exactly as it was drawn.

Every answer is checked here before anything is stored; a refusal carries the HTTP
status the server answers with and one line saying why.
"""

from __future__ import annotations

import hashlib
import json
import random
import secrets
from typing import Any

from ..checks import number_within, show_value
from ..webserver import Refused
from .config import ListeningTest
from .store import RATING_MAX, AnswerRefused, ResultsStore

MAX_COMMENT_CHARS = 2000
DIFFICULTY_LABELS = ("very difficult", "difficult", "neither", "easy", "very easy")  # 1..5


def fingerprint(test: ListeningTest, audio: dict[str, bytes]) -> str:
    """What a results file is tied to: the clip ids, pages and pairs, and the audio served."""
    shape = {"clips": list(test.clips), "pages": [list(p) for p in test.pages],
             "ab": [[p.real, p.synthetic, p.label] for p in test.ab_pairs],
             "audio": {clip: hashlib.sha256(audio[clip]).hexdigest() for clip in test.clips}}
    return hashlib.sha256(json.dumps(shape, sort_keys=True).encode()).hexdigest()


def pair_key(test: ListeningTest, pair_index: int) -> str:
    """How an A/B pair is named in the results file."""
    pair = test.ab_pairs[pair_index]
    return f"{pair.real}/{pair.synthetic}"


def make_plan(test: ListeningTest, rng: random.Random | None = None) -> dict[str, Any]:
    """A participant's random orders and sides, with a fresh handle for every clip shown."""
    rng = rng or random.SystemRandom()
    steps: list[dict[str, Any]] = []
    for page, clip_ids in enumerate(test.pages):
        order = list(clip_ids)
        rng.shuffle(order)
        steps.append({"kind": "mushra", "page": page,
                      "clips": [{"handle": secrets.token_urlsafe(9), "clip": c} for c in order]})
    pairs = list(range(len(test.ab_pairs)))
    rng.shuffle(pairs)
    for index in pairs:
        sides = [test.ab_pairs[index].real, test.ab_pairs[index].synthetic]
        rng.shuffle(sides)
        steps.append({"kind": "ab", "pair": index,
                      "clips": [{"handle": secrets.token_urlsafe(9), "clip": c} for c in sides]})
    return {"version": 1, "steps": steps}


class Session:
    """A participant's session: what to show next, and the checked answers."""

    def __init__(self, test: ListeningTest, store: ResultsStore, participant: str, plan: dict[str, Any]):
        self.test, self.store, self.participant = test, store, participant
        self.steps: list[dict[str, Any]] = plan["steps"]
        self._handles = {c["handle"]: (k, c["clip"]) for k, step in enumerate(self.steps) for c in step["clips"]}

    # -- where the participant is ---------------------------------------------------

    def _done(self) -> list[bool]:
        pages = self.store.answered_pages(self.participant)
        pairs = self.store.answered_pairs(self.participant)
        return [step["page"] in pages if step["kind"] == "mushra" else pair_key(self.test, step["pair"]) in pairs
                for step in self.steps]

    def current(self) -> int | None:
        """The first step not yet answered, or None when the test is finished."""
        return _first_open(self._done())

    def state(self) -> dict[str, Any]:
        """What the browser shows: progress and the current step, by handles only."""
        done = self._done()
        current = _first_open(done)
        shown = None
        if current is not None:
            step = self.steps[current]
            plays = self.store.play_counts(self.participant, current)
            kind_steps = [s for s in self.steps if s["kind"] == step["kind"]]
            shown = {"index": current, "kind": step["kind"],
                     "number": kind_steps.index(step) + 1, "of": len(kind_steps),
                     "clips": [{"handle": c["handle"], "label": label, "plays": plays.get(c["clip"], 0)}
                               for c, label in zip(step["clips"], _labels(step))]}
        return {"title": self.test.title, "participant": self.participant, "steps_total": len(self.steps),
                "steps_done": sum(done), "step": shown, "rating_max": RATING_MAX,
                "difficulty_labels": list(DIFFICULTY_LABELS)}

    # -- what the participant does --------------------------------------------------

    def clip_of(self, handle: str) -> str:
        """The clip id behind one of this participant's handles (404 for any other)."""
        if not isinstance(handle, str) or handle not in self._handles:
            raise Refused(404, f"no sound {str(handle)[:40]!r} in this session")
        return self._handles[handle][1]

    def play(self, handle: Any) -> int:
        """Count one play of a sound on the current step; returns its play count."""
        self.clip_of(handle)
        step, clip = self._handles[handle]
        if step != self.current():
            raise Refused(409, "that sound belongs to a step that is not the current one")
        return self.store.add_play(self.participant, step, clip)

    def answer(self, step_index: Any, payload: Any) -> None:
        """Check and store the answer to one step (a whole MUSHRA page, or one A/B pair)."""
        if not isinstance(step_index, int) or not 0 <= step_index < len(self.steps):
            raise Refused(404, f"no step {show_value(step_index)} in this session; steps are 0 to {len(self.steps) - 1}")
        done = self._done()
        current = _first_open(done)
        if done[step_index]:
            raise Refused(409, f"step {step_index} was already answered; answers cannot be changed")
        if step_index != current:
            raise Refused(409, f"step {step_index} is not the current one; answer step {current} first")
        if not isinstance(payload, dict):
            raise Refused(400, "the answer must be a JSON object")
        step = self.steps[step_index]
        plays = self.store.play_counts(self.participant, step_index)
        try:
            if step["kind"] == "mushra":
                self._answer_page(step, payload, plays)
            else:
                self._answer_pair(step, payload, plays)
        except AnswerRefused as exc:  # a replay racing its original
            raise Refused(409, str(exc)) from None

    @staticmethod
    def _unplayed(step: dict[str, Any], plays: dict[str, int]) -> None:
        missing = [label for label, c in zip(_labels(step), step["clips"]) if plays.get(c["clip"], 0) == 0]
        if missing:
            raise Refused(409, f"play every sound before answering; not played yet: {', '.join(missing)}")

    def _answer_page(self, step: dict[str, Any], payload: dict, plays: dict[str, int]) -> None:
        _only_keys(payload, {"ratings"})
        ratings = payload.get("ratings")
        on_page = {c["handle"]: (position, c["clip"]) for position, c in enumerate(step["clips"])}
        if not isinstance(ratings, list) or len(ratings) != len(on_page):
            raise Refused(422, f"ratings must list all {len(on_page)} sounds of the page, one entry each")
        answers, seen = [], set()
        for entry in ratings:
            if not isinstance(entry, dict):
                raise Refused(422, "each rating must be an object with handle, rating and comment")
            _only_keys(entry, {"handle", "rating", "comment"})
            handle = entry.get("handle")
            if not isinstance(handle, str) or handle not in on_page:
                raise Refused(422, f"handle {str(handle)[:40]!r} is not a sound of this page")
            if handle in seen:
                raise Refused(422, f"handle {show_value(handle)} is rated twice")
            seen.add(handle)
            rating = entry.get("rating")
            if not number_within(rating, 0.0, RATING_MAX):
                raise Refused(422, f"parameter rating = {_short(rating)} is out of range; allowed: 0 to "
                                   f"{RATING_MAX} (points)")
            comment = entry.get("comment", "")
            if not isinstance(comment, str) or len(comment) > MAX_COMMENT_CHARS or not _encodable(comment):
                raise Refused(422, f"parameter comment must be text of at most {MAX_COMMENT_CHARS} characters")
            position, clip = on_page[handle]
            answers.append({"clip": clip, "rating": float(rating), "shown_position": position,
                            "play_count": plays.get(clip, 0), "comment": comment.strip()})
        self._unplayed(step, plays)
        self.store.add_page(self.participant, step["page"], sorted(answers, key=lambda a: a["shown_position"]))

    def _answer_pair(self, step: dict[str, Any], payload: dict, plays: dict[str, int]) -> None:
        _only_keys(payload, {"picked", "difficulty"})
        picked = payload.get("picked")
        if picked not in ("A", "B"):
            raise Refused(422, f"parameter picked = {_short(picked)} is not allowed; allowed: 'A' or 'B'")
        difficulty = payload.get("difficulty")
        if isinstance(difficulty, bool) or not isinstance(difficulty, int) or not 1 <= difficulty <= 5:
            raise Refused(422, f"parameter difficulty = {_short(difficulty)} is out of range; allowed: 1 to 5 "
                               "(1 very difficult, 5 very easy)")
        self._unplayed(step, plays)
        pair = self.test.ab_pairs[step["pair"]]
        chosen = step["clips"][0 if picked == "A" else 1]["clip"]
        self.store.add_ab(self.participant, pair_key(self.test, step["pair"]), pair.label,
                          picked_real=chosen == pair.real, difficulty=difficulty)


def _first_open(done: list[bool]) -> int | None:
    """The first step not yet answered, or None."""
    return next((k for k, answered in enumerate(done) if not answered), None)


def _short(value: Any) -> str:
    """A value as it goes into a one-line message (long ones cut)."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _encodable(text: str) -> bool:
    """Text SQLite can store (JSON may carry lone surrogates, which UTF-8 cannot)."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _labels(step: dict[str, Any]) -> list[str]:
    """What the participant sees: "Sound 1".. in the order shown, or "A" and "B"."""
    if step["kind"] == "mushra":
        return [f"Sound {i + 1}" for i in range(len(step["clips"]))]
    return ["A", "B"]


def _only_keys(payload: dict, allowed: set[str]) -> None:
    unknown = sorted(set(payload) - allowed)
    if unknown:
        raise Refused(422, f"unknown field {show_value(unknown[0])}; allowed: {', '.join(sorted(allowed))}")
