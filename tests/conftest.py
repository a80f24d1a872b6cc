"""Shared fixtures: every test must leave no Robot, task or timer behind (LeakCheck)."""

from __future__ import annotations

import asyncio
import shutil
import tempfile
from collections.abc import AsyncIterator, Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from galileo_async.testing import LeakCheck
from galileo_async.transports import Link
from tests.support.fake_device import FakeDevice

settings.register_profile(
    "ci", max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile("dev", max_examples=100, deadline=None)
settings.load_profile("ci")


@pytest.fixture(autouse=True)
def runtime_dir(monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A fresh $XDG_RUNTIME_DIR for each test and the galileo processes it starts.

    Control sockets live there: tests never meet another test's, or the user's. Short and
    under /tmp: a Unix socket's path is limited to about 100 bytes.
    """
    path = Path(tempfile.mkdtemp(prefix="gctl-", dir="/tmp"))
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(path))
    yield path
    shutil.rmtree(path, ignore_errors=True)


@pytest.fixture(autouse=True)
async def no_lingering_tasks() -> AsyncIterator[None]:
    """Fail a test that leaves a Robot open, a task running or a timer armed on its loop."""
    check = LeakCheck()
    yield
    problems = await check.finish()
    if problems:
        pytest.fail("test left things behind:\n  " + "\n  ".join(problems))


#: Bound, in seconds, on closing a link a test opened.
LINK_CLOSE_TIMEOUT = 2.0


@pytest.fixture
async def device() -> AsyncIterator[FakeDevice]:
    """A started in-memory fake device (tests/support/fake_device.py), stopped afterwards."""
    fake = FakeDevice()
    await fake.start()
    yield fake
    await fake.stop()


@pytest.fixture
async def links() -> AsyncIterator[list[Link]]:
    """Links a test opened; all closed at teardown, whatever the test did."""
    opened: list[Link] = []
    yield opened
    for link in opened:
        await asyncio.wait_for(link.close(), LINK_CLOSE_TIMEOUT)
