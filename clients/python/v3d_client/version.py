"""The client's version, and which servers it speaks to.

The client is versioned with the server: it ships in the server's repository and carries the server's version. A
server whose ``GET /api/health`` names a version of another ``major.minor`` (for 0.x, another minor) may have routes
or fields this client does not know, or lack some it uses; the client says so at its first call
(:class:`~v3d_client.errors.VersionMismatch`) instead of failing later on a missing field.
"""
from __future__ import annotations

__version__ = "0.1.0"


def _series(version: str) -> tuple[int, ...]:
    """The part of ``version`` that must agree: ``(major, minor)``.

    >>> _series("0.1.3"), _series("1.2")
    ((0, 1), (1, 2))
    """
    parts = version.split(".")
    return tuple(int(p) for p in parts[:2])


def mismatch(server_version: str | None, client_version: str = __version__) -> str | None:
    """Why a client of ``client_version`` cannot speak to a server of ``server_version`` (None when it can).

    ``None`` for the server's version means a server that does not say its version: older than every client.

    >>> mismatch("0.1.7", "0.1.0") is None
    True
    >>> print(mismatch("0.2.0", "0.1.0"))  # doctest: +NORMALIZE_WHITESPACE
    the server runs v3d 0.2.0, newer than this client (0.1.0): install the client of its version
    (pip install ./clients/python from a checkout of v3d 0.2.0)
    >>> mismatch(None, "0.1.0").startswith("the server does not say its version: it is older")
    True
    """
    if server_version is None:
        return (f"the server does not say its version: it is older than this client ({client_version}); use the "
                "client of the server's checkout")
    try:
        server, client = _series(server_version), _series(client_version)
    except ValueError:
        return f"the server names version {server_version!r}, which this client ({client_version}) cannot read"
    if server == client:
        return None
    side = "newer" if server > client else "older"
    return (f"the server runs v3d {server_version}, {side} than this client ({client_version}): install the client "
            f"of its version (pip install ./clients/python from a checkout of v3d {server_version})")
