"""Live source: a receive thread on the data and position UDP ports feeding a bounded queue of batches.

The thread only copies datagrams into (batch, 1206) arrays; decoding and sweep assembly run in the
thread that iterates :meth:`UdpReceiver.sweeps`. When that consumer falls behind and the queue is full,
whole batches are dropped and counted as overruns (never blocking the socket, which would make the
kernel drop silently instead).
"""

from __future__ import annotations

import errno
import os
import queue
import selectors
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from drivers.vlp16.datagrams import DatagramBatch, PositionDatagram, fault_entry
from drivers.vlp16.errors import ReceiverError
from drivers.vlp16.layout import DATA_PACKET_SIZE, POSITION_PACKET_SIZE
from drivers.vlp16.pcap import Ports
from drivers.vlp16.sweep import StreamStats, Sweep, SweepAssembler, Vlp16Config
from drivers.vlp16.validate import PacketFault


def udp_port_owner(port: int) -> str:
    """Who has UDP ``port`` bound: "pid N: command line" per process, from /proc (Linux; another user's
    processes are visible to root only), or how to find out."""
    inodes: set[str] = set()
    for table in ("/proc/net/udp", "/proc/net/udp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for fields in (line.split() for line in lines):
            if len(fields) > 9 and int(fields[1].rsplit(":", 1)[1], 16) == port:
                inodes.add(f"socket:[{fields[9]}]")
    hint = f"not visible to this user: `sudo ss -ulpn 'sport = :{port}'` names it"
    if not inodes:  # no /proc (not Linux), or the socket is gone already
        return hint
    owners = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            if any(os.readlink(fd) in inodes for fd in (proc / "fd").iterdir()):
                argv = (proc / "cmdline").read_bytes().split(b"\0")
                this = " (this process)" if proc.name == str(os.getpid()) else ""
                command = " ".join(a.decode("utf-8", "replace") for a in argv if a)
                owners.append(f"pid {proc.name}{this}: {command}"[:200])
        except OSError:  # gone meanwhile, or not ours to look at
            continue
    return "; ".join(owners) if owners else hint


class _BatchBuilder:
    """Datagrams received since the last hand-over; rows are written in place by recv_into."""

    def __init__(self, capacity: int) -> None:
        self.rows = np.empty((capacity, DATA_PACKET_SIZE + 1), dtype=np.uint8)  # +1 byte exposes oversize
        self.host_s = np.empty(capacity)
        self.index = np.empty(capacity, dtype=np.int64)
        self.count = 0
        self.positions: list[PositionDatagram] = []
        self.bad_size: list[int] = []
        self.started = 0.0

    @property
    def full(self) -> bool:
        return self.count == len(self.rows)

    def __len__(self) -> int:
        return self.count + len(self.positions) + len(self.bad_size)

    def take(self) -> DatagramBatch:
        n = self.count
        batch = DatagramBatch(
            self.rows[:n, :DATA_PACKET_SIZE].copy(),
            self.host_s[:n].copy(),
            self.index[:n].copy(),
            tuple(self.positions),
            fault_entry(PacketFault.SIZE, np.array(self.bad_size, np.int64)),
        )
        self.count, self.positions, self.bad_size = 0, [], []
        return batch


class UdpReceiver:
    """Receive VLP-16 UDP packets; use as a context manager and iterate :meth:`sweeps`.

    ``ports``: destination ports to bind (0 = let the OS choose; see :attr:`ports` after start).
    ``rcvbuf_bytes``: requested SO_RCVBUF (the kernel may cap it: see :attr:`rcvbuf_bytes`).
    """

    def __init__(
        self,
        config: Vlp16Config | None = None,
        host: str = "0.0.0.0",
        ports: Ports | None = None,
        rcvbuf_bytes: int = 8 << 20,
        queue_batches: int = 256,
        batch_packets: int = 64,
        batch_wait_s: float = 0.02,
    ) -> None:
        self.config = config or Vlp16Config()
        self.host = host
        self.ports = ports or Ports()
        self.requested_rcvbuf = rcvbuf_bytes
        self.rcvbuf_bytes = 0
        self.overruns = 0
        self._queue: queue.Queue[DatagramBatch] = queue.Queue(maxsize=queue_batches)
        self._batch_packets = batch_packets
        self._batch_wait_s = batch_wait_s
        self._assembler = SweepAssembler(self.config)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._sockets: list[socket.socket] = []
        self._datagrams = 0
        self._error: OSError | None = None  # what stopped the receive thread, if it failed

    # -- lifecycle -----------------------------------------------------------------------------------------
    def start(self) -> UdpReceiver:
        if self._thread is not None or self._stop.is_set():
            raise ReceiverError("UDP receiver: start() may be called once")
        data = self._bind(self.ports.data)
        position = self._bind(self.ports.position)
        self.ports = Ports(data.getsockname()[1], position.getsockname()[1])
        self._thread = threading.Thread(
            target=self._run, args=(data, position), name="vlp16-receiver", daemon=True
        )
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop the receive thread (within ``batch_wait_s``) and close the sockets; safe to call twice."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        for sock in self._sockets:
            sock.close()
        self._sockets.clear()

    def __enter__(self) -> UdpReceiver:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def stats(self) -> StreamStats:
        return self._assembler.stats(overruns=self.overruns)

    # -- consumer ------------------------------------------------------------------------------------------
    def sweeps(self, timeout_s: float, idle_s: float | None = None) -> Iterator[Sweep]:
        """Yield sweeps until ``timeout_s`` passes, the receiver is closed, or (if given) no datagram came
        for ``idle_s`` after the first one; then yield the pending partial sweep."""
        if self._thread is None:
            raise ReceiverError("UDP receiver: call start() (or use it as a context manager) first")
        deadline = time.monotonic() + timeout_s
        last_batch: float | None = None
        while (now := time.monotonic()) < deadline:
            try:
                batch = self._queue.get(timeout=min(0.05, deadline - now))
            except queue.Empty:
                if self._error is not None:
                    raise ReceiverError(f"UDP receiver: receiving failed ({self._error})") from self._error
                if self._stop.is_set() or (
                    idle_s is not None and last_batch is not None and time.monotonic() - last_batch >= idle_s
                ):
                    break
                continue
            last_batch = time.monotonic()
            yield from self._assembler.feed(batch)
        yield from self._assembler.flush()

    # -- receive thread ------------------------------------------------------------------------------------
    def _bind(self, port: int) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sockets.append(sock)
        # No SO_REUSEADDR (nor SO_REUSEPORT): on Linux it lets a second UDP socket bind the same port, and the
        # later one silently takes the sensor's packets from the first. A port has one receiver.
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, self.requested_rcvbuf)
            sock.bind((self.host, port))
        except OSError as exc:
            self.close()
            if exc.errno == errno.EADDRINUSE:
                raise ReceiverError(f"UDP receiver: port {port} is in use by another process "
                                    f"({udp_port_owner(port)}); stop it, or receive on another port") from exc
            raise ReceiverError(f"UDP receiver: cannot bind {self.host}:{port} ({exc.strerror})") from exc
        sock.setblocking(False)
        self.rcvbuf_bytes = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        return sock

    def _run(self, data: socket.socket, position: socket.socket) -> None:
        builder = _BatchBuilder(self._batch_packets)
        try:
            with selectors.DefaultSelector() as selector:
                selector.register(data, selectors.EVENT_READ, self._drain_data)
                selector.register(position, selectors.EVENT_READ, self._drain_position)
                while not self._stop.is_set():
                    for key, _ in selector.select(timeout=self._batch_wait_s):
                        key.data(key.fileobj, builder)
                    if len(builder) and (
                        builder.full or time.monotonic() - builder.started >= self._batch_wait_s
                    ):
                        self._hand_over(builder)
        except OSError as exc:
            self._error = exc  # reported by sweeps(); the thread ends
            self._stop.set()
        if len(builder):
            self._hand_over(builder)

    def _next_index(self, builder: _BatchBuilder) -> int:
        if not len(builder):
            builder.started = time.monotonic()
        self._datagrams += 1
        return self._datagrams - 1

    def _drain_data(self, sock: socket.socket, builder: _BatchBuilder) -> None:
        while not builder.full:
            row = builder.rows[builder.count]
            try:
                size = sock.recv_into(memoryview(row))
            except BlockingIOError:
                return
            index = self._next_index(builder)
            if size != DATA_PACKET_SIZE:
                builder.bad_size.append(index)
                continue
            builder.host_s[builder.count] = time.time()
            builder.index[builder.count] = index
            builder.count += 1

    def _drain_position(self, sock: socket.socket, builder: _BatchBuilder) -> None:
        while True:
            try:
                payload = sock.recv(POSITION_PACKET_SIZE + 1)
            except BlockingIOError:
                return
            index = self._next_index(builder)
            if len(payload) == POSITION_PACKET_SIZE:
                builder.positions.append(PositionDatagram(payload, time.time(), index))
            else:
                builder.bad_size.append(index)

    def _hand_over(self, builder: _BatchBuilder) -> None:
        datagrams = len(builder)
        try:
            self._queue.put_nowait(builder.take())
        except queue.Full:
            self.overruns += datagrams
