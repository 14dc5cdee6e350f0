"""Datasets built from pedestrian recordings that fuzzynav does not ship (ETH/BIWI, UCY: no stated licence), from
the user's copy (``python -m runners.dataset build eth_ucy_v1 --source DIR``).

Such a manifest has a ``source`` field::

    source:
      scenes:                      # scene -> where its file is under --source (the first that exists), options
        eth: {file: [seq_eth/obsmat.txt, ETH/seq_eth/obsmat.txt, eth/obsmat.txt]}
        students03: {file: [students03/obsmat.txt], max_gap: 1, windows: [0, 1, 2]}   # its own windows
      params: {duration_s: 60, path_length: 800, max_steps: 60}   # the recorded generator's, for every scene
      windows: [0, 1, 2, 3, 4]     # params.window of each scenario (a scene's own ``windows`` replace them)
      sha256: {eth: ...}           # written by build: the scenes built and their files' SHA-256

and ``sweep.scenarios`` names scenes. ``build`` uses the scenes of ``sweep.scenarios`` whose file the user has
(the others are left out, said in a note), records each file's SHA-256, and runs scenario ``<scene>_w<k>`` for
every window k: a ``recorded`` scenario (:mod:`fuzzynav.scenarios.generators.recorded`) written into a temporary
configuration folder that the compositions search. ``verify`` needs the same files: each one's SHA-256 must be
the manifest's (another copy of a recording is another dataset), then it regenerates and compares as for any
dataset. Errors are one line naming the manifest's field or the file.
"""

from __future__ import annotations

import copy
import hashlib
import re
from pathlib import Path
from typing import Any

import yaml

from fuzzynav.params import limits
from fuzzynav.scenarios.recordings import FORMATS
from runners.datasets.manifest import DatasetError

SOURCE_FIELDS = ("scenes", "params", "windows", "sha256")
SCENE_FIELDS = ("file", "format", "max_gap", "windows")
MAX_WINDOWS = 1000


def check_source(source: Any, path: Path) -> None:
    """The ``source`` field as data (what it means is checked when the scenarios compose)."""
    if source is None:
        return
    if not isinstance(source, dict):
        raise DatasetError(f"{path}: source: expected a mapping")
    for key in source:
        if key not in SOURCE_FIELDS:
            raise DatasetError(f"{path}: source.{_shown(key)}: unknown field (allowed: {', '.join(SOURCE_FIELDS)})")
    scenes = source.get("scenes")
    if not (isinstance(scenes, dict) and scenes):
        raise DatasetError(f"{path}: source.scenes: expected a mapping of scene name to its file")
    for scene, entry in scenes.items():
        where = f"{path}: source.scenes.{_shown(scene)}"
        if not (isinstance(scene, str) and limits.NAME_PATTERN.fullmatch(scene)):
            raise DatasetError(f"{where}: not a scene name (letters, digits, _-.)")
        if not isinstance(entry, dict):
            raise DatasetError(f"{where}: expected a mapping with file")
        for key in entry:
            if key not in SCENE_FIELDS:
                raise DatasetError(f"{where}.{_shown(key)}: unknown field (allowed: {', '.join(SCENE_FIELDS)})")
        files = entry.get("file")
        files = [files] if isinstance(files, str) else files
        if not (isinstance(files, list) and files and all(_relative(f) for f in files)):
            raise DatasetError(f"{where}.file: expected a relative path (or a list of them) under --source, without "
                               f"'..', got {entry.get('file')!r:.60}")
        if entry.get("format") is not None and not (isinstance(entry["format"], str) and entry["format"] in FORMATS):
            raise DatasetError(f"{where}.format: expected one of {', '.join(FORMATS)}, got {entry['format']!r:.40}")
        gap = entry.get("max_gap", 0)
        if isinstance(gap, bool) or not isinstance(gap, int) or not 0 <= gap <= 1000:
            raise DatasetError(f"{where}.max_gap: expected a whole number in [0, 1000], got {gap!r:.40}")
    params = source.get("params", {})
    if not isinstance(params, dict):
        raise DatasetError(f"{path}: source.params: expected a mapping of the recorded generator's parameters")
    for key in ("recording", "window", "start_s", "format", "max_gap"):
        if key in params:
            raise DatasetError(f"{path}: source.params.{key}: set by the dataset (scenes and windows)")
    _check_windows(source.get("windows"), f"{path}: source.windows")
    for scene, entry in scenes.items():
        if "windows" in entry:
            _check_windows(entry["windows"], f"{path}: source.scenes.{_shown(scene)}.windows")
    digests = source.get("sha256")
    if digests is not None and not (isinstance(digests, dict) and digests and all(
            s in scenes and isinstance(d, str) and re.fullmatch("[0-9a-f]{64}", d) for s, d in digests.items())):
        raise DatasetError(f"{path}: source.sha256: expected a mapping of scenes of source.scenes to 64 lowercase "
                           "hex digits")


def scene_windows(source: dict[str, Any], scene: str) -> int:
    """How many windows of ``scene`` a dataset runs: its own ``windows``, else ``source.windows``."""
    entry = source["scenes"].get(scene) or {}
    return len(entry.get("windows", source["windows"]))


def _check_windows(windows: Any, where: str) -> None:
    if not (isinstance(windows, list) and windows and len(windows) <= MAX_WINDOWS and all(
            isinstance(k, int) and not isinstance(k, bool) and 0 <= k <= 1_000_000 for k in windows)
            and len(set(windows)) == len(windows)):
        raise DatasetError(f"{where}: expected a list of distinct window numbers (0 or more), at most "
                           f"{MAX_WINDOWS}, got {windows!r:.60}")


def _shown(key: Any) -> str:
    """A manifest's key in a message: as written when it is a name, else its repr (one line, at most 40 chars)."""
    return key if isinstance(key, str) and limits.NAME_PATTERN.fullmatch(key) else repr(key)[:40]


def _relative(text: Any) -> bool:
    if not isinstance(text, str) or not text or "\0" in text or len(text) > 1000:
        return False
    p = Path(text)
    return not p.is_absolute() and ".." not in p.parts


def _locate(entry: dict[str, Any], source: Path) -> Path | None:
    files = entry["file"] if isinstance(entry["file"], list) else [entry["file"]]
    return next((source / f for f in files if (source / f).is_file()), None)


def _sha256(path: Path) -> str:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError as err:
        raise DatasetError(f"{path}: cannot be read ({err.strerror or err})") from None


def prepare(manifest: dict[str, Any], path: Path, source: Path | None, conf_dir: Path,
            building: bool) -> tuple[dict[str, Any], list[str], list[str]]:
    """(the manifest to run, the overrides every composition needs, notes) for a manifest with ``source``: its
    scenes expanded to one scenario per window, written into ``conf_dir`` (module docstring). A manifest without
    ``source`` is returned as it is. ``building``: take the scenes the user has and record their SHA-256 in the
    returned manifest's ``source.sha256``; else check the files against it."""
    spec = manifest.get("source")
    if spec is None:
        if source is not None:
            raise DatasetError(f"--source: dataset {manifest['name']} is not built from recordings ({path} has no "
                               "source field)")
        return manifest, [], []
    if source is None:
        raise DatasetError(f"{path}: source: this dataset is built from recordings fuzzynav does not ship: give "
                           "--source DIR, the folder of your copy (docs/recordings.md says where to get them)")
    if not source.is_dir():
        raise DatasetError(f"--source {source}: not a directory")
    run = copy.deepcopy(manifest)
    notes = []
    files: dict[str, Path] = {}
    if building:
        for scene in manifest["sweep"]["scenarios"]:
            entry = spec["scenes"].get(scene)
            if entry is None:
                raise DatasetError(f"{path}: sweep.scenarios: {scene!r:.40} is not a scene of source.scenes")
            found = _locate(entry, source)
            if found is None:
                notes.append(f"scene {scene}: none of {entry['file']} under {source}: left out")
                continue
            files[scene] = found
        if not files:
            raise DatasetError(f"--source {source}: none of the scenes' files is there ({'; '.join(notes)})")
        run["source"]["sha256"] = {scene: _sha256(f) for scene, f in files.items()}
    else:
        digests = spec.get("sha256")
        if not digests:
            raise DatasetError(f"{path}: source.sha256: missing (run: python -m runners.dataset build "
                               f"{manifest['name']} --source DIR)")
        for scene, digest in digests.items():
            found = _locate(spec["scenes"][scene], source)
            if found is None:
                raise DatasetError(f"--source {source}: scene {scene}: none of {spec['scenes'][scene]['file']} is "
                                   "there (the dataset was built with it)")
            got = _sha256(found)
            if got != digest:
                raise DatasetError(f"{found}: sha256 {got[:16]}… is not the manifest's {digest[:16]}… for scene "
                                   f"{scene} (another copy or version of the recording)")
            files[scene] = found
    scenario_dir = conf_dir / "scenario"
    scenario_dir.mkdir(parents=True, exist_ok=True)
    names = []
    for scene, file in files.items():
        entry = spec["scenes"][scene]
        options = {k: entry[k] for k in ("format", "max_gap") if entry.get(k) is not None}
        for k in entry.get("windows", spec["windows"]):
            name = f"{scene}_w{k}"
            params = {"recording": str(file.resolve()), **options, **(spec.get("params") or {}), "window": k}
            (scenario_dir / f"{name}.yaml").write_text(yaml.safe_dump(
                {"name": name, "generator": "recorded", "params": params}, sort_keys=False))
            names.append(name)
    run["sweep"]["scenarios"] = names
    return run, [f"hydra.searchpath=[file://{conf_dir.resolve()}]"], notes
