"""Quote a value in an error message at bounded cost.

A scene file or a log's metadata may hold a value that is huge (a 50 MB list) or whose
``repr()`` is exponential in its size (a YAML "billion laughs" of nested aliases). Every
message that shows a user's value goes through :func:`quote`, which looks at a bounded part of
the value and returns at most ``limit`` characters.
"""
from __future__ import annotations

import reprlib

QUOTE_LIMIT = 80          # characters

_REPR = reprlib.Repr()
_REPR.maxlevel = 3        # nesting depth shown
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6
_REPR.maxstring = _REPR.maxother = QUOTE_LIMIT
_REPR.maxlong = 40        # digits of a huge integer


def quote(value, limit: int = QUOTE_LIMIT, *, plain: bool = False) -> str:
    """``repr(value)`` (``str`` for a string with ``plain``) cut to at most ``limit``
    characters (the cut ends in "..."); the work is bounded whatever the value's size or
    nesting."""
    try:
        text = value[:limit + 1] if plain and isinstance(value, str) else _REPR.repr(value)
    except Exception:                      # a broken __repr__ must not hide the real error
        text = f"<{type(value).__name__}>"
    text = " ".join(text.split())
    return text if len(text) <= limit else text[:limit - 3] + "..."
