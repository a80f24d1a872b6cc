"""The decoders' status builders: GalileoStatus records, equal to validated statuses.

A builder fills a record slot by slot without pydantic: decoding builds no pydantic model,
and what it builds reads, dumps and compares like the status validation makes.
"""

from __future__ import annotations

import json
import struct
import subprocess
import sys

import pytest

from galileo_async.models import GalileoStatus, NavStatus, StatusLayout
from galileo_async.protocol import LAYOUTS, StatusDecoder
from galileo_async.protocol._build import status_builder, trusted_status
from tests.support import vectors as v

#: A v2 frame whose nav_status (9) no firmware sends: built through the enum map's fallback.
UNKNOWN_NAV = v.HEADER + b"\x55" + struct.pack(v.V2_FORMAT, 9, *v.V2_ACTIVE_VALUES[1:]) + b"\x00"
#: (layout, frame): every golden vector, an unknown enum value, and a run of v2 frames (the
#: decoder unpacks several whole frames in one pass).
FRAMES: list[tuple[str, bytes]] = [
    *((status.layout.value, frame) for _, frame, status in v.STATUS_VECTORS),
    ("v2", UNKNOWN_NAV),
    ("v2", v.V2_ACTIVE * 3 + v.V2_EXAMPLE * 3),
]


def decoded() -> list[GalileoStatus]:
    """Every status of FRAMES, each layout's frames through a decoder of their own."""
    statuses: list[GalileoStatus] = []
    for layout, frame in FRAMES:
        statuses += StatusDecoder(layout).feed(frame)
    return statuses


def test_built_statuses_equal_validated_ones_in_every_way_they_show() -> None:
    statuses = decoded()
    assert len(statuses) == len(FRAMES) + 5
    for status in statuses:
        validated = GalileoStatus.model_validate(status.model_dump())
        assert type(status) is GalileoStatus
        assert status == validated
        assert hash(status) == hash(validated)
        assert repr(status) == repr(validated)
        assert status.model_dump_json() == validated.model_dump_json()
        assert status.model_fields_set == {"layout", *LAYOUTS[status.layout].fields}
    for _, frame, expected in v.STATUS_VECTORS:
        (status,) = StatusDecoder(expected.layout).feed(frame)
        assert status == expected
    unknown = statuses[len(v.STATUS_VECTORS)].nav_status
    assert unknown is not None
    assert (int(unknown), unknown.known) == (9, False)


def test_decoding_builds_no_pydantic_model() -> None:
    code = (
        "import json, sys\n"
        "from galileo_async import models\n"
        "from galileo_async.protocol import StatusDecoder\n"
        "from galileo_async.protocol._build import trusted_status\n"
        "statuses = [s for layout, frame in json.loads(sys.stdin.read())\n"
        "            for s in StatusDecoder(layout).feed(bytes.fromhex(frame))]\n"
        "statuses.append(trusted_status({'nav_status': models.NavStatus.OPEN}))\n"
        "print(json.dumps([len(statuses), models._model.cache_info().currsize]))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code],
        input=json.dumps([(layout, frame.hex()) for layout, frame in FRAMES]),
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    count, models_built = json.loads(done.stdout)
    assert count == len(FRAMES) + 5 + 1
    assert models_built == 0  # the companion model is built by validation and dumps only


def test_a_builder_with_plain_maps_makes_no_pseudo_members() -> None:
    maps = {"nav_status": {1: NavStatus.OPEN}}
    build = status_builder(StatusLayout.V1, ["nav_status", "power", "time_stamp"], maps)
    built = build((1, 12.5, None))
    assert built == GalileoStatus(layout=StatusLayout.V1, nav_status=1, power=12.5)
    assert built.model_fields_set == {"layout", "nav_status", "power", "time_stamp"}
    with pytest.raises(KeyError):  # the exact lookup misses, the map itself too
        build((0, 0.0, None))


def test_trusted_status_reads_the_mapping_it_is_given() -> None:
    values = v.V2_ACTIVE_STATUS.model_dump()
    status = trusted_status(values)
    values["power"] = 1.0  # not adopted: the status keeps what it read
    assert status == v.V2_ACTIVE_STATUS
    assert status.model_fields_set == set(GalileoStatus.model_fields)
    partial = trusted_status({"layout": StatusLayout.V1, "power": 12.5})
    assert partial.model_fields_set == {"layout", "power"}
    assert partial == GalileoStatus(layout=StatusLayout.V1, power=12.5)
