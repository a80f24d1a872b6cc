"""Record a robot's drive to a target into MCAP, then read the recording back.

python examples/record_mcap.py [URL] [FILE]   # default: $GALILEO_PORT, else sim://; drive.mcap

Open FILE in Foxglove or Lichtblick (Open local file): /robot/status in a Raw Messages or
Plot panel, /robot/events in the Log panel. Needs the extra [mcap].
"""

from __future__ import annotations

import asyncio
import os
import sys

import galileo_async as galileo
from galileo_async.recording import McapRecorder, read_recording

URL = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("GALILEO_PORT", "sim://")
FILE = sys.argv[2] if len(sys.argv) > 2 else "drive.mcap"


async def main() -> None:
    async with galileo.connect(URL) as robot:
        if not robot.status or not robot.status.navigating:
            await robot.start_navigation(timeout=60)
        async with McapRecorder(FILE, robot) as recorder:
            await robot.goto(1, timeout=120)
        if recorder.dropped:
            print(f"the disk could not keep up: {recorder.dropped} messages were not recorded")
    recorded = read_recording(FILE).robot()
    print(f"{FILE}: {len(recorded.statuses)} statuses, {len(recorded.raw)} raw chunks")
    for seconds, log in recorded.events:
        print(f"{seconds:6.2f} s  {log['message']}")


if __name__ == "__main__":
    asyncio.run(main())
