"""The fast status builder is fenced to the pydantic versions it was checked against.

Inside ``PYDANTIC_CHECKED`` the decoder stores a status's fields without model_construct;
outside it (another interpreter, told it runs another pydantic) every status is built by
``model_construct``, and the statuses are equal.
"""

from __future__ import annotations

import base64
import json
import pickle
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import pydantic
import pytest

from galileo_async.models import GalileoStatus, NavStatus, StatusLayout
from galileo_async.protocol import StatusDecoder
from galileo_async.protocol._build import (
    FAST_PATH,
    PYDANTIC_CHECKED,
    fast_path_supported,
    status_builder,
    trusted_status,
)
from tests.support import vectors as v

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

#: A v2 frame whose nav_status (9) no firmware sends: built through the enum map's fallback.
UNKNOWN_NAV = v.HEADER + b"\x55" + struct.pack(v.V2_FORMAT, 9, *v.V2_ACTIVE_VALUES[1:]) + b"\x00"
#: (layout, frame) decoded on both paths: every golden vector, an unknown enum value, and a
#: run of v2 frames (the decoder unpacks several whole frames in one pass).
FRAMES: list[tuple[str, bytes]] = [
    *((status.layout.value, frame) for _, frame, status in v.STATUS_VECTORS),
    ("v2", UNKNOWN_NAV),
    ("v2", v.V2_ACTIVE * 3 + v.V2_EXAMPLE * 3),
]
#: Decodes FRAMES and builds one trusted status, then prints whether the fast path ran and
#: the statuses (pickled). The argument is the pydantic version the interpreter reports.
DECODE = """
import base64, json, pickle, sys
import pydantic, pydantic.version
pydantic.version.VERSION = pydantic.VERSION = sys.argv[1]
from galileo_async.models import NavStatus, StatusLayout
from galileo_async.protocol import StatusDecoder
from galileo_async.protocol._build import FAST_PATH, trusted_status
statuses = []
for layout, frame in json.loads(sys.stdin.read()):
    statuses += StatusDecoder(layout).feed(bytes.fromhex(frame))
statuses.append(trusted_status(
    {"layout": StatusLayout.V1, "nav_status": NavStatus.OPEN, "power": 12.5}))
sets = {id(s.model_fields_set) for s in statuses if len(s.model_fields_set) == 22}
print(json.dumps({"fast": FAST_PATH, "shared_sets": len(sets) == 1,
                  "statuses": base64.b64encode(pickle.dumps(statuses)).decode()}))
"""


def decode_as(version: str) -> dict[str, Any]:
    """Run DECODE in a fresh interpreter whose pydantic reports ``version``."""
    frames = json.dumps([(layout, frame.hex()) for layout, frame in FRAMES])
    result = subprocess.run(
        [sys.executable, "-c", DECODE, version],
        input=frames,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    report: dict[str, Any] = json.loads(result.stdout)
    report["statuses"] = pickle.loads(base64.b64decode(report["statuses"]))
    return report


def test_the_installed_pydantic_is_within_the_checked_range() -> None:
    # Fails when the environment moves to a pydantic the fast path was not checked
    # against: run the tests with it, then widen PYDANTIC_CHECKED.
    assert PYDANTIC_CHECKED == ((2, 7), (2, 15))
    assert fast_path_supported(pydantic.VERSION), pydantic.VERSION
    assert FAST_PATH


def test_the_checked_range_starts_at_the_oldest_pydantic_the_package_accepts() -> None:
    pyproject = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())
    (requirement,) = (r for r in pyproject["project"]["dependencies"] if r.startswith("pydantic"))
    low = ".".join(map(str, PYDANTIC_CHECKED[0]))
    assert requirement == f"pydantic>={low}"


@pytest.mark.parametrize(
    ("version", "supported"),
    [
        ("2.7.0", True),
        ("2.7.0b1", True),
        ("2.14.4", True),
        ("2.14.99", True),
        ("2.6.9", False),
        ("2.15.0", False),
        ("3.0.0", False),
        ("1.10.13", False),
        ("", False),
        ("two", False),
    ],
)
def test_fast_path_supported(version: str, supported: bool) -> None:
    assert fast_path_supported(version) is supported


def test_in_range_the_decoder_takes_the_fast_path() -> None:
    report = decode_as(pydantic.VERSION)
    assert report["fast"] is True
    assert report["shared_sets"] is True  # one read-only fields set, no set per status


@pytest.mark.parametrize("version", ["3.0.0", "2.15.0", "2.6.0"])
def test_out_of_range_statuses_come_from_model_construct_and_are_equal(version: str) -> None:
    fallback = decode_as(version)
    assert fallback["fast"] is False
    assert fallback["shared_sets"] is False  # model_construct makes a set per status
    expected: list[GalileoStatus] = []
    for layout, frame in FRAMES:
        expected += StatusDecoder(layout).feed(frame)
    expected.append(
        trusted_status({"layout": StatusLayout.V1, "nav_status": NavStatus.OPEN, "power": 12.5})
    )
    assert len(expected) == len(FRAMES) + 5 + 1
    statuses: list[GalileoStatus] = fallback["statuses"]
    assert statuses == expected
    for got, want in zip(statuses, expected, strict=True):
        assert repr(got) == repr(want)
        assert got.model_fields_set == want.model_fields_set
        assert got.model_dump_json() == want.model_dump_json()
    assert statuses[len(v.STATUS_VECTORS)].nav_status.known is False  # type: ignore[union-attr]


def test_the_constructing_builder_equals_the_fast_one() -> None:
    maps = {"nav_status": {1: NavStatus.OPEN}}
    names = ["nav_status", "power", "time_stamp"]
    fast = status_builder(StatusLayout.V1, names, maps)
    plain = status_builder(StatusLayout.V1, names, maps, fast=False)
    built, constructed = fast((1, 12.5, None)), plain((1, 12.5, None))
    assert built == constructed == GalileoStatus(layout=StatusLayout.V1, nav_status=1, power=12.5)
    assert built.model_fields_set == constructed.model_fields_set
    assert built.model_fields_set is fast((1, 13.0, 8)).model_fields_set
    assert constructed.model_fields_set is not plain((1, 13.0, 8)).model_fields_set
    with pytest.raises(KeyError):  # a plain dict makes no pseudo-members on either path
        plain((0, 0.0, None))
