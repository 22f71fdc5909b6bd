"""``app.services.accounts.users``: argon2 password hashes, API tokens stored as SHA-256 only, token and
session resolution, token ids, labels, expiry and revocation, role changes, the audit of every admin action,
bad names and roles, the demo account and the session-signing key."""
from __future__ import annotations

import hashlib
from datetime import timedelta

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from app.core.errors import InvalidInputError, NotFoundError
from app.db.models import ApiToken, ServerSecret, User
from app.db.types import utcnow
from app.services.accounts import users
from app.services.audit import log as audit

pytestmark = pytest.mark.engine


def test_passwords_are_stored_as_argon2id_hashes_that_verify(db_session: Session) -> None:
    user, _ = users.create_user(db_session, "ana", "annotator", "s3cret pass")
    stored = db_session.scalar(sa.select(User.password_hash).where(User.name == "ana"))
    assert stored.startswith("$argon2id$v=19$") and "s3cret" not in stored
    assert users.authenticate_password(db_session, "ana", "s3cret pass").id == user.id
    assert users.authenticate_password(db_session, "ana", "s3cret pasS") is None
    assert users.authenticate_password(db_session, "nobody", "s3cret pass") is None


def test_tokens_are_random_and_stored_only_as_their_sha256(db_session: Session) -> None:
    user, first = users.create_user(db_session, "bo", "reviewer", "pw")
    second = users.issue_token(db_session, "bo").token
    assert first != second and first.startswith("v3d_") and len(first) == 4 + 43  # 32 random bytes, base64url
    stored = db_session.scalars(sa.select(ApiToken.token_hash).where(ApiToken.user_id == user.id)).all()
    assert sorted(stored) == sorted(hashlib.sha256(t.encode()).hexdigest() for t in (first, second))
    dump = repr(db_session.execute(sa.select(ApiToken.__table__)).all())
    assert first not in dump and second not in dump
    assert users.resolve_token(db_session, first).id == user.id
    assert users.resolve_token(db_session, first[:-1]) is None
    assert users.resolve_token(db_session, "not-a-v3d-token") is None


def test_token_use_is_recorded_at_most_once_a_minute(db_session: Session) -> None:
    _, token = users.create_user(db_session, "cy", "admin", "pw")
    row = db_session.scalar(sa.select(ApiToken).where(ApiToken.token_hash == users.hash_token(token)))
    assert row.last_used_at is None
    users.resolve_token(db_session, token)
    first_use = row.last_used_at
    assert first_use is not None
    users.resolve_token(db_session, token)
    assert row.last_used_at == first_use  # within the resolution: no write
    row.last_used_at = first_use - users.TOKEN_USE_RESOLUTION - timedelta(seconds=1)
    db_session.commit()
    users.resolve_token(db_session, token)
    assert row.last_used_at > first_use - users.TOKEN_USE_RESOLUTION


def test_bad_names_roles_and_duplicates_name_the_field(db_session: Session) -> None:
    users.create_user(db_session, "dee", "annotator", "pw")
    with pytest.raises(InvalidInputError) as dup:
        users.create_user(db_session, "dee", "admin", "other")
    assert dup.value.field == "name" and "already exists" in str(dup.value)
    with pytest.raises(InvalidInputError) as role:
        users.check_new_user(db_session, "eve", "boss")
    assert role.value.field == "role" and "annotator, reviewer, admin" in str(role.value)
    for name in ("", "-x", "has space", "x" * 101):
        with pytest.raises(InvalidInputError) as bad:
            users.check_new_user(db_session, name, "admin")
        assert bad.value.field == "name"
    with pytest.raises(InvalidInputError) as empty:
        users.create_user(db_session, "eve", "admin", "")
    assert empty.value.field == "password"
    with pytest.raises(NotFoundError):
        users.issue_token(db_session, "nobody")
    assert [u.name for u in users.list_users(db_session) if u.name in ("dee", "eve")] == ["dee"]


def test_sessions_end_at_logout_and_when_disabled(db_session: Session) -> None:
    user, token = users.create_user(db_session, "fay", "annotator", "pw")
    assert users.resolve_session_user(db_session, user.id, 0) is user
    users.end_sessions(db_session, user.id)
    db_session.refresh(user)
    assert users.resolve_session_user(db_session, user.id, 0) is None
    assert users.resolve_session_user(db_session, user.id, 1) is user
    users.set_disabled(db_session, "fay")
    assert users.resolve_session_user(db_session, user.id, user.session_generation) is None
    assert users.resolve_token(db_session, token) is None
    users.set_disabled(db_session, "fay", False)
    assert users.resolve_token(db_session, token) is None  # disabling revoked it for good (issue 15)
    assert users.authenticate_password(db_session, "fay", "pw").id == user.id
    assert users.resolve_token(db_session, users.issue_token(db_session, "fay").token).id == user.id


def test_tokens_have_an_id_a_label_an_expiry_and_are_revoked_one_by_one(db_session: Session) -> None:
    user, first = users.create_user(db_session, "hal", "annotator", "pw")
    ci = users.issue_token(db_session, "hal", label="nightly CI", expires_days=30)
    assert ci.token.startswith("v3d_") and ci.label == "nightly CI"
    assert timedelta(days=29, hours=23) < ci.expires_at - utcnow() <= timedelta(days=30)
    listed = users.list_tokens(db_session, "hal")
    assert [(t.label, t.state) for t in listed] == [("first token", "active"), ("nightly CI", "active")]
    assert listed[1].id == ci.id and listed[1].expires_at == ci.expires_at
    assert ci.token not in repr(listed) and first not in repr(listed)

    revoked = users.revoke_token(db_session, "hal", ci.id)
    assert revoked.state == "revoked" and revoked.revoked_at is not None
    assert users.resolve_token(db_session, ci.token) is None
    assert users.resolve_token(db_session, first).id == user.id  # the other one works on
    assert users.revoke_token(db_session, "hal", ci.id).revoked_at == revoked.revoked_at  # idempotent

    other, _ = users.create_user(db_session, "ida", "annotator", "pw")
    ida_token = users.list_tokens(db_session, "ida")[0].id
    with pytest.raises(NotFoundError):
        users.revoke_token(db_session, "hal", ida_token)  # another user's token is not found under hal
    with pytest.raises(NotFoundError):
        users.revoke_token(db_session, "hal", 10**9)
    assert {u.name: u.tokens for u in users.list_users(db_session)}["hal"] == 1  # working tokens only


def test_an_expired_token_stops_working(db_session: Session) -> None:
    users.create_user(db_session, "jo", "annotator", "pw")
    issued = users.issue_token(db_session, "jo", expires_days=1)
    assert users.resolve_token(db_session, issued.token) is not None
    row = db_session.get(ApiToken, issued.id)
    row.expires_at = utcnow() - timedelta(seconds=1)
    db_session.commit()
    assert users.resolve_token(db_session, issued.token) is None
    assert users.list_tokens(db_session, "jo")[-1].state == "expired"
    for bad, field in (({"expires_days": 0}, "expires_days"), ({"expires_days": 4000}, "expires_days"),
                       ({"label": "x" * 101}, "label")):
        with pytest.raises(InvalidInputError) as err:
            users.issue_token(db_session, "jo", **bad)
        assert err.value.field == field


def test_role_changes_and_every_admin_action_are_audited_without_secrets(db_session: Session) -> None:
    _, first = users.create_user(db_session, "kim", "annotator", "the password", actor="root")
    issued = users.issue_token(db_session, "kim", label="script", actor="root")
    users.set_role(db_session, "kim", "reviewer", actor="root")
    users.set_role(db_session, "kim", "reviewer", actor="root")  # no change: no entry
    users.revoke_token(db_session, "kim", issued.id, actor="root")
    users.set_disabled(db_session, "kim", actor="root")
    users.set_disabled(db_session, "kim", False)
    with pytest.raises(InvalidInputError) as role:
        users.set_role(db_session, "kim", "boss")
    assert role.value.field == "role"
    entries = [e for e in reversed(audit.list_entries(db_session, limit=500).items)
               if (e.after or {}).get("user") == "kim"]
    assert [e.action for e in entries] == ["user.create", "token.issue", "user.role", "token.revoke",
                                           "user.disable", "user.enable"]
    assert [e.actor for e in entries][:5] == ["root"] * 5 and entries[5].actor.startswith("cli:")
    assert entries[0].after["user"] == "kim" and entries[0].after["role"] == "annotator"
    assert entries[1].after["token_id"] == issued.id and entries[1].after["label"] == "script"
    assert (entries[2].before["role"], entries[2].after["role"]) == ("annotator", "reviewer")
    assert entries[4].after == {"user": "kim", "tokens_revoked": 1}  # the first token; the other was revoked
    dump = repr([(e.before, e.after) for e in entries])
    assert first not in dump and issued.token not in dump and "the password" not in dump
    assert "$argon2" not in dump and users.hash_token(first) not in dump
    assert not any(e.action in audit.ADMIN_ACTIONS for e in audit.list_entries(db_session, include_admin=False,
                                                                                limit=500).items)
    with pytest.raises(NotFoundError):
        users.set_role(db_session, "nobody", "admin")
    with pytest.raises(InvalidInputError) as disabled:
        users.set_disabled(db_session, "kim")
        users.issue_token(db_session, "kim")
    assert disabled.value.field == "name"


def test_list_counts_tokens_and_flags_the_demo_account(db_session: Session) -> None:
    users.create_user(db_session, "gus", "reviewer", "pw")
    users.issue_token(db_session, "gus")
    assert users.demo_account(db_session) is None
    assert "log in as 'demo'" in users.ensure_demo_account(db_session)
    assert "log in as 'demo'" in users.ensure_demo_account(db_session)  # made once
    rows = {u.name: u for u in users.list_users(db_session)}
    assert (rows["gus"].role, rows["gus"].tokens, rows["gus"].demo) == ("reviewer", 2, False)
    assert (rows["demo"].role, rows["demo"].tokens, rows["demo"].demo) == ("admin", 1, True)
    assert users.demo_account(db_session).name == "demo"
    users.set_disabled(db_session, "demo")
    assert users.demo_account(db_session) is None


def test_a_real_user_called_demo_is_never_turned_into_the_demo_account(db_session: Session) -> None:
    users.create_user(db_session, "demo", "annotator", "not demo")
    assert "not made" in users.ensure_demo_account(db_session)
    assert users.demo_account(db_session) is None
    assert users.authenticate_password(db_session, "demo", "demo") is None


def test_the_session_key_is_made_by_the_migration_and_again_when_lost(db_session: Session) -> None:
    stored = db_session.get(ServerSecret, "session").value
    assert len(stored) >= 64 and users.session_secret(db_session) == stored
    assert users.session_secret(db_session, "from the environment") == "from the environment"
    db_session.delete(db_session.get(ServerSecret, "session"))
    db_session.commit()
    again = users.session_secret(db_session)
    assert again != stored and users.session_secret(db_session) == again


def test_names_that_read_as_one_are_refused_by_the_database_too(db_session: Session) -> None:
    """Two users whose names differ only by case or trailing dots were kept apart by a read before the insert only:
    two requests at once could both pass it. The name's key (``app.core.names.name_key``) is a column with a unique
    index, filled by the model, so the database refuses the second whoever writes it."""
    users.create_user(db_session, "Zoe", "annotator", "pw")
    assert db_session.scalar(sa.select(User.name_key).where(User.name == "Zoe")) == "zoe"
    for twin in ("zoe", "ZOE.."):
        db_session.add(User(name=twin, role="annotator", password_hash="x"))
        with pytest.raises(sa.exc.IntegrityError):
            db_session.flush()
        db_session.rollback()
    with pytest.raises(InvalidInputError) as refused:
        users.create_user(db_session, "zoe.", "annotator", "pw")
    assert refused.value.field == "name" and "'Zoe' exists" in str(refused.value)


def test_token_user_finds_whom_resolve_token_finds_and_records_the_use(db_session: Session) -> None:
    """What a request's principal is read from (``token_user``, one statement of the tables' columns) answers as
    ``resolve_token``: a working token's user, none for a wrong, revoked, expired token or a disabled user; its first
    use, and a use after the resolution, is recorded."""
    def same(token: str) -> tuple[int, str, str] | None:
        got = users.token_user(db_session, token)
        user = users.resolve_token(db_session, token)
        assert got == (None if user is None else (user.id, user.name, user.role.value))
        return got

    user, token = users.create_user(db_session, "kim", "reviewer", "pw")
    row = db_session.scalar(sa.select(ApiToken).where(ApiToken.token_hash == users.hash_token(token)))
    assert users.token_user(db_session, token) == (user.id, "kim", "reviewer") and row.last_used_at is not None
    first_use = row.last_used_at
    assert same(token) == (user.id, "kim", "reviewer") and row.last_used_at == first_use  # within the resolution
    row.last_used_at = first_use - users.TOKEN_USE_RESOLUTION - timedelta(seconds=1)
    db_session.commit()
    assert users.token_user(db_session, token) == (user.id, "kim", "reviewer")
    assert row.last_used_at > first_use - users.TOKEN_USE_RESOLUTION  # recorded again
    assert same(token[:-1]) is None and same("not-a-v3d-token") is None and same("v3d_" + "x" * 300) is None
    expiring = users.issue_token(db_session, "kim", expires_days=1)
    assert same(expiring.token) == (user.id, "kim", "reviewer")
    db_session.get(ApiToken, expiring.id).expires_at = utcnow() - timedelta(seconds=1)
    db_session.commit()
    assert same(expiring.token) is None
    revoked = users.issue_token(db_session, "kim")
    users.revoke_token(db_session, "kim", revoked.id)
    assert same(revoked.token) is None and same(token) is not None
    users.set_disabled(db_session, "kim")
    assert same(token) is None
