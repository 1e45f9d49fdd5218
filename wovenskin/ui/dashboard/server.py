"""The dashboard's web server: the page, its static files and one WebSocket per browser.

:func:`create_app` builds the FastAPI app around a :class:`~.runner.DashboardRunner`:
``GET /`` is the page, ``/static`` its scripts (three.js is vendored in the package: the
page never loads anything from the internet), ``/ws`` the WebSocket.  On the socket the
server first sends the scene (``{"type": "scene"}``), then the runner's newest state at the
page rate (latest only: a slow browser skips frames, the session never waits for it).  The
browser sends ``{"type": "command", "cmd": ...}`` and ``{"type": "touch", "t": seconds,
"touches": [{"id", "x_mm", "y_mm", "force_n"}, ...]}`` (or several such ``samples`` at
once), ``{"type": "key"}`` and ``{"type": "pendant"}`` for the page's keyboard and
teach pendant (:func:`.teleop.handle_input`) and ``{"type": "hold"}`` heartbeats; the
simulated skin plays timestamped touches at their own spacing, so a bunched
delivery does not distort a gesture.  A bad message gets one ``{"type": "error"}`` line
back and changes nothing.

Bound to a loopback address the server is open to this machine's users; bound elsewhere it
requires a token (``?token=`` on the page's address, then a cookie), compared in constant
time, on every request and socket.  Sockets opened by another site's page (a foreign
``Origin``) are refused either way.  Without a token, every request and socket must name
this machine by a loopback name in its ``Host`` (``localhost``, ``127.0.0.1``, ``[::1]``;
:func:`loopback_host`), and a socket's ``Origin`` must be that same address: a page served
from another name that resolves to 127.0.0.1 (DNS rebinding) gets ``403`` and its socket
is closed with ``4403`` before it is accepted.

Every socket message is handled without ever dropping the connection: a binary frame,
JSON nested past 64 levels, a touch id or time that is not a finite number, anything a
message could hold gets one ``{"type": "error"}`` reply.

Virtual fingers never outlive the page that put them down: a page whose socket closes
while its fingertips are on the virtual skin has them lifted (a lift-off: the command
ends), and so has a page that sends nothing for :data:`TOUCH_SILENCE_S` while they are
down (the page repeats resting fingers every 0.25 s: a hold-to-run heartbeat).  One page
draws at a time (:class:`~.page_touch.PageTouch`): the others' touches are refused until its fingers
lift.  Keys and jog buttons follow the same rule: a page that holds one and sends nothing
for :data:`TOUCH_SILENCE_S` has it released (the page sends a ``hold`` heartbeat every
0.25 s while one is held).  :func:`serve` runs uvicorn until Ctrl-C.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import json
import math
import secrets
import threading
import time
from collections.abc import Callable
from importlib import resources
from pathlib import Path

from fastapi import FastAPI, Request, WebSocket, WebSocketDisconnect
from fastapi.responses import HTMLResponse, JSONResponse, PlainTextResponse
from fastapi.staticfiles import StaticFiles

from wovenskin.recording.untrusted import loads_json
from wovenskin.ui.dashboard.adapt_api import add_adapt_routes
from wovenskin.ui.dashboard.page_touch import PageTouch, parse_touch_message
from wovenskin.ui.dashboard.runner import DashboardRunner
from wovenskin.ui.dashboard.teleop import PageHold, handle_input

LOOPBACK = ("127.0.0.1", "localhost", "::1")
COOKIE = "wovenskin_token"
MAX_MESSAGE_BYTES = 16_384
TOUCH_SILENCE_S = 1.0  # a page with fingers down sends at least every 0.25 s (its heartbeat)
TOUCH_SILENCE_MESSAGE = "virtual fingers lifted: the page stopped sending while touching"
HOLD_SILENCE_MESSAGE = "keys and jog button released: the page stopped sending while holding"


def static_dir() -> Path:
    return Path(str(resources.files("wovenskin.ui.dashboard").joinpath("static")))


def needs_token(host: str) -> bool:
    return host not in LOOPBACK


def new_token() -> str:
    return secrets.token_urlsafe(18)


def _token_ok(expected: str | None, given: str | None) -> bool:
    if expected is None:
        return True
    return given is not None and hmac.compare_digest(expected.encode(), given.encode())


def same_origin(origin: str | None, host: str | None) -> bool:
    """Whether a WebSocket comes from our own page (or from a client that is no browser).

    Browsers let any site open a WebSocket to 127.0.0.1 and send its ``Origin``: without
    this check a web page open in the same browser could drive the robot."""
    if origin is None:
        return True
    from urllib.parse import urlsplit

    return host is not None and urlsplit(origin).netloc.lower() == host.lower()


LOOPBACK_NAMES_TEXT = "localhost, 127.0.0.1 or [::1]"


def loopback_host(host: str | None) -> bool:
    """Whether a ``Host`` header (``name[:port]``) names this machine's loopback interface:
    ``localhost`` or a loopback IP address.  Any other name may be an attacker's domain
    re-pointed at 127.0.0.1 (DNS rebinding), so a server without a token refuses it."""
    import ipaddress
    from urllib.parse import urlsplit

    if not host:
        return False
    try:
        name = urlsplit(f"//{host.strip()}").hostname
    except ValueError:
        return False
    if name is None:
        return False
    if name == "localhost":
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


class LoopbackHostGuard:
    """ASGI middleware: without a token, only requests and sockets whose ``Host`` is a
    loopback name (:func:`loopback_host`) reach the app; others get ``403`` (HTTP) or are
    closed with ``4403`` before the WebSocket is accepted."""

    def __init__(self, app, enabled: bool = True) -> None:
        self.app = app
        self.enabled = enabled

    async def __call__(self, scope, receive, send) -> None:
        if not self.enabled or scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        host = headers.get(b"host", b"").decode("latin-1")
        if loopback_host(host):
            await self.app(scope, receive, send)
            return
        if scope["type"] == "websocket":
            await send({"type": "websocket.close", "code": 4403, "reason": "Host refused"})
            return
        text = (
            f"refused: Host {host[:80]!r} is not a loopback name; this dashboard answers only "
            f"{LOOPBACK_NAMES_TEXT} (protection against DNS rebinding)"
        )
        await PlainTextResponse(text, status_code=403)(scope, receive, send)


def lan_addresses() -> list[str]:
    """This machine's IPv4 addresses on its networks (no loopback), for a tablet to use.

    From the host name's addresses and from the source address the system would route
    private networks through (a UDP ``connect`` sends nothing); empty when offline."""
    import socket

    found: set[str] = set()
    with contextlib.suppress(OSError):
        for info in socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET):
            found.add(str(info[4][0]))
    for probe in ("10.255.255.255", "172.31.255.255", "192.168.255.255"):
        with contextlib.suppress(OSError), socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
            udp.connect((probe, 9))
            found.add(str(udp.getsockname()[0]))
    return sorted(a for a in found if not a.startswith(("127.", "0.")))


def other_device_urls(url: str, host: str) -> list[str]:
    """The page's address as other devices reach it, when ``host`` binds every address."""
    if host not in ("0.0.0.0", "::"):
        return []
    from urllib.parse import urlsplit, urlunsplit

    parts = urlsplit(url)
    return [urlunsplit(parts._replace(netloc=f"{ip}:{parts.port}")) for ip in lan_addresses()]


def create_app(runner: DashboardRunner, token: str | None = None) -> FastAPI:
    """The app serving ``runner``; ``token`` (None: no check) guards every request."""
    app = FastAPI(title="wovenskin dashboard", docs_url=None, redoc_url=None, openapi_url=None)
    page = (static_dir() / "index.html").read_text(encoding="utf-8")
    virtual_skin: dict = {"holder": None}  # the page whose fingers are down (PageTouch)

    @app.middleware("http")
    async def check_token(request: Request, call_next):
        given = request.query_params.get("token") or request.cookies.get(COOKIE)
        if not _token_ok(token, given):
            return PlainTextResponse(
                "a token is required: open the address printed at start", status_code=401
            )
        response = await call_next(request)
        if token is not None and request.query_params.get("token"):
            response.set_cookie(COOKIE, token, httponly=True, samesite="strict")
        return response

    # outermost: a foreign Host never reaches the token check or the app (DNS rebinding)
    app.add_middleware(LoopbackHostGuard, enabled=token is None)

    @app.get("/", response_class=HTMLResponse)
    async def index() -> str:
        return page

    @app.get("/api/state")
    async def state() -> JSONResponse:
        return JSONResponse(runner.latest() or {"type": "state", "seq": 0})

    add_adapt_routes(app, runner, same_origin)  # the "Record & adapt" panel (adapt_api.py)
    app.mount("/static", StaticFiles(directory=static_dir()), name="static")

    @app.websocket("/ws")
    async def socket(ws: WebSocket) -> None:
        given = ws.query_params.get("token") or ws.cookies.get(COOKIE)
        if not _token_ok(token, given):
            await ws.close(code=4401)
            return
        if not same_origin(ws.headers.get("origin"), ws.headers.get("host")):
            await ws.close(code=4403)  # another site's page in the user's browser
            return
        await ws.accept()
        replies: asyncio.Queue[str] = asyncio.Queue(maxsize=64)
        sender = asyncio.create_task(_send_states(ws, runner, replies))
        touch = PageTouch(virtual_skin)  # this page's fingertips on the virtual skin
        hold = PageHold()  # this page's held keys and jog button
        try:
            while True:
                if touch.down or hold.held:  # hold-to-run: a page holding keeps talking
                    try:
                        text = await asyncio.wait_for(_receive(ws), TOUCH_SILENCE_S)
                    except TimeoutError:
                        if touch.down:
                            runner.touch({})
                            touch.set_down(False)
                            runner.note(TOUCH_SILENCE_MESSAGE)
                        if hold.held:
                            _release(runner, hold)
                            runner.note(HOLD_SILENCE_MESSAGE)
                        continue
                else:
                    text = await _receive(ws)
                reply = _handle(runner, text, touch, hold)
                if reply is not None and not replies.full():
                    replies.put_nowait(json.dumps(reply))
        except WebSocketDisconnect:
            pass
        finally:
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await sender
            if touch.down:  # a page that went away cannot lift its fingers: lift them
                touch.set_down(False)
                with contextlib.suppress(Exception):
                    runner.touch({})
            with contextlib.suppress(Exception):
                _release(runner, hold)

    return app


async def _receive(ws: WebSocket) -> str | bytes:
    """The next frame's text, or its bytes for a binary frame (answered with an error);
    ``WebSocketDisconnect`` when the page went away."""
    message = await ws.receive()
    if message["type"] == "websocket.disconnect":
        raise WebSocketDisconnect(message.get("code", 1000))
    text = message.get("text")
    return text if isinstance(text, str) else bytes(message.get("bytes") or b"")


async def _send_states(ws: WebSocket, runner: DashboardRunner, replies: asyncio.Queue) -> None:
    """The scene, then the newest state at the page rate (never one twice, none queued),
    and the replies to the browser's messages; the one task that writes to ``ws``."""
    await ws.send_text(json.dumps(runner.describe()))
    sent = -1
    scene_key = runner.scene_key
    poll = 0.5 / runner.ui_rate_hz  # twice per page frame: no state waits a whole period
    while True:
        while not replies.empty():
            await ws.send_text(replies.get_nowait())
        snapshot = runner.latest()
        if snapshot is not None and snapshot["seq"] != sent:
            if runner.scene_key != scene_key:  # another robot or task: the page needs shapes
                scene_key = runner.scene_key
                await ws.send_text(json.dumps(runner.describe()))
            sent = snapshot["seq"]
            await ws.send_text(json.dumps(snapshot, allow_nan=False))
        await asyncio.sleep(poll)


def _release(runner: DashboardRunner, hold: PageHold) -> None:
    """Lift whatever keys and jog button ``hold`` (one page's) keeps down."""
    if hold.keys:
        handle_input(runner.inputs, {"type": "key", "release_all": True}, hold)
    if hold.jog:
        handle_input(runner.inputs, {"type": "pendant", "op": "release"}, hold)


def _handle(
    runner: DashboardRunner,
    text: str | bytes,
    page: PageTouch | None = None,
    hold: PageHold | None = None,
) -> dict | None:
    """Carry out one browser message; returns an error reply or None, never raises (a bad
    message must not drop the page's connection).  ``page`` (None: no bookkeeping) keeps
    whether this page's last touch sample had fingertips down."""
    if isinstance(text, bytes):
        return {"type": "error", "message": "binary frames are not understood: send JSON text"}
    if len(text) > MAX_MESSAGE_BYTES:
        return {"type": "error", "message": "message too long"}
    try:
        return _carry_out(runner, text, page, hold if hold is not None else PageHold())
    except (ValueError, TypeError) as exc:
        return {"type": "error", "message": " ".join(str(exc).split())[:200]}
    except Exception as exc:  # noqa: BLE001 - whatever it was, the page keeps its socket
        return {"type": "error", "message": f"message not handled ({type(exc).__name__})"}


def _carry_out(
    runner: DashboardRunner, text: str, page: PageTouch | None, hold: PageHold
) -> dict | None:
    """One message's effect (see :func:`_handle`); ValueError/TypeError for bad ones."""
    message = loads_json(text, "the message")
    if not isinstance(message, dict):
        raise ValueError("a message must be a JSON object")
    kind = message.get("type")
    if kind == "touch":  # {"touches": [...], "t": s} or {"samples": [{"t", "touches"}]}
        samples = parse_touch_message(message)
        if page is not None and not page.may_touch():
            raise ValueError("another page is drawing on the virtual skin: wait for its lift")
        for client_t, touches in samples:
            runner.touch(touches, client_t)
            if page is not None:
                page.set_down(bool(touches))
    elif kind == "command":
        runner.submit({k: v for k, v in message.items() if k != "type"})
    elif kind in ("key", "pendant"):
        handle_input(runner.inputs, message, hold)
    elif kind == "hold":  # the heartbeat of a page holding a key or jog button
        pass
    elif kind == "ping":
        t = message.get("t")
        finite = isinstance(t, int | float) and not isinstance(t, bool) and math.isfinite(t)
        return {"type": "pong", "t": t if finite else None}
    else:
        raise ValueError(f"unknown message type {str(kind)[:40]!r}")
    return None


def serve(
    runner: DashboardRunner,
    host: str = "127.0.0.1",
    port: int = 8000,
    token: str | None = None,
    on_ready: Callable[[str], None] | None = None,
    seconds: float | None = None,
) -> None:
    """Start ``runner``, serve the page until Ctrl-C (or ``seconds`` pass), then stop and
    close everything.  ``token`` is required when ``host`` is not loopback (one is made
    when not given); ``on_ready(url)`` is called once the socket listens."""
    import uvicorn

    if needs_token(host) and token is None:
        token = new_token()
    app = create_app(runner, token)
    config = uvicorn.Config(app, host=host, port=port, log_level="warning", ws_max_size=65536)
    server = uvicorn.Server(config)
    shown = "127.0.0.1" if host in ("0.0.0.0", "::") else host
    url = f"http://{shown}:{port}/" + (f"?token={token}" if token else "")

    async def main() -> None:
        task = asyncio.create_task(server.serve())
        while not server.started and not task.done():
            await asyncio.sleep(0.02)
        if server.started and on_ready is not None:
            on_ready(url)
        if seconds is not None:
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(asyncio.shield(task), seconds)
            server.should_exit = True
        await task

    runner.start()
    try:
        asyncio.run(main())
    except KeyboardInterrupt:
        pass
    finally:
        runner.close()


class BackgroundServer:
    """The dashboard served from a background thread (tests, notebooks): ``start()`` returns
    the page's address once it listens; ``stop()`` ends the server and closes the runner."""

    def __init__(
        self, runner: DashboardRunner, host: str = "127.0.0.1", port: int = 0,
        token: str | None = None,
    ) -> None:  # fmt: skip
        import socket

        import uvicorn

        if port == 0:  # a free port, chosen now so that the address is known before start
            with socket.socket() as probe:
                probe.bind((host, 0))
                port = probe.getsockname()[1]
        self.runner, self.host, self.port, self.token = runner, host, port, token
        config = uvicorn.Config(
            create_app(runner, token), host=host, port=port, log_level="warning"
        )
        self._server = uvicorn.Server(config)
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/" + (f"?token={self.token}" if self.token else "")

    def start(self, timeout: float = 20.0) -> str:
        self.runner.start()
        self._thread = threading.Thread(target=self._server.run, name="dashboard-http", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + timeout
        while not self._server.started:
            if time.monotonic() > deadline or not self._thread.is_alive():
                self.stop()
                raise RuntimeError(f"the dashboard did not start on {self.host}:{self.port}")
            time.sleep(0.02)
        return self.url

    def stop(self) -> None:
        self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout=10.0)
        self.runner.close()
