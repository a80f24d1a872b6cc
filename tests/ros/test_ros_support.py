"""The ROS tests skip where ROS 1 is missing, unless GALILEO_REQUIRE_PEERS=1 demands it."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from _pytest.outcomes import Failed, Skipped

from tests.support import peers, ros_support


@pytest.fixture
def no_ros(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(shutil, "which", lambda name, *args, **kwargs: None)


@pytest.mark.usefixtures("no_ros")
def test_missing_ros_skips_by_default(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(peers.REQUIRE_PEERS_VARIABLE, raising=False)
    with pytest.raises(Skipped, match=r"ROS 1 .*\.ci/setup"):
        ros_support.require_ros()


@pytest.mark.usefixtures("no_ros")
@pytest.mark.parametrize("value", ["0", ""])
def test_missing_ros_skips_unless_the_variable_is_1(
    monkeypatch: pytest.MonkeyPatch, value: str
) -> None:
    monkeypatch.setenv(peers.REQUIRE_PEERS_VARIABLE, value)
    with pytest.raises(Skipped):
        ros_support.require_ros()


@pytest.mark.usefixtures("no_ros")
def test_missing_ros_fails_when_required(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(peers.REQUIRE_PEERS_VARIABLE, "1")
    with pytest.raises(Failed, match=r"ROS 1 .*\.ci/setup.*GALILEO_REQUIRE_PEERS=1"):
        ros_support.require_ros()


@pytest.mark.usefixtures("no_ros")
def test_fixtures_that_need_ros_skip_too(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.delenv(peers.REQUIRE_PEERS_VARIABLE, raising=False)
    with pytest.raises(Skipped):
        ros_support.RosMaster(tmp_path)
    with pytest.raises(Skipped):
        ros_support.genpy_script("print(1)")


def test_installed_ros_is_found() -> None:
    rosmaster = ros_support.require_ros()  # follows the same skip-or-fail rule
    assert os.access(rosmaster, os.X_OK)
    assert os.access(ros_support.SYSTEM_PYTHON, os.X_OK)
