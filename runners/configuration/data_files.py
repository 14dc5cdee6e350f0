"""Scenario and controller files are data: checked as text before any YAML loader builds them.

Hydra parses the files it composes with a full YAML loader and OmegaConf then expands every alias into a
tree and resolves ``${...}`` interpolations (including ``${oc.env:...}``). A hostile or broken file could
therefore hang the run (alias "billion laughs", a 100 MB file), read the environment, or name a log file
outside the output directory. :func:`check_data_text` refuses, with one line naming the file (and the line or
the field):

- files over :data:`fuzzynav.params.limits.MAX_DATA_FILE_BYTES`, or not UTF-8;
- YAML tags (``!!python/...``, ``!!binary``, ``!custom``): a data file needs none;
- nesting deeper than :data:`~fuzzynav.params.limits.MAX_YAML_DEPTH`, recursive aliases, more than
  :data:`~fuzzynav.params.limits.MAX_YAML_NODES` nodes once aliases are expanded (aliases themselves are fine:
  ``conf/controller/listing.yaml`` shares its sensor terms with one);
- interpolations: any ``${`` in a key or value;
- a key given twice in one mapping (YAML's loaders keep the last silently, dropping the first block);
- YAML 1.1 base-60 numbers (``max_steps: 1:00`` is read as 60): quote them or write the number;
- anything but one mapping at the top (Hydra's own message for that names no file).

The scanner and composer are libyaml's (C) when available: linear in the file size, no objects built.
"""

from __future__ import annotations

import re
import stat
from dataclasses import dataclass
from pathlib import Path

import yaml

from fuzzynav.params import limits
from fuzzynav.params.checks import key_text

#: YAML's safe loader, by libyaml where PyYAML has it (about ten times faster; the same data)
SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_OPEN = (yaml.BlockMappingStartToken, yaml.BlockSequenceStartToken, yaml.FlowMappingStartToken,
         yaml.FlowSequenceStartToken)
_CLOSE = (yaml.BlockEndToken, yaml.FlowMappingEndToken, yaml.FlowSequenceEndToken)


#: YAML 1.1's base-60 numbers (``1:00`` is 60, ``1:30:00.5`` is 5400.5), which the loaders read silently
_SEXAGESIMAL = re.compile(r"[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+(?:\.[0-9_]*)?")


class DataFileError(ValueError):
    """A data file is not plain, bounded data; the message starts with the file (and line or field)."""


@dataclass(frozen=True)
class DataKind:
    """A kind of data file: its size limits (bytes; YAML nodes once aliases are expanded) and how messages name
    it (``one``: "a scenario or controller file"; ``all``: "scenario and controller files")."""

    one: str
    all: str
    max_bytes: int
    max_nodes: int
    interpolations: bool = False  # ``${...}`` allowed (Hydra's config files use them; data files must not)


SCENARIO_OR_CONTROLLER = DataKind("a scenario or controller file", "scenario and controller files",
                                  limits.MAX_DATA_FILE_BYTES, limits.MAX_YAML_NODES)
#: dataset manifests (runners.dataset) hold a few dozen nodes per episode: larger limits, the same rules
MANIFEST = DataKind("a dataset manifest", "dataset manifests", limits.MAX_MANIFEST_BYTES, limits.MAX_MANIFEST_NODES)
#: the other files Hydra composes (navigator, planner, sweep presets, launchers, config.yaml): the same limits, so a
#: hostile or broken one cannot hang the command either, but Hydra's interpolations are theirs to use
CONFIG_FILE = DataKind("a config file", "config files", limits.MAX_DATA_FILE_BYTES, limits.MAX_YAML_NODES,
                       interpolations=True)


def check_data_file(path: Path, kind: DataKind | None = None) -> bytes:
    """Check a data file on disk (default: a scenario or controller file) and return its bytes. What the path
    leads to (links followed) must be a regular file, and its size is checked before it is read: ``/dev/zero`` or
    a FIFO would be read for ever, a huge file whole."""
    kind = kind or SCENARIO_OR_CONTROLLER
    try:
        info = path.stat()
        if not stat.S_ISREG(info.st_mode):
            raise DataFileError(f"{path}: not a regular file")
        if info.st_size > kind.max_bytes:
            raise DataFileError(f"{path}: {info.st_size:,} bytes, more than the limit of {kind.max_bytes:,} for "
                                f"{kind.one}")
        with path.open("rb") as f:
            raw = f.read(kind.max_bytes + 1)  # a file growing since the stat is still read only this far
    except OSError as err:
        raise DataFileError(f"{path}: cannot read: {err.strerror or err}") from None
    check_data_text(raw, str(path), kind)
    return raw


def check_data_text(raw: bytes | str, source: str, kind: DataKind | None = None) -> None:
    """Check the text of a data file named ``source`` (see the module docstring); ``kind``: its limits and how
    messages name it (default: a scenario or controller file)."""
    kind = kind or SCENARIO_OR_CONTROLLER
    size = len(raw.encode() if isinstance(raw, str) else raw)
    if size > kind.max_bytes:
        raise DataFileError(f"{source}: {size:,} bytes, more than the limit of {kind.max_bytes:,} for {kind.one}")
    if isinstance(raw, bytes):
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as err:
            raise DataFileError(f"{source}: not UTF-8 text (byte {err.start})") from None
    else:
        text = raw
    try:
        _Events(source, kind).check(yaml.parse(text, Loader=SAFE_LOADER))
    except yaml.MarkedYAMLError as err:
        raise DataFileError(f"{source}{_yaml_error(err)}") from None
    except yaml.reader.ReaderError as err:  # a character YAML does not allow: say where
        line = text.count("\n", 0, err.position) + 1 if isinstance(err.position, int) else 0
        raise DataFileError(f"{source}:{line}: YAML error: {str(err).splitlines()[0]}") from None
    except yaml.YAMLError as err:
        raise DataFileError(f"{source}: YAML error: {str(err).splitlines()[0]}") from None


def _yaml_error(err: yaml.MarkedYAMLError) -> str:
    """``:line:column: YAML error: …`` at the construct that is broken (an unclosed ``[`` is reported where it
    opens, as Hydra's loader does), with the position where the parser noticed it."""
    first = err.context_mark or err.problem_mark
    where = f":{first.line + 1}:{first.column + 1}" if first else ""
    text = "; ".join(str(t) for t in (err.context, err.problem) if t)
    seen = err.problem_mark
    if seen and err.context_mark and (seen.line, seen.column) != (first.line, first.column):
        text += f" (line {seen.line + 1}, column {seen.column + 1})"
    return f"{where}: YAML error: {text}"


class _Frame:
    """An open sequence or mapping: its field, its node count so far, its anchor, the key being filled and (of a
    mapping) the plain keys seen so far; every key is a node, so the node limit bounds them too."""

    __slots__ = ("anchor", "field", "index", "is_map", "key", "keys", "size", "want_key")

    def __init__(self, field: str, is_map: bool, anchor: str | None) -> None:
        self.field, self.is_map, self.anchor = field, is_map, anchor
        self.size, self.index, self.want_key, self.key = 1, 0, True, "?"
        self.keys: set[str] = set()


class _Events:
    """One pass over the parser's events (libyaml: no Python objects built but the events): no tags, one
    document, bounded nesting, no ``${``, and the node count with every alias expanded (an anchor's size is
    known when its node ends, so an alias costs one addition: "billion laughs" is counted, not built)."""

    def __init__(self, source: str, kind: DataKind) -> None:
        self.source, self.kind = source, kind
        self.stack: list[_Frame] = [_Frame("", False, None)]
        self.anchors: dict[str, int] = {}
        self.documents = 0

    def fail(self, event: yaml.Event, field: str, problem: str) -> None:
        line = f":{event.start_mark.line + 1}" if event.start_mark else ""
        field = field if len(field) <= 80 else f"...{field[-77:]}"  # one readable line
        raise DataFileError(f"{self.source}{line}: {field or 'top level'}: {problem}")

    def field(self) -> str:
        """The field of the node that starts now (a key of a mapping counts as the mapping's field)."""
        parent = self.stack[-1]
        if parent.is_map:
            if parent.want_key:
                return parent.field
            return f"{parent.field}.{parent.key}" if parent.field else parent.key
        return f"{parent.field}[{parent.index}]" if len(self.stack) > 1 else ""

    def add(self, event: yaml.Event, size: int, scalar: str | None = None) -> None:
        parent = self.stack[-1]
        if parent.is_map and parent.want_key:
            parent.key = key_text(scalar) if scalar is not None else "?"
            # ``<<`` merges are keys of their own; ``sweep:`` written twice kept only the second block
            if scalar is not None and scalar != "<<":
                if scalar in parent.keys:
                    self.fail(event, parent.field, f"duplicate key {_short(scalar)}")
                parent.keys.add(scalar)
        parent.want_key = not parent.want_key
        parent.index += 1
        parent.size += size
        if parent.size > self.kind.max_nodes:
            self.fail(event, parent.field, f"more than {self.kind.max_nodes:,} YAML nodes once aliases are "
                                           "expanded (the limit)")

    def check(self, events) -> None:
        for event in events:
            if isinstance(event, yaml.DocumentStartEvent):
                self.documents += 1
                if self.documents > 1:
                    self.fail(event, "", "more than one YAML document")
            elif isinstance(event, yaml.ScalarEvent | yaml.SequenceStartEvent | yaml.MappingStartEvent):
                field = self.field()
                if len(self.stack) == 1 and not isinstance(event, yaml.MappingStartEvent):
                    self.fail(event, "", f"expected a mapping ({self.kind.one} is a YAML mapping)")
                if event.tag is not None:
                    self.fail(event, field, f"YAML tag {event.tag!r} is not allowed: {self.kind.all} are data")
                if isinstance(event, yaml.ScalarEvent):
                    if "${" in event.value and not self.kind.interpolations:
                        self.fail(event, field, f"interpolation {_short(event.value)} is not allowed: "
                                                f"{self.kind.all} are data")
                    if event.implicit[0] and _SEXAGESIMAL.fullmatch(event.value):
                        self.fail(event, field, f"{event.value!r} is a base-60 number in YAML 1.1 (read as "
                                                f"{yaml.safe_load(event.value):g}): write the number, or quote it")
                    if event.anchor is not None:
                        self.anchors[event.anchor] = 1
                    self.add(event, 1, event.value)
                    continue
                if len(self.stack) > limits.MAX_YAML_DEPTH:
                    self.fail(event, field, f"nested deeper than the limit of {limits.MAX_YAML_DEPTH} levels")
                self.stack.append(_Frame(field, isinstance(event, yaml.MappingStartEvent), event.anchor))
            elif isinstance(event, yaml.SequenceEndEvent | yaml.MappingEndEvent):
                frame = self.stack.pop()
                if frame.anchor is not None:
                    self.anchors[frame.anchor] = frame.size
                self.add(event, frame.size)
            elif isinstance(event, yaml.AliasEvent):
                field = self.field()
                if len(self.stack) == 1:
                    self.fail(event, "", f"expected a mapping ({self.kind.one} is a YAML mapping)")
                if event.anchor not in self.anchors:
                    opened = any(f.anchor == event.anchor for f in self.stack)
                    self.fail(event, field, "recursive alias" if opened else f"undefined alias *{event.anchor}")
                self.add(event, self.anchors[event.anchor])


def _short(text: str) -> str:
    return repr(text) if len(text) <= 60 else f"{text[:57]!r}..."
