"""Where a benchmark writes its results (``--out``): checked by trying before anything is measured, written whole
at the end, and never lost.

A benchmark takes minutes; an ``--out`` that cannot be written used to be found only when it ended (a traceback,
the results gone). ``os.access`` is no check for root, who passes it on a read-only file system's folder or an
immutable file: :func:`out_problem` creates a file beside the target and opens the target for appending (without
changing it), and :func:`write_results` writes a temporary file and renames it over the target; if that still
fails, the results go to a file in the system's temporary folder and the message names it.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path


def out_problem(out: Path) -> str | None:
    """Why the results cannot be written to ``out``, or None (one line naming the path)."""
    try:
        problem = _out_problem(out)
    except ValueError as err:  # a NUL byte in the name
        problem = f"{str(out)[:60]}: not a file name ({err})"
    except OSError as err:  # a name too long, a component that is not a directory, ...
        problem = f"{str(out)[:60]}: cannot be used ({err.strerror or err})"
    # one line, whatever the name holds: control characters (a newline, a record separator) shown escaped
    return None if problem is None else "".join(c if c.isprintable() else repr(c)[1:-1] for c in problem)


def _out_problem(out: Path) -> str | None:
    if str(out) in ("", "."):
        return f"{str(out)!r}: not a file name"
    if out.is_dir():
        return f"{out}: is a directory, not a file name"
    if out.exists() and not out.is_file():
        return f"{out}: not a regular file"
    parent = out.parent
    if not parent.exists():
        return f"{out}: the directory {parent} does not exist"
    if not parent.is_dir():
        return f"{out}: {parent} is not a directory"
    try:
        with tempfile.NamedTemporaryFile(dir=parent, prefix=f".{out.name}.", suffix=".probe"):
            pass
        if out.exists():
            with out.open("ab"):
                pass
    except OSError as err:
        return f"{out}: cannot be written ({err.strerror or err})"
    return None


def write_results(out: Path, text: str) -> tuple[Path, str | None]:
    """Write ``text`` to ``out`` whole (a temporary file renamed over it). Returns (where it was written, a line
    saying why not ``out``, or None)."""
    tmp = None
    try:
        with tempfile.NamedTemporaryFile("w", dir=out.parent, prefix=f".{out.name}.", suffix=".tmp",
                                         delete=False) as f:
            tmp = Path(f.name)
            f.write(text)
        os.replace(tmp, out)
        return out, None
    except OSError as err:
        if tmp is not None:
            with contextlib.suppress(OSError):
                tmp.unlink()
        with tempfile.NamedTemporaryFile("w", prefix=f"{out.stem}-", suffix=out.suffix or ".json",
                                         delete=False) as f:
            f.write(text)
        return Path(f.name), f"{out}: cannot be written ({err.strerror or err}); the results are in {f.name}"
