"""The robot's end of the ros:// latency probe: a rospy node that publishes on demand.

Runs under the system Python with Debian's rospy and genpy (not the project's venv), so it
is self-contained: its own message texts, as the robot's .msg files. It publishes
``/galileo/status`` only when told, and records when each ``/galileo/cmds`` message
reaches its callback.

Control on stdin, one line each: ``status K`` publishes a status whose targetNumID is K
(time.monotonic() just before the publish is recorded); ``dump N`` waits until N commands
have arrived (at most DUMP_TIMEOUT s), then prints one JSON line: ``sent`` (K → time) and
``commands`` ([time, first byte] per command, in arrival order). ``quit`` ends the node.
Times are CLOCK_MONOTONIC, the clock time.monotonic() and time.perf_counter() read in
every process on the machine. It prints ``READY`` once publisher and subscriber exist.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time

import genpy.dynamic
import rospy

HEADER_TEXT = """# Standard metadata for higher-level stamped data types.
uint32 seq
time stamp
string frame_id
"""
SEP = "\n" + "=" * 80 + "\nMSG: std_msgs/Header\n"
CMDS_TEXT = "Header header\nuint32 length\nuint8[] data\n"
STATUS_TEXT = """Header header
int32 navStatus
int32 visualStatus
int32 mapStatus
int32 gcStatus
int32 gbaStatus
int32 chargeStatus
int32 loopStatus
float32 power
int32 targetNumID
int32 targetStatus
float32 targetDistance
int32 angleGoalStatus
float32 controlSpeedX
float32 controlSpeedTheta
float32 currentSpeedX
float32 currentSpeedTheta
float32 currentPosX
float32 currentPosY
float32 currentAngle
int32 busyStatus
"""
DUMP_TIMEOUT = 10.0


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--name", default="galileo_serial_server")
    args = parser.parse_args()
    status_type = "galileo_serial_server/GalileoStatus"
    cmds_type = "galileo_serial_server/GalileoNativeCmds"
    status_cls = genpy.dynamic.generate_dynamic(status_type, STATUS_TEXT + SEP + HEADER_TEXT)[
        status_type
    ]
    cmds_cls = genpy.dynamic.generate_dynamic(cmds_type, CMDS_TEXT + SEP + HEADER_TEXT)[cmds_type]

    commands: list[list[float]] = []
    arrived = threading.Condition()

    def on_cmds(msg: object) -> None:
        when = time.monotonic()
        data = bytes(bytearray(msg.data))  # type: ignore[attr-defined]
        with arrived:
            commands.append([when, data[0] if data else -1])
            arrived.notify_all()

    rospy.init_node(args.name, disable_signals=True)
    # queue_size=None: publish() writes to the subscribers in this thread, no hand-over.
    pub = rospy.Publisher("/galileo/status", status_cls, queue_size=None)
    rospy.Subscriber("/galileo/cmds", cmds_cls, on_cmds, queue_size=100, tcp_nodelay=True)

    def status(k: int) -> object:
        msg = status_cls()
        msg.header.stamp = rospy.Time.from_sec(time.time())
        msg.navStatus, msg.visualStatus, msg.power = 1, 1, 12.5
        msg.targetNumID, msg.targetStatus = k, 0
        return msg

    print(f"READY {os.getpid()}", flush=True)
    sent: dict[int, float] = {}
    while True:
        line = sys.stdin.readline()
        if not line or line.strip() == "quit":
            break
        word, _, value = line.strip().partition(" ")
        if word == "status":
            k = int(value)
            msg = status(k)
            sent[k] = time.monotonic()
            pub.publish(msg)
        elif word == "dump":
            deadline = time.monotonic() + DUMP_TIMEOUT
            with arrived:
                while len(commands) < int(value) and time.monotonic() < deadline:
                    arrived.wait(deadline - time.monotonic())
                got = list(commands)
            print(json.dumps({"sent": sent, "commands": got}), flush=True)
    rospy.signal_shutdown("quit")


if __name__ == "__main__":
    main()
