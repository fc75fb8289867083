"""Access to the studio over the network: an access token checked on every WebSocket connection.

The studio binds 127.0.0.1 unless told otherwise. Served on another address (``--host 0.0.0.0``),
anyone who can reach the port can read and write styles and motions, so ``studio serve`` warns and
accepts ``--token`` (or ``MOTION_STUDIO_TOKEN``). The browser passes the token in the WebSocket URL —
viser's client connects to the ``websocket`` query parameter of the page when one is given::

    http://HOST:PORT/?websocket=ws://HOST:PORT/?token=TOKEN

A connection whose handshake path lacks the token is closed (code 1008, "access token required")
before any scene or GUI message is sent: viser runs the connect callbacks of its WebSocket layer
before it starts the producers, and :func:`require_token` puts its check first. viser 1.1 has no
public hook for this, so it uses ``ViserServer._websock_server`` (tests/test_security.py fails if
that changes).
"""

from __future__ import annotations

import hmac
import ipaddress
import os
import secrets
import socket
from urllib.parse import parse_qs, urlsplit

import viser

TOKEN_ENV = "MOTION_STUDIO_TOKEN"
TOKEN_PARAM = "token"


def is_loopback(host: str) -> bool:
    if host in ("localhost", ""):
        return host == "localhost"
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def new_token() -> str:
    return secrets.token_urlsafe(18)


def token_from_path(path: str) -> str | None:
    values = parse_qs(urlsplit(path).query).get(TOKEN_PARAM)
    return values[0] if values else None


def require_token(server: viser.ViserServer, token: str) -> None:
    """Close every WebSocket connection whose URL does not carry ``?token=<token>``."""
    infra = server._websock_server  # noqa: SLF001 - viser 1.1 has no public connection gate

    async def gate(conn) -> None:  # runs on viser's event loop, before any message is sent
        ws = infra._live_connections.get(conn.client_id)  # noqa: SLF001
        if ws is None:
            return
        given = token_from_path(ws.request.path if ws.request is not None else "")
        if given is None or not hmac.compare_digest(given.encode(), token.encode()):
            await ws.close(1008, "access token required")

    infra._client_connect_cb.insert(0, gate)  # noqa: SLF001


def browser_url(host: str, port: int, token: str | None) -> str:
    """The address to open: the machine's name for a wildcard bind, the token in the WebSocket URL."""
    shown = socket.gethostname() if host in ("0.0.0.0", "::", "") else host
    if ":" in shown and not shown.startswith("["):
        shown = f"[{shown}]"
    if not token:
        return f"http://{shown}:{port}"
    return f"http://{shown}:{port}/?websocket=ws://{shown}:{port}/?{TOKEN_PARAM}={token}"


def token_from_env() -> str | None:
    return os.environ.get(TOKEN_ENV) or None
