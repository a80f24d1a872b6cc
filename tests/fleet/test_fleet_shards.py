"""Shards: a fleet file split over N processes, every robot in exactly one, by name only."""

from __future__ import annotations

import random
import zlib

import pytest

from galileo_async.errors import InvalidArgument
from galileo_async.fleet.shards import Shard, parse_shard, shard_of

NAMES = [f"robot-{i:04d}" for i in range(1000)] + ["alpha", "beta", "ünïcode"]


@pytest.mark.parametrize("count", [1, 2, 3, 7, 16])
def test_every_robot_is_in_exactly_one_shard(count: int) -> None:
    shards = [Shard(k, count).select(NAMES) for k in range(1, count + 1)]
    assert sorted(name for shard in shards for name in shard) == sorted(NAMES)
    assert sum(len(shard) for shard in shards) == len(NAMES)  # none in two
    if count > 1:  # spread, not all in one
        assert all(len(shard) > len(NAMES) / count / 2 for shard in shards)


def test_the_assignment_does_not_depend_on_the_file_order() -> None:
    shuffled = NAMES[:]
    random.Random(5).shuffle(shuffled)
    for k in (1, 2, 3):
        assert set(Shard(k, 3).select(shuffled)) == set(Shard(k, 3).select(NAMES))
        assert set(Shard(k, 3).select(shuffled[:10])) == set(Shard(k, 3).select(NAMES)) & set(
            shuffled[:10]
        )


def test_a_name_always_lands_in_the_same_shard() -> None:
    # crc32 of the UTF-8 name: the same in every process and on every machine.
    assert shard_of("alpha", 4) == zlib.crc32(b"alpha") % 4 + 1
    assert Shard(shard_of("beta", 5), 5).holds("beta")


def test_parse_shard() -> None:
    assert parse_shard("2/4") == Shard(2, 4)
    assert str(parse_shard("1/1")) == "1/1"
    for bad in ("0/4", "5/4", "2", "a/b", "1/0", "", "-1/2"):
        with pytest.raises(InvalidArgument, match="shard must be K/N"):
            parse_shard(bad)
