"""The HTTP side of the dashboard's "Record & adapt" panel (:mod:`.adapt_flow`).

``GET /api/adapt`` is the panel's newest state (as the page's snapshots carry it) with the
whole adapt report once there is one.  ``POST /api/adapt/{op}`` with a JSON body asks for
``record`` (``{"name", "gestures"?, "trials"?, "perform"?}``), ``cancel``, ``use``,
``revert`` or ``reset``: ``202 {"ok": true, "message"}`` when it was queued for the
session thread, ``400 {"ok": false, "error"}`` (one line) when it cannot be done now.

The server's token and loopback-host guards cover these routes like every other.  Being
requests that change what the robot runs, they also refuse another site's page: a body
that is not ``application/json`` (which a cross-site form cannot send without the
browser asking first, and this server never allows) gets ``415``, a foreign ``Origin``
``403``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse

from wovenskin.errors import ConfigError
from wovenskin.recording.untrusted import loads_json

MAX_BODY_BYTES = 16_384


def add_adapt_routes(
    app: FastAPI, runner: Any, same_origin: Callable[[str | None, str | None], bool]
) -> None:
    """Add the panel's routes to ``app`` (``same_origin(origin, host)``: the server's check)."""

    @app.get("/api/adapt")
    async def adapt_state() -> JSONResponse:
        snapshot = runner.latest() or {}
        part = snapshot.get("adapt") or runner.adapt.part(runner, 0.0)
        return JSONResponse({**part, "report": runner.adapt.report})

    @app.post("/api/adapt/{op}")
    async def adapt_request(op: str, request: Request) -> JSONResponse:
        if not same_origin(request.headers.get("origin"), request.headers.get("host")):
            return _refused(403, "refused: a request from another site's page")
        kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
        if kind != "application/json":
            return _refused(415, "send the request as application/json")
        raw = await request.body()
        if len(raw) > MAX_BODY_BYTES:
            return _refused(413, "request too long")
        try:
            body = loads_json(raw or b"{}", "the request") if raw.strip() else {}
            if not isinstance(body, dict):
                raise ConfigError("the request must be a JSON object")
            message = runner.adapt.request(op, body, runner)
        except (ConfigError, ValueError) as exc:
            return _refused(400, " ".join(str(exc).split())[:300])
        return JSONResponse({"ok": True, "message": message}, status_code=202)


def _refused(status: int, line: str) -> JSONResponse:
    return JSONResponse({"ok": False, "error": line}, status_code=status)
