"""Test-side robot for the ROS link: a rospy node that plays a Galileo robot's ROS side.

Runs under the system Python with Debian's rospy and genpy (not the project's venv), so
it is self-contained: its own message texts (as the robot's .msg files) and a small robot
model following the real firmware (docs/protocol.md §2). It publishes
``/galileo/status`` at 30 Hz and applies ``/galileo/cmds``.

``--hostname NAME`` makes it advertise NAME (as ROS_HOSTNAME does) while it listens on
``--bind`` (127.0.0.1): a robot whose host name the test's host cannot resolve.
``--goal-num`` keeps the parameter ``/galileo/goal_num`` as the vendor's navigation node
does: a string, the number of targets, dynamic ones included.

Control from the test on stdin, one line each: ``busy SECONDS`` (report busy and hold
commands), ``abort`` (the planner gives up on the goal), ``freeze`` (the navigation stack
dies behind a live serial node: the last status is re-published, commands reach no one),
``thaw`` (the stack restarts and, as /galileo/cmds is latched, executes only the last
command sent meanwhile), ``quit``.
It prints ``READY`` once its publisher and subscriber are registered.
"""

from __future__ import annotations

import argparse
import math
import os
import queue
import struct
import sys
import threading
import time

import genpy.dynamic
import rosgraph.network
import rospy

HEADER_TEXT = """# Standard metadata for higher-level stamped data types.
uint32 seq
time stamp
string frame_id
"""
SEP = "\n" + "=" * 80 + "\nMSG: std_msgs/Header\n"

CMDS_TEXT = "Header header\nuint32 length\nuint8[] data\n"
STATUS_FULL = """Header header
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
# The vendor document's 13-field version (older robots).
STATUS_13 = """Header header
int32 navStatus # 0 closed, 1 open
int32 visualStatus
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
"""

RATE_HZ = 30.0
ARRIVE = 0.005


class RobotModel:
    """A small robot: navigation, visual init, goals, patrol, mapping, busy."""

    def __init__(
        self, targets: list[tuple[float, float]], speed: float, visual_init: float
    ) -> None:
        self.map_targets = list(targets)
        self.dynamic: list[tuple[float, float]] = []
        self.speed = speed
        self.visual_init = visual_init
        self.nav = 0
        self.visual = -1
        self.visual_ready_at = 0.0
        self.mapping = 0
        self.charge = 0
        self.loop = 0
        self.dwell = 0.2
        self.patrol_next_at: float | None = None
        self.target_id = -1
        self.target_status = -1
        self.distance = -1.0
        self.x = 0.0
        self.y = 0.0
        self.angle = 0.0
        self.vx = 0.0
        self.vth = 0.0
        self.busy_until = 0.0
        self.abort_requested = False

    @property
    def targets(self) -> list[tuple[float, float]]:
        return self.map_targets + self.dynamic

    def busy(self, now: float) -> bool:
        return now < self.busy_until

    def apply(self, data: bytes, now: float) -> None:
        if len(data) < 2:
            return
        op, arg = data[0], data[1]
        if op == ord("m"):
            self._nav_command(data, now)
        elif op == ord("g") and arg == ord("i") and len(data) == 10:
            self.dynamic.append(struct.unpack("<ff", data[2:10]))
        elif op == ord("g") and arg == ord("r"):
            self.dynamic.clear()
        elif op == ord("g"):
            self._goto(arg)
        elif op == ord("i"):
            if arg == 0 and self.target_status == 1:
                self.target_status = 2
            elif arg == 1 and self.target_status == 2:
                self.target_status = 1
            elif arg == 2 and self.target_status in (1, 2):
                self.target_status = 0
                self.target_id = -1  # firmware: cancel resets the id (docs/protocol.md §2.c)
        elif op == ord("V"):
            if arg == 0:
                self._stop_nav()
                self.mapping = 1
            elif arg == 1:
                self.mapping = 0
        elif op == ord("j"):
            self.charge = {0: 1, 1: 0}.get(arg, self.charge)
        elif op in (ord("f"), ord("b")):
            self.vx = (1 if op == ord("f") else -1) * arg / 100.0
        elif op in (ord("c"), ord("d")):
            self.vth = (1 if op == ord("c") else -1) * arg / 100.0
        elif op == ord("s"):
            self.vx = self.vth = 0.0

    def _nav_command(self, data: bytes, now: float) -> None:
        arg = data[1]
        if arg == 0 and not self.nav and not self.mapping:
            self.nav = 1
            self.visual = 0
            self.visual_ready_at = now + self.visual_init
        elif arg == 4:
            self._stop_nav()
        elif arg == 5 and self.nav:
            if len(data) >= 3:
                self.dwell = data[2]
            if not self.loop:
                self.loop = 1
                self.patrol_next_at = now
        elif arg == 6:
            self.loop = 0
            self.patrol_next_at = None

    def _stop_nav(self) -> None:
        self.nav = 0
        self.visual = -1
        self.loop = 0
        self.patrol_next_at = None
        if self.target_status in (1, 2):
            self.target_status = 0
        self.vx = self.vth = 0.0

    def _goto(self, target: int) -> None:
        if self.visual not in (1, 2):
            return
        if target < len(self.targets):
            self.target_id = target
            self.target_status = 1
            self.distance = self._distance_to(target)
        else:
            self.target_status = -1  # firmware: error is -1 and the id is unchanged

    def _distance_to(self, target: int) -> float:
        tx, ty = self.targets[target]
        return math.hypot(tx - self.x, ty - self.y)

    def step(self, now: float, dt: float) -> None:
        if self.nav and self.visual == 0 and now >= self.visual_ready_at:
            self.visual = 1
        if self.target_status == 1 and 0 <= self.target_id < len(self.targets):
            self._move(dt)
        elif self.target_status != 1:
            self.vx = 0.0 if self.target_status in (0, 2) else self.vx
        due = self.patrol_next_at is not None and now >= self.patrol_next_at
        if self.loop and self.target_status != 1 and due and self.targets:
            following = (self.target_id + 1) % len(self.targets) if self.target_id >= 0 else 0
            self._goto(following)
            self.patrol_next_at = None
        if self.loop and self.target_status == 0 and self.patrol_next_at is None:
            self.patrol_next_at = now + self.dwell

    def _move(self, dt: float) -> None:
        if self.abort_requested:
            self.abort_requested = False
            self.target_status = 0
            self.vx = 0.0
            return
        tx, ty = self.targets[self.target_id]
        dx, dy = tx - self.x, ty - self.y
        dist = math.hypot(dx, dy)
        step = self.speed * dt
        if dist <= max(step, ARRIVE):
            self.x, self.y = tx, ty
            self.distance = 0.0
            self.target_status = 0
            self.vx = 0.0
            return
        self.angle = math.atan2(dy, dx)
        self.x += dx / dist * step
        self.y += dy / dist * step
        self.distance = dist - step
        self.vx = self.speed


def status_message(cls: type, model: RobotModel, now: float) -> object:
    msg = cls()
    msg.header.stamp = rospy.Time.from_sec(time.time())
    values = {
        "navStatus": model.nav,
        "visualStatus": model.visual,
        "mapStatus": model.mapping,
        "gcStatus": 0,
        "gbaStatus": 0,
        "chargeStatus": model.charge,
        "loopStatus": model.loop,
        "power": 12.5,
        "targetNumID": model.target_id,
        "targetStatus": model.target_status,
        "targetDistance": model.distance,
        "angleGoalStatus": 1
        if model.target_status == 0
        else (0 if model.target_status == 1 else -1),
        "controlSpeedX": model.vx,
        "controlSpeedTheta": model.vth,
        "currentSpeedX": model.vx,
        "currentSpeedTheta": model.vth,
        "currentPosX": model.x,
        "currentPosY": model.y,
        "currentAngle": model.angle,
        "busyStatus": 1 if model.busy(now) else 0,
    }
    for name in msg.__slots__:
        if name in values:
            setattr(msg, name, values[name])
    return msg


def read_control(lines: queue.Queue[str]) -> None:
    for line in sys.stdin:
        lines.put(line.strip())
    lines.put("quit")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--version", choices=["full", "13"], default="full")
    parser.add_argument("--targets", default="1,0;0,1;-1,0;0,-1")
    parser.add_argument("--speed", type=float, default=4.0)
    parser.add_argument("--visual-init", type=float, default=0.2)
    parser.add_argument("--name", default="galileo_serial_server")
    parser.add_argument("--hostname", default=None)
    parser.add_argument("--bind", default="127.0.0.1")
    parser.add_argument("--goal-num", action="store_true")
    args = parser.parse_args()
    if args.hostname is not None:
        os.environ["ROS_HOSTNAME"] = args.hostname
        # rospy would listen on every interface for a host name: keep the test on loopback.
        rosgraph.network.get_bind_address = lambda address=None: args.bind
    targets = [tuple(float(v) for v in pair.split(",")) for pair in args.targets.split(";") if pair]

    status_text = STATUS_FULL if args.version == "full" else STATUS_13
    status_type = "galileo_serial_server/GalileoStatus"
    cmds_type = "galileo_serial_server/GalileoNativeCmds"
    status_cls = genpy.dynamic.generate_dynamic(status_type, status_text + SEP + HEADER_TEXT)[
        status_type
    ]
    cmds_cls = genpy.dynamic.generate_dynamic(cmds_type, CMDS_TEXT + SEP + HEADER_TEXT)[cmds_type]

    model = RobotModel(targets, args.speed, args.visual_init)  # type: ignore[arg-type]
    incoming: queue.Queue[bytes] = queue.Queue()
    received = [0]

    def on_cmds(msg: object) -> None:
        data = bytes(bytearray(msg.data))  # type: ignore[attr-defined]
        if msg.length != len(data):  # type: ignore[attr-defined]
            return
        received[0] += 1
        incoming.put(data)

    rospy.init_node(args.name, disable_signals=True)
    goal_num = [-1]

    def publish_goal_num() -> None:
        # The vendor's navigation node sets it as a string of the target count.
        if args.goal_num and goal_num[0] != len(model.targets):
            goal_num[0] = len(model.targets)
            rospy.set_param("/galileo/goal_num", str(goal_num[0]))

    publish_goal_num()
    pub = rospy.Publisher("/galileo/status", status_cls, queue_size=10)
    rospy.Subscriber("/galileo/cmds", cmds_cls, on_cmds, queue_size=100)
    control: queue.Queue[str] = queue.Queue()
    threading.Thread(target=read_control, args=(control,), daemon=True).start()
    print(f"READY {os.getpid()}", flush=True)

    held: list[bytes] = []
    frozen: list[object] = []  # the status the dead navigation stack left behind
    last = time.monotonic()
    period = 1.0 / RATE_HZ
    while not rospy.is_shutdown():
        now = time.monotonic()
        while not control.empty():
            line = control.get_nowait()
            if line == "quit":
                rospy.signal_shutdown("quit")
                return
            if line.startswith("busy "):
                model.busy_until = now + float(line.split()[1])
            elif line == "abort":
                model.abort_requested = True
            elif line == "freeze":
                frozen[:] = [status_message(status_cls, model, now)]
            elif line == "thaw":
                frozen.clear()
                held[:] = held[-1:]  # a latched topic hands the new subscriber its last message
        while not incoming.empty():
            held.append(incoming.get_nowait())
        if frozen:
            pub.publish(frozen[0])
            last = now
            time.sleep(max(0.0, period - (time.monotonic() - now)))
            continue
        while held and not model.busy(now):  # busy: commands wait (docs/protocol.md §2)
            model.apply(held.pop(0), now)
        publish_goal_num()
        model.step(now, now - last)
        last = now
        pub.publish(status_message(status_cls, model, now))
        time.sleep(max(0.0, period - (time.monotonic() - now)))


if __name__ == "__main__":
    main()
