"""``rigd doctor``'s service check against a real ``rigd serve`` on loopback: up, then down."""

from __future__ import annotations

import pytest
from api_helpers import Server, free_port

from rigd.doctor import Check, DoctorOptions, Status, run_checks
from rigd.doctor import network as doctor_network
from rigd.doctor.network import service_check
from rigd.version import software_version


def service_line(monkeypatch: pytest.MonkeyPatch, port: int, config: str) -> Check:
    """The service check of a whole doctor run, with the service address configured as rigd serve reads it."""
    monkeypatch.setenv("RIGD_PORT", str(port))
    monkeypatch.setenv("RIGD_CONFIG", str(config))
    checks = {c.name: c for c in run_checks(DoctorOptions(listen_s=0.1))}
    return checks["service"]


def test_service_up_then_down(tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    server = Server(tmp_path / "data").start()
    try:
        up = service_line(monkeypatch, server.port, server.env["RIGD_CONFIG"])
        assert up.status is Status.OK, up
        assert f"127.0.0.1:{server.port}/status: up, rigd {software_version()}" in up.detail
    finally:
        server.stop()
    down = service_line(monkeypatch, server.port, server.env["RIGD_CONFIG"])
    assert down.status is Status.WARN and "not reachable" in down.detail
    assert "systemctl start rigd" in down.fix


def test_a_service_on_another_address_is_not_contacted(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_contact(*args, **kwargs):
        raise AssertionError("doctor contacted a non-loopback address")

    monkeypatch.setattr(doctor_network.urllib.request, "urlopen", no_contact)
    check = service_check("192.0.2.10", 8000, timeout_s=1.0)
    assert check.status is Status.WARN and "not contacted" in check.detail


def test_something_else_on_the_service_port_fails(tmp_path) -> None:
    import http.server
    import threading

    class NotRigd(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 (http.server's name)
            self.send_response(200)
            self.end_headers()
            self.wfile.write(b"<html>a printer</html>")

        def log_message(self, *args) -> None:
            pass

    with http.server.HTTPServer(("127.0.0.1", free_port()), NotRigd) as httpd:
        thread = threading.Thread(target=httpd.serve_forever, daemon=True)
        thread.start()
        check = service_check("127.0.0.1", httpd.server_address[1], timeout_s=2.0)
        httpd.shutdown()
    assert check.status is Status.FAIL and "not JSON" in check.detail
