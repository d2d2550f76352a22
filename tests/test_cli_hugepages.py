"""The command line stops numpy's huge-page advice (``lattice_cad.cli._no_hugepage_advice``)
in its own process and the ones it starts, unless the user set NUMPY_MADVISE_HUGEPAGE.

Each case runs in a fresh interpreter: the switch is numpy's global state.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

PROBE = """
import json, os, sys
import numpy as np
from lattice_cad.cli import _no_hugepage_advice
before = bool(np._core.multiarray._get_madvise_hugepage())
did = _no_hugepage_advice()
after = bool(np._core.multiarray._get_madvise_hugepage())
# a process started from here imports numpy with the variable the CLI set
child = subprocess_out = __import__("subprocess").run(
    [sys.executable, "-c",
     "import numpy as np; print(int(np._core.multiarray._get_madvise_hugepage()))"],
    capture_output=True, text=True, check=True,
).stdout.strip()
print(json.dumps({"before": before, "did": did, "after": after, "child": child,
                  "env": os.environ.get("NUMPY_MADVISE_HUGEPAGE")}))
"""


def _probe(env_value: str | None) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "NUMPY_MADVISE_HUGEPAGE"}
    if env_value is not None:
        env["NUMPY_MADVISE_HUGEPAGE"] = env_value
    out = subprocess.run(
        [sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="numpy advises on Linux only")
def test_cli_turns_the_advice_off_here_and_in_children():
    got = _probe(None)
    assert got == {"before": True, "did": True, "after": False, "child": "0", "env": "0"}


def test_the_users_setting_wins():
    for value, on in (("1", True), ("0", False)):
        got = _probe(value)
        assert got["did"] is False
        assert got["before"] == got["after"] == on
        assert got["env"] == value
        assert got["child"] == str(int(on))
