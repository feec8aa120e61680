"""``rigd doctor``: what a field engineer checks first, one :class:`Check` line each (docs/doctor.md)."""

from __future__ import annotations

from rigd.api.settings import load_settings as load_service_settings
from rigd.doctor.errors import DoctorError
from rigd.doctor.local import (
    camera_usb_check,
    data_dir_check,
    head_check,
    rig_file_check,
    sdk_check,
    versions_check,
)
from rigd.doctor.network import lidar_port_check, service_check
from rigd.doctor.records import Check, DoctorOptions, Status
from rigd.errors import RigdError

__all__ = ["Check", "DoctorError", "DoctorOptions", "Status", "run_checks"]


def run_checks(options: DoctorOptions) -> list[Check]:
    """Every check, in the order a field engineer works through them."""
    checks = [versions_check()]
    rig_check, rig = rig_file_check(options.config)
    checks.append(rig_check)
    try:
        service = load_service_settings(config=options.config)  # as rigd serve --config reads it
    except RigdError as exc:
        checks.append(Check("service settings", Status.FAIL, str(exc),
                            "correct the RIGD_* variables or the rig file's service: section (docs/service.md)"))
        service = None
    if service is not None:
        checks.append(data_dir_check(service.data_dir))
    checks += [lidar_port_check(rig, options.listen_s), camera_usb_check(rig), sdk_check(rig, options.sdk_library),
               head_check(rig, options.sdk_library)]
    if service is not None:
        checks.append(service_check(service.host, service.port, options.http_timeout_s))
    return checks
