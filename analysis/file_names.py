"""File names as text: a path given in bytes that are not UTF-8 (copied from another system) made into UTF-8 text
for tables, reports and one-line errors. Its own module, with nothing else imported, so that a command's start-up
can check its arguments without loading the log reader."""

from __future__ import annotations


def printable(text: str) -> str:
    """``text`` (a path as the file system gave it, or a message naming one) as UTF-8 text: the bytes of a name
    that are not UTF-8 as ``\\xNN`` escapes (the tables' writers refuse the surrogates Python reads them as)."""
    try:
        return text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    except UnicodeEncodeError:  # a surrogate that no file name gave
        return text.encode("utf-8", "backslashreplace").decode("utf-8")


def is_utf8(text: str) -> bool:
    """Whether ``text`` holds no byte that is not UTF-8 (no lone surrogate)."""
    return printable(text) == text
