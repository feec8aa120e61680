"""Settings of ``rigd serve`` (pydantic-settings): arguments > ``RIGD_*`` environment > the ``service:``
section of the rig file (``RIGD_CONFIG``) > defaults. The rest of the rig file (sensor sources, initial guess,
capture defaults) is read by :func:`rigd.capture.config.load_settings`, as ``rigd capture`` reads it."""

from __future__ import annotations

import ipaddress
import os
from pathlib import Path
from typing import Any

from pydantic import Field, SecretStr, ValidationError
from pydantic_settings import BaseSettings, InitSettingsSource, PydanticBaseSettingsSource, SettingsConfigDict

from rigd.dataset.store import read_yaml_mapping
from rigd.errors import RigdError

MIN_TOKEN_LENGTH = 16


class Settings(BaseSettings):
    model_config = SettingsConfigDict(env_prefix="RIGD_", extra="forbid")

    data_dir: Path = Field(Path("rigd-data"), description="datasets, the database and job outputs")
    config: Path | None = Field(None, description="the rig file (/etc/rigd/rig.yaml): sources, initial guess")
    host: str = Field("127.0.0.1", description="listen address; other than loopback it needs a token")
    port: int = Field(8000, ge=0, le=65535, description="listen port")
    token: SecretStr | None = Field(None, description=f"bearer token for mutating requests ({MIN_TOKEN_LENGTH} or more "
                                    "printable ASCII characters, never empty); required to listen on a "
                                    "non-loopback address")
    auto_activate_require_converged: bool = Field(True, description="auto_activate only a converged calibration")
    auto_activate_min_pairs: int = Field(6, ge=1, description="auto_activate needs at least this many pairs")
    auto_activate_max_rotation_deg: float = Field(
        5.0, gt=0, description="auto_activate only if the rotation moved at most this far from the active version")
    auto_activate_max_translation_cm: float = Field(
        10.0, gt=0, description="auto_activate only if the translation moved at most this far from the active version")
    sensor_poll_s: float = Field(10.0, ge=1.0, description="seconds between sensor checks for GET /status")
    max_body_bytes: int = Field(65536, ge=1024, description="largest request body accepted")
    body_timeout_s: float = Field(10.0, gt=0, le=600, description="seconds a request body may take to arrive; "
                                  "slower ones get 408")
    header_timeout_s: float = Field(10.0, gt=0, le=600, description="seconds a request line and its headers may "
                                    "take to arrive (from the connection's start or its previous response); "
                                    "slower ones get 408")
    max_connections: int = Field(4096, ge=16, le=1_000_000, description="open client connections; beyond it a "
                                 "new one closes the oldest still waiting for its headers (lowered to fit the "
                                 "open-file limit)")
    max_queued_jobs: int = Field(4, ge=1, le=1000, description="calibrations that may wait behind the running "
                                 "one; more get 429")
    min_free_mb: float = Field(64.0, ge=0, le=1e9, description="MB the data directory's file system must have "
                               "free for a capture, calibration or check to start (less: 507, nothing queued)")
    workers: int = Field(2, ge=1, le=64, description="processes a calibration job works in (its pairs' edges and "
                         "independent solves side by side; 1: the least memory and no process start-ups)")
    log_level: str = Field("info", description="uvicorn log level")

    @classmethod
    def settings_customise_sources(
        cls,
        settings_cls: type[BaseSettings],
        init_settings: PydanticBaseSettingsSource,
        env_settings: PydanticBaseSettingsSource,
        dotenv_settings: PydanticBaseSettingsSource,
        file_secret_settings: PydanticBaseSettingsSource,
    ) -> tuple[PydanticBaseSettingsSource, ...]:
        init_kwargs = getattr(init_settings, "init_kwargs", {})
        config = init_kwargs.get("config") or os.environ.get("RIGD_CONFIG")
        section = service_section(Path(config)) if config else {}
        return init_settings, env_settings, InitSettingsSource(settings_cls, init_kwargs=section)


def service_section(config: Path) -> dict[str, Any]:
    section = read_yaml_mapping(config).get("service") or {}
    if not isinstance(section, dict):
        raise RigdError(f"{config}: 'service' must be a mapping of settings, got {section!r}")
    if "token" in section and section["token"] is None:  # "token:" with no value: empty, not absent
        section = {**section, "token": ""}
    return section


def load_settings(**overrides: Any) -> Settings:
    """Settings from all sources; bad values raise RigdError naming the setting."""
    try:
        return Settings(**{k: v for k, v in overrides.items() if v is not None})
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in exc.errors())
        raise RigdError(f"bad rigd serve settings: {problems}") from exc


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def token_problem(token: str) -> str | None:
    """Why ``token`` cannot be the API token, or None when it can."""
    if not token.strip():
        # An empty RIGD_TOKEN= (a placeholder left in rigd.env) must never read as "no token".
        return "is empty; set a secret of at least 16 characters, or remove the setting to run without one"
    if token != token.strip():
        return "has leading or trailing white space, which HTTP strips from the Authorization header"
    if len(token) < MIN_TOKEN_LENGTH:
        return f"must have at least {MIN_TOKEN_LENGTH} characters"
    if not (token.isascii() and token.isprintable()):
        # Clients send headers as UTF-8 or latin-1 at their whim; only printable ASCII is the same bytes in both.
        return "must be printable ASCII (letters, digits, punctuation, spaces), as HTTP headers carry it"
    return None


def check_exposure(settings: Settings) -> None:
    """Refuse a non-loopback listen address without a token, and a token clients cannot send anywhere."""
    token = settings.token.get_secret_value() if settings.token is not None else None
    problem = token_problem(token) if token is not None else None
    if problem is not None:
        raise RigdError(f"the API token (RIGD_TOKEN) {problem}")
    if token is None and not is_loopback(settings.host):
        raise RigdError(f"refusing to listen on {settings.host} without an API token: set RIGD_TOKEN (e.g. in "
                        "/etc/rigd/rigd.env) or listen on 127.0.0.1")
