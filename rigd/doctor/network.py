"""Network checks. They contact nothing but loopback: the VLP-16 port is only listened on (nothing is sent), and
the service is asked for GET /status only when it listens on a loopback or wildcard address."""

from __future__ import annotations

import errno
import json
import socket
import time
import urllib.error
import urllib.request

from drivers.vlp16 import DATA_PACKET_SIZE
from rigd.capture.config import RigSettings
from rigd.capture.specs import LidarKind, parse_lidar
from rigd.doctor.records import Check, Status
from rigd.errors import RigdError
from rigd.version import software_version

_WILDCARD = {"0.0.0.0", "::", ""}
_LOOPBACK_NAMES = {"localhost", "127.0.0.1", "::1"}


def lidar_port_check(settings: RigSettings, listen_s: float) -> Check:
    """Bind the VLP-16 data port the rig file names and count what arrives in ``listen_s`` seconds."""
    name = "VLP-16 UDP port"
    try:
        spec = parse_lidar(settings.lidar_source)
    except RigdError as exc:
        return Check(name, Status.FAIL, str(exc), "correct lidar.source in the rig file (docs/configuration.md)")
    if spec.kind is not LidarKind.UDP:
        return Check(name, Status.OK, f"not used: lidar source is {settings.lidar_source}")
    where = f"{spec.host}:{spec.data_port}"
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.bind((spec.host, spec.data_port))
        except OSError as exc:
            busy = exc.errno == errno.EADDRINUSE
            fix = (f"stop what holds it (ss -ulpn 'sport = :{spec.data_port}'; a running rigd capture or serve "
                   "job does)" if busy else "correct lidar.source's address: it must be one of this computer's")
            return Check(name, Status.FAIL, f"cannot bind {where}: {exc.strerror}", fix)
        total, data = _count_datagrams(sock, listen_s)
    detail = f"{where} bound; {total} datagrams in {listen_s:g} s, {data} of them VLP-16 data packets"
    if data:
        return Check(name, Status.OK, detail)
    fix = ("no VLP-16 data packets: check the sensor's power and Ethernet cable, that this interface is on the "
           "sensor's subnet (deploy/network, default sensor 192.168.1.201) and that its destination port is "
           f"{spec.data_port} (its web page)")
    return Check(name, Status.WARN, detail, fix)


def _count_datagrams(sock: socket.socket, listen_s: float) -> tuple[int, int]:
    """(all datagrams, those of a data packet's size) received within ``listen_s`` seconds."""
    total = data = 0
    deadline = time.monotonic() + listen_s
    while (left := deadline - time.monotonic()) > 0:
        sock.settimeout(left)
        try:
            payload = sock.recv(2048)
        except TimeoutError:
            break
        total += 1
        data += len(payload) == DATA_PACKET_SIZE
    return total, data


def service_check(host: str, port: int, timeout_s: float) -> Check:
    """GET /status of ``rigd serve`` at its configured address, if that is on this computer's loopback."""
    name = "service"
    if host in _WILDCARD:
        host = "127.0.0.1"  # listening on every address includes loopback
    if host not in _LOOPBACK_NAMES and not host.startswith("127."):
        return Check(name, Status.WARN, f"configured to listen on {host}:{port}, not loopback: not contacted",
                     f"from a computer on that network: curl http://{host}:{port}/status")
    url = f"http://{'[::1]' if host == '::1' else host}:{port}/status"
    try:
        with urllib.request.urlopen(url, timeout=timeout_s) as reply:  # loopback only, see above
            body = json.loads(reply.read())
    except urllib.error.HTTPError as exc:
        return Check(name, Status.FAIL, f"GET {url}: HTTP {exc.code}", "see journalctl -u rigd")
    except (urllib.error.URLError, TimeoutError, ConnectionError) as exc:
        reason = getattr(exc, "reason", exc)
        return Check(name, Status.WARN, f"GET {url}: not reachable ({reason})",
                     "start it: systemctl start rigd (or rigd serve); needed only for the HTTP API")
    except json.JSONDecodeError:
        return Check(name, Status.FAIL, f"GET {url}: the reply is not JSON: another program holds port {port}",
                     "stop that program or give rigd another port (RIGD_PORT)")
    served = body.get("software_version", "?") if isinstance(body, dict) else "?"
    detail = f"GET {url}: up, rigd {served}"
    if served != software_version():
        return Check(name, Status.WARN, f"{detail}, but this is rigd {software_version()}",
                     "restart it after an upgrade: systemctl restart rigd")
    return Check(name, Status.OK, detail)
