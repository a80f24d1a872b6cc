"""What importing the package loads: the sans-IO core and the top level stay light.

Each case imports in a fresh interpreter and reads ``sys.modules``: pydantic (and with it
the status model) loads when a status is first built or named, asyncio with the first
asyncio layer (docs/architecture.md, "Import cost").
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

#: Modules that the light imports must not load.
HEAVY = ("pydantic", "pydantic_core", "asyncio", "galileo_async.models", "serial", "anyio")


def loaded_after(code: str) -> set[str]:
    """The HEAVY modules (and galileo_async's submodules) loaded after running ``code``."""
    script = (
        f"{code}\nimport json, sys\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.partition('.')[0] in "
        f"{sorted({m.partition('.')[0] for m in HEAVY} | {'galileo_async'})!r})))"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True, timeout=60
    )
    return set(json.loads(done.stdout))


@pytest.mark.parametrize(
    "code",
    [
        "import galileo_async",
        "import galileo_async.protocol",
        "from galileo_async import NavStatus, StatusLayout, LinkState, errors",
        "from galileo_async.protocol import StatusDecoder, StatusEncoder, UdpStatusDecoder",
        "from galileo_async.protocol import StatusDecoder; StatusDecoder().feed(b'garbage')",
    ],
)
def test_the_light_imports_load_no_pydantic_and_no_asyncio(code: str) -> None:
    loaded = loaded_after(code)
    assert not loaded & set(HEAVY), loaded & set(HEAVY)


def test_the_first_decoded_status_loads_the_status_model_and_no_asyncio() -> None:
    code = (
        "from galileo_async.protocol import LAYOUTS, StatusDecoder, StatusEncoder\n"
        "fields = LAYOUTS['v2'].fields\n"
        "frame = StatusEncoder('v2', fields).frame([None] * len(fields))\n"
        "(status,) = StatusDecoder().feed(frame)\n"
        "assert type(status).__name__ == 'GalileoStatus', status\n"
    )
    loaded = loaded_after(code)
    assert {"pydantic", "galileo_async.models"} <= loaded
    assert "asyncio" not in loaded


def test_naming_the_status_model_loads_it_and_pydantic_but_no_asyncio() -> None:
    loaded = loaded_after("import galileo_async; galileo_async.GalileoStatus")
    assert {"pydantic", "galileo_async.models"} <= loaded
    assert "asyncio" not in loaded
    assert "galileo_async.robot" not in loaded
