"""Every tutorial of docs/tutorials/ runs exactly as written (the convention is in docs/tutorials/index.md).

Each tutorial's fenced code blocks run in order in a fresh temporary working directory:

- a block with a title (```python title="my_policies.py"```, ```yaml title="my_conf/x.yaml"```) is a file: its
  content is written to that path, relative to the working directory;
- a ```bash``` block is run by bash with ``set -euo pipefail``;
- a ```python``` block without a title is run by ``python -`` (so the working directory is on ``sys.path``, as in
  an interactive session); its ``assert``s are the tutorial's own checks;
- a ```text``` block is expected output, shown and not run: right after a command, each of its lines must be a
  line that command printed (stdout or stderr), where ``...`` stands for any text and ``<name>`` for any word (a
  date, a time); a line of ``...`` alone marks lines left out.

In both kinds of command ``python`` is this test's interpreter (a folder with a ``python`` that runs
``sys.executable`` comes first on ``PATH``). A block of any other kind fails the test, so that nothing in a
tutorial goes unchecked by accident.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = ROOT / "docs" / "tutorials"
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.S | re.M)
TITLE = re.compile(r'title="([^"]+)"')
NOT_RUN = {"text"}
BLOCK_TIMEOUT_S = 600


@dataclass(frozen=True)
class Block:
    kind: str  # "file", "bash", "python" or "text"
    language: str
    body: str
    title: str | None
    line: int


def blocks(markdown: str) -> list[Block]:
    """The fenced code blocks of a tutorial, in order, classified by the convention above."""
    found = []
    for m in FENCE.finditer(markdown):
        info, body = m.group(1).strip(), m.group(2)
        language = info.split()[0] if info else ""
        title = TITLE.search(info)
        line = markdown.count("\n", 0, m.start()) + 1
        if title:
            kind = "file"
        elif language in ("bash", "python") or language in NOT_RUN:
            kind = language
        else:
            raise ValueError(f"line {line}: a ```{info}``` block is neither a file, a command nor output")
        found.append(Block(kind, language, body, title.group(1) if title else None, line))
    return found


def shown_in(line: str, printed: list[str]) -> bool:
    """Whether a line of a tutorial's expected output is one of the ``printed`` lines (``...``: any text; ``<name>``:
    any word; a line of ``...`` alone, or an empty one, stands for lines left out)."""
    text = line.rstrip()
    if text.strip() in ("", "..."):
        return True
    pattern = "".join(".*?" if part == "..." else r"[^\s/]+?" if part.startswith("<") else re.escape(part)
                      for part in re.split(r"(\.\.\.|<[a-z_]+>)", text))
    return any(re.fullmatch(pattern, out) for out in printed)


def tutorials() -> list[Path]:
    return sorted(p for p in TUTORIALS.glob("*.md") if p.name != "index.md")


def test_the_convention_reads_files_commands_and_output():
    text = ('intro\n```python title="a/b.py"\nx = 1\n```\n\n```bash\npython -m x \\\n  y\n```\n'
            '```text\nout\n```\n```python\nassert True\n```\n')
    got = [(b.kind, b.title, b.body) for b in blocks(text)]
    assert got == [("file", "a/b.py", "x = 1\n"), ("bash", None, "python -m x \\\n  y\n"), ("text", None, "out\n"),
                   ("python", None, "assert True\n")]
    with pytest.raises(ValueError, match="line 1"):
        blocks("```sh\nls\n```\n")


def test_every_tutorial_is_in_the_index_and_runs_something():
    index = (TUTORIALS / "index.md").read_text()
    for path in tutorials():
        assert f"({path.name})" in index, f"{path.name} is not linked from docs/tutorials/index.md"
        kinds = {b.kind for b in blocks(path.read_text())}
        assert kinds & {"bash", "python"}, f"{path.name} runs nothing"


@pytest.mark.parametrize("path", tutorials(), ids=lambda p: p.stem)
def test_tutorial_runs_as_written(path: Path, tmp_path: Path):
    work = tmp_path / "work"
    work.mkdir()
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    python = bin_dir / "python"  # a script, not a link: a link outside the venv would lose the venv (pyvenv.cfg)
    python.write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
    python.chmod(0o755)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "HYDRA_FULL_ERROR")}
    env["PATH"] = os.pathsep.join([str(bin_dir), str(Path(sys.executable).parent), env.get("PATH", "")])
    env["MPLBACKEND"] = "Agg"
    start = time.monotonic()
    printed: list[str] | None = None  # the lines the last command printed, for the text block after it
    for block in blocks(path.read_text()):
        where = f"{path.name}:{block.line}"
        if block.kind == "file":
            target = work / block.title
            assert work in target.resolve().parents, f"{where}: {block.title} is outside the working directory"
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(block.body)
            continue
        if block.kind == "text":
            if printed is not None:
                missing = [line for line in block.body.splitlines() if not shown_in(line, printed)]
                assert not missing, (f"{where}: the tutorial shows lines the command did not print:\n"
                                     + "\n".join(missing) + "\n--- printed:\n" + "\n".join(printed)[-4000:])
            printed = None
            continue
        printed = None
        if block.kind == "bash":
            cmd, stdin = ["bash", "-c", "set -euo pipefail\n" + block.body], None
        else:
            cmd, stdin = [str(bin_dir / "python"), "-"], block.body
        proc = subprocess.run(cmd, cwd=work, env=env, input=stdin, capture_output=True, text=True,
                              timeout=BLOCK_TIMEOUT_S)
        assert proc.returncode == 0, (f"{where}: exit {proc.returncode}\n--- block:\n{block.body}\n--- stdout:\n"
                                      f"{proc.stdout[-4000:]}\n--- stderr:\n{proc.stderr[-4000:]}")
        printed = [line.rstrip() for line in (proc.stdout + "\n" + proc.stderr).splitlines()]
    print(f"{path.name}: {time.monotonic() - start:.1f} s")
    # the commands wrote only inside the working directory (Hydra's outputs included)
    assert not (ROOT / "docs" / "tutorials" / "outputs").exists()


def test_expected_output_lines_match_printed_lines_with_placeholders_only():
    printed = ["gap policy=fuzzy seed=0: goal after 42 steps (42 s)  log: /tmp/x/outputs/2026-12-08/00-01-02/a.mcap",
               "     gap auto(h=2)         3          1.00     3       41.00"]
    assert shown_in("gap policy=fuzzy seed=0: goal after 42 steps (42 s)  log: .../outputs/<date>/<time>/a.mcap",
                    printed)
    assert shown_in("     gap auto(h=2)         3          1.00     3       41.00", printed)
    assert shown_in("...", printed) and shown_in("", printed)
    assert not shown_in("     gap auto(h=2)         3          1.00     3       40.67", printed)
    assert not shown_in("gap policy=fuzzy seed=0: goal after 41 steps (41 s)  log: .../<date>/<time>/a.mcap", printed)
