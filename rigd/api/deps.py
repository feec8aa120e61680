"""FastAPI dependencies: the service, and the bearer token that mutating endpoints require."""

from __future__ import annotations

import hmac
from typing import Annotated

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from rigd.api.service import Service


def get_service(request: Request) -> Service:
    service: Service = request.app.state.service
    return service


ServiceDep = Annotated[Service, Depends(get_service)]

_bearer = HTTPBearer(auto_error=False, description="RIGD_TOKEN; required by mutating endpoints when configured")


def require_token(service: ServiceDep,
                  credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]) -> None:
    """Mutating endpoints: when the service has a token, the request must carry it (constant-time check)."""
    token = service.settings.token
    if token is None:
        return
    # The header as its bytes on the wire (Starlette decodes headers as latin-1); the token is ASCII.
    given = credentials.credentials.encode("latin-1") if credentials is not None else b""
    if not hmac.compare_digest(given, token.get_secret_value().encode()):
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "a valid bearer token is required",
                            headers={"WWW-Authenticate": "Bearer"})


Authorized = Depends(require_token)
