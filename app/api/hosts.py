"""Which ``Host`` a request may name (DNS rebinding).

A web page on ``attacker.example`` can make its name resolve to 127.0.0.1 (or to the server's address) after
the browser loaded it: its script then talks to v3d *as its own origin*, so the same-origin policy, the
``SameSite`` cookie and the CSRF token do not stop it, and the answers are its to read. What still gives it away
is the ``Host`` header, which names the attacker's domain. So every request must name a loopback host
(:data:`LOOPBACK_HOSTS`, any port) or one of ``V3D_ALLOWED_HOSTS``: anything else gets 400 before any route
(Starlette's ``TrustedHostMiddleware``, installed by ``app.main.create_app`` with :func:`allowed_hosts`).
The demo account, whose password is public, also needs a loopback ``Host`` (:func:`loopback_host`) besides a
loopback peer (``app.services.accounts.throttle.from_this_machine``).
"""
from __future__ import annotations

from typing import Optional

from app.core.config import Settings

#: The names of this machine a request may always use (as Starlette parses a ``Host``: IPv6 in brackets).
LOOPBACK_HOSTS = ("localhost", "127.0.0.1", "[::1]")


def allowed_hosts(settings: Settings) -> list[str]:
    """The host patterns requests may name: :data:`LOOPBACK_HOSTS` and ``V3D_ALLOWED_HOSTS``.

    >>> allowed_hosts(Settings(allowed_hosts="v3d.example.org,::1"))
    ['localhost', '127.0.0.1', '[::1]', 'v3d.example.org']
    """
    return list(dict.fromkeys([*LOOPBACK_HOSTS, *settings.allowed_hosts]))


def host_name(header: Optional[str]) -> Optional[str]:
    """The host of a ``Host`` header without its port, lower case (an IPv6 address in brackets); None when
    absent or malformed.

    >>> host_name("LocalHost:8000"), host_name("[::1]:8000"), host_name("127.0.0.1"), host_name("a:b"), host_name(None)
    ('localhost', '[::1]', '127.0.0.1', None, None)
    """
    if not header:
        return None
    text = header.strip().lower()
    if text.startswith("["):
        end = text.find("]")
        name, rest = (text[:end + 1], text[end + 1:]) if end > 0 else ("", "")
    else:
        name, colon, port = text.partition(":")
        rest = colon + port
    if not name or (rest and not (rest.startswith(":") and rest[1:].isdigit())):
        return None
    return name


def loopback_host(header: Optional[str]) -> bool:
    """Whether a ``Host`` header names this machine by a loopback name (:data:`LOOPBACK_HOSTS`, any port).

    >>> loopback_host("127.0.0.1:8000"), loopback_host("[::1]"), loopback_host("rebind.attacker.example:8000")
    (True, True, False)
    """
    return host_name(header) in LOOPBACK_HOSTS
