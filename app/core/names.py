"""Names people read: what a name shown to other people may hold, the key that tells two names apart, and an upload's
title made safe to show.

A name someone gives (a release, a user, a detector's source) is read by other people on pages, in listings, logs and
terminals, so it must read as what it is:

* no control or format character (Unicode categories Cc and Cf: a right-to-left override, a zero-width space, a byte
  order mark, a terminal's escape), nor a line or paragraph separator (Zl, Zp) or a lone surrogate (Cs);
* not made of dots alone (``.``, ``..``: a page's address cannot hold them as a name) and no leading or trailing
  white space;
* stored in Unicode's composed form (NFC): a decomposed ``é`` (``e`` and a combining accent) is stored as the one
  character a keyboard types, so a name is found however it was typed;
* unique by its :func:`name_key` (NFKC, case folded, trailing dots dropped): names that only differ by case, by
  composition or by a compatibility form (``ﬁ`` and ``fi``, a full-width ``Ａ``) read as one name, so the second is
  refused. Each table of names stores its key in a column of its own with a unique index (the database's constraint,
  not a read), filled by the model whenever the name is set.

One rule for every name and every door (the API's schemas, the CLI, the services): :func:`check_name`.
"""
from __future__ import annotations

import unicodedata

from app.core.errors import InvalidInputError

#: The Unicode categories no name may hold (module docstring).
UNSHOWN_CATEGORIES = frozenset({"Cc", "Cf", "Cs", "Zl", "Zp"})
#: The longest upload title shown (characters).
TITLE_MAX = 120


def unshown_character(text: str) -> str | None:
    """The first character of ``text`` in :data:`UNSHOWN_CATEGORIES`, written as ``U+202E``, or None.

    >>> unshown_character("abc\\u202edcba"), unshown_character("Zoë")
    ('U+202E', None)
    """
    for c in text:
        if unicodedata.category(c) in UNSHOWN_CATEGORIES:
            return f"U+{ord(c):04X}"
    return None


def check_name(name: object, field: str = "name", *, max_length: int = 200, what: str = "a name") -> str:
    """``name`` as stored: its NFC form, once it passes the rule of the module docstring.

    Args:
        name: the name as given.
        field: the field an error names (``name``, ``source``).
        max_length: the most characters its NFC form may have.
        what: how the error calls it ("a release name").

    Returns:
        ``unicodedata.normalize("NFC", name)``.

    Raises:
        InvalidInputError: not text, empty, too long, white space around it, dots alone, or a control or format
            character (named by its code point), naming ``field``.

    >>> check_name("Cafe\\u0301 v1")
    'Café v1'
    """
    if not isinstance(name, str):
        raise InvalidInputError(f"{what} is text", field=field)
    name = unicodedata.normalize("NFC", name)
    bad = unshown_character(name)
    if bad is not None:
        raise InvalidInputError(f"{what} has no control or format character (it holds {bad}: such characters reorder "
                                "or hide text where people read it)", field=field)
    if not name.strip() or len(name) > max_length or name != name.strip():
        raise InvalidInputError(f"{what} is 1 to {max_length} characters, no leading or trailing space", field=field)
    if not name.strip("."):
        raise InvalidInputError(f"{what} is not made of dots alone ({name!r} names no page)", field=field)
    return name


def name_key(name: str) -> str:
    """What tells two names apart for people: NFKC, case folded (then NFKC again, as case folding may leave a
    decomposed form), without trailing dots. Two names with one key are one name (module docstring).

    >>> name_key("Ana.."), name_key("Cafe\\u0301"), name_key("ＲＥＬＥＡＳＥ"), name_key("Straße")
    ('ana', 'café', 'release', 'strasse')
    """
    folded = unicodedata.normalize("NFKC", unicodedata.normalize("NFKC", name).casefold())
    return folded.rstrip(".")


def clean_title(text: str, max_length: int = TITLE_MAX) -> str:
    """``text`` (an uploaded file's name, say) as it may be shown to other people: NFC, each character of
    :data:`UNSHOWN_CATEGORIES` replaced by U+FFFD (so nothing reorders, hides or escapes the text around it, and it
    shows that something was there), white space around it dropped, at most ``max_length`` characters (an ellipsis
    ends a longer one). Never raises; may answer ``""``.

    >>> clean_title("evil\\u202egpj.zip"), clean_title("\\x1b[31mred.zip")
    ('evil\\ufffdgpj.zip', '\\ufffd[31mred.zip')
    """
    text = unicodedata.normalize("NFC", str(text))
    text = "".join("\ufffd" if unicodedata.category(c) in UNSHOWN_CATEGORIES else c for c in text).strip()
    return text if len(text) <= max_length else text[:max_length - 1] + "\u2026"
