"""One page's live stream over a WebSocket: read its messages, send its blocks at its pace.

Three tasks share one :class:`~barsynth.studio.stream.Stream`:

- the reader takes every message as it comes. A ``played`` report only moves a counter,
  so it is handled at once, even while a new voice is being built; everything else goes,
  in order, to
- the commander, which carries out one command at a time (``set`` messages that arrive
  while one waits are merged into it, so a dragged slider never builds a queue, even for a
  model whose every change takes a new design). Work that takes long (building
  a voice for ``start``, trying a ``set`` on a fresh voice first, which also fills the
  models' design caches, planning a ``note_on``: its pitch search, a new Instrument for new
  settings) runs in a thread and outside the lock, so the sound goes on
  meanwhile; only the final swap or change takes the lock;
- the producer, which sends every block the page has room for, computing them together
  in one thread hop, and tells the page (once per voice) when its settings cost more
  than real time to play.
"""

from __future__ import annotations

import asyncio
import collections
import logging
import time
from typing import Any

from ..errors import BarsynthError
from ..exciters.sample import MAX_ATTACK_SAMPLES
from .stream import Stream, StreamError, parse_message

DATA_BYTES = 26 * MAX_ATTACK_SAMPLES
"""What a model's data rows may add to a message or a request: a recorded attack of up to
MAX_ATTACK_SAMPLES numbers, each at most 25 characters and a comma in JSON (500 KB)."""
MAX_MESSAGE_BYTES = 16 * 1024 + DATA_BYTES
IDLE_S = 120.0  # a stream that hears nothing from its page for this long is closed
SLOW_WINDOW_S = 0.25  # sound over which a stream's cost is compared with real time
MAX_QUEUED = 64  # commands waiting; a page that floods the stream beyond this is closed

log = logging.getLogger("barsynth.studio")


class SlowWatch:
    """Tells, once per voice, when computing a stream's blocks takes more than 90 % of real time
    (by the clock in the computing thread, so a machine too busy to keep up counts too)."""

    def __init__(self) -> None:
        self.spent = 0.0  # seconds spent computing over the window
        self.sound = 0.0  # seconds of sound over the window
        self.told: set[int] = set()

    def too_slow(self, spent_s: float, sound_s: float, voice: Any) -> bool:
        self.spent += spent_s
        self.sound += sound_s
        if self.sound < SLOW_WINDOW_S:
            return False
        slow = self.spent > 0.9 * self.sound and id(voice) not in self.told
        self.spent = self.sound = 0.0
        if slow:
            self.told.add(id(voice))
        return slow

    @staticmethod
    def message(model_name: str | None) -> str:
        return (f"these {model_name} settings take longer to compute than to play on this machine, so the "
                "sound will stutter; use fewer points or steps (points, oversampling) or render a WAV instead")


def _blocks(session: Stream, count: int) -> tuple[list[bytes], float]:
    """``count`` blocks and the time they took to compute (s)."""
    began = time.perf_counter()
    blocks = [session.next_block() for _ in range(count)]
    return blocks, time.perf_counter() - began


def _rehearse(session: Stream, values: dict) -> None:
    """Build a fresh voice with the changed settings (raises what the change would raise)."""
    model, voice = session.model, session.voice
    if model is None or voice is None:
        return
    model.voice(model.table.changed(voice.parameters, values), sample_rate=session.sample_rate)


async def play(socket: Any, session: Stream) -> None:
    """Serve one stream until the page goes away, falls silent for ``IDLE_S`` or floods it."""
    from starlette.websockets import WebSocketDisconnect

    busy, sending, wake, queued = asyncio.Lock(), asyncio.Lock(), asyncio.Event(), asyncio.Event()
    commands: collections.deque = collections.deque()

    async def send(text: dict | None = None, data: bytes | None = None) -> None:
        async with sending:
            if data is not None:
                await socket.send_bytes(data)
            else:
                await socket.send_json(text)

    async def produce() -> None:
        slow = SlowWatch()
        while True:
            wanted = session.blocks_wanted()
            if not wanted:
                wake.clear()
                if not session.blocks_wanted():
                    await wake.wait()
                continue
            async with busy:
                blocks, spent_s = await asyncio.to_thread(_blocks, session, wanted)
                refused = session.refused()
                if slow.too_slow(spent_s, wanted * session.block / session.sample_rate, session.voice):
                    refused.append(SlowWatch.message(session.model_name))
            for data in blocks:
                await send(data=data)
            for message in refused:
                await send({"type": "error", "error": message})

    async def command(message: dict[str, Any]) -> None:
        kind = message["type"]
        if kind == "start":
            model, resolved, rate = session.prepare_start(message)
            voice, gain = await asyncio.to_thread(Stream.build_voice, model, resolved, rate)
            async with busy:
                started = session.start(model, voice, gain, rate)
            await send(started)
            return
        if kind == "note_on":  # the note's pitch search and voices are built off the lock
            note = await asyncio.to_thread(session.plan_note, message)
            async with busy:
                session.play_note(note)
            return
        if kind == "set" and isinstance(message.get("parameters"), dict):
            if session.model is not None:
                session.model.table.validate(message["parameters"])
            await asyncio.to_thread(_rehearse, session, message["parameters"])
        async with busy:
            if kind == "set":
                await asyncio.to_thread(session.handle, message)
            else:
                session.handle(message)

    async def commander() -> None:
        while True:
            if not commands:
                queued.clear()
                await queued.wait()
                continue
            message = commands.popleft()
            try:
                await command(message)
            except BarsynthError as exc:
                await send({"type": "error", "error": str(exc)})
            except Exception as exc:  # a defect: say so, keep the stream going
                log.exception("studio stream: %s message failed", message.get("type"))
                await send({"type": "error", "error": f"the studio could not carry out this {message.get('type')} "
                                                      f"message ({type(exc).__name__}); it goes on as it was"})
            wake.set()

    def enqueue(message: dict[str, Any]) -> bool:
        """Queue a command; a ``set`` joins a ``set`` still waiting (its values merged, its id the
        newest), so a dragged slider never builds a queue. False when the page floods the stream."""
        if message["type"] == "set" and commands and commands[-1]["type"] == "set" \
                and isinstance(message.get("parameters"), dict) and isinstance(commands[-1].get("parameters"), dict):
            waiting = commands[-1]
            waiting["parameters"] = {**waiting["parameters"], **message["parameters"]}
            if "id" in message:
                waiting["id"] = message["id"]
            return True
        if len(commands) >= MAX_QUEUED:
            return False
        commands.append(message)
        queued.set()
        return True

    tasks = [asyncio.create_task(produce()), asyncio.create_task(commander())]
    try:
        while True:
            try:
                received = await asyncio.wait_for(socket.receive(), IDLE_S)
            except TimeoutError:
                await socket.close(code=1001, reason=f"no message for {IDLE_S:g} s; the stream is closed")
                break
            if received["type"] == "websocket.disconnect":
                break
            try:
                text = received.get("text")
                if text is None:
                    raise StreamError("stream messages are JSON text; binary frames are not taken")
                if len(text.encode()) > MAX_MESSAGE_BYTES:
                    raise StreamError(f"a stream message is too large; allowed: up to {MAX_MESSAGE_BYTES} bytes")
                message = parse_message(text)
                if message["type"] == "played":
                    session.handle(message)
                elif not enqueue(message):
                    await socket.close(code=1008, reason=f"more than {MAX_QUEUED} messages waiting; the stream "
                                                         "is closed")
                    break
            except BarsynthError as exc:
                await send({"type": "error", "error": str(exc)})
            except (WebSocketDisconnect, RuntimeError):
                raise
            except Exception as exc:  # a defect: say so, keep reading
                log.exception("studio stream: a message failed")
                await send({"type": "error", "error": f"the studio could not read this message "
                                                      f"({type(exc).__name__}); the stream goes on as it was"})
            wake.set()
    except (WebSocketDisconnect, RuntimeError):
        pass  # the page went away mid-send
    finally:
        for task in tasks:
            task.cancel()
        for task in tasks:
            try:
                await task
            except (asyncio.CancelledError, WebSocketDisconnect, RuntimeError, OSError):
                pass
