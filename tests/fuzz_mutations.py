"""Hypothesis strategies that mutate valid inputs (plain YAML data, YAML text, command-line overrides).

A mutation starts from something that works — a shipped scenario or controller, the default run config — and
breaks one to three things about it, the way a typo, a bad script or a hostile user would:

- numbers become NaN, ±inf, huge, tiny, negative, zero, or another type;
- strings become path-like (``../../escaped/x``, ``/abs``), hold NUL or a newline, grow long, or hold an
  interpolation (``${oc.env:HOME}``);
- structure: a list becomes a mapping or the reverse, keys go missing, extra keys appear (including YAML's
  boolean keys), lists are repeated past the size limits;
- text (for files): YAML tags, alias bombs, deep nesting, huge padding, control characters, non-UTF-8 bytes,
  several documents.

Everything here is a pure function of the drawn choices, so Hypothesis can shrink a failure to a small case.
"""

from __future__ import annotations

import copy
import math
from typing import Any

from hypothesis import strategies as st

Path = tuple[Any, ...]

BAD_NUMBERS = [math.nan, math.inf, -math.inf, 1e308, -1e308, 1e12, -1e12, -1, 0, -0.0, 1e-300, 1e-9, 0.5,
               2**63, 10**30, -(2**31)]
BAD_STRINGS = ["../../escaped/x", "/tmp/abs", "a\x00b", "a\nb", "x" * 300, "", ".hidden", "${oc.env:HOME}",
               "${now:%H}", "é", "a/b", "con", " ", "-", "on"]
WRONG_TYPES: list[Any] = [None, True, False, "abc", [], {}, [1, 2], {"a": 1}, 3.5, 7]
EXTRA_KEYS: list[Any] = ["extra", True, False, 1, None, "${x}", "a\nb", "x" * 100, "on"]
REPEATS = [2, 3, 10, 101, 501, 1001, 2001]
MAX_LIST = 3_000  # longest list a repetition makes (above every list limit of fuzzynav.params.limits)


def numbers() -> st.SearchStrategy[Any]:
    return st.one_of(st.sampled_from(BAD_NUMBERS), st.floats(), st.integers(min_value=-(2**70), max_value=2**70))


def strings() -> st.SearchStrategy[str]:
    return st.one_of(st.sampled_from(BAD_STRINGS), st.text(max_size=30))


def values() -> st.SearchStrategy[Any]:
    """Any replacement value: a bad number, a bad string, or a value of the wrong type."""
    return st.one_of(numbers(), strings(), st.sampled_from(WRONG_TYPES))


def paths(tree: Any, prefix: Path = ()) -> list[Path]:
    """Every node's path (mapping keys and list indices), the root included."""
    out = [prefix]
    if isinstance(tree, dict):
        for key, value in tree.items():
            out += paths(value, (*prefix, key))
    elif isinstance(tree, list):
        for i, value in enumerate(tree):
            out += paths(value, (*prefix, i))
    return out


def get(tree: Any, path: Path) -> Any:
    for key in path:
        tree = tree[key]
    return tree


def _put(tree: Any, path: Path, value: Any) -> Any:
    if not path:
        return value
    parent = get(tree, path[:-1])
    parent[path[-1]] = value
    return tree


def _delete(tree: Any, path: Path) -> Any:
    if not path:
        return None
    parent = get(tree, path[:-1])
    del parent[path[-1]]
    return tree


@st.composite
def mutation(draw: st.DrawFn, tree: Any, where: list[Path] | None = None) -> tuple[Any, str]:
    """One mutation of ``tree`` (a deep copy is changed) at one of ``where`` (default: every path); returns
    the new tree and a short description (for the failure report)."""
    tree = copy.deepcopy(tree)
    candidates = where if where is not None else paths(tree)
    path = draw(st.sampled_from(candidates))
    node = get(tree, path)
    kinds = ["replace", "delete"]
    if isinstance(node, int | float) and not isinstance(node, bool):
        kinds += ["number", "scale"]
    if isinstance(node, str):
        kinds += ["string"]
    if isinstance(node, dict):
        kinds += ["add_key", "swap"]
    if isinstance(node, list):
        kinds += ["swap", "repeat"]
    kind = draw(st.sampled_from(kinds))
    if kind == "replace":
        value = draw(values())
        return _put(tree, path, value), f"{_show(path)} = {value!r:.80}"
    if kind == "delete":
        return _delete(tree, path), f"delete {_show(path)}"
    if kind == "number":
        value = draw(numbers())
        return _put(tree, path, value), f"{_show(path)} = {value!r}"
    if kind == "scale":
        factor = draw(st.sampled_from([-1, 1e3, 1e9, 1e-9, 0]))
        return _put(tree, path, node * factor), f"{_show(path)} *= {factor}"
    if kind == "string":
        value = draw(strings())
        return _put(tree, path, value), f"{_show(path)} = {value!r:.80}"
    if kind == "add_key":
        key = draw(st.sampled_from(EXTRA_KEYS))
        value = draw(values())
        node[key] = value
        return tree, f"{_show(path)}[{key!r:.40}] = {value!r:.40}"
    if kind == "swap":
        swapped = list(node.values()) if isinstance(node, dict) else {str(i): v for i, v in enumerate(node)}
        return _put(tree, path, swapped), f"swap {_show(path)}"
    # past every size limit, but not without bound: repeated repeats would make the fuzzer itself the hang
    times = min(draw(st.sampled_from(REPEATS)), max(1, MAX_LIST // max(1, len(node))))
    return _put(tree, path, node * times), f"{_show(path)} *= {times} (list)"


@st.composite
def mutations(draw: st.DrawFn, tree: Any, where: list[Path] | None = None, most: int = 3) -> tuple[Any, list[str]]:
    """One to ``most`` mutations in a row (paths are drawn afresh after each, as the tree changes)."""
    steps = []
    for _ in range(draw(st.integers(min_value=1, max_value=most))):
        if where is not None:
            where = [p for p in where if _exists(tree, p)] or [()]
        tree, what = draw(mutation(tree, where))
        steps.append(what)
        if not isinstance(tree, dict | list):
            break
    return tree, steps


def _exists(tree: Any, path: Path) -> bool:
    try:
        get(tree, path)
    except (KeyError, IndexError, TypeError):
        return False
    return True


def _show(path: Path) -> str:
    return ".".join(str(p) for p in path) or "<root>"


# -- text mutations (whole files) -----------------------------------------------------------------------------


def alias_bomb(width: int, depth: int) -> str:
    """``a0: &a0 [x, x, …]``, ``a1: &a1 [*a0, *a0, …]``… : width ** depth nodes once expanded."""
    lines = [f"a0: &a0 [{', '.join(['x'] * width)}]"]
    lines += [f"a{d}: &a{d} [{', '.join([f'*a{d - 1}'] * width)}]" for d in range(1, depth)]
    return "\n".join(lines) + "\n"


@st.composite
def text_mutation(draw: st.DrawFn, text: str) -> tuple[bytes, str]:
    """A whole-file mutation of YAML ``text``; returns the new file content and a description."""
    lines = text.splitlines()
    at = draw(st.integers(min_value=0, max_value=max(0, len(lines) - 1)))
    kind = draw(st.sampled_from(["tag", "bomb", "nest", "pad", "control", "bytes", "documents", "interpolate",
                                 "dup_key", "truncate", "anchor_self"]))
    if kind == "tag":
        tag = draw(st.sampled_from(["!!python/object/apply:os.system ['true']", "!!binary aGVsbG8=", "!custom x",
                                    "!!set {a, b}", "!!timestamp 2024-01-01", "!!str 5", "!!float 1"]))
        lines.append(f"tagged: {tag}")
        return "\n".join(lines).encode(), f"tag {tag}"
    if kind == "bomb":
        width, depth = draw(st.sampled_from([(2, 3), (4, 6), (10, 4), (10, 5), (10, 9), (3, 20)]))
        return (text + "\n" + alias_bomb(width, depth)).encode(), f"alias bomb {width}^{depth}"
    if kind == "nest":
        depth = draw(st.sampled_from([5, 31, 40, 1000, 20000]))
        return (text + "\nnested: " + "[" * depth + "]" * depth + "\n").encode(), f"nesting {depth}"
    if kind == "pad":
        size = draw(st.sampled_from([10_000, 999_000, 1_100_000]))
        return (text + "\n#" + "x" * size + "\n").encode(), f"padding {size}"
    if kind == "control":
        char = draw(st.sampled_from(["\x00", "\x07", "\x1b", "\ufeff", "\u2028"]))
        lines.insert(at, f"bad: a{char}b")
        return "\n".join(lines).encode(), f"control {char!r}"
    if kind == "bytes":
        return text.encode()[: 10 * at] + b"\xff\xfe\x80" + text.encode()[10 * at:], "non-UTF-8 bytes"
    if kind == "documents":
        return (text + "\n---\n" + text).encode(), "two documents"
    if kind == "interpolate":
        value = draw(st.sampled_from(["${oc.env:HOME}", "${hydra:runtime.cwd}", "${seed}", "x${y}"]))
        lines.append(f"interp: '{value}'")
        return "\n".join(lines).encode(), f"interpolation {value}"
    if kind == "dup_key":
        lines.append(lines[at] if lines else "a: 1")
        return "\n".join(lines).encode(), f"duplicate line {at}"
    if kind == "truncate":
        cut = draw(st.integers(min_value=0, max_value=len(text)))
        return text[:cut].encode(), f"truncated at {cut}"
    return (text + "\nself: &s [1, *s]\n").encode(), "recursive alias"


def override_value(value: Any) -> str:
    """A value in Hydra's override syntax (strings quoted, so that a path or a NUL reaches the config)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value == math.inf else "-inf" if value == -math.inf
                                                 else repr(value))
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return "'" + value.replace("\\", "\\\\").replace("'", "\\'") + "'"
    if isinstance(value, list):
        return "[" + ",".join(override_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ",".join(f"{k}:{override_value(v)}" for k, v in value.items()) + "}"
    return str(value)


@st.composite
def override(draw: st.DrawFn, config: dict[str, Any]) -> str:
    """A command-line override of one field of ``config`` (the default run config): a bad value, a deletion
    (``~key``) or an extra key (``+key=value``)."""
    leaves = [p for p in paths(config) if p and not isinstance(get(config, p), dict)
              and not any(isinstance(k, int) for k in p)]
    path = draw(st.sampled_from(leaves))
    key = ".".join(str(k) for k in path)
    kind = draw(st.sampled_from(["set", "set", "set", "delete", "add"]))
    if kind == "delete":
        return f"~{key}"
    value = override_value(draw(values()))
    if kind == "add":
        extra = draw(st.sampled_from(["extra", "on", "x" * 100, "h_wiat"]))
        parent = ".".join(str(k) for k in path[:-1])
        return f"+{parent}.{extra}={value}" if parent else f"+{extra}={value}"
    return f"{key}={value}"
