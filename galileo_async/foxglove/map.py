"""A robot's map on the Foxglove server: its PNG on ``/name/map``, its place on ``/name/map_info``.

Only for a robot with the HTTP API (``robot.http``). The map is read (robot.http.map_image)
when a viewer subscribes to either channel, and again when the robot's current map changes:
while someone is subscribed, the map's name is looked at every MAP_CHECK seconds. Nothing is
read for nobody; a read that fails is logged and tried again at the next subscription or look.
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from typing import TYPE_CHECKING

import foxglove
from foxglove.channels import CompressedImageChannel
from foxglove.messages import CompressedImage, Timestamp

from ..errors import GalileoError
from .schemas import MAP_INFO_SCHEMA_NAME, map_info_json, map_info_schema

if TYPE_CHECKING:
    from ..robot import HttpPart

__all__ = ["MAP_CHECK", "MAP_TIMEOUT", "MAP_TOPICS", "MapChannels"]

_log = logging.getLogger("galileo_async.foxglove")

#: The map topics of a robot with the HTTP API, after its ``/name`` prefix.
MAP_TOPICS = ("map", "map_info")
#: Seconds between two looks at the robot's current map while a viewer is subscribed.
MAP_CHECK = 10.0
#: Seconds one read of the map (its name, parameters and PNG) may take.
MAP_TIMEOUT = 30.0


class MapChannels:
    """``/name/map`` (foxglove.CompressedImage, PNG) and ``/name/map_info`` (JSON) of one robot."""

    def __init__(
        self, name: str, http: HttpPart, context: foxglove.Context, *, frame_id: str
    ) -> None:
        self.name, self.http, self.frame_id = name, http, frame_id
        self.image = CompressedImageChannel(f"/{name}/map", context=context)
        schema = foxglove.Schema(
            name=MAP_INFO_SCHEMA_NAME, encoding="jsonschema", data=map_info_schema()
        )
        self.info = foxglove.Channel(
            f"/{name}/map_info", schema=schema, message_encoding="json", context=context
        )
        #: The map last published (None: none yet), maps published, reads that failed.
        self.current: str | None = None
        self.published = 0
        self.failed = 0
        self._task: asyncio.Task[None] | None = None
        self._wanted = False
        self._looked = -math.inf

    @property
    def topics(self) -> tuple[str, ...]:
        """The two channels' topics."""
        return (f"/{self.name}/map", f"/{self.name}/map_info")

    def wanted(self) -> None:
        """A viewer subscribed: read the map and publish it (on the loop)."""
        self._wanted = True
        self._read()

    def tick(self) -> None:
        """Every MAP_CHECK s while subscribed: publish the map again if it is another one."""
        if not (self.image.has_sinks() or self.info.has_sinks()):
            return
        if time.monotonic() - self._looked >= MAP_CHECK:
            self._read()

    def close(self) -> asyncio.Task[None] | None:
        """Take the channels off the server; the read under way, cancelled (to be awaited)."""
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
        self.image.close()
        self.info.close()
        return task

    def _read(self) -> None:
        if self._task is not None and not self._task.done():
            return  # its publication reaches every viewer subscribed by then
        self._looked = time.monotonic()
        self._task = asyncio.get_running_loop().create_task(
            self._publish(), name=f"foxglove map of {self.name}"
        )

    async def _publish(self) -> None:
        try:
            await asyncio.wait_for(self._read_and_publish(), MAP_TIMEOUT)
        except (GalileoError, asyncio.TimeoutError) as exc:
            self.failed += 1
            self._wanted = False  # tried for it: the next subscription or look tries again
            _log.warning("foxglove: robot %s: no map image: %s", self.name, exc or "timed out")
        if self._wanted and self._task is asyncio.current_task():
            self._task = None  # a subscription came after the look: read again for it
            self._read()

    async def _read_and_publish(self) -> None:
        where = await self.http.current_map()
        wanted, self._wanted = self._wanted, False
        if not wanted and where.map == self.current:
            return
        image = await self.http.map_image()
        stamp = Timestamp.from_epoch_secs(time.time())
        self.image.log(
            CompressedImage(timestamp=stamp, frame_id=self.frame_id, data=image.png, format="png")
        )
        self.info.log(map_info_json(where.map, image, self.frame_id))
        self.current = where.map
        self.published += 1
