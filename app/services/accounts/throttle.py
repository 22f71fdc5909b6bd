"""Failed logins are limited, with the ``limits`` library and a store every server process shares.

Two fixed windows of ``V3D_LOGIN_WINDOW_S`` seconds (default 300) count failed logins: per name and client
address (``V3D_LOGIN_MAX_FAILURES_PER_NAME``, default 10) and per client address
(``V3D_LOGIN_MAX_FAILURES_PER_ADDRESS``, default 50). Once either is full, every login from that name and
address (or from that address) is answered 429 with the seconds until the window ends, a right password
too, without verifying it. Only failures count: a person who logs in right is never slowed. Each attempt is
counted before its password is checked (and given back when it was right), so that a burst of attempts at
once cannot slip past the limit while their passwords are being checked.

The counters live in the database (:class:`DatabaseStorage`, table ``rate_limit_counters``): one atomic
upsert per failure (``INSERT ... ON CONFLICT DO UPDATE ... RETURNING`` on SQLite and PostgreSQL), so that the
workers of ``v3d serve --workers N`` and a restart see the same counts. :func:`client_address` says who the
client is: the socket peer, unless the peer is one of ``V3D_TRUSTED_PROXIES``, whose ``X-Forwarded-For`` then
names it (an IPv6 client by its /64 network). Ended windows are deleted as new failures come (``_prune``), so the
table stays as small as the live windows.
"""
from __future__ import annotations

import hashlib
import ipaddress
import math
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Optional, cast

import sqlalchemy as sa
from limits import RateLimitItem, RateLimitItemPerSecond
from limits.storage import Storage
from limits.strategies import FixedWindowRateLimiter
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.engine import CursorResult
from sqlalchemy.orm import Session

from app.db.models import RateLimitCounter
from app.db.unit import write_unit


class DatabaseStorage(Storage):
    """A ``limits`` storage (fixed windows) in the table ``rate_limit_counters``, through ``session_factory``
    (a SQLAlchemy session maker; each call opens and commits a session of its own). ``clock`` gives Unix
    seconds (tests move it)."""

    STORAGE_SCHEME = ["v3d-database"]

    def __init__(self, session_factory: Callable[[], Session], clock: Callable[[], float] = time.time) -> None:
        super().__init__()
        self.session_factory = session_factory
        self.clock = clock

    @property
    def base_exceptions(self) -> type[Exception] | tuple[type[Exception], ...]:
        return sa.exc.SQLAlchemyError

    def incr(self, key: str, expiry: int, amount: int = 1) -> int:
        """Add ``amount`` to the counter ``key`` (a window of ``expiry`` seconds starting now when it has none
        or its window ended) and return the new count, atomically."""
        now = self.clock()
        with self.session_factory() as session:
            with write_unit(session, lock=False):
                insert = (postgresql.insert if session.get_bind().dialect.name == "postgresql" else sqlite.insert)(
                    RateLimitCounter)
                expired = RateLimitCounter.expires_at <= now
                statement = insert.values(key=key, hits=amount, expires_at=now + expiry).on_conflict_do_update(
                    index_elements=[RateLimitCounter.key],
                    set_={"hits": sa.case((expired, amount), else_=RateLimitCounter.hits + amount),
                          "expires_at": sa.case((expired, now + expiry), else_=RateLimitCounter.expires_at)},
                ).returning(RateLimitCounter.hits)
                hits = session.execute(statement).scalar_one()
            self._prune(session, now)
        return int(hits)

    #: Expired counters deleted per failure at most (a bounded, indexed delete).
    PRUNE_BATCH = 100

    def _prune(self, session: Session, now: float) -> None:
        """Delete up to :attr:`PRUNE_BATCH` counters whose window ended (they count as zero anyway), in a
        transaction of its own after the count is committed: each failure removes more ended rows than it
        adds, so the table holds about the counters of the live windows however many names and addresses an
        attacker tries. On PostgreSQL rows another transaction holds are skipped (``SKIP LOCKED``), so two
        prunes never wait for each other."""
        ended = (sa.select(RateLimitCounter.key).where(RateLimitCounter.expires_at <= now)
                 .order_by(RateLimitCounter.expires_at).limit(self.PRUNE_BATCH)
                 .with_for_update(skip_locked=True))
        with write_unit(session, lock=False):
            session.execute(sa.delete(RateLimitCounter).where(RateLimitCounter.key.in_(ended)))

    def _row(self, key: str) -> Optional[RateLimitCounter]:
        with self.session_factory() as session:
            row = session.get(RateLimitCounter, key)
            return row if row is not None and row.expires_at > self.clock() else None

    def get(self, key: str) -> int:
        """The count of ``key`` in its current window (0 when it has none)."""
        row = self._row(key)
        return 0 if row is None else int(row.hits)

    def get_expiry(self, key: str) -> float:
        """When the window of ``key`` ends (Unix seconds; now when it has none)."""
        row = self._row(key)
        return self.clock() if row is None else float(row.expires_at)

    def check(self) -> bool:
        """Whether the database answers."""
        try:
            with self.session_factory() as session:
                session.execute(sa.text("SELECT 1"))
            return True
        except sa.exc.SQLAlchemyError:
            return False

    def reset(self) -> Optional[int]:
        """Forget every counter; returns how many there were."""
        with self.session_factory() as session:
            with write_unit(session, lock=False):
                count = cast(CursorResult, session.execute(sa.delete(RateLimitCounter))).rowcount
        return count

    def decr(self, key: str, amount: int = 1) -> None:
        """Take ``amount`` back from the counter ``key`` within its current window (never below 0; an ended
        window is left alone)."""
        with self.session_factory() as session:
            with write_unit(session, lock=False):
                session.execute(sa.update(RateLimitCounter)
                                .where(RateLimitCounter.key == key, RateLimitCounter.expires_at > self.clock())
                                .values(hits=sa.func.max(RateLimitCounter.hits - amount, 0)
                                        if session.get_bind().dialect.name == "sqlite"
                                        else sa.func.greatest(RateLimitCounter.hits - amount, 0)))

    def clear(self, key: str) -> None:
        """Forget the counter ``key``."""
        with self.session_factory() as session:
            with write_unit(session, lock=False):
                session.execute(sa.delete(RateLimitCounter).where(RateLimitCounter.key == key))


def client_address(peer: Optional[str], forwarded_for: Optional[str], trusted_proxies: Iterable[str]) -> str:
    """Who sent a request: the socket ``peer``, unless it is one of ``trusted_proxies`` (addresses or
    networks); then the right-most address of ``forwarded_for`` (``X-Forwarded-For``) that is not a trusted
    proxy itself (the left part of the header is whatever the client wrote). ``"unknown"`` without a peer.

    >>> client_address("10.0.0.5", "1.2.3.4", [])
    '10.0.0.5'
    >>> client_address("10.0.0.5", "6.6.6.6, 1.2.3.4", ["10.0.0.0/8"])
    '1.2.3.4'
    >>> client_address("10.0.0.5", "1.2.3.4, 10.0.0.7", ["10.0.0.0/8"])
    '1.2.3.4'
    >>> client_address("10.0.0.5", None, ["10.0.0.5"])
    '10.0.0.5'
    >>> client_address("2001:db8:1:2:aaaa::1", None, [])
    '2001:db8:1:2::/64'
    """
    networks = [ipaddress.ip_network(p.strip(), strict=False) for p in trusted_proxies if p.strip()]

    def trusted(address: str) -> bool:
        try:
            ip = ipaddress.ip_address(address)
        except ValueError:
            return False
        return any(ip in net for net in networks)

    if not peer:
        return "unknown"
    if not trusted(peer) or not forwarded_for:
        return client_group(peer)
    hops = [h.strip() for h in forwarded_for.split(",") if h.strip()]
    for hop in reversed(hops):
        if not trusted(hop):
            return client_group(hop)
    return client_group(peer)


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an interface to listen on, or a client's address) is this machine only: ``localhost``
    or a loopback address (``127.0.0.0/8``, ``::1``, IPv4-mapped ``::ffff:127.x``). ``0.0.0.0``, ``::`` and any
    other name or address face a network.

    >>> is_loopback("127.0.0.2"), is_loopback("[::1]"), is_loopback("localhost"), is_loopback("::ffff:127.0.0.1")
    (True, True, True, True)
    >>> is_loopback("0.0.0.0"), is_loopback("::"), is_loopback("10.0.0.1"), is_loopback("v3d.example.org")
    (False, False, False, False)
    """
    if host.strip().lower() == "localhost":
        return True
    try:
        ip = ipaddress.ip_address(host.strip().strip("[]"))
    except ValueError:
        return False  # a host name other than localhost may resolve to any interface
    mapped = getattr(ip, "ipv4_mapped", None)
    return (mapped or ip).is_loopback


#: Headers a reverse proxy adds to what it forwards (RFC 7239 and the customary ones).
PROXY_HEADERS = ("forwarded", "x-forwarded-for", "x-real-ip", "x-forwarded-host", "x-forwarded-proto")


def from_this_machine(peer: Optional[str], headers: Any) -> bool:
    """Whether a request came straight from this machine: its socket ``peer`` is a loopback address and it
    carries none of :data:`PROXY_HEADERS` (``headers``: a case-insensitive mapping). A proxy on this machine
    forwarding the network (to a server on 127.0.0.1) adds them, so its requests are not this machine's, whatever
    ``V3D_TRUSTED_PROXIES`` says. Used for the demo account, whose password is public.

    >>> from_this_machine("127.0.0.1", {}), from_this_machine("127.0.0.1", {"x-forwarded-for": "8.8.8.8"})
    (True, False)
    >>> from_this_machine("10.1.2.3", {}), from_this_machine(None, {})
    (False, False)
    """
    return peer is not None and bool(peer) and is_loopback(peer) and not any(h in headers for h in PROXY_HEADERS)


def client_group(address: str) -> str:
    """The client an ``address`` counts as: an IPv4 address itself, an IPv6 address its ``/64`` network (the
    smallest block a site is given; its hosts choose their own addresses within it), an IPv4-mapped IPv6 address
    its IPv4 address; anything else (not an address) as written.

    >>> client_group("192.0.2.7"), client_group("::ffff:192.0.2.7"), client_group("2001:db8::5"), client_group("x")
    ('192.0.2.7', '192.0.2.7', '2001:db8::/64', 'x')
    """
    try:
        ip = ipaddress.ip_address(address)
    except ValueError:
        return address
    if isinstance(ip, ipaddress.IPv6Address):
        if ip.ipv4_mapped is not None:
            return str(ip.ipv4_mapped)
        return str(ipaddress.ip_network(f"{ip}/64", strict=False))
    return str(ip)


@dataclass
class LoginThrottle:
    """The two limits of failed logins (module docstring) on one storage."""

    storage: DatabaseStorage
    per_name: RateLimitItem
    per_address: RateLimitItem

    @classmethod
    def of(cls, session_factory: Callable[[], Session], max_per_name: int, max_per_address: int,
           window_s: int, clock: Callable[[], float] = time.time) -> "LoginThrottle":
        """The throttle of the settings (``V3D_LOGIN_*``) on the database of ``session_factory``."""
        return cls(DatabaseStorage(session_factory, clock), RateLimitItemPerSecond(max_per_name, window_s),
                   RateLimitItemPerSecond(max_per_address, window_s))

    @property
    def _limiter(self) -> FixedWindowRateLimiter:
        return FixedWindowRateLimiter(self.storage)

    def _limits(self, name: str, address: str) -> list[tuple[RateLimitItem, tuple[str, ...]]]:
        # The name is stored as a digest: a key of bounded length, and no typed name (sometimes a password
        # typed in the wrong field) kept in the database.
        named = hashlib.sha256(name.encode("utf-8")).hexdigest()[:32]
        return [(self.per_name, ("login-failures", "name", named, address)),
                (self.per_address, ("login-failures", "address", address))]

    def retry_after(self, name: str, address: str) -> Optional[int]:
        """Seconds until a login of ``name`` from ``address`` may be tried again, or None when it may now."""
        limiter = self._limiter
        waits = [limiter.get_window_stats(item, *ids).reset_time - self.storage.clock()
                 for item, ids in self._limits(name, address) if not limiter.test(item, *ids)]
        return max(1, math.ceil(max(waits))) if waits else None

    def acquire(self, name: str, address: str) -> Optional[int]:
        """Before a password is checked: count the attempt as a failure in both windows now, so that attempts
        running at once cannot pass the limit together, and return None; or, when a window is full, count
        nothing and return the seconds to wait. A login that then succeeds gives its count back
        (:meth:`succeeded`)."""
        wait = self.retry_after(name, address)
        if wait is not None:
            return wait
        limiter, taken = self._limiter, []
        for item, ids in self._limits(name, address):
            taken.append((item, ids))
            if not limiter.hit(item, *ids):  # another attempt filled the window meanwhile
                self._give_back(taken)
                return self.retry_after(name, address) or 1
        return None

    def succeeded(self, name: str, address: str) -> None:
        """The login counted by :meth:`acquire` was right: it is no failure."""
        self._give_back(self._limits(name, address))

    def _give_back(self, taken: list[tuple[RateLimitItem, tuple[str, ...]]]) -> None:
        for item, ids in taken:
            self.storage.decr(item.key_for(*ids))


def login_throttle(settings: Any, session_factory: Callable[[], Session]) -> LoginThrottle:
    """:meth:`LoginThrottle.of` with ``settings``' limits (``login_max_failures_per_name``,
    ``login_max_failures_per_address``, ``login_window_s``)."""
    return LoginThrottle.of(session_factory, settings.login_max_failures_per_name,
                            settings.login_max_failures_per_address, settings.login_window_s)
