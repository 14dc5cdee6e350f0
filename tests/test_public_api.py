"""fuzzynav's public API: every name of ``fuzzynav.__all__`` resolves, and ``import fuzzynav`` loads no simulator."""

from __future__ import annotations

import subprocess
import sys

import fuzzynav


def test_every_public_name_resolves():
    for name in fuzzynav.__all__:
        assert getattr(fuzzynav, name) is not None
    assert set(fuzzynav.__all__) <= set(dir(fuzzynav))


def test_import_is_light():
    code = "import sys, fuzzynav; print(sorted(m for m in sys.modules if m.startswith('fuzzynav')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "['fuzzynav']"


def test_unknown_name_is_an_attribute_error():
    try:
        fuzzynav.NoSuchThing  # noqa: B018
    except AttributeError as err:
        assert "NoSuchThing" in str(err)
    else:
        raise AssertionError("no AttributeError")
