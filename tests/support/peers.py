"""Real peers of the tests (ROS 1, Mosquitto, tmux): skip where missing, fail where required."""

from __future__ import annotations

import os

import pytest

#: Set to 1 where .ci/setup installed the peers (CI, ``make test`` as root): a missing peer
#: then fails its tests instead of skipping them.
REQUIRE_PEERS_VARIABLE = "GALILEO_REQUIRE_PEERS"


def missing_peer(what: str) -> None:
    """Skip the test for want of ``what``, or fail it when GALILEO_REQUIRE_PEERS=1."""
    message = f"{what} is not installed: run .ci/setup (as root) first"
    if os.environ.get(REQUIRE_PEERS_VARIABLE) == "1":
        pytest.fail(f"{message} ({REQUIRE_PEERS_VARIABLE}=1)")
    pytest.skip(message)
