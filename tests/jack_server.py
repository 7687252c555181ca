"""A real JACK server for tests: Debian's ``jackd2`` with its dummy back end, run as an
ordinary process (no real-time scheduling, no sound card), plus a recording client.

conftest.py imports the fixtures, so a test just takes a ``jack_server`` argument. The fixture ``jack_daemon`` (module scope) starts ``jackd -n NAME --no-realtime
-d dummy -r 48000 -p 256`` under a unique NAME, points ``JACK_DEFAULT_SERVER`` at it (for
PortAudio and python-rtmidi, which take the server from the environment), re-initialises
PortAudio so that ``sounddevice`` lists the JACK host API, and on teardown closes its
clients, terminates PortAudio's JACK client, stops jackd by PID (SIGTERM, then SIGKILL)
and removes the server's files from /dev/shm. See docs/jack-notes.md for the pitfalls.

Timeouts here only guard against hangs (generous, for a loaded 2-core machine); no test
should assert how long anything took.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import stat
import subprocess
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

SAMPLE_RATE = 48000
"""The server's sample rate in Hz."""
BLOCK_FRAMES = 256
"""The server's period (block) in frames."""
READY_TIMEOUT_S = 60.0
"""Longest wait for the server to accept a client (a hang guard, not a measurement)."""
STOP_TIMEOUT_S = 10.0
"""Longest wait after SIGTERM before SIGKILL."""
SHM_DIR = Path("/dev/shm")


def _jack_module():
    """The ``jack`` package (JACK-Client), or a test failure naming what to install."""
    try:
        import jack
    except (ImportError, OSError) as error:  # OSError: libjack missing
        pytest.fail(f"the JACK tests need PyPI's JACK-Client and Debian's libjack-jackd2-0: {error}")
    return jack


def _quiet_jack(jack) -> None:
    """Silence libjack's error and info messages (failed connects while polling)."""
    jack.set_error_function(lambda message: None)
    jack.set_info_function(lambda message: None)


class Recorder:
    """A JACK client that records its audio input ports into a preallocated buffer.

    Each block lands at its JACK frame time, so a cycle the client missed leaves zeros
    rather than shifting later audio. MIDI events on its MIDI input ports are kept with
    their frame (from the start of the recording) in the same time line as the audio.

    Parameters
    ----------
    server_name : str
        The JACK server's name.
    name : str
        The client's name; ports are ``name:in_1`` ... and ``name:midi_in_1`` ...
    channels : int
        Number of audio input ports.
    midi_inputs : int
        Number of MIDI input ports.
    max_duration_s : float
        Capacity of the buffer in seconds.
    """

    def __init__(self, server_name: str, name: str = "recorder", channels: int = 1, midi_inputs: int = 0,
                 max_duration_s: float = 10.0):
        jack = _jack_module()
        self.client = jack.Client(name, no_start_server=True, servername=server_name)
        self.name = self.client.name
        self.sample_rate = self.client.samplerate
        self.inports = [self.client.inports.register(f"in_{i + 1}") for i in range(channels)]
        self.midi_inports = [self.client.midi_inports.register(f"midi_in_{i + 1}") for i in range(midi_inputs)]
        self._buffer = np.zeros((int(max_duration_s * self.sample_rate), channels), dtype=np.float32)
        self._midi: list[tuple[int, int, bytes]] = []
        self._start_frame: int | None = None
        self._end = 0  # frames written so far (relative to the start frame)
        self._armed = False
        self.missed_frames = 0
        self.client.set_process_callback(self._process)
        self.client.activate()

    def _process(self, frames: int) -> None:
        if not self._armed:
            return
        now = self.client.last_frame_time
        if self._start_frame is None:
            self._start_frame = now
        start = now - self._start_frame
        if start > self._end:
            self.missed_frames += start - self._end
        stop = min(start + frames, len(self._buffer))
        if stop <= start:
            self._armed = False
            return
        for channel, port in enumerate(self.inports):
            self._buffer[start:stop, channel] = port.get_array()[: stop - start]
        for index, port in enumerate(self.midi_inports):
            for offset, data in port.incoming_midi_events():
                self._midi.append((start + offset, index, bytes(data)))
        self._end = stop

    @property
    def port_names(self) -> list[str]:
        """The full names of the audio input ports."""
        return [port.name for port in self.inports]

    @property
    def midi_port_names(self) -> list[str]:
        """The full names of the MIDI input ports."""
        return [port.name for port in self.midi_inports]

    def start(self) -> None:
        """Clear the buffer and record from the next cycle on."""
        self._armed = False
        self._buffer[:] = 0.0
        self._midi.clear()
        self._start_frame = None
        self._end = 0
        self.missed_frames = 0
        self._armed = True

    def stop(self) -> None:
        """Stop recording (the recording stays)."""
        self._armed = False

    @property
    def frames(self) -> int:
        """Frames recorded so far."""
        return self._end

    def wait_frames(self, frames: int, timeout_s: float = READY_TIMEOUT_S) -> None:
        """Wait until at least ``frames`` frames are recorded (fails the test on a hang)."""
        frames = min(frames, len(self._buffer))
        deadline = time.monotonic() + timeout_s
        while self._end < frames:
            if time.monotonic() > deadline:
                pytest.fail(f"recorder {self.name}: {self._end} of {frames} frames after {timeout_s:g} s "
                            "(is the JACK server running?)")
            time.sleep(0.01)

    @property
    def audio(self) -> np.ndarray:
        """The recording, shape (frames, channels), float32 in [-1, 1] (a copy)."""
        return self._buffer[: self._end].copy()

    @property
    def midi_events(self) -> list[tuple[int, int, bytes]]:
        """MIDI events received: (frame from the recording's start, port index, message bytes)."""
        return list(self._midi)

    def close(self) -> None:
        """Deactivate and close the client."""
        self._armed = False
        with contextlib.suppress(Exception):
            self.client.deactivate()
        with contextlib.suppress(Exception):
            self.client.close()


@dataclass
class JackServer:
    """A running jackd (dummy back end) and helpers for tests.

    Attributes
    ----------
    name : str
        The server's name (``jackd -n``); ``JACK_DEFAULT_SERVER`` holds it while the fixture runs.
    process : subprocess.Popen
        The jackd process.
    sample_rate : int
        Hz.
    block_frames : int
        Frames per JACK period.
    log_path : Path
        jackd's stdout and stderr.
    """

    name: str
    process: subprocess.Popen
    sample_rate: int
    block_frames: int
    log_path: Path
    _clients: list = field(default_factory=list)
    _control: object = None

    @property
    def env(self) -> dict[str, str]:
        """An environment for subprocesses (e.g. ``barsynth play``) that talk to this server."""
        return {**os.environ, "JACK_DEFAULT_SERVER": self.name, "JACK_NO_START_SERVER": "1"}

    def client(self, name: str):
        """A new ``jack.Client`` on this server (closed at teardown)."""
        jack = _jack_module()
        made = jack.Client(name, no_start_server=True, servername=self.name)
        self._clients.append(made)
        return made

    @property
    def control(self):
        """A client the fixture keeps for connecting and listing ports."""
        if self._control is None:
            self._control = self.client("control")
            self._control.activate()
        return self._control

    def recorder(self, channels: int = 1, midi_inputs: int = 0, max_duration_s: float = 10.0,
                 name: str = "recorder") -> Recorder:
        """A new active :class:`Recorder` (closed at teardown)."""
        made = Recorder(self.name, name, channels, midi_inputs, max_duration_s)
        self._clients.append(made)
        return made

    def _check_no_python_callbacks(self) -> None:
        if any(isinstance(made, Recorder) for made in self._clients):
            pytest.fail("make python-rtmidi ports before any JACK client with a Python process callback "
                        "(Recorder, sounddevice stream): rtmidi holds the GIL while it waits for the server, "
                        "the server waits for the Python callback, and jackd stalls")

    def midi_out(self, name: str, port: str = "out"):
        """A python-rtmidi ``MidiOut`` on JACK with a virtual port ``name:port`` (closed at teardown).

        Make it before any recorder or sounddevice stream (see ``docs/jack-notes.md``)."""
        import rtmidi

        return self._midi_port(rtmidi.MidiOut, name, port)

    def midi_in(self, name: str, port: str = "in"):
        """A python-rtmidi ``MidiIn`` on JACK with a virtual port ``name:port`` (closed at teardown).

        Make it before any recorder or sounddevice stream (see ``docs/jack-notes.md``)."""
        import rtmidi

        return self._midi_port(rtmidi.MidiIn, name, port)

    def _midi_port(self, kind, name: str, port: str):
        import rtmidi

        self._check_no_python_callbacks()
        made = kind(rtmidi.API_UNIX_JACK, name=name)
        made.open_virtual_port(port)
        self._clients.append(made)
        return made

    def ports(self, pattern: str = "", **kwargs) -> list[str]:
        """Names of ports matching ``pattern`` (a regular expression; keywords as ``jack.Client.get_ports``)."""
        return [port.name for port in self.control.get_ports(pattern, **kwargs)]

    def wait_for_ports(self, pattern: str, count: int = 1, timeout_s: float = READY_TIMEOUT_S, **kwargs) -> list[str]:
        """Wait until ``count`` ports match ``pattern``; returns their names (fails the test on a hang)."""
        deadline = time.monotonic() + timeout_s
        while len(found := self.ports(pattern, **kwargs)) < count:
            if time.monotonic() > deadline:
                pytest.fail(f"JACK server {self.name}: no {count} ports match {pattern!r} after {timeout_s:g} s; "
                            f"ports: {self.ports()}")
            time.sleep(0.02)
        return found

    def connect(self, source: str, destination: str) -> None:
        """Connect an output port to an input port (by full name)."""
        self.control.connect(source, destination)

    def disconnect(self, source: str, destination: str) -> None:
        """Disconnect two ports (by full name)."""
        self.control.disconnect(source, destination)

    def has_client(self, name: str) -> bool:
        """Whether the server holds a client called ``name`` (a process that exited without closing
        its client leaves it behind; a synchronous server then stalls at the next graph change)."""
        jack = _jack_module()
        try:
            self.control.get_uuid_for_client_name(name)
        except jack.JackError:
            return False
        return True

    def log_problems(self) -> list[str]:
        """jackd's log lines that tell of a client it could not reach or a cycle it waited for."""
        self._log.flush()
        text = self.log_path.read_text(errors="replace")
        return [line for line in text.splitlines()
                if "SuspendRefNum error" in line or "ClientNotify fails" in line]

    def connections(self, port: str) -> list[str]:
        """Names of the ports connected to ``port``."""
        return [other.name for other in self.control.get_all_connections(port)]

    def close_clients(self) -> None:
        """Close every client and recorder the fixture made."""
        for made in reversed(self._clients):
            with contextlib.suppress(Exception):
                if isinstance(made, Recorder):
                    made.close()
                elif hasattr(made, "close_port"):  # python-rtmidi
                    made.close_port()
                    made.delete()
                else:
                    made.deactivate()
                    made.close()
        self._clients.clear()
        self._control = None


def _portaudio_reinitialise() -> None:
    """Make an imported ``sounddevice`` probe the host APIs again (it probes JACK only at initialisation)."""
    sd = sys.modules.get("sounddevice")
    if sd is None:
        return
    while sd._initialized > 0:
        sd._terminate()
    sd._initialize()


def _portaudio_terminate() -> None:
    """Close PortAudio's JACK client while the server still runs (else Pa_Terminate aborts the process at exit)."""
    sd = sys.modules.get("sounddevice")
    if sd is None:
        return
    while sd._initialized > 0:
        sd._terminate()


def _server_files(name: str) -> list[Path]:
    """This server's sockets and semaphores in /dev/shm (jackd2 names them after the server)."""
    return [path for path in SHM_DIR.glob("jack*") if f"_{name}_" in path.name]


def _shared_file(path: Path) -> bool:
    """jackd2's files that all servers share: the shared-memory registry and the metadata database."""
    return path.name == "jack-shm-registry" or path.name.startswith("jack_db-")


def _other_servers_running() -> bool:
    """Whether any JACK server's socket is left in /dev/shm."""
    return any(stat.S_ISSOCK(path.lstat().st_mode) for path in SHM_DIR.glob("jack_*") if path.exists())


def remove_shared_files() -> None:
    """Remove jackd2's shared files (the shared-memory registry, the metadata directory) when no
    server runs. libjack makes the metadata directory whenever a client opens, even one that finds
    no server: importing sounddevice (PortAudio probing JACK) is enough."""
    if _other_servers_running():
        return
    for path in SHM_DIR.glob("jack*"):
        if _shared_file(path):
            with contextlib.suppress(OSError):
                shutil.rmtree(path) if path.is_dir() else path.unlink()


def start_jack_server(log_path: Path, sample_rate: int = SAMPLE_RATE, block_frames: int = BLOCK_FRAMES,
                      sync: bool = True) -> JackServer:
    """Start jackd with the dummy back end under a unique name and wait until it accepts a client.

    Parameters
    ----------
    log_path : Path
        Where jackd's output goes.
    sample_rate : int
        Hz.
    block_frames : int
        Frames per period.
    sync : bool
        Synchronous mode (``jackd --sync``): each cycle waits for every client (up to the
        10 s client timeout), so a client that is late on a loaded machine delays the dummy
        clock instead of losing blocks, and recordings are sample-exact. Asynchronous mode
        (False) is how a real sound card behaves: a late client loses its block.
    """
    jackd = shutil.which("jackd")
    if jackd is None:
        pytest.fail("jackd not found: the live-audio tests need Debian's jackd2 "
                    "(apt-get install --no-install-recommends jackd2 libportaudio2)")
    jack = _jack_module()
    _quiet_jack(jack)
    name = f"barsynth-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    shm_before = {path.name for path in SHM_DIR.glob("jack*")} if SHM_DIR.is_dir() else set()
    log = open(log_path, "wb")  # noqa: SIM115 (closed by stop_jack_server)
    command = [jackd, "-n", name, "--no-realtime", *(["--sync"] if sync else []), "-t", "10000", "-d", "dummy",
               "-r", str(sample_rate), "-p", str(block_frames)]
    env = {**os.environ, "JACK_NO_START_SERVER": "1"}
    process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, env=env,
                               start_new_session=True)
    server = JackServer(name, process, sample_rate, block_frames, log_path)
    server._log = log
    server._shm_before = shm_before
    deadline = time.monotonic() + READY_TIMEOUT_S
    while True:
        if process.poll() is not None:
            log.flush()
            tail = log_path.read_text(errors="replace")[-2000:]
            stop_jack_server(server)
            pytest.fail(f"jackd exited with status {process.returncode}: {' '.join(command)}\n{tail}")
        try:
            probe = jack.Client("probe", no_start_server=True, servername=name)
        except jack.JackError:
            if time.monotonic() > deadline:
                stop_jack_server(server)
                pytest.fail(f"jackd {name} accepted no client within {READY_TIMEOUT_S:g} s; log: {log_path}")
            time.sleep(0.05)
            continue
        probe.close()
        break
    server._shm_ours = {path.name for path in SHM_DIR.glob("jack-*")} - shm_before
    return server


def stop_process(process: subprocess.Popen, timeout_s: float) -> None:
    """Stop ``process`` with SIGTERM (so that it closes its JACK clients), and SIGKILL only if it
    has not ended within ``timeout_s``."""
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def stop_jack_server(server: JackServer) -> None:
    """Close the fixture's clients, stop jackd by PID (SIGTERM, then SIGKILL) and remove its /dev/shm files."""
    server.close_clients()
    process = server.process
    stop_process(process, STOP_TIMEOUT_S)
    server._log.close()
    leftovers = _server_files(server.name)
    if process.returncode != 0:  # killed: its shared memory segments stay behind
        leftovers += [SHM_DIR / entry for entry in getattr(server, "_shm_ours", set())]
    for path in leftovers:
        with contextlib.suppress(OSError):
            path.unlink()


def _remove_shared_files_at_the_end(config) -> None:
    """Remove jackd2's shared files when the test session ends, not when a module's server stops:
    libjack maps the shared registry once per process and keeps it, so a registry removed and
    made anew by the next module's server would be one this process's clients no longer see
    (its probe fails with ``server_error`` and the new server's segments stay behind)."""
    if not getattr(config, "_barsynth_jack_cleanup", False):
        config._barsynth_jack_cleanup = True
        config.add_cleanup(remove_shared_files)


@pytest.fixture(scope="module")
def jack_daemon(tmp_path_factory, request):
    """A running JACK server (dummy back end, 48 kHz, 256-frame blocks, synchronous mode) for one test module.

    Yields a :class:`JackServer`. ``JACK_DEFAULT_SERVER`` names it and ``JACK_NO_START_SERVER``
    is set while the module runs; an imported ``sounddevice`` is re-initialised so that it
    lists the JACK host API (import ``sounddevice`` before asking for this fixture, or call
    ``sounddevice._terminate(); sounddevice._initialize()`` yourself). Tests use
    :func:`jack_server`, which also closes each test's clients.
    """
    _remove_shared_files_at_the_end(request.config)
    log_path = tmp_path_factory.mktemp("jackd") / "jackd.log"
    saved = {key: os.environ.get(key) for key in ("JACK_DEFAULT_SERVER", "JACK_NO_START_SERVER")}
    server = start_jack_server(log_path)
    os.environ["JACK_DEFAULT_SERVER"] = server.name
    os.environ["JACK_NO_START_SERVER"] = "1"
    try:
        _portaudio_reinitialise()
        yield server
    finally:
        server.close_clients()
        _portaudio_terminate()
        stop_jack_server(server)
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
        if "sounddevice" in sys.modules:
            sys.modules["sounddevice"]._initialize()


@pytest.fixture
def jack_server(jack_daemon):
    """The module's :class:`JackServer`; the clients a test makes through it are closed after the test,
    and the test fails if jackd stopped during it."""
    yield jack_daemon
    jack_daemon.close_clients()
    if jack_daemon.process.poll() is not None:
        pytest.fail(f"jackd {jack_daemon.name} exited with status {jack_daemon.process.returncode}; "
                    f"log: {jack_daemon.log_path}")


__all__ = ["BLOCK_FRAMES", "SAMPLE_RATE", "JackServer", "Recorder", "jack_daemon", "jack_server", "start_jack_server",
           "stop_jack_server"]
